// Tests core/io/ply_io.cpp (readPly): ASCII and binary bodies, polygons, UVs,
// region labels, skipped properties, truncation, huge claimed counts and
// malformed headers.
#include "core/io/mesh_io.h"

#include <cstdint>
#include <limits>
#include <random>
#include <span>
#include <sstream>
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

}  // namespace
