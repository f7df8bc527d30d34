// core::Material -> glTF: images (embedded in the buffer), samplers,
// textures and materials; a mesh of several materials as one primitive per
// material, all drawing the same vertex accessors (the reader merges them
// back into one mesh, vertex for vertex). addMaterials, splitByMaterial.
#include "core/io/gltf_model.h"

namespace core::gltf {

namespace {

std::vector<double> toVector(const Eigen::VectorXd& values) { return {values.data(), values.data() + values.size()}; }

// Textures are (image, sampler) pairs, each written once.
struct TextureTable {
  std::vector<TextureSampler> samplers;
  std::map<std::pair<int, int>, int> textures;
};

int textureIndex(tinygltf::Model& model, TextureTable& table, const TextureBinding& binding, int first_image) {
  int sampler = -1;
  if (binding.sampler != TextureSampler{}) {
    const auto found = std::find(table.samplers.begin(), table.samplers.end(), binding.sampler);
    sampler = static_cast<int>(found - table.samplers.begin());
    if (found == table.samplers.end()) {
      table.samplers.push_back(binding.sampler);
      tinygltf::Sampler s;
      s.magFilter = binding.sampler.mag_filter;
      s.minFilter = binding.sampler.min_filter;
      s.wrapS = binding.sampler.wrap_s;
      s.wrapT = binding.sampler.wrap_t;
      model.samplers.push_back(s);
    }
  }
  const std::pair<int, int> key{binding.image, sampler};
  if (const auto found = table.textures.find(key); found != table.textures.end()) return found->second;
  tinygltf::Texture texture;
  texture.source = first_image + binding.image;
  texture.sampler = sampler;
  model.textures.push_back(texture);
  const int index = static_cast<int>(model.textures.size()) - 1;
  table.textures[key] = index;
  return index;
}

template <class Info>
void setTextureInfo(tinygltf::Model& model, TextureTable& table, const std::optional<TextureBinding>& binding,
                    int first_image, Info& info) {
  if (!binding) return;
  info.index = textureIndex(model, table, *binding, first_image);
  info.texCoord = binding->texcoord;
}

tinygltf::Material toGltfMaterial(tinygltf::Model& model, TextureTable& table, const Material& m, int first_image) {
  tinygltf::Material g;
  g.name = m.name;
  g.pbrMetallicRoughness.baseColorFactor = toVector(m.base_color_factor);
  g.pbrMetallicRoughness.metallicFactor = m.metallic_factor;
  g.pbrMetallicRoughness.roughnessFactor = m.roughness_factor;
  g.emissiveFactor = toVector(m.emissive_factor);
  g.alphaMode = m.alpha_mode;
  g.alphaCutoff = m.alpha_cutoff;
  g.doubleSided = m.double_sided;
  setTextureInfo(model, table, m.base_color_texture, first_image, g.pbrMetallicRoughness.baseColorTexture);
  setTextureInfo(model, table, m.metallic_roughness_texture, first_image, g.pbrMetallicRoughness.metallicRoughnessTexture);
  setTextureInfo(model, table, m.normal_texture, first_image, g.normalTexture);
  if (m.normal_texture) g.normalTexture.scale = m.normal_texture->scale;
  setTextureInfo(model, table, m.occlusion_texture, first_image, g.occlusionTexture);
  if (m.occlusion_texture) g.occlusionTexture.strength = m.occlusion_texture->scale;
  setTextureInfo(model, table, m.emissive_texture, first_image, g.emissiveTexture);
  return g;
}

}  // namespace

void addMaterials(tinygltf::Model& model, const Rig& rig) {
  const int first_image = static_cast<int>(model.images.size());
  for (const TextureImage& image : rig.images) {
    tinygltf::Image g;
    g.name = image.name;
    g.mimeType = image.mime_type;
    g.bufferView = addBufferView(model, {image.bytes.data(), image.bytes.size()}, /*target=*/0);
    model.images.push_back(std::move(g));
  }
  TextureTable table;
  for (const Material& material : rig.materials) {
    model.materials.push_back(toGltfMaterial(model, table, material, first_image));
  }
}

std::vector<tinygltf::Primitive> splitByMaterial(tinygltf::Model& model, const tinygltf::Primitive& primitive,
                                                 const Mesh& mesh, const std::vector<int>& triangle_materials) {
  // Groups in order of first use: a mesh read from primitives (each one
  // material, triangles contiguous) is written back in its triangle order.
  std::vector<std::pair<int, std::vector<std::uint32_t>>> groups;
  for (Eigen::Index f = 0; f < mesh.triangleCount(); ++f) {
    const int material = triangle_materials[static_cast<std::size_t>(f)];
    auto group = std::find_if(groups.begin(), groups.end(), [&](const auto& g) { return g.first == material; });
    if (group == groups.end()) group = groups.insert(groups.end(), {material, {}});
    for (int k = 0; k < 3; ++k) group->second.push_back(static_cast<std::uint32_t>(mesh.triangles(f, k)));
  }
  std::vector<tinygltf::Primitive> primitives;
  for (const auto& [material, indices] : groups) {
    tinygltf::Primitive split = primitive;
    const int view = addBufferView(model, asBytes(indices), TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER);
    split.indices = addAccessor(model, view, TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT, TINYGLTF_TYPE_SCALAR, indices.size());
    split.material = material;
    split.mode = TINYGLTF_MODE_TRIANGLES;
    primitives.push_back(std::move(split));
  }
  return primitives;
}

}  // namespace core::gltf
