// Tests the rig reader and writer of core/io/gltf_*.cpp (core/io/rig_io.h) on
// the files in ../shared/data: round trips of the Khronos samples and the ICT
// rig files (every written GLB through the Khronos validator), and what they
// are read to hold.
#include "core/io/rig_io.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <algorithm>
#include <cstring>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "tests/core/io/rig_io_support.h"
#include "tests/gltf_builder.h"
#include "tests/test_support.h"

namespace {

using core::AnimationPath;
using core::LoadedRig;
using core::Rig;
using namespace rigport_test::gltf;
using namespace rigport_test::rig_io;
using rigport_test::matricesNear;

// ===========================================================================
// Samples in ../shared/data

class RigSamples : public ::testing::TestWithParam<const char*> {};

TEST_P(RigSamples, RoundTripPreservesTheRigAndPassesTheValidator) {
  RIGPORT_REQUIRE_SHARED_DATA(data);
  const std::string name = GetParam();
  auto original = core::readRig(data / "gltf" / name);
  ASSERT_TRUE(original.ok()) << original.error().message;
  const ByteVector bytes = mustEncode(original->rig);
  ASSERT_FALSE(bytes.empty());
  const LoadedRig back = mustRead(bytes);
  const bool four_influences = name == "Fox.glb" || name == "SimpleSkin.glb";
  expectRigsEqual(original->rig, back.rig, four_influences);
  const auto path = writeTemp(bytes, name.substr(0, name.size() - 4));
  EXPECT_GLTF_VALID(path);
  EXPECT_EQ(rigport_test::validateGltf(path).warnings, 0);
}

INSTANTIATE_TEST_SUITE_P(Gltf, RigSamples,
                         ::testing::Values("AnimatedMorphCube.glb", "Fox.glb", "MorphPrimitivesTest.glb",
                                           "MorphStressTest.glb", "SimpleMorph.glb", "SimpleSkin.glb",
                                           "SparseMorphCube.glb"),
                         [](const ::testing::TestParamInfo<const char*>& param) {
                           std::string n = param.param;
                           return n.substr(0, n.size() - 4);
                         });

TEST(RigSampleContent, KhronosSamplesHaveTheirSkinsMorphsAndAnimations) {
  RIGPORT_REQUIRE_SHARED_DATA(data);
  auto fox = core::readRig(data / "gltf" / "Fox.glb");
  ASSERT_TRUE(fox.ok()) << fox.error().message;
  ASSERT_TRUE(fox->rig.skin);
  EXPECT_EQ(fox->rig.skin->joints.size(), 24u);
  EXPECT_EQ(fox->rig.mesh_node, 1);
  ASSERT_EQ(fox->rig.animations.size(), 3u);
  EXPECT_EQ(fox->rig.animations[0].name, "Survey");
  EXPECT_EQ(fox->rig.nodes.size(), 26u);

  auto skin = core::readRig(data / "gltf" / "SimpleSkin.glb");
  ASSERT_TRUE(skin.ok()) << skin.error().message;
  EXPECT_EQ(skin->rig.weights.rows(), 10);
  EXPECT_EQ(skin->rig.nodes[2].parent, 1);
  ASSERT_EQ(skin->rig.animations.size(), 1u);
  EXPECT_EQ(skin->rig.animations[0].channels[0].path, AnimationPath::kRotation);
  EXPECT_EQ(skin->rig.animations[0].channels[0].values.rows(), 12);

  auto stress = core::readRig(data / "gltf" / "MorphStressTest.glb");
  ASSERT_TRUE(stress.ok()) << stress.error().message;
  ASSERT_EQ(stress->rig.morph_targets.size(), 8u);
  EXPECT_EQ(stress->rig.morph_targets[7].name, "Key 8");
  EXPECT_EQ(stress->rig.morph_targets[0].position_deltas.rows(), 24 + 1504);  // both primitives merged
  EXPECT_EQ(stress->rig.morph_targets[0].normal_deltas.rows(), 24 + 1504);
  ASSERT_EQ(stress->rig.attributes.extra_uv_sets.size(), 1u);  // TEXCOORD_1
  ASSERT_EQ(stress->rig.animations.size(), 3u);
  EXPECT_EQ(stress->rig.animations[0].channels[0].values.cols(), 8);

  auto cube = core::readRig(data / "gltf" / "SparseMorphCube.glb");
  ASSERT_TRUE(cube.ok()) << cube.error().message;
  ASSERT_EQ(cube->rig.morph_targets.size(), 1u);
  EXPECT_EQ(cube->rig.morph_targets[0].name, "blendShape1.pCube2");
  EXPECT_NEAR(cube->rig.morph_targets[0].position_deltas.col(0).maxCoeff(), 0.015, 1e-9);

  // AnimatedMorphCube: unskinned under a rotated, scaled node; world space,
  // deltas included; TANGENT is reported as dropped.
  auto animated = core::readRig(data / "gltf" / "AnimatedMorphCube.glb");
  ASSERT_TRUE(animated.ok()) << animated.error().message;
  EXPECT_NEAR(animated->rig.morph_targets[1].position_deltas.cwiseAbs().maxCoeff(), 1.989, 1e-3);
  const auto& warnings = animated->report.warnings;
  EXPECT_TRUE(std::any_of(warnings.begin(), warnings.end(),
                          [](const std::string& w) { return w.find("TANGENT") != std::string::npos; }));
}

// ---------------------------------------------------------------------------
// ICT rig files

TEST(RigIct, SkinnedSourceFaceHasTheDocumentedRig) {
  RIGPORT_REQUIRE_SHARED_DATA(data);
  auto loaded = core::readRig(data / "ict" / "source_face_skinned.glb");
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  const Rig& rig = loaded->rig;
  EXPECT_EQ(loaded->report.warnings, std::vector<std::string>{});
  EXPECT_EQ(rig.mesh.vertexCount(), 11248);
  EXPECT_EQ(rig.mesh_node, 0);
  EXPECT_EQ(rig.nodes[0].name, "face");
  ASSERT_TRUE(rig.skin);
  const std::vector<std::string> names = {"root", "neck", "head", "jaw", "eye_L", "eye_R"};
  ASSERT_EQ(rig.skin->joints.size(), names.size());
  for (std::size_t j = 0; j < names.size(); ++j) {
    EXPECT_EQ(rig.nodes[static_cast<std::size_t>(rig.skin->joints[j])].name, names[j]);
  }
  // Bind pose: inverse binds are the inverses of the joints' world transforms.
  const std::vector<Eigen::Matrix4d> world = core::nodeWorldTransforms(rig.nodes);
  for (std::size_t j = 0; j < names.size(); ++j) {
    const Eigen::Matrix4d product = rig.skin->inverse_bind[j] * world[static_cast<std::size_t>(rig.skin->joints[j])];
    EXPECT_TRUE(matricesNear(product, Eigen::Matrix4d::Identity(), 1e-5)) << names[j];
  }
  EXPECT_TRUE(matricesNear(world[4].topRightCorner<3, 1>(), Eigen::Vector3d(0, 2.18, 2.16), 0.01));  // jaw

  ASSERT_EQ(rig.morph_targets.size(), 53u);
  auto has_target = [&](const std::string& n) {
    return std::any_of(rig.morph_targets.begin(), rig.morph_targets.end(), [&](const auto& t) { return t.name == n; });
  };
  EXPECT_TRUE(has_target("jawOpen"));
  EXPECT_TRUE(has_target("eyeBlink_L"));
  EXPECT_TRUE(has_target("mouthSmile_R"));

  ASSERT_EQ(rig.animations.size(), 2u);
  EXPECT_EQ(rig.animations[0].name, "jaw_open_head_turn");
  EXPECT_EQ(rig.animations[1].name, "expression_weights");
  for (const auto& animation : rig.animations) {
    for (const auto& channel : animation.channels) EXPECT_EQ(channel.times.size(), 61);
  }
  EXPECT_EQ(rig.animations[1].channels[0].values.cols(), 53);

  const Eigen::MatrixXd weights = dense(rig.weights);
  EXPECT_TRUE(matricesNear(weights.rowwise().sum(), Eigen::VectorXd::Ones(weights.rows()), 1e-9));
  EXPECT_GE(weights.minCoeff(), 0.0);
  EXPECT_EQ(weights.col(4).cwiseAbs().maxCoeff(), 0.0);  // eyes carry no weight
  EXPECT_EQ(weights.col(5).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_GT(weights.col(3).maxCoeff(), 0.5);  // the jaw does
}

TEST(RigIct, SkinnedSourceFaceRoundTripsAndValidates) {
  RIGPORT_REQUIRE_SHARED_DATA(data);
  auto loaded = core::readRig(data / "ict" / "source_face_skinned.glb");
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  const ByteVector bytes = mustEncode(loaded->rig);
  const LoadedRig back = mustRead(bytes);
  expectRigsEqual(loaded->rig, back.rig, /*same_influence_sets=*/true);
  const auto path = writeTemp(bytes, "source_face_skinned");
  EXPECT_GLTF_VALID(path);
  EXPECT_EQ(rigport_test::validateGltf(path).warnings, 0);
}

// A rig as studios deliver faces: the face plus eyeballs, teeth, gums and
// tongue, lashes, each a mesh of its own on the face's skin, with its shapes,
// and one clip driving every mesh's morph weights.
TEST(RigIct, MultiMeshRigKeepsEveryMeshRoundTripsAndValidates) {
  RIGPORT_REQUIRE_SHARED_DATA(data);
  auto loaded = core::readRig(data / "ict" / "source_face_full.glb");
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  const Rig& rig = loaded->rig;
  EXPECT_EQ(rig.mesh_name, "ict_face");
  const std::vector<std::string> expected = {"eyeball_L", "eyeball_R", "teeth", "gums_tongue", "eyelashes_L", "eyelashes_R"};
  ASSERT_EQ(rig.parts.size(), expected.size());
  for (std::size_t p = 0; p < expected.size(); ++p) {
    const core::RigPart& part = rig.parts[p];
    EXPECT_EQ(part.name, expected[p]);
    EXPECT_GT(part.mesh.triangleCount(), 0);
    EXPECT_EQ(part.weights.rows(), part.mesh.vertexCount()) << part.name << " is skinned";
    EXPECT_EQ(part.weights.cols(), static_cast<Eigen::Index>(rig.skin->joints.size()));
    EXPECT_EQ(part.morph_targets.size(), rig.morph_targets.size()) << part.name;
  }
  // The expression clip animates the weights of all seven meshes.
  const auto clip = std::find_if(rig.animations.begin(), rig.animations.end(),
                                 [](const core::Animation& a) { return a.name == "expression_weights"; });
  ASSERT_NE(clip, rig.animations.end());
  const auto weight_channels = std::count_if(clip->channels.begin(), clip->channels.end(), [](const core::AnimationChannel& c) {
    return c.path == AnimationPath::kWeights;
  });
  EXPECT_EQ(weight_channels, 7);
  for (const std::string& warning : loaded->report.warnings) {
    EXPECT_EQ(warning.find("dropped"), std::string::npos) << warning;
    EXPECT_EQ(warning.find("skipped"), std::string::npos) << warning;
  }

  const ByteVector bytes = mustEncode(rig);
  const LoadedRig back = mustRead(bytes);
  expectRigsEqual(rig, back.rig, /*same_influence_sets=*/true);
  const auto path = writeTemp(bytes, "source_face_full");
  EXPECT_GLTF_VALID(path);
}

TEST(RigIct, SparseGroundTruthMorphTargetsReadExactly) {
  RIGPORT_REQUIRE_SHARED_DATA(data);
  const auto file = data / "ict" / "targets" / "id_s01.gt.glb";
  auto loaded = core::readRig(file);
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  const Rig& rig = loaded->rig;
  ASSERT_EQ(rig.morph_targets.size(), 53u);
  EXPECT_FALSE(rig.skin);

  // Decode target 0's sparse accessor independently: listed rows equal the
  // stored floats, every other row is exactly zero.
  auto bytes = core::readFileBytes(file);
  ASSERT_TRUE(bytes.ok());
  const auto [doc, bin] = splitGlb(*bytes);
  const json& accessor = doc["accessors"][doc["meshes"][0]["primitives"][0]["targets"][0]["POSITION"].get<int>()];
  ASSERT_TRUE(accessor.contains("sparse"));
  ASSERT_FALSE(accessor.contains("bufferView"));
  const json& sparse = accessor["sparse"];
  const json& index_view = doc["bufferViews"][sparse["indices"]["bufferView"].get<int>()];
  const json& value_view = doc["bufferViews"][sparse["values"]["bufferView"].get<int>()];
  ASSERT_EQ(sparse["indices"]["componentType"], kUnsignedShort);
  const int count = sparse["count"];
  std::vector<char> listed(static_cast<std::size_t>(rig.mesh.vertexCount()), 0);
  const Eigen::MatrixX3d& deltas = rig.morph_targets[0].position_deltas;
  for (int i = 0; i < count; ++i) {
    const std::size_t at = index_view.value("byteOffset", 0) + sparse["indices"].value("byteOffset", 0) + 2 * i;
    const int vertex = bin[at] | bin[at + 1] << 8;
    listed[static_cast<std::size_t>(vertex)] = 1;
    for (int c = 0; c < 3; ++c) {
      float f = 0;
      std::memcpy(
          &f, bin.data() + value_view.value("byteOffset", 0) + sparse["values"].value("byteOffset", 0) + 12 * i + 4 * c,
          4);
      ASSERT_EQ(deltas(vertex, c), static_cast<double>(f)) << "vertex " << vertex;
    }
  }
  int zero_rows = 0;
  for (Eigen::Index v = 0; v < deltas.rows(); ++v) {
    if (listed[static_cast<std::size_t>(v)]) continue;
    EXPECT_TRUE((deltas.row(v).array() == 0.0).all()) << "vertex " << v;
    ++zero_rows;
  }
  EXPECT_GT(zero_rows, 0);
  EXPECT_GT(count, 0);
  EXPECT_EQ(rig.morph_targets[0].name, "browDown_L");

  const ByteVector written = mustEncode(rig);  // sparse again, zero rows exact
  expectMorphTargetsEqual(rig, mustRead(written).rig);
  EXPECT_LT(written.size(), bytes->size() * 11 / 10);
  EXPECT_GLB_CLEAN(written, "id_s01_gt");
}

TEST(RigIct, UvFaceKeepsTexcoordsAndTheIctVertexField) {
  RIGPORT_REQUIRE_SHARED_DATA(data);
  auto loaded = core::readRig(data / "ict" / "source_face_uv.glb");
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  const Rig& rig = loaded->rig;
  EXPECT_EQ(rig.mesh.uvs.rows(), 11657);
  ASSERT_EQ(rig.attributes.fields.count("ICT_VERTEX"), 1u);
  const Eigen::MatrixXd& ict = rig.attributes.fields.at("ICT_VERTEX");
  ASSERT_EQ(ict.cols(), 1);
  ASSERT_EQ(ict.rows(), 11657);
  EXPECT_TRUE((ict.array() == ict.array().round()).all());
  EXPECT_EQ(ict.minCoeff(), 0.0);
  EXPECT_EQ(ict.maxCoeff(), 11247.0);

  const ByteVector bytes = mustEncode(rig);
  const LoadedRig back = mustRead(bytes);
  expectRigsEqual(rig, back.rig, false);
  EXPECT_EQ(back.rig.attributes.fields.at("ICT_VERTEX"), ict);  // exact integers
  EXPECT_GLB_CLEAN(bytes, "source_face_uv");
}

}  // namespace
