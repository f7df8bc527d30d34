// Tests core/geometry/closest_point.cpp and core/geometry/moving_mesh_index.cpp: the
// point-triangle routine against the projection optimality condition, and
// both indices against a brute-force scan over all triangles (with and
// without filters) on meshes built here.
#include "core/base/parallel.h"
#include "core/geometry/closest_point.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>
#include <random>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "core/geometry/mesh.h"
#include "core/geometry/moving_mesh_index.h"
#include "tests/test_support.h"

namespace {

using core::ClosestPointIndex;
using core::ClosestPointOptions;
using core::SurfacePoint;
using Eigen::Vector3d;

struct TestMesh {
  Eigen::MatrixX3d positions;
  Eigen::MatrixX3i triangles;
};

TestMesh fromLists(const std::vector<Vector3d>& v, const std::vector<Eigen::Vector3i>& f) {
  TestMesh m;
  m.positions.resize(static_cast<Eigen::Index>(v.size()), 3);
  m.triangles.resize(static_cast<Eigen::Index>(f.size()), 3);
  for (std::size_t i = 0; i < v.size(); ++i) m.positions.row(static_cast<Eigen::Index>(i)) = v[i].transpose();
  for (std::size_t i = 0; i < f.size(); ++i) m.triangles.row(static_cast<Eigen::Index>(i)) = f[i].transpose();
  return m;
}

// Icosphere with `levels` 1:4 subdivisions, radius 1, vertices moved radially by
// up to `bump` (random, fixed seed): closed, irregular, ~20 * 4^levels faces.
TestMesh makeBumpySphere(int levels, double bump, unsigned seed) {
  const rigport_test::Icosphere sphere = rigport_test::unitIcosphere(levels);
  TestMesh m{sphere.positions, sphere.triangles};
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-bump, bump);
  for (Eigen::Index i = 0; i < m.positions.rows(); ++i) m.positions.row(i) *= 1.0 + u(rng);
  return m;
}

// A triangle soup mixing regular triangles, slivers (thin and needle-like),
// exactly and nearly collinear triples, repeated indices and coincident corners.
TestMesh makeSliverSoup(unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  auto rnd = [&] { return Vector3d(u(rng), u(rng), u(rng)); };
  std::vector<Vector3d> v;
  std::vector<Eigen::Vector3i> f;
  auto add = [&](const Vector3d& a, const Vector3d& b, const Vector3d& c) {
    const int i = static_cast<int>(v.size());
    v.push_back(a);
    v.push_back(b);
    v.push_back(c);
    f.push_back({i, i + 1, i + 2});
  };
  for (int k = 0; k < 60; ++k) {
    const Vector3d a = rnd();
    const Vector3d b = a + 0.3 * rnd();
    const Vector3d side = 0.3 * rnd();
    add(a, b, a + side);                                              // regular
    add(a, b, 0.5 * (a + b) + 1e-6 * side);                           // thin sliver
    add(a, b, a + u01(rng) * (b - a));                                // collinear (maybe not exactly)
    add(a, b, 0.5 * (a + b) + 1e-13 * side);                          // numerically flat
    add(a, a + 1e-9 * side, b);                                       // needle
    add(a, a, b);                                                     // coincident corners
    const int i = static_cast<int>(v.size()) - 1;
    f.push_back({i, i, i - 1});                                       // repeated index
  }
  return fromLists(v, f);
}

// A 30 x 30 grid of small triangles near z = 0 plus a few huge triangles across it.
TestMesh makeHugeAndTiny() {
  std::vector<Vector3d> v;
  std::vector<Eigen::Vector3i> f;
  const int n = 30;
  for (int j = 0; j <= n; ++j) {
    for (int i = 0; i <= n; ++i) v.emplace_back(i / double(n), j / double(n), 0.02 * std::sin(7.0 * i / n + 3.0 * j / n));
  }
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      const int a = j * (n + 1) + i;
      f.push_back({a, a + 1, a + n + 2});
      f.push_back({a, a + n + 2, a + n + 1});
    }
  }
  auto add = [&](const Vector3d& a, const Vector3d& b, const Vector3d& c) {
    const int i = static_cast<int>(v.size());
    v.push_back(a);
    v.push_back(b);
    v.push_back(c);
    f.push_back({i, i + 1, i + 2});
  };
  add({-50, -50, 0.3}, {60, -40, 0.5}, {0, 70, 0.4});           // huge, above the grid
  add({0.5, 0.5, -30}, {0.5, 0.6, 40}, {40, 0.55, 0});          // huge, through the grid
  add({-200, 3, -1}, {300, 3.1, -1.2}, {0, 3.05, 500});         // huge sliver-ish
  add({2, 2, 2}, {2.5, 2, 2}, {2, 2.5, 2});                     // medium
  return fromLists(v, f);
}

double scaleOf(const TestMesh& m) { return std::max(1e-300, core::boundingBoxDiagonal(m.positions)); }

struct Filter {
  const Vector3d* normal = nullptr;
  std::uint64_t mask = ~std::uint64_t{0};
  ClosestPointOptions options;
};

