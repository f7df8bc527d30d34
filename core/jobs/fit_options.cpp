#include "core/jobs/fit_options.h"

#include <map>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/io/json_text.h"

namespace core {

namespace {

const std::map<std::string, FitAlignmentMode> kAlignments = {
    {"auto", FitAlignmentMode::kAuto}, {"landmarks", FitAlignmentMode::kLandmarks}, {"search", FitAlignmentMode::kSearch}};
const std::map<std::string, FitFrame> kFrames = {{"scan", FitFrame::kScan}, {"reference", FitFrame::kReference}};
const std::map<std::string, ShapeAdaptation> kAdaptations = {{"none", ShapeAdaptation::kNone},
                                                             {"rotation", ShapeAdaptation::kRotation},
                                                             {"similarity", ShapeAdaptation::kSimilarity},
                                                             {"local", ShapeAdaptation::kLocal}};
const std::map<std::string, WeightEncoding> kWeightEncodings = {
    {"float", WeightEncoding::kFloat}, {"unorm16", WeightEncoding::kUnorm16}, {"unorm8", WeightEncoding::kUnorm8}};
const std::map<std::string, bool FitOptions::*> kSwitches = {{"reject_borders", &FitOptions::reject_borders},
                                                             {"reject_spikes", &FitOptions::reject_spikes},
                                                             {"diagnostic_attributes", &FitOptions::diagnostic_attributes},
                                                             {"strict", &FitOptions::strict}};
struct Range {
  double FitOptions::*member;
  double lo, hi;
};
const std::map<std::string, Range> kNumbers = {{"binding_weight", {&FitOptions::binding_weight, 0.0, 1e6}},
                                               {"rim_stiffness", {&FitOptions::rim_stiffness, 1.0, 1e4}},
                                               {"rim_weight", {&FitOptions::rim_weight, 0.0, 1e4}},
                                               {"normal_matching", {&FitOptions::normal_matching, 0.0, 1.0}}};
const std::map<std::string, bool TransferOptions::*> kComponents = {
    {"weights", &TransferOptions::weights}, {"joints", &TransferOptions::joints}, {"shapes", &TransferOptions::shapes},
    {"animations", &TransferOptions::animations}, {"attributes", &TransferOptions::attributes}};

template <class T>
Result<T> named(const nlohmann::json& v, const std::map<std::string, T>& names, const std::string& where) {
  const auto it = names.find(v.is_string() ? v.get<std::string>() : std::string());
  if (it != names.end()) return it->second;
  std::string list;
  for (const auto& [name, value] : names) list += (list.empty() ? "\"" : ", \"") + name + "\"";
  return makeError(ErrorCode::kInvalidArgument, where + " must be one of " + list);
}

template <class T>
std::string nameOf(const std::map<std::string, T>& names, T value) {
  for (const auto& [name, v] : names) {
    if (v == value) return name;
  }
  return "";
}

Result<double> number(const nlohmann::json& v, const std::string& where, double lo, double hi) {
  if (!v.is_number() || !(v.get<double>() >= lo && v.get<double>() <= hi)) {
    return makeError(ErrorCode::kInvalidArgument, where + " must be a number in [" + std::to_string(lo) + ", " +
                                                      std::to_string(hi) + "]");
  }
  return v.get<double>();
}

// A whole number in [lo, hi] (2.5 iterations is a typo, not 2).
Result<double> count(const nlohmann::json& v, const std::string& where, int lo, int hi) {
  if (!v.is_number_integer()) {
    return makeError(ErrorCode::kInvalidArgument, where + " must be a whole number in [" + std::to_string(lo) + ", " +
                                                      std::to_string(hi) + "]");
  }
  return number(v, where, lo, hi);
}

Result<std::vector<FitStage>> schedule(const nlohmann::json& v, const std::string& where) {
  if (!v.is_array() || v.empty() || v.size() > 20) {
    return makeError(ErrorCode::kInvalidArgument, where + " must be an array of 1 to 20 stages");
  }
  std::vector<FitStage> out;
  for (std::size_t i = 0; i < v.size(); ++i) {
    const std::string at = where + "[" + std::to_string(i) + "]";
    if (!v[i].is_object()) return makeError(ErrorCode::kInvalidArgument, at + " must be an object");
    FitStage stage;
    for (const auto& [key, value] : v[i].items()) {
      const std::string field = at + "." + key;
      Result<double> x = 0.0;
      if (key == "stiffness") x = number(value, field, 1e-3, 1e6);
      else if (key == "iterations") x = count(value, field, 1, 50);
      else if (key == "max_distance") x = number(value, field, 1e-5, 1.0);
      else if (key == "max_normal_angle_deg") x = number(value, field, 1.0, 180.0);
      else if (key == "landmark_weight") x = number(value, field, 0.0, 1e6);
      else if (key == "point_share") x = number(value, field, 0.0, 1.0);
      else return makeError(ErrorCode::kInvalidArgument, field + " is not a stage setting (stiffness, iterations, "
                                                                 "max_distance, max_normal_angle_deg, landmark_weight, "
                                                                 "point_share)");
      if (!x) return x.error();
      if (key == "stiffness") stage.stiffness = *x;
      else if (key == "iterations") stage.iterations = static_cast<int>(*x);
      else if (key == "max_distance") stage.max_distance = *x;
      else if (key == "max_normal_angle_deg") stage.max_normal_angle_deg = *x;
      else if (key == "landmark_weight") stage.landmark_weight = *x;
      else stage.point_share = *x;
    }
    out.push_back(stage);
  }
  return out;
}

}  // namespace

Result<FitSettings> parseFitOptions(const std::string& text, const std::string& label) {
  auto parsed = parseJsonText(text, label);
  if (!parsed) return parsed.error();
  const nlohmann::json& doc = *parsed;
  if (!doc.is_object()) return makeError(ErrorCode::kInvalidArgument, label + ": expected a JSON object");
  FitSettings s;
  FitOptions& f = s.fit;
  for (const auto& [key, value] : doc.items()) {
    const std::string where = label + ": '" + key + "'";
    auto bad = [&](const std::string& what) { return makeError(ErrorCode::kInvalidArgument, where + " must be " + what); };
    if (key == "alignment") {
      auto m = named(value, kAlignments, where);
      if (!m) return m.error();
      f.alignment = *m;
    } else if (key == "units") {
      const std::string u = value.is_string() ? value.get<std::string>() : "";
      if (u != "auto" && u != "mm" && u != "cm" && u != "m" && u != "in") return bad("\"auto\", \"mm\", \"cm\", \"m\" or \"in\"");
      f.units = u;
    } else if (key == "frame") {
      auto m = named(value, kFrames, where);
      if (!m) return m.error();
      f.frame = *m;
    } else if (key == "adaptation") {
      auto m = named(value, kAdaptations, where);
      if (!m) return m.error();
      f.rebuild.adaptation = *m;
    } else if (key == "weight_encoding") {
      auto m = named(value, kWeightEncodings, where);
      if (!m) return m.error();
      s.write.weight_encoding = *m;
    } else if (key == "max_influences") {
      auto x = count(value, where, 1, 8);
      if (!x) return x.error();
      s.write.max_influences = static_cast<int>(*x);
    } else if (key == "max_yaw_deg" || key == "max_tilt_deg") {
      auto x = number(value, where, 0.0, 180.0);
      if (!x) return x.error();
      (key == "max_yaw_deg" ? f.search.max_yaw_deg : f.search.max_tilt_deg) = *x;
    } else if (key == "schedule") {
      auto stages = schedule(value, where);
      if (!stages) return stages.error();
      f.schedule = std::move(*stages);
    } else if (key == "components") {
      if (!value.is_object()) return bad("an object");
      for (const auto& [name, flag] : value.items()) {
        const auto it = kComponents.find(name);
        if (it == kComponents.end()) return makeError(ErrorCode::kInvalidArgument, where + ": unknown component '" + name + "'");
        if (!flag.is_boolean()) return makeError(ErrorCode::kInvalidArgument, where + "." + name + " must be true or false");
        f.rebuild.*(it->second) = flag.get<bool>();
      }
    } else if (key == "bake_presets") {
      auto bake = parsePresetBake(value.dump(), where);
      if (!bake) return bake.error();
      s.bake = std::move(*bake);
    } else if (const auto sw = kSwitches.find(key); sw != kSwitches.end()) {
      if (!value.is_boolean()) return bad("true or false");
      f.*(sw->second) = value.get<bool>();
    } else if (const auto num = kNumbers.find(key); num != kNumbers.end()) {
      auto x = number(value, where, num->second.lo, num->second.hi);
      if (!x) return x.error();
      f.*(num->second.member) = *x;
    } else {
      std::vector<std::string> known = {"alignment", "units", "frame", "adaptation", "weight_encoding", "max_influences",
                                        "max_yaw_deg", "max_tilt_deg", "schedule", "components", "bake_presets"};
      for (const auto& [name, member] : kSwitches) known.push_back(name);
      for (const auto& [name, range] : kNumbers) known.push_back(name);
      return makeError(ErrorCode::kInvalidArgument, where + " is not a known option" + didYouMean(key, known, '\''));
    }
  }
  f.rebuild.weight_options.max_influences = s.write.max_influences;
  return s;
}

std::string fitOptionsJson(const FitSettings& settings) {
  const FitOptions& f = settings.fit;
  nlohmann::json doc;
  doc["alignment"] = nameOf(kAlignments, f.alignment);
  doc["units"] = f.units;
  doc["frame"] = nameOf(kFrames, f.frame);
  doc["adaptation"] = nameOf(kAdaptations, f.rebuild.adaptation);
  doc["weight_encoding"] = nameOf(kWeightEncodings, settings.write.weight_encoding);
  doc["max_influences"] = settings.write.max_influences;
  doc["max_yaw_deg"] = f.search.max_yaw_deg;
  doc["max_tilt_deg"] = f.search.max_tilt_deg;
  nlohmann::json stages = nlohmann::json::array();
  for (const FitStage& s : f.schedule) {
    stages.push_back({{"stiffness", s.stiffness}, {"iterations", s.iterations}, {"max_distance", s.max_distance},
                      {"max_normal_angle_deg", s.max_normal_angle_deg}, {"landmark_weight", s.landmark_weight},
                      {"point_share", s.point_share}});
  }
  doc["schedule"] = stages;
  nlohmann::json components;
  for (const auto& [name, member] : kComponents) components[name] = f.rebuild.*member;
  doc["components"] = components;
  doc["bake_presets"] = nlohmann::json::parse(presetBakeJson(settings.bake));
  for (const auto& [name, member] : kSwitches) doc[name] = f.*member;
  for (const auto& [name, range] : kNumbers) doc[name] = f.*(range.member);
  return doc.dump();
}

}  // namespace core
