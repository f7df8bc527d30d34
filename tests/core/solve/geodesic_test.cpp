#include "core/base/parallel.h"
#include "core/solve/geodesic.h"

#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <numbers>
#include <random>
#include <set>

#include <gtest/gtest.h>

#include "core/synthetic/synthetic_head.h"
#include "tests/test_support.h"

namespace {

// Unit icosphere: an icosahedron subdivided `levels` times, vertices projected
// onto the sphere (levels = 5: 10242 vertices).
core::Mesh icosphere(int levels) {
  const rigport_test::Icosphere sphere = rigport_test::unitIcosphere(levels);
  core::Mesh mesh;
  mesh.positions = sphere.positions;
  mesh.triangles = sphere.triangles;
  return mesh;
}

// n by n cells on [0, 1]^2 (z = 0), interior vertices jittered by up to
// `jitter` cells, each cell's diagonal chosen at random. Cells for which
// `hole(x, y)` (cell centre) is true are left out.
template <typename Hole>
core::Mesh jitteredGrid(int n, double jitter, unsigned seed, Hole hole) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-jitter, jitter);
  std::bernoulli_distribution coin(0.5);
  core::Mesh mesh;
  mesh.positions.resize((n + 1) * (n + 1), 3);
  for (int j = 0; j <= n; ++j) {
    for (int i = 0; i <= n; ++i) {
      double x = i, y = j;
      if (i > 0 && i < n && j > 0 && j < n) {
        x += u(rng);
        y += u(rng);
      }
      mesh.positions.row(j * (n + 1) + i) << x / n, y / n, 0.0;
    }
  }
  std::vector<Eigen::Vector3i> tris;
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      if (hole((i + 0.5) / n, (j + 0.5) / n)) continue;
      const int a = j * (n + 1) + i, b = a + 1, c = a + n + 2, d = a + n + 1;
      if (coin(rng)) {
        tris.emplace_back(a, b, c);
        tris.emplace_back(a, c, d);
      } else {
        tris.emplace_back(a, b, d);
        tris.emplace_back(b, c, d);
      }
    }
  }
  mesh.triangles.resize(static_cast<Eigen::Index>(tris.size()), 3);
  for (std::size_t i = 0; i < tris.size(); ++i) mesh.triangles.row(static_cast<Eigen::Index>(i)) = tris[i].transpose();
  return mesh;
}

core::Mesh jitteredGrid(int n, double jitter, unsigned seed) {
  return jitteredGrid(n, jitter, seed, [](double, double) { return false; });
}

double meanEdgeLength(const core::Mesh& mesh) {
  double sum = 0.0;
  for (Eigen::Index f = 0; f < mesh.triangleCount(); ++f) {
    for (int c = 0; c < 3; ++c) {
      sum += (mesh.positions.row(mesh.triangles(f, c)) - mesh.positions.row(mesh.triangles(f, (c + 1) % 3))).norm();
    }
  }
  return sum / (3.0 * static_cast<double>(mesh.triangleCount()));
}

// A SurfacePoint exactly at vertex v (the first triangle that uses it).
core::SurfacePoint atVertex(const core::Mesh& mesh, int v) {
  for (Eigen::Index f = 0; f < mesh.triangleCount(); ++f) {
    for (int c = 0; c < 3; ++c) {
      if (mesh.triangles(f, c) == v) {
        core::SurfacePoint p;
        p.face = static_cast<int>(f);
        p.barycentric(c) = 1.0;
        return p;
      }
    }
  }
  ADD_FAILURE() << "vertex " << v << " is on no triangle";
  return {};
}

Eigen::Vector3d pointOf(const core::Mesh& mesh, const core::SurfacePoint& p) {
  Eigen::Vector3d x = Eigen::Vector3d::Zero();
  for (int c = 0; c < 3; ++c) x += p.barycentric(c) * mesh.positions.row(mesh.triangles(p.face, c)).transpose();
  return x;
}

struct RelativeError {
  double mean = 0.0;
  double max = 0.0;
  int samples = 0;
};