// The reference: every non-degenerate triangle, closest compatible one, ties to
// the lower face index.
class BruteForce {
 public:
  explicit BruteForce(const TestMesh& m, std::vector<std::uint64_t> labels = {})
      : m_(m), labels_(std::move(labels)), normals_(core::computeFaceNormals(m.positions, m.triangles)) {
    const double diagonal = core::boundingBoxDiagonal(m.positions);
    for (Eigen::Index f = 0; f < m.triangles.rows(); ++f) {
      if (!core::isDegenerateTriangle(m.positions, m.triangles.row(f), diagonal)) faces_.push_back(static_cast<int>(f));
    }
  }

  SurfacePoint operator()(const Vector3d& q, const Filter& filter = {}) const {
    const bool use_normal = filter.normal != nullptr && filter.options.max_normal_angle_deg < 180.0;
    const double min_cos = std::cos(filter.options.max_normal_angle_deg * std::numbers::pi / 180.0);
    SurfacePoint best;
    for (const int f : faces_) {
      if (!labels_.empty() && (filter.mask & labels_[static_cast<std::size_t>(f)]) == 0) continue;
      if (use_normal && Vector3d(normals_.row(f)).dot(*filter.normal) < min_cos) continue;
      const Eigen::Vector3i t = m_.triangles.row(f);
      SurfacePoint r = core::closestPointOnTriangle(q, m_.positions.row(t(0)), m_.positions.row(t(1)),
                                                    m_.positions.row(t(2)));
      if (r.sq_distance > filter.options.max_distance * filter.options.max_distance) continue;
      if (best.face < 0 || r.sq_distance < best.sq_distance) {
        best = r;
        best.face = f;
      }
    }
    return best;
  }

 private:
  const TestMesh& m_;
  std::vector<std::uint64_t> labels_;
  Eigen::MatrixX3d normals_;
  std::vector<int> faces_;
};

// Same squared distance (1e-12 relative, plus 1e-24 scale^2 absolute: on-surface
// queries have rounding-level distances ~1e-16 whichever face is reported);
// faces may differ only on ties. Also checks barycentrics and the point.
::testing::AssertionResult sameAnswer(const TestMesh& m, const SurfacePoint& got, const SurfacePoint& ref,
                                      const Vector3d& q) {
  if (got.found() != ref.found()) {
    return ::testing::AssertionFailure() << "found " << got.found() << " (face " << got.face << ", d2 "
                                         << got.sq_distance << ") vs reference " << ref.found() << " (face "
                                         << ref.face << ", d2 " << ref.sq_distance << ")";
  }
  if (!got.found()) return ::testing::AssertionSuccess();
  const double scale = scaleOf(m);
  const double tol = 1e-12 * ref.sq_distance + 1e-24 * scale * scale;
  if (std::abs(got.sq_distance - ref.sq_distance) > tol) {
    return ::testing::AssertionFailure() << "d2 " << got.sq_distance << " (face " << got.face << ") vs reference "
                                         << ref.sq_distance << " (face " << ref.face << ")";
  }
  const Vector3d b = got.barycentric;
  if (!(b.minCoeff() >= 0.0 && b.maxCoeff() <= 1.0 && std::abs(b.sum() - 1.0) <= 1e-12)) {
    return ::testing::AssertionFailure() << "barycentrics " << b.transpose();
  }
  const Eigen::Vector3i t = m.triangles.row(got.face);
  const Vector3d rebuilt = b(0) * Vector3d(m.positions.row(t(0))) + b(1) * Vector3d(m.positions.row(t(1))) +
                           b(2) * Vector3d(m.positions.row(t(2)));
  if ((rebuilt - got.point).norm() > 1e-12 * (scale + got.point.norm())) {
    return ::testing::AssertionFailure() << "barycentrics rebuild " << rebuilt.transpose() << " not point "
                                         << got.point.transpose();
  }
  const double d2 = (q - got.point).squaredNorm();
  if (std::abs(d2 - got.sq_distance) > 1e-12 * std::max(d2, 1e-24 * scale * scale)) {
    return ::testing::AssertionFailure() << "sq_distance " << got.sq_distance << " but |q - point|^2 = " << d2;
  }
  return ::testing::AssertionSuccess();
}

