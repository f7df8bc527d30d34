// Tests core/io/mesh_io.cpp, core/io/gltf_*.cpp, core/io/obj_io.cpp and core/io/ply_io.cpp:
// round trips, the Khronos validator, hand-built glTF features (node
// transforms, sparse accessors, strides, modes), robustness against
// truncated and corrupt input (also run under ASan/UBSan), OBJ/PLY specifics
// and the real third-party samples in ../shared/data.
#include "core/io/mesh_io.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "tests/gltf_builder.h"
#include "tests/test_support.h"

namespace {

using core::ErrorCode;
using core::LoadedMesh;
using core::MeshFormat;
using namespace rigport_test::gltf;

std::string startOf(const std::string& message, std::size_t n) { return message.substr(0, n); }

// Expects a failed read whose message starts with `label` and contains `part`.
#define EXPECT_READ_ERROR(result, error_code, label, part)                                    \
  do {                                                                                        \
    const auto& r_ = (result);                                                                \
    ASSERT_FALSE(r_.ok()) << "expected an error containing: " << (part);                      \
    EXPECT_EQ(r_.error().code, (error_code)) << r_.error().message;                           \
    EXPECT_EQ(startOf(r_.error().message, std::string(label).size() + 2), std::string(label) + ": ") \
        << r_.error().message;                                                                \
    EXPECT_NE(r_.error().message.find(part), std::string::npos) << r_.error().message;        \
  } while (0)

// A unit tetrahedron with unit vertex normals and UVs.
core::Mesh makeTetrahedron(bool normals = true, bool uvs = true) {
  core::Mesh mesh;
  mesh.positions.resize(4, 3);
  mesh.positions << 0, 0, 0,  //
      1, 0, 0,                //
      0, 1, 0,                //
      0, 0, 1;
  mesh.triangles.resize(4, 3);
  mesh.triangles << 0, 2, 1,  //
      0, 1, 3,                //
      0, 3, 2,                //
      1, 2, 3;
  if (normals) mesh.normals = core::computeVertexNormals(mesh.positions, mesh.triangles);
  if (uvs) {
    mesh.uvs.resize(4, 2);
    mesh.uvs << 0, 0, 1, 0, 0, 1, 0.5, 0.5;
  }
  return mesh;
}

// An n x n vertex grid on a wavy surface, with normals and UVs.
core::Mesh makeGrid(int n) {
  core::Mesh mesh;
  mesh.positions.resize(n * n, 3);
  mesh.uvs.resize(n * n, 2);
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      const double x = i / double(n - 1);
      const double y = j / double(n - 1);
      mesh.positions.row(j * n + i) << x, y, 0.1 * std::sin(6 * x) * std::cos(4 * y);
      mesh.uvs.row(j * n + i) << x, 1 - y;
    }
  }
  mesh.triangles.resize(2 * (n - 1) * (n - 1), 3);
  int t = 0;
  for (int j = 0; j + 1 < n; ++j) {
    for (int i = 0; i + 1 < n; ++i) {
      const int a = j * n + i;
      mesh.triangles.row(t++) << a, a + 1, a + n + 1;
      mesh.triangles.row(t++) << a, a + n + 1, a + n;
    }
  }
  mesh.normals = core::computeVertexNormals(mesh.positions, mesh.triangles);
  return mesh;
}

// Float-rounded copy, for comparing with what a float32 file holds.
Eigen::MatrixXd asFloat(const Eigen::MatrixXd& m) { return m.cast<float>().cast<double>(); }

// One triangle in the z = 0 plane with +Z normals.
GltfBuilder oneTriangle(json node = json::object()) {
  GltfBuilder b;
  const int pos = b.positions({0, 0, 0, 1, 0, 0, 0, 1, 0});
  const int nrm = b.accessor(b.view(std::vector<float>{0, 0, 1, 0, 0, 1, 0, 0, 1}), kFloat, 3, "VEC3");
  const int idx = b.indices({0, 1, 2});
  b.mesh(json::array({{{"attributes", {{"POSITION", pos}, {"NORMAL", nrm}}}, {"indices", idx}}}));
  node["mesh"] = 0;
  b.node(node);
  b.doc()["scenes"] = json::array({{{"nodes", {0}}}});
  return b;
}

Eigen::MatrixX3d rows3(std::initializer_list<std::initializer_list<double>> rows) {
  Eigen::MatrixX3d m(static_cast<Eigen::Index>(rows.size()), 3);
  Eigen::Index r = 0;
  for (const auto& row : rows) {
    Eigen::Index c = 0;
    for (const double v : row) m(r, c++) = v;
    ++r;
  }
  return m;
}

Eigen::MatrixX3i tris(std::initializer_list<std::initializer_list<int>> rows) {
  Eigen::MatrixX3i m(static_cast<Eigen::Index>(rows.size()), 3);
  Eigen::Index r = 0;
  for (const auto& row : rows) {
    Eigen::Index c = 0;
    for (const int v : row) m(r, c++) = v;
    ++r;
  }
  return m;
}

void writeBytes(const std::filesystem::path& path, const ByteVector& bytes) {
  std::ofstream out(path, std::ios::binary);
  out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
}

// ===========================================================================
// GLB writing

TEST(GltfWrite, RoundTripKeepsPositionsNormalsUvsAndTriangles) {
  const core::Mesh mesh = makeGrid(7);
  auto bytes = core::encodeMeshGlb(mesh);
  ASSERT_TRUE(bytes.ok()) << bytes.error().message;
  auto loaded = core::readGltf(*bytes, "grid.glb", true);
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  EXPECT_TRUE(rigport_test::matricesNear(loaded->mesh.positions, asFloat(mesh.positions), 0.0));
  EXPECT_TRUE(rigport_test::matricesNear(loaded->mesh.normals, mesh.normals, 1e-6));
  EXPECT_TRUE(rigport_test::matricesNear(loaded->mesh.uvs, asFloat(mesh.uvs), 0.0));
  EXPECT_EQ(loaded->mesh.triangles, mesh.triangles);
  EXPECT_EQ(loaded->report.format, MeshFormat::kGlb);
  EXPECT_EQ(loaded->report.meshes_in_file, 1);
  EXPECT_FALSE(loaded->report.normals_computed);
  EXPECT_FALSE(loaded->report.point_cloud);
  EXPECT_EQ(loaded->report.degenerate_triangles, 0);
  EXPECT_EQ(loaded->report.chosen_mesh, "mesh 0 on node 0 (the only mesh)");
  EXPECT_TRUE(loaded->report.warnings.empty()) << loaded->report.warnings.front();
}

// Without NORMAL, the reader computes normals; copies of a vertex split at a
// UV seam must get one normal (else the seam shows in shading and matching).
TEST(GltfRead, ComputedNormalsAreSharedAcrossASplitSeam) {
  core::Mesh mesh = makeTetrahedron(false, false);
  mesh.positions.conservativeResize(5, 3);
  mesh.positions.row(4) = mesh.positions.row(0);
  for (int k = 0; k < 3; ++k) {
    if (mesh.triangles(2, k) == 0) mesh.triangles(2, k) = 4;
  }
  auto bytes = core::encodeMeshGlb(mesh);
  ASSERT_TRUE(bytes.ok()) << bytes.error().message;
  auto loaded = core::readGltf(*bytes, "split.glb", true);
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  EXPECT_TRUE(loaded->report.normals_computed);
  const core::Mesh& read = loaded->mesh;
  ASSERT_EQ(read.normals.rows(), 5);
  EXPECT_TRUE(read.normals.row(0) == read.normals.row(4));
  const core::Mesh whole = makeTetrahedron(false, false);
  const Eigen::MatrixX3d expected = core::computeVertexNormals(read.positions.topRows(4), whole.triangles);
  EXPECT_TRUE(rigport_test::matricesNear(read.normals.topRows(4), expected, 1e-12));
}

TEST(GltfWrite, EncodingIsDeterministic) {
  const core::Mesh mesh = makeGrid(5);
  auto a = core::encodeMeshGlb(mesh);
  auto b = core::encodeMeshGlb(mesh);
  ASSERT_TRUE(a.ok() && b.ok());
  EXPECT_EQ(*a, *b);
  EXPECT_EQ(a->size() % 4, 0u);
}

TEST(GltfWrite, WrittenFilesPassTheKhronosValidator) {
  const auto dir = rigport_test::makeTempDir("validator");
  core::Mesh zero_normal = makeTetrahedron();
  zero_normal.normals.row(2).setZero();       // must be written as some unit vector
  zero_normal.normals.row(3) *= 3.0;          // must be renormalised
  core::Mesh point_cloud = makeTetrahedron(false, false);
  point_cloud.triangles.resize(0, 3);
  const std::vector<std::pair<std::string, core::Mesh>> cases = {
      {"grid.glb", makeGrid(9)},
      {"plain.glb", makeTetrahedron(false, false)},
      {"zero_normal.glb", zero_normal},
      {"points.glb", point_cloud},
  };
  for (const auto& [name, mesh] : cases) {
    const auto path = dir / name;
    ASSERT_TRUE(core::writeMeshGlb(mesh, path).ok()) << name;
    EXPECT_GLTF_VALID(path);
  }
}

