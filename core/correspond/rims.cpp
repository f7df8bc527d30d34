#include "core/correspond/rims.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>
#include <vector>

namespace core {

namespace {

// Closest point of p on the closed polyline `loop` among the edges (a, b)
// that `accept` allows: the edge (from loop[edge] to the next vertex), the
// parameter t in [0, 1] from its start, the point and its squared distance
// (edge -1 and infinite distance when no edge is accepted).
struct LoopPoint {
  int edge = -1;
  double t = 0.0;
  Eigen::Vector3d point = Eigen::Vector3d::Zero();
  double sq_distance = std::numeric_limits<double>::infinity();
};
template <class Accept>
LoopPoint closestOnLoop(const Eigen::Vector3d& p, const Eigen::MatrixX3d& positions, const std::vector<int>& loop,
                        Accept accept) {
  LoopPoint best;
  const std::size_t n = loop.size();
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d a = positions.row(loop[i]), b = positions.row(loop[(i + 1) % n]);
    const Eigen::Vector3d ab = b - a;
    if (!accept(ab)) continue;
    const double len2 = ab.squaredNorm();
    const double t = len2 > 0.0 ? std::clamp((p - a).dot(ab) / len2, 0.0, 1.0) : 0.0;
    const Eigen::Vector3d q = a + t * ab;
    const double d2 = (q - p).squaredNorm();
    if (d2 < best.sq_distance) best = {static_cast<int>(i), t, q, d2};
  }
  return best;
}
constexpr auto kAnyEdge = [](const Eigen::Vector3d&) { return true; };

// A closed polyline parametrised by arc length.
class LoopArc {
 public:
  LoopArc(const std::vector<int>& loop, const Eigen::MatrixX3d& positions) : loop_(loop), positions_(positions) {
    cumulative_.reserve(loop.size() + 1);
    cumulative_.push_back(0.0);
    for (std::size_t i = 0; i < loop.size(); ++i) {
      cumulative_.push_back(cumulative_.back() +
                            (positions.row(loop[(i + 1) % loop.size()]) - positions.row(loop[i])).norm());
    }
  }
  // Edge index and parameter on it at `fraction` (wrapped into [0, 1)) of the length.
  std::pair<std::size_t, double> at(double fraction) const {
    const double length = cumulative_.back();
    const double s = (fraction - std::floor(fraction)) * length;
    const auto after = std::upper_bound(cumulative_.begin(), cumulative_.end(), s) - cumulative_.begin();
    const std::size_t edge = std::min(loop_.size() - 1, static_cast<std::size_t>(std::max<std::ptrdiff_t>(0, after - 1)));
    const double span = cumulative_[edge + 1] - cumulative_[edge];
    return {edge, span > 0.0 ? std::clamp((s - cumulative_[edge]) / span, 0.0, 1.0) : 0.0};
  }
  Eigen::RowVector3d point(const Eigen::MatrixX3d& positions, std::pair<std::size_t, double> where) const {
    const auto [edge, t] = where;
    return (1.0 - t) * positions.row(loop_[edge]) + t * positions.row(loop_[(edge + 1) % loop_.size()]);
  }
  Eigen::RowVector3d point(double fraction) const { return point(positions_, at(fraction)); }

 private:
  const std::vector<int>& loop_;
  const Eigen::MatrixX3d& positions_;
  std::vector<double> cumulative_;
};

// Mean distance from (at most 64 evenly spaced) vertices of loop `from` to the polyline `to`.
double meanDistanceToLoop(const Eigen::MatrixX3d& from_positions, const std::vector<int>& from,
                          const Eigen::MatrixX3d& to_positions, const std::vector<int>& to) {
  const std::size_t stride = std::max<std::size_t>(1, from.size() / 64);
  double sum = 0.0;
  int count = 0;
  for (std::size_t i = 0; i < from.size(); i += stride) {
    const Eigen::Vector3d p = from_positions.row(from[i]).transpose();
    sum += std::sqrt(closestOnLoop(p, to_positions, to, kAnyEdge).sq_distance);
    ++count;
  }
  return count > 0 ? sum / count : std::numeric_limits<double>::infinity();
}

}  // namespace

std::vector<Rim> meshRims(const Mesh& mesh, const std::vector<int>& representative) {
  std::vector<Rim> rims = boundaryLoops(representative.empty() ? mesh : weldedTopology(mesh, representative));
  std::erase_if(rims, [](const Rim& rim) { return !rim.closed || rim.vertices.size() < 3; });
  return rims;
}

