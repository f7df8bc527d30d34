// Fit options JSON (the `--options opts.json` file of `rigport fit`, and the
// "options" of a fit job spec on the service):
//   {"alignment": "auto", "units": "auto", "frame": "scan",
//    "max_yaw_deg": 60, "max_tilt_deg": 15,
//    "schedule": [{"stiffness": 100, "iterations": 3, "max_distance": 0.03,
//                  "max_normal_angle_deg": 70, "landmark_weight": 200, "point_share": 1}, ...],
//    "binding_weight": 10, "rim_stiffness": 10, "rim_weight": 1,
//    "reject_borders": true, "reject_spikes": true,
//    "components": {"weights": true, "joints": true, "shapes": true,
//                   "animations": true, "attributes": true},
//    "adaptation": "rotation", "max_influences": 4, "weight_encoding": "float",
//    "diagnostic_attributes": false, "strict": false}
// Unknown keys are errors, as for transfers.
#pragma once

#include <string>

#include "core/base/error.h"
#include "core/fit/fit.h"
#include "core/jobs/preset_bake.h"
#include "core/io/rig_io.h"

namespace core {

struct FitSettings {
  FitOptions fit;
  RigWriteOptions write;
  PresetBake bake;  // "bake_presets"
};

// `label` names the options' source (file name, or "spec.options") in every message.
Result<FitSettings> parseFitOptions(const std::string& json_text, const std::string& label);
// Every option with its value, as parseFitOptions reads them back (normalised).
std::string fitOptionsJson(const FitSettings& settings);

}  // namespace core