// Region labels (the _REGION custom attribute) are what region-constrained
// matching reads from a target file.
TEST(GltfWrite, RegionLabelsRoundTripAndPassTheValidator) {
  core::Mesh mesh = makeGrid(7);
  mesh.regions.resize(mesh.vertexCount());
  for (Eigen::Index v = 0; v < mesh.vertexCount(); ++v) mesh.regions(v) = static_cast<int>((v * 7) % 64);
  const auto path = rigport_test::makeTempDir("regions") / "regions.glb";
  ASSERT_TRUE(core::writeMeshGlb(mesh, path).ok());
  EXPECT_GLTF_VALID(path);
  auto loaded = core::readMesh(path);
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  EXPECT_EQ(loaded->mesh.regions, mesh.regions);
  EXPECT_TRUE(loaded->report.warnings.empty()) << loaded->report.warnings.front();
}

TEST(GltfRead, RegionLabelsBeyondTheMatchableRangeAreWarnedAndLeftOut) {
  GltfBuilder b;
  const int pos = b.positions({0, 0, 0, 1, 0, 0, 0, 1, 0});
  const int region = b.accessor(b.view(std::vector<std::uint32_t>{0, 70, 1}), kUnsignedInt, 3, "SCALAR");
  b.mesh(json::array({{{"attributes", {{"POSITION", pos}, {"_REGION", region}}}}}));
  auto loaded = core::readGltf(b.glb(), "labels.glb", true);
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  EXPECT_EQ(loaded->mesh.regions.size(), 0);
  ASSERT_EQ(loaded->report.warnings.size(), 1u);
  EXPECT_EQ(loaded->report.warnings[0],
            "_REGION of vertex 1 is 70 (region labels are 0..63); not used for region matching");
}

TEST(GltfWrite, PointCloudRoundTrip) {
  core::Mesh mesh = makeTetrahedron(false, false);
  mesh.triangles.resize(0, 3);
  auto bytes = core::encodeMeshGlb(mesh);
  ASSERT_TRUE(bytes.ok());
  auto loaded = core::readGltf(*bytes, "points.glb", true);
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  EXPECT_TRUE(loaded->report.point_cloud);
  EXPECT_EQ(loaded->mesh.triangleCount(), 0);
  EXPECT_TRUE(rigport_test::matricesNear(loaded->mesh.positions, mesh.positions, 0.0));
}

TEST(GltfWrite, RejectsInvalidMeshes) {
  core::Mesh mesh = makeTetrahedron();
  mesh.positions(1, 1) = std::nan("");
  auto bytes = core::encodeMeshGlb(mesh);
  ASSERT_FALSE(bytes.ok());
  EXPECT_EQ(bytes.error().code, ErrorCode::kInvalidMesh);
  EXPECT_FALSE(core::encodeMeshGlb(core::Mesh{}).ok());
  mesh = makeTetrahedron();
  mesh.positions(3, 2) = 1e300;  // finite, but not as float32
  bytes = core::encodeMeshGlb(mesh);
  ASSERT_FALSE(bytes.ok());
  EXPECT_EQ(bytes.error().message, "mesh to write: vertex 3 position exceeds the float32 range of glTF");
  mesh = makeTetrahedron();
  mesh.regions = Eigen::VectorXi::Zero(3);
  bytes = core::encodeMeshGlb(mesh);
  ASSERT_FALSE(bytes.ok());
  EXPECT_EQ(bytes.error().message, "mesh to write: region label count 3 differs from vertex count 4");
  mesh.regions = Eigen::VectorXi::Zero(4);
  mesh.regions(2) = 64;
  bytes = core::encodeMeshGlb(mesh);
  ASSERT_FALSE(bytes.ok());
  EXPECT_EQ(bytes.error().message, "mesh to write: vertex 2 has region label 64 (labels are 0..63)");
}

// ===========================================================================
// glTF reading: features

TEST(GltfRead, AppliesTheNodeHierarchyTransform) {
  // Parent: matrix translating by (10, 0, 0). Child: T * R * S with a 90 degree
  // rotation about X and a non-uniform scale.
  GltfBuilder b = oneTriangle({{"translation", {0, 5, 0}},
                               {"rotation", {std::sqrt(0.5), 0, 0, std::sqrt(0.5)}},
                               {"scale", {2, 3, 4}}});
  b.node({{"matrix", {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 10, 0, 0, 1}}, {"children", {0}}});
  b.doc()["scenes"][0]["nodes"] = {1};

  Eigen::Affine3d child = Eigen::Translation3d(0, 5, 0) * Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitX()) *
                          Eigen::Scaling(2.0, 3.0, 4.0);
  const Eigen::Matrix4d world = (Eigen::Translation3d(10, 0, 0) * child).matrix();
  const Eigen::Matrix3d linear = world.topLeftCorner<3, 3>();

  for (const bool binary : {true, false}) {
    auto loaded = core::readGltf(binary ? b.glb() : b.gltf(), "xform.gltf", binary);
    ASSERT_TRUE(loaded.ok()) << loaded.error().message;
    const Eigen::MatrixX3d local = rows3({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}});
    Eigen::MatrixX3d expected = (local * linear.transpose()).rowwise() + world.topRightCorner<3, 1>().transpose();
    EXPECT_TRUE(rigport_test::matricesNear(loaded->mesh.positions, expected, 1e-12));
    const Eigen::Vector3d n = (linear.inverse().transpose() * Eigen::Vector3d::UnitZ()).normalized();
    for (int v = 0; v < 3; ++v) {
      EXPECT_TRUE(rigport_test::matricesNear(loaded->mesh.normals.row(v), n.transpose(), 1e-12));
    }
    EXPECT_EQ(loaded->mesh.triangles, tris({{0, 1, 2}})) << "no mirroring: winding kept";
    EXPECT_EQ(loaded->report.format, binary ? MeshFormat::kGlb : MeshFormat::kGltf);
  }
}

TEST(GltfRead, MirroringTransformFlipsWindingAndKeepsNormalsOutward) {
  GltfBuilder b = oneTriangle({{"scale", {1, 1, -1}}});
  auto loaded = core::readGltf(b.glb(), "mirror.glb", true);
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  EXPECT_EQ(loaded->mesh.triangles, tris({{0, 2, 1}}));
  EXPECT_TRUE(rigport_test::matricesNear(loaded->mesh.normals.row(0), Eigen::RowVector3d(0, 0, -1), 1e-12));
  // The face normal of the flipped triangle agrees with the transformed normal.
  const Eigen::MatrixX3d face = core::computeFaceNormals(loaded->mesh.positions, loaded->mesh.triangles);
  EXPECT_GT(face.row(0).dot(loaded->mesh.normals.row(0)), 0.99);
}

TEST(GltfRead, MeshUsedByNoNodeKeepsItsCoordinates) {
  GltfBuilder b = oneTriangle({{"translation", {1, 2, 3}}});
  b.doc()["nodes"][0].erase("mesh");
  auto loaded = core::readGltf(b.glb(), "orphan.glb", true);
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  EXPECT_EQ(loaded->mesh.positions(1, 0), 1.0);
  EXPECT_NE(loaded->report.chosen_mesh.find("used by no node"), std::string::npos) << loaded->report.chosen_mesh;
}

