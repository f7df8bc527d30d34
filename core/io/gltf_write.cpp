// glTF writing: accessors and buffer views appended to buffer 0, the mesh
// primitive with its vertex attributes, the GLB bytes. encodeMeshGlb.

#include "core/io/gltf_model.h"

namespace core::gltf {

namespace {

// ---------------------------------------------------------------------------
// Writing: small helpers that append to buffer 0 (reused for skins, morph
// targets and animations).

static_assert(std::endian::native == std::endian::little, "GLB data is little-endian; writer copies host floats");

}  // namespace

int addBufferView(tinygltf::Model& model, Bytes bytes, int target) {
  if (model.buffers.empty()) model.buffers.emplace_back();
  std::vector<unsigned char>& data = model.buffers[0].data;
  data.resize((data.size() + 3) / 4 * 4, 0);
  tinygltf::BufferView view;
  view.buffer = 0;
  view.byteOffset = data.size();
  view.byteLength = bytes.size();
  view.target = target;
  data.insert(data.end(), bytes.begin(), bytes.end());
  model.bufferViews.push_back(std::move(view));
  return static_cast<int>(model.bufferViews.size()) - 1;
}

int addAccessor(tinygltf::Model& model, int buffer_view, int component_type, int type, std::size_t count,
                std::vector<double> min, std::vector<double> max) {
  tinygltf::Accessor accessor;
  accessor.bufferView = buffer_view;
  accessor.byteOffset = 0;
  accessor.componentType = component_type;
  accessor.type = type;
  accessor.count = count;
  accessor.minValues = std::move(min);
  accessor.maxValues = std::move(max);
  model.accessors.push_back(std::move(accessor));
  return static_cast<int>(model.accessors.size()) - 1;
}

int addFloatAccessor(tinygltf::Model& model, const std::vector<float>& values, int type, int target, bool bounds) {
  const int components = typeComponents(type);
  const std::size_t count = values.size() / static_cast<std::size_t>(components);
  std::vector<double> min;
  std::vector<double> max;
  if (bounds && count > 0) std::tie(min, max) = floatBounds(values, components);
  const int view = addBufferView(model, asBytes(values), target);
  return addAccessor(model, view, TINYGLTF_COMPONENT_TYPE_FLOAT, type, count, std::move(min), std::move(max));
}

namespace {

// The validator requires unit NORMALs: renormalise in float, and give zero or
// unusable normals +Y (they carry no direction anyway).
std::vector<float> unitNormals(const Eigen::MatrixX3d& normals) {
  std::vector<float> out(static_cast<std::size_t>(normals.rows()) * 3);
  for (Eigen::Index v = 0; v < normals.rows(); ++v) {
    Eigen::Vector3d n = normals.row(v).transpose();
    const double len = n.norm();
    n = len > 1e-12 && std::isfinite(len) ? Eigen::Vector3d(n / len) : Eigen::Vector3d::UnitY();
    for (int c = 0; c < 3; ++c) out[static_cast<std::size_t>(v) * 3 + c] = static_cast<float>(n(c));
  }
  return out;
}

}  // namespace

Result<tinygltf::Primitive> addMeshPrimitive(tinygltf::Model& model, const Mesh& mesh, const std::string& label,
                                             bool with_indices) {
  const std::vector<float> positions = toFloats(mesh.positions);
  if (const auto bad = firstNonFinite(positions)) {
    return makeError(ErrorCode::kInvalidMesh,
                     label + ": vertex " + std::to_string(*bad / 3) + " position exceeds the float32 range of glTF");
  }
  tinygltf::Primitive primitive;
  primitive.attributes["POSITION"] =
      addFloatAccessor(model, positions, TINYGLTF_TYPE_VEC3, TINYGLTF_TARGET_ARRAY_BUFFER, /*bounds=*/true);
  if (mesh.normals.rows() > 0) {
    primitive.attributes["NORMAL"] =
        addFloatAccessor(model, unitNormals(mesh.normals), TINYGLTF_TYPE_VEC3, TINYGLTF_TARGET_ARRAY_BUFFER, false);
  }
  if (mesh.uvs.rows() > 0) {
    primitive.attributes["TEXCOORD_0"] =
        addFloatAccessor(model, toFloats(mesh.uvs), TINYGLTF_TYPE_VEC2, TINYGLTF_TARGET_ARRAY_BUFFER, false);
  }
  if (mesh.triangleCount() == 0) {
    primitive.mode = TINYGLTF_MODE_POINTS;  // point cloud: every vertex drawn once
    return primitive;
  }
  primitive.mode = TINYGLTF_MODE_TRIANGLES;  // explicit: tinygltf's default (-1) is invalid
  if (!with_indices) return primitive;
  std::vector<std::uint32_t> indices(static_cast<std::size_t>(mesh.triangleCount()) * 3);
  for (Eigen::Index f = 0; f < mesh.triangleCount(); ++f) {
    for (int k = 0; k < 3; ++k) {
      indices[static_cast<std::size_t>(f) * 3 + k] = static_cast<std::uint32_t>(mesh.triangles(f, k));
    }
  }
  const int view = addBufferView(model, asBytes(indices), TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER);
  primitive.indices =
      addAccessor(model, view, TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT, TINYGLTF_TYPE_SCALAR, indices.size());
  return primitive;
}

namespace {

// An output stream appending to a byte vector reserved up front: the GLB of a
// large rig (hundreds of MB of morph targets) is written once, not grown in
// an ostringstream and copied out of it.
class ByteSink : public std::streambuf {
 public:
  explicit ByteSink(std::size_t reserve) { bytes_.reserve(reserve); }
  std::vector<std::uint8_t> take() { return std::move(bytes_); }

