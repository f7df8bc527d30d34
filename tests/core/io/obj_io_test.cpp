// Tests core/io/obj_io.cpp (readObj): polygons, normals and texture
// coordinates, relative indices, errors that name the line or face, point
// clouds, garbage; and degenerate triangles counted alike by every reader.
#include "core/io/mesh_io.h"

#include <random>
#include <string>

#include <gtest/gtest.h>

#include "tests/core/io/mesh_io_support.h"
#include "tests/gltf_builder.h"
#include "tests/test_support.h"

namespace {

using core::ErrorCode;
using core::MeshFormat;
using namespace rigport_test::gltf;
using namespace rigport_test::mesh_io;

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

}  // namespace
