#include "core/correspond/rims.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "core/synthetic/synthetic_head.h"
#include "core/correspond/warp_job.h"

namespace {

// A flat n x n grid of unit cells in the xy plane (z = 0), cells listed by
// row; cells for which `hole(i, j)` is true are left out.
template <typename Hole>
core::Mesh grid(int n, Hole hole) {
  core::Mesh mesh;
  mesh.positions.resize((n + 1) * (n + 1), 3);
  for (int j = 0; j <= n; ++j) {
    for (int i = 0; i <= n; ++i) mesh.positions.row(j * (n + 1) + i) << i, j, 0.0;
  }
  std::vector<Eigen::RowVector3i> faces;
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      if (hole(i, j)) continue;
      const int a = j * (n + 1) + i, b = a + 1, c = a + n + 2, d = a + n + 1;
      faces.emplace_back(a, b, c);
      faces.emplace_back(a, c, d);
    }
  }
  mesh.triangles.resize(static_cast<Eigen::Index>(faces.size()), 3);
  for (std::size_t f = 0; f < faces.size(); ++f) mesh.triangles.row(static_cast<Eigen::Index>(f)) = faces[f];
  mesh.normals = core::computeVertexNormals(mesh.positions, mesh.triangles);
  return mesh;
}

std::vector<core::Rim> rimsOf(const core::Mesh& mesh) {
  return core::meshRims(mesh, core::coincidentVertexRepresentatives(mesh.positions));
}

core::Mesh holedGrid() {
  return grid(6, [](int i, int j) { return i >= 2 && i <= 3 && j >= 2 && j <= 3; });
}

TEST(Rims, LoopsOfAGridWithAHoleWithTheirFaces) {
  const core::Mesh mesh = holedGrid();
  const std::vector<core::Rim> rims = rimsOf(mesh);
  ASSERT_EQ(rims.size(), 2u);
  EXPECT_DOUBLE_EQ(rims[0].length, 24.0);  // outer square, longest first
  EXPECT_DOUBLE_EQ(rims[1].length, 8.0);   // the hole
  for (const core::Rim& rim : rims) {
    ASSERT_EQ(rim.faces.size(), rim.vertices.size());
    for (std::size_t i = 0; i < rim.vertices.size(); ++i) {
      const Eigen::RowVector3i t = mesh.triangles.row(rim.faces[i]);
      EXPECT_EQ(t(rim.corners[i][0]), rim.vertices[i]) << "edge " << i;
      EXPECT_EQ(t(rim.corners[i][1]), rim.vertices[(i + 1) % rim.vertices.size()]) << "edge " << i;
    }
  }
}

TEST(Rims, ASplitSeamIsNotARim) {
  // The same grid with its faces right of x = 3 moved onto copies of the
  // seam's vertices (a UV seam): the seam is no boundary.
  core::Mesh mesh = grid(6, [](int, int) { return false; });
  const Eigen::Index nv = mesh.positions.rows();
  Eigen::MatrixX3d positions(nv + 7, 3);
  positions.topRows(nv) = mesh.positions;
  for (int j = 0; j <= 6; ++j) positions.row(nv + j) = mesh.positions.row(j * 7 + 3);
  for (Eigen::Index f = 0; f < mesh.triangles.rows(); ++f) {
    bool right = true;
    for (int c = 0; c < 3; ++c) right = right && mesh.positions(mesh.triangles(f, c), 0) >= 3.0;
    if (!right) continue;
    for (int c = 0; c < 3; ++c) {
      const int v = mesh.triangles(f, c);
      if (mesh.positions(v, 0) == 3.0) mesh.triangles(f, c) = static_cast<int>(nv) + v / 7;
    }
  }
  mesh.positions = positions;
  ASSERT_EQ(rimsOf(grid(6, [](int, int) { return false; })).size(), 1u);
  const std::vector<core::Rim> rims = rimsOf(mesh);
  ASSERT_EQ(rims.size(), 1u);
  EXPECT_DOUBLE_EQ(rims[0].length, 24.0);
}

