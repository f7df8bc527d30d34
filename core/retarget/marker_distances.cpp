// Marker-to-vertex distances for mocap retargeting (core/retarget/retarget.h):
// Euclidean, geodesic (heat method, core/solve/geodesic.cpp) and the hybrid of
// papers 002 (Ramos Carretero 2019, "AnimFace") algorithms 5.3-5.4 (hybrid
// weights and blending; here with automatic regions around the mesh's hole
// loops). Depends only on (mesh, markers, distance options): the service
// caches the result.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <numeric>

#include "core/base/parallel.h"
#include "core/base/timing.h"
#include "core/retarget/retarget.h"
#include "core/solve/geodesic.h"

namespace core {

namespace {

constexpr double kHybridWeightCutoff = 1e-3;  // below: pure Euclidean (paper: "when the weight is 0")

// Marker locations as geodesic sources: face landmarks as they are, vertex
// landmarks on a triangle using the vertex, position landmarks snapped to the
// nearest vertex.
Result<std::vector<SurfacePoint>> markerSurfacePoints(const Mesh& mesh, const LandmarkSet& markers,
                                                      const Eigen::MatrixX3d& positions, const std::string& label) {
  std::vector<int> vertex(markers.landmarks.size(), -1);
  std::vector<SurfacePoint> points(markers.landmarks.size());
  for (std::size_t i = 0; i < markers.landmarks.size(); ++i) {
    const Landmark& lm = markers.landmarks[i];
    if (lm.kind == LandmarkKind::kFace) {
      points[i].face = lm.face;
      points[i].barycentric = lm.barycentric;
    } else if (lm.kind == LandmarkKind::kVertex) {
      vertex[i] = lm.vertex;
    } else {
      Eigen::Index best = 0;
      (mesh.positions.rowwise() - positions.row(static_cast<Eigen::Index>(i))).rowwise().squaredNorm().minCoeff(&best);
      vertex[i] = static_cast<int>(best);
    }
  }
  for (Eigen::Index f = 0; f < mesh.triangles.rows(); ++f) {
    for (std::size_t i = 0; i < vertex.size(); ++i) {
      if (vertex[i] < 0 || points[i].face >= 0) continue;
      for (int k = 0; k < 3; ++k) {
        if (mesh.triangles(f, k) == vertex[i]) {
          points[i].face = static_cast<int>(f);
          points[i].barycentric = Eigen::Vector3d::Unit(k);
        }
      }
    }
  }
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (points[i].face < 0) {
      return makeError(ErrorCode::kInvalidLandmarks,
                       label + ": marker " + markers.landmarks[i].name + " is on a vertex used by no triangle");
    }
  }
  return points;
}

// #V by #M Euclidean vertex-to-marker distances.
Eigen::MatrixXd euclideanVertexMarker(const Eigen::MatrixX3d& vertices, const Eigen::MatrixX3d& markers) {
  Eigen::MatrixXd d(vertices.rows(), markers.rows());
  parallelFor(vertices.rows(), [&](std::ptrdiff_t begin, std::ptrdiff_t end) {
    for (Eigen::Index m = 0; m < markers.rows(); ++m) {
      const Eigen::RowVector3d p = markers.row(m);
      for (std::ptrdiff_t v = begin; v < end; ++v) d(v, m) = (vertices.row(v) - p).norm();
    }
  }, 1024);
  return d;
}

Eigen::MatrixXd euclideanMarkerMarker(const Eigen::MatrixX3d& markers) {
  const Eigen::Index m = markers.rows();
  Eigen::MatrixXd d(m, m);
  for (Eigen::Index i = 0; i < m; ++i) {
    for (Eigen::Index j = 0; j < m; ++j) d(i, j) = (markers.row(i) - markers.row(j)).norm();
  }
  return d;
}

// A per-vertex quantity (#V by k) at a surface point, barycentrically.
double atPoint(const Eigen::Ref<const Eigen::VectorXd>& values, const Mesh& mesh, const SurfacePoint& p) {
  return interpolateOnFace(values, mesh.triangles, p.face, p.barycentric)(0);
}

// Minimum distance from every vertex to a vertex subset (brute force; the
// subsets are hole loops or user regions, small next to #V).
Eigen::VectorXd distanceToSet(const Eigen::MatrixX3d& positions, const std::vector<int>& set) {
  Eigen::VectorXd d(positions.rows());
  parallelFor(positions.rows(), [&](std::ptrdiff_t begin, std::ptrdiff_t end) {
    for (std::ptrdiff_t v = begin; v < end; ++v) {
      double best = std::numeric_limits<double>::infinity();
      for (int s : set) best = std::min(best, (positions.row(v) - positions.row(s)).squaredNorm());
      d(v) = std::sqrt(best);
    }
  }, 512);
  return d;
}

struct HybridWeights {
  Eigen::VectorXd weight;  // #V in [0, 1]
  std::vector<GeodesicRegion> regions;
  int loops = 0;
};

// Algorithm 5.3 with regions around the feature holes (or the given ones).
Result<HybridWeights> hybridWeights(const Mesh& mesh, const Eigen::MatrixX3d& markers, const HybridOptions& options,
                                    double diagonal, const std::string& label) {
  const Eigen::Index nv = mesh.vertexCount();
  HybridWeights out;
  // Distance of each vertex to the nearest region (0 inside).
  Eigen::VectorXd to_region = Eigen::VectorXd::Constant(nv, std::numeric_limits<double>::infinity());
  if (!options.regions.empty()) {
    for (std::size_t r = 0; r < options.regions.size(); ++r) {
      const auto& region = options.regions[r];
      for (int v : region) {
        if (v < 0 || v >= nv) {
          return makeError(ErrorCode::kInvalidArgument, label + ": geodesic region " + std::to_string(r) +
                                                            " has vertex " + std::to_string(v) + " out of range");
        }
      }
      if (region.empty()) continue;
      to_region = to_region.cwiseMin(distanceToSet(mesh.positions, region));
      GeodesicRegion info;
      info.region_vertices = static_cast<int>(region.size());
      for (int v : region) info.centroid += mesh.positions.row(v).transpose();
      info.centroid /= static_cast<double>(region.size());
      out.regions.push_back(info);
    }
  } else {
    const std::vector<BoundaryLoop> loops = boundaryLoops(mesh);
    out.loops = static_cast<int>(loops.size());
    const Eigen::Vector3d lo = markers.colwise().minCoeff().transpose(), hi = markers.colwise().maxCoeff().transpose();
    const double grow = 0.1 * (hi - lo).norm();
    for (std::size_t l = 1; l < loops.size(); ++l) {  // loops[0], the longest, is the outer rim
      const std::vector<int>& loop = loops[l].vertices;
      if (loop.size() < 3) continue;
      GeodesicRegion info;
      info.loop = static_cast<int>(l);
      info.loop_vertices = static_cast<int>(loop.size());
      for (int v : loop) info.centroid += mesh.positions.row(v).transpose();
      info.centroid /= static_cast<double>(loop.size());
      if ((info.centroid.array() < lo.array() - grow).any() || (info.centroid.array() > hi.array() + grow).any()) continue;
      for (std::size_t a = 0; a < loop.size(); ++a) {
        for (std::size_t b = a + 1; b < loop.size(); ++b) {
          info.extent = std::max(info.extent, (mesh.positions.row(loop[a]) - mesh.positions.row(loop[b])).norm());
        }
      }
      const Eigen::VectorXd d = (distanceToSet(mesh.positions, loop).array() -
                                 options.region_factor * info.extent).cwiseMax(0.0);
      info.region_vertices = static_cast<int>((d.array() == 0.0).count());
      to_region = to_region.cwiseMin(d);
      out.regions.push_back(info);
    }
  }
  const double gamma = options.blend_gamma > 0.0 ? options.blend_gamma : 0.02 * diagonal;
  out.weight = to_region.unaryExpr([gamma](double d) {
    const double w = std::exp(-d / gamma);
    return w < kHybridWeightCutoff ? 0.0 : w;
  });
  return out;
}

// Algorithm 5.4: geodesic * w + Euclidean * (1 - w); pure Euclidean where w is
// 0 or the surface path does not exist.
double blendDistance(double w, double geodesic, double euclidean) {
  if (w <= 0.0 || !std::isfinite(geodesic)) return euclidean;
  return w * geodesic + (1.0 - w) * euclidean;
}

}  // namespace

