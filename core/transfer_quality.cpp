#include "core/transfer_quality.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/parallel.h"

namespace core {

namespace {

// One shape's outliers: (vertex, score) for every vertex over `ratio`.
// Only rings that move are judged: a vertex is visited when it or a
// neighbour moves at least `floor`, so a sparse shape costs its moving part.
std::vector<std::pair<int, double>> shapeOutliers(const Eigen::MatrixX3d& deltas, const VertexAdjacency& adjacency,
                                                  double ratio, const QualityOptions& options) {
  std::vector<std::pair<int, double>> out;
  const Eigen::Index nv = deltas.rows();
  if (nv == 0) return out;
  const Eigen::VectorXd motion = deltas.rowwise().norm();
  const double largest = motion.maxCoeff();
  if (!(largest > 0.0)) return out;
  const double floor = options.min_motion * largest;
  std::vector<char> judged(static_cast<std::size_t>(nv), 0);
  for (Eigen::Index v = 0; v < nv; ++v) {
    if (motion(v) < floor) continue;
    judged[static_cast<std::size_t>(v)] = 1;
    for (int k = adjacency.offsets[static_cast<std::size_t>(v)]; k < adjacency.offsets[static_cast<std::size_t>(v) + 1]; ++k) {
      judged[static_cast<std::size_t>(adjacency.indices[static_cast<std::size_t>(k)])] = 1;
    }
  }
  for (Eigen::Index v = 0; v < nv; ++v) {
    const int begin = adjacency.offsets[static_cast<std::size_t>(v)], end = adjacency.offsets[static_cast<std::size_t>(v) + 1];
    if (!judged[static_cast<std::size_t>(v)] || end == begin) continue;
    double ring = motion(v), nearest = std::numeric_limits<double>::infinity();
    for (int k = begin; k < end; ++k) {
      const int u = adjacency.indices[static_cast<std::size_t>(k)];
      nearest = std::min(nearest, (deltas.row(v) - deltas.row(u)).squaredNorm());
      ring = std::max(ring, motion(u));
    }
    const double score = std::sqrt(nearest) / ring;
    if (score > ratio) out.emplace_back(static_cast<int>(v), score);
  }
  return out;
}

// The sharpest the source shape `sharp` (sorted by vertex) is at the face
// `at` lies on: over its corners and their rings.
double sourceSharpnessAt(const std::vector<std::pair<int, double>>& sharp, const SurfacePoint& at,
                         const QualitySource& source) {
  if (sharp.empty() || !at.found()) return 0.0;
  auto of = [&](int v) {
    const auto it = std::lower_bound(sharp.begin(), sharp.end(), std::make_pair(v, -1.0));
    return it != sharp.end() && it->first == v ? it->second : 0.0;
  };
  double sharpest = 0.0;
  for (int c = 0; c < 3; ++c) {
    const int v = source.triangles(at.face, c);
    sharpest = std::max(sharpest, of(v));
    const auto begin = source.adjacency.offsets[static_cast<std::size_t>(v)], end = source.adjacency.offsets[static_cast<std::size_t>(v) + 1];
    for (int k = begin; k < end; ++k) sharpest = std::max(sharpest, of(source.adjacency.indices[static_cast<std::size_t>(k)]));
  }
  return sharpest;
}

// A target vertex on side `side` of an opening located on a source face
// whose corners are all on sides of openings, none of them its own: on the
// other lip or lid (a face touching the corners' band or the skin beyond
// belongs to both, as for the matching's filter, sideFaceSets).
bool locatedAcross(int side, const SurfacePoint& at, const std::vector<int>& source_sides,
                   const Eigen::MatrixX3i& source_triangles) {
  if (side < 0 || !at.found()) return false;
  for (int c = 0; c < 3; ++c) {
    const int s = source_sides[static_cast<std::size_t>(source_triangles(at.face, c))];
    if (s < 0 || s == side) return false;
  }
  return true;
}

}  // namespace

std::string QualityReport::summary() const {
  std::string text;
  for (const ShapeOutliers& s : shapes) {
    text += (text.empty() ? "" : ", ") + s.shape + " (" + std::to_string(s.vertices) +
            (s.vertices == 1 ? " vertex)" : " vertices)");
  }
  if (crossed_vertices > 0) {
    text += (text.empty() ? "" : "; ") + std::to_string(crossed_vertices) +
            (crossed_vertices == 1 ? " vertex" : " vertices") + " located across an opening (the other lip or lid)";
    for (std::size_t k = 0; k < crossed_shapes.size(); ++k) {
      text += (k == 0 ? ", moving in " : ", ") + crossed_shapes[k].shape + " (" +
              std::to_string(crossed_shapes[k].vertices) + ")";
    }
  }
  return text;
}

std::size_t ShapeSharpness::memoryBytes() const {
  std::size_t bytes = per_shape.capacity() * sizeof(per_shape[0]);
  for (const auto& s : per_shape) bytes += s.capacity() * sizeof(s[0]);
  return bytes;
}

ShapeSharpness measureShapeSharpness(const std::vector<MorphTarget>& shapes, const VertexAdjacency& adjacency,
                                     const QualityOptions& options) {
  ShapeSharpness out;
  out.per_shape.resize(shapes.size());
  const double ratio = options.source_factor > 0.0 ? options.outlier_ratio / options.source_factor : options.outlier_ratio;
  parallelFor(static_cast<std::ptrdiff_t>(shapes.size()), options.threads, [&](std::ptrdiff_t begin, std::ptrdiff_t end) {
    for (std::ptrdiff_t k = begin; k < end; ++k) {
      out.per_shape[static_cast<std::size_t>(k)] = shapeOutliers(shapes[static_cast<std::size_t>(k)].position_deltas, adjacency, ratio, options);
    }
  }, 1);
  return out;
}

QualityReport checkTransferQuality(const Mesh& target, const std::vector<MorphTarget>& shapes,
                                   const TargetLocations& locations, const std::vector<int>& target_sides,
                                   const QualitySource& source, const QualityOptions& options) {
  QualityReport report;
  const Eigen::Index nv = target.vertexCount();
  report.per_vertex = Eigen::VectorXd::Zero(nv);
  const VertexAdjacency adjacency = vertexAdjacency(target.triangles, nv);
  const bool located = locations.on_source.size() == static_cast<std::size_t>(nv);
  std::vector<std::vector<std::pair<int, double>>> found(shapes.size());
  parallelFor(static_cast<std::ptrdiff_t>(shapes.size()), options.threads, [&](std::ptrdiff_t begin, std::ptrdiff_t end) {
    for (std::ptrdiff_t k = begin; k < end; ++k) {
      const Eigen::MatrixX3d& deltas = shapes[static_cast<std::size_t>(k)].position_deltas;
      if (deltas.rows() != nv) continue;
      auto& outliers = found[static_cast<std::size_t>(k)];
      outliers = shapeOutliers(deltas, adjacency, options.outlier_ratio, options);
      // What the rig's own shape does there is not the transfer's fault.
      if (!located || static_cast<std::size_t>(k) >= source.sharpness.per_shape.size()) continue;
      const auto& sharp = source.sharpness.per_shape[static_cast<std::size_t>(k)];
      std::erase_if(outliers, [&](const std::pair<int, double>& o) {
        return o.second <= options.source_factor *
                               sourceSharpnessAt(sharp, locations.on_source[static_cast<std::size_t>(o.first)], source);
      });
    }
  }, 1);
  for (std::size_t k = 0; k < shapes.size(); ++k) {
    if (found[k].empty()) continue;
    ShapeOutliers entry{shapes[k].name, static_cast<int>(found[k].size()), 0.0};
    for (const auto& [v, score] : found[k]) {
      entry.worst = std::max(entry.worst, score);
      report.per_vertex(v) += 1.0;
      report.worst.push_back({v, shapes[k].name, score});
    }
    report.shape_outliers += entry.vertices;
    report.shapes.push_back(std::move(entry));
  }
  const bool sided = static_cast<Eigen::Index>(target_sides.size()) == nv && !source.sides.empty() && located;
  std::vector<int> crossed;
  for (Eigen::Index v = 0; sided && v < nv; ++v) {
    if (!locatedAcross(target_sides[static_cast<std::size_t>(v)], locations.on_source[static_cast<std::size_t>(v)],
                       source.sides, source.triangles)) {
      continue;
    }
    ++report.crossed_vertices;
    report.per_vertex(v) += 1.0;
    report.worst.push_back({static_cast<int>(v), "", 1.0});
    crossed.push_back(static_cast<int>(v));
  }
  // The shapes the crossed vertices move in: they took the other side's motion.
  for (const MorphTarget& shape : shapes) {
    if (crossed.empty() || shape.position_deltas.rows() != nv) break;
    const double largest = shape.position_deltas.rowwise().norm().maxCoeff();
    ShapeOutliers entry{shape.name, 0, 0.0};
    for (const int v : crossed) {
      const double motion = shape.position_deltas.row(v).norm();
      if (!(largest > 0.0) || motion < options.min_motion * largest) continue;
      ++entry.vertices;
      entry.worst = std::max(entry.worst, motion / largest);
    }
    if (entry.vertices > 0) report.crossed_shapes.push_back(std::move(entry));
  }
  std::stable_sort(report.worst.begin(), report.worst.end(),
                   [](const QualityVertex& a, const QualityVertex& b) { return a.score > b.score; });
  if (report.worst.size() > static_cast<std::size_t>(std::max(0, options.worst_count))) {
    report.worst.resize(static_cast<std::size_t>(std::max(0, options.worst_count)));
  }
  return report;
}

}  // namespace core