// Query points: near the surface (both sides), on the surface, inside the
// bounding box, and far away.
std::vector<Vector3d> makeQueries(const TestMesh& m, int count, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  std::normal_distribution<double> gauss(0.0, 1.0);
  const Eigen::RowVector3d lo = m.positions.colwise().minCoeff();
  const Eigen::RowVector3d hi = m.positions.colwise().maxCoeff();
  const Vector3d center = 0.5 * (lo + hi).transpose();
  const double scale = scaleOf(m);
  std::uniform_int_distribution<Eigen::Index> face(0, m.triangles.rows() - 1);
  std::vector<Vector3d> out;
  out.reserve(count);
  for (int i = 0; i < count; ++i) {
    const int kind = i % 4;
    if (kind <= 1) {  // on / near the surface
      const Eigen::Vector3i t = m.triangles.row(face(rng));
      double b0 = u01(rng), b1 = u01(rng);
      if (b0 + b1 > 1.0) b0 = 1.0 - b0, b1 = 1.0 - b1;
      const Vector3d p = (1 - b0 - b1) * Vector3d(m.positions.row(t(0))) + b0 * Vector3d(m.positions.row(t(1))) +
                         b1 * Vector3d(m.positions.row(t(2)));
      const double offset = kind == 0 ? 0.0 : scale * std::pow(10.0, -4.0 + 3.0 * u01(rng));
      out.push_back(p + offset * Vector3d(gauss(rng), gauss(rng), gauss(rng)).normalized());
    } else if (kind == 2) {  // anywhere in the (slightly grown) box, including inside closed meshes
      const Vector3d r(u01(rng), u01(rng), u01(rng));
      out.push_back(lo.transpose() - 0.1 * scale * Vector3d::Ones() +
                    r.cwiseProduct((hi - lo).transpose() + 0.2 * scale * Vector3d::Ones()));
    } else {  // far away
      const Vector3d dir = Vector3d(gauss(rng), gauss(rng), gauss(rng)).normalized();
      out.push_back(center + scale * std::pow(10.0, 2.0 * u01(rng)) * dir);
    }
  }
  return out;
}

void expectMatchesBruteForce(const TestMesh& m, int count, unsigned seed) {
  const ClosestPointIndex index(m.positions, m.triangles);
  const BruteForce brute(m);
  const auto queries = makeQueries(m, count, seed);
  int failures = 0;
  for (std::size_t i = 0; i < queries.size() && failures < 10; ++i) {
    const auto got = index.closestPoint(queries[i]);
    const auto ref = brute(queries[i]);
    const auto ok = sameAnswer(m, got, ref, queries[i]);
    EXPECT_TRUE(ok) << "query " << i << " at " << queries[i].transpose();
    if (!ok) ++failures;
  }
}

// ---------------------------------------------------------------------------
// closestPointOnTriangle

// x = projection of p onto the convex triangle iff (p - x).(v - x) <= 0 for
// every corner v; checks that plus the barycentric contract.
TEST(ClosestPointOnTriangle, SatisfiesProjectionOptimalityOnRandomTriangles) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  auto rnd = [&] { return Vector3d(u(rng), u(rng), u(rng)); };
  for (int k = 0; k < 20000; ++k) {
    const Vector3d a = rnd(), b = rnd(), c = rnd();
    const Vector3d p = 2.0 * rnd();
    const SurfacePoint r = core::closestPointOnTriangle(p, a, b, c);
    ASSERT_TRUE(r.found());
    ASSERT_NEAR(r.barycentric.sum(), 1.0, 1e-12);
    ASSERT_GE(r.barycentric.minCoeff(), 0.0);
    ASSERT_LE(r.barycentric.maxCoeff(), 1.0);
    const Vector3d x = r.barycentric(0) * a + r.barycentric(1) * b + r.barycentric(2) * c;
    ASSERT_LE((x - r.point).norm(), 1e-12);
    ASSERT_NEAR((p - r.point).squaredNorm(), r.sq_distance, 1e-12);
    for (const Vector3d& v : {a, b, c}) ASSERT_LE((p - r.point).dot(v - r.point), 1e-9) << "triangle " << k;
  }
}

TEST(ClosestPointOnTriangle, ExactAtCornersEdgesAndInterior) {
  const Vector3d a(0, 0, 0), b(2, 0, 0), c(0, 2, 0);
  auto check = [&](const Vector3d& p, const Vector3d& expect_point, double expect_d2) {
    const SurfacePoint r = core::closestPointOnTriangle(p, a, b, c);
    EXPECT_LE((r.point - expect_point).norm(), 1e-15) << p.transpose();
    EXPECT_NEAR(r.sq_distance, expect_d2, 1e-15) << p.transpose();
  };
  check({-1, -1, 0}, a, 2.0);           // corner region
  check({3, -1, 1}, b, 3.0);            // corner region
  check({1, -1, 0}, {1, 0, 0}, 1.0);    // edge region
  check({2, 2, 0}, {1, 1, 0}, 2.0);     // hypotenuse region
  check({0.5, 0.5, 3}, {0.5, 0.5, 0}, 9.0);  // interior: orthogonal projection
  check({0.5, 0.5, 0}, {0.5, 0.5, 0}, 0.0);  // on the face
}

