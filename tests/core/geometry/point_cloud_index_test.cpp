// Tests core/geometry/point_cloud_index.cpp: nearest and k-nearest queries
// against a brute-force scan (random clouds, and integer clouds where exact
// ties and duplicates abound), and the neighbourhood measures on clouds with a
// known answer: normals of a sphere and a plane, borders of a plane with a
// hole, spikes injected into a noisy plane.
#include "core/geometry/point_cloud_index.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <random>
#include <set>
#include <utility>
#include <vector>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "core/base/parallel.h"

namespace {

using core::PointCloudIndex;
using Eigen::Vector3d;
using Neighbour = PointCloudIndex::Neighbour;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

double sqDistance(const Vector3d& a, const Vector3d& b) {
  const double dx = a.x() - b.x(), dy = a.y() - b.y(), dz = a.z() - b.z();
  return dx * dx + dy * dy + dz * dz;
}

// Every finite row of `points` by (squared distance, row): the reference order.
std::vector<Neighbour> bruteForce(const Eigen::MatrixX3d& points, const Vector3d& q) {
  std::vector<Neighbour> all;
  for (Eigen::Index i = 0; i < points.rows(); ++i) {
    if (!points.row(i).allFinite()) continue;
    all.push_back({static_cast<int>(i), sqDistance(points.row(i).transpose(), q)});
  }
  std::sort(all.begin(), all.end(), [](const Neighbour& a, const Neighbour& b) {
    return a.sq_distance < b.sq_distance || (a.sq_distance == b.sq_distance && a.index < b.index);
  });
  return all;
}

Eigen::MatrixX3d randomCloud(int n, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Eigen::MatrixX3d p(n, 3);
  for (int i = 0; i < n; ++i) p.row(i) << u(rng), u(rng), u(rng);
  return p;
}

// Small integer coordinates: many duplicates and many equal distances, all
// computed exactly.
Eigen::MatrixX3d integerCloud(int n, int range, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> u(0, range);
  Eigen::MatrixX3d p(n, 3);
  for (int i = 0; i < n; ++i) p.row(i) << u(rng), u(rng), u(rng);
  return p;
}

double angleDeg(const Vector3d& a, const Vector3d& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b)) * 180.0 / std::numbers::pi;
}

// Angle between lines (normals up to sign).
double lineAngleDeg(const Vector3d& a, const Vector3d& b) {
  const double angle = angleDeg(a, b);
  return std::min(angle, 180.0 - angle);
}

// Uniform random points on a sphere.
Eigen::MatrixX3d sphereCloud(int n, const Vector3d& centre, double radius, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  Eigen::MatrixX3d p(n, 3);
  for (int i = 0; i < n; ++i) {
    const Vector3d d = Vector3d(g(rng), g(rng), g(rng)).normalized();
    p.row(i) = (centre + radius * d).transpose();
  }
  return p;
}

// Fibonacci-spiral points on a sphere: nearly even spacing, as a scanner's
// sampling is (uniform random points cluster and leave gaps).
Eigen::MatrixX3d fibonacciSphere(int n, const Vector3d& centre, double radius) {
  const double golden = std::numbers::pi * (3.0 - std::sqrt(5.0));
  Eigen::MatrixX3d p(n, 3);
  for (int i = 0; i < n; ++i) {
    const double z = 1.0 - (2.0 * i + 1.0) / n, r = std::sqrt(1.0 - z * z);
    p.row(i) = (centre + radius * Vector3d(r * std::cos(golden * i), r * std::sin(golden * i), z)).transpose();
  }
  return p;
}

// A tilted plane (the rotation maps +Z to its normal).
Eigen::Matrix3d planeRotation() {
  return (Eigen::AngleAxisd(0.7, Vector3d(1.0, 2.0, 0.5).normalized()) *
          Eigen::AngleAxisd(0.3, Vector3d::UnitZ()))
      .toRotationMatrix();
}