TEST(GltfRead, ReadsSparsePositionAccessors) {
  // Accessor 0: no bufferView (zeros) + sparse overrides for elements 0 and 2.
  // Accessor 1: dense data + sparse override for element 1.
  GltfBuilder b;
  const int sparse_idx = b.view(std::vector<std::uint8_t>{0, 2, 0, 0});
  const int sparse_val = b.view(std::vector<float>{1, 2, 3, 4, 5, 6});
  const int pos0 = b.accessor(-1, kFloat, 3, "VEC3",
                              {{"sparse",
                                {{"count", 2},
                                 {"indices", {{"bufferView", sparse_idx}, {"componentType", kUnsignedByte}}},
                                 {"values", {{"bufferView", sparse_val}}}}}});
  const int dense = b.view(std::vector<float>{0, 0, 0, 1, 0, 0, 0, 1, 0});
  const int idx16 = b.view(std::vector<std::uint16_t>{1, 0});
  const int val1 = b.view(std::vector<float>{7, 8, 9});
  const int pos1 = b.accessor(dense, kFloat, 3, "VEC3",
                              {{"sparse",
                                {{"count", 1},
                                 {"indices", {{"bufferView", idx16}, {"componentType", kUnsignedShort}}},
                                 {"values", {{"bufferView", val1}}}}}});
  const int idx = b.indices({0, 1, 2});
  b.mesh(json::array({{{"attributes", {{"POSITION", pos0}}}, {"indices", idx}}}), "zeros");
  b.mesh(json::array({{{"attributes", {{"POSITION", pos1}}}, {"indices", idx}}}), "dense");
  b.node({{"mesh", 0}, {"skin", 0}});  // skinned: chosen first
  b.node({{"mesh", 1}});
  b.doc()["skins"] = json::array({{{"joints", {1}}}});

  auto loaded = core::readGltf(b.glb(), "sparse.glb", true);
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  EXPECT_TRUE(rigport_test::matricesNear(loaded->mesh.positions, rows3({{1, 2, 3}, {0, 0, 0}, {4, 5, 6}}), 0.0));
  EXPECT_EQ(loaded->report.chosen_mesh, "mesh 0 'zeros' on node 0 (first skinned mesh)");

  b.doc()["nodes"][0].erase("skin");
  b.doc()["meshes"][0]["primitives"][0]["indices"] = b.indices({0, 1, 2, 0, 2, 1});  // now the largest
  loaded = core::readGltf(b.glb(), "sparse.glb", true);
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  EXPECT_EQ(loaded->report.chosen_mesh, "mesh 0 'zeros' on node 0 (most triangles (2) of 2 meshes)");

  b.doc()["meshes"][1]["primitives"][0]["indices"] = b.indices({0, 1, 2, 0, 2, 1, 1, 2, 0});
  loaded = core::readGltf(b.glb(), "sparse.glb", true);
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  EXPECT_EQ(loaded->report.chosen_mesh, "mesh 1 'dense' on node 1 (most triangles (3) of 2 meshes)");
  EXPECT_TRUE(rigport_test::matricesNear(loaded->mesh.positions, rows3({{0, 0, 0}, {7, 8, 9}, {0, 1, 0}}), 0.0));
  EXPECT_EQ(loaded->report.meshes_in_file, 2);
}

TEST(GltfRead, RejectsSparseIndexOutOfRange) {
  GltfBuilder b;
  const int sparse_idx = b.view(std::vector<std::uint8_t>{7, 0, 0, 0});
  const int sparse_val = b.view(std::vector<float>{1, 2, 3});
  const int pos = b.accessor(-1, kFloat, 3, "VEC3",
                             {{"sparse",
                               {{"count", 1},
                                {"indices", {{"bufferView", sparse_idx}, {"componentType", kUnsignedByte}}},
                                {"values", {{"bufferView", sparse_val}}}}}});
  b.mesh(json::array({{{"attributes", {{"POSITION", pos}}}}}));
  EXPECT_READ_ERROR(core::readGltf(b.glb(), "s.glb", true), ErrorCode::kParse, "s.glb",
                    "accessor 0 (POSITION) sparse index 0 is 7 but the accessor has 3 elements");
}

TEST(GltfRead, ReadsInterleavedStridesAndNormalizedTexcoords) {
  // One bufferView, stride 16: float3 position, then two normalized ubytes (UV) and padding.
  std::vector<std::uint8_t> interleaved;
  const float xyz[3][3] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  const std::uint8_t uv[3][2] = {{0, 255}, {255, 0}, {51, 102}};
  for (int v = 0; v < 3; ++v) {
    const auto* p = reinterpret_cast<const std::uint8_t*>(xyz[v]);
    interleaved.insert(interleaved.end(), p, p + 12);
    interleaved.insert(interleaved.end(), {uv[v][0], uv[v][1], 0, 0});
  }
  GltfBuilder b;
  const int view = b.view(interleaved, 16);
  const int pos = b.accessor(view, kFloat, 3, "VEC3");
  const int tex = b.accessor(view, kUnsignedByte, 3, "VEC2", {{"byteOffset", 12}, {"normalized", true}});
  b.mesh(json::array({{{"attributes", {{"POSITION", pos}, {"TEXCOORD_0", tex}}}}}));  // non-indexed
  auto loaded = core::readGltf(b.glb(), "interleaved.glb", true);
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  EXPECT_TRUE(rigport_test::matricesNear(loaded->mesh.positions, rows3({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}), 0.0));
  Eigen::MatrixX2d expected_uv(3, 2);
  expected_uv << 0, 1, 1, 0, 0.2, 0.4;
  EXPECT_TRUE(rigport_test::matricesNear(loaded->mesh.uvs, expected_uv, 1e-15));
  EXPECT_EQ(loaded->mesh.triangles, tris({{0, 1, 2}})) << "non-indexed: consecutive vertices";
  EXPECT_TRUE(loaded->report.normals_computed);
  EXPECT_TRUE(rigport_test::matricesNear(loaded->mesh.normals.row(0), Eigen::RowVector3d(0, 0, 1), 1e-12));
}

TEST(GltfRead, ConvertsStripsAndFansAndMergesPrimitives) {
  GltfBuilder b;
  const int quad = b.positions({0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0});
  const int tri = b.positions({5, 5, 5, 6, 5, 5, 5, 6, 5});
  const int idx32 = b.accessor(b.view(std::vector<std::uint32_t>{2, 1, 0}), kUnsignedInt, 3, "SCALAR");
  b.mesh(json::array({{{"attributes", {{"POSITION", quad}}}, {"mode", 5}},                      // strip
                      {{"attributes", {{"POSITION", quad}}}, {"mode", 6}},                      // fan
                      {{"attributes", {{"POSITION", tri}}}, {"indices", idx32}, {"mode", 4}}}));  // uint32 indices
  b.node({{"mesh", 0}});
  auto loaded = core::readGltf(b.glb(), "modes.glb", true);
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  EXPECT_EQ(loaded->mesh.vertexCount(), 11);
  EXPECT_EQ(loaded->mesh.triangles, tris({{0, 1, 2}, {1, 3, 2}, {5, 6, 4}, {6, 7, 4}, {10, 9, 8}}));
}

TEST(GltfRead, PointsOnlyMeshIsAPointCloudButLinesAreUnsupported) {
  GltfBuilder b;
  const int pos = b.positions({0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0});
  b.mesh(json::array({{{"attributes", {{"POSITION", pos}}}, {"mode", 0}}}));
  auto loaded = core::readGltf(b.glb(), "points.glb", true);
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  EXPECT_TRUE(loaded->report.point_cloud);
  EXPECT_EQ(loaded->mesh.vertexCount(), 4);

  b.doc()["meshes"][0]["primitives"][0]["mode"] = 1;
  EXPECT_READ_ERROR(core::readGltf(b.glb(), "lines.glb", true), ErrorCode::kUnsupported, "lines.glb",
                    "mesh 0 primitive 0 uses mode LINES");

  b.doc()["meshes"][0]["primitives"][0]["mode"] = 0;
  b.doc()["meshes"][0]["primitives"].push_back({{"attributes", {{"POSITION", pos}}}, {"mode", 4}});
  b.doc()["meshes"][0]["primitives"][1]["indices"] = b.indices({0, 1, 2});
  EXPECT_READ_ERROR(core::readGltf(b.glb(), "mixed.glb", true), ErrorCode::kUnsupported, "mixed.glb",
                    "mesh 0 primitive 0 uses mode POINTS beside triangles");
}

TEST(GltfRead, OutOfRangeIndexNamesTheTriangle) {
  GltfBuilder b;
  const int pos = b.positions({0, 0, 0, 1, 0, 0, 0, 1, 0});
  const int idx = b.indices({0, 1, 2, 2, 1, 3});
  b.mesh(json::array({{{"attributes", {{"POSITION", pos}}}, {"indices", idx}}}));
  EXPECT_READ_ERROR(core::readGltf(b.glb(), "oob.glb", true), ErrorCode::kInvalidMesh, "oob.glb",
                    "triangle 1 (mesh 0 primitive 0) refers to vertex 3 but the primitive has 3 vertices");
}

TEST(GltfRead, AccessorPastTheEndOfItsBufferIsAParseError) {
  GltfBuilder b = oneTriangle();
  b.doc()["accessors"][0]["count"] = 4;  // 48 bytes from a 36-byte bufferView
  EXPECT_READ_ERROR(core::readGltf(b.glb(), "head.glb", true), ErrorCode::kParse, "head.glb",
                    "accessor 0 (POSITION) reads past the end of bufferView 0 (needs 48 bytes at offset 0, "
                    "bufferView 0 has 36)");

  b = oneTriangle();
  b.doc()["bufferViews"][0]["byteLength"] = 400;
  b.doc()["accessors"][0]["count"] = 30;
  EXPECT_READ_ERROR(core::readGltf(b.glb(), "head.glb", true), ErrorCode::kParse, "head.glb",
                    "accessor 0 (POSITION) reads past the end of buffer 0 (needs 400 bytes at offset 0, buffer has");

  b = oneTriangle();
  b.doc()["accessors"][0]["byteOffset"] = 18446744073709551000ull;  // overflow bait
  EXPECT_READ_ERROR(core::readGltf(b.glb(), "head.glb", true), ErrorCode::kParse, "head.glb", "reads past the end");
}

