// (internal to core/io) What the glTF reader and writer share: tinygltf (this
// is the only header that includes tiny_gltf.h, and only core/io/gltf_*.cpp
// include it; tinygltf types never leave them), bounds-checked accessor
// decoding, the scene's chosen mesh, and buffer building for the writer.
//
//   gltf_parse.cpp      GLB container and JSON checks, tinygltf load, the chosen mesh
//   gltf_accessors.cpp  accessor decoding (bounds-checked, overflow-safe)
//   gltf_mesh_read.cpp  primitives -> core::Mesh (readGltf)
//   gltf_skin_read.cpp  nodes, skin, inverse binds, weights
//   gltf_rig_read.cpp   morph targets, animations, vertex attributes (readRig)
//   gltf_material_read.cpp / gltf_material_write.cpp  materials, textures, images
//   gltf_write.cpp      buffers, accessors, the mesh primitive, GLB (encodeMeshGlb)
//   gltf_rig_write.cpp  rig checks, nodes, skin, morph targets, animations (encodeRigGlb)
//
// Reference: Khronos glTF 2.0 specification,
// https://registry.khronos.org/glTF/specs/2.0/glTF-2.0.html.
#pragma once

#include <algorithm>
#include <array>
#include <bit>
#include <cctype>
#include <cmath>
#include <cstring>
#include <fstream>  // tinygltf uses std::ofstream even with TINYGLTF_NO_FS
#include <limits>
#include <map>
#include <optional>
#include <set>
#include <sstream>
#include <string>
#include <string_view>
#include <system_error>
#include <tuple>
#include <utility>
#include <vector>

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <Eigen/SVD>
#include <nlohmann/json.hpp>

#include "core/io/json_text.h"
#include "core/io/mesh_io.h"
#include "core/io/rig_io.h"

// tinygltf 2.7 uses nlohmann::json; TINYGLTF_NO_INCLUDE_JSON makes it use the
// one included above. No image decoding or writing (we never need pixels), no
// external images, and no built-in file system access: the only file access is
// through the callbacks of gltf_parse.cpp, confined to the glTF's directory.
// TINYGLTF_IMPLEMENTATION is defined by gltf_parse.cpp alone.
#define TINYGLTF_NO_STB_IMAGE
#define TINYGLTF_NO_STB_IMAGE_WRITE
#define TINYGLTF_NO_EXTERNAL_IMAGE
#define TINYGLTF_NO_INCLUDE_JSON
#define TINYGLTF_NO_FS
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wshadow"
#pragma GCC diagnostic ignored "-Wpedantic"
#pragma GCC diagnostic ignored "-Wunused-parameter"
#pragma GCC diagnostic ignored "-Wunused-function"
#pragma GCC diagnostic ignored "-Wunused-variable"
#pragma GCC diagnostic ignored "-Wsign-compare"
#pragma GCC diagnostic ignored "-Wmissing-field-initializers"
#pragma GCC diagnostic ignored "-Wimplicit-fallthrough"
#pragma GCC diagnostic ignored "-Wnon-virtual-dtor"
#include <tiny_gltf.h>
#pragma GCC diagnostic pop

namespace core {

// Declared for core/io/mesh_io.cpp (readMesh passes the .gltf file's directory).
Result<LoadedMesh> readGltfWithBaseDir(std::span<const std::uint8_t> bytes, const std::string& label, bool binary,
                                       const std::filesystem::path& base_dir);

}  // namespace core

namespace core::gltf {

using Bytes = std::span<const std::uint8_t>;

// An accessor without a bufferView is all zeros (plus sparse overrides), so its
// count is not bounded by the file size; cap it so a crafted file cannot ask
// for an arbitrarily large allocation. 16M elements is far above any face rig.
inline constexpr std::size_t kMaxImplicitAccessorCount = std::size_t{1} << 24;

std::string quoted(const std::string& name);

Error parseError(const std::string& label, const std::string& what);

std::uint32_t readLe32(const std::uint8_t* p);

// Components of one element (16 for MAT4).
int typeComponents(int type);

// Byte layout of one element: matrix columns start on 4-byte boundaries (spec,
// "Data Alignment"), which only matters for 1- and 2-byte matrix components.
struct ElementLayout {
  int rows = 0;
  int columns = 0;
  std::size_t component_size = 0;
  std::size_t column_stride = 0;
  std::size_t size = 0;  // bytes per element, tightly packed
};

// Decoded accessor: `count` elements of `components` doubles, row-major
// (matrices column-major within the element, as in the file).
struct AccessorValues {
  std::size_t count = 0;
  int components = 0;
  std::vector<double> values;