 protected:
  int_type overflow(int_type c) override {
    if (!traits_type::eq_int_type(c, traits_type::eof())) bytes_.push_back(static_cast<std::uint8_t>(c));
    return traits_type::not_eof(c);
  }
  std::streamsize xsputn(const char* s, std::streamsize n) override {
    bytes_.insert(bytes_.end(), reinterpret_cast<const std::uint8_t*>(s), reinterpret_cast<const std::uint8_t*>(s) + n);
    return n;
  }

 private:
  std::vector<std::uint8_t> bytes_;
};

}  // namespace

Result<std::vector<std::uint8_t>> serializeGlb(const tinygltf::Model& model) {
  tinygltf::TinyGLTF writer;
  std::size_t binary = 0;
  for (const auto& buffer : model.buffers) binary += buffer.data.size();
  // JSON: a few hundred bytes per accessor and buffer view, plus headroom.
  ByteSink sink(binary + 256 * (model.accessors.size() + model.bufferViews.size()) + (64 << 10));
  std::ostream stream(&sink);
  try {
    if (!writer.WriteGltfSceneToStream(&model, stream, /*prettyPrint=*/false, /*writeBinary=*/true)) {
      return makeError(ErrorCode::kIo, "GLB serialisation failed");
    }
  } catch (const std::exception& e) {
    return makeError(ErrorCode::kIo, std::string("GLB serialisation failed: ") + e.what());
  }
  if (!stream) return makeError(ErrorCode::kIo, "GLB serialisation failed (stream error)");
  return sink.take();
}

namespace {

// Accessor over a 1- or 2-byte per-vertex SCALAR padded to a 4-byte stride
// (spec: vertex attribute elements are 4-byte aligned).
int addPaddedScalarAccessor(tinygltf::Model& model, const Eigen::VectorXi& values, bool two_bytes) {
  std::vector<std::uint8_t> bytes(static_cast<std::size_t>(values.size()) * 4, 0);
  for (Eigen::Index v = 0; v < values.size(); ++v) {
    const auto value = static_cast<std::uint32_t>(values(v));
    bytes[static_cast<std::size_t>(v) * 4] = static_cast<std::uint8_t>(value & 0xFF);
    bytes[static_cast<std::size_t>(v) * 4 + 1] = static_cast<std::uint8_t>(value >> 8);
  }
  const int view = addBufferView(model, Bytes(bytes), TINYGLTF_TARGET_ARRAY_BUFFER);
  model.bufferViews[static_cast<std::size_t>(view)].byteStride = 4;
  const int type = two_bytes ? TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT : TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE;
  return addAccessor(model, view, type, TINYGLTF_TYPE_SCALAR, static_cast<std::size_t>(values.size()));
}

Status addLabels(tinygltf::Model& model, const VertexAttributes& attributes, Eigen::Index nv,
                 tinygltf::Primitive& primitive) {
  for (const auto& [key, values] : attributes.labels) {
    const std::string name = "_" + key;
    if (key.empty() || attributes.fields.count(key) > 0) {
      return invalidRig("custom attribute name '" + name + "' is empty or used twice");
    }
    if (values.size() != nv) {
      return invalidRig("label " + key + " has " + std::to_string(values.size()) + " values for " + std::to_string(nv) +
                        " vertices");
    }
    for (Eigen::Index v = 0; v < nv; ++v) {
      if (values(v) < 0 || values(v) > 65535) {
        return invalidRig("label " + key + " of vertex " + std::to_string(v) + " is " + std::to_string(values(v)) +
                          " (0..65535)");
      }
    }
    primitive.attributes[name] = addPaddedScalarAccessor(model, values, values.maxCoeff() > 255);
  }
  return Ok{};
}

Status addFields(tinygltf::Model& model, const VertexAttributes& attributes, Eigen::Index nv,
                 tinygltf::Primitive& primitive) {
  static constexpr std::array<int, 4> kTypes = {TINYGLTF_TYPE_SCALAR, TINYGLTF_TYPE_VEC2, TINYGLTF_TYPE_VEC3,
                                                TINYGLTF_TYPE_VEC4};
  for (const auto& [key, values] : attributes.fields) {
    if (key.empty()) return invalidRig("custom attribute name '_' is empty");
    if (values.rows() != nv || values.cols() < 1 || values.cols() > 4) {
      return invalidRig("field " + key + " is " + std::to_string(values.rows()) + " by " +
                        std::to_string(values.cols()) + ", expected #V " + std::to_string(nv) + " by 1..4");
    }
    const std::vector<float> floats = toFloats(values);
    if (const auto bad = firstNonFinite(floats)) {
      return invalidRig("field " + key + " of vertex " +
                        std::to_string(*bad / static_cast<std::size_t>(values.cols())) + " is not finite in float32");
    }
    const int type = kTypes[static_cast<std::size_t>(values.cols() - 1)];
    primitive.attributes["_" + key] = addFloatAccessor(model, floats, type, TINYGLTF_TARGET_ARRAY_BUFFER, false);
  }
  return Ok{};
}

}  // namespace

Status addVertexAttributes(tinygltf::Model& model, const Rig& rig, tinygltf::Primitive& primitive) {
  const VertexAttributes& attributes = rig.attributes;
  const Eigen::Index nv = rig.mesh.vertexCount();
  if (!attributes.extra_uv_sets.empty() && rig.mesh.uvs.rows() == 0) {
    return invalidRig("extra UV sets need mesh.uvs (TEXCOORD_0)");
  }
  for (std::size_t k = 0; k < attributes.extra_uv_sets.size(); ++k) {
    const std::string name = "TEXCOORD_" + std::to_string(k + 1);
    const std::vector<float> uvs = toFloats(attributes.extra_uv_sets[k]);
    if (attributes.extra_uv_sets[k].rows() != nv || firstNonFinite(uvs)) {
      return invalidRig(name + " must have " + std::to_string(nv) + " finite rows");
    }
    primitive.attributes[name] = addFloatAccessor(model, uvs, TINYGLTF_TYPE_VEC2, TINYGLTF_TARGET_ARRAY_BUFFER, false);
  }
  if (attributes.colors.rows() > 0) {
    if (attributes.colors.rows() != nv) return invalidRig("colors must have " + std::to_string(nv) + " rows");
    for (Eigen::Index v = 0; v < nv; ++v) {
      const auto row = attributes.colors.row(v);
      if (!(row.minCoeff() >= 0.0 && row.maxCoeff() <= 1.0)) {
        return invalidRig("color of vertex " + std::to_string(v) + " is outside [0, 1]");
      }
    }
    primitive.attributes["COLOR_0"] =
        addFloatAccessor(model, toFloats(attributes.colors), TINYGLTF_TYPE_VEC4, TINYGLTF_TARGET_ARRAY_BUFFER, false);
  }
  if (auto ok = addLabels(model, attributes, nv, primitive); !ok) return ok.error();
  return addFields(model, attributes, nv, primitive);
}

}  // namespace core::gltf