// Relative error of `computed` against `exact` over vertices with exact
// distance > min_distance (close to the source the relative error of any
// discretisation is dominated by the mesh spacing).
RelativeError relativeError(const Eigen::VectorXd& computed, const Eigen::VectorXd& exact, double min_distance) {
  RelativeError e;
  for (Eigen::Index v = 0; v < exact.size(); ++v) {
    if (exact(v) <= min_distance) continue;
    const double r = std::abs(computed(v) - exact(v)) / exact(v);
    e.mean += r;
    e.max = std::max(e.max, r);
    ++e.samples;
  }
  if (e.samples > 0) e.mean /= e.samples;
  return e;
}

// Sphere: great-circle distance from vertex sources and from a point inside a face.
TEST(Geodesic, SphereDistancesWithinTwoPercentOfGreatCircle) {
  const core::Mesh sphere = icosphere(5);
  ASSERT_EQ(sphere.vertexCount(), 10242);
  auto solver = core::GeodesicSolver::create(sphere, "icosphere");
  ASSERT_TRUE(solver) << solver.error().message;
  const double h = meanEdgeLength(sphere);
  std::vector<core::SurfacePoint> sources = {atVertex(sphere, 0), atVertex(sphere, 5000)};
  core::SurfacePoint inside;
  inside.face = 1234;
  inside.barycentric << 0.2, 0.3, 0.5;
  sources.push_back(inside);
  const Eigen::MatrixXd d = solver->distances(sources);
  ASSERT_EQ(d.rows(), 3);
  ASSERT_EQ(d.cols(), sphere.vertexCount());
  for (std::size_t s = 0; s < sources.size(); ++s) {
    const Eigen::Vector3d c = pointOf(sphere, sources[s]).normalized();
    Eigen::VectorXd exact(sphere.vertexCount());
    for (Eigen::Index v = 0; v < exact.size(); ++v) {
      exact(v) = std::acos(std::clamp(c.dot(sphere.positions.row(v).transpose()), -1.0, 1.0));
    }
    const RelativeError e = relativeError(d.row(static_cast<Eigen::Index>(s)).transpose(), exact, 5.0 * h);
    std::printf("[ metrics  ] sphere source %zu: relative error mean %.4f max %.4f over %d vertices (d > 5h)\n", s,
                e.mean, e.max, e.samples);
    EXPECT_GT(e.samples, 9000);
    EXPECT_LT(e.max, 0.02) << "source " << s;
    EXPECT_LT(e.mean, 0.01) << "source " << s;
    EXPECT_GE(d.row(static_cast<Eigen::Index>(s)).minCoeff(), 0.0);
  }
  EXPECT_EQ(d(0, 0), 0.0);  // the source vertex itself
}