std::vector<int> matchRims(const std::vector<Rim>& source_rims, const Eigen::MatrixX3d& warped_source,
                           const std::vector<Rim>& target_rims, const Eigen::MatrixX3d& target_positions,
                           const RimMatchOptions& options) {
  // Rims come longest first: the candidates are the first max_rims of each side.
  const std::size_t limit = static_cast<std::size_t>(std::max(0, options.max_rims));
  const std::size_t ns = std::min(source_rims.size(), limit), nt = std::min(target_rims.size(), limit);
  constexpr double kNone = std::numeric_limits<double>::infinity();
  std::vector<double> mismatch(ns * nt, kNone);
  for (std::size_t s = 0; s < ns; ++s) {
    const std::vector<int>& loop = source_rims[s].vertices;
    double warped_length = 0.0;
    Eigen::RowVector3d centre = Eigen::RowVector3d::Zero();
    for (std::size_t i = 0; i < loop.size(); ++i) {
      warped_length += (warped_source.row(loop[i]) - warped_source.row(loop[(i + 1) % loop.size()])).norm();
      centre += warped_source.row(loop[i]);
    }
    centre /= static_cast<double>(loop.size());
    double radius2 = 0.0;
    for (int v : loop) radius2 += (warped_source.row(v) - centre).squaredNorm();
    const double radius = std::sqrt(radius2 / static_cast<double>(loop.size()));
    if (!(radius > 0.0)) continue;
    for (std::size_t t = 0; t < nt; ++t) {
      const double ratio = target_rims[t].length / warped_length;
      if (!(ratio <= options.max_length_ratio && ratio * options.max_length_ratio >= 1.0)) continue;
      const double there = meanDistanceToLoop(warped_source, loop, target_positions, target_rims[t].vertices);
      if (there > options.max_mismatch * radius) continue;
      const double back = meanDistanceToLoop(target_positions, target_rims[t].vertices, warped_source, loop);
      const double m = std::max(there, back) / radius;
      if (m <= options.max_mismatch) mismatch[s * nt + t] = m;
    }
  }
  std::vector<int> match(source_rims.size(), -1);
  for (std::size_t s = 0; s < ns; ++s) {
    const auto row = mismatch.begin() + static_cast<std::ptrdiff_t>(s * nt);
    const auto best = std::min_element(row, row + static_cast<std::ptrdiff_t>(nt));
    if (nt == 0 || *best == kNone) continue;
    const auto t = static_cast<std::size_t>(best - row);
    // Mutual: no other source rim fits this target rim better.
    bool mutual = true;
    for (std::size_t o = 0; o < ns; ++o) {
      if (o != s && mismatch[o * nt + t] < *best) mutual = false;
    }
    if (mutual) match[s] = static_cast<int>(t);
  }
  return match;
}

RimVertices rimVertices(const std::vector<Rim>& rims, const Mesh& mesh, const std::vector<int>& representative) {
  RimVertices out;
  out.rim.assign(static_cast<std::size_t>(mesh.vertexCount()), -1);
  out.tangent = Eigen::MatrixX3d::Zero(mesh.vertexCount(), 3);
  for (std::size_t r = 0; r < rims.size(); ++r) {
    const std::vector<int>& loop = rims[r].vertices;
    const std::size_t n = loop.size();
    for (std::size_t i = 0; i < n; ++i) {
      out.rim[static_cast<std::size_t>(loop[i])] = static_cast<int>(r);
      const Eigen::RowVector3d t = mesh.positions.row(loop[(i + 1) % n]) - mesh.positions.row(loop[(i + n - 1) % n]);
      if (t.norm() > 0.0) out.tangent.row(loop[i]) = t.normalized();
    }
  }
  for (std::size_t v = 0; v < representative.size(); ++v) {
    out.rim[v] = out.rim[static_cast<std::size_t>(representative[v])];
    out.tangent.row(static_cast<Eigen::Index>(v)) = out.tangent.row(representative[v]);
  }
  return out;
}