TEST(ClosestPointOnTriangle, DegenerateTrianglesGiveFinitePointOnTheSegment) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  auto rnd = [&] { return Vector3d(u(rng), u(rng), u(rng)); };
  for (int k = 0; k < 2000; ++k) {
    const Vector3d a = rnd(), b = rnd();
    const Vector3d p = 2.0 * rnd();
    const Vector3d mid = a + 0.37 * (b - a);
    // Closest point on segment [a, b], the hull of every case below.
    const double t = std::clamp((p - a).dot(b - a) / (b - a).squaredNorm(), 0.0, 1.0);
    const Vector3d on_segment = a + t * (b - a);
    const std::vector<std::array<Vector3d, 3>> cases = {{a, a, b}, {a, b, b}, {b, a, a}, {a, b, mid},
                                                        {mid, a, b}, {a, mid, b}};
    for (const auto& tri : cases) {
      const SurfacePoint r = core::closestPointOnTriangle(p, tri[0], tri[1], tri[2]);
      ASSERT_TRUE(r.point.allFinite() && r.barycentric.allFinite() && std::isfinite(r.sq_distance));
      EXPECT_NEAR(r.barycentric.sum(), 1.0, 1e-12);
      EXPECT_GE(r.barycentric.minCoeff(), 0.0);
      EXPECT_LE((r.point - on_segment).norm(), 1e-9) << "case " << k;
      EXPECT_NEAR(r.sq_distance, (p - on_segment).squaredNorm(), 1e-9);
    }
    // A single point.
    const SurfacePoint r = core::closestPointOnTriangle(p, a, a, a);
    ASSERT_TRUE(r.point.allFinite());
    EXPECT_LE((r.point - a).norm(), 0.0);
    EXPECT_NEAR(r.sq_distance, (p - a).squaredNorm(), 1e-15);
  }
}

// ---------------------------------------------------------------------------
// ClosestPointIndex against brute force

TEST(ClosestPointIndex, MatchesBruteForceOnBumpySphere) {
  const TestMesh m = makeBumpySphere(3, 0.05, 1);  // 1280 faces
  expectMatchesBruteForce(m, 3000, 2);
}

TEST(ClosestPointIndex, MatchesBruteForceOnSliversAndDegenerateTriangles) {
  const TestMesh m = makeSliverSoup(3);
  const ClosestPointIndex index(m.positions, m.triangles);
  EXPECT_LT(index.faceCount(), m.triangles.rows());  // repeated indices / coincident corners are skipped
  expectMatchesBruteForce(m, 4000, 4);
}

TEST(ClosestPointIndex, MatchesBruteForceWithHugeAndTinyTriangles) {
  const TestMesh m = makeHugeAndTiny();
  expectMatchesBruteForce(m, 3000, 5);
}

TEST(ClosestPointIndex, MatchesBruteForceOnSingleTriangle) {
  const TestMesh m = fromLists({{0, 0, 0}, {1, 0, 0}, {0.2, 0.9, 0.1}}, {{0, 1, 2}});
  const ClosestPointIndex index(m.positions, m.triangles);
  EXPECT_EQ(index.faceCount(), 1);
  expectMatchesBruteForce(m, 2000, 6);
}

TEST(ClosestPointIndex, MatchesBruteForceForQueriesOnVerticesAndEdges) {
  const TestMesh m = makeBumpySphere(2, 0.1, 8);
  const ClosestPointIndex index(m.positions, m.triangles);
  std::vector<Vector3d> queries;
  for (Eigen::Index v = 0; v < m.positions.rows(); ++v) queries.push_back(m.positions.row(v));
  for (Eigen::Index f = 0; f < m.triangles.rows(); ++f) {
    for (int k = 0; k < 3; ++k) {
      const Vector3d a = m.positions.row(m.triangles(f, k));
      const Vector3d b = m.positions.row(m.triangles(f, (k + 1) % 3));
      queries.push_back(0.5 * (a + b));
      queries.push_back(a + 0.1 * (b - a));
    }
  }
  const BruteForce brute(m);
  for (const Vector3d& q : queries) {
    const auto got = index.closestPoint(q);
    ASSERT_TRUE(sameAnswer(m, got, brute(q), q)) << q.transpose();
    EXPECT_LE(got.sq_distance, 1e-28);
  }
}

TEST(ClosestPointIndex, MatchesBruteForceOnDenseSphere) {
  const TestMesh m = makeBumpySphere(5, 0.02, 9);  // 20480 faces
  expectMatchesBruteForce(m, 200, 10);
}

// ---------------------------------------------------------------------------
// Filters

// One label per face: its band of height.
std::vector<std::uint64_t> bandLabels(const TestMesh& m, int bands) {
  std::vector<std::uint64_t> labels(static_cast<std::size_t>(m.triangles.rows()));
  for (Eigen::Index f = 0; f < m.triangles.rows(); ++f) {
    const double z = m.positions(m.triangles(f, 0), 2);  // in [-1.1, 1.1]
    labels[static_cast<std::size_t>(f)] = std::uint64_t{1} << std::clamp(static_cast<int>((z + 1.1) / 2.2 * bands), 0, bands - 1);
  }
  return labels;
}

