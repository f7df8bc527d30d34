// The rig rebuilt on the fitted mesh (core/fit/rebuild.cpp, through fitScan):
// with the reference's own surface as the scan, the fit is the reference
// (moved as the scan was), so the rebuilt rig must be the reference's in the
// scan's frame and units: skin weights copied as they are, joints whose
// inverse binds make the fitted mesh the bind pose, deltas turned by the
// alignment and scaled by the units only. On the generated rig (always) and
// on ICT (when ../shared/data is present).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <string>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "core/fit/fit.h"
#include "core/rig/skinning.h"
#include "tests/core/fit/fit_fixtures.h"
#include "tests/test_support.h"

namespace {

using rigport_test::FitReferenceCase;

core::Similarity identity() { return {}; }

// 40 degrees about a tilted axis, `unit_factor` times the size, a shift.
core::Similarity turned(double unit_factor) {
  core::Similarity s;
  s.rotation = Eigen::AngleAxisd(40.0 * std::numbers::pi / 180.0, Eigen::Vector3d(-0.4, 1.0, 0.3).normalized())
                   .toRotationMatrix();
  s.scale = unit_factor;
  s.translation = unit_factor * Eigen::Vector3d(0.7, -0.2, 0.4);
  return s;
}

// World positions of the skin's joints.
Eigen::MatrixX3d jointPositions(const core::Rig& rig) {
  const std::vector<Eigen::Matrix4d> world = core::nodeWorldTransforms(rig.nodes);
  Eigen::MatrixX3d out(static_cast<Eigen::Index>(rig.skin->joints.size()), 3);
  for (std::size_t j = 0; j < rig.skin->joints.size(); ++j) {
    out.row(static_cast<Eigen::Index>(j)) = world[static_cast<std::size_t>(rig.skin->joints[j])].block<3, 1>(0, 3).transpose();
  }
  return out;
}

// The reference's own surface, moved by `move`, fitted with its own
// landmarks (moved alike); the rebuilt rig checked against the reference.
void expectRebuiltAsTheReferenceMoved(const FitReferenceCase& ref, const core::Similarity& move,
                                      const std::string& units) {
  const core::PreparedRig& prepared = *ref.rig;
  const core::Rig& source = prepared.rig;
  core::Mesh scan;
  scan.positions = source.mesh.positions;
  scan.triangles = source.mesh.triangles;
  const core::LandmarkSet landmarks =
      rigport_test::positionLandmarks(prepared.surface.landmarks, prepared.surface.landmark_positions);
  const auto fit = core::fitScan(*ref.reference, rigport_test::transformed(scan, move),
                                 rigport_test::transformedLandmarks(landmarks, move), "reference moved");
  ASSERT_TRUE(fit) << fit.error().message;
  const core::Rig& rig = fit->rig;
  const core::FitReport& r = fit->report;
  EXPECT_EQ(r.scan.units, units);
  EXPECT_NEAR(r.unit_scale, move.scale, 1e-12 * move.scale);
  const double diagonal = move.scale * prepared.surface.diagonal;  // scan units

  // Positions: the reference moved; topology and UVs its own.
  const Eigen::MatrixX3d expected = rigport_test::transformedPoints(source.mesh.positions, move);
  EXPECT_TRUE(rigport_test::matricesNear(rig.mesh.positions, expected, 1e-9 * diagonal));
  EXPECT_EQ(rig.mesh.triangles, source.mesh.triangles);
  EXPECT_EQ(rig.mesh.uvs, source.mesh.uvs);

  // Skin weights: the very same.
  ASSERT_TRUE(rig.skin.has_value());
  EXPECT_EQ(rig.skin->joints, source.skin->joints);
  ASSERT_EQ(rig.weights.rows(), source.weights.rows());
  ASSERT_EQ(rig.weights.cols(), source.weights.cols());
  EXPECT_EQ(rig.weights.nonZeros(), source.weights.nonZeros());
  EXPECT_EQ((rig.weights - source.weights).norm(), 0.0);

  // Joints: moved as the mesh, and bound to it: skinning at rest (every node
  // at its rest transform, no shape) reproduces the fitted positions.
  EXPECT_TRUE(rigport_test::matricesNear(jointPositions(rig), rigport_test::transformedPoints(jointPositions(source), move),
                                         1e-7 * diagonal));
  core::Pose rest;
  rest.nodes = rig.nodes;
  rest.morph_weights = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(rig.morph_targets.size()));
  EXPECT_TRUE(rigport_test::matricesNear(core::poseMesh(rig, rest), rig.mesh.positions, 1e-9 * diagonal));
  EXPECT_GT(r.joints, 0);

  // Deltas: unit factor x rotation x the reference's; normal deltas turned.
  ASSERT_EQ(rig.morph_targets.size(), source.morph_targets.size());
  EXPECT_EQ(r.shapes, static_cast<int>(source.morph_targets.size()));
  double worst = 0.0, largest = 0.0;
  for (std::size_t k = 0; k < source.morph_targets.size(); ++k) {
    const core::MorphTarget& in = source.morph_targets[k];
    const core::MorphTarget& out = rig.morph_targets[k];
    EXPECT_EQ(out.name, in.name);
    const Eigen::MatrixX3d deltas = move.scale * in.position_deltas * move.rotation.transpose();
    worst = std::max(worst, (out.position_deltas - deltas).cwiseAbs().maxCoeff());
    largest = std::max(largest, deltas.cwiseAbs().maxCoeff());
    if (in.normal_deltas.rows() > 0) {
      EXPECT_TRUE(rigport_test::matricesNear(out.normal_deltas, in.normal_deltas * move.rotation.transpose(), 1e-12))
          << in.name;
    }
  }
  std::printf("%s: deltas off by at most %.3g (largest %.3g, scan units), %zu shapes, %d joints moved\n",
              prepared.surface.label.c_str(), worst, largest, rig.morph_targets.size(), r.joints);
  EXPECT_LE(worst, 1e-12 * largest);

