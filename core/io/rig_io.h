// Reading and writing rigs (core::Rig) as glTF 2.0 / GLB. Implemented in
// core/io/gltf_*.cpp, the only files that include tiny_gltf.h.
#pragma once

#include <cstdint>
#include <filesystem>
#include <span>
#include <vector>

#include "core/base/error.h"
#include "core/io/mesh_io.h"
#include "core/rig/rig.h"

namespace core {

struct LoadedRig {
  Rig rig;
  MeshReadReport report;  // which mesh was chosen, what was computed or dropped
};

// The rig of the chosen mesh (first skinned, else largest; see readGltf):
// its nodes, skin and weights, morph targets (dense and sparse accessors,
// names from mesh.extras.targetNames), animations and vertex attributes.
Result<LoadedRig> readRig(const std::filesystem::path& path);
Result<LoadedRig> readRigGltf(std::span<const std::uint8_t> bytes, const std::string& label, bool binary);

enum class WeightEncoding {
  kFloat,   // WEIGHTS_n as float32, renormalised to sum 1
  kUnorm16, // normalized unsigned short, quantised sums exactly 65535
  kUnorm8,  // normalized unsigned byte, quantised sums exactly 255
};

struct RigWriteOptions {
  // Influences per vertex, largest kept and renormalised: 4 -> JOINTS_0/WEIGHTS_0, 8 -> also _1 (max 8).
  int max_influences = 4;
  WeightEncoding weight_encoding = WeightEncoding::kFloat;  // WEIGHTS_n component type
  // Morph deltas as sparse accessors when that is smaller (rows exactly 0 omitted).
  bool sparse_morph_targets = true;
};

// One mesh node (with its skin), every rig node, morph targets with
// mesh.extras.targetNames, animations, attributes. Skin rules are enforced:
// weights >= 0, no joint twice per vertex, sums within the validator's
// tolerance, unused slots (joint 0, weight 0), inverse binds with bottom row
// 0 0 0 1. Deterministic bytes.
Result<std::vector<std::uint8_t>> encodeRigGlb(const Rig& rig, const RigWriteOptions& options = {});
Status writeRigGlb(const Rig& rig, const std::filesystem::path& path, const RigWriteOptions& options = {});

}  // namespace core