TEST(Geodesic, PlaneDistancesWithinTwoPercentOfEuclidean) {
  const core::Mesh plane = jitteredGrid(100, 0.3, 17);
  auto solver = core::GeodesicSolver::create(plane, "plane");
  ASSERT_TRUE(solver) << solver.error().message;
  const double h = meanEdgeLength(plane);
  // The centre, a point near a corner (isolines meet the boundary), and a
  // point inside a triangle.
  std::vector<core::SurfacePoint> sources = {atVertex(plane, 50 * 101 + 50), atVertex(plane, 15 * 101 + 20)};
  core::SurfacePoint inside;
  inside.face = 2 * (70 * 100 + 30);
  inside.barycentric << 0.5, 0.25, 0.25;
  sources.push_back(inside);
  const Eigen::MatrixXd d = solver->distances(sources);
  // The square's four corner vertices are the known weak spot (isolines meet
  // a 90-degree boundary corner): checked apart, with a looser bound.
  const std::vector<int> corners = {0, 100, 100 * 101, 101 * 101 - 1};
  for (std::size_t s = 0; s < sources.size(); ++s) {
    const Eigen::Vector3d c = pointOf(plane, sources[s]);
    Eigen::VectorXd exact = (plane.positions.rowwise() - c.transpose()).rowwise().norm();
    Eigen::VectorXd computed = d.row(static_cast<Eigen::Index>(s)).transpose();
    double worst_corner = 0.0;
    for (int v : corners) {
      worst_corner = std::max(worst_corner, std::abs(computed(v) - exact(v)) / exact(v));
      exact(v) = 0.0;  // excluded below
    }
    const RelativeError e = relativeError(computed, exact, 5.0 * h);
    const RelativeError e8 = relativeError(computed, exact, 8.0 * h);
    std::printf("[ metrics  ] plane source %zu: relative error mean %.4f max %.4f over %d vertices (d > 5h), "
                "max %.4f (d > 8h); square corners max %.4f\n", s, e.mean, e.max, e.samples, e8.max, worst_corner);
    EXPECT_GT(e.samples, 9000);
    EXPECT_LT(e.mean, 0.01) << "source " << s;
    EXPECT_LT(e8.max, 0.02) << "source " << s;
    // A source inside a triangle is smeared over its corners: its near field
    // (5-8 h) is up to ~2.4% off; vertex sources stay within 2% from 5 h.
    EXPECT_LT(e.max, s == 2 ? 0.03 : 0.02) << "source " << s;
    EXPECT_LT(worst_corner, 0.03) << "source " << s;
  }
}

// Known limit: for a source on the boundary the Dirichlet solution vanishes
// (u = 0 there), so only the Neumann one is left and the error is anisotropic:
// distances along the boundary come out short, into the interior long.
TEST(Geodesic, SourceOnTheBoundaryIsWithinTenPercent) {
  const core::Mesh plane = jitteredGrid(40, 0.0, 2);
  auto solver = core::GeodesicSolver::create(plane, "plane");
  ASSERT_TRUE(solver);
  const double h = meanEdgeLength(plane);
  for (int source : {0, 20}) {  // a corner, the middle of an edge
    const Eigen::MatrixXd d = solver->distances({atVertex(plane, source)});
    const Eigen::Vector3d c = plane.positions.row(source).transpose();
    const Eigen::VectorXd exact = (plane.positions.rowwise() - c.transpose()).rowwise().norm();
    const RelativeError e = relativeError(d.row(0).transpose(), exact, 5.0 * h);
    std::printf("[ metrics  ] plane, source on the boundary (vertex %d): relative error mean %.4f max %.4f\n", source,
                e.mean, e.max);
    EXPECT_LT(e.mean, 0.05);
    EXPECT_LT(e.max, 0.10);
  }
}

TEST(Geodesic, AveragingBoundaryConditionsHelpsNearBoundaries) {
  const core::Mesh plane = jitteredGrid(60, 0.3, 3);
  const double h = meanEdgeLength(plane);
  const std::vector<core::SurfacePoint> sources = {atVertex(plane, 10 * 61 + 12)};
  const Eigen::Vector3d c = pointOf(plane, sources[0]);
  const Eigen::VectorXd exact = (plane.positions.rowwise() - c.transpose()).rowwise().norm();
  RelativeError errors[2];
  for (bool average : {false, true}) {
    core::GeodesicOptions options;
    options.average_boundary_conditions = average;
    auto solver = core::GeodesicSolver::create(plane, "plane", options);
    ASSERT_TRUE(solver) << solver.error().message;
    errors[average] = relativeError(solver->distances(sources).row(0).transpose(), exact, 5.0 * h);
    std::printf("[ metrics  ] plane, source near a corner, %s: relative error mean %.4f max %.4f\n",
                average ? "Neumann+Dirichlet average" : "Neumann only", errors[average].mean, errors[average].max);
  }
  EXPECT_LT(errors[1].mean, errors[0].mean);
}

struct Asymmetry {
  double mean = 0.0;
  double worst = 0.0;
  int pairs = 0;
};