// A grid of n x n points, `spacing` apart, with in-plane jitter and noise
// along the normal (both uniform, as fractions of the spacing), rotated by
// planeRotation() and moved off the origin. Cells where `keep` is false are left out;
// `cells` receives the (i, j) of each row.
template <class Keep>
Eigen::MatrixX3d gridPlane(int n, double spacing, double jitter, double noise, unsigned seed, Keep keep,
                           std::vector<std::pair<int, int>>* cells = nullptr) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const Eigen::Matrix3d r = planeRotation();
  const Vector3d offset(3.0, -1.0, 2.0);
  std::vector<Vector3d> points;
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      if (!keep(i, j)) continue;
      const Vector3d local(spacing * (i + jitter * u(rng)), spacing * (j + jitter * u(rng)), spacing * noise * u(rng));
      points.push_back(r * local + offset);
      if (cells) cells->emplace_back(i, j);
    }
  }
  Eigen::MatrixX3d p(static_cast<Eigen::Index>(points.size()), 3);
  for (std::size_t i = 0; i < points.size(); ++i) p.row(static_cast<Eigen::Index>(i)) = points[i].transpose();
  return p;
}

// ---------------------------------------------------------------------------
// Queries

TEST(PointCloudIndex, EmptyIndexFindsNone) {
  Eigen::MatrixX3d nan_rows(2, 3);
  nan_rows << kNaN, 0.0, 0.0, 1.0, std::numeric_limits<double>::infinity(), 0.0;
  std::vector<PointCloudIndex> indices;
  indices.emplace_back();
  indices.emplace_back(Eigen::MatrixX3d(0, 3));
  indices.emplace_back(nan_rows);
  PointCloudIndex moved(randomCloud(10, 1));
  PointCloudIndex taker(std::move(moved));
  EXPECT_EQ(taker.size(), 10);
  for (const PointCloudIndex* index : {&indices[0], &indices[1], &indices[2], &moved}) {
    EXPECT_EQ(index->size(), 0);
    EXPECT_EQ(index->nearest(Vector3d(0.0, 0.0, 0.0)).index, -1);
    EXPECT_TRUE(std::isinf(index->nearest(Vector3d(0.0, 0.0, 0.0)).sq_distance));
    EXPECT_TRUE(index->nearest(Vector3d(0.0, 0.0, 0.0), 5).empty());
    const auto batch = index->nearest(Eigen::MatrixX3d(Eigen::MatrixX3d::Zero(3, 3)));
    ASSERT_EQ(batch.size(), 3u);
    for (const auto& nb : batch) EXPECT_EQ(nb.index, -1);
  }
}

TEST(PointCloudIndex, NearestMatchesBruteForceOnRandomCloud) {
  const Eigen::MatrixX3d points = randomCloud(3000, 7);
  const PointCloudIndex index(points);
  ASSERT_EQ(index.size(), 3000);
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-1.5, 1.5);  // some queries outside the cloud's box
  for (int t = 0; t < 600; ++t) {
    const Vector3d q = t % 10 == 0 ? Vector3d(points.row(t).transpose()) : Vector3d(u(rng), u(rng), u(rng));
    const auto expected = bruteForce(points, q);
    const Neighbour got = index.nearest(q);
    ASSERT_EQ(got.index, expected[0].index) << "query " << t;
    EXPECT_EQ(got.sq_distance, expected[0].sq_distance);
    for (const int k : {1, 8, 31}) {
      const auto knn = index.nearest(q, k);
      ASSERT_EQ(knn.size(), static_cast<std::size_t>(k));
      for (int j = 0; j < k; ++j) {
        ASSERT_EQ(knn[j].index, expected[j].index) << "query " << t << " k " << k << " rank " << j;
        EXPECT_EQ(knn[j].sq_distance, expected[j].sq_distance);
      }
    }
  }
}