  // The rig's other meshes: moved as the face was, weights and shapes kept.
  ASSERT_EQ(rig.parts.size(), source.parts.size());
  ASSERT_EQ(r.parts.size(), source.parts.size());
  for (std::size_t p = 0; p < source.parts.size(); ++p) {
    const core::RigPart& in = source.parts[p];
    const core::RigPart& out = rig.parts[p];
    SCOPED_TRACE(in.name);
    EXPECT_EQ(out.name, in.name);
    EXPECT_TRUE(rigport_test::matricesNear(out.mesh.positions, rigport_test::transformedPoints(in.mesh.positions, move),
                                           1e-7 * diagonal));
    EXPECT_EQ((out.weights - in.weights).norm(), 0.0);
    ASSERT_EQ(out.morph_targets.size(), in.morph_targets.size());
    for (std::size_t k = 0; k < in.morph_targets.size(); ++k) {
      const Eigen::MatrixX3d deltas = move.scale * in.morph_targets[k].position_deltas * move.rotation.transpose();
      EXPECT_LE((out.morph_targets[k].position_deltas - deltas).cwiseAbs().maxCoeff(), 1e-6 * (largest + 1e-30))
          << in.morph_targets[k].name;
    }
  }
}

TEST(RebuildRig, GeneratedRigOnItselfIsItself) {
  const FitReferenceCase& ref = rigport_test::syntheticFitReference();
  ASSERT_TRUE(ref.reference) << ref.error;
  expectRebuiltAsTheReferenceMoved(ref, identity(), "m");
}

TEST(RebuildRig, GeneratedRigOnItselfTurnedAndInMillimetres) {
  const FitReferenceCase& ref = rigport_test::syntheticFitReference();
  ASSERT_TRUE(ref.reference) << ref.error;
  expectRebuiltAsTheReferenceMoved(ref, turned(1000.0), "mm");  // m -> mm
}

TEST(RebuildRig, IctOnItselfIsItself) {
  RIGPORT_REQUIRE_SHARED_DATA(data);
  const FitReferenceCase& ref = rigport_test::ictFitReference(data);
  ASSERT_TRUE(ref.reference) << "ICT reference did not load: " << ref.error;
  expectRebuiltAsTheReferenceMoved(ref, identity(), "cm");
}

TEST(RebuildRig, IctOnItselfTurnedAndInMillimetres) {
  RIGPORT_REQUIRE_SHARED_DATA(data);
  const FitReferenceCase& ref = rigport_test::ictFitReference(data);
  ASSERT_TRUE(ref.reference) << "ICT reference did not load: " << ref.error;
  expectRebuiltAsTheReferenceMoved(ref, turned(10.0), "mm");  // cm -> mm
}

// The multi-mesh ICT rig (eyeballs, teeth, gums and tongue, lashes): every
// mesh rebuilt with the face.
TEST(RebuildRig, IctMultiMeshOnItselfTurnedAndInMillimetres) {
  RIGPORT_REQUIRE_SHARED_DATA(data);
  static const FitReferenceCase ref = rigport_test::loadIctFitReference(data, "source_face_full.glb");
  ASSERT_TRUE(ref.reference) << "ICT multi-mesh reference did not load: " << ref.error;
  ASSERT_EQ(ref.rig->rig.parts.size(), 6u);
  expectRebuiltAsTheReferenceMoved(ref, turned(10.0), "mm");  // cm -> mm
}

// The components switches: what is left out is absent from the output.
TEST(RebuildRig, ComponentsLeftOutAreAbsent) {
  const FitReferenceCase& ref = rigport_test::syntheticFitReference();
  ASSERT_TRUE(ref.reference) << ref.error;
  const core::PreparedRig& prepared = *ref.rig;
  core::Mesh scan;
  scan.positions = prepared.rig.mesh.positions;
  scan.triangles = prepared.rig.mesh.triangles;
  const core::LandmarkSet landmarks =
      rigport_test::positionLandmarks(prepared.surface.landmarks, prepared.surface.landmark_positions);
  core::FitOptions options;
  options.rebuild.weights = false;
  options.rebuild.shapes = false;
  options.rebuild.animations = false;
  options.rebuild.attributes = false;
  const auto fit = core::fitScan(*ref.reference, scan, landmarks, "reference", options);
  ASSERT_TRUE(fit) << fit.error().message;
  EXPECT_FALSE(fit->rig.skin.has_value());
  EXPECT_EQ(fit->rig.weights.nonZeros(), 0);
  EXPECT_TRUE(fit->rig.morph_targets.empty());
  EXPECT_TRUE(fit->rig.animations.empty());
  EXPECT_TRUE(fit->rig.attributes.labels.empty());
  EXPECT_FALSE(prepared.rig.morph_targets.empty());
  EXPECT_FALSE(prepared.rig.animations.empty());
  EXPECT_FALSE(prepared.rig.attributes.labels.empty());
}

}  // namespace
