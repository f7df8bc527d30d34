// Transfer options JSON (the `--options opts.json` file of `rigport transfer`,
// and the "options" of a transfer job spec on the service):
//   {"components": {"weights": true, "joints": true, "shapes": true,
//                   "animations": true, "attributes": true},
//    "uvs": false, "max_influences": 4, "weight_encoding": "float",
//    "low_confidence_distance": 0.05, "low_confidence_angle_deg": 30,
//    "adaptation": "rotation", "exaggeration": 1.0,
//    "shape_exaggeration": {"jawOpen": 1.5}, "joint_exaggeration": {"jaw": 1.2},
//    "diagnostic_attributes": false, "refine_iterations": 2,
//    "region_matching": true, "rim_matching": true, "slide_centres": true,
//    "target_pulls": true, "smooth_guide": true, "side_matching": true,
//    "strict": false, "repair_unsure": true, "correspondence": "warp",
//    "bake_presets": false}   (true, or ["joy", ...]: core/jobs/preset_bake.h)
// Unknown keys are errors (a typo must not be silently ignored). nlohmann is
// used privately in the .cpp, as in core/jobs/diagnostics_json.cpp.
#pragma once

#include <string>

#include "core/base/error.h"
#include "core/io/rig_io.h"
#include "core/jobs/preset_bake.h"
#include "core/transfer/transfer.h"

namespace core {

// What locates the target's vertices on the source: the warp (the dense
// refinement of `rigport warp`, default), or a fit of the source onto the
// target as onto a scan (core/fit; docs/FIT.md, "The fit as a correspondence").
enum class CorrespondenceMethod { kWarp, kFit };
const char* correspondenceMethodName(CorrespondenceMethod method);  // "warp", "fit"

struct TransferSettings {
  TransferOptions transfer;
  RigWriteOptions write;
  CorrespondenceMethod correspondence = CorrespondenceMethod::kWarp;
  PresetBake bake;  // "bake_presets"
};

// `label` names the source (file name, or "spec.options") in every message.
Result<TransferSettings> parseTransferOptions(const std::string& json_text, const std::string& label);
// Every option with its value, as parseTransferOptions reads them back: the
// settings normalised (the defaults: transferOptionsJson of "{}" parsed).
std::string transferOptionsJson(const TransferSettings& settings);

}  // namespace core