TEST(GltfRead, NaNPositionIsAnInvalidMesh) {
  GltfBuilder b;
  const int pos = b.positions({0, 0, 0, 1, std::nanf(""), 0, 0, 1, 0});
  b.mesh(json::array({{{"attributes", {{"POSITION", pos}}}}}));
  EXPECT_READ_ERROR(core::readGltf(b.glb(), "nan.glb", true), ErrorCode::kInvalidMesh, "nan.glb",
                    "vertex 1 has a non-finite position");
}

TEST(GltfRead, ExternalBuffersAreRefusedFromMemoryAndConfinedFromFiles) {
  GltfBuilder b = oneTriangle();
  json doc = b.doc();
  doc["buffers"] = json::array({{{"byteLength", b.bin().size()}, {"uri", "tri.bin"}}});
  const ByteVector text = toBytes(doc.dump());
  EXPECT_READ_ERROR(core::readGltf(text, "tri.gltf", false), ErrorCode::kUnsupported, "tri.gltf",
                    "buffer 0 refers to the external file 'tri.bin'");

  const auto dir = rigport_test::makeTempDir("external");
  writeBytes(dir / "tri.gltf", text);
  writeBytes(dir / "tri.bin", b.bin());
  auto loaded = core::readMesh(dir / "tri.gltf");
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  EXPECT_EQ(loaded->mesh.vertexCount(), 3);

  doc["buffers"][0]["uri"] = "../external/tri.bin";
  writeBytes(dir / "escape.gltf", toBytes(doc.dump()));
  EXPECT_READ_ERROR(core::readMesh(dir / "escape.gltf"), ErrorCode::kUnsupported, "escape.gltf",
                    "is not a relative file name inside the glTF's directory");

  doc["buffers"][0]["uri"] = "missing.bin";
  writeBytes(dir / "missing.gltf", toBytes(doc.dump()));
  EXPECT_READ_ERROR(core::readMesh(dir / "missing.gltf"), ErrorCode::kParse, "missing.gltf", "missing.bin");
}

TEST(GltfRead, RejectsCompressedGeometryExtensions) {
  GltfBuilder b = oneTriangle();
  b.doc()["extensionsUsed"] = {"KHR_draco_mesh_compression"};
  b.doc()["extensionsRequired"] = {"KHR_draco_mesh_compression"};
  EXPECT_READ_ERROR(core::readGltf(b.glb(), "draco.glb", true), ErrorCode::kUnsupported, "draco.glb",
                    "KHR_draco_mesh_compression");
}

TEST(GltfRead, BrokenContainersAndHierarchiesGiveCleanErrors) {
  EXPECT_READ_ERROR(core::readGltf(toBytes("glTF"), "a.glb", true), ErrorCode::kParse, "a.glb", "truncated GLB");
  EXPECT_READ_ERROR(core::readGltf(toBytes("{\"asset\": "), "a.gltf", false), ErrorCode::kParse, "a.gltf",
                    "not valid glTF JSON");
  EXPECT_READ_ERROR(core::readGltf(toBytes("PK\x03\x04 not a glb at all"), "a.glb", true), ErrorCode::kParse, "a.glb",
                    "not a binary glTF");
  GltfBuilder b = oneTriangle();
  b.node({{"children", {0}}});
  b.doc()["nodes"][0]["children"] = {1};  // 0 -> 1 -> 0
  EXPECT_READ_ERROR(core::readGltf(b.glb(), "cycle.glb", true), ErrorCode::kParse, "cycle.glb",
                    "the node hierarchy has a cycle");
  b = oneTriangle();
  b.doc()["nodes"][0]["children"] = {5};
  EXPECT_READ_ERROR(core::readGltf(b.glb(), "child.glb", true), ErrorCode::kParse, "child.glb",
                    "node 0 lists child 5 but the file has 1 nodes");
  b = oneTriangle();
  b.doc().erase("meshes");
  b.doc()["nodes"][0].erase("mesh");
  EXPECT_READ_ERROR(core::readGltf(b.glb(), "empty.glb", true), ErrorCode::kInvalidMesh, "empty.glb", "no mesh");
}

// ===========================================================================
// glTF reading: robustness (meshoptimizer-style memory-safety tests)

TEST(GltfRobustness, EveryTruncationOfASmallGlbIsACleanError) {
  auto bytes = core::encodeMeshGlb(makeTetrahedron());
  ASSERT_TRUE(bytes.ok());
  for (std::size_t n = 0; n < bytes->size(); ++n) {
    const auto result = core::readGltf(std::span(bytes->data(), n), "cut.glb", true);
    ASSERT_FALSE(result.ok()) << "prefix of " << n << " bytes was accepted";
    EXPECT_EQ(result.error().code, ErrorCode::kParse) << result.error().message;
    EXPECT_EQ(result.error().message.rfind("cut.glb: ", 0), 0u) << result.error().message;
  }
}

TEST(GltfRobustness, TruncatedChunksWithConsistentHeadersAreCleanErrors) {
  // Cut the BIN chunk but patch the GLB and chunk lengths to match, so the
  // container looks fine and the accessor bounds checks must catch it.
  auto bytes = core::encodeMeshGlb(makeGrid(4));
  ASSERT_TRUE(bytes.ok());
  auto [doc, bin] = splitGlb(*bytes);
  for (std::size_t n = 4; n < bin.size(); n += 4) {
    json d = doc;
    d["buffers"][0]["byteLength"] = n;
    const ByteVector glb = makeGlb(d, ByteVector(bin.begin(), bin.begin() + static_cast<std::ptrdiff_t>(n)));
    const auto result = core::readGltf(glb, "cut.glb", true);
    ASSERT_FALSE(result.ok()) << n;
    EXPECT_EQ(result.error().code, ErrorCode::kParse) << result.error().message;
  }
}

TEST(GltfRobustness, GarbageBytesAreCleanErrors) {
  std::mt19937 rng(1234);
  for (int i = 0; i < 300; ++i) {
    ByteVector bytes(rng() % 2048);
    for (auto& b : bytes) b = static_cast<std::uint8_t>(rng());
    if (i % 3 == 1 && bytes.size() >= 20) {  // plausible GLB header, random rest
      std::memcpy(bytes.data(), "glTF", 4);
      const std::uint8_t version[4] = {2, 0, 0, 0};
      std::memcpy(bytes.data() + 4, version, 4);
      const auto size = static_cast<std::uint32_t>(bytes.size());
      std::memcpy(bytes.data() + 8, &size, 4);
    }
    for (const bool binary : {true, false}) {
      const auto result = core::readGltf(bytes, "noise.glb", binary);
      ASSERT_FALSE(result.ok());
      EXPECT_EQ(result.error().message.rfind("noise.glb: ", 0), 0u) << result.error().message;
    }
  }
}

// Collects JSON pointers of every number in a document.
void numberPointers(const json& value, const json::json_pointer& at, std::vector<json::json_pointer>& out) {
  if (value.is_number()) out.push_back(at);
  if (value.is_object()) {
    for (auto it = value.begin(); it != value.end(); ++it) numberPointers(it.value(), at / it.key(), out);
  }
  if (value.is_array()) {
    for (std::size_t i = 0; i < value.size(); ++i) numberPointers(value[i], at / i, out);
  }
}