TEST(PointCloudIndex, TiesGoToTheLowerIndexLikeBruteForce) {
  // 400 points on a 5 x 5 x 5 lattice: every point has ~3 copies, and
  // distances from lattice and half-lattice queries tie in large groups.
  const Eigen::MatrixX3d points = integerCloud(400, 4, 3);
  const PointCloudIndex index(points);
  std::mt19937 rng(5);
  std::uniform_int_distribution<int> u(-2, 12);
  int tied_ranks = 0;
  for (int t = 0; t < 300; ++t) {
    const Vector3d q = Vector3d(u(rng), u(rng), u(rng)) / 2.0;
    const auto expected = bruteForce(points, q);
    const Neighbour got = index.nearest(q);
    ASSERT_EQ(got.index, expected[0].index) << "query " << t;
    EXPECT_EQ(got.sq_distance, expected[0].sq_distance);
    for (const int k : {1, 4, 17, 100, 400, 1000}) {
      const auto knn = index.nearest(q, k);
      ASSERT_EQ(knn.size(), static_cast<std::size_t>(std::min(k, 400)));
      for (std::size_t j = 0; j < knn.size(); ++j) {
        ASSERT_EQ(knn[j].index, expected[j].index) << "query " << t << " k " << k << " rank " << j;
        ASSERT_EQ(knn[j].sq_distance, expected[j].sq_distance);
        if (j > 0 && knn[j].sq_distance == knn[j - 1].sq_distance) ++tied_ranks;
      }
    }
  }
  EXPECT_GT(tied_ranks, 1000);  // the test did exercise ties
  EXPECT_TRUE(index.nearest(Vector3d(0.0, 0.0, 0.0), 0).empty());
  EXPECT_TRUE(index.nearest(Vector3d(0.0, 0.0, 0.0), -3).empty());
}

TEST(PointCloudIndex, NonFiniteRowsAndQueriesAreSkipped) {
  Eigen::MatrixX3d points = randomCloud(200, 9);
  points(17, 1) = kNaN;
  points(120, 2) = -std::numeric_limits<double>::infinity();
  const PointCloudIndex index(points);
  EXPECT_EQ(index.size(), 198);
  for (Eigen::Index i = 0; i < points.rows(); ++i) {
    if (i == 17 || i == 120) continue;
    const Vector3d q = points.row(i).transpose();
    EXPECT_EQ(index.nearest(q).index, bruteForce(points, q)[0].index);
    for (const auto& nb : index.nearest(q, 250)) EXPECT_TRUE(nb.index != 17 && nb.index != 120);
  }
  EXPECT_EQ(index.nearest(Vector3d(kNaN, 0.0, 0.0)).index, -1);
  EXPECT_TRUE(index.nearest(Vector3d(0.0, kNaN, 0.0), 3).empty());
  EXPECT_GT(index.memoryBytes(), 198 * 3 * sizeof(double));
}

TEST(PointCloudIndex, BatchEqualsSingleQueries) {
  const Eigen::MatrixX3d points = randomCloud(5000, 21);
  const PointCloudIndex index(points);
  Eigen::MatrixX3d queries = 1.2 * randomCloud(2000, 22);
  queries.topRows(100) = points.topRows(100);  // exact hits
  queries.row(5) << kNaN, 0.0, 0.0;
  for (const int threads : {1, 2, 3}) {
    const core::ScopedThreadCount scoped(threads);
    const auto batch = index.nearest(queries);
    ASSERT_EQ(batch.size(), 2000u);
    for (Eigen::Index i = 0; i < queries.rows(); ++i) {
      const Neighbour single = index.nearest(Vector3d(queries.row(i).transpose()));
      ASSERT_EQ(batch[i].index, single.index) << "row " << i;
      EXPECT_EQ(batch[i].sq_distance, single.sq_distance);
    }
    EXPECT_EQ(batch[5].index, -1);
    EXPECT_EQ(batch[42].index, 42);
    EXPECT_EQ(batch[42].sq_distance, 0.0);
  }
}

// ---------------------------------------------------------------------------
// Normals

