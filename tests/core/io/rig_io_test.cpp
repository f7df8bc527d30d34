// Tests the rig reader and writer of core/io/gltf_*.cpp (core/io/rig_io.h): round
// trips of the Khronos samples and the ICT rig files in ../shared/data (every
// written GLB through the Khronos validator), the writer's skin rules on a
// hand-built rig (influence limits, weight encodings, labels and fields,
// determinism), and clean errors for bad or truncated input.
#include "core/io/rig_io.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "tests/gltf_builder.h"
#include "tests/test_support.h"

namespace {

using core::AnimationPath;
using core::ErrorCode;
using core::Interpolation;
using core::LoadedRig;
using core::Rig;
using core::RigWriteOptions;
using core::WeightEncoding;
using namespace rigport_test::gltf;
using rigport_test::matricesNear;

// ---------------------------------------------------------------------------
// Helpers

// Element `i`, component `c` of an accessor with a bufferView (no sparse), as
// the raw integer or float the file holds.
double rawComponent(const json& doc, const ByteVector& bin, int accessor, std::size_t i, int c) {
  const json& a = doc["accessors"][accessor];
  const json& view = doc["bufferViews"][a["bufferView"].get<int>()];
  const int type = a["componentType"];
  const std::size_t size = type == kFloat ? 4 : type == kUnsignedShort ? 2 : 1;
  const std::size_t components = a["type"] == "SCALAR" ? 1 : a["type"] == "VEC2" ? 2 : a["type"] == "VEC3" ? 3 : 4;
  const std::size_t stride = view.value("byteStride", components * size);
  const std::size_t offset = view.value("byteOffset", 0) + a.value("byteOffset", 0) + i * stride + c * size;
  if (type == kFloat) {
    float f = 0;
    std::memcpy(&f, bin.data() + offset, 4);
    return f;
  }
  if (type == kUnsignedShort) return bin[offset] | bin[offset + 1] << 8;
  return bin[offset];
}

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

std::filesystem::path writeTemp(const ByteVector& bytes, const std::string& name) {
  const std::filesystem::path path = rigport_test::makeTempDir(name) / (name + ".glb");
  std::ofstream out(path, std::ios::binary);
  out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
  return path;
}

// The validator's result for `bytes` (written to a temp file).
rigport_test::ValidatorResult validate(const ByteVector& bytes, const std::string& name) {
  return rigport_test::validateGltf(writeTemp(bytes, name));
}

// Valid and without warnings.
#define EXPECT_GLB_CLEAN(bytes, name)           \
  do {                                          \
    const auto vr_ = validate((bytes), (name)); \
    EXPECT_TRUE(vr_.ran) << vr_.output;         \
    EXPECT_EQ(vr_.errors, 0) << vr_.output;     \
    EXPECT_EQ(vr_.warnings, 0) << vr_.output;   \
  } while (0)

LoadedRig mustRead(const ByteVector& bytes, const std::string& label = "written.glb") {
  auto rig = core::readRigGltf(bytes, label, /*binary=*/true);
  EXPECT_TRUE(rig.ok()) << rig.error().message;
  return rig.ok() ? std::move(*rig) : LoadedRig{};
}

ByteVector mustEncode(const Rig& rig, const RigWriteOptions& options = {}) {
  auto bytes = core::encodeRigGlb(rig, options);
  EXPECT_TRUE(bytes.ok()) << bytes.error().message;
  return bytes.ok() ? std::move(*bytes) : ByteVector{};
}

Eigen::MatrixXd dense(const core::SkinWeights& w) { return Eigen::MatrixXd(w); }

double maxAbs(const Eigen::MatrixXd& m) { return m.size() == 0 ? 0.0 : m.cwiseAbs().maxCoeff(); }

// Quaternions equal up to sign.
::testing::AssertionResult rotationsNear(const Eigen::Quaterniond& a, const Eigen::Quaterniond& b, double tol) {
  const double d =
      std::min((a.coeffs() - b.coeffs()).cwiseAbs().maxCoeff(), (a.coeffs() + b.coeffs()).cwiseAbs().maxCoeff());
  if (d <= tol) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << a.coeffs().transpose() << " vs " << b.coeffs().transpose();
}

// ---------------------------------------------------------------------------
// Rig comparison (what a round trip must preserve)

void expectNodesEqual(const Rig& a, const Rig& b) {
  ASSERT_EQ(a.nodes.size(), b.nodes.size());
  EXPECT_EQ(a.mesh_node, b.mesh_node);
  for (std::size_t i = 0; i < a.nodes.size(); ++i) {
    SCOPED_TRACE("node " + std::to_string(i));
    EXPECT_EQ(a.nodes[i].name, b.nodes[i].name);
    EXPECT_EQ(a.nodes[i].parent, b.nodes[i].parent);
    EXPECT_TRUE(
        matricesNear(a.nodes[i].translation, b.nodes[i].translation, 1e-12 * (1 + a.nodes[i].translation.norm())));
    EXPECT_TRUE(rotationsNear(a.nodes[i].rotation, b.nodes[i].rotation, 1e-12));
    EXPECT_TRUE(matricesNear(a.nodes[i].scale, b.nodes[i].scale, 1e-12 * a.nodes[i].scale.norm()));
  }
}

void expectSkinEqual(const Rig& a, const Rig& b, bool same_influence_sets) {
  ASSERT_EQ(a.skin.has_value(), b.skin.has_value());
  if (!a.skin) return;
  EXPECT_EQ(a.skin->name, b.skin->name);
  EXPECT_EQ(a.skin->joints, b.skin->joints);
  EXPECT_EQ(a.skin->skeleton, b.skin->skeleton);
  ASSERT_EQ(a.skin->inverse_bind.size(), b.skin->inverse_bind.size());
  for (std::size_t j = 0; j < a.skin->inverse_bind.size(); ++j) {
    const Eigen::Matrix4d& m = a.skin->inverse_bind[j];
    EXPECT_TRUE(matricesNear(m, b.skin->inverse_bind[j], 1e-7 * (1 + maxAbs(m)))) << "joint " << j;
  }
  const Eigen::MatrixXd wa = dense(a.weights);
  const Eigen::MatrixXd wb = dense(b.weights);
  EXPECT_TRUE(matricesNear(wa, wb, 1e-6));
  if (same_influence_sets) {
    EXPECT_TRUE(((wa.array() != 0.0) == (wb.array() != 0.0)).all()) << "influence sets differ";
  }
}

void expectMorphTargetsEqual(const Rig& a, const Rig& b) {
  ASSERT_EQ(a.morph_targets.size(), b.morph_targets.size());
  for (std::size_t t = 0; t < a.morph_targets.size(); ++t) {
    SCOPED_TRACE("morph target " + std::to_string(t));
    const core::MorphTarget& ta = a.morph_targets[t];
    const core::MorphTarget& tb = b.morph_targets[t];
    EXPECT_EQ(ta.name, tb.name);
    EXPECT_TRUE(matricesNear(ta.position_deltas, tb.position_deltas, 1e-6 * (1e-6 + maxAbs(ta.position_deltas))));
    EXPECT_TRUE(matricesNear(ta.normal_deltas, tb.normal_deltas, 1e-6 * (1 + maxAbs(ta.normal_deltas))));
  }
  EXPECT_TRUE(matricesNear(a.morph_default_weights, b.morph_default_weights, 1e-7));
}

void expectAnimationsEqual(const Rig& a, const Rig& b) {
  ASSERT_EQ(a.animations.size(), b.animations.size());
  for (std::size_t i = 0; i < a.animations.size(); ++i) {
    SCOPED_TRACE("animation " + std::to_string(i));
    EXPECT_EQ(a.animations[i].name, b.animations[i].name);
    ASSERT_EQ(a.animations[i].channels.size(), b.animations[i].channels.size());
    for (std::size_t c = 0; c < a.animations[i].channels.size(); ++c) {
      SCOPED_TRACE("channel " + std::to_string(c));
      const core::AnimationChannel& ca = a.animations[i].channels[c];
      const core::AnimationChannel& cb = b.animations[i].channels[c];
      EXPECT_EQ(ca.node, cb.node);
      EXPECT_EQ(ca.path, cb.path);
      EXPECT_EQ(ca.interpolation, cb.interpolation);
      EXPECT_TRUE(matricesNear(ca.times, cb.times, 0.0));  // float in, float out
      EXPECT_TRUE(matricesNear(ca.values, cb.values, 1e-6 * (1 + maxAbs(ca.values))));
    }
  }
}

void expectAttributesEqual(const Rig& a, const Rig& b) {
  ASSERT_EQ(a.attributes.extra_uv_sets.size(), b.attributes.extra_uv_sets.size());
  for (std::size_t k = 0; k < a.attributes.extra_uv_sets.size(); ++k) {
    EXPECT_TRUE(matricesNear(a.attributes.extra_uv_sets[k], b.attributes.extra_uv_sets[k], 1e-7));
  }
  EXPECT_TRUE(matricesNear(a.attributes.colors, b.attributes.colors, 1e-7));
  ASSERT_EQ(a.attributes.labels.size(), b.attributes.labels.size());
  for (const auto& [key, values] : a.attributes.labels) {
    ASSERT_EQ(b.attributes.labels.count(key), 1u) << key;
    EXPECT_EQ(values, b.attributes.labels.at(key)) << key;
  }
  ASSERT_EQ(a.attributes.fields.size(), b.attributes.fields.size());
  for (const auto& [key, values] : a.attributes.fields) {
    ASSERT_EQ(b.attributes.fields.count(key), 1u) << key;
    EXPECT_TRUE(matricesNear(values, b.attributes.fields.at(key), 1e-6 * (1 + maxAbs(values)))) << key;
  }
}

void expectMeshEqual(const Rig& a, const Rig& b) {
  const double scale = 1 + maxAbs(a.mesh.positions);
  EXPECT_TRUE(matricesNear(a.mesh.positions, b.mesh.positions, 1e-6 * scale));
  ASSERT_EQ(a.mesh.triangles.rows(), b.mesh.triangles.rows());
  EXPECT_TRUE((a.mesh.triangles.array() == b.mesh.triangles.array()).all());
  EXPECT_TRUE(matricesNear(a.mesh.normals, b.mesh.normals, 1e-6));
  EXPECT_TRUE(matricesNear(a.mesh.uvs, b.mesh.uvs, 1e-7));
  EXPECT_EQ(a.mesh_name, b.mesh_name);
}

void expectRigsEqual(const Rig& a, const Rig& b, bool same_influence_sets) {
  expectMeshEqual(a, b);
  expectNodesEqual(a, b);
  expectSkinEqual(a, b, same_influence_sets);
  expectMorphTargetsEqual(a, b);
  expectAnimationsEqual(a, b);
  expectAttributesEqual(a, b);
}

// ---------------------------------------------------------------------------
// A hand-built rig: a 3 x 3 vertex grid (8 triangles) skinned to a chain of
// six joints under a root node, two morph targets, one animation.

constexpr int kGrid = 3;
constexpr int kJoints = 6;

core::Mesh makeGridMesh() {
  core::Mesh mesh;
  mesh.positions.resize(kGrid * kGrid, 3);
  mesh.uvs.resize(kGrid * kGrid, 2);
  for (int j = 0; j < kGrid; ++j) {
    for (int i = 0; i < kGrid; ++i) {
      mesh.positions.row(j * kGrid + i) << i * 0.5, j * 0.5, 0.1 * i * j;
      mesh.uvs.row(j * kGrid + i) << i / 2.0, j / 2.0;
    }
  }
  mesh.triangles.resize(2 * (kGrid - 1) * (kGrid - 1), 3);
  int f = 0;
  for (int j = 0; j + 1 < kGrid; ++j) {
    for (int i = 0; i + 1 < kGrid; ++i) {
      const int v = j * kGrid + i;
      mesh.triangles.row(f++) << v, v + 1, v + kGrid + 1;
      mesh.triangles.row(f++) << v, v + kGrid + 1, v + kGrid;
    }
  }
  mesh.normals = core::computeVertexNormals(mesh.positions, mesh.triangles);
  return mesh;
}

core::SkinWeights makeWeights(Eigen::Index nv) {
  std::vector<Eigen::Triplet<double>> triplets;
  // Vertex 0: six influences, a tie between joints 3 and 4.
  const double w0[kJoints] = {0.3, 0.25, 0.2, 0.1, 0.1, 0.05};
  for (int j = 0; j < kJoints; ++j) triplets.emplace_back(0, j, w0[j]);
  for (int v = 1; v < nv; ++v) {
    triplets.emplace_back(v, v % kJoints, 0.7);
    triplets.emplace_back(v, (v + 1) % kJoints, 0.2);
    triplets.emplace_back(v, (v + 2) % kJoints, 0.1 / 3);  // 1/3 and 2/3: not exact in any encoding
    triplets.emplace_back(v, (v + 2) % kJoints, 0.2 / 3);  // same joint again: merged by setFromTriplets
  }
  core::SkinWeights weights(nv, kJoints);
  weights.setFromTriplets(triplets.begin(), triplets.end());
  return weights;
}

Rig makeRig() {
  Rig rig;
  rig.mesh = makeGridMesh();
  rig.mesh_name = "grid";
  rig.nodes.push_back(
      {"grid_node", -1, Eigen::Vector3d::Zero(), Eigen::Quaterniond::Identity(), Eigen::Vector3d::Ones()});
  rig.nodes.push_back({"root", -1, Eigen::Vector3d(0, 0, 1), Eigen::Quaterniond::Identity(), Eigen::Vector3d::Ones()});
  for (int j = 0; j < kJoints; ++j) {
    const Eigen::Quaterniond q(Eigen::AngleAxisd(0.1 * (j + 1), Eigen::Vector3d::UnitZ()));
    rig.nodes.push_back({"j" + std::to_string(j), j == 0 ? 1 : j + 1, Eigen::Vector3d(0, 0.3, 0), q,
                         Eigen::Vector3d::Constant(j == 2 ? 1.5 : 1.0)});
  }
  rig.mesh_node = 0;
  core::Skin skin;
  skin.name = "chain";
  skin.skeleton = 1;
  const std::vector<Eigen::Matrix4d> world = core::nodeWorldTransforms(rig.nodes);
  for (int j = 0; j < kJoints; ++j) {
    skin.joints.push_back(j + 2);
    Eigen::Matrix4d inverse = world[static_cast<std::size_t>(j + 2)].inverse();
    inverse.row(3) << 0, 0, 0, 1;
    skin.inverse_bind.push_back(inverse);
  }
  rig.skin = skin;
  rig.weights = makeWeights(rig.mesh.vertexCount());

  core::MorphTarget smile{"smile", Eigen::MatrixX3d::Zero(kGrid * kGrid, 3), Eigen::MatrixX3d()};
  smile.position_deltas.row(4) << 0, 0, 0.5;
  smile.position_deltas.row(0) << -0.25, 0.125, 0;
  core::MorphTarget flat{"flat", Eigen::MatrixX3d::Zero(kGrid * kGrid, 3), Eigen::MatrixX3d()};
  rig.morph_targets = {smile, flat};
  rig.morph_default_weights = Eigen::Vector2d(0.25, 0);

  core::Animation animation;
  animation.name = "wave";
  core::AnimationChannel rotate;
  rotate.node = 2;
  rotate.path = AnimationPath::kRotation;
  rotate.times = Eigen::Vector3d(0, 0.5, 1);
  rotate.values.resize(3, 4);
  for (int k = 0; k < 3; ++k) {
    const Eigen::Quaterniond q(Eigen::AngleAxisd(0.2 * k, Eigen::Vector3d::UnitX()));
    rotate.values.row(k) << q.x(), q.y(), q.z(), q.w();
  }
  core::AnimationChannel move;
  move.node = 3;
  move.path = AnimationPath::kTranslation;
  move.interpolation = Interpolation::kStep;
  move.times = Eigen::Vector2d(0, 1);
  move.values.resize(2, 3);
  move.values << 0, 0.3, 0, 0, 0.5, 0;
  core::AnimationChannel blend;
  blend.node = 0;
  blend.path = AnimationPath::kWeights;
  blend.interpolation = Interpolation::kCubicSpline;
  blend.times = Eigen::Vector2d(0, 1);
  blend.values.resize(6, 2);  // in-tangent, value, out-tangent per key
  blend.values << 0, 0, 0, 0, 1, 0, -1, 0, 1, 0.5, 0, 0;
  animation.channels = {rotate, move, blend};
  rig.animations = {animation};

  rig.attributes.labels["PART"] = Eigen::VectorXi::LinSpaced(kGrid * kGrid, 0, 300);  // > 255: unsigned short
  rig.attributes.labels["SIDE"] = Eigen::VectorXi::LinSpaced(kGrid * kGrid, 0, 2);      // unsigned byte
  rig.attributes.fields["MASK"] = Eigen::VectorXd::LinSpaced(kGrid * kGrid, 0, 1);
  rig.attributes.fields["OFFSET"] = Eigen::MatrixXd::Random(kGrid * kGrid, 3);
  rig.attributes.colors = Eigen::MatrixX4d::Constant(kGrid * kGrid, 4, 0.5);
  rig.attributes.extra_uv_sets = {rig.mesh.uvs * 0.5};
  return rig;
}

// The kept influences of vertex 0 (largest first) for `max_influences`.
std::map<int, double> expectedVertex0(int max_influences) {
  const double w0[kJoints] = {0.3, 0.25, 0.2, 0.1, 0.1, 0.05};
  std::map<int, double> kept;
  double sum = 0;
  for (int j = 0; j < std::min(max_influences, kJoints); ++j) sum += w0[j];  // already in rank order
  for (int j = 0; j < std::min(max_influences, kJoints); ++j) kept[j] = w0[j] / sum;
  return kept;
}

std::map<int, double> row(const core::SkinWeights& weights, Eigen::Index v) {
  std::map<int, double> out;
  for (core::SkinWeights::InnerIterator it(weights, v); it; ++it) out[static_cast<int>(it.col())] = it.value();
  return out;
}

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

// ===========================================================================
// Writer rules on the hand-built rig

TEST(RigWrite, HandBuiltRigRoundTripsAndIsClean) {
  const Rig rig = makeRig();
  const ByteVector bytes = mustEncode(rig);
  const LoadedRig back = mustRead(bytes);
  Rig expected = rig;
  expected.weights = back.rig.weights;  // vertex 0 loses influences: checked below
  expectRigsEqual(expected, back.rig, false);
  EXPECT_EQ(back.report.warnings, std::vector<std::string>{});
  EXPECT_GLB_CLEAN(bytes, "hand_built");
}

TEST(RigWrite, KeepsTheFourLargestInfluencesRenormalised) {
  const Rig rig = makeRig();
  const LoadedRig back = mustRead(mustEncode(rig));
  const std::map<int, double> kept = row(back.rig.weights, 0);
  const std::map<int, double> expected = expectedVertex0(4);  // tie 3 vs 4: the lower joint
  ASSERT_EQ(kept.size(), expected.size());
  for (const auto& [joint, w] : expected) EXPECT_NEAR(kept.at(joint), w, 1e-7) << "joint " << joint;
  // Other vertices: 3 influences (the repeated joint merged), unchanged.
  const Eigen::MatrixXd original = dense(rig.weights);
  const Eigen::MatrixXd read = dense(back.rig.weights);
  EXPECT_TRUE(matricesNear(original.bottomRows(original.rows() - 1), read.bottomRows(read.rows() - 1), 1e-7));
  EXPECT_EQ(row(back.rig.weights, 1).size(), 3u);
}

TEST(RigWrite, EightInfluencesUseASecondJointsWeightsSet) {
  const Rig rig = makeRig();
  RigWriteOptions options;
  options.max_influences = 8;
  const ByteVector bytes = mustEncode(rig, options);
  const auto [doc, bin] = splitGlb(bytes);
  const json& attributes = doc["meshes"][0]["primitives"][0]["attributes"];
  EXPECT_TRUE(attributes.contains("JOINTS_1"));
  EXPECT_TRUE(attributes.contains("WEIGHTS_1"));
  const LoadedRig back = mustRead(bytes);
  EXPECT_TRUE(matricesNear(dense(back.rig.weights), dense(rig.weights), 1e-7));
  EXPECT_GLB_CLEAN(bytes, "eight_influences");

  options.max_influences = 9;
  auto bad = core::encodeRigGlb(rig, options);
  ASSERT_FALSE(bad.ok());
  EXPECT_EQ(bad.error().code, ErrorCode::kInvalidArgument);
}

TEST(RigWrite, QuantisedWeightsSumExactlyPerVertex) {
  const Rig rig = makeRig();
  for (const auto& [encoding, scale] :
       {std::pair{WeightEncoding::kUnorm8, 255}, std::pair{WeightEncoding::kUnorm16, 65535}}) {
    SCOPED_TRACE(scale);
    for (const int max_influences : {4, 8}) {
      RigWriteOptions options;
      options.weight_encoding = encoding;
      options.max_influences = max_influences;
      const ByteVector bytes = mustEncode(rig, options);
      const auto [doc, bin] = splitGlb(bytes);
      const json& attributes = doc["meshes"][0]["primitives"][0]["attributes"];
      const int sets = attributes.contains("WEIGHTS_1") ? 2 : 1;
      EXPECT_EQ(sets, max_influences == 8 ? 2 : 1);
      for (std::size_t v = 0; v < static_cast<std::size_t>(rig.mesh.vertexCount()); ++v) {
        long total = 0;
        for (int s = 0; s < sets; ++s) {
          const int accessor = attributes["WEIGHTS_" + std::to_string(s)];
          EXPECT_TRUE(doc["accessors"][accessor].value("normalized", false));
          for (int c = 0; c < 4; ++c) total += static_cast<long>(rawComponent(doc, bin, accessor, v, c));
        }
        EXPECT_EQ(total, scale) << "vertex " << v;
      }
      const LoadedRig back = mustRead(bytes);
      const Eigen::MatrixXd read = dense(back.rig.weights);
      EXPECT_TRUE(matricesNear(read.rowwise().sum(), Eigen::VectorXd::Ones(read.rows()), 1e-12));
      Eigen::MatrixXd expected = dense(rig.weights);
      if (max_influences == 4) {
        expected.row(0).setZero();
        for (const auto& [joint, w] : expectedVertex0(4)) expected(0, joint) = w;
      }
      EXPECT_TRUE(matricesNear(read, expected, 1.0 / scale));
      EXPECT_GLB_CLEAN(bytes, "unorm" + std::to_string(scale) + "_" + std::to_string(max_influences));
    }
  }
}

TEST(RigWrite, FloatWeightsSumToOneInFloat) {
  const Rig rig = makeRig();
  const ByteVector bytes = mustEncode(rig);
  const auto [doc, bin] = splitGlb(bytes);
  const int accessor = doc["meshes"][0]["primitives"][0]["attributes"]["WEIGHTS_0"];
  for (std::size_t v = 0; v < static_cast<std::size_t>(rig.mesh.vertexCount()); ++v) {
    float sum = 0;
    for (int c = 0; c < 4; ++c) sum += static_cast<float>(rawComponent(doc, bin, accessor, v, c));
    EXPECT_EQ(sum, 1.0f) << "vertex " << v;
  }
}

TEST(RigWrite, EncodingIsDeterministic) {
  const Rig rig = makeRig();
  EXPECT_EQ(mustEncode(rig), mustEncode(rig));
  RigWriteOptions options;
  options.weight_encoding = WeightEncoding::kUnorm16;
  options.sparse_morph_targets = false;
  EXPECT_EQ(mustEncode(rig, options), mustEncode(rig, options));
}

TEST(RigWrite, LabelsAndFieldsRoundTrip) {
  const Rig rig = makeRig();
  const ByteVector bytes = mustEncode(rig);
  const auto [doc, bin] = splitGlb(bytes);
  const json& attributes = doc["meshes"][0]["primitives"][0]["attributes"];
  EXPECT_EQ(doc["accessors"][attributes["_PART"].get<int>()]["componentType"], kUnsignedShort);
  EXPECT_EQ(doc["accessors"][attributes["_SIDE"].get<int>()]["componentType"], kUnsignedByte);
  EXPECT_EQ(doc["accessors"][attributes["_OFFSET"].get<int>()]["type"], "VEC3");
  const LoadedRig back = mustRead(bytes);
  expectAttributesEqual(rig, back.rig);

  Rig negative = makeRig();
  negative.attributes.labels["SIDE"](3) = -1;
  auto error = core::encodeRigGlb(negative);
  ASSERT_FALSE(error.ok());
  EXPECT_EQ(error.error().code, ErrorCode::kInvalidArgument);
  EXPECT_NE(error.error().message.find("vertex 3"), std::string::npos) << error.error().message;
  negative.attributes.labels["SIDE"](3) = 70000;
  EXPECT_FALSE(core::encodeRigGlb(negative).ok());
}

TEST(RigWrite, MorphTargetsAreSparseWhenSmallerAndZeroTargetsHaveNoData) {
  const Rig rig = makeRig();
  const ByteVector bytes = mustEncode(rig);
  const auto [doc, bin] = splitGlb(bytes);
  const json& targets = doc["meshes"][0]["primitives"][0]["targets"];
  const json& smile = doc["accessors"][targets[0]["POSITION"].get<int>()];
  const json& flat = doc["accessors"][targets[1]["POSITION"].get<int>()];
  EXPECT_TRUE(smile.contains("sparse"));
  EXPECT_EQ(smile["sparse"]["count"], 2);
  EXPECT_EQ(smile["min"], json::array({-0.25, 0, 0}));  // implicit zeros included
  EXPECT_EQ(smile["max"], json::array({0, 0.125, 0.5}));
  EXPECT_FALSE(flat.contains("bufferView"));
  EXPECT_FALSE(flat.contains("sparse"));
  EXPECT_EQ(doc["meshes"][0]["extras"]["targetNames"], json::array({"smile", "flat"}));
  EXPECT_EQ(doc["meshes"][0]["weights"], json::array({0.25, 0}));

  RigWriteOptions dense_options;
  dense_options.sparse_morph_targets = false;
  const ByteVector dense_bytes = mustEncode(rig, dense_options);
  const auto [dense_doc, dense_bin] = splitGlb(dense_bytes);
  EXPECT_TRUE(
      dense_doc["accessors"][dense_doc["meshes"][0]["primitives"][0]["targets"][0]["POSITION"].get<int>()].contains(
          "bufferView"));
  expectMorphTargetsEqual(rig, mustRead(dense_bytes).rig);
  EXPECT_GLB_CLEAN(dense_bytes, "dense_morphs");
}

TEST(RigWrite, RejectsNegativeWeightsAndUnweightedVertices) {
  Rig rig = makeRig();
  rig.weights.coeffRef(5, 5) = -0.25;
  auto negative = core::encodeRigGlb(rig);
  ASSERT_FALSE(negative.ok());
  EXPECT_EQ(negative.error().code, ErrorCode::kInvalidArgument);
  EXPECT_NE(negative.error().message.find("vertex 5"), std::string::npos) << negative.error().message;

  rig = makeRig();
  for (core::SkinWeights::InnerIterator it(rig.weights, 4); it; ++it) it.valueRef() = 0.0;
  auto empty = core::encodeRigGlb(rig);
  ASSERT_FALSE(empty.ok());
  EXPECT_EQ(empty.error().code, ErrorCode::kInvalidArgument);
  EXPECT_NE(empty.error().message.find("vertex 4 "), std::string::npos) << empty.error().message;
}

TEST(RigWrite, RejectsAnInverseBindMatrixThatIsNotAffine) {
  Rig rig = makeRig();
  rig.skin->inverse_bind[2](3, 0) = 0.5;
  auto bytes = core::encodeRigGlb(rig);
  ASSERT_FALSE(bytes.ok());
  EXPECT_EQ(bytes.error().code, ErrorCode::kInvalidArgument);
  EXPECT_NE(bytes.error().message.find("joint 2"), std::string::npos) << bytes.error().message;

  rig = makeRig();
  rig.skin->inverse_bind[2](3, 0) = 1e-12;  // float noise: written as exactly 0 0 0 1
  const LoadedRig back = mustRead(mustEncode(rig));
  EXPECT_EQ(back.rig.skin->inverse_bind[2].row(3), Eigen::RowVector4d(0, 0, 0, 1));
}

TEST(RigWrite, RejectsBrokenHierarchiesAndAnimations) {
  Rig cycle = makeRig();
  cycle.nodes[1].parent = 7;  // root under the last joint
  auto bytes = core::encodeRigGlb(cycle);
  ASSERT_FALSE(bytes.ok());
  EXPECT_EQ(bytes.error().code, ErrorCode::kInvalidArgument);
  EXPECT_NE(bytes.error().message.find("cycle"), std::string::npos) << bytes.error().message;

  Rig bad_node = makeRig();
  bad_node.animations[0].channels[0].node = 42;
  bytes = core::encodeRigGlb(bad_node);
  ASSERT_FALSE(bytes.ok());
  EXPECT_NE(bytes.error().message.find("animation 0 'wave' channel 0"), std::string::npos) << bytes.error().message;

  Rig bad_parent = makeRig();
  bad_parent.nodes[1].parent = 99;
  bytes = core::encodeRigGlb(bad_parent);
  ASSERT_FALSE(bytes.ok());
  EXPECT_NE(bytes.error().message.find("node 1 'root' has parent 99"), std::string::npos) << bytes.error().message;

  Rig weights_elsewhere = makeRig();
  weights_elsewhere.animations[0].channels[2].node = 3;
  EXPECT_FALSE(core::encodeRigGlb(weights_elsewhere).ok());

  Rig bad_shape = makeRig();
  bad_shape.animations[0].channels[2].values.conservativeResize(4, 2);
  EXPECT_FALSE(core::encodeRigGlb(bad_shape).ok());

  Rig bad_times = makeRig();
  bad_times.animations[0].channels[0].times(2) = 0.5;
  EXPECT_FALSE(core::encodeRigGlb(bad_times).ok());
}

TEST(RigWrite, SkinnedMeshNodeIsWrittenAsAnIdentityRoot) {
  Rig rig = makeRig();
  rig.nodes[0].parent = 1;
  rig.nodes[0].translation = Eigen::Vector3d(1, 2, 3);
  const ByteVector bytes = mustEncode(rig);
  const LoadedRig back = mustRead(bytes);
  EXPECT_EQ(back.rig.mesh_node, 0);
  EXPECT_EQ(back.rig.nodes[0].parent, -1);
  EXPECT_EQ(back.rig.nodes[0].translation, Eigen::Vector3d::Zero());
  EXPECT_TRUE(matricesNear(back.rig.mesh.positions, rig.mesh.positions, 1e-6));  // bind space untouched
  EXPECT_GLB_CLEAN(bytes, "reset_mesh_node");

  // With a child, the node keeps its transform and the mesh moves to a new root.
  rig.nodes.push_back({"child", 0, Eigen::Vector3d(0, 1, 0), Eigen::Quaterniond::Identity(), Eigen::Vector3d::Ones()});
  const ByteVector appended = mustEncode(rig);
  const LoadedRig back2 = mustRead(appended);
  ASSERT_EQ(back2.rig.nodes.size(), rig.nodes.size() + 1);
  EXPECT_EQ(back2.rig.mesh_node, static_cast<int>(rig.nodes.size()));
  EXPECT_EQ(back2.rig.nodes[0].parent, 1);
  EXPECT_EQ(back2.rig.nodes[0].translation, Eigen::Vector3d(1, 2, 3));
  EXPECT_EQ(back2.rig.animations[0].channels[2].node, back2.rig.mesh_node);  // weights follow the mesh
  EXPECT_GLB_CLEAN(appended, "appended_mesh_node");
}

TEST(RigWrite, UnskinnedMeshUnderATransformedNodeStaysInWorldSpace) {
  Rig rig = makeRig();
  rig.skin.reset();
  rig.weights = core::SkinWeights();
  rig.nodes[0].parent = 1;
  rig.nodes[0].rotation = Eigen::Quaterniond(Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()));
  rig.nodes[0].scale = Eigen::Vector3d(2, 2, -2);  // mirrored: the winding flips on write and back on read
  const ByteVector bytes = mustEncode(rig);
  const LoadedRig back = mustRead(bytes);
  expectRigsEqual(rig, back.rig, false);
  EXPECT_GLB_CLEAN(bytes, "unskinned_transformed");

