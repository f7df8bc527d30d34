// Retarget options JSON (the "options" of a retarget job spec on the service;
// the CLI's flags map onto the same names):
//   {"method": "hybrid", "kernel": "gaussian", "gamma": 0, "rest_frame": 0,
//    "tolerance": 0.05, "exact": false, "keep_head_motion": false,
//    "max_gap_frames": 10, "fill_long_gaps": true}
// and the stiffness file / multipart field: {"<marker>": 1..9, ...}.
// Unknown keys are errors. nlohmann is used privately in the .cpp.
#pragma once

#include <map>
#include <optional>
#include <string>
#include <string_view>

#include "core/base/error.h"
#include "core/retarget/retarget.h"

namespace core {

struct RetargetSettings {
  MarkerDistanceOptions distances;
  RetargetOptions retarget;
  TrcReadOptions clip;  // how the TRC's gaps are filled
};

std::optional<DistanceMethod> parseDistanceMethod(std::string_view name);  // euclidean | geodesic | hybrid
std::optional<RbfKernel> parseRbfKernel(std::string_view name);           // gaussian | multiquadric | thin_plate (or thin-plate) | linear

// `label` names the source ("spec.options") in every message.
Result<RetargetSettings> parseRetargetOptions(const std::string& json_text, const std::string& label);
// Every option with its value, as parseRetargetOptions reads them back.
std::string retargetOptionsJson(const RetargetSettings& settings);
Result<std::map<std::string, double>> parseStiffness(const std::string& json_text, const std::string& label);

}  // namespace core