TEST(ClosestPointIndex, NormalFilterMatchesBruteForceOverCompatibleFaces) {
  const TestMesh m = makeBumpySphere(3, 0.05, 12);
  const ClosestPointIndex index(m.positions, m.triangles);
  const BruteForce brute(m);
  const auto queries = makeQueries(m, 2000, 13);
  std::mt19937 rng(14);
  std::normal_distribution<double> gauss(0.0, 1.0);
  const double angles[] = {30.0, 60.0, 90.0, 150.0};
  for (std::size_t i = 0; i < queries.size(); ++i) {
    const Vector3d n = Vector3d(gauss(rng), gauss(rng), gauss(rng)).normalized();
    Filter filter;
    filter.normal = &n;
    filter.options.max_normal_angle_deg = angles[i % 4];
    const auto got = index.closestPoint(queries[i], &n, ~std::uint64_t{0}, filter.options);
    ASSERT_TRUE(sameAnswer(m, got, brute(queries[i], filter), queries[i])) << "query " << i;
    ASSERT_TRUE(got.found());  // a closed sphere has every normal direction
  }
}

TEST(ClosestPointIndex, LabelFilterMatchesBruteForceOverCompatibleFaces) {
  const TestMesh m = makeBumpySphere(3, 0.05, 15);
  const std::vector<std::uint64_t> labels = bandLabels(m, 7);
  const ClosestPointIndex index(m.positions, m.triangles, labels);
  const BruteForce brute(m, labels);
  const auto queries = makeQueries(m, 2000, 16);
  std::mt19937_64 rng(17);
  for (std::size_t i = 0; i < queries.size(); ++i) {
    Filter filter;
    filter.mask = (i % 3 == 0) ? (std::uint64_t{1} << (i % 7)) : rng();
    const auto got = index.closestPoint(queries[i], nullptr, filter.mask, filter.options);
    ASSERT_TRUE(sameAnswer(m, got, brute(queries[i], filter), queries[i])) << "query " << i;
  }
}

TEST(ClosestPointIndex, CombinedFiltersAndMaxDistanceMatchBruteForce) {
  const TestMesh m = makeSliverSoup(18);
  // Label sets: one label per face, a second on every third face.
  std::vector<std::uint64_t> labels(static_cast<std::size_t>(m.triangles.rows()));
  for (std::size_t f = 0; f < labels.size(); ++f) {
    labels[f] = (std::uint64_t{1} << ((f * 7) % 64)) | (f % 3 == 0 ? std::uint64_t{1} << ((f * 11) % 64) : 0);
  }
  const ClosestPointIndex index(m.positions, m.triangles, labels);
  const BruteForce brute(m, labels);
  const auto queries = makeQueries(m, 3000, 19);
  std::mt19937_64 rng(20);
  std::normal_distribution<double> gauss(0.0, 1.0);
  int found = 0, not_found = 0;
  for (std::size_t i = 0; i < queries.size(); ++i) {
    const Vector3d n = Vector3d(gauss(rng), gauss(rng), gauss(rng)).normalized();
    Filter filter;
    filter.normal = (i % 2) ? &n : nullptr;
    filter.mask = rng() | rng();
    filter.options.max_normal_angle_deg = 75.0;
    filter.options.max_distance = (i % 3 == 0) ? std::numeric_limits<double>::infinity() : 0.3 * (i % 5);
    const auto got = index.closestPoint(queries[i], filter.normal, filter.mask, filter.options);
    ASSERT_TRUE(sameAnswer(m, got, brute(queries[i], filter), queries[i])) << "query " << i;
    if (got.found()) {
      ++found;
      EXPECT_LE(std::sqrt(got.sq_distance), filter.options.max_distance);
    } else {
      ++not_found;
    }
  }
  EXPECT_GT(found, 100);  // the test exercises both outcomes
  EXPECT_GT(not_found, 100);
}

TEST(ClosestPointIndex, NoCompatibleFaceGivesMinusOne) {
  const TestMesh m = makeHugeAndTiny();
  std::vector<std::uint64_t> labels(static_cast<std::size_t>(m.triangles.rows()), std::uint64_t{1} << 3);
  const ClosestPointIndex index(m.positions, m.triangles, labels);
  const Vector3d q(0.5, 0.5, 0.1);
  ClosestPointOptions options;
  EXPECT_FALSE(index.closestPoint(q, nullptr, ~(std::uint64_t{1} << 3), options).found());  // label absent
  EXPECT_TRUE(index.closestPoint(q, nullptr, std::uint64_t{1} << 3, options).found());

  // Grid-only mesh: every face normal is near +z.
  TestMesh grid = m;
  grid.triangles.conservativeResize(m.triangles.rows() - 4, 3);
  const ClosestPointIndex grid_index(grid.positions, grid.triangles);
  const Vector3d down(0, 0, -1);
  options.max_normal_angle_deg = 60.0;
  const auto none = grid_index.closestPoint(q, &down, ~std::uint64_t{0}, options);
  EXPECT_FALSE(none.found());
  EXPECT_EQ(none.face, -1);
  const Vector3d up(0, 0, 1);
  EXPECT_TRUE(grid_index.closestPoint(q, &up, ~std::uint64_t{0}, options).found());
}

