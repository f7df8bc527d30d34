// Tests core/io/mesh_io.cpp: the reader chosen by extension then content,
// file I/O (atomic writes, mapped files, large files read in place), and the
// real third-party samples in ../shared/data read through readMesh.
#include "core/io/mesh_io.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <random>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "tests/core/io/mesh_io_support.h"
#include "tests/gltf_builder.h"
#include "tests/test_support.h"

namespace {

using core::ErrorCode;
using core::MeshFormat;
using namespace rigport_test::gltf;
using namespace rigport_test::mesh_io;

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
