// prepareScan and checkScan (core/fit/scan.h) on small made-up surfaces:
// small pieces are detached, borders and holes flagged, spikes flagged and
// left out of the index, a cloud's missing normals estimated, and the inputs
// no fit can use refused with a message naming the cause.
#include "core/fit/scan.h"

#include <cmath>
#include <limits>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "tests/test_support.h"

namespace {

// A (cells x cells) grid of unit squares in the plane z = 0, two triangles
// per square, vertex (i, j) at row i * (cells + 1) + j, facing +Z. Squares
// with skip(i, j) true are left out (a hole).
template <class Skip>
core::Mesh gridPlane(int cells, Skip skip) {
  core::Mesh out;
  const int side = cells + 1;
  out.positions.resize(side * side, 3);
  for (int i = 0; i < side; ++i) {
    for (int j = 0; j < side; ++j) out.positions.row(i * side + j) << j, i, 0.0;
  }
  std::vector<Eigen::RowVector3i> triangles;
  for (int i = 0; i < cells; ++i) {
    for (int j = 0; j < cells; ++j) {
      if (skip(i, j)) continue;
      const int a = i * side + j, b = a + 1, c = a + side, d = c + 1;
      triangles.emplace_back(a, b, d);
      triangles.emplace_back(a, d, c);
    }
  }
  out.triangles.resize(static_cast<Eigen::Index>(triangles.size()), 3);
  for (std::size_t f = 0; f < triangles.size(); ++f) out.triangles.row(static_cast<Eigen::Index>(f)) = triangles[f];
  return out;
}

core::Mesh gridPlane(int cells) {
  return gridPlane(cells, [](int, int) { return false; });
}

// A spherical cap of `radius` about `centre`, up to `angle_deg` from its
// pole (+Z), as a (rings x segments) grid closed at the pole.
core::Mesh sphereCap(const Eigen::Vector3d& centre, double radius, double angle_deg, int rings, int segments) {
  core::Mesh out;
  out.positions.resize(1 + rings * segments, 3);
  out.positions.row(0) = (centre + radius * Eigen::Vector3d::UnitZ()).transpose();
  for (int r = 1; r <= rings; ++r) {
    const double polar = angle_deg * std::numbers::pi / 180.0 * r / rings;
    for (int s = 0; s < segments; ++s) {
      const double a = 2.0 * std::numbers::pi * s / segments;
      out.positions.row(1 + (r - 1) * segments + s) =
          (centre + radius * Eigen::Vector3d(std::sin(polar) * std::cos(a), std::sin(polar) * std::sin(a), std::cos(polar)))
              .transpose();
    }
  }
  std::vector<Eigen::RowVector3i> triangles;
  for (int s = 0; s < segments; ++s) triangles.emplace_back(0, 1 + s, 1 + (s + 1) % segments);
  for (int r = 1; r < rings; ++r) {
    for (int s = 0; s < segments; ++s) {
      const int a = 1 + (r - 1) * segments + s, b = 1 + (r - 1) * segments + (s + 1) % segments;
      const int c = a + segments, d = b + segments;
      triangles.emplace_back(a, c, d);
      triangles.emplace_back(a, d, b);
    }
  }
  out.triangles.resize(static_cast<Eigen::Index>(triangles.size()), 3);
  for (std::size_t f = 0; f < triangles.size(); ++f) out.triangles.row(static_cast<Eigen::Index>(f)) = triangles[f];
  return out;
}

// Both meshes in one (b's indices after a's).
core::Mesh joined(const core::Mesh& a, const core::Mesh& b) {
  core::Mesh out;
  out.positions.resize(a.vertexCount() + b.vertexCount(), 3);
  out.positions << a.positions, b.positions;
  out.triangles.resize(a.triangleCount() + b.triangleCount(), 3);
  out.triangles << a.triangles, (b.triangles.array() + static_cast<int>(a.vertexCount())).matrix();
  return out;
}

int countFlag(const core::ScanSurface& scan, std::uint8_t flag) {
  int n = 0;
  for (const std::uint8_t f : scan.flags) n += (f & flag) ? 1 : 0;
  return n;
}

TEST(PrepareScan, SmallPieceBesideTheSkinIsDetachedAndNotMatched) {
  const core::Mesh plane = gridPlane(20);
  // A cap of radius 1 over 60 degrees: pi square units, 0.8% of the plane's 400.
  const core::Mesh cap = sphereCap(Eigen::Vector3d(10.0, 10.0, 2.0), 1.0, 60.0, 4, 12);
  auto scan = core::prepareScan(joined(plane, cap), "plane and cap");
  ASSERT_TRUE(scan) << scan.error().message;
  EXPECT_EQ(scan->report.pieces, 2);
  EXPECT_EQ(scan->report.detached_points, cap.vertexCount());
  for (Eigen::Index v = 0; v < scan->mesh.vertexCount(); ++v) {
    const bool on_cap = v >= plane.vertexCount();
    EXPECT_EQ((scan->flags[static_cast<std::size_t>(v)] & core::kScanDetached) != 0, on_cap) << "vertex " << v;
  }
  // Right above the cap, the nearest usable surface is the plane below it.
  const Eigen::MatrixX3d above = Eigen::RowVector3d(10.0, 10.0, 3.2);
  const core::ScanMatch m = scan->nearest(above).front();
  ASSERT_TRUE(m.found);
  EXPECT_NEAR(m.point.z(), 0.0, 1e-12);
  EXPECT_NEAR(m.distance, 3.2, 1e-12);
  EXPECT_EQ(m.flags & core::kScanDetached, 0);
}

TEST(PrepareScan, LargeSecondPieceIsNotDetached) {
  const core::Mesh plane = gridPlane(20);
  // A hemisphere of radius 5: 157 square units, 39% of the plane's area.
  const core::Mesh dome = sphereCap(Eigen::Vector3d(10.0, 10.0, 3.0), 5.0, 90.0, 8, 24);
  auto scan = core::prepareScan(joined(plane, dome), "plane and dome");
  ASSERT_TRUE(scan) << scan.error().message;
  EXPECT_EQ(scan->report.pieces, 2);
  EXPECT_EQ(scan->report.detached_points, 0);
  EXPECT_EQ(countFlag(*scan, core::kScanDetached), 0);
}

// A 20 x 20 plane with the 4 x 4 squares of its middle left out.
bool inHole(int i, int j) { return i >= 8 && i < 12 && j >= 8 && j < 12; }

TEST(PrepareScan, PlaneWithAHoleHasItsCropAndHoleFlaggedAsBorders) {
  auto scan = core::prepareScan(gridPlane(20, inHole), "plane with a hole");
  ASSERT_TRUE(scan) << scan.error().message;
  EXPECT_EQ(scan->report.holes, 1);
  EXPECT_EQ(scan->report.pieces, 1);
  int on_border = 0;
  for (int i = 0; i <= 20; ++i) {
    for (int j = 0; j <= 20; ++j) {
      const bool crop = i == 0 || j == 0 || i == 20 || j == 20;
      const int from_centre = std::max(std::abs(i - 10), std::abs(j - 10));
      const bool hole_rim = from_centre == 2;
      const int rings_from_crop = std::min(std::min(i, j), std::min(20 - i, 20 - j));
      const bool flagged = (scan->flags[static_cast<std::size_t>(i * 21 + j)] & core::kScanBorder) != 0;
      if (crop || hole_rim) {
        EXPECT_TRUE(flagged) << "border vertex (" << i << ", " << j << ") not flagged";
        ++on_border;
      } else if (from_centre >= 4 && rings_from_crop >= 2) {
        EXPECT_FALSE(flagged) << "inner vertex (" << i << ", " << j << ") flagged";
      }
    }
  }
  EXPECT_GE(scan->report.border_points, on_border);
  // Over the hole the nearest surface point is on its rim: beyond the data.
  // Over the inner plane it is not.
  const core::ScanMatch over_hole = scan->nearest(Eigen::RowVector3d(10.0, 10.0, 0.5)).front();
  const core::ScanMatch over_skin = scan->nearest(Eigen::RowVector3d(4.3, 15.6, 0.5)).front();
  ASSERT_TRUE(over_hole.found);
  ASSERT_TRUE(over_skin.found);
  EXPECT_NE(over_hole.flags & core::kScanBorder, 0);
  EXPECT_EQ(over_skin.flags & core::kScanBorder, 0);
  EXPECT_NEAR(over_skin.distance, 0.5, 1e-12);
}

TEST(PrepareScan, CloudOfAPlaneWithAHoleHasItsHoleFlagged) {
  const core::Mesh mesh = gridPlane(30, [](int, int) { return false; });
  core::Mesh cloud;
  std::vector<Eigen::RowVector3d> points;
  for (Eigen::Index v = 0; v < mesh.vertexCount(); ++v) {
    const Eigen::RowVector3d p = mesh.positions.row(v);
    if ((p - Eigen::RowVector3d(15.0, 15.0, 0.0)).norm() >= 4.0) points.push_back(p);
  }
  cloud.positions.resize(static_cast<Eigen::Index>(points.size()), 3);
  for (std::size_t i = 0; i < points.size(); ++i) cloud.positions.row(static_cast<Eigen::Index>(i)) = points[i];
  cloud.normals = Eigen::MatrixX3d::Zero(cloud.positions.rows(), 3);
  cloud.normals.col(2).setOnes();
  auto scan = core::prepareScan(cloud, "cloud with a hole");
  ASSERT_TRUE(scan) << scan.error().message;
  EXPECT_TRUE(scan->report.point_cloud);
  for (Eigen::Index v = 0; v < cloud.vertexCount(); ++v) {
    const Eigen::RowVector3d p = cloud.positions.row(v);
    const double from_hole = (p - Eigen::RowVector3d(15.0, 15.0, 0.0)).norm();
    const double from_crop = std::min(std::min(p.x(), p.y()), std::min(30.0 - p.x(), 30.0 - p.y()));
    const bool flagged = (scan->flags[static_cast<std::size_t>(v)] & core::kScanBorder) != 0;
    if (from_hole < 4.5 || from_crop == 0.0) {
      EXPECT_TRUE(flagged) << "border point (" << p << ") not flagged";
    } else if (from_hole > 7.0 && from_crop >= 3.0) {
      EXPECT_FALSE(flagged) << "inner point (" << p << ") flagged";
    }
  }
}

// A plane of unit squares with small noise (2% of an edge) and, at
// `spike_height` edges above it, one vertex.
core::Mesh noisyPlane(double spike_height, int spike_vertex) {
  core::Mesh mesh = gridPlane(30);
  std::mt19937 rng(17);
  std::normal_distribution<double> noise(0.0, 0.02);
  for (Eigen::Index v = 0; v < mesh.vertexCount(); ++v) mesh.positions(v, 2) = noise(rng);
  mesh.positions(spike_vertex, 2) += spike_height;
  return mesh;
}

TEST(PrepareScan, SpikeOnAMeshIsFlaggedAndLeftOutOfTheIndex) {
  const int side = 31, spike = 15 * side + 15;
  auto plain = core::prepareScan(noisyPlane(0.0, spike), "noisy plane");
  ASSERT_TRUE(plain) << plain.error().message;
  EXPECT_EQ(plain->report.spikes, 0);

  auto scan = core::prepareScan(noisyPlane(3.0, spike), "noisy plane with a spike");
  ASSERT_TRUE(scan) << scan.error().message;
  EXPECT_NE(scan->flags[static_cast<std::size_t>(spike)] & core::kScanSpike, 0);
  EXPECT_GE(scan->report.spikes, 1);
  for (int i = 0; i < side; ++i) {
    for (int j = 0; j < side; ++j) {
      if (std::max(std::abs(i - 15), std::abs(j - 15)) <= 1) continue;  // the spike and its ring
      EXPECT_EQ(scan->flags[static_cast<std::size_t>(i * side + j)] & core::kScanSpike, 0)
          << "vertex (" << i << ", " << j << ") flagged";
    }
  }
  // Right above the tip the nearest usable surface is not on the spike.
  const core::ScanMatch m = scan->nearest(Eigen::RowVector3d(15.0, 15.0, 3.5)).front();
  ASSERT_TRUE(m.found);
  EXPECT_LT(m.point.z(), 0.5);
  EXPECT_EQ(m.flags & core::kScanSpike, 0);
}

// 2,000 points on a unit sphere (a Fibonacci spiral: even, no two alike).
core::Mesh sphereCloud(int n) {
  core::Mesh cloud;
  cloud.positions.resize(n, 3);
  const double golden = std::numbers::pi * (3.0 - std::sqrt(5.0));
  for (int i = 0; i < n; ++i) {
    const double y = 1.0 - 2.0 * (i + 0.5) / n, r = std::sqrt(1.0 - y * y);
    cloud.positions.row(i) << r * std::cos(golden * i), y, r * std::sin(golden * i);
  }
  return cloud;
}

TEST(PrepareScan, CloudWithoutNormalsGetsThemEstimated) {
  const core::Mesh cloud = sphereCloud(2000);
  auto scan = core::prepareScan(cloud, "sphere cloud");
  ASSERT_TRUE(scan) << scan.error().message;
  EXPECT_TRUE(scan->report.point_cloud);
  EXPECT_TRUE(scan->report.normals_computed);
  ASSERT_EQ(scan->normals.rows(), cloud.vertexCount());
  double worst = 1.0;
  for (Eigen::Index v = 0; v < cloud.vertexCount(); ++v) {
    EXPECT_NEAR(scan->normals.row(v).norm(), 1.0, 1e-9) << "point " << v;
    worst = std::min(worst, std::abs(scan->normals.row(v).dot(cloud.positions.row(v))));
  }
  EXPECT_GT(worst, 0.99);  // along the radius, either way (oriented after alignment)
  EXPECT_EQ(scan->report.border_points, 0);  // a closed surface

  core::Mesh with_normals = cloud;
  with_normals.normals = cloud.positions;
  auto given = core::prepareScan(with_normals, "sphere cloud with normals");
  ASSERT_TRUE(given) << given.error().message;
  EXPECT_FALSE(given->report.normals_computed);
  EXPECT_TRUE(rigport_test::matricesNear(given->normals, with_normals.normals, 0.0));
}

// The border rule of clouds (cloudBorderPoints: an angular gap over 90
// degrees among the 16 nearest neighbours) read on a cloud drawn uniformly
// at random, as photogrammetry leaves it: an inner point's 16 neighbour
// directions leave such a gap by chance with probability ~16 (3/4)^15 = 0.21,
// and 22% of a 50k-point random cloud on ICT were flagged, which leaves a
// third of the face uncovered and fails the fit's gate (verdict "fail").
// Disabled until the rule is fixed; it states what should hold.
TEST(PrepareScan, RandomCloudOfAPlaneHasNoBordersInside) {
  std::mt19937 rng(23);
  std::uniform_real_distribution<double> at(0.0, 30.0);
  core::Mesh cloud;
  cloud.positions.resize(9000, 3);
  for (Eigen::Index i = 0; i < cloud.positions.rows(); ++i) cloud.positions.row(i) << at(rng), at(rng), 0.0;
  cloud.normals = Eigen::MatrixX3d::Zero(cloud.positions.rows(), 3);
  cloud.normals.col(2).setOnes();
  auto scan = core::prepareScan(cloud, "random plane cloud");
  ASSERT_TRUE(scan) << scan.error().message;
  int inner = 0, inner_flagged = 0;
  for (Eigen::Index v = 0; v < cloud.vertexCount(); ++v) {
    const Eigen::RowVector3d p = cloud.positions.row(v);
    if (std::min(std::min(p.x(), p.y()), std::min(30.0 - p.x(), 30.0 - p.y())) < 2.0) continue;
    ++inner;
    inner_flagged += (scan->flags[static_cast<std::size_t>(v)] & core::kScanBorder) ? 1 : 0;
  }
  std::printf("random cloud: %d of %d inner points flagged as border (%.1f%%)\n", inner_flagged, inner,
              100.0 * inner_flagged / inner);
  EXPECT_LE(inner_flagged, inner / 100);
}

// A roof: the grid folded along x = 10, both halves rising 45 degrees to the
// ridge. A query beside the ridge on the left slope carrying the right
// slope's normal: the closest point is on the left slope, the point nearest
// in position and normal across the ridge; without a normal weight the two
// agree.
TEST(PrepareScan, NearestAlikeDrawsAQueryToThePointOfItsNormal) {
  core::Mesh roof = gridPlane(20);
  for (Eigen::Index v = 0; v < roof.positions.rows(); ++v) roof.positions(v, 2) = 10.0 - std::abs(roof.positions(v, 0) - 10.0);
  auto scan = core::prepareScan(roof, "roof.ply");
  ASSERT_TRUE(scan) << scan.error().message;
  Eigen::MatrixX3d query(1, 3), normal(1, 3);
  query << 9.0, 10.0, 9.3;                            // 0.3 above the left slope (x = 9, z = 9), 1 left of the ridge
  normal << std::sqrt(0.5), 0.0, std::sqrt(0.5);      // the right slope's normal (it falls towards +x)
  const core::ScanMatch closest = scan->nearest(query)[0];
  ASSERT_TRUE(closest.found);
  EXPECT_LT(closest.point.x(), 10.0);
  const core::ScanMatch alike = scan->nearestAlike(query, normal, 5.0)[0];
  ASSERT_TRUE(alike.found);
  EXPECT_GT(alike.point.x(), 10.0) << alike.point.transpose();
  EXPECT_GT(alike.normal.dot(normal.row(0).transpose()), 0.9) << alike.normal.transpose();
  const core::ScanMatch plain = scan->nearestAlike(query, normal, 0.0)[0];
  ASSERT_TRUE(plain.found);
  EXPECT_LT(plain.point.x(), 10.0);
  EXPECT_NEAR(plain.distance, (plain.point - query.row(0).transpose()).norm(), 1e-12);
}

TEST(CheckScan, RefusesTooFewPointsNaNAndOnePosition) {
  core::Mesh ten;
  ten.positions = rigport_test::randomPoints(10, 3);
  const auto few = core::checkScan(ten, "ten.ply");
  ASSERT_FALSE(few);
  EXPECT_EQ(few.error().code, core::ErrorCode::kInvalidMesh);
  EXPECT_NE(few.error().message.find("ten.ply"), std::string::npos) << few.error().message;
  EXPECT_NE(few.error().message.find("10 points"), std::string::npos) << few.error().message;

  core::Mesh nan;
  nan.positions = rigport_test::randomPoints(500, 4);
  nan.positions(137, 1) = std::numeric_limits<double>::quiet_NaN();
  const auto bad = core::checkScan(nan, "nan.ply");
  ASSERT_FALSE(bad);
  EXPECT_EQ(bad.error().code, core::ErrorCode::kInvalidMesh);
  EXPECT_NE(bad.error().message.find("vertex 137"), std::string::npos) << bad.error().message;

  core::Mesh one;
  one.positions = Eigen::MatrixX3d::Constant(500, 3, 2.5);
  const auto same = core::checkScan(one, "one.ply");
  ASSERT_FALSE(same);
  EXPECT_EQ(same.error().code, core::ErrorCode::kInvalidMesh);
  EXPECT_NE(same.error().message.find("one position"), std::string::npos) << same.error().message;

  // prepareScan refuses alike; 100 distinct points are enough.
  EXPECT_FALSE(core::prepareScan(nan, "nan.ply"));
  core::Mesh hundred;
  hundred.positions = rigport_test::randomPoints(100, 5);
  EXPECT_TRUE(core::checkScan(hundred, "hundred.ply"));
}

}  // namespace
