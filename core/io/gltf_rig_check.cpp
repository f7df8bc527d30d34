// glTF rig writing, the checks first: every rule the validator enforces that
// the Rig type does not (nodes, skin, morph targets, parts), so a rig that
// passes writes a valid file. checkRig.

#include "core/io/gltf_model.h"

namespace core::gltf {

std::string nodeName(const Rig& rig, int node) {
  return "node " + std::to_string(node) + quoted(rig.nodes[static_cast<std::size_t>(node)].name);
}

namespace {

Status checkRigNodes(const Rig& rig) {
  const int n = static_cast<int>(rig.nodes.size());
  for (int i = 0; i < n; ++i) {
    const Node& node = rig.nodes[static_cast<std::size_t>(i)];
    if (node.parent < -1 || node.parent >= n || node.parent == i) {
      return invalidRig(nodeName(rig, i) + " has parent " + std::to_string(node.parent) + ", not another node");
    }
    if (!node.translation.allFinite() || !node.rotation.coeffs().allFinite() || !node.scale.allFinite()) {
      return invalidRig(nodeName(rig, i) + " has a non-finite transform");
    }
    if (!(node.rotation.norm() > 0.0)) return invalidRig(nodeName(rig, i) + " has a zero rotation quaternion");
  }
  for (int i = 0; i < n; ++i) {  // every parent is a node index now
    int steps = 0;
    for (int p = rig.nodes[static_cast<std::size_t>(i)].parent; p >= 0;
         p = rig.nodes[static_cast<std::size_t>(p)].parent) {
      if (++steps > n) return invalidRig(nodeName(rig, i) + " is in a cycle of parents");
    }
  }
  if (rig.mesh_node < -1 || rig.mesh_node >= n) {
    return invalidRig("mesh_node " + std::to_string(rig.mesh_node) + " is not a node index (or -1)");
  }
  return Ok{};
}

// Skin weights (of the face or a part) are #V by #joints.
Status checkWeightsShape(const SkinWeights& weights, Eigen::Index nv, std::size_t joints) {
  if (weights.rows() != nv || weights.cols() != static_cast<Eigen::Index>(joints)) {
    return invalidRig("skin weights are " + std::to_string(weights.rows()) + " by " + std::to_string(weights.cols()) +
                      ", expected #V " + std::to_string(nv) + " by #joints " + std::to_string(joints));
  }
  return Ok{};
}

Status checkRigSkin(const Rig& rig) {
  const Eigen::Index nv = rig.mesh.vertexCount();
  if (!rig.skin) {
    if (rig.weights.nonZeros() > 0) return invalidRig("it has skin weights but no skin");
    return Ok{};
  }
  const Skin& skin = *rig.skin;
  const std::size_t count = skin.joints.size();
  if (count == 0 || count > 65536) return invalidRig("the skin has " + std::to_string(count) + " joints (1..65536)");
  std::vector<char> used(rig.nodes.size(), 0);
  for (std::size_t j = 0; j < count; ++j) {
    const int node = skin.joints[j];
    if (node < 0 || static_cast<std::size_t>(node) >= rig.nodes.size()) {
      return invalidRig("skin joint " + std::to_string(j) + " is node " + std::to_string(node) + " but the rig has " +
                        std::to_string(rig.nodes.size()) + " nodes");
    }
    if (used[static_cast<std::size_t>(node)]) {
      return invalidRig("skin joint " + std::to_string(j) + " repeats " + nodeName(rig, node));
    }
    used[static_cast<std::size_t>(node)] = 1;
  }
  if (skin.inverse_bind.size() != count) {
    return invalidRig("the skin has " + std::to_string(count) + " joints but " +
                      std::to_string(skin.inverse_bind.size()) + " inverse bind matrices");
  }
  for (std::size_t j = 0; j < count; ++j) {
    const Eigen::Matrix4d& m = skin.inverse_bind[j];
    const std::string joint = "skin joint " + std::to_string(j) + " (" + nodeName(rig, skin.joints[j]) + ")";
    if (!m.allFinite() || !m.cast<float>().allFinite()) {
      return invalidRig(joint + " inverse bind matrix is not finite in float32");
    }
    if ((m.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).cwiseAbs().maxCoeff() > 1e-9) {
      return invalidRig(joint + " inverse bind matrix bottom row is not 0 0 0 1");
    }
  }
  if (skin.skeleton < -1 || skin.skeleton >= static_cast<int>(rig.nodes.size())) {
    return invalidRig("skin skeleton " + std::to_string(skin.skeleton) + " is not a node index (or -1)");
  }
  return checkWeightsShape(rig.weights, nv, count);
}

// The morph targets of one mesh (the face or a part) and their default weights.
Status checkMorphTargets(const Mesh& mesh, const std::vector<MorphTarget>& targets, const Eigen::VectorXd& defaults) {
  const Eigen::Index nv = mesh.vertexCount();
  const std::size_t count = targets.size();
  for (std::size_t t = 0; t < count; ++t) {
    const MorphTarget& target = targets[t];
    const std::string what = "morph target " + std::to_string(t) + quoted(target.name);
    if (target.position_deltas.rows() != nv) {
      return invalidRig(what + " has " + std::to_string(target.position_deltas.rows()) + " position deltas for " +
                        std::to_string(nv) + " vertices");
    }
    if (target.normal_deltas.rows() != 0 && target.normal_deltas.rows() != nv) {
      return invalidRig(what + " has " + std::to_string(target.normal_deltas.rows()) + " normal deltas for " +
                        std::to_string(nv) + " vertices");
    }
    if (target.normal_deltas.rows() > 0 && mesh.normals.rows() == 0) {
      return invalidRig(what + " has normal deltas but the mesh has no normals");
    }
  }
  if ((defaults.size() != 0 && defaults.size() != static_cast<Eigen::Index>(count)) || !defaults.allFinite()) {
    return invalidRig("morph_default_weights has " + std::to_string(defaults.size()) + " values for " +
                      std::to_string(count) + " morph targets (or is not finite)");
  }
  return Ok{};
}

Status checkRigMorphTargets(const Rig& rig) {
  if (auto ok = checkMorphTargets(rig.mesh, rig.morph_targets, rig.morph_default_weights); !ok) return ok;
  for (const std::string& baked : rig.baked_presets) {
    const bool known = std::any_of(rig.morph_targets.begin(), rig.morph_targets.end(),
                                   [&](const MorphTarget& t) { return t.name == baked; });
    if (!known) return invalidRig("baked preset '" + baked + "' is not a morph target of the face");
  }
  return Ok{};
}

Status checkMaterial(const Rig& rig, const Material& m, const std::string& what) {
  if (!m.base_color_factor.allFinite() || !m.emissive_factor.allFinite() || !std::isfinite(m.metallic_factor) ||
      !std::isfinite(m.roughness_factor) || !std::isfinite(m.alpha_cutoff)) {
    return invalidRig(what + " has a non-finite factor");
  }
  if (m.alpha_mode != "OPAQUE" && m.alpha_mode != "MASK" && m.alpha_mode != "BLEND") {
    return invalidRig(what + " alpha_mode is '" + m.alpha_mode + "' (OPAQUE, MASK or BLEND)");
  }
  for (const auto* binding : {&m.base_color_texture, &m.metallic_roughness_texture, &m.normal_texture,
                              &m.occlusion_texture, &m.emissive_texture}) {
    if (!*binding) continue;
    if ((*binding)->image < 0 || (*binding)->image >= static_cast<int>(rig.images.size())) {
      return invalidRig(what + " uses image " + std::to_string((*binding)->image) + " but the rig has " +
                        std::to_string(rig.images.size()));
    }
    if ((*binding)->texcoord < 0 || !std::isfinite((*binding)->scale)) {
      return invalidRig(what + " has a texture with texcoord " + std::to_string((*binding)->texcoord) +
                        " or a non-finite scale");
    }
  }
  return Ok{};
}

// The UV sets a mesh has: TEXCOORD_0 (Mesh::uvs) and the extra ones.
int uvSetCount(const Mesh& mesh, const VertexAttributes& attributes) {
  return mesh.uvs.rows() > 0 ? 1 + static_cast<int>(attributes.extra_uv_sets.size()) : 0;
}

// One material per triangle (or none), each a material of the rig whose
// textures read UV sets the mesh has (the validator requires them).
Status checkTriangleMaterials(const Rig& rig, const Mesh& mesh, const VertexAttributes& attributes,
                              const std::vector<int>& triangle_materials) {
  if (triangle_materials.empty()) return Ok{};
  if (static_cast<Eigen::Index>(triangle_materials.size()) != mesh.triangleCount()) {
    return invalidRig("triangle_materials has " + std::to_string(triangle_materials.size()) + " entries for " +
                      std::to_string(mesh.triangleCount()) + " triangles");
  }
  std::set<int> used(triangle_materials.begin(), triangle_materials.end());
  for (const int m : used) {
    if (m < -1 || m >= static_cast<int>(rig.materials.size())) {
      return invalidRig("a triangle uses material " + std::to_string(m) + " but the rig has " +
                        std::to_string(rig.materials.size()));
    }
    if (m < 0) continue;
    const Material& material = rig.materials[static_cast<std::size_t>(m)];
    for (const auto* binding : {&material.base_color_texture, &material.metallic_roughness_texture,
                                &material.normal_texture, &material.occlusion_texture, &material.emissive_texture}) {
      if (*binding && (*binding)->texcoord >= uvSetCount(mesh, attributes)) {
        return invalidRig("material " + std::to_string(m) + quoted(material.name) + " reads TEXCOORD_" +
                          std::to_string((*binding)->texcoord) + " but the mesh has " +
                          std::to_string(uvSetCount(mesh, attributes)) + " UV sets");
      }
    }
  }
  return Ok{};
}

Status checkRigMaterials(const Rig& rig) {
  for (std::size_t i = 0; i < rig.images.size(); ++i) {
    const TextureImage& image = rig.images[i];
    if (image.bytes.empty() || (image.mime_type != "image/png" && image.mime_type != "image/jpeg")) {
      return invalidRig("image " + std::to_string(i) + quoted(image.name) + " is empty or not image/png or image/jpeg");
    }
  }
  for (std::size_t m = 0; m < rig.materials.size(); ++m) {
    if (auto ok = checkMaterial(rig, rig.materials[m], "material " + std::to_string(m) + quoted(rig.materials[m].name)); !ok) {
      return ok;
    }
  }
  return checkTriangleMaterials(rig, rig.mesh, rig.attributes, rig.triangle_materials);
}

}  // namespace

Status checkRig(const Rig& rig, const RigWriteOptions& options) {
  if (options.max_influences < 1 || options.max_influences > 8) {
    return invalidRig("max_influences is " + std::to_string(options.max_influences) + " (1..8)");
  }
  if (auto ok = validateMesh(rig.mesh, kRigLabel); !ok) return ok.error();
  if (rig.mesh.vertexCount() == 0) return makeError(ErrorCode::kInvalidMesh, kRigLabel + ": the mesh has no vertices");
  if (auto ok = checkRigNodes(rig); !ok) return ok.error();
  if (auto ok = checkRigSkin(rig); !ok) return ok.error();
  if (auto ok = checkRigMorphTargets(rig); !ok) return ok.error();
  if (auto ok = checkRigMaterials(rig); !ok) return ok.error();
  for (std::size_t p = 0; p < rig.parts.size(); ++p) {
    const RigPart& part = rig.parts[p];
    const std::string what = "part " + std::to_string(p) + quoted(part.name);
    if (part.node < 0 || part.node >= static_cast<int>(rig.nodes.size()) || part.node == rig.mesh_node) {
      return invalidRig(what + " is on node " + std::to_string(part.node) + ", not a node of its own");
    }
    if (part.weights.size() > 0 && !rig.skin) return invalidRig(what + " has skin weights but the rig has no skin");
    if (auto ok = validateMesh(part.mesh, kRigLabel + " " + what); !ok) return ok.error();
    // The skin is the face's (checked above); a part without weights follows its node.
    if (part.weights.size() > 0) {
      if (auto ok = checkWeightsShape(part.weights, part.mesh.vertexCount(), rig.skin->joints.size()); !ok) {
        return makeError(ok.error().code, what + ": " + ok.error().message);
      }
    }
    if (auto ok = checkMorphTargets(part.mesh, part.morph_targets, part.morph_default_weights); !ok) {
      return makeError(ok.error().code, what + ": " + ok.error().message);
    }
    if (auto ok = checkTriangleMaterials(rig, part.mesh, part.attributes, part.triangle_materials); !ok) {
      return makeError(ok.error().code, what + ": " + ok.error().message);
    }
  }
  for (std::size_t p = 0; p < rig.parts.size(); ++p) {
    for (std::size_t q = 0; q < p; ++q) {
      if (rig.parts[p].node == rig.parts[q].node) {
        return invalidRig("parts " + std::to_string(q) + " and " + std::to_string(p) + " are on one node");
      }
    }
  }
  return Ok{};
}

}  // namespace core::gltf