// Evenly sampled: every normal within 3 degrees of the radius. Randomly
// sampled at the same density: a point whose neighbours all lie to one side
// tilts by up to the angle they subtend (~6 degrees here), so the median is checked.
TEST(CloudNormals, SphereNormalsAreRadialWithADeterministicSign) {
  const Vector3d centre(5.0, -3.0, 1.0);
  {
    const Eigen::MatrixX3d random = sphereCloud(4000, centre, 2.0, 31);
    const Eigen::MatrixX3d normals = estimateCloudNormals(random, PointCloudIndex(random));
    std::vector<double> angles;
    for (Eigen::Index i = 0; i < random.rows(); ++i) {
      angles.push_back(lineAngleDeg(normals.row(i).transpose(), Vector3d(random.row(i).transpose()) - centre));
    }
    std::nth_element(angles.begin(), angles.begin() + 2000, angles.end());
    EXPECT_LT(angles[2000], 1.5);
  }
  const Eigen::MatrixX3d points = fibonacciSphere(4000, centre, 2.0);
  const PointCloudIndex index(points);
  const Eigen::MatrixX3d normals = estimateCloudNormals(points, index);
  ASSERT_EQ(normals.rows(), points.rows());
  double worst = 0.0;
  for (Eigen::Index i = 0; i < points.rows(); ++i) {
    const Vector3d n = normals.row(i).transpose();
    EXPECT_NEAR(n.norm(), 1.0, 1e-12);
    worst = std::max(worst, lineAngleDeg(n, Vector3d(points.row(i).transpose()) - centre));
    Eigen::Index largest = 0;
    n.cwiseAbs().maxCoeff(&largest);
    EXPECT_GT(n(largest), 0.0) << "row " << i;
  }
  EXPECT_LT(worst, 3.0);
  // Same input, any thread count: the same bits.
  const core::ScopedThreadCount one(1);
  EXPECT_TRUE(estimateCloudNormals(points, index) == normals);
}

TEST(CloudNormals, PlaneNormalsWithinADegree) {
  const Eigen::MatrixX3d points = gridPlane(40, 0.01, 0.3, 0.01, 41, [](int, int) { return true; });
  const PointCloudIndex index(points);
  const Vector3d truth = planeRotation().col(2);
  const Eigen::MatrixX3d normals = estimateCloudNormals(points, index, 12);
  double worst = 0.0;
  for (Eigen::Index i = 0; i < points.rows(); ++i) {
    worst = std::max(worst, lineAngleDeg(normals.row(i).transpose(), truth));
  }
  EXPECT_LT(worst, 1.5);
}

TEST(CloudNormals, NonFinitePointsGetZeroNormals) {
  Eigen::MatrixX3d points = sphereCloud(300, Vector3d::Zero(), 1.0, 43);
  points(10, 0) = kNaN;
  const Eigen::MatrixX3d normals = estimateCloudNormals(points, PointCloudIndex(points));
  EXPECT_EQ(normals.row(10).norm(), 0.0);
  EXPECT_NEAR(normals.row(11).norm(), 1.0, 1e-12);
}

TEST(CloudNormals, OrientNormalsLikeFlipsExactlyTheDisagreeingOnes) {
  const Eigen::MatrixX3d points = sphereCloud(2000, Vector3d::Zero(), 1.0, 51);
  const PointCloudIndex index(points);
  Eigen::MatrixX3d normals = estimateCloudNormals(points, index);
  const Eigen::MatrixX3d outward = points.rowwise().normalized();
  int disagreeing = 0;
  for (Eigen::Index i = 0; i < points.rows(); ++i) disagreeing += normals.row(i).dot(outward.row(i)) < 0.0 ? 1 : 0;
  EXPECT_GT(disagreeing, 500);  // the sign rule is not the outward one
  EXPECT_LT(disagreeing, 1500);
  const Eigen::MatrixX3d before = normals;
  EXPECT_EQ(core::orientNormalsLike(normals, outward), disagreeing);
  for (Eigen::Index i = 0; i < points.rows(); ++i) {
    EXPECT_GT(normals.row(i).dot(outward.row(i)), 0.9);
    EXPECT_TRUE(normals.row(i) == before.row(i) || normals.row(i) == -before.row(i));
  }
  EXPECT_EQ(core::orientNormalsLike(normals, outward), 0);
  // Against the opposite reference every normal turns.
  EXPECT_EQ(core::orientNormalsLike(normals, -outward), 2000);
}

// ---------------------------------------------------------------------------
// Borders