TEST(GltfRobustness, CorruptedJsonFieldsAndBinBytesNeverCrash) {
  // Sparse + dense + strided data, then random rewrites of numeric JSON fields
  // (offsets, counts, strides, indices, types) and random BIN byte flips.
  GltfBuilder b = oneTriangle({{"translation", {1, 2, 3}}});
  const int sparse_idx = b.view(std::vector<std::uint16_t>{0, 2});
  const int sparse_val = b.view(std::vector<float>{1, 2, 3, 4, 5, 6});
  b.doc()["accessors"][0]["sparse"] = {{"count", 2},
                                       {"indices", {{"bufferView", sparse_idx}, {"componentType", kUnsignedShort}}},
                                       {"values", {{"bufferView", sparse_val}}}};
  const int uv = b.accessor(b.view(std::vector<std::uint8_t>{0, 0, 255, 0, 0, 255, 9, 9}), kUnsignedByte, 3, "VEC2",
                            {{"normalized", true}});
  b.doc()["meshes"][0]["primitives"][0]["attributes"]["TEXCOORD_0"] = uv;
  b.doc()["buffers"] = json::array({{{"byteLength", b.bin().size()}}});
  const json base = b.doc();
  ASSERT_TRUE(core::readGltf(b.glb(), "fuzz.glb", true).ok());

  std::vector<json::json_pointer> pointers;
  numberPointers(base, json::json_pointer(), pointers);
  const std::vector<double> values = {-1, 0, 1, 2, 3, 4, 5, 7, 12, 36, 255, 5120, 5126, 65535, 2147483647.0,
                                      4294967296.0, 9007199254740992.0, 1e300, 0.5};
  std::mt19937 rng(42);
  int accepted = 0;
  for (int i = 0; i < 1500; ++i) {
    json doc = base;
    ByteVector bin = b.bin();
    const int edits = 1 + static_cast<int>(rng() % 3);
    for (int e = 0; e < edits; ++e) {
      const auto& ptr = pointers[rng() % pointers.size()];
      const double v = values[rng() % values.size()];
      if (v == std::floor(v) && std::abs(v) < 1e18) {
        doc[ptr] = static_cast<long long>(v);
      } else {
        doc[ptr] = v;
      }
    }
    if (i % 4 == 0) bin[rng() % bin.size()] = static_cast<std::uint8_t>(rng());
    const auto result = core::readGltf(makeGlb(doc, bin), "fuzz.glb", true);
    if (result.ok()) {
      ++accepted;
      EXPECT_TRUE(core::validateMesh(result->mesh, "fuzz").ok());
    } else {
      EXPECT_EQ(result.error().message.rfind("fuzz.glb: ", 0), 0u) << result.error().message;
    }
  }
  EXPECT_GT(accepted, 0);  // some edits are harmless (e.g. translation values)
}

// ===========================================================================
// Real third-party samples

TEST(GltfSamples, AllKhronosSamplesLoad) {
  RIGPORT_REQUIRE_SHARED_DATA(dir);
  for (const char* name : {"AnimatedMorphCube.glb", "Fox.glb", "MorphPrimitivesTest.glb", "MorphStressTest.glb",
                           "SimpleMorph.glb", "SimpleSkin.glb", "SparseMorphCube.glb"}) {
    auto loaded = core::readMesh(dir / "gltf" / name);
    ASSERT_TRUE(loaded.ok()) << name << ": " << loaded.error().message;
    EXPECT_GT(loaded->mesh.triangleCount(), 0) << name;
    EXPECT_EQ(loaded->mesh.normals.rows(), loaded->mesh.vertexCount()) << name;
    EXPECT_TRUE(core::validateMesh(loaded->mesh, name).ok()) << name;
  }
}

TEST(GltfSamples, FoxIsNonIndexedAndSkinned) {
  RIGPORT_REQUIRE_SHARED_DATA(dir);
  auto loaded = core::readMesh(dir / "gltf" / "Fox.glb");
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  EXPECT_EQ(loaded->mesh.vertexCount(), 1728);
  EXPECT_EQ(loaded->mesh.triangleCount(), 576);
  EXPECT_EQ(loaded->mesh.triangles.row(1), Eigen::RowVector3i(3, 4, 5));
  EXPECT_EQ(loaded->mesh.uvs.rows(), 1728);
  EXPECT_TRUE(loaded->report.normals_computed);
  EXPECT_EQ(loaded->report.chosen_mesh, "mesh 0 'fox1' on node 1 'fox' (first skinned mesh)");
}

TEST(GltfSamples, SimpleSkinAndSparseMorphCube) {
  RIGPORT_REQUIRE_SHARED_DATA(dir);
  auto skin = core::readMesh(dir / "gltf" / "SimpleSkin.glb");
  ASSERT_TRUE(skin.ok()) << skin.error().message;
  EXPECT_EQ(skin->mesh.vertexCount(), 10);
  EXPECT_EQ(skin->mesh.triangleCount(), 8);
  EXPECT_NE(skin->report.chosen_mesh.find("first skinned mesh"), std::string::npos);

  auto cube = core::readMesh(dir / "gltf" / "SparseMorphCube.glb");
  ASSERT_TRUE(cube.ok()) << cube.error().message;
  EXPECT_EQ(cube->mesh.vertexCount(), 24);
  EXPECT_EQ(cube->mesh.triangleCount(), 12);
}

TEST(GltfSamples, MorphPrimitivesTestMergesBothPrimitives) {
  RIGPORT_REQUIRE_SHARED_DATA(dir);
  auto loaded = core::readMesh(dir / "gltf" / "MorphPrimitivesTest.glb");
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  EXPECT_EQ(loaded->mesh.vertexCount(), 21 + 9);
  EXPECT_EQ(loaded->mesh.triangleCount(), (72 + 24) / 3);
  // Triangles of the second primitive refer to its own (offset) vertices.
  EXPECT_GE(loaded->mesh.triangles.bottomRows(8).minCoeff(), 21);
}

TEST(GltfSamples, AnimatedMorphCubeNodeTransformIsApplied) {
  RIGPORT_REQUIRE_SHARED_DATA(dir);
  auto loaded = core::readMesh(dir / "gltf" / "AnimatedMorphCube.glb");
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  // The node scales the 2 cm cube (diagonal 0.0346) by 100 and rotates it.
  EXPECT_NEAR(core::boundingBoxDiagonal(loaded->mesh.positions), 2.0 * std::sqrt(3.0), 1e-5);
}

TEST(GltfSamples, IctSourceFaceAndRemeshedTarget) {
  RIGPORT_REQUIRE_SHARED_DATA(dir);
  auto source = core::readMesh(dir / "ict" / "source_face.glb");
  ASSERT_TRUE(source.ok()) << source.error().message;
  EXPECT_EQ(source->mesh.vertexCount(), 11248);
  EXPECT_EQ(source->mesh.triangleCount(), 22288);
  EXPECT_FALSE(source->report.normals_computed);
  EXPECT_EQ(source->report.chosen_mesh, "mesh 0 'ict_face' on node 0 'face' (the only mesh)");

  auto target = core::readMesh(dir / "ict" / "targets" / "id_s01_remesh.glb");
  ASSERT_TRUE(target.ok()) << target.error().message;
  EXPECT_EQ(target->mesh.vertexCount(), 5884);

  auto skinned = core::readMesh(dir / "ict" / "source_face_skinned.glb");
  ASSERT_TRUE(skinned.ok()) << skinned.error().message;
  EXPECT_TRUE(rigport_test::matricesNear(skinned->mesh.positions, source->mesh.positions, 0.0));

  // Re-encoded ICT face: valid and identical after a round trip.
  const auto out = rigport_test::makeTempDir("ict") / "source_face_rewritten.glb";
  ASSERT_TRUE(core::writeMeshGlb(source->mesh, out).ok());
  EXPECT_GLTF_VALID(out);
  auto again = core::readMesh(out);
  ASSERT_TRUE(again.ok()) << again.error().message;
  EXPECT_TRUE(rigport_test::matricesNear(again->mesh.positions, source->mesh.positions, 0.0));
  EXPECT_EQ(again->mesh.triangles, source->mesh.triangles);
}

TEST(GltfSamples, TruncatedIctFaceIsACleanError) {
  RIGPORT_REQUIRE_SHARED_DATA(dir);
  auto bytes = core::readFileBytes(dir / "ict" / "targets" / "id_s01_remesh.glb");
  ASSERT_TRUE(bytes.ok());
  for (std::size_t n = 0; n < bytes->size(); n += bytes->size() / 29 + 1) {
    const auto result = core::readGltf(std::span(bytes->data(), n), "cut.glb", true);
    ASSERT_FALSE(result.ok()) << n;
    EXPECT_EQ(result.error().code, ErrorCode::kParse);
  }
}

// ===========================================================================
// OBJ

TEST(ObjRead, FanTriangulatesQuadsAndPentagons) {
  const std::string obj =
      "# quad, pentagon and a triangle\n"
      "o shape\n"
      "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
      "v 3 0 0\nv 4 0 0\nv 4.5 1 0\nv 3.5 2 0\nv 2.5 1 0\n"
      "f 1 2 3 4\n"
      "f 5 6 7 8 9\n"
      "g other\n"
      "f 1 2 5\n";
  auto loaded = core::readObj(toBytes(obj), "poly.obj");
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  EXPECT_EQ(loaded->mesh.vertexCount(), 9);
  EXPECT_EQ(loaded->mesh.triangles, tris({{0, 1, 2}, {0, 2, 3}, {4, 5, 6}, {4, 6, 7}, {4, 7, 8}, {0, 1, 4}}));
  EXPECT_EQ(loaded->report.polygons_triangulated, 2);
  EXPECT_EQ(loaded->report.format, MeshFormat::kObj);
  EXPECT_TRUE(loaded->report.normals_computed);
  EXPECT_EQ(loaded->mesh.uvs.rows(), 0);
}

