// Tests the mesh writer of core/io/gltf_write.cpp (encodeMeshGlb, writeMeshGlb):
// round trips through the reader, deterministic bytes, region labels, point
// clouds, meshes it refuses, and every written file through the Khronos
// validator.
#include "core/io/mesh_io.h"

#include <cmath>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "tests/core/io/mesh_io_support.h"
#include "tests/test_support.h"

namespace {

using core::ErrorCode;
using core::MeshFormat;
using namespace rigport_test::mesh_io;

// Float-rounded copy, for comparing with what a float32 file holds.
Eigen::MatrixXd asFloat(const Eigen::MatrixXd& m) { return m.cast<float>().cast<double>(); }

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

}  // namespace