// A 40 x 40 grid with a 10 x 10 hole (cells 15..24 on both axes), jittered.
// Ring r = Chebyshev distance in cells to the nearest missing cell (outside the
// grid or in the hole): ring 1 is the border. Tolerance of one ring: every
// ring-1 point is flagged except the hole's four corners (their neighbours
// leave a gap of exactly 90 degrees on the unjittered grid, so jitter decides),
// ring-2 points may be flagged, deeper ones never.
TEST(CloudBorders, GridWithSquareHoleFlagsTheOuterAndHoleRings) {
  constexpr int kN = 40, kLo = 15, kHi = 24;
  const auto in_hole = [](int i, int j) { return i >= kLo && i <= kHi && j >= kLo && j <= kHi; };
  std::vector<std::pair<int, int>> cells;
  const Eigen::MatrixX3d points =
      gridPlane(kN, 0.5, 0.15, 0.02, 61, [&](int i, int j) { return !in_hole(i, j); }, &cells);
  const auto ring = [&](int i, int j) {
    int r = std::min({i + 1, j + 1, kN - i, kN - j});
    const int di = std::max({kLo - i, 0, i - kHi}), dj = std::max({kLo - j, 0, j - kHi});
    return std::min(r, std::max(di, dj));
  };
  const std::set<std::pair<int, int>> hole_corners = {
      {kLo - 1, kLo - 1}, {kLo - 1, kHi + 1}, {kHi + 1, kLo - 1}, {kHi + 1, kHi + 1}};
  const PointCloudIndex index(points);
  const Eigen::MatrixX3d normals = estimateCloudNormals(points, index);
  const std::vector<char> border = core::cloudBorderPoints(points, normals, index);
  ASSERT_EQ(border.size(), cells.size());
  int ring1 = 0, ring2_flagged = 0, interior = 0;
  for (std::size_t p = 0; p < cells.size(); ++p) {
    const auto [i, j] = cells[p];
    const int r = ring(i, j);
    if (r == 1 && !hole_corners.contains(cells[p])) {
      EXPECT_TRUE(border[p]) << "ring-1 point (" << i << ", " << j << ") not flagged";
      ++ring1;
    } else if (r == 2) {
      ring2_flagged += border[p];
    } else if (r >= 3) {
      EXPECT_FALSE(border[p]) << "interior point (" << i << ", " << j << ") flagged";
      ++interior;
    }
  }
  EXPECT_EQ(ring1, 4 * (kN - 1) + 4 * (kHi - kLo + 2) - 4);
  EXPECT_GT(interior, 1000);
  EXPECT_LE(ring2_flagged, 4);  // a few at most, near corners
}

// An evenly sampled closed surface has no border. (Uniform random sampling
// would: 16 independent directions leave a 90-degree gap with probability
// ~0.21, and about that share of such a cloud is flagged.)
TEST(CloudBorders, SphereHasNoBorderAndIsolatedPointsAreBorders) {
  const Eigen::MatrixX3d sphere = fibonacciSphere(3000, Vector3d::Zero(), 1.0);
  const PointCloudIndex sphere_index(sphere);
  const auto on_sphere = core::cloudBorderPoints(sphere, estimateCloudNormals(sphere, sphere_index), sphere_index);
  EXPECT_EQ(std::count(on_sphere.begin(), on_sphere.end(), 1), 0);

  Eigen::MatrixX3d lonely(1, 3);
  lonely << 1.0, 2.0, 3.0;
  const PointCloudIndex lonely_index(lonely);
  Eigen::MatrixX3d up(1, 3);
  up << 0.0, 0.0, 1.0;
  EXPECT_EQ(core::cloudBorderPoints(lonely, up, lonely_index)[0], 1);
}

// ---------------------------------------------------------------------------
// Spikes