TEST(ObjRead, KeepsPerVertexNormalsAndFlipsTextureV) {
  const std::string obj =
      "v 0 0 0\r\nv 1 0 0\r\nv 0 1 0\r\nv 1 1 0\r\n"
      "vt 0 0\r\nvt 1 0\r\nvt 0 1\r\nvt 1 0.25\r\n"
      "vn 0 0 2\r\nvn 0 0 1\r\n"
      "f 1/1/1 2/2/1 3/3/2\r\nf 2/2/1 4/4/1 3/3/2\r\n";
  auto loaded = core::readObj(toBytes(obj), "uv.obj");
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  Eigen::MatrixX2d uv(4, 2);
  uv << 0, 1, 1, 1, 0, 0, 1, 0.75;
  EXPECT_TRUE(rigport_test::matricesNear(loaded->mesh.uvs, uv, 0.0));
  EXPECT_FALSE(loaded->report.normals_computed);
  EXPECT_TRUE(rigport_test::matricesNear(loaded->mesh.normals, rows3({{0, 0, 1}, {0, 0, 1}, {0, 0, 1}, {0, 0, 1}}), 0.0));
  EXPECT_TRUE(loaded->report.warnings.empty());
}

TEST(ObjRead, UvSeamsDropUvsAndConflictingNormalsAreRecomputed) {
  const std::string obj =
      "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\n"
      "vt 0 0\nvt 1 0\nvt 0 1\nvt 1 1\nvt 0.5 0.5\n"
      "vn 0 0 1\nvn 1 0 0\n"
      "f 1/1/1 2/2/1 3/3/1\nf 2/5/2 4/4/1 3/3/1\n";
  auto loaded = core::readObj(toBytes(obj), "seam.obj");
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  EXPECT_EQ(loaded->mesh.uvs.rows(), 0);
  EXPECT_TRUE(loaded->report.normals_computed);
  ASSERT_EQ(loaded->report.warnings.size(), 2u);
  EXPECT_NE(loaded->report.warnings[0].find("vertex 1 has several"), std::string::npos) << loaded->report.warnings[0];
  EXPECT_NE(loaded->report.warnings[1].find("UVs dropped"), std::string::npos) << loaded->report.warnings[1];
  EXPECT_EQ(loaded->mesh.vertexCount(), 4) << "vertices are never split";
}

TEST(ObjRead, ResolvesNegativeRelativeIndices) {
  auto loaded = core::readObj(toBytes("v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -1\nv 2 2 0\nf -4 -2 -1\n"), "rel.obj");
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  EXPECT_EQ(loaded->mesh.triangles, tris({{0, 1, 2}, {0, 2, 3}}));
}

TEST(ObjRead, NonFiniteVertexIsNamedWithItsLine) {
  EXPECT_READ_ERROR(core::readObj(toBytes("# c\nv 0 0 0\nv 1 nan 0\nv 0 1 0\nf 1 2 3\n"), "face.obj"),
                    ErrorCode::kInvalidMesh, "face.obj", "vertex 1 (line 3) has a non-finite coordinate (y = nan)");
  EXPECT_READ_ERROR(core::readObj(toBytes("v 0 0 0\nv 1 0 1e999\n"), "face.obj"), ErrorCode::kInvalidMesh, "face.obj",
                    "vertex 1 (line 2) has a non-finite coordinate (z = 1e999)");
  EXPECT_READ_ERROR(core::readObj(toBytes("v 0 0 0\nv 1 0 zero\n"), "face.obj"), ErrorCode::kParse, "face.obj",
                    "vertex 1 (line 2) has a coordinate that is not a number ('zero')");
  EXPECT_READ_ERROR(core::readObj(toBytes("v 0 0\n"), "face.obj"), ErrorCode::kParse, "face.obj",
                    "vertex 0 (line 1) has fewer than 3 coordinates");
}

TEST(ObjRead, OutOfRangeIndicesNameTheTriangle) {
  EXPECT_READ_ERROR(core::readObj(toBytes("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3\nf 1 2 3 9\n"), "idx.obj"),
                    ErrorCode::kInvalidMesh, "idx.obj",
                    "triangle 2 (face 1) refers to vertex 9 (OBJ numbers from 1) but the file has 4 vertices");
  EXPECT_READ_ERROR(core::readObj(toBytes("v 0 0 0\nv 1 0 0\nv 0 1 0\nf -5 1 2\n"), "idx.obj"),
                    ErrorCode::kInvalidMesh, "idx.obj", "triangle 0 (face 0) refers to a vertex before the first one");
  EXPECT_READ_ERROR(core::readObj(toBytes("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n"), "idx.obj"), ErrorCode::kParse,
                    "idx.obj", "");
  EXPECT_READ_ERROR(core::readObj(toBytes("v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//1 3//4\n"), "idx.obj"),
                    ErrorCode::kParse, "idx.obj", "face 0 refers to normal 4 (OBJ numbers from 1) but the file has 1");
}

TEST(ObjRead, VerticesWithoutFacesAreAPointCloud) {
  auto loaded = core::readObj(toBytes("v 0 0 0\nv 1 0 0\nv 0 1 0\n"), "cloud.obj");
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  EXPECT_TRUE(loaded->report.point_cloud);
  EXPECT_EQ(loaded->mesh.vertexCount(), 3);
  EXPECT_EQ(loaded->mesh.triangleCount(), 0);
}

// Degenerate faces (a repeated corner, three collinear corners) are kept and
// counted, the same by every reader.
TEST(MeshRead, DegenerateTrianglesAreKeptAndCountedByEveryReader) {
  const std::string obj = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 2 0 0\nf 1 2 3\nf 1 2 2\nf 1 2 4\n";
  auto from_obj = core::readObj(toBytes(obj), "flat.obj");
  ASSERT_TRUE(from_obj.ok()) << from_obj.error().message;
  EXPECT_EQ(from_obj->mesh.triangleCount(), 3);
  EXPECT_EQ(from_obj->report.degenerate_triangles, 2);
  const std::string ply =
      "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
      "element face 3\nproperty list uchar int vertex_indices\nend_header\n"
      "0 0 0\n1 0 0\n0 1 0\n2 0 0\n3 0 1 2\n3 0 1 1\n3 0 1 3\n";
  auto from_ply = core::readPly(toBytes(ply), "flat.ply");
  ASSERT_TRUE(from_ply.ok()) << from_ply.error().message;
  EXPECT_EQ(from_ply->report.degenerate_triangles, 2);
  auto glb = core::encodeMeshGlb(from_obj->mesh);
  ASSERT_TRUE(glb.ok()) << glb.error().message;
  auto from_glb = core::readGltf(*glb, "flat.glb", true);
  ASSERT_TRUE(from_glb.ok()) << from_glb.error().message;
  EXPECT_EQ(from_glb->mesh.triangleCount(), 3);
  EXPECT_EQ(from_glb->report.degenerate_triangles, 2);
}

TEST(ObjRead, GarbageIsAParseError) {
  EXPECT_READ_ERROR(core::readObj(toBytes(""), "g.obj"), ErrorCode::kParse, "g.obj", "no vertices");
  EXPECT_READ_ERROR(core::readObj(toBytes("hello world\nthis is not a mesh\n"), "g.obj"), ErrorCode::kParse, "g.obj",
                    "no vertices");
  std::mt19937 rng(7);
  for (int i = 0; i < 100; ++i) {
    ByteVector bytes(rng() % 1024 + 1);
    for (auto& b : bytes) b = static_cast<std::uint8_t>(rng());
    const auto result = core::readObj(bytes, "g.obj");
    if (!result.ok()) {
      EXPECT_EQ(result.error().message.rfind("g.obj: ", 0), 0u);
    }
  }
}

// ===========================================================================
// PLY

const char* kAsciiPly =
    "ply\n"
    "format ascii 1.0\n"
    "comment made by hand\n"
    "element vertex 5\n"
    "property float x\n"
    "property float y\n"
    "property float z\n"
    "property uchar confidence\n"
    "property float s\n"
    "property float t\n"
    "element face 2\n"
    "property list uchar int vertex_indices\n"
    "property list uchar float texcoord\n"
    "element edge 1\n"
    "property int vertex1\n"
    "property int vertex2\n"
    "end_header\n"
    "0 0 0 9 0 0\n"
    "1 0 0 9 1 0\n"
    "1 1 0 9 1 1\n"
    "0 1 0 9 0 1\n"
    "2 2 2 9 0.5 0.25\n"
    "4 0 1 2 3 2 0.5 0.5\n"
    "3 0 1 4 0\n"
    "0 1\n";