const char* distanceMethodName(DistanceMethod method) {
  switch (method) {
    case DistanceMethod::kEuclidean: return "euclidean";
    case DistanceMethod::kGeodesic: return "geodesic";
    case DistanceMethod::kHybrid: return "hybrid";
  }
  return "unknown";
}

std::size_t MarkerDistances::memoryBytes() const {
  std::size_t bytes = sizeof(*this);
  for (const auto& n : marker_names) bytes += n.capacity();
  bytes += sizeof(double) * static_cast<std::size_t>(marker_positions.size() + marker_marker.size() + vertex_marker.size() +
                                                    geodesic_weight.size());
  return bytes + regions.size() * sizeof(GeodesicRegion);
}

Result<MarkerDistances> computeMarkerDistances(const Mesh& mesh, const LandmarkSet& markers, const std::string& label,
                                               const MarkerDistanceOptions& options) {
  const auto t0 = Clock::now();
  if (auto ok = validateSurfaceMesh(mesh, label); !ok) return ok.error();
  if (markers.landmarks.size() < 4) {
    return makeError(ErrorCode::kInvalidLandmarks,
                     label + ": " + std::to_string(markers.landmarks.size()) + " markers (at least 4 needed)");
  }
  auto positions = resolveLandmarks(markers, mesh, label);
  if (!positions) return positions.error();

  MarkerDistances out;
  out.method = options.method;
  out.mesh_diagonal = boundingBoxDiagonal(mesh.positions);
  out.marker_positions = *positions;
  for (const Landmark& lm : markers.landmarks) out.marker_names.push_back(lm.name);
  const Eigen::Index nm = out.marker_positions.rows();

  const Eigen::MatrixXd euclidean_mm = euclideanMarkerMarker(out.marker_positions);
  Eigen::MatrixXd euclidean_vm = euclideanVertexMarker(mesh.positions, out.marker_positions);
  if (options.method == DistanceMethod::kEuclidean) {
    out.marker_marker = euclidean_mm;
    out.vertex_marker = std::move(euclidean_vm);
    out.compute_ms = msSince(t0);
    return out;
  }

  auto points = markerSurfacePoints(mesh, markers, out.marker_positions, label);
  if (!points) return points.error();
  auto solver = GeodesicSolver::create(mesh, label, options.geodesic);
  if (!solver) return solver.error();
  const Eigen::MatrixXd geodesic_vm = solver->distances(*points).transpose();  // #V by #M
  // Marker to marker: the distance field of marker i read at marker j's point,
  // symmetrised (the heat method is not exactly symmetric), zero diagonal.
  Eigen::MatrixXd geodesic_mm(nm, nm);
  for (Eigen::Index i = 0; i < nm; ++i) {
    for (Eigen::Index j = 0; j < nm; ++j) {
      geodesic_mm(i, j) = atPoint(geodesic_vm.col(i), mesh, (*points)[static_cast<std::size_t>(j)]);
    }
  }
  geodesic_mm = (0.5 * (geodesic_mm + geodesic_mm.transpose())).eval();
  geodesic_mm.diagonal().setZero();

  if (options.method == DistanceMethod::kGeodesic) {
    for (Eigen::Index i = 0; i < nm; ++i) {
      for (Eigen::Index j = 0; j < nm; ++j) {
        if (!std::isfinite(geodesic_mm(i, j))) {
          return makeError(ErrorCode::kInvalidLandmarks, label + ": markers " + out.marker_names[static_cast<std::size_t>(i)] +
                                                             " and " + out.marker_names[static_cast<std::size_t>(j)] +
                                                             " are on parts of the mesh not connected by its surface");
        }
      }
    }
    out.marker_marker = geodesic_mm;
    out.vertex_marker = geodesic_vm;
    out.compute_ms = msSince(t0);
    return out;
  }

  auto hybrid = hybridWeights(mesh, out.marker_positions, options.hybrid, out.mesh_diagonal, label);
  if (!hybrid) return hybrid.error();
  out.geodesic_weight = std::move(hybrid->weight);
  out.regions = std::move(hybrid->regions);
  out.boundary_loops = hybrid->loops;
  Eigen::VectorXd marker_weight(nm);
  for (Eigen::Index i = 0; i < nm; ++i) marker_weight(i) = atPoint(out.geodesic_weight, mesh, (*points)[static_cast<std::size_t>(i)]);
  out.marker_marker.resize(nm, nm);
  for (Eigen::Index i = 0; i < nm; ++i) {
    for (Eigen::Index j = 0; j < nm; ++j) {
      out.marker_marker(i, j) = blendDistance(0.5 * (marker_weight(i) + marker_weight(j)), geodesic_mm(i, j), euclidean_mm(i, j));
    }
  }
  out.vertex_marker = std::move(euclidean_vm);
  parallelFor(mesh.vertexCount(), [&](std::ptrdiff_t begin, std::ptrdiff_t end) {
    for (Eigen::Index m = 0; m < nm; ++m) {
      for (std::ptrdiff_t v = begin; v < end; ++v) {
        out.vertex_marker(v, m) = blendDistance(out.geodesic_weight(v), geodesic_vm(v, m), out.vertex_marker(v, m));
      }
    }
  }, 1024);
  out.compute_ms = msSince(t0);
  return out;
}

}  // namespace core