TEST(CloudSpikes, FindsInjectedOutliersOnANoisyPlaneAndNothingElse) {
  constexpr int kN = 50;
  constexpr double kSpacing = 0.2;
  std::vector<std::pair<int, int>> cells;
  Eigen::MatrixX3d points = gridPlane(kN, kSpacing, 0.1, 0.05, 81, [](int, int) { return true; }, &cells);
  const Vector3d normal = planeRotation().col(2);
  // (cell, offset along the normal in spacings): inside, signed both ways,
  // from 1 to 4 spacings, and two on the grid's edge.
  const std::vector<std::pair<std::pair<int, int>, double>> injected = {
      {{10, 10}, 1.0}, {{10, 30}, -1.2}, {{25, 25}, 4.0}, {{30, 12}, -2.0}, {{40, 40}, 1.5},
      {{18, 44}, 3.0}, {{42, 20}, -1.0}, {{0, 25}, 3.0},  {{25, 49}, -3.0}};
  std::set<Eigen::Index> expected;
  for (const auto& [cell, height] : injected) {
    const auto row = static_cast<Eigen::Index>(cell.first * kN + cell.second);
    ASSERT_EQ(cells[static_cast<std::size_t>(row)], cell);
    points.row(row) += height * kSpacing * normal.transpose();
    expected.insert(row);
  }
  // A spike scanned twice: its copy must not hold it up.
  points.conservativeResize(points.rows() + 1, 3);
  points.row(points.rows() - 1) = points.row(25 * kN + 25);
  expected.insert(points.rows() - 1);

  // Within the sampling's own scale: a third of a spacing is 7 noise
  // amplitudes off, but not a spike.
  points.row(35 * kN + 5) += 0.3 * kSpacing * normal.transpose();

  const PointCloudIndex index(points);
  const std::vector<char> spikes = core::cloudSpikes(points, index);
  std::set<Eigen::Index> found;
  for (std::size_t i = 0; i < spikes.size(); ++i) {
    if (spikes[i]) found.insert(static_cast<Eigen::Index>(i));
  }
  EXPECT_EQ(found, expected);
}

// A spike over a hole: its nearest neighbours are the hole's rim, far away
// along the plane, so the spacing is the rim's own, not the distance to it.
TEST(CloudSpikes, FindsASpikeOverAHole) {
  constexpr int kN = 40, kLo = 15, kHi = 24;
  Eigen::MatrixX3d points = gridPlane(kN, 1.0, 0.1, 0.05, 87, [&](int i, int j) {
    return !(i >= kLo && i <= kHi && j >= kLo && j <= kHi);
  });
  points.conservativeResize(points.rows() + 1, 3);
  const Vector3d above = planeRotation() * Vector3d(19.5, 19.5, 2.0) + Vector3d(3.0, -1.0, 2.0);
  points.row(points.rows() - 1) = above.transpose();
  const std::vector<char> spikes = core::cloudSpikes(points, PointCloudIndex(points));
  EXPECT_EQ(spikes.back(), 1);
  EXPECT_EQ(std::count(spikes.begin(), spikes.end(), 1), 1);
}

TEST(CloudSpikes, SmoothSurfacesHaveNone) {
  // Noise-free but rotated (rounding only): the floor and the spacing rule.
  const Eigen::MatrixX3d plane = gridPlane(30, 1e-3, 0.0, 0.0, 91, [](int, int) { return true; });
  const auto on_plane = core::cloudSpikes(plane, PointCloudIndex(plane));
  EXPECT_EQ(std::count(on_plane.begin(), on_plane.end(), 1), 0);
  // Curvature and some noise.
  const Eigen::RowVector3d centre(1.0, 2.0, 3.0);
  Eigen::MatrixX3d sphere = sphereCloud(5000, centre.transpose(), 10.0, 93);
  std::mt19937 rng(95);
  std::normal_distribution<double> g(0.0, 0.002);  // radius 10, spacing ~0.5: noise ~4% of the spacing
  for (Eigen::Index i = 0; i < sphere.rows(); ++i) sphere.row(i) = centre + (1.0 + g(rng)) * (sphere.row(i) - centre);
  const auto on_sphere = core::cloudSpikes(sphere, PointCloudIndex(sphere));
  EXPECT_EQ(std::count(on_sphere.begin(), on_sphere.end(), 1), 0);
  // One spike on it, two spacings out, is found.
  sphere.row(100) += 1.0 * (sphere.row(100) - centre).normalized();
  const auto spiked = core::cloudSpikes(sphere, PointCloudIndex(sphere));
  EXPECT_EQ(std::count(spiked.begin(), spiked.end(), 1), 1);
  EXPECT_EQ(spiked[100], 1);
}

}  // namespace
