#include "core/jobs/transfer_options.h"

#include <map>
#include <set>

#include <nlohmann/json.hpp>

#include "core/io/json_text.h"

namespace core {

namespace {


Result<double> number(const nlohmann::json& v, const std::string& where, double lo, double hi) {
  if (!v.is_number()) return makeError(ErrorCode::kInvalidArgument, where + " must be a number");
  const double x = v.get<double>();
  if (!(x >= lo && x <= hi)) {
    return makeError(ErrorCode::kInvalidArgument, where + " must be in [" + std::to_string(lo) + ", " + std::to_string(hi) + "]");
  }
  return x;
}

Result<bool> boolean(const nlohmann::json& v, const std::string& where) {
  if (!v.is_boolean()) return makeError(ErrorCode::kInvalidArgument, where + " must be true or false");
  return v.get<bool>();
}

Status gains(const nlohmann::json& v, const std::string& where, std::map<std::string, double>& out) {
  if (!v.is_object()) return makeError(ErrorCode::kInvalidArgument, where + " must be an object of name: factor");
  for (const auto& [name, value] : v.items()) {
    auto x = number(value, where + "." + name, -100.0, 100.0);
    if (!x) return x.error();
    out[name] = *x;
  }
  return Ok{};
}

// The warp's on/off switches, by their JSON key.
const std::map<std::string, bool WarpOptions::*> kWarpSwitches = {
    {"region_matching", &WarpOptions::region_matching}, {"rim_matching", &WarpOptions::rim_matching},
    {"slide_centres", &WarpOptions::slide_centres},     {"target_pulls", &WarpOptions::target_pulls},
    {"smooth_guide", &WarpOptions::smooth_guide},       {"rim_location", &WarpOptions::rim_location},
    {"side_matching", &WarpOptions::side_matching}};
// GLB weight encodings, by their JSON name.
const std::map<std::string, WeightEncoding> kWeightEncodings = {
    {"float", WeightEncoding::kFloat}, {"unorm16", WeightEncoding::kUnorm16}, {"unorm8", WeightEncoding::kUnorm8}};
// The transfer's own on/off switches.
const std::map<std::string, bool TransferOptions::*> kTransferSwitches = {
    {"uvs", &TransferOptions::uvs},
    {"diagnostic_attributes", &TransferOptions::diagnostic_attributes},
    {"strict", &TransferOptions::strict},
    {"repair_unsure", &TransferOptions::repair_unsure}};

}  // namespace

const char* correspondenceMethodName(CorrespondenceMethod method) {
  return method == CorrespondenceMethod::kFit ? "fit" : "warp";
}

Result<TransferSettings> parseTransferOptions(const std::string& text, const std::string& label) {
  auto parsed = parseJsonText(text, label);
  if (!parsed) return parsed.error();
  const nlohmann::json& doc = *parsed;
  if (!doc.is_object()) return makeError(ErrorCode::kInvalidArgument, label + ": expected a JSON object");
  TransferSettings s;
  TransferOptions& t = s.transfer;
  for (const auto& [key, value] : doc.items()) {
    const std::string where = label + ": '" + key + "'";
    Status ok = Ok{};
    if (key == "components") {
      if (!value.is_object()) return makeError(ErrorCode::kInvalidArgument, where + " must be an object");
      const std::map<std::string, bool*> flags = {{"weights", &t.weights}, {"joints", &t.joints}, {"shapes", &t.shapes},
                                                  {"animations", &t.animations}, {"attributes", &t.attributes}};
      for (const auto& [name, flag] : value.items()) {
        const auto it = flags.find(name);
        if (it == flags.end()) return makeError(ErrorCode::kInvalidArgument, where + ": unknown component '" + name + "'");
        auto b = boolean(flag, where + "." + name);
        if (!b) return b.error();
        *it->second = *b;
      }
    } else if (const auto flag = kTransferSwitches.find(key); flag != kTransferSwitches.end()) {
      auto b = boolean(value, where);
      if (!b) return b.error();
      t.*(flag->second) = *b;
    } else if (key == "max_influences") {
      auto x = number(value, where, 1, 8);
      if (!x) return x.error();
      t.weight_options.max_influences = static_cast<int>(*x);
      s.write.max_influences = static_cast<int>(*x);
    } else if (key == "weight_encoding") {
      const auto e = kWeightEncodings.find(value.is_string() ? value.get<std::string>() : "");
      if (e == kWeightEncodings.end()) {
        return makeError(ErrorCode::kInvalidArgument, where + " must be \"float\", \"unorm16\" or \"unorm8\"");
      }
      s.write.weight_encoding = e->second;
    } else if (key == "low_confidence_distance") {
      auto x = number(value, where, 0.0, 1.0);
      if (!x) return x.error();
      t.warp.locate.low_confidence_distance = *x;
    } else if (key == "low_confidence_angle_deg") {
      auto x = number(value, where, 0.0, 180.0);
      if (!x) return x.error();
      t.warp.locate.low_confidence_angle_deg = *x;
    } else if (key == "adaptation") {
      const std::string a = value.is_string() ? value.get<std::string>() : "";
      if (a == "none") t.adaptation = ShapeAdaptation::kNone;
      else if (a == "rotation") t.adaptation = ShapeAdaptation::kRotation;
      else if (a == "similarity") t.adaptation = ShapeAdaptation::kSimilarity;
      else if (a == "local") t.adaptation = ShapeAdaptation::kLocal;
      else return makeError(ErrorCode::kInvalidArgument, where + " must be \"none\", \"rotation\", \"similarity\" or \"local\"");
    } else if (key == "correspondence") {
      const std::string m = value.is_string() ? value.get<std::string>() : "";
      if (m == "warp") s.correspondence = CorrespondenceMethod::kWarp;
      else if (m == "fit") s.correspondence = CorrespondenceMethod::kFit;
      else return makeError(ErrorCode::kInvalidArgument, where + " must be \"warp\" or \"fit\"");
    } else if (key == "exaggeration") {
      auto x = number(value, where, -100.0, 100.0);
      if (!x) return x.error();
      t.exaggeration = *x;
    } else if (key == "shape_exaggeration") {
      ok = gains(value, where, t.shape_exaggeration);
    } else if (key == "joint_exaggeration") {
      ok = gains(value, where, t.joint_exaggeration);
    } else if (const auto it = kWarpSwitches.find(key); it != kWarpSwitches.end()) {
      auto b = boolean(value, where);
      if (!b) return b.error();
      t.warp.*(it->second) = *b;
    } else if (key == "bake_presets") {
      auto bake = parsePresetBake(value.dump(), where);
      if (!bake) return bake.error();
      s.bake = std::move(*bake);
    } else if (key == "refine_iterations") {
      auto x = number(value, where, 0, 20);
      if (!x) return x.error();
      t.warp.refine_iterations = static_cast<int>(*x);
    } else {
      std::vector<std::string> known = {"components", "max_influences", "weight_encoding", "low_confidence_distance",
                                        "low_confidence_angle_deg", "adaptation", "correspondence", "exaggeration", "shape_exaggeration",
                                        "joint_exaggeration", "refine_iterations", "bake_presets"};
      for (const auto& [name, member] : kWarpSwitches) known.push_back(name);
      for (const auto& [name, member] : kTransferSwitches) known.push_back(name);
      return makeError(ErrorCode::kInvalidArgument, where + " is not a known option" + didYouMean(key, known, '\''));
    }
    if (!ok) return ok.error();
  }
  return s;
}

std::string transferOptionsJson(const TransferSettings& settings) {
  const TransferOptions& t = settings.transfer;
  nlohmann::json doc;
  doc["components"] = {{"weights", t.weights}, {"joints", t.joints}, {"shapes", t.shapes},
                       {"animations", t.animations}, {"attributes", t.attributes}};
  for (const auto& [name, member] : kTransferSwitches) doc[name] = t.*member;
  for (const auto& [name, member] : kWarpSwitches) doc[name] = t.warp.*member;
  doc["max_influences"] = settings.write.max_influences;
  for (const auto& [name, encoding] : kWeightEncodings) {
    if (encoding == settings.write.weight_encoding) doc["weight_encoding"] = name;
  }
  doc["low_confidence_distance"] = t.warp.locate.low_confidence_distance;
  doc["low_confidence_angle_deg"] = t.warp.locate.low_confidence_angle_deg;
  doc["adaptation"] = shapeAdaptationName(t.adaptation);
  doc["correspondence"] = correspondenceMethodName(settings.correspondence);
  doc["exaggeration"] = t.exaggeration;
  doc["shape_exaggeration"] = t.shape_exaggeration;
  doc["joint_exaggeration"] = t.joint_exaggeration;
  doc["refine_iterations"] = t.warp.refine_iterations;
  doc["bake_presets"] = nlohmann::json::parse(presetBakeJson(settings.bake));
  return doc.dump();
}

}  // namespace core
