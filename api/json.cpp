#include "api/json.h"

#include <cstdint>

namespace api {

namespace {

using nlohmann::json;

// Field readers: each returns an error string naming `where.key`, or empty.
std::string readString(const json& j, const char* key, std::string& out, const std::string& where, bool required) {
  const auto it = j.find(key);
  if (it == j.end() || it->is_null()) return required ? where + "." + key + ": required" : "";
  if (!it->is_string()) return where + "." + key + ": expected a string";
  out = it->get<std::string>();
  return "";
}

template <typename Number>
std::string readNumber(const json& j, const char* key, Number& out, const std::string& where, bool required) {
  const auto it = j.find(key);
  if (it == j.end() || it->is_null()) return required ? where + "." + key + ": required" : "";
  if (!it->is_number()) return where + "." + key + ": expected a number";
  out = it->get<Number>();
  return "";
}

std::string readBool(const json& j, const char* key, bool& out, const std::string& where) {
  const auto it = j.find(key);
  if (it == j.end() || it->is_null()) return "";
  if (!it->is_boolean()) return where + "." + key + ": expected true or false";
  out = it->get<bool>();
  return "";
}

json nullIfEmpty(const std::string& s) { return s.empty() ? json(nullptr) : json(s); }

}  // namespace

json toJson(const Problem& p) {
  json j = {{"type", p.type}, {"title", p.title}, {"status", p.status}, {"detail", p.detail}};
  if (!p.instance.empty()) j["instance"] = p.instance;
  return j;
}

json toJson(const RigInfo& r) {
  json j = {{"id", r.id}, {"name", r.name}, {"size_bytes", r.size_bytes}, {"vertices", r.vertices},
            {"joints", r.joints}, {"morph_targets", r.morph_targets}, {"landmarks", r.landmarks},
            {"has_components", r.has_components}, {"created_at", r.created_at}};
  if (r.region_labels) j["region_labels"] = *r.region_labels;
  return j;
}

json toJson(const JobSpec& s) {
  json j = {{"kind", jobKindName(s.kind)}, {"options", s.options}};
  if (!s.rig.empty()) j["rig"] = s.rig;
  return j;
}

json toJson(const JobInfo& job) {
  json j = {{"id", job.id},
            {"kind", job.kind},
            {"rig", nullIfEmpty(job.rig)},
            {"status", jobStatusName(job.status)},
            {"stage", job.stage},
            {"progress", job.progress},
            {"attempts", job.attempts},
            {"cache_hit", job.cache_hit},
            {"has_components", job.has_components},
            {"created_at", job.created_at},
            {"started_at", nullIfEmpty(job.started_at)},
            {"finished_at", nullIfEmpty(job.finished_at)},
            {"timings_ms", job.timings_ms},
            {"files", job.files}};
  j["error"] = job.error ? toJson(*job.error) : json(nullptr);
  return j;
}

json toJson(const JobPage& page) {
  json items = json::array();
  for (const auto& job : page.items) items.push_back(toJson(job));
  return {{"items", items}, {"next", nullIfEmpty(page.next)}};
}

json toJson(const RigPage& page) {
  json items = json::array();
  for (const auto& rig : page.items) items.push_back(toJson(rig));
  return {{"items", items}};
}

Parsed<Problem> problemFromJson(const json& j) {
  if (!j.is_object()) return std::string("problem: expected an object");
  Problem p;
  for (const std::string& e : {readString(j, "type", p.type, "problem", true), readString(j, "title", p.title, "problem", false),
                               readNumber(j, "status", p.status, "problem", true),
                               readString(j, "detail", p.detail, "problem", false),
                               readString(j, "instance", p.instance, "problem", false)}) {
    if (!e.empty()) return e;
  }
  return p;
}

Parsed<RigInfo> rigInfoFromJson(const json& j) {
  if (!j.is_object()) return std::string("rig: expected an object");
  RigInfo r;
  for (const std::string& e :
       {readString(j, "id", r.id, "rig", true), readString(j, "name", r.name, "rig", false),
        readNumber(j, "size_bytes", r.size_bytes, "rig", false), readNumber(j, "vertices", r.vertices, "rig", false),
        readNumber(j, "joints", r.joints, "rig", false), readNumber(j, "morph_targets", r.morph_targets, "rig", false),
        readNumber(j, "landmarks", r.landmarks, "rig", false), readBool(j, "has_components", r.has_components, "rig"),
        readString(j, "created_at", r.created_at, "rig", false)}) {
    if (!e.empty()) return e;
  }
  if (j.contains("region_labels")) {
    const json& labels = j["region_labels"];
    if (!labels.is_array()) return std::string("rig.region_labels: expected an array of integers 0-63");
    std::vector<int> values;
    for (const json& l : labels) {
      if (!l.is_number_integer() || l.get<std::int64_t>() < 0 || l.get<std::int64_t>() > 63) {
        return std::string("rig.region_labels: expected an array of integers 0-63");
      }
      values.push_back(l.get<int>());
    }
    r.region_labels = std::move(values);
  }
  return r;
}

Parsed<JobSpec> jobSpecFromJson(const json& j) {
  if (!j.is_object()) return std::string("spec: expected a JSON object {\"kind\":..., \"rig\":..., \"options\":{...}}");
  JobSpec s;
  for (const auto& [key, value] : j.items()) {
    if (key != "kind" && key != "rig" && key != "options") return "spec." + key + ": not a known field (kind, rig, options)";
  }
  std::string kind;
  for (const std::string& e : {readString(j, "kind", kind, "spec", true), readString(j, "rig", s.rig, "spec", false)}) {
    if (!e.empty()) return e;
  }
  const auto parsed_kind = parseJobKind(kind);
  if (!parsed_kind) {
    std::string known;
    for (const JobKindInfo& k : jobKinds()) known += std::string(known.empty() ? "" : ", ") + jobKindName(k.kind);
    return "spec.kind: unknown kind '" + kind + "' (known: " + known + ")";
  }
  s.kind = *parsed_kind;
  if (const auto it = j.find("options"); it != j.end() && !it->is_null()) {
    if (!it->is_object()) return std::string("spec.options: expected an object");
    s.options = *it;
  }
  return s;
}

Parsed<JobInfo> jobInfoFromJson(const json& j) {
  if (!j.is_object()) return std::string("job: expected an object");
  JobInfo job;
  std::string status;
  for (const std::string& e :
       {readString(j, "id", job.id, "job", true), readString(j, "kind", job.kind, "job", false),
        readString(j, "rig", job.rig, "job", false), readString(j, "status", status, "job", true),
        readString(j, "stage", job.stage, "job", false), readNumber(j, "progress", job.progress, "job", false),
        readNumber(j, "attempts", job.attempts, "job", false), readBool(j, "cache_hit", job.cache_hit, "job"),
        readBool(j, "has_components", job.has_components, "job"), readString(j, "created_at", job.created_at, "job", false),
        readString(j, "started_at", job.started_at, "job", false),
        readString(j, "finished_at", job.finished_at, "job", false)}) {
    if (!e.empty()) return e;
  }
  const auto parsed_status = parseJobStatus(status);
  if (!parsed_status) return "job.status: unknown status '" + status + "'";
  job.status = *parsed_status;
  if (const auto it = j.find("timings_ms"); it != j.end() && it->is_object()) {
    for (const auto& [stage, ms] : it->items()) {
      if (ms.is_number()) job.timings_ms[stage] = ms.get<double>();
    }
  }
  if (const auto it = j.find("files"); it != j.end() && it->is_object()) {
    for (const auto& [field, name] : it->items()) {
      if (name.is_string()) job.files[field] = name.get<std::string>();
    }
  }
  if (const auto it = j.find("error"); it != j.end() && !it->is_null()) {
    auto problem = problemFromJson(*it);
    if (!problem) return "job.error: " + problem.error();
    job.error = std::move(*problem);
  }
  return job;
}

Parsed<JobPage> jobPageFromJson(const json& j) {
  if (!j.is_object() || !j.contains("items") || !j["items"].is_array()) return std::string("page: expected {\"items\": [...]}");
  JobPage page;
  for (const auto& item : j["items"]) {
    auto job = jobInfoFromJson(item);
    if (!job) return job.error();
    page.items.push_back(std::move(*job));
  }
  if (const std::string e = readString(j, "next", page.next, "page", false); !e.empty()) return e;
  return page;
}

Parsed<RigPage> rigPageFromJson(const json& j) {
  if (!j.is_object() || !j.contains("items") || !j["items"].is_array()) return std::string("page: expected {\"items\": [...]}");
  RigPage page;
  for (const auto& item : j["items"]) {
    auto rig = rigInfoFromJson(item);
    if (!rig) return rig.error();
    page.items.push_back(std::move(*rig));
  }
  return page;
}

bool isValidUtf8(std::string_view text) {
  std::size_t i = 0;
  while (i < text.size()) {
    const auto c = static_cast<unsigned char>(text[i]);
    int more = 0;
    std::uint32_t code = 0, least = 0;
    if (c < 0x80) {
      ++i;
      continue;
    } else if ((c & 0xE0) == 0xC0) {
      more = 1, code = c & 0x1F, least = 0x80;
    } else if ((c & 0xF0) == 0xE0) {
      more = 2, code = c & 0x0F, least = 0x800;
    } else if ((c & 0xF8) == 0xF0) {
      more = 3, code = c & 0x07, least = 0x10000;
    } else {
      return false;
    }
    if (i + static_cast<std::size_t>(more) >= text.size()) return false;  // truncated
    for (int k = 1; k <= more; ++k) {
      const auto t = static_cast<unsigned char>(text[i + static_cast<std::size_t>(k)]);
      if ((t & 0xC0) != 0x80) return false;
      code = (code << 6) | (t & 0x3F);
    }
    if (code < least || code > 0x10FFFF || (code >= 0xD800 && code <= 0xDFFF)) return false;
    i += static_cast<std::size_t>(more) + 1;
  }
  return true;
}

std::string dumpJson(const json& j) { return j.dump(-1, ' ', false, json::error_handler_t::replace); }

Parsed<json> parseJsonText(const std::string& text, const std::string& label) {
  // Nesting capped while parsing (nlohmann's parser is iterative; copies and
  // dumps of what it builds recurse once per level: 100,000 levels of
  // spec.options overflowed a server thread's stack). The rule of core's
  // readers (core/io/json_text.h), which api does not include.
  struct TooDeep {};
  try {
    return json::parse(text, [](int depth, json::parse_event_t event, json&) {
      if ((event == json::parse_event_t::object_start || event == json::parse_event_t::array_start) &&
          depth >= kMaxJsonDepth) {
        throw TooDeep{};
      }
      return true;
    });
  } catch (const TooDeep&) {
    return label + ": JSON nested deeper than " + std::to_string(kMaxJsonDepth) + " levels";
  } catch (const json::parse_error& e) {
    return label + ": not valid JSON (byte " + std::to_string(e.byte) + ")";
  } catch (const json::exception& e) {  // a number out of range (1e400) and the like
    return label + ": not valid JSON (" + e.what() + ")";
  }
}

}  // namespace api
