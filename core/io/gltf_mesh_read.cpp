// glTF primitives -> core::Mesh: triangles from every mode, primitives merged,
// placed by their node's world transform, normals finished; the mesh's
// _REGION labels. readGltf.

#include "core/io/gltf_model.h"

namespace core::gltf {

namespace {

// ---------------------------------------------------------------------------
// Primitive -> core::Mesh

const char* modeName(int mode) {
  switch (mode) {
    case TINYGLTF_MODE_POINTS: return "POINTS";
    case TINYGLTF_MODE_LINE: return "LINES";
    case TINYGLTF_MODE_LINE_LOOP: return "LINE_LOOP";
    case TINYGLTF_MODE_LINE_STRIP: return "LINE_STRIP";
    case TINYGLTF_MODE_TRIANGLES: return "TRIANGLES";
    case TINYGLTF_MODE_TRIANGLE_STRIP: return "TRIANGLE_STRIP";
    case TINYGLTF_MODE_TRIANGLE_FAN: return "TRIANGLE_FAN";
    default: return "unknown";
  }
}

bool isTriangleMode(int mode) {
  return mode == TINYGLTF_MODE_TRIANGLES || mode == TINYGLTF_MODE_TRIANGLE_STRIP ||
         mode == TINYGLTF_MODE_TRIANGLE_FAN;
}

// One primitive's vertex data, before merging.
struct PrimitiveData {
  Eigen::MatrixX3d positions;
  Eigen::MatrixX3d normals;  // 0 rows when the primitive has none
  Eigen::MatrixX2d uvs;      // 0 rows when the primitive has none
  std::vector<std::array<std::int64_t, 3>> triangles;  // primitive-local vertex indices
  int same_vertices_as = -1;  // an earlier primitive whose vertices these triangles index (no rows here)
};

// Expands TRIANGLES / TRIANGLE_STRIP / TRIANGLE_FAN element lists (spec,
// "Primitive Topology") into triangles. `elements` are vertex indices in drawing order.
Result<std::vector<std::array<std::int64_t, 3>>> assembleTriangles(const std::vector<std::int64_t>& elements, int mode,
                                                                   const std::string& what,
                                                                   const std::string& label) {
  std::vector<std::array<std::int64_t, 3>> triangles;
  const std::size_t n = elements.size();
  if (mode == TINYGLTF_MODE_TRIANGLES) {
    if (n % 3 != 0) {
      return parseError(label, what + " draws TRIANGLES from " + std::to_string(n) +
                                   " elements, which is not a multiple of 3");
    }
    triangles.reserve(n / 3);
    for (std::size_t i = 0; i + 2 < n; i += 3) triangles.push_back({elements[i], elements[i + 1], elements[i + 2]});
  } else if (mode == TINYGLTF_MODE_TRIANGLE_STRIP) {
    // Odd triangles swap their last two vertices to keep a consistent winding.
    for (std::size_t i = 0; i + 2 < n; ++i) {
      if (i % 2 == 0) {
        triangles.push_back({elements[i], elements[i + 1], elements[i + 2]});
      } else {
        triangles.push_back({elements[i], elements[i + 2], elements[i + 1]});
      }
    }
  } else {  // TRIANGLE_FAN
    for (std::size_t i = 0; i + 2 < n; ++i) triangles.push_back({elements[i + 1], elements[i + 2], elements[0]});
  }
  return triangles;
}

Result<PrimitiveData> readPrimitive(const tinygltf::Model& model, const tinygltf::Primitive& primitive,
                                    const std::string& what, bool want_triangles, const std::string& label) {
  PrimitiveData out;
  const auto position_it = primitive.attributes.find("POSITION");
  if (position_it == primitive.attributes.end()) return parseError(label, what + " has no POSITION attribute");
  auto positions = readAttribute<Eigen::MatrixX3d>(model, position_it->second, "POSITION", 3, label);
  if (!positions) return positions.error();
  out.positions = std::move(*positions);
  const auto nv = static_cast<std::size_t>(out.positions.rows());

  auto read_optional = [&]<typename Matrix>(const char* name, int components, Matrix& target) -> Status {
    const auto it = primitive.attributes.find(name);
    if (it == primitive.attributes.end()) return Ok{};
    auto values = readAttribute<Matrix>(model, it->second, name, components, label);
    if (!values) return values.error();
    if (static_cast<std::size_t>(values->rows()) != nv) {
      return parseError(label, what + " " + name + " has " + std::to_string(values->rows()) +
                                   " elements but POSITION has " + std::to_string(nv));
    }
    target = std::move(*values);
    return Ok{};
  };
  if (auto ok = read_optional("NORMAL", 3, out.normals); !ok) return ok.error();
  if (auto ok = read_optional("TEXCOORD_0", 2, out.uvs); !ok) return ok.error();
  if (!want_triangles) return out;

  // Element list: the indices, or consecutive vertices for a non-indexed primitive.
  std::vector<std::int64_t> elements;
  if (primitive.indices >= 0) {
    auto indices = readAccessor(model, primitive.indices, "indices", label);
    if (!indices) return indices.error();
    if (indices->components != 1) return parseError(label, what + " indices accessor is not SCALAR");
    elements.resize(indices->count);
    for (std::size_t i = 0; i < indices->count; ++i) {
      const double index = indices->values[i];
      // Anything outside [0, nv) is caught per triangle below; clamp to keep
      // the conversion defined.
      elements[i] = index >= 0.0 && index < 9.0e15 ? static_cast<std::int64_t>(index) : -1;
    }
  } else {
    elements.resize(nv);
    for (std::size_t i = 0; i < nv; ++i) elements[i] = static_cast<std::int64_t>(i);
  }
  auto triangles = assembleTriangles(elements, primitive.mode, what, label);
  if (!triangles) return triangles.error();
  out.triangles = std::move(*triangles);
  return out;
}

// Positions by the affine part of `world`, normals by its inverse transpose
// (not renormalised here); a mirroring transform flips the winding to keep faces front.
Status applyTransform(const Eigen::Matrix4d& world, const std::string& label, Mesh& mesh,
                      std::vector<std::string>& warnings) {
  if (world.isIdentity(0.0)) return Ok{};
  const Eigen::Matrix3d linear = world.topLeftCorner<3, 3>();
  const Eigen::Vector3d translation = world.topRightCorner<3, 1>();
  const double det = linear.determinant();
  if (!(std::abs(det) > 0.0) || !std::isfinite(det)) {
    return makeError(ErrorCode::kInvalidMesh, label + ": the node transform of the mesh is singular (zero scale)");
  }
  if (world.row(3) != Eigen::RowVector4d(0, 0, 0, 1)) {
    warnings.push_back("the node transform has a projective row; it was ignored");
  }
  mesh.positions = ((mesh.positions * linear.transpose()).rowwise() + translation.transpose()).eval();
  if (mesh.normals.rows() > 0) {
    const Eigen::Matrix3d normal_matrix = linear.inverse().transpose();
    mesh.normals = (mesh.normals * normal_matrix.transpose()).eval();  // renormalised by the caller
  }
  if (det < 0.0) mesh.triangles.col(1).swap(mesh.triangles.col(2));
  return Ok{};
}

// Triangles when any primitive has them; a POINTS-only mesh is a point cloud.
// Returns whether the mesh has triangles.
Result<bool> checkPrimitiveModes(const tinygltf::Mesh& gmesh, const std::string& mesh_name, const std::string& label) {
  if (gmesh.primitives.empty()) return makeError(ErrorCode::kInvalidMesh, label + ": " + mesh_name + " has no primitives");
  const bool has_triangles =
      std::any_of(gmesh.primitives.begin(), gmesh.primitives.end(), [](const auto& p) { return isTriangleMode(p.mode); });
  for (std::size_t p = 0; p < gmesh.primitives.size(); ++p) {
    const int mode = gmesh.primitives[p].mode;
    const std::string what = mesh_name + " primitive " + std::to_string(p);
    if (mode < TINYGLTF_MODE_POINTS || mode > TINYGLTF_MODE_TRIANGLE_FAN) {
      return parseError(label, what + " has invalid mode " + std::to_string(mode));
    }
    if (isTriangleMode(mode) || (!has_triangles && mode == TINYGLTF_MODE_POINTS)) continue;
    return makeError(ErrorCode::kUnsupported, label + ": " + what + " uses mode " + modeName(mode) +
                                                  (has_triangles ? " beside triangles" : "") +
                                                  "; only triangle meshes and point clouds are supported");
  }
  return has_triangles;
}

// Reads every primitive and checks its indices; an out-of-range index names
// the triangle by its index in the merged mesh.
Result<std::vector<PrimitiveData>> readPrimitives(const tinygltf::Model& model, const tinygltf::Mesh& gmesh,
                                                  const std::string& mesh_name, bool has_triangles,
                                                  const std::string& label) {
  std::vector<PrimitiveData> parts;
  std::size_t total_vertices = 0;
  std::size_t total_triangles = 0;
  for (std::size_t p = 0; p < gmesh.primitives.size(); ++p) {
    const std::string what = mesh_name + " primitive " + std::to_string(p);
    auto part = readPrimitive(model, gmesh.primitives[p], what, has_triangles, label);
    if (!part) return part.error();
    const auto nv = static_cast<std::int64_t>(part->positions.rows());
    for (std::size_t t = 0; t < part->triangles.size(); ++t) {
      for (const std::int64_t index : part->triangles[t]) {
        if (index < 0 || index >= nv) {
          return makeError(ErrorCode::kInvalidMesh,
                           label + ": triangle " + std::to_string(total_triangles + t) + " (" + what +
                               ") refers to vertex " + (index < 0 ? std::string("<invalid>") : std::to_string(index)) +
                               " but the primitive has " + std::to_string(nv) + " vertices");
        }
      }
    }
    part->same_vertices_as = sameVerticesAs(gmesh, p);
    if (part->same_vertices_as >= 0) {  // its vertices are the earlier primitive's
      part->positions.resize(0, 3);
      part->normals.resize(0, 3);
      part->uvs.resize(0, 2);
    }
    total_vertices += static_cast<std::size_t>(part->positions.rows());
    total_triangles += part->triangles.size();
    if (total_vertices > static_cast<std::size_t>(std::numeric_limits<int>::max()) ||
        total_triangles > static_cast<std::size_t>(std::numeric_limits<int>::max())) {
      return makeError(ErrorCode::kUnsupported, label + ": " + mesh_name + " is too large for 32-bit indices");
    }
    parts.push_back(std::move(*part));
  }
  return parts;
}

bool ownsVertices(const PrimitiveData& p) { return p.same_vertices_as < 0; }

// Of the primitives that own vertices, whether they have normals (UVs); a
// repeat has what its original has.
bool hasNormals(const PrimitiveData& p) { return !ownsVertices(p) || p.normals.rows() > 0; }

bool hasUvs(const PrimitiveData& p) { return !ownsVertices(p) || p.uvs.rows() > 0; }

// Concatenates the primitives (vertex offsets added to their triangles).
// Normals missing on some primitives are left zero (filled later); UVs are
// kept only when every primitive has them.
Mesh mergePrimitives(const std::vector<PrimitiveData>& parts, const std::string& mesh_name, MeshReadReport& report) {
  const bool any_normals = std::any_of(parts.begin(), parts.end(), [](const auto& p) { return ownsVertices(p) && hasNormals(p); });
  const bool all_uvs = std::all_of(parts.begin(), parts.end(), hasUvs);
  if (!all_uvs && std::any_of(parts.begin(), parts.end(), [](const auto& p) { return ownsVertices(p) && hasUvs(p); })) {
    report.warnings.push_back("TEXCOORD_0 is missing on some primitives of " + mesh_name + "; UVs dropped");
  }
  Eigen::Index nv_total = 0;
  Eigen::Index nf_total = 0;
  for (const PrimitiveData& part : parts) {
    nv_total += part.positions.rows();
    nf_total += static_cast<Eigen::Index>(part.triangles.size());
  }
  Mesh mesh;
  mesh.positions.resize(nv_total, 3);
  mesh.triangles.resize(nf_total, 3);
  if (any_normals) mesh.normals = Eigen::MatrixX3d::Zero(nv_total, 3);
  if (all_uvs) mesh.uvs.resize(nv_total, 2);
  Eigen::Index v0 = 0;
  Eigen::Index t0 = 0;
  std::vector<Eigen::Index> offsets;
  for (const PrimitiveData& part : parts) {
    const Eigen::Index nv = part.positions.rows();
    const Eigen::Index offset = ownsVertices(part) ? v0 : offsets[static_cast<std::size_t>(part.same_vertices_as)];
    offsets.push_back(offset);
    if (ownsVertices(part)) {
      mesh.positions.middleRows(v0, nv) = part.positions;
      if (part.normals.rows() > 0) mesh.normals.middleRows(v0, nv) = part.normals;
      if (all_uvs) mesh.uvs.middleRows(v0, nv) = part.uvs;
      v0 += nv;
    }
    for (const auto& tri : part.triangles) {
      for (int k = 0; k < 3; ++k) mesh.triangles(t0, k) = static_cast<int>(tri[static_cast<std::size_t>(k)] + offset);
      ++t0;
    }
  }
  return mesh;
}

// Moves the mesh into world space with the node that instances it. glTF spec
// ("Skins"): a skinned mesh's node transform is ignored (its joints place it),
// so a skinned mesh stays in the bind-pose space its inverse bind matrices use.
Status placeMesh(const tinygltf::Model& model, const MeshChoice& choice, const std::string& label, Mesh& mesh,
                 MeshReadReport& report) {
  if (choice.node < 0) return Ok{};
  auto world = worldTransform(model, choice.node, label);
  if (!world) return world.error();
  if (!choice.skinned) return applyTransform(*world, label, mesh, report.warnings);
  if (!world->isIdentity(1e-12)) {
    report.warnings.push_back("node " + std::to_string(choice.node) +
                              " transform ignored: glTF places skinned meshes by their joints");
  }
  return Ok{};
}

// Unit normals whatever the file or the transform did to their length, and
// area-weighted ones (computed in world space) where the file has none.
void finishNormals(const std::vector<PrimitiveData>& parts, const std::string& mesh_name, Mesh& mesh,
                   MeshReadReport& report) {
  for (Eigen::Index v = 0; v < mesh.normals.rows(); ++v) {
    const double len = mesh.normals.row(v).norm();
    if (len > 0.0) mesh.normals.row(v) /= len;
  }
  if (report.point_cloud || std::all_of(parts.begin(), parts.end(), hasNormals)) return;
  const Eigen::MatrixX3d computed = computeSeamlessVertexNormals(mesh.positions, mesh.triangles);
  report.normals_computed = true;
  if (mesh.normals.rows() == 0) {
    mesh.normals = computed;
    return;
  }
  Eigen::Index v0 = 0;
  for (const PrimitiveData& part : parts) {
    const Eigen::Index nv = part.positions.rows();  // 0 for a repeat
    if (!hasNormals(part)) mesh.normals.middleRows(v0, nv) = computed.middleRows(v0, nv);
    v0 += nv;
  }
  report.warnings.push_back("NORMAL is missing on some primitives of " + mesh_name + "; computed there");
}

}  // namespace

Result<LoadedMesh> buildMesh(const tinygltf::Model& model, const MeshChoice& choice, const std::string& label,
                             LoadedMesh loaded) {
  MeshReadReport& report = loaded.report;
  const tinygltf::Mesh& gmesh = model.meshes[static_cast<std::size_t>(choice.mesh)];
  const std::string mesh_name = "mesh " + std::to_string(choice.mesh);

  auto has_triangles = checkPrimitiveModes(gmesh, mesh_name, label);
  if (!has_triangles) return has_triangles.error();
  auto parts = readPrimitives(model, gmesh, mesh_name, *has_triangles, label);
  if (!parts) return parts.error();
  loaded.mesh = mergePrimitives(*parts, mesh_name, report);
  Mesh& mesh = loaded.mesh;
  if (auto ok = placeMesh(model, choice, label, mesh, report); !ok) return ok.error();
  if (auto ok = validateMesh(mesh, label); !ok) return ok.error();
  report.point_cloud = mesh.triangleCount() == 0;
  finishNormals(*parts, mesh_name, mesh, report);

  report.degenerate_triangles = countDegenerateTriangles(mesh);
  return loaded;
}

namespace {

// Region labels for region-constrained matching: the _REGION custom attribute
// when it is an integer SCALAR in 0..kMaxRegionLabel (anything else is warned
// and left out of the matching; a rig still carries it as a label).
Status readMeshRegions(const tinygltf::Model& model, const MeshChoice& choice, const std::string& label, Mesh& mesh,
                       std::vector<std::string>& warnings) {
  const tinygltf::Mesh& gmesh = model.meshes[static_cast<std::size_t>(choice.mesh)];
  const std::string name = std::string("_") + kRegionAttribute;
  if (!presentInAny(attributeAccessors(gmesh, name))) return Ok{};
  const std::string mesh_name = "mesh " + std::to_string(choice.mesh);
  VertexAttributes read;
  std::vector<std::string> dropped;
  if (auto ok = readCustomAttribute(model, gmesh, primitiveRanges(model, gmesh), name, mesh_name, label, read, dropped);
      !ok) {
    return ok.error();
  }
  const auto labels = read.labels.find(kRegionAttribute);
  if (labels == read.labels.end()) {
    warnings.push_back(name + " of " + mesh_name + " is not an integer SCALAR on every primitive; not used for region matching");
    return Ok{};
  }
  if (const Eigen::Index v = firstInvalidRegionLabel(labels->second); v >= 0) {
    warnings.push_back(name + " of vertex " + std::to_string(v) + " is " + std::to_string(labels->second(v)) +
                       " (region labels are 0.." + std::to_string(kMaxRegionLabel) + "); not used for region matching");
    return Ok{};
  }
  mesh.regions = labels->second;
  return Ok{};
}

}  // namespace

Result<LoadedMesh> chosenMesh(const ParsedGltf& parsed, const std::string& label, LoadedMesh loaded) {
  auto mesh = buildMesh(parsed.model, parsed.choice, label, std::move(loaded));
  if (!mesh) return mesh.error();
  if (auto ok = readMeshRegions(parsed.model, parsed.choice, label, mesh->mesh, mesh->report.warnings); !ok) {
    return ok.error();
  }
  return mesh;
}

namespace {

Result<LoadedMesh> readGltfImpl(Bytes bytes, const std::string& label, bool binary,
                                const std::optional<std::filesystem::path>& base_dir) {
  LoadedMesh loaded;
  auto parsed = parseGltf(bytes, label, binary, base_dir, loaded.report);
  if (!parsed) return parsed.error();
  // A mesh input (a target, a scan) is one mesh: the others are named, not lost silently.
  std::vector<std::string> others;
  for (std::size_t m = 0; m < parsed->model.meshes.size(); ++m) {
    if (static_cast<int>(m) == parsed->choice.mesh) continue;
    const std::string& name = parsed->model.meshes[m].name;
    others.push_back(name.empty() ? "mesh " + std::to_string(m) : name);
  }
  if (!others.empty()) {
    loaded.report.warnings.push_back("only " + parsed->choice.description + " was read; the file's other meshes (" +
                                     joinNames(others) + ") were dropped: a target or scan is one mesh (a rig's other "
                                     "meshes come from the source rig)");
  }
  return chosenMesh(*parsed, label, std::move(loaded));
}

}  // namespace

}  // namespace core::gltf

namespace core {

Result<LoadedMesh> readGltf(std::span<const std::uint8_t> bytes, const std::string& label, bool binary) {
  return gltf::readGltfImpl(bytes, label, binary, std::nullopt);
}

Result<LoadedMesh> readGltfWithBaseDir(std::span<const std::uint8_t> bytes, const std::string& label, bool binary,
                                       const std::filesystem::path& base_dir) {
  return gltf::readGltfImpl(bytes, label, binary, base_dir);
}

}  // namespace core