// |d(a -> b) - d(b -> a)| / min over pairs of `count` random interior vertices
// (not on a boundary, see SourceOnTheBoundaryIsWithinTenPercent) at least 5 h apart.
Asymmetry measureAsymmetry(const core::Mesh& mesh, const core::GeodesicOptions& options, int count) {
  Asymmetry result;
  auto solver = core::GeodesicSolver::create(mesh, "mesh", options);
  EXPECT_TRUE(solver) << solver.error().message;
  if (!solver) return result;
  const double h = meanEdgeLength(mesh);
  std::set<int> excluded;
  for (const auto& loop : core::boundaryLoops(mesh)) excluded.insert(loop.vertices.begin(), loop.vertices.end());
  std::vector<char> used(static_cast<std::size_t>(mesh.vertexCount()), 0);
  for (Eigen::Index f = 0; f < mesh.triangleCount(); ++f) {
    for (int c = 0; c < 3; ++c) used[static_cast<std::size_t>(mesh.triangles(f, c))] = 1;
  }
  std::mt19937 rng(8);
  std::uniform_int_distribution<int> pick(0, static_cast<int>(mesh.vertexCount()) - 1);
  std::vector<int> vertices;
  std::vector<core::SurfacePoint> sources;
  while (static_cast<int>(sources.size()) < count) {
    const int v = pick(rng);
    if (!used[static_cast<std::size_t>(v)] || !excluded.insert(v).second) continue;
    vertices.push_back(v);
    sources.push_back(atVertex(mesh, v));
  }
  const Eigen::MatrixXd d = solver->distances(sources);
  for (std::size_t i = 0; i < vertices.size(); ++i) {
    for (std::size_t j = i + 1; j < vertices.size(); ++j) {
      const double a = d(static_cast<Eigen::Index>(i), vertices[j]), b = d(static_cast<Eigen::Index>(j), vertices[i]);
      if (std::min(a, b) < 5.0 * h) continue;
      const double r = std::abs(a - b) / std::min(a, b);
      result.worst = std::max(result.worst, r);
      result.mean += r;
      ++result.pairs;
    }
  }
  result.mean /= std::max(result.pairs, 1);
  return result;
}

TEST(Geodesic, DistancesAreNearlySymmetric) {
  const Asymmetry a = measureAsymmetry(core::generateHead().mesh, {}, 30);
  std::printf("[ metrics  ] head: relative asymmetry mean %.4f worst %.4f over %d pairs\n", a.mean, a.worst, a.pairs);
  EXPECT_GT(a.pairs, 200);
  EXPECT_LT(a.mean, 0.02);
  EXPECT_LT(a.worst, 0.10);
}

// A jittered head has many obtuse triangles: at time_factor 1 some plain
// cotangent heat fields collapse; clamped heat weights keep them sane.
TEST(Geodesic, ClampedHeatWeightsRescueMeshesWithObtuseTriangles) {
  core::HeadResolution resolution;
  resolution.jitter = 0.2;
  resolution.seed = 4;
  const core::Mesh head = core::generateHead({}, resolution).mesh;
  core::GeodesicOptions options;
  options.time_factor = 1.0;
  const Asymmetry plain = measureAsymmetry(head, options, 30);
  options.clamp_heat_weights = true;
  const Asymmetry clamped = measureAsymmetry(head, options, 30);
  std::printf("[ metrics  ] jittered head, time_factor 1: asymmetry mean %.4f worst %.4f plain, mean %.4f worst %.4f "
              "clamped\n", plain.mean, plain.worst, clamped.mean, clamped.worst);
  EXPECT_GT(plain.mean, 0.1);  // the failure this option exists for; if it vanishes, revisit the default
  EXPECT_LT(clamped.mean, 0.05);
  EXPECT_LT(clamped.worst, 0.25);
}

