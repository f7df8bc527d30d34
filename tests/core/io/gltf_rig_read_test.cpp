// Tests the rig reader of core/io/gltf_rig_read.cpp and gltf_skin_read.cpp
// (readRigGltf) on hand-made and broken files: influences merged and
// renormalised, bad weights, joints and animations named in the error, node
// matrices, custom attributes, rigs too large for memory, truncated and
// corrupted bytes.
#include "core/io/rig_io.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <nlohmann/json.hpp>
#include <span>
#include <string>
#include <vector>

#include "tests/core/io/rig_io_support.h"
#include "tests/gltf_builder.h"
#include "tests/test_support.h"

namespace {

using core::ErrorCode;
using namespace rigport_test::gltf;
using namespace rigport_test::rig_io;
using rigport_test::matricesNear;

// One triangle skinned to two joints (identity inverse binds) with the given
// JOINTS_0 (unsigned byte) and WEIGHTS_0 (float) for its 3 vertices.
GltfBuilder skinnedTriangle(const std::vector<std::uint8_t>& joints, const std::vector<float>& weights) {
  GltfBuilder b;
  const int pos = b.accessor(b.view(std::vector<float>{0, 0, 0, 1, 0, 0, 0, 1, 0}), kFloat, 3, "VEC3",
                             {{"min", {0, 0, 0}}, {"max", {1, 1, 0}}});
  const int idx = b.accessor(b.view(std::vector<std::uint16_t>{0, 1, 2}), kUnsignedShort, 3, "SCALAR");
  const int j = b.accessor(b.view(joints), kUnsignedByte, 3, "VEC4");
  const int w = b.accessor(b.view(weights), kFloat, 3, "VEC4");
  b.doc()["meshes"] = json::array(
      {{{"primitives",
         json::array({{{"attributes", {{"POSITION", pos}, {"JOINTS_0", j}, {"WEIGHTS_0", w}}}, {"indices", idx}}})}}});
  b.doc()["nodes"] = json::array(
      {{{"mesh", 0}, {"skin", 0}}, {{"name", "j0"}, {"children", {2}}}, {{"name", "j1"}, {"translation", {0, 1, 0}}}});
  b.doc()["skins"] = json::array({{{"name", "tri_skin"}, {"joints", {1, 2}}}});
  b.doc()["scenes"] = json::array({{{"nodes", {0, 1}}}});
  return b;
}

// ===========================================================================
// Reading hand-made and broken files

TEST(RigRead, MergesRepeatedJointsDropsZeroWeightsAndRenormalises) {
  GltfBuilder b = skinnedTriangle({1, 1, 0, 1, /**/ 0, 1, 0, 0, /**/ 0, 1, 0, 0},
                                  {0.25f, 0.25f, 0.5f, 0.0f, /**/ 0.5f, 0.5f, 0, 0, /**/ 2.0f, 2.0f, 0, 0});
  auto loaded = core::readRigGltf(b.glb(), "tri.glb", true);
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  const Eigen::MatrixXd w = dense(loaded->rig.weights);
  EXPECT_TRUE(matricesNear(w, (Eigen::MatrixXd(3, 2) << 0.5, 0.5, 0.5, 0.5, 0.5, 0.5).finished(), 1e-12));
  EXPECT_EQ(row(loaded->rig.weights, 0).size(), 2u);
  const auto& warnings = loaded->report.warnings;
  EXPECT_TRUE(std::any_of(warnings.begin(), warnings.end(), [](const auto& m) {
    return m.find("1 vertices") != std::string::npos;
  })) << ::testing::PrintToString(warnings);
  EXPECT_EQ(loaded->rig.skin->name, "tri_skin");
  EXPECT_EQ(loaded->rig.skin->inverse_bind[1], Eigen::Matrix4d::Identity());  // no accessor: identity
}

TEST(RigRead, BadWeightsAndJointsNameTheVertex) {
  auto negative = core::readRigGltf(
      skinnedTriangle({0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0}, {1, 0, 0, 0, 1.5f, -0.5f, 0, 0, 1, 0, 0, 0}).glb(),
      "tri.glb", true);
  ASSERT_FALSE(negative.ok());
  EXPECT_EQ(negative.error().code, ErrorCode::kInvalidMesh);
  EXPECT_NE(negative.error().message.find("vertex 1"), std::string::npos) << negative.error().message;

  auto joint = core::readRigGltf(
      skinnedTriangle({0, 1, 0, 0, 0, 1, 0, 0, 0, 7, 0, 0}, {1, 0, 0, 0, 1, 0, 0, 0, 0.5f, 0.5f, 0, 0}).glb(),
      "tri.glb", true);
  ASSERT_FALSE(joint.ok());
  EXPECT_NE(joint.error().message.find("vertex 2 uses joint 7"), std::string::npos) << joint.error().message;

  // Out-of-range joint with zero weight is ignored (and so is the slot).
  auto ignored = core::readRigGltf(
      skinnedTriangle({0, 9, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0}, {1, 0, 0, 0, 1, 0, 0, 0, 0.5f, 0.5f, 0, 0}).glb(),
      "tri.glb", true);
  EXPECT_TRUE(ignored.ok()) << ignored.error().message;
}

TEST(RigRead, SkinJointOutOfRangeIsAParseErrorNamingTheSkinAndJoint) {
  GltfBuilder b = skinnedTriangle({0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0}, {1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0});
  b.doc()["skins"][0]["joints"] = {1, 12};
  auto loaded = core::readRigGltf(b.glb(), "tri.glb", true);
  ASSERT_FALSE(loaded.ok());
  EXPECT_EQ(loaded.error().code, ErrorCode::kParse);
  EXPECT_NE(loaded.error().message.find("skin 0 'tri_skin' joint 1 refers to node 12"), std::string::npos)
      << loaded.error().message;

  // The same in a written rig.
  auto [doc, bin] = splitGlb(mustEncode(makeRig()));
  doc["skins"][0]["joints"][3] = 400;
  auto written = core::readRigGltf(makeGlb(doc, bin), "rig.glb", true);
  ASSERT_FALSE(written.ok());
  EXPECT_NE(written.error().message.find("joint 3 refers to node 400"), std::string::npos) << written.error().message;

  b = skinnedTriangle({0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0}, {1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0});
  b.doc()["skins"][0]["joints"] = {1, 1};
  EXPECT_FALSE(core::readRigGltf(b.glb(), "tri.glb", true).ok());
}

TEST(RigRead, BrokenAnimationsAreParseErrorsNamingTheChannel) {
  const ByteVector good = mustEncode(makeRig());
  {
    auto [doc, bin] = splitGlb(good);
    doc["animations"][0]["channels"][1]["target"]["node"] = 99;
    auto loaded = core::readRigGltf(makeGlb(doc, bin), "rig.glb", true);
    ASSERT_FALSE(loaded.ok());
    EXPECT_EQ(loaded.error().code, ErrorCode::kParse);
    EXPECT_NE(loaded.error().message.find("animation 0 'wave' channel 1 targets node 99"), std::string::npos)
        << loaded.error().message;
  }
  {
    auto [doc, bin] = splitGlb(good);
    const int output = doc["animations"][0]["samplers"][0]["output"];
    doc["accessors"][output]["count"] = 2;
    auto loaded = core::readRigGltf(makeGlb(doc, bin), "rig.glb", true);
    ASSERT_FALSE(loaded.ok());
    EXPECT_NE(loaded.error().message.find("animation 0 'wave' channel 0 output has 2 elements"), std::string::npos)
        << loaded.error().message;
  }
  {
    auto [doc, bin] = splitGlb(good);
    doc["animations"][0]["samplers"][2]["interpolation"] = "BEZIER";
    EXPECT_FALSE(core::readRigGltf(makeGlb(doc, bin), "rig.glb", true).ok());
  }
}

TEST(RigRead, NodeMatricesAreDecomposedAndShearIsReported) {
  GltfBuilder b = skinnedTriangle({0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0}, {1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0});
  const Eigen::Quaterniond q(Eigen::AngleAxisd(0.4, Eigen::Vector3d(0, 1, 1).normalized()));
  Eigen::Affine3d trs = Eigen::Translation3d(1, 2, 3) * q * Eigen::Scaling(2.0, 3.0, 0.5);
  std::vector<double> m(trs.matrix().data(), trs.matrix().data() + 16);  // column-major
  b.doc()["nodes"][1]["matrix"] = m;
  b.doc()["nodes"][2].erase("translation");
  b.doc()["nodes"][2]["matrix"] = {1, 0, 0, 0, 0.5, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};  // shear
  auto loaded = core::readRigGltf(b.glb(), "tri.glb", true);
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  const core::Node& node = loaded->rig.nodes[1];
  EXPECT_TRUE(matricesNear(node.translation, Eigen::Vector3d(1, 2, 3), 1e-12));
  EXPECT_TRUE(rotationsNear(node.rotation, q, 1e-12));
  EXPECT_TRUE(matricesNear(node.scale, Eigen::Vector3d(2, 3, 0.5), 1e-12));
  const auto& warnings = loaded->report.warnings;
  EXPECT_TRUE(std::any_of(warnings.begin(), warnings.end(), [](const auto& w) {
    return w.find("node 2 'j1' matrix has shear") != std::string::npos;
  })) << ::testing::PrintToString(warnings);
}

TEST(RigRead, ReadsColorsCustomAttributesAndQuantisedRotations) {
  GltfBuilder b = skinnedTriangle({0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0}, {1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0});
  json& attributes = b.doc()["meshes"][0]["primitives"][0]["attributes"];
  attributes["COLOR_0"] = b.accessor(b.view(std::vector<std::uint8_t>{255, 0, 0, 0, 0, 255, 0, 0, 0, 0, 51, 0}),
                                     kUnsignedByte, 3, "VEC3", {{"normalized", true}});
  b.doc()["bufferViews"].back()["byteStride"] = 4;
  attributes["_FLAG"] = b.accessor(b.view(std::vector<std::uint16_t>{7, 0, 8, 0, 9, 0}), kUnsignedShort, 3, "SCALAR");
  b.doc()["bufferViews"].back()["byteStride"] = 4;
  attributes["_W"] = b.accessor(b.view(std::vector<std::uint16_t>{0, 65535, 65535, 0, 0, 0}), kUnsignedShort, 3,
                                "VEC2", {{"normalized", true}});
  attributes["_PAIR"] = b.accessor(b.view(std::vector<std::uint16_t>{1, 2, 3, 4, 5, 6}), kUnsignedShort, 3, "VEC2");
  attributes["TEXCOORD_0"] = b.accessor(b.view(std::vector<float>{0, 0, 1, 0, 0, 1}), kFloat, 3, "VEC2");
  attributes["TEXCOORD_1"] = b.accessor(b.view(std::vector<float>{0.5f, 0, 1, 0, 0, 1}), kFloat, 3, "VEC2");
  const int times = b.accessor(b.view(std::vector<float>{0, 1}), kFloat, 2, "SCALAR", {{"min", {0}}, {"max", {1}}});
  const int rotations = b.accessor(b.view(std::vector<std::int16_t>{0, 0, 0, 32767, 23170, 0, 0, 23170}), 5122, 2,
                                   "VEC4", {{"normalized", true}});
  b.doc()["animations"] = json::array(
      {{{"samplers", json::array({{{"input", times}, {"output", rotations}}})},
        {"channels", json::array({{{"sampler", 0}, {"target", {{"node", 2}, {"path", "rotation"}}}}})}}});
  auto loaded = core::readRigGltf(b.glb(), "attributes.glb", true);
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  const core::VertexAttributes& read = loaded->rig.attributes;
  EXPECT_TRUE(matricesNear(read.colors, (Eigen::MatrixXd(3, 4) << 1, 0, 0, 1, 0, 1, 0, 1, 0, 0, 0.2, 1).finished(), 1e-12));
  ASSERT_EQ(read.labels.count("FLAG"), 1u);
  EXPECT_EQ(read.labels.at("FLAG"), Eigen::Vector3i(7, 8, 9));
  ASSERT_EQ(read.fields.count("W"), 1u);
  EXPECT_TRUE(matricesNear(read.fields.at("W"), (Eigen::MatrixXd(3, 2) << 0, 1, 1, 0, 0, 0).finished(), 0.0));
  EXPECT_EQ(read.fields.count("PAIR") + read.labels.count("PAIR"), 0u);  // integer VEC2: warned, dropped
  ASSERT_EQ(read.extra_uv_sets.size(), 1u);
  EXPECT_EQ(read.extra_uv_sets[0](0, 0), 0.5);
  const auto& warnings = loaded->report.warnings;
  EXPECT_TRUE(std::any_of(warnings.begin(), warnings.end(), [](const auto& w) { return w.find("_PAIR") != std::string::npos; }))
      << ::testing::PrintToString(warnings);
  ASSERT_EQ(loaded->rig.animations.size(), 1u);
  const Eigen::MatrixXd& q = loaded->rig.animations[0].channels[0].values;
  EXPECT_TRUE(matricesNear(q.row(0), Eigen::RowVector4d(0, 0, 0, 1), 1e-12));
  EXPECT_TRUE(matricesNear(q.row(1), Eigen::RowVector4d(std::sqrt(0.5), 0, 0, std::sqrt(0.5)), 1e-12));  // unit

  const ByteVector bytes = mustEncode(loaded->rig);
  expectAttributesEqual(loaded->rig, mustRead(bytes).rig);
  EXPECT_GLB_CLEAN(bytes, "attributes");
}

TEST(RigRead, RigsTooLargeForMemoryAreRejectedBeforeReading) {
  // Accessors without a bufferView cost no file bytes but 2^24 elements each.
  GltfBuilder b = skinnedTriangle({0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0}, {1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0});
  const int huge = b.accessor(-1, kFloat, std::size_t{1} << 24, "VEC4");
  const int times = b.accessor(-1, kFloat, std::size_t{1} << 24, "SCALAR");
  json samplers = json::array();
  json channels = json::array();
  for (int i = 0; i < 3; ++i) {
    samplers.push_back({{"input", times}, {"output", huge}});
    channels.push_back({{"sampler", i}, {"target", {{"node", 1 + i % 2}, {"path", i < 2 ? "rotation" : "scale"}}}});
  }
  b.doc()["animations"] = json::array({{{"samplers", samplers}, {"channels", channels}}});
  auto loaded = core::readRigGltf(b.glb(), "huge.glb", true);
  ASSERT_FALSE(loaded.ok());
  EXPECT_EQ(loaded.error().code, ErrorCode::kUnsupported) << loaded.error().message;
}

TEST(RigRead, EveryTruncationOfARigGlbIsACleanError) {
  const ByteVector bytes = mustEncode(makeRig());
  for (std::size_t n = 0; n < bytes.size(); ++n) {
    auto loaded = core::readRigGltf(std::span<const std::uint8_t>(bytes.data(), n), "cut.glb", true);
    ASSERT_FALSE(loaded.ok()) << "prefix of " << n << " bytes";
    EXPECT_EQ(loaded.error().message.rfind("cut.glb: ", 0), 0u) << loaded.error().message;
  }
}

TEST(RigRead, TruncatedSamplesAreCleanErrors) {
  RIGPORT_REQUIRE_SHARED_DATA(data);
  for (const char* name : {"SimpleSkin.glb", "SparseMorphCube.glb"}) {
    auto bytes = core::readFileBytes(data / "gltf" / name);
    ASSERT_TRUE(bytes.ok());
    for (std::size_t n = 0; n < bytes->size(); n += 7) {
      auto loaded = core::readRigGltf(std::span<const std::uint8_t>(bytes->data(), n), name, true);
      EXPECT_FALSE(loaded.ok()) << name << " prefix of " << n << " bytes";
    }
  }
}

TEST(RigRead, CorruptedBinBytesNeverCrash) {
  const ByteVector good = mustEncode(makeRig());
  const auto [doc, bin] = splitGlb(good);
  for (std::size_t i = 0; i < bin.size(); i += 3) {
    ByteVector corrupt = bin;
    corrupt[i] ^= 0xFF;
    auto loaded = core::readRigGltf(makeGlb(doc, corrupt), "corrupt.glb", true);
    if (!loaded.ok()) {
      EXPECT_EQ(loaded.error().message.rfind("corrupt.glb: ", 0), 0u) << loaded.error().message;
    }
  }
}

}  // namespace