namespace core {

Result<std::vector<std::uint8_t>> encodeMeshGlb(const Mesh& mesh) {
  const std::string label = "mesh to write";
  if (auto ok = validateMesh(mesh, label); !ok) return ok.error();
  if (mesh.vertexCount() == 0) return makeError(ErrorCode::kInvalidMesh, label + ": it has no vertices");

  tinygltf::Model model;
  model.asset.version = "2.0";
  model.asset.generator = "rigport";
  auto primitive = gltf::addMeshPrimitive(model, mesh, label);
  if (!primitive) return primitive.error();
  if (mesh.regions.size() > 0) {
    primitive->attributes[std::string("_") + kRegionAttribute] = gltf::addPaddedScalarAccessor(model, mesh.regions, false);
  }
  tinygltf::Mesh gmesh;
  gmesh.primitives.push_back(std::move(*primitive));
  model.meshes.push_back(std::move(gmesh));
  tinygltf::Node node;
  node.mesh = 0;
  model.nodes.push_back(std::move(node));
  tinygltf::Scene scene;
  scene.nodes.push_back(0);
  model.scenes.push_back(std::move(scene));
  model.defaultScene = 0;
  return gltf::serializeGlb(model);
}

Status writeMeshGlb(const Mesh& mesh, const std::filesystem::path& path) {
  auto bytes = encodeMeshGlb(mesh);
  if (!bytes) return makeError(bytes.error().code, path.filename().string() + ": " + bytes.error().message);
  return writeFileBytes(path, *bytes);
}

}  // namespace core