// Across an open mouth the path goes round a lip corner, so it is much longer
// than the straight line; with closed lips it is not.
TEST(Geodesic, DistanceAcrossAnOpenMouthGoesRoundTheCorner) {
  double ratio[2] = {0.0, 0.0};
  for (int open = 0; open < 2; ++open) {
    core::HeadShape shape;
    shape.mouth_open = open ? 0.04 : 0.0;
    const core::SyntheticHead head = core::generateHead(shape);
    const int upper = head.landmarks.indexOf("mouth_inner_2"), lower = head.landmarks.indexOf("mouth_inner_6");
    ASSERT_GE(upper, 0);
    ASSERT_GE(lower, 0);
    const auto& lu = head.landmarks.landmarks[static_cast<std::size_t>(upper)];
    const auto& ll = head.landmarks.landmarks[static_cast<std::size_t>(lower)];
    ASSERT_EQ(lu.kind, core::LandmarkKind::kFace);
    const core::SurfacePoint a{lu.face, lu.barycentric}, b{ll.face, ll.barycentric};
    auto solver = core::GeodesicSolver::create(head.mesh, "head");
    ASSERT_TRUE(solver) << solver.error().message;
    const Eigen::MatrixXd d = solver->distances({a, b});
    // Geodesic at the other lip point: interpolate the distance field.
    double ab = 0.0, ba = 0.0;
    for (int c = 0; c < 3; ++c) {
      ab += b.barycentric(c) * d(0, head.mesh.triangles(b.face, c));
      ba += a.barycentric(c) * d(1, head.mesh.triangles(a.face, c));
    }
    const double euclidean = (pointOf(head.mesh, a) - pointOf(head.mesh, b)).norm();
    ratio[open] = 0.5 * (ab + ba) / euclidean;
    std::printf("[ metrics  ] mouth %s: lip-to-lip geodesic %.4f / %.4f m, Euclidean %.4f m\n",
                open ? "open" : "closed", ab, ba, euclidean);
  }
  // Closed lips are within about one edge of each other (h ~ 4 mm here), so
  // only bound the closed case loosely; the open case must go round.
  EXPECT_LT(ratio[0], 1.5);
  EXPECT_GT(ratio[1], 2.5);
}

TEST(Geodesic, ResultsDoNotDependOnThreadCount) {
  const core::Mesh plane = jitteredGrid(40, 0.3, 9);
  auto solver = core::GeodesicSolver::create(plane, "plane");
  ASSERT_TRUE(solver);
  std::vector<core::SurfacePoint> sources;
  for (int s = 0; s < 21; ++s) {  // several blocks, and a partial one
    core::SurfacePoint p;
    p.face = 37 * s + 5;
    p.barycentric << 0.2, 0.5, 0.3;
    sources.push_back(p);
  }
  auto onThreads = [&](const std::vector<core::SurfacePoint>& points, int threads) {
    const core::ScopedThreadCount scope(threads);
    return solver->distances(points);
  };
  const Eigen::MatrixXd one = onThreads(sources, 1);
  for (int threads : {2, 3, 0}) {
    const Eigen::MatrixXd many = onThreads(sources, threads);
    EXPECT_TRUE((one.array() == many.array()).all()) << threads << " threads";
  }
  // A source alone gives the same row as within a block.
  const Eigen::MatrixXd single = onThreads({sources[17]}, 1);
  EXPECT_TRUE((single.row(0).array() == one.row(17).array()).all());
}