TEST(ClosestPointIndex, MaxDistanceIsHonoured) {
  const TestMesh m = makeBumpySphere(3, 0.05, 21);
  const ClosestPointIndex index(m.positions, m.triangles);
  const BruteForce brute(m);
  const auto queries = makeQueries(m, 1500, 22);
  for (std::size_t i = 0; i < queries.size(); ++i) {
    Filter filter;
    filter.options.max_distance = 0.05 * (i % 10);
    const auto got = index.closestPoint(queries[i], nullptr, ~std::uint64_t{0}, filter.options);
    ASSERT_TRUE(sameAnswer(m, got, brute(queries[i], filter), queries[i])) << "query " << i;
    if (got.found()) {
      EXPECT_LE(got.sq_distance, filter.options.max_distance * filter.options.max_distance);
    }
  }
  // The sphere centre is ~1 from every face.
  ClosestPointOptions options;
  options.max_distance = 0.5;
  EXPECT_FALSE(index.closestPoint(Vector3d::Zero(), nullptr, ~std::uint64_t{0}, options).found());
}

// ---------------------------------------------------------------------------
// Batch, determinism, bookkeeping

TEST(ClosestPointIndex, BatchIsIdenticalForOneAndTwoThreads) {
  const TestMesh m = makeBumpySphere(3, 0.05, 23);
  const std::vector<std::uint64_t> labels = bandLabels(m, 5);
  const ClosestPointIndex index(m.positions, m.triangles, labels);
  const auto list = makeQueries(m, 3000, 24);
  Eigen::MatrixX3d queries(list.size(), 3);
  for (std::size_t i = 0; i < list.size(); ++i) queries.row(static_cast<Eigen::Index>(i)) = list[i].transpose();
  core::ClosestPointFilters filters;
  filters.normals = Eigen::MatrixX3d::Random(queries.rows(), 3).rowwise().normalized();
  std::mt19937_64 rng(25);
  for (Eigen::Index i = 0; i < queries.rows(); ++i) filters.label_masks.push_back(rng());
  ClosestPointOptions options;
  options.max_normal_angle_deg = 80.0;
  for (const bool filtered : {false, true}) {
    auto onThreads = [&](int threads) {
      const core::ScopedThreadCount scope(threads);
      return index.closestPoints(queries, options, filtered ? filters : core::ClosestPointFilters{});
    };
    const auto one = onThreads(1);
    const auto two = onThreads(2);
    ASSERT_EQ(one.size(), list.size());
    ASSERT_EQ(two.size(), list.size());
    for (std::size_t i = 0; i < list.size(); ++i) {
      ASSERT_EQ(one[i].face, two[i].face) << i;
      ASSERT_EQ(one[i].sq_distance, two[i].sq_distance) << i;
      ASSERT_EQ(one[i].point, two[i].point) << i;
      ASSERT_EQ(one[i].barycentric, two[i].barycentric) << i;
      // Batch equals the single-query API.
      const Vector3d n = filters.normals.row(static_cast<Eigen::Index>(i));
      const auto single = filtered ? index.closestPoint(list[i], &n, filters.label_masks[i], options)
                                   : index.closestPoint(list[i], nullptr, ~std::uint64_t{0}, options);
      ASSERT_EQ(single.face, one[i].face) << i;
      ASSERT_EQ(single.sq_distance, one[i].sq_distance) << i;
    }
  }
}

TEST(ClosestPointIndex, TiesGoToTheLowerFaceIndex) {
  // Two copies of the same triangle: every query ties.
  const TestMesh m = fromLists({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 0}, {1, 0, 0}, {0, 1, 0}}, {{3, 4, 5}, {0, 1, 2}});
  const ClosestPointIndex index(m.positions, m.triangles);
  for (const auto& q : makeQueries(m, 200, 26)) EXPECT_EQ(index.closestPoint(q).face, 0);
}

TEST(ClosestPointIndex, CountsFacesAndMemoryAndHandlesEmptyAndMovedIndices) {
  const TestMesh m = makeSliverSoup(27);
  ClosestPointIndex index(m.positions, m.triangles);
  int expected = 0;
  const double diagonal = core::boundingBoxDiagonal(m.positions);
  for (Eigen::Index f = 0; f < m.triangles.rows(); ++f) {
    expected += core::isDegenerateTriangle(m.positions, m.triangles.row(f), diagonal) ? 0 : 1;
  }
  EXPECT_EQ(index.faceCount(), expected);
  EXPECT_GT(index.memoryBytes(), static_cast<std::size_t>(expected) * 32);

  ClosestPointIndex moved(std::move(index));
  EXPECT_EQ(moved.faceCount(), expected);
  EXPECT_TRUE(moved.closestPoint(Vector3d(0.1, 0.2, 0.3)).found());

  const ClosestPointIndex empty(Eigen::MatrixX3d(0, 3), Eigen::MatrixX3i(0, 3));
  EXPECT_EQ(empty.faceCount(), 0);
  EXPECT_FALSE(empty.closestPoint(Vector3d::Zero()).found());
  EXPECT_TRUE(empty.closestPoints(Eigen::MatrixX3d::Zero(5, 3)).size() == 5);

  // Only degenerate faces: nothing is indexed.
  const TestMesh flat = fromLists({{0, 0, 0}, {1, 0, 0}, {2, 0, 0}}, {{0, 1, 2}, {0, 0, 1}});
  const ClosestPointIndex flat_index(flat.positions, flat.triangles);
  EXPECT_EQ(flat_index.faceCount(), 0);
  EXPECT_FALSE(flat_index.closestPoint(Vector3d(1, 1, 0)).found());
}

