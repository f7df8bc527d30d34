#include "core/transfer/transfer_quality.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/base/parallel.h"

namespace core {

namespace {

// How far vertex v's delta is from its nearest neighbour's, over the
// largest motion of its closed ring (|delta|^2 in `motion2`), when that is
// over `ratio` and the ring moves at least `floor2` (squared); else -1.
// Most vertices have a neighbour within reach of the two's own motion,
// which the ring's only exceeds: that neighbour ends the test.
double outlierScore(const Eigen::MatrixX3d& deltas, const Eigen::VectorXd& motion2, const VertexAdjacency& adjacency,
                    Eigen::Index v, double ratio, double floor2) {
  const int begin = adjacency.offsets[static_cast<std::size_t>(v)], end = adjacency.offsets[static_cast<std::size_t>(v) + 1];
  if (begin == end) return -1.0;
  const double ratio2 = ratio * ratio;
  const Eigen::RowVector3d d = deltas.row(v);
  for (int k = begin; k < end; ++k) {
    const int u = adjacency.indices[static_cast<std::size_t>(k)];
    if ((d - deltas.row(u)).squaredNorm() <= ratio2 * std::max(motion2(v), motion2(u))) return -1.0;
  }
  double ring2 = motion2(v), nearest2 = std::numeric_limits<double>::infinity();
  for (int k = begin; k < end; ++k) {
    const int u = adjacency.indices[static_cast<std::size_t>(k)];
    ring2 = std::max(ring2, motion2(u));
    nearest2 = std::min(nearest2, (d - deltas.row(u)).squaredNorm());
  }
  if (ring2 < floor2 || !(ring2 > 0.0) || nearest2 <= ratio2 * ring2) return -1.0;
  return std::sqrt(nearest2 / ring2);
}

// Scratch space of shapeOutliers, kept across the shapes one thread checks.
struct OutlierScratch {
  Eigen::VectorXd motion2;
  std::vector<unsigned> stamp;  // == round: the vertex is a candidate this round
  unsigned round = 0;
  std::vector<int> candidates;
};

// One shape's outliers: (vertex, score), ascending, for every vertex scoring
// over the ratio (outlierScore), its floor from the shape's largest motion.
// Only the vertices moving at least the floor and their neighbours can
// score: a shape that moves a part of the face costs that part.
std::vector<std::pair<int, double>> shapeOutliers(const Eigen::MatrixX3d& deltas, const VertexAdjacency& adjacency,
                                                  const QualityOptions& options, OutlierScratch& scratch) {
  std::vector<std::pair<int, double>> out;
  const Eigen::Index nv = deltas.rows();
  if (nv == 0) return out;
  Eigen::VectorXd& motion2 = scratch.motion2;
  motion2 = deltas.col(0).cwiseAbs2() + deltas.col(1).cwiseAbs2() + deltas.col(2).cwiseAbs2();
  const double floor2 = options.min_motion * options.min_motion * motion2.maxCoeff();
  if (scratch.stamp.size() != static_cast<std::size_t>(nv) || ++scratch.round == 0) {
    scratch.stamp.assign(static_cast<std::size_t>(nv), 0);
    scratch.round = 1;
  }
  std::vector<int>& candidates = scratch.candidates;
  candidates.clear();
  auto judge = [&](int v) {
    if (scratch.stamp[static_cast<std::size_t>(v)] == scratch.round) return;
    scratch.stamp[static_cast<std::size_t>(v)] = scratch.round;
    candidates.push_back(v);
  };
  for (Eigen::Index v = 0; v < nv; ++v) {
    if (!(motion2(v) >= floor2)) continue;
    judge(static_cast<int>(v));
    for (int k = adjacency.offsets[static_cast<std::size_t>(v)]; k < adjacency.offsets[static_cast<std::size_t>(v) + 1]; ++k) {
      judge(adjacency.indices[static_cast<std::size_t>(k)]);
    }
  }
  for (const int v : candidates) {
    const double score = outlierScore(deltas, motion2, adjacency, v, options.outlier_ratio, floor2);
    if (score > options.outlier_ratio) out.emplace_back(v, score);
  }
  std::sort(out.begin(), out.end());
  return out;
}

// The sharpest the source shape is itself where `at` lies: the largest
// outlierScore (any ratio) over the face's corners and their rings.
// `motion2`: the shape's |delta|^2, `floor2` its floor (shapeOutliers).
double sourceSharpnessAt(const Eigen::MatrixX3d& deltas, const Eigen::VectorXd& motion2, double floor2,
                         const SurfacePoint& at, const QualitySource& source) {
  if (!at.found()) return 0.0;
  double sharpest = 0.0;
  auto judge = [&](int v) { sharpest = std::max(sharpest, outlierScore(deltas, motion2, source.adjacency, v, 0.0, floor2)); };
  for (int c = 0; c < 3; ++c) {
    const int v = source.triangles(at.face, c);
    judge(v);
    for (int k = source.adjacency.offsets[static_cast<std::size_t>(v)]; k < source.adjacency.offsets[static_cast<std::size_t>(v) + 1]; ++k) {
      judge(source.adjacency.indices[static_cast<std::size_t>(k)]);
    }
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

QualityReport checkTransferQuality(const Mesh& target, const VertexAdjacency& target_adjacency,
                                   const std::vector<MorphTarget>& shapes, const TargetLocations& locations,
                                   const std::vector<int>& target_sides, const QualitySource& source,
                                   const QualityOptions& options) {
  QualityReport report;
  const Eigen::Index nv = target.vertexCount();
  report.per_vertex = Eigen::VectorXd::Zero(nv);
  const bool located = locations.on_source.size() == static_cast<std::size_t>(nv);
  std::vector<std::vector<std::pair<int, double>>> found(shapes.size());
  parallelFor(static_cast<std::ptrdiff_t>(shapes.size()), [&](std::ptrdiff_t begin, std::ptrdiff_t end) {
    OutlierScratch scratch;
    for (std::ptrdiff_t k = begin; k < end; ++k) {
      const Eigen::MatrixX3d& deltas = shapes[static_cast<std::size_t>(k)].position_deltas;
      if (deltas.rows() != nv) continue;
      auto& outliers = found[static_cast<std::size_t>(k)];
      outliers = shapeOutliers(deltas, target_adjacency, options, scratch);
      // What the rig's own shape does there is not the transfer's fault.
      if (outliers.empty() || !located || static_cast<std::size_t>(k) >= source.shapes.size()) continue;
      const Eigen::MatrixX3d& own = source.shapes[static_cast<std::size_t>(k)].position_deltas;
      if (own.rows() == 0) continue;
      const Eigen::VectorXd motion2 = own.rowwise().squaredNorm();
      const double floor2 = options.min_motion * options.min_motion * motion2.maxCoeff();
      std::erase_if(outliers, [&](const std::pair<int, double>& o) {
        const SurfacePoint& at = locations.on_source[static_cast<std::size_t>(o.first)];
        return o.second <= options.source_factor * sourceSharpnessAt(own, motion2, floor2, at, source);
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