TEST(Geodesic, SeparateComponentsAreInfinitelyFar) {
  // Two grids side by side, not connected, plus an unused vertex.
  const core::Mesh a = jitteredGrid(10, 0.2, 1);
  core::Mesh mesh;
  mesh.positions.resize(2 * a.vertexCount() + 1, 3);
  mesh.positions.topRows(a.vertexCount()) = a.positions;
  mesh.positions.middleRows(a.vertexCount(), a.vertexCount()) = a.positions.rowwise() + Eigen::RowVector3d(2.0, 0, 0);
  mesh.positions.bottomRows(1) << 5.0, 5.0, 5.0;
  mesh.triangles.resize(2 * a.triangleCount(), 3);
  mesh.triangles.topRows(a.triangleCount()) = a.triangles;
  mesh.triangles.bottomRows(a.triangleCount()) = a.triangles.array() + static_cast<int>(a.vertexCount());
  auto solver = core::GeodesicSolver::create(mesh, "two grids");
  ASSERT_TRUE(solver) << solver.error().message;
  EXPECT_EQ(solver->vertexCount(), mesh.vertexCount());
  const Eigen::Index n = a.vertexCount();
  const int centre = 5 * 11 + 5;  // an interior vertex of each grid
  const Eigen::MatrixXd d = solver->distances({atVertex(mesh, centre), atVertex(mesh, static_cast<int>(n) + centre)});
  EXPECT_TRUE(d.row(0).head(n).allFinite());
  EXPECT_TRUE((d.row(0).segment(n, n).array() == std::numeric_limits<double>::infinity()).all());
  EXPECT_TRUE(d.row(1).segment(n, n).allFinite());
  EXPECT_TRUE((d.row(1).head(n).array() == std::numeric_limits<double>::infinity()).all());
  EXPECT_EQ(d(0, 2 * n), std::numeric_limits<double>::infinity());
  EXPECT_EQ(d(0, centre), 0.0);
  EXPECT_EQ(d(1, n + centre), 0.0);
  const double to_corner = (mesh.positions.row(n + centre) - mesh.positions.row(n)).norm();
  EXPECT_NEAR(d(1, n), to_corner, 0.03 * to_corner);  // the second grid's first corner
}

TEST(Geodesic, SkipsDegenerateTrianglesAndRejectsUnusableMeshes) {
  core::Mesh mesh = jitteredGrid(20, 0.0, 2);
  // Append zero-area triangles (repeated vertex, collinear): they are skipped.
  const Eigen::Index f = mesh.triangleCount();
  mesh.triangles.conservativeResize(f + 2, 3);
  mesh.triangles.row(f) << 0, 0, 1;
  mesh.triangles.row(f + 1) << 0, 1, 2;  // three vertices on the bottom edge
  auto solver = core::GeodesicSolver::create(mesh, "slivers");
  ASSERT_TRUE(solver) << solver.error().message;
  const Eigen::MatrixXd d = solver->distances({atVertex(mesh, 21 * 10 + 10)});  // the centre
  EXPECT_TRUE(d.allFinite());
  EXPECT_NEAR(d(0, 10), 0.5, 0.01);  // the middle of the bottom edge

  core::Mesh points = mesh;
  points.triangles.resize(0, 3);
  auto none = core::GeodesicSolver::create(points, "points");
  ASSERT_FALSE(none);
  EXPECT_EQ(none.error().code, core::ErrorCode::kInvalidMesh);
  EXPECT_NE(none.error().message.find("points"), std::string::npos);

  core::Mesh flat = mesh;
  flat.triangles.resize(1, 3);
  flat.triangles.row(0) << 0, 1, 2;  // collinear only
  auto degenerate = core::GeodesicSolver::create(flat, "flat");
  ASSERT_FALSE(degenerate);
  EXPECT_EQ(degenerate.error().code, core::ErrorCode::kInvalidMesh);

  core::Mesh nan = mesh;
  nan.positions(7, 1) = std::numeric_limits<double>::quiet_NaN();
  auto bad = core::GeodesicSolver::create(nan, "nan");
  ASSERT_FALSE(bad);
  EXPECT_EQ(bad.error().code, core::ErrorCode::kInvalidMesh);

  core::GeodesicOptions options;
  options.time_factor = 0.0;
  auto bad_option = core::GeodesicSolver::create(mesh, "mesh", options);
  ASSERT_FALSE(bad_option);
  EXPECT_EQ(bad_option.error().code, core::ErrorCode::kInvalidArgument);
}