TEST(Rims, ClosestPointKeepsToTheSideRunningTheTangentsWay) {
  const core::Mesh mesh = holedGrid();
  const std::vector<core::Rim> rims = rimsOf(mesh);
  ASSERT_EQ(rims.size(), 2u);
  const core::Rim& hole = rims[1];
  // Inside the hole, nearer its top side (y = 4) than its bottom (y = 2).
  const Eigen::Vector3d p(3.0, 3.4, 0.0);
  const core::SurfacePoint any_way = core::closestPointOnRim(p, Eigen::Vector3d::Zero(), hole, mesh.positions);
  EXPECT_FALSE(any_way.found());  // a zero tangent runs no edge's way
  int top = -1, bottom = -1;
  for (std::size_t i = 0; i < hole.vertices.size(); ++i) {
    const Eigen::RowVector3d a = mesh.positions.row(hole.vertices[i]);
    const Eigen::RowVector3d b = mesh.positions.row(hole.vertices[(i + 1) % hole.vertices.size()]);
    if (a(1) == 4.0 && b(1) == 4.0) top = static_cast<int>(i);
    if (a(1) == 2.0 && b(1) == 2.0) bottom = static_cast<int>(i);
  }
  ASSERT_GE(top, 0);
  ASSERT_GE(bottom, 0);
  auto direction = [&](int i) {
    return Eigen::Vector3d(mesh.positions.row(hole.vertices[(static_cast<std::size_t>(i) + 1) % hole.vertices.size()]) -
                           mesh.positions.row(hole.vertices[static_cast<std::size_t>(i)]));
  };
  const core::SurfacePoint near_side = core::closestPointOnRim(p, direction(top), hole, mesh.positions);
  ASSERT_TRUE(near_side.found());
  EXPECT_NEAR(near_side.point.y(), 4.0, 1e-12);
  EXPECT_NEAR(near_side.point.x(), 3.0, 1e-12);
  EXPECT_NEAR(std::sqrt(near_side.sq_distance), 0.6, 1e-12);
  // The point on the face is the point found.
  const Eigen::RowVector3i t = mesh.triangles.row(near_side.face);
  Eigen::RowVector3d on_face = Eigen::RowVector3d::Zero();
  for (int c = 0; c < 3; ++c) on_face += near_side.barycentric(c) * mesh.positions.row(t(c));
  EXPECT_LT((on_face.transpose() - near_side.point).norm(), 1e-12);
  // Running the bottom side's way, the nearer top side is not a candidate.
  const core::SurfacePoint far_side = core::closestPointOnRim(p, direction(bottom), hole, mesh.positions);
  ASSERT_TRUE(far_side.found());
  EXPECT_NEAR(far_side.point.y(), 2.0, 1e-12);
}

TEST(Rims, MatchedToTheirOwnAndNotToStrangers) {
  const core::Mesh mesh = holedGrid();
  const std::vector<core::Rim> rims = rimsOf(mesh);
  // A slightly moved copy: each rim finds its own.
  Eigen::MatrixX3d moved = mesh.positions;
  moved.col(0).array() += 0.2;
  moved.col(2).array() += 0.1;
  EXPECT_EQ(core::matchRims(rims, moved, rims, mesh.positions), (std::vector<int>{0, 1}));
  // A target whose hole is three times as long: the hole has no match, the
  // outer rim still does.
  const core::Mesh big_hole = grid(6, [](int i, int j) { return i >= 1 && i <= 4 && j >= 1 && j <= 4; });
  const std::vector<core::Rim> other = rimsOf(big_hole);
  ASSERT_EQ(other.size(), 2u);
  core::RimMatchOptions options;
  EXPECT_EQ(core::matchRims(rims, mesh.positions, other, big_hole.positions, options), (std::vector<int>{0, -1}));
  // Only the longest max_rims of each side are candidates.
  core::RimMatchOptions longest;
  longest.max_rims = 1;
  EXPECT_EQ(core::matchRims(rims, moved, rims, mesh.positions, longest), (std::vector<int>{0, -1}));
  // Far away: nothing matches.
  Eigen::MatrixX3d far = mesh.positions;
  far.col(2).array() += 100.0;
  EXPECT_EQ(core::matchRims(rims, far, rims, mesh.positions), (std::vector<int>{-1, -1}));
}

// A rim warped off its target (shifted along the tube's axis, and sampled
// otherwise) pairs each point with the target point at its own place round
// the loop, evenly spaced.
TEST(Rims, PairedPointsKeepTheirPlaceRoundTheLoopWhereverTheWarpLeftIt) {
  auto circle = [](int n, double start, double z) {
    Eigen::MatrixX3d p(n, 3);
    for (int i = 0; i < n; ++i) {
      const double a = start + 2.0 * std::numbers::pi * i / n;
      p.row(i) << 2.0 * std::cos(a), 2.0 * std::sin(a), z;
    }
    return p;
  };
  auto loopOf = [](int n) {
    core::Rim rim;
    for (int i = 0; i < n; ++i) rim.vertices.push_back(i);
    return rim;
  };
  const Eigen::MatrixX3d source = circle(48, 0.0, 0.0), target = circle(30, 0.3, 0.0);
  const Eigen::MatrixX3d warped = circle(48, 0.0, 3.0);  // the warp left the rim 1.5 radii down the tube
  const core::RimPairs pairs = core::pairRimPoints(loopOf(48), source, warped, loopOf(30), target, 16);
  ASSERT_EQ(pairs.source.rows(), 16);
  ASSERT_EQ(pairs.target.rows(), 16);
  const double spacing = 2.0 * 2.0 * std::numbers::pi / 16;
  for (Eigen::Index k = 0; k < 16; ++k) {
    // Within a quarter spacing (the offset's step) plus the polygons' chords.
    EXPECT_LT((pairs.target.row(k) - pairs.source.row(k)).norm(), 0.3 * spacing) << "pair " << k;
    EXPECT_NEAR((pairs.source.row((k + 1) % 16) - pairs.source.row(k)).norm(), spacing, 0.05 * spacing) << "pair " << k;
  }
}

}  // namespace