int addNearRimVertices(RimVertices& on_rim, const Mesh& mesh, const std::vector<int>& representative, double fraction) {
  auto pointOf = [&](int v) {
    return static_cast<std::size_t>(representative.empty() ? v : representative[static_cast<std::size_t>(v)]);
  };
  const Eigen::VectorXd edge = meanIncidentEdgeLengths(mesh, representative);
  const std::vector<int> rim = on_rim.rim;  // the rims as given: no chains of near points
  for (Eigen::Index f = 0; f < mesh.triangles.rows(); ++f) {
    for (int k = 0; k < 3; ++k) {
      for (const bool reversed : {false, true}) {
        const int a = mesh.triangles(f, reversed ? (k + 1) % 3 : k), b = mesh.triangles(f, reversed ? k : (k + 1) % 3);
        const std::size_t pb = pointOf(b);
        if (rim[static_cast<std::size_t>(a)] < 0 || rim[pb] >= 0 || on_rim.rim[pb] >= 0) continue;
        if ((mesh.positions.row(a) - mesh.positions.row(b)).norm() >= fraction * edge(a)) continue;
        on_rim.rim[pb] = rim[static_cast<std::size_t>(a)];
        on_rim.tangent.row(static_cast<Eigen::Index>(pb)) = on_rim.tangent.row(a);
      }
    }
  }
  // Copies take their point's (representatives come first in index order).
  int joined = 0;
  for (std::size_t v = 0; v < rim.size(); ++v) {
    const std::size_t p = pointOf(static_cast<int>(v));
    if (rim[v] >= 0 || on_rim.rim[p] < 0) continue;
    on_rim.rim[v] = on_rim.rim[p];
    on_rim.tangent.row(static_cast<Eigen::Index>(v)) = on_rim.tangent.row(static_cast<Eigen::Index>(p));
    ++joined;
  }
  return joined;
}

bool rimNearPoints(const Rim& rim, const Eigen::MatrixX3d& positions, const Eigen::MatrixX3d& points, double distance) {
  for (Eigen::Index i = 0; i < points.rows(); ++i) {
    const Eigen::Vector3d p = points.row(i).transpose();
    if (closestOnLoop(p, positions, rim.vertices, kAnyEdge).sq_distance <= distance * distance) return true;
  }
  return false;
}

RimPairs pairRimPoints(const Rim& source_rim, const Eigen::MatrixX3d& source_positions,
                       const Eigen::MatrixX3d& warped_source, const Rim& target_rim,
                       const Eigen::MatrixX3d& target_positions, int count) {
  RimPairs out;
  if (count <= 0 || source_rim.vertices.size() < 2 || target_rim.vertices.size() < 2) return out;
  const LoopArc source(source_rim.vertices, warped_source), target(target_rim.vertices, target_positions);
  out.source.resize(count, 3);
  Eigen::MatrixX3d warped(count, 3);
  for (int k = 0; k < count; ++k) {
    const auto where = source.at((k + 0.5) / count);
    out.source.row(k) = source.point(source_positions, where);
    warped.row(k) = source.point(warped_source, where);
  }
  // The offset: a search over steps a quarter of the pairs' spacing.
  const int steps = 4 * count;
  double best_cost = std::numeric_limits<double>::infinity();
  double best_offset = 0.0;
  for (int j = 0; j < steps; ++j) {
    const double offset = static_cast<double>(j) / steps;
    double cost = 0.0;
    for (int k = 0; k < count && cost < best_cost; ++k) {
      cost += (warped.row(k) - target.point((k + 0.5) / count + offset)).squaredNorm();
    }
    if (cost < best_cost) best_cost = cost, best_offset = offset;
  }
  out.target.resize(count, 3);
  for (int k = 0; k < count; ++k) out.target.row(k) = target.point((k + 0.5) / count + best_offset);
  return out;
}

SurfacePoint closestPointOnRim(const Eigen::Vector3d& p, const Eigen::Vector3d& tangent, const Rim& rim,
                               const Eigen::MatrixX3d& positions) {
  const LoopPoint q =
      closestOnLoop(p, positions, rim.vertices, [&](const Eigen::Vector3d& edge) { return edge.dot(tangent) > 0.0; });
  SurfacePoint best;
  if (q.edge < 0) return best;
  const auto i = static_cast<std::size_t>(q.edge);
  best.face = rim.faces[i];
  best.barycentric.setZero();
  best.barycentric(rim.corners[i][0]) = 1.0 - q.t;
  best.barycentric(rim.corners[i][1]) = q.t;
  best.point = q.point;
  best.sq_distance = q.sq_distance;
  return best;
}

}  // namespace core
