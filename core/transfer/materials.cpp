#include "core/transfer/materials.h"

#include <algorithm>
#include <map>
#include <set>

namespace core {

namespace {

int mostUsed(const std::vector<int>& values) {
  std::map<int, int> count;
  for (const int v : values) ++count[v];
  return std::max_element(count.begin(), count.end(), [](const auto& a, const auto& b) { return a.second < b.second; })
      ->first;
}

bool hasTextures(const Material& m) {
  return m.base_color_texture || m.metallic_roughness_texture || m.normal_texture || m.occlusion_texture ||
         m.emissive_texture;
}

std::vector<TextureBinding*> bindings(Material& m) {
  std::vector<TextureBinding*> out;
  for (auto* b : {&m.base_color_texture, &m.metallic_roughness_texture, &m.normal_texture, &m.occlusion_texture,
                  &m.emissive_texture}) {
    if (*b) out.push_back(&**b);
  }
  return out;
}

// Drops images no material uses, renumbering the bindings.
void dropUnusedImages(Rig& rig) {
  std::vector<int> new_index(rig.images.size(), -1);
  for (Material& m : rig.materials) {
    for (TextureBinding* b : bindings(m)) new_index[static_cast<std::size_t>(b->image)] = 0;
  }
  std::vector<TextureImage> kept;
  for (std::size_t i = 0; i < rig.images.size(); ++i) {
    if (new_index[i] < 0) continue;
    new_index[i] = static_cast<int>(kept.size());
    kept.push_back(std::move(rig.images[i]));
  }
  rig.images = std::move(kept);
  for (Material& m : rig.materials) {
    for (TextureBinding* b : bindings(m)) b->image = new_index[static_cast<std::size_t>(b->image)];
  }
}

}  // namespace

std::vector<int> carryTriangleMaterials(const std::vector<int>& source_triangle_materials,
                                        const Eigen::MatrixX3i& target_triangles,
                                        const std::vector<SurfacePoint>& on_source) {
  if (source_triangle_materials.empty()) return {};
  const int fallback = mostUsed(source_triangle_materials);
  std::vector<int> out(static_cast<std::size_t>(target_triangles.rows()), fallback);
  for (Eigen::Index f = 0; f < target_triangles.rows(); ++f) {
    std::vector<int> votes;
    for (int k = 0; k < 3; ++k) {
      const SurfacePoint& at = on_source[static_cast<std::size_t>(target_triangles(f, k))];
      if (at.found()) votes.push_back(source_triangle_materials[static_cast<std::size_t>(at.face)]);
    }
    if (!votes.empty()) out[static_cast<std::size_t>(f)] = mostUsed(votes);
  }
  return out;
}

std::vector<std::string> untextureFaceMaterials(Rig& rig) {
  std::set<int> used_by_parts;
  for (const RigPart& part : rig.parts) used_by_parts.insert(part.triangle_materials.begin(), part.triangle_materials.end());
  const std::set<int> used_by_face(rig.triangle_materials.begin(), rig.triangle_materials.end());
  std::vector<std::string> warnings;
  std::map<int, int> replaced;
  for (const int m : used_by_face) {
    if (m < 0 || !hasTextures(rig.materials[static_cast<std::size_t>(m)])) continue;
    Material plain = rig.materials[static_cast<std::size_t>(m)];
    plain.base_color_texture.reset();
    plain.metallic_roughness_texture.reset();
    plain.normal_texture.reset();
    plain.occlusion_texture.reset();
    plain.emissive_texture.reset();
    warnings.push_back("material '" + plain.name +
                       "' of the face has textures laid out on the source's UVs; the target keeps its own UVs, so "
                       "the face gets the material's factors without its textures");
    if (used_by_parts.count(m) > 0) {
      replaced[m] = static_cast<int>(rig.materials.size());
      rig.materials.push_back(std::move(plain));
    } else {
      rig.materials[static_cast<std::size_t>(m)] = std::move(plain);
    }
  }
  for (int& m : rig.triangle_materials) {
    if (const auto it = replaced.find(m); it != replaced.end()) m = it->second;
  }
  dropUnusedImages(rig);
  return warnings;
}

}  // namespace core