TEST(ClosestPointIndex, NonFiniteQueryFindsNothing) {
  const TestMesh m = makeBumpySphere(1, 0.0, 28);
  const ClosestPointIndex index(m.positions, m.triangles);
  EXPECT_FALSE(index.closestPoint(Vector3d(std::nan(""), 0, 0)).found());
  EXPECT_FALSE(index.closestPoint(Vector3d(std::numeric_limits<double>::infinity(), 0, 0)).found());
}

// ---------------------------------------------------------------------------
// MovingMeshIndex: built at rest, fitted to moved positions

// The rest mesh moved smoothly but far (twisted, stretched 3x along x, bent),
// plus per-vertex noise of a quarter edge that folds some triangles over:
// the groups built at rest are no longer tight.
TestMesh moved(const TestMesh& rest, unsigned seed) {
  TestMesh m = rest;
  std::mt19937 rng(seed);
  std::normal_distribution<double> gauss(0.0, 1.0);
  const double edge = (rest.positions.row(rest.triangles(0, 0)) - rest.positions.row(rest.triangles(0, 1))).norm();
  for (Eigen::Index v = 0; v < m.positions.rows(); ++v) {
    const Vector3d p = rest.positions.row(v);
    const double twist = 1.2 * p.z();
    Vector3d q(std::cos(twist) * p.x() - std::sin(twist) * p.y(), std::sin(twist) * p.x() + std::cos(twist) * p.y(), p.z());
    q.x() *= 3.0;
    q.z() += 0.4 * q.x() * q.x();
    m.positions.row(v) = (q + 0.25 * edge * Vector3d(gauss(rng), gauss(rng), gauss(rng))).transpose();
  }
  return m;
}

// Bit-identical to ClosestPointIndex on the same positions (and so to the
// brute force, which ClosestPointIndex matches above).
::testing::AssertionResult identical(const SurfacePoint& got, const SurfacePoint& ref) {
  if (got.face == ref.face && got.sq_distance == ref.sq_distance && got.barycentric == ref.barycentric &&
      got.point == ref.point) {
    return ::testing::AssertionSuccess();
  }
  return ::testing::AssertionFailure() << "face " << got.face << " d2 " << got.sq_distance << " vs ClosestPointIndex face "
                                       << ref.face << " d2 " << ref.sq_distance;
}

Eigen::MatrixX3d rowsOf(const std::vector<Vector3d>& list) {
  Eigen::MatrixX3d m(static_cast<Eigen::Index>(list.size()), 3);
  for (std::size_t i = 0; i < list.size(); ++i) m.row(static_cast<Eigen::Index>(i)) = list[i].transpose();
  return m;
}

TEST(MovingMeshIndex, MatchesBruteForceAfterTheVerticesMoveFar) {
  const TestMesh rest = makeBumpySphere(3, 0.05, 31);
  const core::MovingMeshIndex hierarchy(rest.positions, rest.triangles);
  for (const unsigned seed : {32u, 33u}) {
    const TestMesh m = moved(rest, seed);
    const auto fitted = hierarchy.fit(m.positions);
    EXPECT_EQ(fitted.faceCount(), ClosestPointIndex(m.positions, m.triangles).faceCount());
    const BruteForce brute(m);
    const auto queries = makeQueries(m, 2000, seed + 10);
    const auto got = fitted.closestPoints(rowsOf(queries));
    for (std::size_t i = 0; i < queries.size(); ++i) {
      ASSERT_TRUE(sameAnswer(m, got[i], brute(queries[i]), queries[i])) << "query " << i;
    }
  }
  // Fitted at rest it answers as at rest.
  const auto queries = makeQueries(rest, 500, 34);
  const auto got = hierarchy.fit(rest.positions).closestPoints(rowsOf(queries));
  const ClosestPointIndex index(rest.positions, rest.triangles);
  for (std::size_t i = 0; i < queries.size(); ++i) ASSERT_TRUE(identical(got[i], index.closestPoint(queries[i]))) << i;
}

