#include "core/correspond/opening_sides.h"

#include <cmath>
#include <limits>
#include <numbers>
#include <map>

#include <gtest/gtest.h>

#include "core/solve/inpainting.h"
#include "core/io/landmarks.h"
#include "core/synthetic/synthetic_rig.h"
#include "core/transfer/transfer.h"
#include "tests/test_support.h"

namespace {

TEST(OpeningSides, LipsAndLidsOfAHeadTakeTheirOwnSide) {
  const core::PreparedRig& source = rigport_test::preparedTouchingLipsSource();
  ASSERT_EQ(source.surface.openings.size(), 3u);  // the mouth and the two eyes, not the neck or the back
  const Eigen::VectorXi& truth = rigport_test::touchingLipsSource().rig.attributes.labels.at("REGION");
  // A painted lip or lid takes one side of its opening (per eye for the lids,
  // which one region paints on both), never both; most of the lips have one.
  std::map<int, std::map<int, int>> sides_of_region;
  for (Eigen::Index v = 0; v < truth.size(); ++v) {
    const int side = source.surface.vertex_sides[static_cast<std::size_t>(v)];
    if (truth(v) != core::kRegionSkin && side >= 0) ++sides_of_region[truth(v)][side];
  }
  for (const int region : {core::kRegionUpperLip, core::kRegionLowerLip, core::kRegionUpperLid, core::kRegionLowerLid}) {
    const auto& sides = sides_of_region[region];
    EXPECT_EQ(sides.size(), region == core::kRegionUpperLip || region == core::kRegionLowerLip ? 1u : 2u)
        << "region " << region;
    for (const auto& [a, count_a] : sides) {
      for (const auto& [b, count_b] : sides) EXPECT_FALSE(core::oppositeSides(a, b)) << "region " << region;
    }
  }
  const auto side_of = [&](int region) { return sides_of_region[region].begin()->first; };
  EXPECT_TRUE(core::oppositeSides(side_of(core::kRegionUpperLip), side_of(core::kRegionLowerLip)));
  EXPECT_TRUE(core::oppositeSides(side_of(core::kRegionUpperLid), side_of(core::kRegionLowerLid)));
  int lip_vertices = 0, sided_lip_vertices = 0;
  for (Eigen::Index v = 0; v < truth.size(); ++v) {
    if (truth(v) != core::kRegionUpperLip && truth(v) != core::kRegionLowerLip) continue;
    ++lip_vertices;
    sided_lip_vertices += source.surface.vertex_sides[static_cast<std::size_t>(v)] >= 0 ? 1 : 0;
  }
  EXPECT_GT(sided_lip_vertices, lip_vertices / 2);
}

// A rim far longer than a face's (a scan's ragged border, a hostile file)
// is split in linear time: a disc with a 20000-vertex rim and one landmark on
// it is an opening as wide as the disc.
TEST(OpeningSides, ALongRimIsSplitAcrossItsWidth) {
  constexpr int n = 20000;
  core::Mesh disc;
  disc.positions.resize(n + 1, 3);
  disc.triangles.resize(n, 3);
  disc.positions.row(n).setZero();
  for (int i = 0; i < n; ++i) {
    const double a = 2.0 * std::numbers::pi * i / n;
    disc.positions.row(i) << std::cos(a), 0.5 * std::sin(a), 0.0;  // an ellipse 2 wide
    disc.triangles.row(i) << n, i, (i + 1) % n;
  }
  const std::vector<core::Rim> rims = core::meshRims(disc, {});
  ASSERT_EQ(rims.size(), 1u);
  Eigen::MatrixX3d landmark(1, 3);
  landmark << 0.0, 0.5, 0.0;
  const std::vector<core::Opening> openings = core::findOpenings(disc, rims, landmark);
  ASSERT_EQ(openings.size(), 1u);
  EXPECT_NEAR(openings[0].width, 2.0, 1e-6);
  const std::vector<int> sides =
      core::openingSides(disc, core::vertexAdjacency(disc.triangles, disc.vertexCount()), {}, rims, openings);
  EXPECT_EQ(sides[static_cast<std::size_t>(n / 4)] / 2, 0);  // the top of the ellipse: a side of opening 0
  EXPECT_TRUE(core::oppositeSides(sides[static_cast<std::size_t>(n / 4)], sides[static_cast<std::size_t>(3 * n / 4)]));
}

TEST(OpeningSides, LaplacianCutAcrossSidesKeepsRowSumsZero) {
  // A strip of 2 x 3 vertices: the top row side 0, the bottom row side 1 of
  // one opening, the middle column between them.
  Eigen::MatrixX3i triangles(4, 3);
  triangles << 0, 3, 1, 1, 3, 4, 1, 4, 2, 2, 4, 5;
  const Eigen::SparseMatrix<double> laplacian = core::uniformLaplacian(triangles, 6, {});
  const std::vector<int> sides = {0, core::kBetweenSides, 0, 1, core::kBetweenSides, 1};
  Eigen::SparseMatrix<double> cut = laplacian;
  core::cutAcrossSides(cut, sides);
  EXPECT_EQ(cut.coeff(0, 3), 0.0);   // 0 - 3 crosses
  EXPECT_EQ(cut.coeff(2, 4), -1.0);  // 2 - 4 reaches the corner band: kept
  EXPECT_EQ(cut.coeff(2, 5), 0.0);
  // Nothing across: unchanged.
  Eigen::SparseMatrix<double> open = laplacian;
  core::cutAcrossSides(open, {0, 0, 0, core::kBetweenSides, core::kBetweenSides, core::kBetweenSides});
  EXPECT_TRUE(open.isApprox(laplacian));
  const Eigen::VectorXd sums = cut * Eigen::VectorXd::Ones(6);
  EXPECT_LT(sums.cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_EQ(cut.coeff(0, 0), laplacian.coeff(0, 0) - 1.0);
}

// Lips that touch, a target with 10 landmarks: no lower-lip vertex takes an
// upper-lip delta or weight, nor the other way, with and without _REGION
// labels (which, on both meshes, take the sides' place). Without the sides
// and the repair (the papers' matching) the same case does cross.
TEST(OpeningSides, TouchingLipsNeverTradeDeltasOrWeights) {
  const core::SyntheticRig& target = rigport_test::saggingMouthTarget();
  const Eigen::VectorXi& truth = target.rig.attributes.labels.at("REGION");
  const core::LandmarkSet landmarks = rigport_test::tenLandmarks(target);
  // The target's own rig (the generator's jawOpen and jaw weights) is what
  // each of its lip vertices should do: one that moves, or is weighted to the
  // jaw, as the other lip does is counted. Over the middle 40% of the mouth:
  // nearer the corners the generator paints by height, and the rim's ends,
  // which turn up, carry a few lower-lip vertices it calls upper.
  const std::size_t jaw_shape = 0;  // jawOpen
  const int jaw_joint = 3;          // root, neck, head, jaw
  const Eigen::MatrixX3d& own_jaw = target.rig.morph_targets[jaw_shape].position_deltas;
  const double largest = own_jaw.rowwise().norm().maxCoeff();
  const auto corner = [&](const char* name) {
    const core::Landmark& l = target.landmarks.landmarks[static_cast<std::size_t>(target.landmarks.indexOf(name))];
    return core::interpolateOnFace(target.rig.mesh.positions, target.rig.mesh.triangles, l.face, l.barycentric);
  };
  const Eigen::RowVector3d right = corner("mouth_outer_0"), left = corner("mouth_outer_6");
  const double middle = 0.5 * (left(0) + right(0)), reach = 0.2 * std::abs(left(0) - right(0));
  struct Crossings {
    int deltas = 0, weights = 0, lip_vertices = 0;
  };
  auto crossings = [&](const core::Rig& out) {
    Crossings c;
    const Eigen::MatrixX3d& jaw = out.morph_targets[jaw_shape].position_deltas;
    for (Eigen::Index v = 0; v < truth.size(); ++v) {
      if (truth(v) != core::kRegionUpperLip && truth(v) != core::kRegionLowerLip) continue;
      if (std::abs(target.rig.mesh.positions(v, 0) - middle) > reach) continue;
      ++c.lip_vertices;
      c.deltas += (jaw.row(v) - own_jaw.row(v)).norm() > 0.5 * largest ? 1 : 0;
      c.weights += std::abs(out.weights.coeff(v, jaw_joint) - target.rig.weights.coeff(v, jaw_joint)) > 0.5 ? 1 : 0;
    }
    return c;
  };
  for (const bool labelled : {false, true}) {
    core::Mesh mesh = target.rig.mesh;
    if (!labelled) mesh.regions.resize(0);
    auto result = core::transferRig(rigport_test::preparedTouchingLipsSource(), mesh, landmarks, labelled ? "labelled" : "scan");
    ASSERT_TRUE(result) << result.error().message;
    EXPECT_EQ(result->report.warp.region_matching, labelled);
    EXPECT_EQ(result->report.warp.sided_openings, 3);
    const Crossings c = crossings(result->rig);
    EXPECT_GT(c.lip_vertices, 50);
    EXPECT_EQ(c.deltas, 0) << (labelled ? "labelled" : "unlabelled");
    EXPECT_EQ(c.weights, 0) << (labelled ? "labelled" : "unlabelled");
    // Unlabelled, the check finds nothing unsure. (The generator paints by
    // height, so near a corner it calls upper a few vertices of the lower
    // lip's rim; matched by those labels they do stand out.)
    if (!labelled) {
      EXPECT_TRUE(result->report.quality.clean()) << result->report.quality.summary();
    }
  }

  // The case is a real one: without the sides (and the repair) 6 vertices
  // of the middle of the lips crossed (measured); matched as the papers do
  // (no sides, no repair, the normal and gap tests off) they do cross.
  core::Mesh scan = target.rig.mesh;
  scan.regions.resize(0);
  core::TransferOptions plain;
  plain.warp = core::plainWarpOptions();
  plain.warp.locate.max_normal_angle_deg = 180.0;
  plain.warp.locate.max_relative_distance = 0.0;
  plain.warp.projection.max_normal_angle_deg = 180.0;
  plain.repair_unsure = false;
  auto crossed = core::transferRig(rigport_test::preparedTouchingLipsSource(), scan, landmarks, "scan", plain);
  ASSERT_TRUE(crossed) << crossed.error().message;
  const Crossings c = crossings(crossed->rig);
  EXPECT_GT(c.deltas, 0);
}

}  // namespace