  rig.mesh_node = -1;  // no node: a root node is made for the mesh
  rig.animations.clear();
  const LoadedRig back2 = mustRead(mustEncode(rig));
  EXPECT_EQ(back2.rig.mesh_node, static_cast<int>(rig.nodes.size()));
  EXPECT_EQ(back2.rig.nodes.back().name, "grid");
  EXPECT_TRUE(matricesNear(back2.rig.mesh.positions, rig.mesh.positions, 1e-6));
}

TEST(RigWrite, WriteRigGlbThenReadRig) {
  const Rig rig = makeRig();
  const auto path = rigport_test::makeTempDir("write") / "rig.glb";
  ASSERT_TRUE(core::writeRigGlb(rig, path).ok());
  auto back = core::readRig(path);
  ASSERT_TRUE(back.ok()) << back.error().message;
  EXPECT_EQ(back->rig.morph_targets.size(), 2u);
  Rig bad = rig;
  bad.mesh_node = 99;
  auto status = core::writeRigGlb(bad, path);
  ASSERT_FALSE(status.ok());
  EXPECT_EQ(status.error().message.rfind("rig.glb: ", 0), 0u) << status.error().message;
}

TEST(RigWrite, ReadRigAcceptsGltfTextWithABufferFileBesideIt) {
  const Rig rig = makeRig();
  auto [doc, bin] = splitGlb(mustEncode(rig));
  const auto dir = rigport_test::makeTempDir("text");
  doc["buffers"][0]["uri"] = "rig.bin";
  std::ofstream(dir / "rig.gltf") << doc.dump();
  std::ofstream(dir / "rig.bin", std::ios::binary)
      .write(reinterpret_cast<const char*>(bin.data()), static_cast<std::streamsize>(bin.size()));
  auto back = core::readRig(dir / "rig.gltf");
  ASSERT_TRUE(back.ok()) << back.error().message;
  EXPECT_EQ(back->report.format, core::MeshFormat::kGltf);
  expectMorphTargetsEqual(rig, back->rig);
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