TEST(MovingMeshIndex, EqualsClosestPointIndexWithFiltersAndDegenerateFaces) {
  const TestMesh rest = makeSliverSoup(35);
  const core::MovingMeshIndex hierarchy(rest.positions, rest.triangles);
  // Moved: scaled and sheared, and every tenth triangle collapsed to a point
  // (degenerate there though not at rest).
  TestMesh m = rest;
  Eigen::Matrix3d shear;
  shear << 2.0, 0.5, 0.0, 0.0, 0.7, 0.3, 0.1, 0.0, 1.5;
  m.positions = (rest.positions * shear.transpose()).eval();
  for (Eigen::Index f = 0; f < m.triangles.rows(); f += 10) {
    for (int k = 1; k < 3; ++k) m.positions.row(m.triangles(f, k)) = m.positions.row(m.triangles(f, 0));
  }
  std::vector<std::uint64_t> labels(static_cast<std::size_t>(m.triangles.rows()));
  for (std::size_t f = 0; f < labels.size(); ++f) labels[f] = std::uint64_t{1} << ((f * 5) % 64);
  const ClosestPointIndex index(m.positions, m.triangles, labels);
  const auto fitted = hierarchy.fit(m.positions, labels);
  EXPECT_EQ(fitted.faceCount(), index.faceCount());
  const auto list = makeQueries(m, 3000, 36);
  core::ClosestPointFilters filters;
  filters.normals = Eigen::MatrixX3d::Random(static_cast<Eigen::Index>(list.size()), 3).rowwise().normalized();
  std::mt19937_64 rng(37);
  for (std::size_t i = 0; i < list.size(); ++i) filters.label_masks.push_back(rng() | rng());
  for (const double max_distance : {std::numeric_limits<double>::infinity(), 0.4}) {
    ClosestPointOptions options;
    options.max_normal_angle_deg = 75.0;
    options.max_distance = max_distance;
    const core::ScopedThreadCount threads(2);
    for (const bool filtered : {false, true}) {
      const auto got = fitted.closestPoints(rowsOf(list), options, filtered ? filters : core::ClosestPointFilters{});
      const auto ref = index.closestPoints(rowsOf(list), options, filtered ? filters : core::ClosestPointFilters{});
      int found = 0;
      for (std::size_t i = 0; i < list.size(); ++i) {
        ASSERT_TRUE(identical(got[i], ref[i])) << "query " << i << (filtered ? " filtered" : "");
        found += got[i].found() ? 1 : 0;
      }
      EXPECT_GT(found, 100);
    }
  }
}

// Faces spread so unevenly (at x = 2^k) that every cut at the middle of their
// extent peels off one: the hierarchy must stay shallow (median splits take
// over; a query's stack is bounded by the depth) and answer exactly. Faces
// far smaller than the diagonal are degenerate by the indices' rule, as in
// the brute force.
TEST(MovingMeshIndex, ExtremelyUnevenFacesStayExact) {
  std::vector<Vector3d> v;
  std::vector<Eigen::Vector3i> f;
  for (int k = 0; k < 300; ++k) {
    const double x = std::ldexp(1.0, k);
    const int i = static_cast<int>(v.size());
    v.push_back({x, 0.0, 0.0});
    v.push_back({1.5 * x, 0.0, 0.3 * x});
    v.push_back({x, 0.7 * x, 0.1 * x});
    f.push_back({i, i + 1, i + 2});
  }
  const TestMesh m = fromLists(v, f);
  const core::MovingMeshIndex hierarchy(m.positions, m.triangles);
  const auto fitted = hierarchy.fit(m.positions);
  EXPECT_GT(fitted.faceCount(), 20);
  const BruteForce brute(m);
  std::vector<Vector3d> queries;
  for (int k = 0; k < 300; k += 3) {
    const double x = std::ldexp(1.0, k);
    queries.push_back({1.2 * x, 0.3 * x, 0.5 * x});
    queries.push_back({x, -0.2 * x, 0.0});
  }
  const auto got = fitted.closestPoints(rowsOf(queries));
  for (std::size_t i = 0; i < queries.size(); ++i) {
    const SurfacePoint ref = brute(queries[i]);
    EXPECT_EQ(got[i].face, ref.face) << "query " << i;
    EXPECT_EQ(got[i].sq_distance, ref.sq_distance) << "query " << i;
  }
}

TEST(MovingMeshIndex, TiesNonFiniteQueriesAndEmptyMeshes) {
  // Two copies of one triangle: ties go to the lower face index.
  const TestMesh twin = fromLists({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 0}, {1, 0, 0}, {0, 1, 0}}, {{3, 4, 5}, {0, 1, 2}});
  const core::MovingMeshIndex hierarchy(twin.positions, twin.triangles);
  const auto fitted = hierarchy.fit(twin.positions);
  for (const auto& r : fitted.closestPoints(rowsOf(makeQueries(twin, 100, 38)))) EXPECT_EQ(r.face, 0);
  Eigen::MatrixX3d odd(2, 3);
  odd << std::nan(""), 0, 0, std::numeric_limits<double>::infinity(), 0, 0;
  for (const auto& r : fitted.closestPoints(odd)) EXPECT_FALSE(r.found());
  EXPECT_GT(hierarchy.memoryBytes(), 0u);
  EXPECT_EQ(hierarchy.triangles(), twin.triangles);

  const core::MovingMeshIndex empty(Eigen::MatrixX3d(0, 3), Eigen::MatrixX3i(0, 3));
  const auto nothing = empty.fit(Eigen::MatrixX3d(0, 3));
  EXPECT_EQ(nothing.faceCount(), 0);
  EXPECT_FALSE(nothing.closestPoints(Eigen::MatrixX3d::Zero(3, 3))[0].found());
}

}  // namespace
