// The rig components document (docs/COMPONENTS.md) in JSON:
//   {"format": "rigport.components", "version": 1, "locators": [...], "clusters": [...],
//    "point_constraints": [...], "aim_constraints": [...], "curves": [...], "surfaces": [...],
//    "wires": [...], "lattices": [...], "push_to_surfaces": [...], "muscles": [...],
//    "crease_clusters": [...], "controls": [...], "presets": {"smile": {"controls": {"mouth_smile": 1.0}}}}
// Unknown keys are errors; every message names the file, the component and the field.
#pragma once

#include <filesystem>
#include <string>
#include <string_view>

#include "core/base/error.h"
#include "core/components/components.h"
#include "core/geometry/mesh.h"

namespace core {

// Parses and validates (validateComponents without mesh counts; check index
// ranges against a mesh with validate()). `label` (the file name) starts every message.
Result<ComponentsDocument> parseComponents(std::string_view json_text, const std::string& label);
Result<ComponentsDocument> readComponents(const std::filesystem::path& path);

// A rig's document: parsed and checked against the rig's face (vertex and
// face indices in range), as an upload, a transfer or a fit takes it.
Result<ComponentsDocument> parseRigComponents(std::string_view json_text, const std::string& label, const Mesh& face);
Result<ComponentsDocument> readRigComponents(const std::filesystem::path& path, const Mesh& face);

// The document as JSON (deterministic; defaults written out; rotations as
// quaternions). parseComponents(formatComponents(doc)) == doc.
std::string formatComponents(const ComponentsDocument& doc);

}  // namespace core
