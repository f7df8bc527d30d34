#include "core/correspond/opening_sides.h"

#include <algorithm>
#include <cassert>
#include <functional>
#include <limits>
#include <queue>
#include <utility>

#include <Eigen/Geometry>

namespace core {

namespace {

constexpr double kUnreached = std::numeric_limits<double>::infinity();

// The copies of each split point (UV seams, hard edges), as CSR by
// representative (empty when every vertex is its own).
struct PointCopies {
  std::vector<int> offsets;  // #V + 1, by representative
  std::vector<int> vertices;
};

PointCopies pointCopies(const std::vector<int>& representative) {
  PointCopies out;
  if (representative.empty()) return out;
  out.offsets.assign(representative.size() + 1, 0);
  for (const int r : representative) ++out.offsets[static_cast<std::size_t>(r) + 1];
  for (std::size_t v = 0; v + 1 < out.offsets.size(); ++v) out.offsets[v + 1] += out.offsets[v];
  out.vertices.resize(representative.size());
  std::vector<int> fill(out.offsets.begin(), out.offsets.end() - 1);
  for (std::size_t v = 0; v < representative.size(); ++v) {
    out.vertices[static_cast<std::size_t>(fill[static_cast<std::size_t>(representative[v])]++)] = static_cast<int>(v);
  }
  return out;
}

// Distances along the mesh's edges from the vertices `seeds` (0 there), up
// to `radius`: vertices beyond it stay unreached. The copies of a split
// point are one point (distance 0 between them), so a UV seam across a lip
// does not cut it. Bounded Dijkstra, so the cost is the zone's, not the
// mesh's; `distance` must be all unreached on entry and `reached` empty, and
// both are left for the caller to read and reset.
void edgeDistances(const VertexAdjacency& adjacency, const RowMatrixX3d& positions,
                   const std::vector<int>& representative, const PointCopies& copies, const std::vector<int>& seeds,
                   double radius, std::vector<double>& distance, std::vector<int>& reached) {
  using Entry = std::pair<double, int>;
  std::priority_queue<Entry, std::vector<Entry>, std::greater<>> queue;
  auto relax = [&](int u, double du) {
    if (du > radius || du >= distance[static_cast<std::size_t>(u)]) return;
    if (distance[static_cast<std::size_t>(u)] == kUnreached) reached.push_back(u);
    distance[static_cast<std::size_t>(u)] = du;
    queue.emplace(du, u);
  };
  for (const int s : seeds) relax(s, 0.0);
  while (!queue.empty()) {
    const auto [d, v] = queue.top();
    queue.pop();
    if (d > distance[static_cast<std::size_t>(v)]) continue;
    if (!representative.empty()) {
      const auto r = static_cast<std::size_t>(representative[static_cast<std::size_t>(v)]);
      for (int k = copies.offsets[r]; k < copies.offsets[r + 1]; ++k) relax(copies.vertices[static_cast<std::size_t>(k)], d);
    }
    for (int k = adjacency.offsets[static_cast<std::size_t>(v)]; k < adjacency.offsets[static_cast<std::size_t>(v) + 1]; ++k) {
      const int u = adjacency.indices[static_cast<std::size_t>(k)];
      relax(u, d + (positions.row(u) - positions.row(v)).norm());
    }
  }
}

// The two vertices of `loop` farthest apart, as positions in it: exactly
// for a rim of a face's size; for a longer one (a scan's ragged border, a
// hostile file) by alternating farthest-point sweeps, so the cost stays
// linear.
std::array<int, 2> farthestApart(const std::vector<int>& loop, const Eigen::MatrixX3d& positions) {
  constexpr std::size_t kExactUpTo = 2048;
  std::array<int, 2> best{0, 0};
  double widest = -1.0;
  auto farthestFrom = [&](std::size_t a) {
    std::size_t far = a;
    double d_far = -1.0;
    for (std::size_t b = 0; b < loop.size(); ++b) {
      const double d = (positions.row(loop[a]) - positions.row(loop[b])).squaredNorm();
      if (d > d_far) {
        d_far = d;
        far = b;
      }
    }
    if (d_far > widest) {
      widest = d_far;
      best = {static_cast<int>(std::min(a, far)), static_cast<int>(std::max(a, far))};
    }
    return far;
  };
  if (loop.size() <= kExactUpTo) {
    for (std::size_t a = 0; a < loop.size(); ++a) farthestFrom(a);
  } else {
    std::size_t a = 0;
    for (int sweep = 0; sweep < 4; ++sweep) a = farthestFrom(a);
  }
  return best;
}

}  // namespace

Opening openingAtCorners(const Rim& rim, int rim_index, const Eigen::MatrixX3d& positions,
                         const Eigen::Matrix<double, 2, 3>& corner_points) {
  Opening opening;
  for (int c = 0; c < 2; ++c) {
    double nearest = kUnreached;
    for (std::size_t i = 0; i < rim.vertices.size(); ++i) {
      const double d = (positions.row(rim.vertices[i]) - corner_points.row(c)).squaredNorm();
      if (d < nearest) {
        nearest = d;
        opening.corners[static_cast<std::size_t>(c)] = static_cast<int>(i);
      }
    }
  }
  if (rim.vertices.empty() || opening.corners[0] == opening.corners[1]) return opening;
  opening.rim = rim_index;
  opening.width = (positions.row(rim.vertices[static_cast<std::size_t>(opening.corners[0])]) -
                   positions.row(rim.vertices[static_cast<std::size_t>(opening.corners[1])]))
                      .norm();
  return opening;
}

std::vector<Opening> findOpenings(const Mesh& mesh, const std::vector<Rim>& rims, const Eigen::MatrixX3d& landmarks,
                                  const OpeningSideOptions& options) {
  std::vector<Opening> openings;
  const double near = options.landmark_distance * boundingBoxDiagonal(mesh.positions);
  for (std::size_t r = 0; r < rims.size() && openings.size() < kMaxOpenings; ++r) {
    const Rim& rim = rims[r];
    if (rim.vertices.size() < 3) continue;
    // Landmarks within `near` of the rim's box only: most are far from most rims.
    Eigen::AlignedBox3d box;
    for (const int v : rim.vertices) box.extend(mesh.positions.row(v).transpose());
    std::vector<Eigen::Index> close;
    for (Eigen::Index l = 0; l < landmarks.rows(); ++l) {
      if (box.exteriorDistance(landmarks.row(l).transpose()) <= near) close.push_back(l);
    }
    bool on_rim = false;
    for (std::size_t i = 0; i < close.size() && !on_rim; ++i) on_rim = rimNearPoints(rim, mesh.positions, landmarks.row(close[i]), near);
    if (!on_rim) continue;
    // The rim's own extent (its two vertices farthest apart) says how far
    // its landmarks may lie.
    const std::array<int, 2> across = farthestApart(rim.vertices, mesh.positions);
    const double widest = (mesh.positions.row(rim.vertices[static_cast<std::size_t>(across[0])]) -
                           mesh.positions.row(rim.vertices[static_cast<std::size_t>(across[1])]))
                              .squaredNorm();
    Eigen::Matrix<double, 2, 3> anchors;
    for (int c = 0; c < 2; ++c) anchors.row(c) = mesh.positions.row(rim.vertices[static_cast<std::size_t>(across[static_cast<std::size_t>(c)])]);
    // The opening's landmarks: the rim vertices nearest the two farthest
    // apart are its corners (a rounded rim's farthest points wander along its
    // ends from one face to another; landmarks are placed where the corners
    // are).
    std::vector<Eigen::Index> own;
    const double zone = options.zone * std::sqrt(widest);
    for (Eigen::Index l = 0; l < landmarks.rows(); ++l) {
      if (box.exteriorDistance(landmarks.row(l).transpose()) <= zone &&
          rimNearPoints(rim, mesh.positions, landmarks.row(l), zone)) {
        own.push_back(l);
      }
    }
    double apart = -1.0;
    for (std::size_t a = 0; a < own.size(); ++a) {
      for (std::size_t b = a + 1; b < own.size(); ++b) {
        const double d = (landmarks.row(own[a]) - landmarks.row(own[b])).squaredNorm();
        if (d > apart) {
          apart = d;
          anchors.row(0) = landmarks.row(own[a]);
          anchors.row(1) = landmarks.row(own[b]);
        }
      }
    }
    const Opening opening = openingAtCorners(rim, static_cast<int>(r), mesh.positions, anchors);
    if (opening.rim >= 0) openings.push_back(opening);
  }
  return openings;
}

std::vector<int> openingSides(const Mesh& mesh, const VertexAdjacency& adjacency, const std::vector<int>& representative,
                              const std::vector<Rim>& rims, const std::vector<Opening>& openings,
                              const OpeningSideOptions& options) {
  const Eigen::Index nv = mesh.vertexCount();
  std::vector<int> sides(static_cast<std::size_t>(nv), kOffOpenings);
  if (openings.empty()) return sides;
  const PointCopies copies = pointCopies(representative);
  const RowMatrixX3d positions = mesh.positions;  // a vertex's coordinates in one cache line
  std::vector<double> near(static_cast<std::size_t>(nv), kUnreached), far(static_cast<std::size_t>(nv), kUnreached);
  std::vector<double> best(static_cast<std::size_t>(nv), kUnreached);  // distance to the opening whose side a vertex took
  std::vector<int> reached_near, reached_far;
  for (std::size_t k = 0; k < openings.size(); ++k) {
    const Opening& opening = openings[k];
    if (opening.rim < 0) continue;
    const std::vector<int>& loop = rims[static_cast<std::size_t>(opening.rim)].vertices;
    const auto n = static_cast<int>(loop.size());
    // Side 0: corners[0] to corners[1] in loop order; side 1: back round. The
    // corners belong to both, so near them the two distances agree.
    std::array<std::vector<int>, 2> chains;
    for (int s = 0; s < 2; ++s) {
      const int from = opening.corners[static_cast<std::size_t>(s)], to = opening.corners[static_cast<std::size_t>(1 - s)];
      for (int i = from;; i = (i + 1) % n) {
        chains[static_cast<std::size_t>(s)].push_back(loop[static_cast<std::size_t>(i)]);
        if (i == to) break;
      }
    }
    const double radius = options.zone * opening.width;
    // The band where no side is sure: a corner is placed to within a rim
    // edge of where it is, so within the longest rim edge at either corner.
    double corner_edge = 0.0;
    for (const int c : opening.corners) {
      const Eigen::RowVector3d p = mesh.positions.row(loop[static_cast<std::size_t>(c)]);
      corner_edge = std::max({corner_edge, (mesh.positions.row(loop[static_cast<std::size_t>((c + 1) % n)]) - p).norm(),
                              (mesh.positions.row(loop[static_cast<std::size_t>((c + n - 1) % n)]) - p).norm()});
    }
    edgeDistances(adjacency, positions, representative, copies, chains[0], radius, near, reached_near);
    edgeDistances(adjacency, positions, representative, copies, chains[1], radius, far, reached_far);
    for (const std::vector<int>* reached : {&reached_near, &reached_far}) {
      for (const int v : *reached) {
        const auto i = static_cast<std::size_t>(v);
        const double d0 = near[i], d1 = far[i];
        const double own = std::min(d0, d1);
        // Two openings' zones may overlap (a mouth's and a nostril's): the
        // nearer opening wins (and a vertex reached from both chains is
        // seen twice: the second finds own == best).
        if (own >= best[i]) continue;
        best[i] = own;
        int side = kBetweenSides;
        if (d0 + corner_edge <= d1) side = 2 * static_cast<int>(k);
        if (d1 + corner_edge <= d0) side = 2 * static_cast<int>(k) + 1;
        sides[i] = side;
      }
    }
    for (const int v : reached_near) near[static_cast<std::size_t>(v)] = kUnreached;
    for (const int v : reached_far) far[static_cast<std::size_t>(v)] = kUnreached;
    reached_near.clear();
    reached_far.clear();
  }
  return sides;
}

std::vector<std::uint64_t> sideMasks(const std::vector<int>& sides) {
  if (std::all_of(sides.begin(), sides.end(), [](int s) { return s < 0; })) return {};
  std::vector<std::uint64_t> masks(sides.size(), ~std::uint64_t{0});
  for (std::size_t v = 0; v < sides.size(); ++v) {
    assert(sides[v] < 64);
    if (sides[v] >= 0) masks[v] = std::uint64_t{1} << sides[v];
  }
  return masks;
}

std::vector<std::uint64_t> sideFaceSets(const std::vector<int>& sides, const Eigen::MatrixX3i& triangles) {
  if (std::all_of(sides.begin(), sides.end(), [](int s) { return s < 0; })) return {};
  std::vector<std::uint64_t> sets(static_cast<std::size_t>(triangles.rows()), 0);
  for (Eigen::Index f = 0; f < triangles.rows(); ++f) {
    std::uint64_t set = 0;
    for (int c = 0; c < 3; ++c) {
      const int s = sides[static_cast<std::size_t>(triangles(f, c))];
      set |= s >= 0 ? std::uint64_t{1} << s : ~std::uint64_t{0};
    }
    sets[static_cast<std::size_t>(f)] = set;
  }
  return sets;
}

void cutAcrossSides(Eigen::SparseMatrix<double>& laplacian, const std::vector<int>& sides) {
  assert(static_cast<Eigen::Index>(sides.size()) == laplacian.rows());
  auto across = [&](Eigen::Index i, Eigen::Index j) {
    return oppositeSides(sides[static_cast<std::size_t>(i)], sides[static_cast<std::size_t>(j)]);
  };
  // Usually no edge crosses (an open mouth's lips meet only at its corners,
  // which are between the sides): then the Laplacian as it is.
  bool any = false;
  for (Eigen::Index j = 0; j < laplacian.outerSize() && !any; ++j) {
    for (Eigen::SparseMatrix<double>::InnerIterator it(laplacian, j); it && !any; ++it) any = across(it.row(), it.col());
  }
  if (!any) return;
  std::vector<Eigen::Triplet<double>> kept;
  kept.reserve(static_cast<std::size_t>(laplacian.nonZeros()));
  Eigen::VectorXd lost = Eigen::VectorXd::Zero(laplacian.rows());
  for (Eigen::Index j = 0; j < laplacian.outerSize(); ++j) {
    for (Eigen::SparseMatrix<double>::InnerIterator it(laplacian, j); it; ++it) {
      if (it.row() != it.col() && across(it.row(), it.col())) {
        lost(it.row()) += it.value();
        continue;
      }
      kept.emplace_back(it.row(), it.col(), it.value());
    }
  }
  for (Eigen::Index i = 0; i < laplacian.rows(); ++i) {
    if (lost(i) != 0.0) kept.emplace_back(i, i, lost(i));  // the row's sum stays 0
  }
  Eigen::SparseMatrix<double> cut(laplacian.rows(), laplacian.cols());
  cut.setFromTriplets(kept.begin(), kept.end());
  laplacian = std::move(cut);
}

}  // namespace core
