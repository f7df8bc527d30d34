// The "bake_presets" job option: see preset_bake.h.

#include "core/jobs/preset_bake.h"

#include <nlohmann/json.hpp>

#include "core/components/bake.h"

namespace core {

Result<PresetBake> parsePresetBake(std::string_view value_json, const std::string& where) {
  const nlohmann::json value = nlohmann::json::parse(value_json, nullptr, false);
  PresetBake bake;
  if (value.is_boolean()) {
    bake.enabled = value.get<bool>();
    return bake;
  }
  if (!value.is_array()) {
    return makeError(ErrorCode::kInvalidArgument, where + " must be true, false or an array of preset names");
  }
  for (std::size_t i = 0; i < value.size(); ++i) {
    if (!value[i].is_string() || value[i].get<std::string>().empty()) {
      return makeError(ErrorCode::kInvalidArgument, where + "[" + std::to_string(i) + "] must be a preset name");
    }
    bake.presets.push_back(value[i].get<std::string>());
  }
  if (bake.presets.empty()) return makeError(ErrorCode::kInvalidArgument, where + " names no preset (true bakes them all)");
  bake.enabled = true;
  return bake;
}

std::string presetBakeJson(const PresetBake& bake) {
  if (!bake.enabled || bake.presets.empty()) return nlohmann::json(bake.enabled).dump();
  return nlohmann::json(bake.presets).dump();
}

Status applyPresetBake(const PresetBake& bake, Rig& rig, const std::optional<ComponentsDocument>& components,
                       std::vector<std::string>& warnings) {
  if (!bake.enabled) return Ok{};
  if (!components) {
    return makeError(ErrorCode::kInvalidArgument,
                     "bake_presets: the rig has no components document to bake presets from");
  }
  auto baked = bakePresets(rig, *components, bake.presets);
  if (!baked) return makeError(baked.error().code, "bake_presets: " + baked.error().message);
  for (std::string& warning : baked->warnings) warnings.push_back(std::move(warning));
  return Ok{};
}

}  // namespace core
