// A rig's components document rebuilt on the fitted mesh by vertex index
// (paper 001 4.3; core/transfer/components_transfer.h rebuildComponents,
// through fitScan): bindings by vertex and face kept exactly, free points
// through the fit's dense map, lengths by the head's size. Posed with the
// same controls, the rebuilt document must move the fitted face as the
// reference's moves the reference, up to the fit's own change of shape.
#include <cmath>
#include <cstdio>
#include <numbers>
#include <string>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "core/components/pose.h"
#include "core/fit/fit.h"
#include "core/synthetic/synthetic_head.h"
#include "tests/core/fit/fit_fixtures.h"
#include "tests/test_support.h"

namespace {

using rigport_test::FitReferenceCase;

// The rig's landmark named `name`, and the vertex nearest it.
struct LandmarkAt {
  Eigen::Vector3d position;
  int vertex = -1;
};

LandmarkAt landmarkAt(const core::PreparedRig& rig, const std::string& name) {
  const auto& names = rig.surface.landmarks.landmarks;
  for (std::size_t l = 0; l < names.size(); ++l) {
    if (names[l].name != name) continue;
    LandmarkAt at;
    at.position = rig.surface.landmark_positions.row(static_cast<Eigen::Index>(l)).transpose();
    (rig.surface.mesh.positions.rowwise() - at.position.transpose()).rowwise().squaredNorm().minCoeff(&at.vertex);
    return at;
  }
  ADD_FAILURE() << "no landmark " << name;
  return {};
}

// A small mouth rig on the generated face, built from its landmarks: a
// zygomatic-like muscle (origin a free point inside the cheek, insertion the
// left mouth corner) sliding a corner cluster; an upper-lip wire whose CVs
// sit on lip vertices and follow the cluster; a locator bound by face and
// barycentric; preset "smile".
core::ComponentsDocument mouthRig(const core::PreparedRig& rig) {
  using namespace core;
  const core::Mesh& mesh = rig.surface.mesh;
  const LandmarkAt corner_l = landmarkAt(rig, "mouth_outer_0"), corner_r = landmarkAt(rig, "mouth_outer_6");
  const LandmarkAt top = landmarkAt(rig, "mouth_outer_3"), nose = landmarkAt(rig, "nose_bridge_3");
  const double width = (corner_l.position - corner_r.position).norm();
  const Eigen::Vector3d up = (nose.position - top.position).normalized();
  ComponentsDocument doc;
  doc.locators = {{"lip_top", Binding::onFace(mesh.triangles.rows() / 2, {0.2, 0.3, 0.5})}};
  Cluster corner{"corner_l", Binding::atVertex(corner_l.vertex), {}};
  for (Eigen::Index v = 0; v < mesh.vertexCount(); ++v) {
    const double d = (mesh.positions.row(v).transpose() - corner_l.position).norm() / (0.35 * width);
    if (d < 1.0) corner.members.push_back({static_cast<int>(v), (1.0 - d * d) * (1.0 - d * d)});
  }
  doc.clusters = {corner};
  Muscle zygomatic;
  zygomatic.name = "zygomatic_l";
  zygomatic.origin = Binding::atPosition(corner_l.position + 0.6 * width * up + 0.4 * (corner_l.position - corner_r.position));
  zygomatic.insertion = Binding::atVertex(corner_l.vertex);
  zygomatic.max_contraction = 0.4;
  zygomatic.drives = {{TargetKind::kCluster, "corner_l", MuscleDriveMode::kTranslate, 1.0}};
  doc.muscles = {zygomatic};
  NurbsCurve base{"lip_base", 3, {0, 0, 0, 0, 1, 1, 1, 1}, {}, {}, {}};
  for (const char* name : {"mouth_outer_0", "mouth_outer_2", "mouth_outer_4", "mouth_outer_6"}) {
    base.points.push_back(Binding::atVertex(landmarkAt(rig, name).vertex));
  }
  NurbsCurve lip = base;
  lip.name = "lip";
  lip.drivers = {{0, TargetKind::kCluster, "corner_l", 1.0}, {1, TargetKind::kCluster, "corner_l", 0.5}};
  doc.curves = {base, lip};
  Wire wire;
  wire.name = "upper_lip";
  wire.base_curve = "lip_base";
  wire.curve = "lip";
  wire.dropoff_distance = 0.25 * width;
  doc.wires = {wire};
  Control smile;
  smile.name = "smile";
  smile.drives = {{DriveTargetKind::kMuscle, "zygomatic_l", ClusterChannel::kTranslateX, JointChannel::kRotateX, 0.4}};
  doc.controls = {smile};
  doc.presets["smile"].controls = {{"smile", 1.0}};
  return doc;
}

// The generated rig with the mouth rig on it, prepared for fitting.
const FitReferenceCase& syntheticWithComponents() {
  static const FitReferenceCase loaded = [] {
    core::SyntheticRig generated = core::generateRig();
    auto prepared = core::prepareRig(std::move(generated.rig), std::move(generated.landmarks), "synthetic rig");
    if (prepared) prepared->components = mouthRig(*prepared);
    return rigport_test::preparedForFitting(std::move(prepared));
  }();
  return loaded;
}

// posed - rest of `doc` at preset "smile" on the mesh (#V by 3).
Eigen::MatrixX3d smileDisplacement(const Eigen::MatrixX3d& rest, const Eigen::MatrixX3i& triangles,
                                   const core::ComponentsDocument& doc) {
  auto controls = core::presetControls(doc, "smile");
  EXPECT_TRUE(controls) << controls.error().message;
  auto posed = core::evaluatePose(rest, triangles, doc, *controls);
  EXPECT_TRUE(posed) << posed.error().message;
  return posed ? Eigen::MatrixX3d(posed->positions - rest) : Eigen::MatrixX3d::Zero(rest.rows(), 3);
}

TEST(RebuildComponents, ReferenceMovedKeepsBindingsAndMovesFreePoints) {
  const FitReferenceCase& ref = syntheticWithComponents();
  ASSERT_TRUE(ref.reference) << ref.error;
  const core::ComponentsDocument& doc = *ref.rig->components;
  ASSERT_TRUE(core::validate(doc, ref.rig->rig.mesh.vertexCount()));

  core::Similarity move;  // 30 degrees, ten times the size (m -> dm), a shift
  move.rotation = Eigen::AngleAxisd(30.0 * std::numbers::pi / 180.0, Eigen::Vector3d(0.2, 1.0, -0.1).normalized())
                      .toRotationMatrix();
  move.scale = 10.0;
  move.translation = Eigen::Vector3d(3.0, -1.0, 2.0);
  const core::Mesh& rest = ref.rig->surface.mesh;
  core::Mesh scan;
  scan.positions = rest.positions;
  scan.triangles = rest.triangles;
  const core::LandmarkSet landmarks =
      rigport_test::positionLandmarks(ref.rig->surface.landmarks, ref.rig->surface.landmark_positions);
  const auto fit = core::fitScan(*ref.reference, rigport_test::transformed(scan, move),
                                 rigport_test::transformedLandmarks(landmarks, move), "reference moved");
  ASSERT_TRUE(fit) << fit.error().message;
  ASSERT_TRUE(fit->components.has_value());
  const core::ComponentsDocument& out = *fit->components;

  // Bindings to the mesh exactly kept; free points moved; lengths scaled.
  EXPECT_EQ(out.clusters, doc.clusters);
  EXPECT_EQ(out.curves, doc.curves);
  EXPECT_EQ(out.locators, doc.locators);
  EXPECT_EQ(out.muscles[0].insertion, doc.muscles[0].insertion);
  const double diagonal = move.scale * ref.rig->surface.diagonal;
  const Eigen::Vector3d origin = move.scale * move.rotation * doc.muscles[0].origin.position + move.translation;
  EXPECT_LE((out.muscles[0].origin.position - origin).norm(), 1e-9 * diagonal);
  EXPECT_NEAR(out.wires[0].dropoff_distance, move.scale * doc.wires[0].dropoff_distance, 1e-12 * diagonal);

  // Posed alike: the fitted face moves as the reference does, moved.
  const Eigen::MatrixX3d reference_move = smileDisplacement(rest.positions, rest.triangles, doc);
  const Eigen::MatrixX3d fitted_move = smileDisplacement(fit->rig.mesh.positions, fit->rig.mesh.triangles, out);
  const Eigen::MatrixX3d expected = move.scale * reference_move * move.rotation.transpose();
  ASSERT_GT(expected.rowwise().norm().maxCoeff(), 1e-3 * diagonal);  // the preset moves the mouth
  EXPECT_LE((fitted_move - expected).rowwise().norm().maxCoeff(), 1e-9 * diagonal);
}

// Another identity: the fitted face is not the reference, so the rebuilt
// document moves it as the reference's moves the reference only up to the
// change of shape (mouth width and lip curve differ: the same cluster weights
// and wire distance cover a different share of the lip). Measured 2026-11-28:
// E 0.105.
TEST(RebuildComponents, OtherIdentityMovesAlike) {
  const FitReferenceCase& ref = syntheticWithComponents();
  ASSERT_TRUE(ref.reference) << ref.error;
  const core::ComponentsDocument& doc = *ref.rig->components;
  const core::SyntheticHead head = core::generateHead(core::randomHeadShape(7, 0.15), core::HeadResolution{});
  const auto fit = core::fitScan(*ref.reference, head.mesh, head.landmarks, "generated head 7");
  ASSERT_TRUE(fit) << fit.error().message;
  ASSERT_TRUE(fit->components.has_value());
  EXPECT_EQ(fit->report.verdict, "ok");
  const core::Mesh& rest = ref.rig->surface.mesh;
  const Eigen::MatrixX3d reference_move = smileDisplacement(rest.positions, rest.triangles, doc);
  const Eigen::MatrixX3d fitted_move =
      smileDisplacement(fit->rig.mesh.positions, fit->rig.mesh.triangles, *fit->components);
  // The fit's own change of shape: the head's size (free points and lengths follow it).
  const double size = fit->report.scan.size_ratio;
  const double e = (fitted_move - size * reference_move).rowwise().norm().sum() / (size * reference_move).rowwise().norm().sum();
  std::printf("components on generated head 7 (size %.3f x the reference): E %.4f between the fitted and the "
              "reference's smile\n", size, e);
  EXPECT_LE(e, 0.15);
}

}  // namespace
