// Presets of a rig components document baked into morph targets of the
// rig's face, so that any glTF consumer (Blender, three.js, game engines)
// plays the deformer rig's expressions. A baked target is the preset's posed
// face (evaluatePose) minus the rest, plus the rig's own shapes the preset
// drives (their weights times their deltas). Joint rotations a preset drives
// cannot be held by a morph target: they are named in the warnings. The rig
// records which targets are baked presets (Rig::baked_presets; the GLB's
// mesh.extras), so baking again replaces them.
#pragma once

#include <string>
#include <vector>

#include "core/base/error.h"
#include "core/components/components.h"
#include "core/rig/rig.h"

namespace core {

struct BakeReport {
  std::vector<std::string> baked;     // in the order added (or replaced)
  std::vector<std::string> warnings;  // joint rotations left out, clamped controls
};

// `presets`: the names to bake, all the document's (by name) when empty.
// Errors: an unknown preset ("did you mean"), a preset named like a morph
// target of the rig that is not a baked preset, anything evaluatePose refuses.
// On error the rig is unchanged.
Result<BakeReport> bakePresets(Rig& rig, const ComponentsDocument& doc, const std::vector<std::string>& presets = {});

}  // namespace core