TEST(PlyRead, AsciiWithPolygonsUvsAndSkippedProperties) {
  auto loaded = core::readPly(toBytes(kAsciiPly), "a.ply");
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  EXPECT_EQ(loaded->mesh.vertexCount(), 5);
  EXPECT_EQ(loaded->mesh.triangles, tris({{0, 1, 2}, {0, 2, 3}, {0, 1, 4}}));
  EXPECT_EQ(loaded->report.polygons_triangulated, 1);
  EXPECT_EQ(loaded->report.format, MeshFormat::kPly);
  EXPECT_TRUE(loaded->report.normals_computed);
  ASSERT_EQ(loaded->mesh.uvs.rows(), 5);
  EXPECT_EQ(loaded->mesh.uvs.row(4), Eigen::RowVector2d(0.5, 0.75));
  EXPECT_EQ(loaded->mesh.positions.row(4), Eigen::RowVector3d(2, 2, 2));
}

// A scan's region labels (the glTF _REGION of PLY): an integer vertex
// property 'region'; values outside 0..63 or a float property are warned and
// left out.
TEST(PlyRead, RegionPropertyGivesRegionLabels) {
  auto ply = [](const std::string& type, const std::string& values) {
    std::string text = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                       "property " + type + " region\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n";
    std::istringstream in(values);
    const double xyz[3][3] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
    for (const auto& p : xyz) {
      std::string value;
      in >> value;
      text += std::to_string(p[0]) + " " + std::to_string(p[1]) + " " + std::to_string(p[2]) + " " + value + "\n";
    }
    return toBytes(text + "3 0 1 2\n");
  };
  auto labelled = core::readPly(ply("uchar", "0 2 63"), "labelled.ply");
  ASSERT_TRUE(labelled.ok()) << labelled.error().message;
  EXPECT_EQ(labelled->mesh.regions, (Eigen::VectorXi(3) << 0, 2, 63).finished());
  EXPECT_TRUE(labelled->report.warnings.empty());

  auto beyond = core::readPly(ply("int", "1 70 2"), "beyond.ply");
  ASSERT_TRUE(beyond.ok()) << beyond.error().message;
  EXPECT_EQ(beyond->mesh.regions.size(), 0);
  ASSERT_EQ(beyond->report.warnings.size(), 1u);
  EXPECT_EQ(beyond->report.warnings[0],
            "PLY vertex property 'region' of vertex 1 is 70 (region labels are 0..63); not used for region matching");

  auto floats = core::readPly(ply("float", "1 2 3"), "floats.ply");
  ASSERT_TRUE(floats.ok()) << floats.error().message;
  EXPECT_EQ(floats->mesh.regions.size(), 0);
  ASSERT_EQ(floats->report.warnings.size(), 1u);
  EXPECT_EQ(floats->report.warnings[0], "PLY vertex property 'region' is not an integer scalar; not used for region matching");
}

// Little-endian PLY body writer.
struct PlyBody {
  ByteVector bytes;
  template <typename T>
  PlyBody& put(T value) {
    const auto* p = reinterpret_cast<const std::uint8_t*>(&value);
    bytes.insert(bytes.end(), p, p + sizeof(T));
    return *this;
  }
};

ByteVector binaryPly(float y1 = 0.0f) {
  const std::string header =
      "ply\r\n"
      "format binary_little_endian 1.0\r\n"
      "element vertex 4\r\n"
      "property double x\r\nproperty double y\r\nproperty double z\r\n"
      "property float nx\r\nproperty float ny\r\nproperty float nz\r\n"
      "property list uchar int extra_list\r\n"
      "property uint8 red\r\n"
      "element face 2\r\n"
      "property list uchar uint vertex_indices\r\n"
      "property int16 flags\r\n"
      "end_header\r\n";
  PlyBody body;
  const double xyz[4][3] = {{0, 0, 0}, {1, y1, 0}, {0, 1, 0}, {1, 1, 0.5}};
  for (int v = 0; v < 4; ++v) {
    body.put(xyz[v][0]).put(xyz[v][1]).put(xyz[v][2]);
    body.put(0.0f).put(0.0f).put(2.0f);
    body.put(std::uint8_t{2}).put(std::int32_t{7}).put(std::int32_t{8});
    body.put(std::uint8_t{200});
  }
  body.put(std::uint8_t{3}).put(std::uint32_t{0}).put(std::uint32_t{1}).put(std::uint32_t{2}).put(std::int16_t{-1});
  body.put(std::uint8_t{3}).put(std::uint32_t{1}).put(std::uint32_t{3}).put(std::uint32_t{2}).put(std::int16_t{-1});
  ByteVector out = toBytes(header);
  out.insert(out.end(), body.bytes.begin(), body.bytes.end());
  return out;
}

TEST(PlyRead, BinaryLittleEndianWithDoublesNormalsAndExtraLists) {
  auto loaded = core::readPly(binaryPly(), "b.ply");
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  EXPECT_TRUE(rigport_test::matricesNear(loaded->mesh.positions,
                                         rows3({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 0.5}}), 0.0));
  EXPECT_EQ(loaded->mesh.triangles, tris({{0, 1, 2}, {1, 3, 2}}));
  EXPECT_FALSE(loaded->report.normals_computed);
  EXPECT_EQ(loaded->mesh.normals.row(3), Eigen::RowVector3d(0, 0, 1)) << "normals renormalised";
}

TEST(PlyRead, EveryTruncationOfABinaryPlyIsACleanError) {
  const ByteVector bytes = binaryPly();
  for (std::size_t n = 0; n < bytes.size(); ++n) {
    const auto result = core::readPly(std::span(bytes.data(), n), "cut.ply");
    ASSERT_FALSE(result.ok()) << n;
    EXPECT_EQ(result.error().code, ErrorCode::kParse) << result.error().message;
    EXPECT_EQ(result.error().message.rfind("cut.ply: ", 0), 0u) << result.error().message;
  }
}

TEST(PlyRead, PointsOnly) {
  const std::string ply =
      "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
      "element face 0\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 0 1\n";
  auto loaded = core::readPly(toBytes(ply), "pts.ply");
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  EXPECT_TRUE(loaded->report.point_cloud);
  EXPECT_EQ(loaded->mesh.vertexCount(), 3);

  const std::string no_faces =
      "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\n"
      "end_header\n0 0 0\n";
  loaded = core::readPly(toBytes(no_faces), "pts.ply");
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  EXPECT_TRUE(loaded->report.point_cloud);
}

TEST(PlyRead, BigEndianIsUnsupported) {
  const std::string ply =
      "ply\nformat binary_big_endian 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\n"
      "end_header\n123456789012";
  EXPECT_READ_ERROR(core::readPly(toBytes(ply), "be.ply"), ErrorCode::kUnsupported, "be.ply", "binary_big_endian");
}

TEST(PlyRead, HugeClaimedCountsAreRejectedBeforeAllocating) {
  // Under ASan an attempted 24 TB allocation would abort the test.
  for (const char* format : {"binary_little_endian", "ascii"}) {
    const std::string ply = std::string("ply\nformat ") + format +
                            " 1.0\nelement vertex 1000000000000\nproperty float x\nproperty float y\n"
                            "property float z\nend_header\n0 0 0\n";
    const auto result = core::readPly(toBytes(ply), "huge.ply");
    ASSERT_FALSE(result.ok());
    EXPECT_EQ(result.error().message.rfind("huge.ply: ", 0), 0u) << result.error().message;
  }
  const std::string faces =
      "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
      "property float z\nelement face 900000000\nproperty list uchar int vertex_indices\nend_header\n";
  ByteVector bytes = toBytes(faces);
  bytes.resize(bytes.size() + 36 + 13, 0);
  EXPECT_READ_ERROR(core::readPly(bytes, "huge.ply"), ErrorCode::kParse, "huge.ply",
                    "claims 900000000 'face' elements");
  const std::string list =
      "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
      "element face 1\nproperty list uint int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n4000000000 0 1 2\n";
  EXPECT_READ_ERROR(core::readPly(toBytes(list), "huge.ply"), ErrorCode::kParse, "huge.ply",
                    "face 0 has an invalid list length");
}

TEST(PlyRead, NonFiniteVertexAndBadIndexAreNamed) {
  std::string ply =
      "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
      "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 nan 0\n0 1 0\n3 0 1 2\n";
  EXPECT_READ_ERROR(core::readPly(toBytes(ply), "face.ply"), ErrorCode::kInvalidMesh, "face.ply",
                    "vertex 1 has a non-finite coordinate (y = nan)");
  EXPECT_READ_ERROR(core::readPly(binaryPly(std::numeric_limits<float>::infinity()), "face.ply"),
                    ErrorCode::kInvalidMesh, "face.ply", "vertex 1 has a non-finite coordinate (y = inf)");
  ply = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
        "element face 2\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n4 0 1 2 3\n";
  EXPECT_READ_ERROR(core::readPly(toBytes(ply), "face.ply"), ErrorCode::kInvalidMesh, "face.ply",
                    "triangle 2 (face 1) refers to vertex 3 but the file has 3 vertices");
  ply = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
        "end_header\n0 0 0\n1 zero 0\n0 1 0\n";
  EXPECT_READ_ERROR(core::readPly(toBytes(ply), "face.ply"), ErrorCode::kParse, "face.ply",
                    "vertex 1: 'zero' is not a number");
}

