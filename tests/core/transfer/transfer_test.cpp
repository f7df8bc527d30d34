// Tests core/transfer/transfer.cpp end to end: weights normalised and pruned,
// output bytes independent of the thread count, exaggeration of shapes and
// joint keys, clear errors for bad inputs, and the animation's strain
// following the source's.
#include "core/base/parallel.h"
#include "core/transfer/transfer.h"

#include <algorithm>
#include <cstdio>
#include <limits>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "core/geometry/mesh.h"
#include "core/io/rig_io.h"
#include "core/rig/skinning.h"
#include "tests/core/transfer/transfer_rigs.h"
#include "tests/test_support.h"

namespace {

using rigport_test::matricesNear;
using namespace rigport_test::transfer;

TEST(TransferRig, WeightsAreNormalisedPrunedAndShapesSparseOnAnotherFace) {
  const core::SyntheticRig& target = otherHead();
  core::TransferOptions options;
  options.weight_options.max_influences = 2;
  options.diagnostic_attributes = true;
  auto result = core::transferRig(preparedSource(), target.rig.mesh, target.landmarks, "other", options);
  ASSERT_TRUE(result) << result.error().message;
  const core::Rig& out = result->rig;
  ASSERT_EQ(out.weights.rows(), target.rig.mesh.vertexCount());
  for (Eigen::Index v = 0; v < out.weights.rows(); ++v) {
    double sum = 0;
    int count = 0;
    for (core::SkinWeights::InnerIterator it(out.weights, v); it; ++it) {
      EXPECT_GE(it.value(), 0.0);
      sum += it.value();
      ++count;
    }
    ASSERT_NEAR(sum, 1.0, 1e-12) << "vertex " << v;
    ASSERT_LE(count, 2);
  }
  EXPECT_LE(result->report.max_influences, 2);
  EXPECT_TRUE(out.attributes.fields.count("CONFIDENCE") && out.attributes.fields.count("INPAINTED"));
  // The eyeBlink shape stays zero away from the lids.
  const auto& blink = out.morph_targets[5];
  EXPECT_EQ(blink.name, "eyeBlink_R");
  EXPECT_LT((blink.position_deltas.rowwise().norm().array() > 0).count(), out.mesh.vertexCount() / 10);
}

// The service runs a job with its own thread count and the CLI with the
// machine's, and both must hand a TD the same file: every parallel stage
// writes by index and sums in a fixed order, so the GLB's bytes do not
// depend on the threads (3 is more than this machine has: other chunks).
TEST(TransferRig, OutputBytesDoNotDependOnTheThreadCount) {
  const core::SyntheticRig& target = otherHead();
  std::vector<std::vector<std::uint8_t>> glbs;
  for (const int threads : {1, 2, 3}) {
    const core::ScopedThreadCount scope(threads);
    core::TransferOptions options;
    options.diagnostic_attributes = true;
    auto result = core::transferRig(preparedSource(), target.rig.mesh, target.landmarks, "other", options);
    ASSERT_TRUE(result) << result.error().message;
    auto glb = core::encodeRigGlb(result->rig);
    ASSERT_TRUE(glb) << glb.error().message;
    glbs.push_back(std::move(*glb));
  }
  EXPECT_EQ(glbs[1], glbs[0]) << "2 threads against 1";
  EXPECT_EQ(glbs[2], glbs[0]) << "3 threads against 1";
}

TEST(TransferRig, ExaggerationScalesShapesAndAnimatedDeltas) {
  const core::Rig& src = sourceRig().rig;
  core::TransferOptions options;
  options.shape_exaggeration["jawOpen"] = 2.0;
  options.joint_exaggeration["jaw"] = 3.0;
  auto result = core::transferRig(preparedSource(), src.mesh, sourceRig().landmarks, "self", options);
  ASSERT_TRUE(result);
  EXPECT_TRUE(result->report.warnings.empty());  // both names are the rig's
  const double diag = core::boundingBoxDiagonal(src.mesh.positions);
  EXPECT_TRUE(matricesNear(result->rig.morph_targets[0].position_deltas, 2.0 * src.morph_targets[0].position_deltas, 1e-4 * diag));
  EXPECT_TRUE(matricesNear(result->rig.morph_targets[1].position_deltas, src.morph_targets[1].position_deltas, 1e-4 * diag));
  const auto& sc = src.animations[0].channels[1];
  const auto& oc = result->rig.animations[0].channels[1];
  ASSERT_EQ(sc.path, core::AnimationPath::kTranslation);
  const Eigen::RowVector3d rest = src.nodes[3].translation.transpose();
  EXPECT_TRUE(matricesNear(oc.values.row(30) - rest, 3.0 * (sc.values.row(30) - rest), 1e-6 * diag));
  // The jaw's rotation keys turn three times as far from its rest; the head,
  // at the global 1, keeps its keys.
  auto key = [](const core::AnimationChannel& c, Eigen::Index k) {
    return Eigen::Quaterniond(c.values(k, 3), c.values(k, 0), c.values(k, 1), c.values(k, 2));
  };
  const auto& jaw_in = src.animations[0].channels[0];
  const auto& jaw_out = result->rig.animations[0].channels[0];
  ASSERT_EQ(jaw_in.path, core::AnimationPath::kRotation);
  ASSERT_EQ(jaw_in.node, 3);
  const Eigen::Quaterniond jaw_rest = src.nodes[3].rotation;
  for (const Eigen::Index k : {5, 15, 25}) {
    EXPECT_NEAR(jaw_rest.angularDistance(key(jaw_out, k)), 3.0 * jaw_rest.angularDistance(key(jaw_in, k)), 1e-9);
  }
  EXPECT_GT(jaw_rest.angularDistance(key(jaw_out, 15)), 0.9);  // 3 x 18 degrees
  EXPECT_TRUE(matricesNear(result->rig.animations[0].channels[2].values, src.animations[0].channels[2].values, 1e-12));
}

// Joints off, weights on: the target is skinned to the source's joints as
// they are (same skin, same inverse binds), and the GLB writes.
TEST(TransferRig, WeightsWithoutMovingJointsKeepTheSourceSkin) {
  const core::SyntheticRig& target = otherHead();
  core::TransferOptions options;
  options.joints = false;
  auto result = core::transferRig(preparedSource(), target.rig.mesh, target.landmarks, "other", options);
  ASSERT_TRUE(result) << result.error().message;
  const core::Rig& src = sourceRig().rig;
  ASSERT_TRUE(result->rig.skin.has_value());
  EXPECT_EQ(result->rig.skin->joints, src.skin->joints);
  EXPECT_EQ(result->rig.weights.rows(), target.rig.mesh.vertexCount());
  auto glb = core::encodeRigGlb(result->rig);
  EXPECT_TRUE(glb) << glb.error().message;
}

// With joints left as they are (joints off), the clips still come with the
// asked exaggeration: on the source's own skeleton, keys move twice as far
// from rest (translation and rotation alike); nothing else changes.
TEST(TransferRig, ExaggerationAppliesWithoutTransferringJoints) {
  const core::Rig& src = sourceRig().rig;
  core::TransferOptions options;
  options.joints = false;
  options.joint_exaggeration["jaw"] = 2.0;
  auto result = core::transferRig(preparedSource(), src.mesh, sourceRig().landmarks, "self", options);
  ASSERT_TRUE(result) << result.error().message;
  const core::Rig& out = result->rig;
  ASSERT_EQ(out.nodes.size(), src.nodes.size());
  EXPECT_EQ(out.nodes[3].translation, src.nodes[3].translation);
  const auto& rotation_in = src.animations[0].channels[0];
  const auto& rotation_out = out.animations[0].channels[0];
  const auto& move_in = src.animations[0].channels[1];
  const auto& move_out = out.animations[0].channels[1];
  const Eigen::Quaterniond rest = src.nodes[3].rotation;
  const Eigen::RowVector3d rest_t = src.nodes[3].translation.transpose();
  for (const Eigen::Index k : {5, 15, 25}) {
    auto key = [](const core::AnimationChannel& c, Eigen::Index i) {
      return Eigen::Quaterniond(c.values(i, 3), c.values(i, 0), c.values(i, 1), c.values(i, 2));
    };
    EXPECT_NEAR(rest.angularDistance(key(rotation_out, k)), 2.0 * rest.angularDistance(key(rotation_in, k)), 1e-9);
    EXPECT_TRUE(matricesNear(move_out.values.row(k) - rest_t, 2.0 * (move_in.values.row(k) - rest_t), 1e-12));
  }
  // The head is not named: its keys are the source's, bit for bit.
  EXPECT_TRUE(out.animations[0].channels[2].values == src.animations[0].channels[2].values);
}

TEST(TransferRig, ExaggerationOfNamesTheRigLacksIsReported) {
  const core::Rig& src = sourceRig().rig;
  core::TransferOptions options;
  options.shape_exaggeration["JawOpen"] = 2.0;  // the rig's is jawOpen
  options.joint_exaggeration["chin"] = 1.5;
  auto result = core::transferRig(preparedSource(), src.mesh, sourceRig().landmarks, "self", options);
  ASSERT_TRUE(result);
  const auto& w = result->report.warnings;
  ASSERT_EQ(w.size(), 2u);
  EXPECT_NE(w[0].find("shape_exaggeration names 'JawOpen'"), std::string::npos) << w[0];
  EXPECT_NE(w[0].find("did you mean 'jawOpen'?"), std::string::npos) << w[0];
  EXPECT_NE(w[1].find("joint_exaggeration names 'chin'"), std::string::npos) << w[1];
  EXPECT_EQ(w[1].find("did you mean"), std::string::npos) << w[1];
  // Nothing else changes: the shapes keep their size.
  EXPECT_TRUE(matricesNear(result->rig.morph_targets[0].position_deltas, src.morph_targets[0].position_deltas,
                           1e-4 * core::boundingBoxDiagonal(src.mesh.positions)));
}

TEST(TransferRig, BadInputsGiveClearErrors) {
  core::Rig unskinned = sourceRig().rig;
  unskinned.skin.reset();
  unskinned.weights.resize(0, 0);
  auto prepared = core::prepareRig(unskinned, sourceRig().landmarks, "noskin.glb");
  ASSERT_TRUE(prepared);
  auto r = core::transferRig(*prepared, sourceRig().rig.mesh, sourceRig().landmarks, "t");
  ASSERT_FALSE(r);
  EXPECT_NE(r.error().message.find("no skin"), std::string::npos) << r.error().message;

  core::LandmarkSet renamed = sourceRig().landmarks;
  for (auto& lm : renamed.landmarks) lm.name = "x_" + lm.name;
  auto m = core::transferRig(preparedSource(), sourceRig().rig.mesh, renamed, "renamed.json");
  ASSERT_FALSE(m);
  EXPECT_NE(m.error().message.find("not among the rig's landmarks"), std::string::npos);

  core::LandmarkSet three;
  three.landmarks.assign(sourceRig().landmarks.landmarks.begin(), sourceRig().landmarks.landmarks.begin() + 3);
  auto f = core::transferRig(preparedSource(), sourceRig().rig.mesh, three, "three.json");
  ASSERT_FALSE(f);
  EXPECT_NE(f.error().message.find("at least 4"), std::string::npos);

  // Landmarks of another mesh: named as the likely cause, not "a scaled copy".
  core::LandmarkSet foreign = sourceRig().landmarks;
  for (auto& l : foreign.landmarks) l.face %= static_cast<int>(otherHead().rig.mesh.triangleCount());
  auto wrong = core::transferRig(preparedSource(), otherHead().rig.mesh, foreign, "other.glb");
  ASSERT_TRUE(wrong) << wrong.error().message;
  EXPECT_TRUE(wrong->report.warp.landmarks_misfit);
  for (const std::string& w : wrong->report.warnings) {
    EXPECT_EQ(w.find("times the size of the source"), std::string::npos) << w;
    EXPECT_EQ(w.find("stretched"), std::string::npos) << w;
  }

  core::Rig nan_keys = sourceRig().rig;
  nan_keys.animations[0].channels[0].values(3, 1) = std::numeric_limits<double>::quiet_NaN();
  auto n = core::prepareRig(nan_keys, sourceRig().landmarks, "nan.glb");
  ASSERT_FALSE(n);
  EXPECT_NE(n.error().message.find("non-finite"), std::string::npos);
}

// Drops morph-weight channels: the skinned (joint) motion alone.
core::Rig skinnedOnly(core::Rig rig) {
  for (auto& a : rig.animations) {
    std::erase_if(a.channels, [](const core::AnimationChannel& c) { return c.path == core::AnimationPath::kWeights; });
  }
  return rig;
}

TEST(TransferRig, AnimationStrainFollowsTheSource) {
  // Papers 000 sec. 5.3.1: eps = (l1 - l0) / l0 of the mouth opening (inner
  // lip midpoints) over the skinned clip, source vs target.
  // Same proportions (strain depends on the lever arm over the rest gap),
  // other topology and size: the relative opening must follow.
  core::SyntheticRig target = core::generateRig(core::HeadShape{}, core::HeadResolution{80, 76, true, 0.2, 21});
  target.rig.mesh.positions *= 1.3;
  auto result = core::transferRig(preparedSource(), target.rig.mesh, target.landmarks, "other");
  ASSERT_TRUE(result) << result.error().message;
  auto lipGap = [](const core::Rig& rig, const core::LandmarkSet& lms, const Eigen::MatrixX3d& posed) {
    auto at = [&](const char* name) {
      const auto& l = lms.landmarks[static_cast<std::size_t>(lms.indexOf(name))];
      Eigen::RowVector3d p = Eigen::RowVector3d::Zero();
      for (int k = 0; k < 3; ++k) p += l.barycentric(k) * posed.row(rig.mesh.triangles(l.face, k));
      return p;
    };
    return (at("mouth_inner_2") - at("mouth_inner_6")).norm();
  };
  const core::Rig src = skinnedOnly(sourceRig().rig);
  const core::Rig out = skinnedOnly(result->rig);
  const double l0s = lipGap(src, sourceRig().landmarks, src.mesh.positions);
  const double l0t = lipGap(out, target.landmarks, target.rig.mesh.positions);
  std::vector<double> es, et;
  for (int k = 0; k <= 60; ++k) {
    const double t = k / 30.0;
    es.push_back(lipGap(src, sourceRig().landmarks, core::poseMesh(src, core::samplePose(src, src.animations[0], t))) / l0s - 1);
    et.push_back(lipGap(out, target.landmarks, core::poseMesh(out, core::samplePose(out, out.animations[0], t))) / l0t - 1);
  }
  const Eigen::Map<Eigen::VectorXd> a(es.data(), static_cast<Eigen::Index>(es.size())), b(et.data(), static_cast<Eigen::Index>(et.size()));
  const Eigen::VectorXd ac = a.array() - a.mean(), bc = b.array() - b.mean();
  const double correlation = ac.dot(bc) / (ac.norm() * bc.norm());
  const double amplitude = (b.maxCoeff() - b.minCoeff()) / (a.maxCoeff() - a.minCoeff());
  std::printf("strain correlation %.4f amplitude ratio %.3f\n", correlation, amplitude);
  EXPECT_GE(correlation, 0.99);
  EXPECT_NEAR(amplitude, 1.0, 0.1);
}

}  // namespace
