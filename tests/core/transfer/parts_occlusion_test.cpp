// The parts' check (core/transfer/parts_occlusion.h) on a face made simple:
// a sheet facing +Z with a square hole (an eye), its rim bent back (a mask's
// edge), and a wall far behind (the back of the head). A ball behind the
// sheet or seen through the hole is hidden; a ball in front of the sheet, or
// one too big for the hole, pokes through.
#include "core/transfer/parts_occlusion.h"

#include <gtest/gtest.h>

#include "tests/test_support.h"

namespace {

// An 8 x 8 grid of quads over [-2, 2]^2 at z = 0, its outer ring of vertices
// at z = -1, the 2 x 2 quads of [-0.5, 0.5]^2 left out (the hole); plus a
// 1 x 1 quad wall at z = -3 facing -Z.
core::Mesh sheetWithHole() {
  constexpr int n = 8;
  core::Mesh m;
  m.positions.resize((n + 1) * (n + 1) + 4, 3);
  for (int j = 0; j <= n; ++j) {
    for (int i = 0; i <= n; ++i) {
      const bool rim = i == 0 || j == 0 || i == n || j == n;
      m.positions.row(j * (n + 1) + i) << -2.0 + 0.5 * i, -2.0 + 0.5 * j, rim ? -1.0 : 0.0;
    }
  }
  const int w = (n + 1) * (n + 1);
  m.positions.row(w + 0) << -3.0, -3.0, -3.0;
  m.positions.row(w + 1) << 3.0, -3.0, -3.0;
  m.positions.row(w + 2) << 3.0, 3.0, -3.0;
  m.positions.row(w + 3) << -3.0, 3.0, -3.0;
  std::vector<Eigen::Vector3i> tris;
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      if ((i == 3 || i == 4) && (j == 3 || j == 4)) continue;  // the hole
      const int v = j * (n + 1) + i;
      tris.emplace_back(v, v + 1, v + n + 2);
      tris.emplace_back(v, v + n + 2, v + n + 1);
    }
  }
  tris.emplace_back(w + 0, w + 2, w + 1);  // facing -Z
  tris.emplace_back(w + 0, w + 3, w + 2);
  m.triangles.resize(static_cast<Eigen::Index>(tris.size()), 3);
  for (std::size_t t = 0; t < tris.size(); ++t) m.triangles.row(static_cast<Eigen::Index>(t)) = tris[t].transpose();
  return m;
}

Eigen::MatrixX3d ball(const Eigen::Vector3d& centre, double radius) {
  const auto sphere = rigport_test::unitIcosphere(3);
  return (radius * sphere.positions).rowwise() + centre.transpose();
}

TEST(PartsOcclusion, ForwardIsTheLandmarksPlaneNormalOnTheSideOfTheSkin) {
  Eigen::MatrixX3d landmarks(5, 3);
  landmarks << -1, 0, 2, 1, 0, 2, 0, 1, 2.1, 0, -1, 1.9, 0.5, 0.5, 2;
  EXPECT_GT(core::faceForward(landmarks, Eigen::Vector3d(0.2, 0, 1)).z(), 0.99);
  EXPECT_LT(core::faceForward(landmarks, Eigen::Vector3d(0, 0.1, -1)).z(), -0.99);
  EXPECT_EQ(core::faceForward(landmarks.topRows(2), Eigen::Vector3d::UnitZ()).norm(), 0.0);  // no plane
}

TEST(PartsOcclusion, FindsTheSheetsOpenings) {
  const core::SkinOcclusion skin(sheetWithHole(), Eigen::Vector3d::UnitZ());
  EXPECT_EQ(skin.openings(), 3);  // the hole, the sheet's rim, the wall's edge
  EXPECT_NEAR(skin.tolerance(), 0.001 * std::sqrt(6.0 * 6.0 * 2 + 3.0 * 3.0), 1e-12);
}

TEST(PartsOcclusion, ABallBehindTheSheetOrSeenThroughTheHoleIsHidden) {
  const core::Mesh face = sheetWithHole();
  const core::SkinOcclusion skin(face, Eigen::Vector3d::UnitZ());
  // Behind the skin.
  EXPECT_EQ(skin.countInFront(skin.standOut(face.positions, ball({1.0, 0.0, -0.5}, 0.3))), 0);
  // Behind the hole, the wall further back: the hole's cap is its front-most crossing.
  EXPECT_EQ(skin.countInFront(skin.standOut(face.positions, ball({0.0, 0.0, -1.0}, 0.3))), 0);
  // Bulging through the hole, as a cornea past the lids: seen through the opening.
  const Eigen::VectorXd bulging = skin.standOut(face.positions, ball({0.0, 0.0, 0.1}, 0.3));
  EXPECT_EQ(skin.countInFront(bulging), 0);
  EXPECT_EQ(bulging.cwiseAbs().maxCoeff(), 0.0);
}

TEST(PartsOcclusion, ABallInFrontOfTheSheetOrTooBigForTheHolePokesThrough) {
  const core::Mesh face = sheetWithHole();
  const core::SkinOcclusion skin(face, Eigen::Vector3d::UnitZ());
  // In front of the skin: every vertex, by its height above the sheet.
  const Eigen::MatrixX3d front = ball({1.0, 0.0, 0.5}, 0.3);
  const Eigen::VectorXd stand_out = skin.standOut(face.positions, front);
  EXPECT_EQ(skin.countInFront(stand_out), front.rows());
  EXPECT_LT((stand_out - front.col(2)).cwiseAbs().maxCoeff(), 1e-12);
  // Too big for the hole: what is in front of the sheet beside the hole.
  const Eigen::MatrixX3d big = ball({0.0, 0.0, 0.0}, 0.7);
  int expected = 0;
  for (Eigen::Index v = 0; v < big.rows(); ++v) {
    const bool over_skin = std::abs(big(v, 0)) > 0.5 + 1e-9 || std::abs(big(v, 1)) > 0.5 + 1e-9;
    expected += over_skin && big(v, 2) > skin.tolerance();
  }
  EXPECT_GT(expected, 0);
  EXPECT_EQ(skin.countInFront(skin.standOut(face.positions, big)), expected);
  // The same ball moved back behind the sheet: hidden.
  EXPECT_EQ(skin.countInFront(skin.standOut(face.positions, ball({0.0, 0.0, -0.75}, 0.7))), 0);
}

TEST(PartsOcclusion, APoseMovesTheSkinNotTheOpenings) {
  core::Mesh face = sheetWithHole();
  const core::SkinOcclusion skin(face, Eigen::Vector3d::UnitZ());
  // The sheet pulled back 1 unit (a lid opening): the ball in front of it now stands 1 further out.
  Eigen::MatrixX3d posed = face.positions;
  posed.col(2).array() -= 1.0;
  const Eigen::MatrixX3d front = ball({1.0, 0.0, 0.5}, 0.3);
  const Eigen::VectorXd stand_out = skin.standOut(posed, front);
  EXPECT_LT((stand_out - (front.col(2).array() + 1.0).matrix()).cwiseAbs().maxCoeff(), 1e-12);
  // Per part counts in one call.
  const Eigen::MatrixX3d hidden = ball({1.0, 0.0, -2.5}, 0.3);
  const std::vector<int> counts = core::partsInFront(skin, face.positions, {&front, &hidden});
  ASSERT_EQ(counts.size(), 2u);
  EXPECT_EQ(counts[0], front.rows());
  EXPECT_EQ(counts[1], 0);
}

}  // namespace