TEST(PlyRead, MalformedHeadersAndGarbage) {
  EXPECT_READ_ERROR(core::readPly(toBytes("ply\nformat ascii 1.0\nelement vertex 1\n"), "h.ply"), ErrorCode::kParse,
                    "h.ply", "no end_header");
  EXPECT_READ_ERROR(core::readPly(toBytes("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\n0\n"),
                                  "h.ply"),
                    ErrorCode::kParse, "h.ply", "no scalar 'y' property");
  EXPECT_READ_ERROR(core::readPly(toBytes("ply\nformat ascii 1.0\nproperty float x\nend_header\n"), "h.ply"),
                    ErrorCode::kParse, "h.ply", "line 3: property before any element");
  std::mt19937 rng(99);
  for (int i = 0; i < 200; ++i) {
    ByteVector bytes = toBytes(kAsciiPly);
    for (int e = 0; e < 3; ++e) bytes[rng() % bytes.size()] = static_cast<std::uint8_t>(rng());
    const auto result = core::readPly(bytes, "m.ply");
    if (!result.ok()) {
      EXPECT_EQ(result.error().message.rfind("m.ply: ", 0), 0u);
    }
  }
}

// ===========================================================================
// Dispatch and file I/O

TEST(MeshIo, ChoosesTheReaderByExtensionThenByContent) {
  const auto dir = rigport_test::makeTempDir("dispatch");
  auto glb = core::encodeMeshGlb(makeTetrahedron());
  ASSERT_TRUE(glb.ok());
  writeBytes(dir / "upper.GLB", *glb);
  writeBytes(dir / "sniffed.bin", *glb);
  writeBytes(dir / "mesh.PLY", toBytes(kAsciiPly));
  writeBytes(dir / "mesh.data", toBytes(kAsciiPly));
  writeBytes(dir / "mesh.Obj", toBytes("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"));
  writeBytes(dir / "mesh.txt", toBytes("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"));

  const std::vector<std::pair<std::string, MeshFormat>> ok_cases = {
      {"upper.GLB", MeshFormat::kGlb}, {"sniffed.bin", MeshFormat::kGlb}, {"mesh.PLY", MeshFormat::kPly},
      {"mesh.data", MeshFormat::kPly}, {"mesh.Obj", MeshFormat::kObj}};
  for (const auto& [name, format] : ok_cases) {
    auto loaded = core::readMesh(dir / name);
    ASSERT_TRUE(loaded.ok()) << name << ": " << loaded.error().message;
    EXPECT_EQ(loaded->report.format, format) << name;
  }
  EXPECT_READ_ERROR(core::readMesh(dir / "mesh.txt"), ErrorCode::kUnsupported, "mesh.txt", "unrecognised");
}

TEST(MeshIo, ReadFromMemoryUsesTheGivenFormatAndLabel) {
  auto loaded = core::readMeshFromMemory(toBytes(kAsciiPly), MeshFormat::kPly, "upload.target");
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  EXPECT_READ_ERROR(core::readMeshFromMemory(toBytes(kAsciiPly), MeshFormat::kGlb, "upload.target"),
                    ErrorCode::kParse, "upload.target", "not a binary glTF");
}

TEST(MeshIo, MissingFileIsAnIoErrorNamingThePath) {
  const auto path = rigport_test::makeTempDir("missing") / "nope.glb";
  const auto result = core::readMesh(path);
  ASSERT_FALSE(result.ok());
  EXPECT_EQ(result.error().code, ErrorCode::kIo);
  EXPECT_NE(result.error().message.find(path.string()), std::string::npos) << result.error().message;
  EXPECT_NE(result.error().message.find("No such file"), std::string::npos) << result.error().message;
}

TEST(MeshIo, WriteFileBytesReplacesAtomicallyAndLeavesNoTempFiles) {
  const auto dir = rigport_test::makeTempDir("atomic");
  const auto path = dir / "out.bin";
  ASSERT_TRUE(core::writeFileBytes(path, toBytes("first version")).ok());
  ASSERT_TRUE(core::writeFileBytes(path, toBytes("second")).ok());
  auto bytes = core::readFileBytes(path);
  ASSERT_TRUE(bytes.ok());
  EXPECT_EQ(std::string(bytes->begin(), bytes->end()), "second");
  EXPECT_EQ(std::distance(std::filesystem::directory_iterator(dir), std::filesystem::directory_iterator()), 1);

  const auto bad = dir / "no_such_dir" / "out.bin";
  const auto status = core::writeFileBytes(bad, toBytes("x"));
  ASSERT_FALSE(status.ok());
  EXPECT_EQ(status.error().code, ErrorCode::kIo);
  EXPECT_NE(status.error().message.find(bad.string()), std::string::npos) << status.error().message;

  // Renaming onto a directory fails after the temp file was written: it must be removed.
  std::filesystem::create_directory(dir / "occupied");
  std::filesystem::create_directory(dir / "occupied" / "child");
  EXPECT_FALSE(core::writeFileBytes(dir / "occupied", toBytes("x")).ok());
  EXPECT_EQ(std::distance(std::filesystem::directory_iterator(dir), std::filesystem::directory_iterator()), 2);
}

TEST(MeshIo, MappedFileHoldsTheFileBytesLargeOrSmall) {
  const auto dir = rigport_test::makeTempDir("mapped");
  std::vector<std::uint8_t> large(3u << 19);  // 1.5 MB: mapped
  std::mt19937 rng(7);
  for (auto& b : large) b = static_cast<std::uint8_t>(rng());
  ASSERT_TRUE(core::writeFileBytes(dir / "large.bin", large).ok());
  ASSERT_TRUE(core::writeFileBytes(dir / "small.bin", toBytes("small file")).ok());

  auto mapped = core::MappedFile::open(dir / "large.bin");
  ASSERT_TRUE(mapped.ok()) << mapped.error().message;
  EXPECT_TRUE(std::ranges::equal(mapped->bytes(), large));
  core::MappedFile moved = std::move(*mapped);  // the mapping moves with it
  EXPECT_TRUE(mapped->bytes().empty());
  EXPECT_TRUE(std::ranges::equal(moved.bytes(), large));
  auto small = core::MappedFile::open(dir / "small.bin");
  ASSERT_TRUE(small.ok());
  moved = std::move(*small);  // the large mapping is released, the small bytes taken over
  EXPECT_EQ(std::string(moved.bytes().begin(), moved.bytes().end()), "small file");

  const auto missing = core::MappedFile::open(dir / "nope.bin");
  ASSERT_FALSE(missing.ok());
  EXPECT_EQ(missing.error().code, ErrorCode::kIo);
  EXPECT_NE(missing.error().message.find((dir / "nope.bin").string()), std::string::npos);
}

TEST(MeshIo, ReadMeshReadsALargeFileInPlace) {
  // 40k vertices: a GLB over the size from which MappedFile maps.
  core::Mesh mesh;
  const int n = 200;
  mesh.positions.resize(n * n, 3);
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) mesh.positions.row(i * n + j) << i, j, 0.25 * ((i * j) % 7);  // exact in float
  }
  mesh.triangles.resize(2 * (n - 1) * (n - 1), 3);
  int t = 0;
  for (int i = 0; i + 1 < n; ++i) {
    for (int j = 0; j + 1 < n; ++j) {
      const int v = i * n + j;
      mesh.triangles.row(t++) << v, v + n, v + 1;
      mesh.triangles.row(t++) << v + 1, v + n, v + n + 1;
    }
  }
  const auto path = rigport_test::makeTempDir("large") / "grid.glb";
  ASSERT_TRUE(core::writeMeshGlb(mesh, path).ok());
  ASSERT_GE(std::filesystem::file_size(path), std::uintmax_t{1} << 20);
  auto loaded = core::readMesh(path);
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  EXPECT_TRUE(rigport_test::matricesNear(loaded->mesh.positions, mesh.positions, 0.0));
  EXPECT_EQ(loaded->mesh.triangles, mesh.triangles);
}

TEST(MeshIo, WriteMeshGlbThenReadMesh) {
  const auto path = rigport_test::makeTempDir("glb") / "tet.glb";
  const core::Mesh mesh = makeTetrahedron();
  ASSERT_TRUE(core::writeMeshGlb(mesh, path).ok());
  auto loaded = core::readMesh(path);
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  EXPECT_TRUE(rigport_test::matricesNear(loaded->mesh.positions, mesh.positions, 0.0));
  EXPECT_EQ(loaded->mesh.triangles, mesh.triangles);
}

}  // namespace
