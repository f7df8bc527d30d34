#include "core/jobs/retarget_options.h"

#include <nlohmann/json.hpp>

#include "core/io/json_text.h"

namespace core {

std::optional<DistanceMethod> parseDistanceMethod(std::string_view name) {
  for (auto m : {DistanceMethod::kEuclidean, DistanceMethod::kGeodesic, DistanceMethod::kHybrid}) {
    if (name == distanceMethodName(m)) return m;
  }
  return std::nullopt;
}

std::optional<RbfKernel> parseRbfKernel(std::string_view name) {
  if (name == "thin-plate") name = "thin_plate";  // the CLI's spelling
  for (auto k : {RbfKernel::kGaussian, RbfKernel::kMultiquadric, RbfKernel::kThinPlate, RbfKernel::kLinear}) {
    if (name == rbfKernelName(k)) return k;
  }
  return std::nullopt;
}

Result<RetargetSettings> parseRetargetOptions(const std::string& text, const std::string& label) {
  auto parsed = parseJsonText(text, label);
  if (!parsed) return parsed.error();
  const nlohmann::json& doc = *parsed;
  if (!doc.is_object()) return makeError(ErrorCode::kInvalidArgument, label + ": expected a JSON object");
  RetargetSettings s;
  for (const auto& [key, value] : doc.items()) {
    const std::string where = label + ": '" + key + "'";
    auto bad = [&](const std::string& what) { return makeError(ErrorCode::kInvalidArgument, where + " must be " + what); };
    if (key == "method") {
      const auto m = value.is_string() ? parseDistanceMethod(value.get<std::string>()) : std::nullopt;
      if (!m) return bad("\"euclidean\", \"geodesic\" or \"hybrid\"");
      s.distances.method = *m;
    } else if (key == "kernel") {
      const auto k = value.is_string() ? parseRbfKernel(value.get<std::string>()) : std::nullopt;
      if (!k) return bad("\"gaussian\", \"multiquadric\", \"thin-plate\" or \"linear\"");
      s.retarget.kernel = *k;
    } else if (key == "gamma") {
      if (!value.is_number() || !(value.get<double>() >= 0.0)) return bad("a number >= 0 (model units; 0 = default)");
      s.retarget.gamma = value.get<double>();
    } else if (key == "rest_frame") {
      if (!value.is_number_integer() || value.get<long long>() < 0) return bad("a frame index >= 0");
      s.retarget.rest_frame = value.get<int>();
    } else if (key == "tolerance") {
      if (!value.is_number() || !(value.get<double>() > 0.0 && value.get<double>() < 1.0)) return bad("in (0, 1)");
      s.retarget.bake.tolerance = value.get<double>();
    } else if (key == "exact") {
      if (!value.is_boolean()) return bad("true or false");
      s.retarget.bake.exact = value.get<bool>();
    } else if (key == "keep_head_motion") {
      if (!value.is_boolean()) return bad("true or false");
      s.retarget.remove_head_motion = !value.get<bool>();
    } else if (key == "max_gap_frames") {
      if (!value.is_number_integer() || value.get<long long>() < 0 || value.get<long long>() > 1000000) {
        return bad("a frame count >= 0");
      }
      s.clip.max_gap_frames = value.get<int>();
    } else if (key == "fill_long_gaps") {
      if (!value.is_boolean()) return bad("true or false");
      s.clip.fill_long_gaps = value.get<bool>();
    } else {
      const std::vector<std::string> known = {"method",    "kernel",           "gamma",          "rest_frame",    "tolerance",
                                              "exact",     "keep_head_motion", "max_gap_frames", "fill_long_gaps"};
      return makeError(ErrorCode::kInvalidArgument, where + " is not a known option" + didYouMean(key, known, '\''));
    }
  }
  return s;
}

Result<std::map<std::string, double>> parseStiffness(const std::string& text, const std::string& label) {
  auto parsed = parseJsonText(text, label);
  if (!parsed) return parsed.error();
  const nlohmann::json& doc = *parsed;
  if (!doc.is_object()) return makeError(ErrorCode::kParse, label + ": expected an object {\"marker\": 1-9}");
  std::map<std::string, double> out;
  for (const auto& [name, value] : doc.items()) {
    if (!value.is_number()) return makeError(ErrorCode::kParse, label + ": stiffness of " + name + " is not a number");
    const double stiffness = value.get<double>();
    if (!(stiffness >= 1.0 && stiffness <= 9.0)) {
      return makeError(ErrorCode::kInvalidArgument, label + ": stiffness of " + name + " is " + value.dump() +
                                                        " (the scale is 1-9)");
    }
    out[name] = stiffness;
  }
  return out;
}

std::string retargetOptionsJson(const RetargetSettings& settings) {
  const nlohmann::json doc = {{"method", distanceMethodName(settings.distances.method)},
                              {"kernel", rbfKernelName(settings.retarget.kernel)},
                              {"gamma", settings.retarget.gamma},
                              {"rest_frame", settings.retarget.rest_frame},
                              {"tolerance", settings.retarget.bake.tolerance},
                              {"exact", settings.retarget.bake.exact},
                              {"keep_head_motion", !settings.retarget.remove_head_motion},
                              {"max_gap_frames", settings.clip.max_gap_frames},
                              {"fill_long_gaps", settings.clip.fill_long_gaps}};
  return doc.dump();
}

}  // namespace core
