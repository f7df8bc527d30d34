// ClosestPointIndex throughput: index build and single-threaded queries on
// procedural bumpy UV spheres of radius ~1 (~10k and ~100k triangles; no
// external files). MovingMeshIndex: fit to the sphere moved by a smooth map
// (built at rest once), and batches of near-surface queries on the moved
// sphere against a ClosestPointIndex built for it.
//   closest_point_bench --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
// Query kinds (65,536 queries cycled, random order):
//   0 near: uniform surface samples moved along the face normal by up to
//     +-0.02 (a projection workload; up to ~0.3 median edge on the 10k mesh,
//     ~1 on the 100k mesh);
//   1 box: uniform in the bounding box (mostly inside the sphere, far from it);
//   2 near + normal filter at 60 degrees, query normals = face normal tilted by
//     about 20 degrees on average (some nearby faces are rejected).
#include <cmath>
#include <cstdint>
#include <numbers>
#include <random>
#include <vector>

#include <benchmark/benchmark.h>

#include "core/base/parallel.h"
#include "core/geometry/closest_point.h"
#include "core/geometry/mesh.h"
#include "core/geometry/moving_mesh_index.h"

namespace {

struct BenchMesh {
  Eigen::MatrixX3d positions;
  Eigen::MatrixX3i triangles;
};

// Bumpy UV sphere of radius ~1 with `rings` x 2*rings quads split in two:
// ~4 rings^2 triangles, smaller (and thinner) near the poles.
BenchMesh makeBumpySphere(int rings) {
  const int segments = 2 * rings;
  BenchMesh m;
  m.positions.resize(2 + (rings - 1) * segments, 3);
  auto radius = [](double theta, double phi) {
    return 1.0 + 0.08 * std::sin(5.0 * theta) * std::cos(7.0 * phi) + 0.03 * std::sin(13.0 * phi + 3.0 * theta);
  };
  m.positions.row(0) << 0, 0, radius(0, 0);
  for (int r = 1; r < rings; ++r) {
    const double theta = std::numbers::pi * r / rings;
    for (int s = 0; s < segments; ++s) {
      const double phi = 2.0 * std::numbers::pi * s / segments;
      const double rad = radius(theta, phi);
      m.positions.row(1 + (r - 1) * segments + s) << rad * std::sin(theta) * std::cos(phi),
          rad * std::sin(theta) * std::sin(phi), rad * std::cos(theta);
    }
  }
  const int south = static_cast<int>(m.positions.rows()) - 1;
  m.positions.row(south) << 0, 0, -radius(std::numbers::pi, 0);
  std::vector<Eigen::Vector3i> tris;
  auto vid = [&](int r, int s) { return 1 + (r - 1) * segments + (s % segments); };
  for (int s = 0; s < segments; ++s) tris.push_back({0, vid(1, s), vid(1, s + 1)});
  for (int r = 1; r < rings - 1; ++r) {
    for (int s = 0; s < segments; ++s) {
      tris.push_back({vid(r, s), vid(r + 1, s), vid(r + 1, s + 1)});
      tris.push_back({vid(r, s), vid(r + 1, s + 1), vid(r, s + 1)});
    }
  }
  for (int s = 0; s < segments; ++s) tris.push_back({south, vid(rings - 1, s + 1), vid(rings - 1, s)});
  m.triangles.resize(static_cast<Eigen::Index>(tris.size()), 3);
  for (std::size_t i = 0; i < tris.size(); ++i) m.triangles.row(static_cast<Eigen::Index>(i)) = tris[i].transpose();
  return m;
}

const BenchMesh& meshForSize(int thousands) {
  if (thousands <= 10) {
    static const BenchMesh small = makeBumpySphere(50);  // 9,800 triangles, median edge ~0.06
    return small;
  }
  static const BenchMesh large = makeBumpySphere(158);  // 99,224 triangles, median edge ~0.02
  return large;
}

// Built once per process (the build itself is measured by BM_Build).
const core::ClosestPointIndex& indexForSize(int thousands) {
  if (thousands <= 10) {
    static const core::ClosestPointIndex small(meshForSize(10).positions, meshForSize(10).triangles);
    return small;
  }
  static const core::ClosestPointIndex large(meshForSize(100).positions, meshForSize(100).triangles);
  return large;
}

struct Workload {
  std::vector<Eigen::Vector3d> points;
  std::vector<Eigen::Vector3d> normals;
};

Workload nearSurfaceQueries(const BenchMesh& m, int count, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  std::normal_distribution<double> gauss(0.0, 1.0);
  std::uniform_int_distribution<Eigen::Index> face(0, m.triangles.rows() - 1);
  const Eigen::MatrixX3d normals = core::computeFaceNormals(m.positions, m.triangles);
  Workload w;
  for (int i = 0; i < count; ++i) {
    const Eigen::Index f = face(rng);
    double b1 = u01(rng), b2 = u01(rng);
    if (b1 + b2 > 1.0) b1 = 1.0 - b1, b2 = 1.0 - b2;
    const Eigen::Vector3d a = m.positions.row(m.triangles(f, 0));
    const Eigen::Vector3d b = m.positions.row(m.triangles(f, 1));
    const Eigen::Vector3d c = m.positions.row(m.triangles(f, 2));
    const Eigen::Vector3d n = normals.row(f);
    w.points.push_back(a + b1 * (b - a) + b2 * (c - a) + 0.02 * (2.0 * u01(rng) - 1.0) * n);
    const Eigen::Vector3d tilt(gauss(rng), gauss(rng), gauss(rng));
    w.normals.push_back((n + 0.3 * tilt).normalized());
  }
  return w;
}

Workload boxQueries(const BenchMesh& m, int count, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  const Eigen::Vector3d lo = m.positions.colwise().minCoeff().transpose();
  const Eigen::Vector3d hi = m.positions.colwise().maxCoeff().transpose();
  Workload w;
  for (int i = 0; i < count; ++i) {
    w.points.push_back(lo + Eigen::Vector3d(u01(rng), u01(rng), u01(rng)).cwiseProduct(hi - lo));
  }
  return w;
}

void BM_Build(benchmark::State& state) {
  const BenchMesh& m = meshForSize(static_cast<int>(state.range(0)));
  for (auto _ : state) {
    core::ClosestPointIndex index(m.positions, m.triangles);
    benchmark::DoNotOptimize(index.faceCount());
  }
  state.SetItemsProcessed(state.iterations() * m.triangles.rows());
  const core::ClosestPointIndex index(m.positions, m.triangles);
  state.counters["faces"] = static_cast<double>(index.faceCount());
  state.counters["MB"] = static_cast<double>(index.memoryBytes()) / (1024.0 * 1024.0);
}

enum Kind { kNear = 0, kBox = 1, kNearNormal60 = 2 };

void BM_Query(benchmark::State& state) {
  const BenchMesh& m = meshForSize(static_cast<int>(state.range(0)));
  const auto kind = static_cast<Kind>(state.range(1));
  const core::ClosestPointIndex& index = indexForSize(static_cast<int>(state.range(0)));
  const Workload w = kind == kBox ? boxQueries(m, 1 << 16, 2) : nearSurfaceQueries(m, 1 << 16, 1);
  core::ClosestPointOptions options;
  options.max_normal_angle_deg = 60.0;
  std::size_t i = 0;
  std::int64_t misses = 0;
  for (auto _ : state) {
    const std::size_t k = i++ & ((1u << 16) - 1);
    const core::SurfacePoint p = kind == kNearNormal60
                                     ? index.closestPoint(w.points[k], &w.normals[k], ~std::uint64_t{0}, options)
                                     : index.closestPoint(w.points[k]);
    misses += p.found() ? 0 : 1;
    benchmark::DoNotOptimize(p);
  }
  state.SetItemsProcessed(state.iterations());
  state.counters["not_found"] = static_cast<double>(misses);
}

// The sphere moved by a smooth, non-rigid map (stretched, sheared, bent), as
// a warp carries the rig's surface onto a target.
BenchMesh moved(const BenchMesh& m) {
  BenchMesh out = m;
  for (Eigen::Index v = 0; v < m.positions.rows(); ++v) {
    const double x = m.positions(v, 0), y = m.positions(v, 1), z = m.positions(v, 2);
    out.positions.row(v) << 1.3 * x + 0.2 * std::sin(3.0 * y), y + 0.1 * z * z, 0.8 * z + 0.1 * x;
  }
  return out;
}

void BM_MovingFit(benchmark::State& state) {
  const BenchMesh& m = meshForSize(static_cast<int>(state.range(0)));
  const BenchMesh target = moved(m);
  const core::MovingMeshIndex hierarchy(m.positions, m.triangles);
  for (auto _ : state) {
    const auto fitted = hierarchy.fit(target.positions);
    benchmark::DoNotOptimize(fitted.faceCount());
  }
  state.SetItemsProcessed(state.iterations() * m.triangles.rows());
}

// 4,096 near-surface queries (with the 60-degree normal filter) per
// iteration on the moved sphere; index = 0 ClosestPointIndex, 1 MovingMeshIndex.
void BM_MovedBatch(benchmark::State& state) {
  const BenchMesh& m = meshForSize(static_cast<int>(state.range(0)));
  const BenchMesh target = moved(m);
  const Workload w = nearSurfaceQueries(target, 4096, 3);
  Eigen::MatrixX3d queries(4096, 3);
  core::ClosestPointFilters filters;
  filters.normals.resize(4096, 3);
  for (int i = 0; i < 4096; ++i) {
    queries.row(i) = w.points[static_cast<std::size_t>(i)].transpose();
    filters.normals.row(i) = w.normals[static_cast<std::size_t>(i)].transpose();
  }
  core::ClosestPointOptions options;
  options.max_normal_angle_deg = 60.0;
  const core::ScopedThreadCount options_threads(1);
  const core::ClosestPointIndex index(target.positions, target.triangles);
  const core::MovingMeshIndex hierarchy(m.positions, m.triangles);
  const auto fitted = hierarchy.fit(target.positions);
  for (auto _ : state) {
    const auto found = state.range(1) == 0 ? index.closestPoints(queries, options, filters)
                                           : fitted.closestPoints(queries, options, filters);
    benchmark::DoNotOptimize(found.data());
  }
  state.SetItemsProcessed(state.iterations() * 4096);
}

BENCHMARK(BM_Build)->Arg(10)->Arg(100)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_MovingFit)->Arg(10)->Arg(100)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_MovedBatch)->ArgNames({"ktris", "moving"})->ArgsProduct({{10, 100}, {0, 1}})->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Query)
    ->ArgNames({"ktris", "kind"})
    ->ArgsProduct({{10, 100}, {kNear, kBox, kNearNormal60}})
    ->Unit(benchmark::kNanosecond);

}  // namespace

BENCHMARK_MAIN();