// Consecutive loop vertices must share a boundary edge, and each loop closes.
void expectLoopsFollowBoundaryEdges(const core::Mesh& mesh, const std::vector<core::BoundaryLoop>& boundary) {
  std::map<std::pair<int, int>, int> use;
  for (Eigen::Index f = 0; f < mesh.triangleCount(); ++f) {
    for (int c = 0; c < 3; ++c) ++use[std::minmax(mesh.triangles(f, c), mesh.triangles(f, (c + 1) % 3))];
  }
  std::size_t boundary_edges = 0;
  for (const auto& [edge, count] : use) boundary_edges += count == 1;
  std::size_t loop_edges = 0;
  for (const core::BoundaryLoop& b : boundary) {
    const std::vector<int>& loop = b.vertices;
    EXPECT_TRUE(b.closed);
    ASSERT_EQ(b.faces.size(), loop.size());
    for (std::size_t i = 0; i < loop.size(); ++i) {
      const auto key = std::minmax(loop[i], loop[(i + 1) % loop.size()]);
      EXPECT_EQ(use[key], 1) << "loop step " << key.first << "-" << key.second << " is not a boundary edge";
      // The edge is its face's, in the face's winding.
      EXPECT_EQ(mesh.triangles(b.faces[i], b.corners[i][0]), loop[i]);
      EXPECT_EQ(mesh.triangles(b.faces[i], b.corners[i][1]), loop[(i + 1) % loop.size()]);
    }
    loop_edges += loop.size();
  }
  EXPECT_EQ(loop_edges, boundary_edges);
}

TEST(Geodesic, BoundaryLoopsOfAnAnnulusAreOrderedOuterFirst) {
  const core::Mesh annulus =
      jitteredGrid(20, 0.2, 5, [](double x, double y) { return std::abs(x - 0.5) < 0.2 && std::abs(y - 0.5) < 0.2; });
  const auto loops = core::boundaryLoops(annulus);
  ASSERT_EQ(loops.size(), 2u);
  EXPECT_EQ(loops[0].vertices.size(), 80u);  // the square's 4 x 20 edges
  EXPECT_EQ(loops[1].vertices.size(), 32u);  // the hole: 4 x 8 cells
  EXPECT_EQ(loops[0].vertices.front(), 0);   // starts at its smallest vertex
  expectLoopsFollowBoundaryEdges(annulus, loops);
  EXPECT_TRUE(core::boundaryLoops(icosphere(2)).empty());
}

TEST(Geodesic, BoundaryLoopsOfAnOpenHeadIncludeMouthAndEyes) {
  core::HeadShape shape;
  shape.mouth_open = 0.04;
  const core::SyntheticHead head = core::generateHead(shape);
  const auto loops = core::boundaryLoops(head.mesh);
  ASSERT_GE(loops.size(), 4u);  // rim, mouth, two eyes
  expectLoopsFollowBoundaryEdges(head.mesh, loops);
  // The mouth loop contains the vertices nearest the inner lip landmarks.
  auto lengthOf = [&](const std::vector<int>& loop) {
    double s = 0.0;
    for (std::size_t i = 0; i < loop.size(); ++i) {
      s += (head.mesh.positions.row(loop[i]) - head.mesh.positions.row(loop[(i + 1) % loop.size()])).norm();
    }
    return s;
  };
  for (std::size_t i = 0; i < loops.size(); ++i) {
    EXPECT_NEAR(loops[i].length, lengthOf(loops[i].vertices), 1e-12);
    if (i > 0) {
      EXPECT_GE(loops[i - 1].length, loops[i].length);
    }
  }
  const int upper = head.landmarks.indexOf("mouth_inner_2");
  const auto& lu = head.landmarks.landmarks[static_cast<std::size_t>(upper)];
  const Eigen::Vector3d lip = pointOf(head.mesh, {lu.face, lu.barycentric});
  int nearest_loop = -1;
  double nearest = std::numeric_limits<double>::infinity();
  for (std::size_t l = 0; l < loops.size(); ++l) {
    for (int v : loops[l].vertices) {
      const double dist = (head.mesh.positions.row(v).transpose() - lip).norm();
      if (dist < nearest) {
        nearest = dist;
        nearest_loop = static_cast<int>(l);
      }
    }
  }
  // Rim first, then the mouth (longer than either eye).
  EXPECT_EQ(nearest_loop, 1);
}

}  // namespace