  double at(std::size_t element, int component) const {
    return values[element * static_cast<std::size_t>(components) + static_cast<std::size_t>(component)];
  }
};

// Where decoded values go: component c of element i at
// data[i * element_stride + c * component_stride] (row-major values, or a
// block of rows of a column-major matrix).
struct DecodeDestination {
  double* data = nullptr;
  std::size_t element_stride = 0;
  std::size_t component_stride = 1;
};

// An accessor checked against its bufferViews and buffers, ready to decode:
// every byte it will read is known to be inside the file, so a caller may
// size its destination by `count` before decoding.
struct CheckedAccessor {
  std::string what;  // "accessor 3 (POSITION)", for messages
  std::size_t count = 0;
  int components = 0;
  ElementLayout layout;
  int component_type = 0;
  bool normalized = false;
  const std::uint8_t* data = nullptr;  // nullptr: no bufferView, all zeros
  std::size_t stride = 0;
  // accessor.sparse, when present
  std::size_t sparse_count = 0;
  int sparse_index_type = 0;
  const std::uint8_t* sparse_indices = nullptr;
  const std::uint8_t* sparse_values = nullptr;
};

// Checks accessor `index` (any type, stride, normalisation, sparse). `role`
// says what it is for ("POSITION", "indices") in error messages.
Result<CheckedAccessor> checkAccessor(const tinygltf::Model& model, int index, const std::string& role,
                                      const std::string& label);

// Decodes a checked accessor into `dst`, which has room for its count
// elements: the dense data (or zeros), then the sparse overrides.
Status decodeAccessor(const CheckedAccessor& a, DecodeDestination dst, const std::string& label);

// Reads accessor `index` (any type, stride, normalisation, sparse) as doubles.
// `role` says what it is for ("POSITION", "indices") in error messages.
Result<AccessorValues> readAccessor(const tinygltf::Model& model, int index, const std::string& role,
                                    const std::string& label);

// Reads a per-vertex attribute with the expected component count, decoded
// straight into a #count by `components` matrix.
template <typename Matrix>
Result<Matrix> readAttribute(const tinygltf::Model& model, int index, const std::string& role, int components,
                             const std::string& label) {
  auto checked = checkAccessor(model, index, role, label);
  if (!checked) return checked.error();
  if (checked->components != components) {
    return parseError(label, checked->what + " has " + std::to_string(checked->components) +
                                 " components per element, expected " + std::to_string(components));
  }
  Matrix values(static_cast<Eigen::Index>(checked->count), components);
  if (auto ok = decodeAccessor(*checked, {values.data(), 1, checked->count}, label); !ok) return ok.error();
  return values;
}

// Node-local transform: `matrix` (column-major) or T * R * S.
Result<Eigen::Matrix4d> localTransform(const tinygltf::Node& node, int index, const std::string& label);

// Parent of every node (-1 for roots), rejecting out-of-range children and
// nodes with two parents.
Result<std::vector<int>> nodeParents(const tinygltf::Model& model, const std::string& label);

// World transform of `node`: product of local transforms up to the root.
Result<Eigen::Matrix4d> worldTransform(const tinygltf::Model& model, int node, const std::string& label);

struct MeshChoice {
  int mesh = -1;
  int node = -1;  // first node instancing it, -1 if none
  bool skinned = false;
  std::string description;  // for MeshReadReport::chosen_mesh
};

// The chosen glTF mesh as one core::Mesh: all its primitives merged, placed
// by its node, validated.
Result<LoadedMesh> buildMesh(const tinygltf::Model& model, const MeshChoice& choice, const std::string& label,
                             LoadedMesh loaded);

// The parsed file and the mesh chosen from it: the common start of readGltf
// and readRig.
struct ParsedGltf {
  tinygltf::Model model;
  MeshChoice choice;
};

Result<ParsedGltf> parseGltf(Bytes bytes, const std::string& label, bool binary,
                             const std::optional<std::filesystem::path>& base_dir, MeshReadReport& report);

// Every node with its parent and local TRS (a `matrix` is decomposed).
Result<std::vector<Node>> readNodes(const tinygltf::Model& model, const std::string& label,
                                    std::vector<std::string>& warnings);

// Rows of the merged mesh that come from each primitive (mergePrimitives order).
// A primitive with the same vertex attributes (accessor for accessor, morph
// targets too) as an earlier one draws that one's vertices with its own
// indices and material (how a mesh of several materials is written): it adds
// no rows and its range is the earlier one's.
struct PrimitiveRange {
  Eigen::Index offset = 0;
  Eigen::Index count = 0;
};

// Triangles a primitive draws (0 for points and lines).
std::size_t primitiveTriangleCount(const tinygltf::Model& model, const tinygltf::Primitive& primitive);

// The file's materials and embedded images into rig.materials / rig.images
// (glTF indices kept; textures on external images dropped with a warning).
void readMaterials(const tinygltf::Model& model, Rig& rig, std::vector<std::string>& warnings);

// Per triangle of the merged mesh (`triangles` of them), its primitive's
// material; empty when no primitive has one.
std::vector<int> triangleMaterials(const tinygltf::Model& model, const tinygltf::Mesh& gmesh, Eigen::Index triangles,
                                   const std::string& mesh_name, std::vector<std::string>& warnings);

// The earlier primitive whose vertices primitive `p` draws, or -1.
int sameVerticesAs(const tinygltf::Mesh& gmesh, std::size_t p);

std::vector<PrimitiveRange> primitiveRanges(const tinygltf::Model& model, const tinygltf::Mesh& gmesh);

Eigen::Index vertexTotal(const std::vector<PrimitiveRange>& ranges);

// Accessor of attribute `name` in each primitive, or in its morph target
// `target` (-1: the primitive's own attributes); -1 where absent.
std::vector<int> attributeAccessors(const tinygltf::Mesh& gmesh, const std::string& name, int target = -1);

bool presentInAll(const std::vector<int>& accessors);

bool presentInAny(const std::vector<int>& accessors);

// One attribute of every primitive merged into a #V by `components` matrix
// (rows of primitives without it stay zero; no rows when no primitive has it),
// decoded straight into place. `components` 0 takes the count from the first
// accessor. Values must be finite.
template <typename Matrix = Eigen::MatrixXd>
Result<Matrix> readMergedAttribute(const tinygltf::Model& model, const std::vector<int>& accessors,
                                   const std::vector<PrimitiveRange>& ranges, int components, const std::string& role,
                                   const std::string& mesh_name, const std::string& label) {
  Matrix merged;
  for (std::size_t p = 0; p < accessors.size(); ++p) {
    if (accessors[p] < 0) continue;
    const std::string what = mesh_name + " primitive " + std::to_string(p) + " " + role;
    auto checked = checkAccessor(model, accessors[p], role, label);
    if (!checked) return checked.error();
    if (components == 0) components = checked->components;
    if (checked->components != components) {
      return parseError(label, what + " has " + std::to_string(checked->components) +
                                   " components per element, expected " + std::to_string(components));
    }
    const PrimitiveRange range = ranges[p];
    if (checked->count != static_cast<std::size_t>(range.count)) {
      return parseError(label, what + " has " + std::to_string(checked->count) + " elements but POSITION has " +
                                   std::to_string(range.count));
    }
    if (merged.rows() == 0) {
      merged.resize(vertexTotal(ranges), components);
      if (!presentInAll(accessors)) merged.setZero();
    }
    if (auto ok = decodeAccessor(*checked,
                                 {merged.data() + range.offset, 1, static_cast<std::size_t>(merged.rows())}, label);
        !ok) {
      return ok.error();
    }
    for (Eigen::Index v = range.offset; v < range.offset + range.count; ++v) {
      if (!merged.row(v).allFinite()) {
        return makeError(ErrorCode::kInvalidMesh, label + ": " + role + " of vertex " + std::to_string(v) +
                                                      " is not finite");
      }
    }
  }
  return merged;
}

// mesh.extras key listing the morph targets that are baked presets of the
// rig's components (Rig::baked_presets).
inline const char* const kBakedPresetsKey = "rigportBakedPresets";

// mesh.extras.targetNames when it is a list of `count` strings, else target_<i>.
std::vector<std::string> targetNames(const tinygltf::Mesh& gmesh, std::size_t count, const std::string& mesh_name,
                                     std::vector<std::string>& warnings);

std::optional<Interpolation> interpolation(const std::string& name);

// Custom attribute "_NAME": unnormalised integer SCALAR -> labels["NAME"],
// float or normalized SCALAR..VEC4 -> fields["NAME"]; anything else warned.
Status readCustomAttribute(const tinygltf::Model& model, const tinygltf::Mesh& gmesh,
                           const std::vector<PrimitiveRange>& ranges, const std::string& name,
                           const std::string& mesh_name, const std::string& label, VertexAttributes& out,
                           std::vector<std::string>& warnings);

// Skin and weights of a skinned mesh node (JOINTS/WEIGHTS of an unskinned
// mesh are ignored with a warning). With `shared` (a part on the face's skin,
// already read) only the weights are read, against its joints.
Status readSkinning(const tinygltf::Model& model, const MeshChoice& choice, const std::vector<PrimitiveRange>& ranges,
                    const std::string& mesh_name, const std::string& label, Rig& rig,
                    std::vector<std::string>& warnings, const Skin* shared = nullptr);

// The chosen mesh of a parsed file (buildMesh) with its region labels.
Result<LoadedMesh> chosenMesh(const ParsedGltf& parsed, const std::string& label, LoadedMesh loaded);

template <typename T>
Bytes asBytes(const std::vector<T>& values) {
  return Bytes(reinterpret_cast<const std::uint8_t*>(values.data()), values.size() * sizeof(T));
}

// Appends `bytes` to buffer 0 at a 4-byte aligned offset and returns the new
// bufferView. `target` is TINYGLTF_TARGET_ARRAY_BUFFER, ..._ELEMENT_ARRAY_BUFFER
// or 0 (animation / inverse-bind data has no target).
int addBufferView(tinygltf::Model& model, Bytes bytes, int target);

// Adds an accessor over a whole bufferView and returns its index.
int addAccessor(tinygltf::Model& model, int buffer_view, int component_type, int type, std::size_t count,
                std::vector<double> min = {}, std::vector<double> max = {});

// Per-component min and max of `values` (count * components floats).
inline std::pair<std::vector<double>, std::vector<double>> floatBounds(const std::vector<float>& values, int components) {
  const auto n = static_cast<std::size_t>(components);
  std::vector<double> min(n, std::numeric_limits<double>::infinity());
  std::vector<double> max(n, -std::numeric_limits<double>::infinity());
  for (std::size_t row = 0; row + n <= values.size(); row += n) {
    for (std::size_t c = 0; c < n; ++c) {
      min[c] = std::min(min[c], static_cast<double>(values[row + c]));
      max[c] = std::max(max[c], static_cast<double>(values[row + c]));
    }
  }
  return {min, max};
}

// Float accessor from `values` (count * components floats, row-major). With
// `bounds`, min/max are set from the float values themselves, as the spec
// requires for POSITION (and the validator checks exactly).
int addFloatAccessor(tinygltf::Model& model, const std::vector<float>& values, int type, int target, bool bounds);

// Row-major float copy of a matrix.
template <typename Derived>
std::vector<float> toFloats(const Eigen::MatrixBase<Derived>& m) {
  std::vector<float> out(static_cast<std::size_t>(m.rows() * m.cols()));
  for (Eigen::Index r = 0; r < m.rows(); ++r) {
    for (Eigen::Index c = 0; c < m.cols(); ++c) {
      out[static_cast<std::size_t>(r * m.cols() + c)] = static_cast<float>(m(r, c));
    }
  }
  return out;
}

// Index of the first value that is not finite (a finite double can still
// overflow float32), or nullopt.
inline std::optional<std::size_t> firstNonFinite(const std::vector<float>& values) {
  const auto bad = std::find_if(values.begin(), values.end(), [](float x) { return !std::isfinite(x); });
  if (bad == values.end()) return std::nullopt;
  return static_cast<std::size_t>(bad - values.begin());
}

// POSITION (with min/max), unit NORMAL, TEXCOORD_0 and uint32 indices of a
// validated `mesh` as one primitive, mode TRIANGLES (POINTS for a point cloud).
// Without indices when the caller splits the triangles (splitByMaterial).
Result<tinygltf::Primitive> addMeshPrimitive(tinygltf::Model& model, const Mesh& mesh, const std::string& label,
                                             bool with_indices = true);

// The rig's images (into buffer 0), samplers, textures and materials, glTF
// indices those of Rig::materials / Rig::images (gltf_material_write.cpp).
void addMaterials(tinygltf::Model& model, const Rig& rig);

// One primitive per material of `triangle_materials` (one per triangle of
// `mesh`; -1: none), each a copy of `primitive` (its vertex attributes and
// morph targets shared) with the triangles of that material, in order of
// first use.
std::vector<tinygltf::Primitive> splitByMaterial(tinygltf::Model& model, const tinygltf::Primitive& primitive,
                                                 const Mesh& mesh, const std::vector<int>& triangle_materials);

// Serialises `model` as GLB bytes (tinygltf's writer; deterministic since its
// JSON objects are ordered maps).
Result<std::vector<std::uint8_t>> serializeGlb(const tinygltf::Model& model);

// What messages about a rig being written call it.
inline const std::string kRigLabel = "rig to write";
Error invalidRig(const std::string& what);
// "node 3 'jaw'": a node of the rig to write, in messages.
std::string nodeName(const Rig& rig, int node);
// Every rule the validator enforces that the Rig type does not (gltf_rig_check.cpp).
Status checkRig(const Rig& rig, const RigWriteOptions& options);

// TEXCOORD_1.., COLOR_0 and the custom attributes.
Status addVertexAttributes(tinygltf::Model& model, const Rig& rig, tinygltf::Primitive& primitive);

}  // namespace core::gltf
