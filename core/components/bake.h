// Presets of a rig components document baked into morph targets, so that
// any glTF consumer (Blender, three.js, game engines) plays the deformer
// rig's expressions. A baked target is the preset's pose held by the mesh at
// the rig's rest skeleton minus the rest (poseAtRest, pose_spec.h): the
// components' motion, the rig's own shapes the preset drives (their weights
// times their deltas) and the joints it turns, aims or carries (a jaw
// cluster carrying the jaw joint: the lower teeth open). The face always
// gets the target; a part (teeth, lashes) gets a target of the same name
// when the preset moves it. The rig records which targets are baked presets
// (Rig::baked_presets; the GLB's mesh.extras), so baking again replaces
// them. A consumer that also turns those joints turns them twice.
#pragma once

#include <string>
#include <vector>

#include "core/base/error.h"
#include "core/components/components.h"
#include "core/rig/rig.h"

namespace core {

struct BakeReport {
  std::vector<std::string> baked;     // in the order added (or replaced)
  std::vector<std::string> warnings;  // clamped controls
};

// `presets`: the names to bake, all the document's (by name) when empty.
// Errors: an unknown preset ("did you mean"), a preset named like a morph
// target of the rig (face or part) that is not a baked preset, anything
// poseRig refuses.
// On error the rig is unchanged.
Result<BakeReport> bakePresets(Rig& rig, const ComponentsDocument& doc, const std::vector<std::string>& presets = {});

}  // namespace core
