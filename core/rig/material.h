// How a rig's meshes look: glTF 2.0 metallic-roughness materials with their
// textures, kept as read so that a transfer or fit writes the face, eyes and
// teeth back the way the studio shaded them. Plain data; nothing here is
// evaluated (the rig's geometry never depends on it).
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

namespace core {

// An image as its encoded bytes (PNG, JPEG, ...), never decoded.
struct TextureImage {
  std::string name;
  std::string mime_type;           // "image/png", "image/jpeg", ...
  std::vector<std::uint8_t> bytes;
};

// glTF sampler values (filters and wrap modes by their GL enums; -1: unset).
struct TextureSampler {
  int mag_filter = -1;
  int min_filter = -1;
  int wrap_s = 10497;  // REPEAT
  int wrap_t = 10497;
  bool operator==(const TextureSampler&) const = default;
};

// A texture slot of a material: which image, sampled how, through which UV set.
struct TextureBinding {
  int image = -1;         // index into Rig::images
  TextureSampler sampler;
  int texcoord = 0;       // TEXCOORD_n
  double scale = 1.0;     // normalTexture.scale, occlusionTexture.strength; 1 elsewhere
};

struct Material {
  std::string name;
  Eigen::Vector4d base_color_factor = Eigen::Vector4d::Ones();
  double metallic_factor = 1.0;
  double roughness_factor = 1.0;
  Eigen::Vector3d emissive_factor = Eigen::Vector3d::Zero();
  std::string alpha_mode = "OPAQUE";  // OPAQUE, MASK, BLEND
  double alpha_cutoff = 0.5;
  bool double_sided = false;
  std::optional<TextureBinding> base_color_texture;
  std::optional<TextureBinding> metallic_roughness_texture;
  std::optional<TextureBinding> normal_texture;
  std::optional<TextureBinding> occlusion_texture;
  std::optional<TextureBinding> emissive_texture;
};

}  // namespace core
