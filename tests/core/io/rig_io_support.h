// Helpers the rig reader and writer tests share (tests/core/io/rig_io_test.cpp,
// gltf_rig_write_test.cpp, gltf_rig_read_test.cpp): encode and read with the
// error in the failure, the validator on bytes, what a round trip must
// preserve, and a hand-built rig.
#pragma once

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <Eigen/SparseCore>
#include <gtest/gtest.h>

#include "core/io/rig_io.h"
#include "tests/gltf_builder.h"
#include "tests/test_support.h"

namespace rigport_test::rig_io {

// ---------------------------------------------------------------------------
// Helpers

inline std::filesystem::path writeTemp(const gltf::ByteVector& bytes, const std::string& name) {
  const std::filesystem::path path = rigport_test::makeTempDir(name) / (name + ".glb");
  std::ofstream out(path, std::ios::binary);
  out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
  return path;
}

// The validator's result for `bytes` (written to a temp file).
inline rigport_test::ValidatorResult validate(const gltf::ByteVector& bytes, const std::string& name) {
  return rigport_test::validateGltf(writeTemp(bytes, name));
}

// Valid and without warnings.
#define EXPECT_GLB_CLEAN(bytes, name)                                   \
  do {                                                                  \
    const auto vr_ = ::rigport_test::rig_io::validate((bytes), (name)); \
    EXPECT_TRUE(vr_.ran) << vr_.output;                                 \
    EXPECT_EQ(vr_.errors, 0) << vr_.output;                             \
    EXPECT_EQ(vr_.warnings, 0) << vr_.output;                           \
  } while (0)

inline core::LoadedRig mustRead(const gltf::ByteVector& bytes, const std::string& label = "written.glb") {
  auto rig = core::readRigGltf(bytes, label, /*binary=*/true);
  EXPECT_TRUE(rig.ok()) << rig.error().message;
  return rig.ok() ? std::move(*rig) : core::LoadedRig{};
}

inline gltf::ByteVector mustEncode(const core::Rig& rig, const core::RigWriteOptions& options = {}) {
  auto bytes = core::encodeRigGlb(rig, options);
  EXPECT_TRUE(bytes.ok()) << bytes.error().message;
  return bytes.ok() ? std::move(*bytes) : gltf::ByteVector{};
}

inline Eigen::MatrixXd dense(const core::SkinWeights& w) { return Eigen::MatrixXd(w); }

inline double maxAbs(const Eigen::MatrixXd& m) { return m.size() == 0 ? 0.0 : m.cwiseAbs().maxCoeff(); }

// Quaternions equal up to sign.
inline ::testing::AssertionResult rotationsNear(const Eigen::Quaterniond& a, const Eigen::Quaterniond& b, double tol) {
  const double d =
      std::min((a.coeffs() - b.coeffs()).cwiseAbs().maxCoeff(), (a.coeffs() + b.coeffs()).cwiseAbs().maxCoeff());
  if (d <= tol) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << a.coeffs().transpose() << " vs " << b.coeffs().transpose();
}

// ---------------------------------------------------------------------------
// Rig comparison (what a round trip must preserve)

inline void expectNodesEqual(const core::Rig& a, const core::Rig& b) {
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

inline void expectSkinEqual(const core::Rig& a, const core::Rig& b, bool same_influence_sets) {
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

inline void expectMorphTargetsEqual(const core::Rig& a, const core::Rig& b) {
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

inline void expectAnimationsEqual(const core::Rig& a, const core::Rig& b) {
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

inline void expectAttributesEqual(const core::Rig& a, const core::Rig& b) {
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

inline void expectMeshEqual(const core::Rig& a, const core::Rig& b) {
  const double scale = 1 + maxAbs(a.mesh.positions);
  EXPECT_TRUE(matricesNear(a.mesh.positions, b.mesh.positions, 1e-6 * scale));
  ASSERT_EQ(a.mesh.triangles.rows(), b.mesh.triangles.rows());
  EXPECT_TRUE((a.mesh.triangles.array() == b.mesh.triangles.array()).all());
  EXPECT_TRUE(matricesNear(a.mesh.normals, b.mesh.normals, 1e-6));
  EXPECT_TRUE(matricesNear(a.mesh.uvs, b.mesh.uvs, 1e-7));
  EXPECT_EQ(a.mesh_name, b.mesh_name);
}

inline void expectTextureEqual(const std::optional<core::TextureBinding>& a, const std::optional<core::TextureBinding>& b) {
  ASSERT_EQ(a.has_value(), b.has_value());
  if (!a) return;
  EXPECT_EQ(a->image, b->image);
  EXPECT_EQ(a->texcoord, b->texcoord);
  EXPECT_EQ(a->sampler, b->sampler);
  EXPECT_NEAR(a->scale, b->scale, 1e-12);
}

inline void expectMaterialsEqual(const core::Rig& a, const core::Rig& b) {
  EXPECT_EQ(a.triangle_materials, b.triangle_materials);
  ASSERT_EQ(a.images.size(), b.images.size());
  for (std::size_t i = 0; i < a.images.size(); ++i) {
    EXPECT_EQ(a.images[i].name, b.images[i].name);
    EXPECT_EQ(a.images[i].mime_type, b.images[i].mime_type);
    EXPECT_EQ(a.images[i].bytes, b.images[i].bytes);
  }
  ASSERT_EQ(a.materials.size(), b.materials.size());
  for (std::size_t m = 0; m < a.materials.size(); ++m) {
    const core::Material& x = a.materials[m];
    const core::Material& y = b.materials[m];
    SCOPED_TRACE("material " + x.name);
    EXPECT_EQ(x.name, y.name);
    EXPECT_TRUE(matricesNear(x.base_color_factor, y.base_color_factor, 1e-12));
    EXPECT_TRUE(matricesNear(x.emissive_factor, y.emissive_factor, 1e-12));
    EXPECT_NEAR(x.metallic_factor, y.metallic_factor, 1e-12);
    EXPECT_NEAR(x.roughness_factor, y.roughness_factor, 1e-12);
    EXPECT_EQ(x.alpha_mode, y.alpha_mode);
    EXPECT_NEAR(x.alpha_cutoff, y.alpha_cutoff, 1e-12);
    EXPECT_EQ(x.double_sided, y.double_sided);
    expectTextureEqual(x.base_color_texture, y.base_color_texture);
    expectTextureEqual(x.metallic_roughness_texture, y.metallic_roughness_texture);
    expectTextureEqual(x.normal_texture, y.normal_texture);
    expectTextureEqual(x.occlusion_texture, y.occlusion_texture);
    expectTextureEqual(x.emissive_texture, y.emissive_texture);
  }
}

inline void expectRigsEqual(const core::Rig& a, const core::Rig& b, bool same_influence_sets) {
  expectMeshEqual(a, b);
  expectNodesEqual(a, b);
  expectSkinEqual(a, b, same_influence_sets);
  expectMorphTargetsEqual(a, b);
  expectAnimationsEqual(a, b);
  expectAttributesEqual(a, b);
  expectMaterialsEqual(a, b);
  ASSERT_EQ(a.parts.size(), b.parts.size());
  for (std::size_t p = 0; p < a.parts.size(); ++p) {
    SCOPED_TRACE("part " + a.parts[p].name);
    EXPECT_EQ(a.parts[p].node, b.parts[p].node);
    const core::Rig pa = core::partAsRig(a, a.parts[p]);
    const core::Rig pb = core::partAsRig(b, b.parts[p]);
    expectMeshEqual(pa, pb);
    expectSkinEqual(pa, pb, same_influence_sets);
    expectMorphTargetsEqual(pa, pb);
    expectAttributesEqual(pa, pb);
    EXPECT_EQ(pa.triangle_materials, pb.triangle_materials);
  }
}

// ---------------------------------------------------------------------------
// A hand-built rig: a 3 x 3 vertex grid (8 triangles) skinned to a chain of
// six joints under a root node, two morph targets, one animation.

constexpr int kGrid = 3;
constexpr int kJoints = 6;

inline core::Mesh makeGridMesh() {
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

inline core::SkinWeights makeWeights(Eigen::Index nv) {
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

inline core::Rig makeRig() {
  core::Rig rig;
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
  rotate.path = core::AnimationPath::kRotation;
  rotate.times = Eigen::Vector3d(0, 0.5, 1);
  rotate.values.resize(3, 4);
  for (int k = 0; k < 3; ++k) {
    const Eigen::Quaterniond q(Eigen::AngleAxisd(0.2 * k, Eigen::Vector3d::UnitX()));
    rotate.values.row(k) << q.x(), q.y(), q.z(), q.w();
  }
  core::AnimationChannel move;
  move.node = 3;
  move.path = core::AnimationPath::kTranslation;
  move.interpolation = core::Interpolation::kStep;
  move.times = Eigen::Vector2d(0, 1);
  move.values.resize(2, 3);
  move.values << 0, 0.3, 0, 0, 0.5, 0;
  core::AnimationChannel blend;
  blend.node = 0;
  blend.path = core::AnimationPath::kWeights;
  blend.interpolation = core::Interpolation::kCubicSpline;
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

// The influences of vertex `v`: joint -> weight.
inline std::map<int, double> row(const core::SkinWeights& weights, Eigen::Index v) {
  std::map<int, double> out;
  for (core::SkinWeights::InnerIterator it(weights, v); it; ++it) out[static_cast<int>(it.col())] = it.value();
  return out;
}

}  // namespace rigport_test::rig_io
