// Tests the mesh reader of core/io/gltf_*.cpp (readGltf): hand-built glTF
// features (node transforms, sparse accessors, strides, modes, the mesh
// chosen), clean errors for broken files, and robustness against truncated
// and corrupt input (meshoptimizer-style memory-safety tests, also run under
// ASan/UBSan).
#include "core/io/mesh_io.h"

#include <cmath>
#include <cstring>
#include <random>
#include <span>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "tests/core/io/mesh_io_support.h"
#include "tests/gltf_builder.h"
#include "tests/test_support.h"

namespace {

using core::ErrorCode;
using core::MeshFormat;
using namespace rigport_test::gltf;
using namespace rigport_test::mesh_io;

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
  // The fan draws the strip's vertices (the same POSITION accessor): they
  // are one set of vertices in the merged mesh, not two copies.
  EXPECT_EQ(loaded->mesh.vertexCount(), 7);
  EXPECT_EQ(loaded->mesh.triangles, tris({{0, 1, 2}, {1, 3, 2}, {1, 2, 0}, {2, 3, 0}, {6, 5, 4}}));
}

TEST(GltfRead, PrimitivesWithTheirOwnVerticesAreConcatenated) {
  GltfBuilder b;
  const int quad = b.positions({0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0});
  const int copy = b.positions({0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0});  // the same values, another accessor
  b.mesh(json::array({{{"attributes", {{"POSITION", quad}}}, {"mode", 5}},
                      {{"attributes", {{"POSITION", copy}}}, {"mode", 6}}}));
  b.node({{"mesh", 0}});
  auto loaded = core::readGltf(b.glb(), "two_quads.glb", true);
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  EXPECT_EQ(loaded->mesh.vertexCount(), 8);
  EXPECT_EQ(loaded->mesh.triangles, tris({{0, 1, 2}, {1, 3, 2}, {5, 6, 4}, {6, 7, 4}}));
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

}  // namespace
