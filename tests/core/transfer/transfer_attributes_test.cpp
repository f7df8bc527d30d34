// Tests core/transfer/transfer.cpp and core/transfer/attributes.cpp across the
// lips and UV seams: region labels, fields and colours never take the other
// lip's value, and UVs keep each target triangle on one chart.
#include "core/transfer/transfer.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <numbers>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "core/geometry/mesh.h"
#include "core/io/rig_io.h"
#include "core/rig/rig.h"
#include "tests/core/transfer/transfer_rigs.h"
#include "tests/test_support.h"

namespace {

using rigport_test::matricesNear;
using namespace rigport_test::transfer;

// Without region labels on the target (a scan): normal compatibility and the
// thin-gap test alone keep the lips apart.
TEST(TransferRig, LowerLipNeverTakesTheUpperLip) {
  const core::SyntheticRig& target = lipTarget();
  core::Mesh scan = target.rig.mesh;
  scan.regions.resize(0);
  core::TransferOptions lip_options;
  lip_options.diagnostic_attributes = true;
  auto result = core::transferRig(preparedSource(), scan, target.landmarks, "other", lip_options);
  ASSERT_TRUE(result) << result.error().message;
  EXPECT_FALSE(result->report.warp.region_matching);
  const Eigen::VectorXi& truth = target.rig.attributes.labels.at("REGION");
  const Eigen::VectorXi& moved = result->rig.attributes.labels.at("REGION");
  int lower = 0, wrong = 0;
  for (Eigen::Index v = 0; v < truth.size(); ++v) {
    if (truth(v) == core::kRegionLowerLip) {
      ++lower;
      wrong += moved(v) == core::kRegionUpperLip;
    }
    if (truth(v) == core::kRegionUpperLip) wrong += moved(v) == core::kRegionLowerLip;

  }
  EXPECT_GT(lower, 20);
  EXPECT_EQ(wrong, 0);
  // jawOpen moves the lower lip, not the upper one.
  const auto& jaw = result->rig.morph_targets[0].position_deltas;
  double upper = 0, lower_motion = 0;
  int nu = 0, nl = 0;
  for (Eigen::Index v = 0; v < truth.size(); ++v) {
    if (truth(v) == core::kRegionUpperLip) upper += jaw.row(v).norm(), ++nu;
    if (truth(v) == core::kRegionLowerLip) lower_motion += jaw.row(v).norm(), ++nl;
  }
  EXPECT_LT(upper / nu, 0.1 * lower_motion / nl);
}

// Region-constrained matching end to end: the target is another head with
// its lips pressed shut (each lip moved half the slit towards the other, so
// the rims meet), matched with the normal filters and the gap test off, so
// that nothing but the labels keeps the lips apart. (The mechanism itself is
// tested on coincident sheets in correspondence_test.)
TEST(TransferRig, RegionLabelsKeepPressedLipsApart) {
  const core::Rig& target = lipTarget().rig;
  const Eigen::VectorXi& truth = target.attributes.labels.at("REGION");
  double upper_bottom = std::numeric_limits<double>::infinity(), lower_top = -upper_bottom;
  for (Eigen::Index v = 0; v < truth.size(); ++v) {
    if (truth(v) == core::kRegionUpperLip) upper_bottom = std::min(upper_bottom, target.mesh.positions(v, 1));
    if (truth(v) == core::kRegionLowerLip) lower_top = std::max(lower_top, target.mesh.positions(v, 1));
  }
  const double slit = upper_bottom - lower_top;
  ASSERT_GT(slit, 0.0);
  core::Mesh pressed = target.mesh;
  for (Eigen::Index v = 0; v < truth.size(); ++v) {
    if (truth(v) == core::kRegionUpperLip) pressed.positions(v, 1) -= 0.5 * slit;
    if (truth(v) == core::kRegionLowerLip) pressed.positions(v, 1) += 0.5 * slit;
  }
  pressed.normals = core::computeVertexNormals(pressed.positions, pressed.triangles);
  pressed.regions.resize(0);  // a scan: no labels
  core::TransferOptions options;
  options.warp.projection.max_normal_angle_deg = 180.0;
  options.warp.locate.max_normal_angle_deg = 180.0;
  options.warp.locate.max_relative_distance = 0.0;

  auto unlabelled = core::transferRig(preparedSource(), pressed, lipTarget().landmarks, "unlabelled", options);
  ASSERT_TRUE(unlabelled) << unlabelled.error().message;
  EXPECT_FALSE(unlabelled->report.warp.region_matching);
  EXPECT_TRUE(unlabelled->report.warp.warnings.empty());  // labelled rigs onto unlabelled scans: the usual case

  core::Mesh labelled = pressed;
  labelled.regions = truth;
  auto constrained = core::transferRig(preparedSource(), labelled, lipTarget().landmarks, "labelled", options);
  ASSERT_TRUE(constrained) << constrained.error().message;
  EXPECT_TRUE(constrained->report.warp.region_matching);
  EXPECT_TRUE(constrained->report.warp.warnings.empty());
  // No lip vertex takes the other lip's label, and the upper lip stays still
  // under jawOpen.
  const Eigen::VectorXi& moved = constrained->rig.attributes.labels.at("REGION");
  const Eigen::MatrixX3d& jaw = constrained->rig.morph_targets[0].position_deltas;
  const double lower_motion = jaw.rowwise().norm().maxCoeff();
  int upper = 0, lower = 0;
  for (Eigen::Index v = 0; v < truth.size(); ++v) {
    if (truth(v) == core::kRegionLowerLip) {
      ++lower;
      EXPECT_NE(moved(v), core::kRegionUpperLip) << "lower-lip vertex " << v;
    }
    if (truth(v) == core::kRegionUpperLip) {
      ++upper;
      EXPECT_NE(moved(v), core::kRegionLowerLip) << "upper-lip vertex " << v;
      EXPECT_LT(jaw.row(v).norm(), 0.25 * lower_motion) << "upper-lip vertex " << v;
    }
  }
  EXPECT_GT(upper, 20);
  EXPECT_GT(lower, 20);

  // Labels present but the option off: exactly the unlabelled result.
  options.warp.region_matching = false;
  auto switched_off = core::transferRig(preparedSource(), labelled, lipTarget().landmarks, "labelled", options);
  ASSERT_TRUE(switched_off) << switched_off.error().message;
  EXPECT_FALSE(switched_off->report.warp.region_matching);
  EXPECT_EQ(switched_off->rig.morph_targets[0].position_deltas, unlabelled->rig.morph_targets[0].position_deltas);

  // A region the other side does not have is named.
  options.warp.region_matching = true;
  core::Mesh relabelled = labelled;
  for (Eigen::Index v = 0; v < relabelled.regions.size(); ++v) {
    if (relabelled.regions(v) == core::kRegionUpperLid) relabelled.regions(v) = 9;
  }
  auto renumbered = core::transferRig(preparedSource(), relabelled, lipTarget().landmarks, "relabelled", options);
  ASSERT_TRUE(renumbered) << renumbered.error().message;
  ASSERT_EQ(renumbered->report.warp.warnings.size(), 2u);
  EXPECT_EQ(renumbered->report.warp.warnings[0],
            "region label 3 occurs on the source but not on relabelled: those source vertices cannot match (left "
            "unmatched)");
  EXPECT_EQ(renumbered->report.warp.warnings[1],
            "region label 9 occurs on relabelled but not on the source: those target vertices cannot be located "
            "(inpainted)");

  // No label in common: a clear error, not a rig of inpainted vertices.
  core::Mesh disjoint = labelled;
  disjoint.regions.array() += 10;
  auto refused = core::transferRig(preparedSource(), disjoint, lipTarget().landmarks, "disjoint.glb", options);
  ASSERT_FALSE(refused);
  EXPECT_EQ(refused.error().message,
            "disjoint.glb: its _REGION labels (10, 11, 12, 13, 14) share none with the source's (0, 1, 2, 3, 4): "
            "nothing could match; check the numbering, or set region_matching to false");

  // Labels on the target only: said, and ignored.
  core::Rig unlabelled_rig = sourceRig().rig;
  unlabelled_rig.attributes.labels.erase("REGION");
  auto unlabelled_source = core::prepareRig(unlabelled_rig, sourceRig().landmarks, "source without regions");
  ASSERT_TRUE(unlabelled_source) << unlabelled_source.error().message;
  auto one_sided = core::transferRig(*unlabelled_source, labelled, lipTarget().landmarks, "labelled", options);
  ASSERT_TRUE(one_sided) << one_sided.error().message;
  EXPECT_FALSE(one_sided->report.warp.region_matching);
  ASSERT_EQ(one_sided->report.warp.warnings.size(), 1u);
  EXPECT_EQ(one_sided->report.warp.warnings[0],
            "labelled carries _REGION labels but the source does not: matching is not region-constrained");
}

// Fields and colours follow the same rule as labels: a vertex matched across
// the lip gap never copies the other lip's value; inpainted values blend
// their surroundings (harmonic: within the range of the field). The field is
// +1 on the lower lip, -1 on the upper one, 0 elsewhere.
TEST(TransferRig, FieldsAndColoursNeverCrossTheLips) {
  core::Rig rig = sourceRig().rig;
  const Eigen::VectorXi& region = rig.attributes.labels.at("REGION");
  const Eigen::VectorXd lips = (region.array() == core::kRegionLowerLip).cast<double>() -
                               (region.array() == core::kRegionUpperLip).cast<double>();
  rig.attributes.fields["LIPS"] = lips;
  rig.attributes.colors = Eigen::MatrixXd::Ones(rig.mesh.vertexCount(), 4);
  rig.attributes.colors.col(0) = 0.5 * (lips.array() + 1.0);
  auto prepared = core::prepareRig(rig, sourceRig().landmarks, "source with a lip field");
  ASSERT_TRUE(prepared) << prepared.error().message;
  const core::SyntheticRig& target = lipTarget();
  core::Mesh scan = target.rig.mesh;  // no region labels: normals and the gap test alone
  scan.regions.resize(0);
  auto result = core::transferRig(*prepared, scan, target.landmarks, "other");
  ASSERT_TRUE(result) << result.error().message;
  ASSERT_GT(result->report.warp.low_confidence_vertices, 0) << "the case must exercise untrusted vertices";
  const Eigen::VectorXi& truth = target.rig.attributes.labels.at("REGION");
  const Eigen::MatrixXd& field = result->rig.attributes.fields.at("LIPS");
  const Eigen::MatrixXd& colors = result->rig.attributes.colors;
  ASSERT_EQ(field.rows(), truth.size());
  ASSERT_EQ(colors.rows(), truth.size());
  EXPECT_GE(field.minCoeff(), -1.0 - 1e-12);
  EXPECT_LE(field.maxCoeff(), 1.0 + 1e-12);
  int upper = 0, lower = 0;
  for (Eigen::Index v = 0; v < truth.size(); ++v) {
    if (truth(v) == core::kRegionUpperLip) {
      ++upper;
      EXPECT_LT(field(v, 0), 0.5) << "upper-lip vertex " << v;
      EXPECT_LT(colors(v, 0), 0.75) << "upper-lip vertex " << v;
    }
    if (truth(v) == core::kRegionLowerLip) {
      ++lower;
      EXPECT_GT(field(v, 0), -0.5) << "lower-lip vertex " << v;
      EXPECT_GT(colors(v, 0), 0.25) << "lower-lip vertex " << v;
    }
  }
  EXPECT_GT(upper, 20);
  EXPECT_GT(lower, 20);
}

// UVs are seam-aware: a cylindrical unwrap with its seam down one side of
// the head (the vertices of triangles across it split into a second chart, as
// in any UV-mapped mesh). Every target triangle takes one chart, so none
// spans the atlas (u from near 0 to near 1); target vertices where the seam
// crosses are split, each copy carrying the same weights and shapes.
TEST(TransferRig, UvsKeepEachTriangleOnItsOwnChart) {
  core::Rig rig = sourceRig().rig;
  const Eigen::RowVector3d centre =
      0.5 * (rig.mesh.positions.colwise().minCoeff() + rig.mesh.positions.colwise().maxCoeff());
  // Around the vertical axis, the seam (angle +-pi) down the side of the head.
  auto angle = [&](const Eigen::RowVector3d& p) { return std::atan2(p(2) - centre(2), -(p(0) - centre(0))); };
  auto unwrap = [&](const Eigen::MatrixX3d& positions) {
    Eigen::MatrixX2d uvs(positions.rows(), 2);
    for (Eigen::Index v = 0; v < positions.rows(); ++v) {
      uvs.row(v) << angle(positions.row(v)) / (2 * std::numbers::pi) + 0.5, (positions(v, 1) - centre(1)) / 40.0 + 0.5;
    }
    return uvs;
  };
  Eigen::MatrixX2d uvs = unwrap(rig.mesh.positions);
  std::map<int, int> second_chart;  // vertex -> its copy with u + 1
  std::vector<int> copy_of;
  int crossing = 0;
  for (Eigen::Index f = 0; f < rig.mesh.triangleCount(); ++f) {
    const Eigen::Vector3d u(uvs(rig.mesh.triangles(f, 0), 0), uvs(rig.mesh.triangles(f, 1), 0), uvs(rig.mesh.triangles(f, 2), 0));
    if (u.maxCoeff() - u.minCoeff() < 0.5) continue;  // not across the seam
    ++crossing;
    for (int k = 0; k < 3; ++k) {
      const int v = rig.mesh.triangles(f, k);
      if (u(k) >= 0.5) continue;
      auto [it, added] = second_chart.emplace(v, static_cast<int>(rig.mesh.vertexCount() + std::ssize(copy_of)));
      if (added) copy_of.push_back(v);
      rig.mesh.triangles(f, k) = it->second;
    }
  }
  ASSERT_GT(crossing, 10);
  core::appendVertexCopies(rig, copy_of);
  ASSERT_EQ(rig.mesh.positions.rows(), uvs.rows() + std::ssize(copy_of));
  uvs.conservativeResize(rig.mesh.vertexCount(), 2);
  for (const auto& [v, copy] : second_chart) uvs.row(copy) = uvs.row(v) + Eigen::RowVector2d(1.0, 0.0);
  rig.mesh.uvs = uvs;
  // A second set without seams (a planar projection, as a lightmap might be).
  rig.attributes.extra_uv_sets = {rig.mesh.positions.leftCols(2) / 40.0};
  auto prepared = core::prepareRig(rig, sourceRig().landmarks, "source with a UV seam");
  ASSERT_TRUE(prepared) << prepared.error().message;

  const core::SyntheticRig& target = lipTarget();
  const Eigen::Index nt = target.rig.mesh.vertexCount();
  core::TransferOptions options;
  options.uvs = true;
  auto result = core::transferRig(*prepared, target.rig.mesh, target.landmarks, "other", options);
  ASSERT_TRUE(result) << result.error().message;
  const core::Rig& out = result->rig;
  const Eigen::Index added = result->report.uv_seam_vertices;
  EXPECT_GT(added, 5);
  EXPECT_GT(result->report.uv_extended_vertices, 5);
  ASSERT_EQ(out.mesh.vertexCount(), nt + added);
  ASSERT_EQ(out.mesh.uvs.rows(), nt + added);
  ASSERT_EQ(out.weights.rows(), nt + added);
  ASSERT_EQ(out.attributes.extra_uv_sets.size(), 1u);
  ASSERT_EQ(out.attributes.extra_uv_sets[0].rows(), nt + added);
  ASSERT_EQ(out.mesh.triangleCount(), target.rig.mesh.triangleCount());
  // The target's vertices keep their places and order; each copy sits on the
  // target vertex it was made from (found through the triangles) and carries
  // its weights and shape deltas.
  EXPECT_EQ(out.mesh.positions.topRows(nt), target.rig.mesh.positions);
  std::vector<int> original(static_cast<std::size_t>(nt + added), -1);
  for (Eigen::Index f = 0; f < out.mesh.triangleCount(); ++f) {
    for (int k = 0; k < 3; ++k) {
      const int v = out.mesh.triangles(f, k), was = target.rig.mesh.triangles(f, k);
      ASSERT_TRUE(v == was || v >= nt) << "triangle " << f << " corner " << k;
      int& o = original[static_cast<std::size_t>(v)];
      ASSERT_TRUE(o < 0 || o == was) << "vertex " << v << " copies two target vertices";
      o = was;
    }
  }
  const Eigen::MatrixXd weights(out.weights);
  for (Eigen::Index c = nt; c < nt + added; ++c) {
    const int v = original[static_cast<std::size_t>(c)];
    ASSERT_GE(v, 0) << "copy " << c << " is on no triangle";
    EXPECT_EQ(out.mesh.positions.row(c), out.mesh.positions.row(v));
    EXPECT_EQ(weights.row(c), weights.row(v));
    for (const core::MorphTarget& shape : out.morph_targets) EXPECT_EQ(shape.position_deltas.row(c), shape.position_deltas.row(v));
    // The other side of the seam: u about one apart, v the same; the
    // seamless set about the same.
    EXPECT_NEAR(std::abs(out.mesh.uvs(c, 0) - out.mesh.uvs(v, 0)), 1.0, 0.05) << "copy " << c << " of " << v;
    EXPECT_NEAR(out.mesh.uvs(c, 1), out.mesh.uvs(v, 1), 0.02) << "copy " << c << " of " << v;
    EXPECT_LT((out.attributes.extra_uv_sets[0].row(c) - out.attributes.extra_uv_sets[0].row(v)).norm(), 1e-3) << "copy " << c;
  }
  // No triangle across the atlas; near the seam no blend of the two charts.
  for (Eigen::Index f = 0; f < out.mesh.triangleCount(); ++f) {
    const Eigen::Vector3d u(out.mesh.uvs(out.mesh.triangles(f, 0), 0), out.mesh.uvs(out.mesh.triangles(f, 1), 0),
                            out.mesh.uvs(out.mesh.triangles(f, 2), 0));
    ASSERT_LT(u.maxCoeff() - u.minCoeff(), 0.2) << "triangle " << f << " spans the atlas: u " << u.transpose();
  }
  int at_seam = 0;
  for (Eigen::Index v = 0; v < out.mesh.vertexCount(); ++v) {
    ASSERT_TRUE(out.mesh.uvs.row(v).allFinite()) << "vertex " << v;
    if (std::abs(angle(out.mesh.positions.row(v))) < 0.97 * std::numbers::pi) continue;
    ++at_seam;
    EXPECT_GT(std::abs(out.mesh.uvs(v, 0) - 0.5), 0.35) << "vertex " << v << " at the seam blends the two charts";
  }
  EXPECT_GT(at_seam, 5);
  const auto glb = rigport_test::makeTempDir("uv_seams") / "seams.glb";
  ASSERT_TRUE(core::writeRigGlb(out, glb)) << glb;
  EXPECT_GLTF_VALID(glb);

  // A layout without seams (a planar projection): nothing to split, and every
  // vertex takes the UVs of its location (linear in x and y).
  core::Rig planar = sourceRig().rig;
  planar.mesh.uvs = planar.mesh.positions.leftCols(2) / 40.0;
  auto planar_source = core::prepareRig(planar, sourceRig().landmarks, "planar");
  ASSERT_TRUE(planar_source) << planar_source.error().message;
  auto flat = core::transferRig(*planar_source, target.rig.mesh, target.landmarks, "other", options);
  ASSERT_TRUE(flat) << flat.error().message;
  EXPECT_EQ(flat->report.uv_seam_vertices, 0);
  ASSERT_EQ(flat->rig.mesh.vertexCount(), nt);
  EXPECT_EQ(flat->rig.mesh.triangles, target.rig.mesh.triangles);

  // A rig without UVs: said, and the target keeps its own.
  auto without = core::transferRig(preparedSource(), target.rig.mesh, target.landmarks, "other", options);
  ASSERT_TRUE(without) << without.error().message;
  EXPECT_EQ(without->rig.mesh.uvs, target.rig.mesh.uvs);
  EXPECT_EQ(without->rig.mesh.vertexCount(), nt);
  EXPECT_NE(std::find(without->report.warnings.begin(), without->report.warnings.end(),
                      "uvs: " + preparedSource().surface.label + " has no UV set to transfer; other keeps its own UVs"),
            without->report.warnings.end());

  // Vertices with no location (a region label the rig lacks: the upper
  // lids) take UVs inpainted from their located neighbours: inside the range
  // those span, on no triangle across the atlas.
  core::Mesh relabelled = target.rig.mesh;
  relabelled.regions = target.rig.attributes.labels.at("REGION");
  for (Eigen::Index v = 0; v < relabelled.regions.size(); ++v) {
    if (relabelled.regions(v) == core::kRegionUpperLid) relabelled.regions(v) = 9;
  }
  auto lidless = core::transferRig(*prepared, relabelled, target.landmarks, "relabelled", options);
  ASSERT_TRUE(lidless) << lidless.error().message;
  EXPECT_GT(lidless->report.unlocated_vertices, 10);
  const core::Mesh& lid_out = lidless->rig.mesh;
  Eigen::RowVector2d lo = Eigen::RowVector2d::Constant(1e9), hi = -lo;
  for (Eigen::Index v = 0; v < nt; ++v) {
    if (relabelled.regions(v) == 9) continue;
    lo = lo.cwiseMin(lid_out.uvs.row(v));
    hi = hi.cwiseMax(lid_out.uvs.row(v));
  }
  for (Eigen::Index v = 0; v < nt; ++v) {
    if (relabelled.regions(v) != 9) continue;
    ASSERT_TRUE((lid_out.uvs.row(v).array() >= lo.array() - 1e-9).all() && (lid_out.uvs.row(v).array() <= hi.array() + 1e-9).all())
        << "lid vertex " << v << " UV " << lid_out.uvs.row(v);
  }
  for (Eigen::Index f = 0; f < lid_out.triangleCount(); ++f) {
    const Eigen::Vector3d u(lid_out.uvs(lid_out.triangles(f, 0), 0), lid_out.uvs(lid_out.triangles(f, 1), 0),
                            lid_out.uvs(lid_out.triangles(f, 2), 0));
    ASSERT_LT(u.maxCoeff() - u.minCoeff(), 0.2) << "triangle " << f << " spans the atlas: u " << u.transpose();
  }
}

}  // namespace
