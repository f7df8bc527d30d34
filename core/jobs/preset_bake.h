// The "bake_presets" option of transfer and fit jobs: the result's
// components presets baked into morph targets of its face (bakePresets,
// core/components/bake.h) before the GLB is written, so the delivered rig
// plays them in any glTF consumer.
//   "bake_presets": false        (default) none
//   "bake_presets": true         every preset of the result's document
//   "bake_presets": ["joy", ...] these
#pragma once

#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "core/base/error.h"
#include "core/components/components.h"
#include "core/rig/rig.h"

namespace core {

struct PresetBake {
  bool enabled = false;
  std::vector<std::string> presets;  // empty: every preset
};

// The option's value as JSON text (the options parsers hand it over so that
// no core header sees nlohmann); `where` names the option in messages
// ("opts.json: 'bake_presets'").
Result<PresetBake> parsePresetBake(std::string_view value_json, const std::string& where);
std::string presetBakeJson(const PresetBake& bake);

// Bakes into `rig` when enabled; its warnings (joint turns not bakeable)
// join `warnings`. Errors: enabled without a document (the rig was given
// none), an unknown preset ("did you mean").
Status applyPresetBake(const PresetBake& bake, Rig& rig, const std::optional<ComponentsDocument>& components,
                       std::vector<std::string>& warnings);

}  // namespace core
