// glTF materials -> core::Material: factors, alpha, textures with their
// samplers and images (kept encoded), and which material each triangle of a
// mesh uses. readMaterials, triangleMaterials.
#include "core/io/gltf_model.h"

namespace core::gltf {

namespace {

// glTF core images are PNG or JPEG (spec "Images"); told by their signature,
// as the declared mimeType of a data: URI is often octet-stream.
std::string imageMimeType(const std::vector<unsigned char>& bytes) {
  static constexpr unsigned char kPng[] = {0x89, 'P', 'N', 'G', 0x0D, 0x0A, 0x1A, 0x0A};
  if (bytes.size() >= 8 && std::equal(std::begin(kPng), std::end(kPng), bytes.begin())) return "image/png";
  if (bytes.size() >= 3 && bytes[0] == 0xFF && bytes[1] == 0xD8 && bytes[2] == 0xFF) return "image/jpeg";
  return {};
}

bool finiteVector(const std::vector<double>& values, std::size_t size) {
  return values.size() == size && std::all_of(values.begin(), values.end(), [](double v) { return std::isfinite(v); });
}

// A texture slot: the texture's image (when kept) and sampler; nullopt (with a
// warning) when the texture or its image cannot be carried.
std::optional<TextureBinding> readBinding(const tinygltf::Model& model, int texture, int texcoord, double scale,
                                          const std::vector<int>& image_index, const std::string& what,
                                          std::vector<std::string>& warnings) {
  if (texture < 0) return std::nullopt;
  if (static_cast<std::size_t>(texture) >= model.textures.size()) {
    warnings.push_back(what + " refers to texture " + std::to_string(texture) + " but the file has " +
                       std::to_string(model.textures.size()) + "; the slot was dropped");
    return std::nullopt;
  }
  const tinygltf::Texture& gtexture = model.textures[static_cast<std::size_t>(texture)];
  const int source = gtexture.source;
  if (source < 0 || static_cast<std::size_t>(source) >= image_index.size() || image_index[static_cast<std::size_t>(source)] < 0) {
    warnings.push_back(what + " uses texture " + std::to_string(texture) + " whose image is not embedded; the slot was dropped");
    return std::nullopt;
  }
  TextureBinding binding;
  binding.image = image_index[static_cast<std::size_t>(source)];
  binding.texcoord = std::max(0, texcoord);
  binding.scale = std::isfinite(scale) ? scale : 1.0;
  if (gtexture.sampler >= 0 && static_cast<std::size_t>(gtexture.sampler) < model.samplers.size()) {
    const tinygltf::Sampler& s = model.samplers[static_cast<std::size_t>(gtexture.sampler)];
    binding.sampler = {s.magFilter, s.minFilter, s.wrapS, s.wrapT};
  }
  return binding;
}

Material readMaterial(const tinygltf::Model& model, const tinygltf::Material& gmaterial, std::size_t index,
                      const std::vector<int>& image_index, std::vector<std::string>& warnings) {
  const std::string what = "material " + std::to_string(index) + quoted(gmaterial.name);
  const tinygltf::PbrMetallicRoughness& pbr = gmaterial.pbrMetallicRoughness;
  Material m;
  m.name = gmaterial.name;
  if (finiteVector(pbr.baseColorFactor, 4)) {
    m.base_color_factor = Eigen::Vector4d(pbr.baseColorFactor[0], pbr.baseColorFactor[1], pbr.baseColorFactor[2],
                                          pbr.baseColorFactor[3]);
  }
  if (std::isfinite(pbr.metallicFactor)) m.metallic_factor = std::clamp(pbr.metallicFactor, 0.0, 1.0);
  if (std::isfinite(pbr.roughnessFactor)) m.roughness_factor = std::clamp(pbr.roughnessFactor, 0.0, 1.0);
  if (finiteVector(gmaterial.emissiveFactor, 3)) {
    m.emissive_factor = Eigen::Vector3d(gmaterial.emissiveFactor[0], gmaterial.emissiveFactor[1], gmaterial.emissiveFactor[2]);
  }
  if (gmaterial.alphaMode == "MASK" || gmaterial.alphaMode == "BLEND") m.alpha_mode = gmaterial.alphaMode;
  if (std::isfinite(gmaterial.alphaCutoff) && gmaterial.alphaCutoff >= 0.0) m.alpha_cutoff = gmaterial.alphaCutoff;
  m.double_sided = gmaterial.doubleSided;
  m.base_color_texture = readBinding(model, pbr.baseColorTexture.index, pbr.baseColorTexture.texCoord, 1.0,
                                     image_index, what + " baseColorTexture", warnings);
  m.metallic_roughness_texture =
      readBinding(model, pbr.metallicRoughnessTexture.index, pbr.metallicRoughnessTexture.texCoord, 1.0, image_index,
                  what + " metallicRoughnessTexture", warnings);
  m.normal_texture = readBinding(model, gmaterial.normalTexture.index, gmaterial.normalTexture.texCoord,
                                 gmaterial.normalTexture.scale, image_index, what + " normalTexture", warnings);
  m.occlusion_texture = readBinding(model, gmaterial.occlusionTexture.index, gmaterial.occlusionTexture.texCoord,
                                    gmaterial.occlusionTexture.strength, image_index, what + " occlusionTexture", warnings);
  m.emissive_texture = readBinding(model, gmaterial.emissiveTexture.index, gmaterial.emissiveTexture.texCoord, 1.0,
                                   image_index, what + " emissiveTexture", warnings);
  if (!gmaterial.extensions.empty()) {
    warnings.push_back(what + " uses extensions (" + gmaterial.extensions.begin()->first +
                       (gmaterial.extensions.size() > 1 ? ", ..." : "") + ") that are not carried");
  }
  return m;
}

}  // namespace

void readMaterials(const tinygltf::Model& model, Rig& rig, std::vector<std::string>& warnings) {
  // Images kept encoded by the loader (gltf_parse.cpp); an external file is
  // never read here, so a texture on one cannot be carried.
  std::vector<int> image_index(model.images.size(), -1);
  for (std::size_t i = 0; i < model.images.size(); ++i) {
    const tinygltf::Image& image = model.images[i];
    if (image.image.empty()) {
      warnings.push_back("image " + std::to_string(i) + quoted(image.name) +
                         (image.uri.empty() ? std::string(" is empty") : " is the external file '" + image.uri + "'") +
                         "; textures using it are dropped (embed images in the GLB to keep them)");
      continue;
    }
    const std::string mime_type = imageMimeType(image.image);
    if (mime_type.empty()) {
      warnings.push_back("image " + std::to_string(i) + quoted(image.name) +
                         " is neither PNG nor JPEG; textures using it are dropped");
      continue;
    }
    image_index[i] = static_cast<int>(rig.images.size());
    rig.images.push_back({image.name, mime_type, image.image});
  }
  for (std::size_t m = 0; m < model.materials.size(); ++m) {
    rig.materials.push_back(readMaterial(model, model.materials[m], m, image_index, warnings));
  }
}

std::vector<int> triangleMaterials(const tinygltf::Model& model, const tinygltf::Mesh& gmesh, Eigen::Index triangles,
                                   const std::string& mesh_name, std::vector<std::string>& warnings) {
  const bool any = std::any_of(gmesh.primitives.begin(), gmesh.primitives.end(),
                               [](const tinygltf::Primitive& p) { return p.material >= 0; });
  if (!any) return {};
  std::vector<int> per_triangle;
  per_triangle.reserve(static_cast<std::size_t>(triangles));
  for (std::size_t p = 0; p < gmesh.primitives.size(); ++p) {
    const tinygltf::Primitive& primitive = gmesh.primitives[p];
    int material = primitive.material;
    if (material >= static_cast<int>(model.materials.size())) {
      warnings.push_back(mesh_name + " primitive " + std::to_string(p) + " refers to material " +
                         std::to_string(material) + " but the file has " + std::to_string(model.materials.size()) +
                         "; drawn without one");
      material = -1;
    }
    per_triangle.insert(per_triangle.end(), primitiveTriangleCount(model, primitive), std::max(-1, material));
  }
  if (static_cast<Eigen::Index>(per_triangle.size()) != triangles) return {};  // cannot happen: buildMesh counted these
  return per_triangle;
}

}  // namespace core::gltf
