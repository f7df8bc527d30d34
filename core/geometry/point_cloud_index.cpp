// Nearest points of a point cloud, and the neighbourhood measures a scan given
// as points needs (normals, borders, spikes).
//
// Index: nanoflann's k-d tree over the points in double, with the points
// copied in tree order (a leaf reads one contiguous run). Queries use their
// own result sets, which order candidates by (squared distance, row), so ties
// go to the lower row exactly as a brute-force scan would; the pruning radius
// they report is widened by a relative 1e-10 so that nanoflann's strict leaf
// test and the rounding of its incremental cell distances never drop a tie.
// Rows with a non-finite coordinate are not indexed (a NaN would poison the
// tree's boxes); a non-finite query finds none.
//
// Neighbourhood measures read each point's k nearest through the public
// queries, one point per iteration of a parallelFor (outputs by row, so they do
// not depend on the thread count). Planes are the least-squares planes of the
// neighbours: their centroid and the smallest principal axis of their 3x3
// covariance (Eigen's iterative SelfAdjointEigenSolver, accurate also when two
// eigenvalues are close).
//
// Measured (1 thread, best of 3 runs of medians, on a busy 2-core machine):
// the s02 scan cloud (33k points): index 3.7 ms, normals 41 ms, borders
// 58 ms, spikes 47 ms; 50k points sampled on the ICT face: 11.2k nearest
// queries (its vertices, moved ~1 mm) 3.0 ms, 12 nearest of each 10 ms.
#include "core/geometry/point_cloud_index.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>
#include <utility>
#include <vector>

#include <Eigen/Eigenvalues>

#include "core/base/parallel.h"

#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wshadow"
#pragma GCC diagnostic ignored "-Wpedantic"
#pragma GCC diagnostic ignored "-Wunused-parameter"
#include <nanoflann.hpp>
#pragma GCC diagnostic pop

namespace core {
namespace {

constexpr double kInfinity = std::numeric_limits<double>::infinity();

// nanoflann dataset adaptor over points stored as x, y, z triples.
struct Cloud {
  const double* xyz = nullptr;
  std::size_t size = 0;
  std::size_t kdtree_get_point_count() const { return size; }
  double kdtree_get_pt(std::uint32_t i, std::size_t dim) const { return xyz[3 * i + dim]; }
  template <class Bbox>
  bool kdtree_get_bbox(Bbox&) const {
    return false;
  }
};

using KdTree = nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<double, Cloud, double, std::uint32_t>,
                                                   Cloud, 3, std::uint32_t>;

// Points per leaf (nanoflann's default is 10): 10, 16 and 32 were within 5%
// of each other on the measurements in the file comment.
constexpr int kLeafSize = 16;

// The pruning radius reported to nanoflann, widened so that candidates tying
// the current worst still reach addPoint() (see the file comment); the
// smallest denormal makes that hold for copies of the query (distance 0) too.
double widened(double sq_distance) {
  return sq_distance * (1.0 + 1e-10) + std::numeric_limits<double>::denorm_min();
}

// Candidate order: distance, then row.
bool before(double d0, int i0, double d1, int i1) { return d0 < d1 || (d0 == d1 && i0 < i1); }

struct NearestSet {
  const std::int32_t* rows;  // tree slot -> row
  double best = kInfinity;
  std::int32_t best_row = -1;

  std::size_t size() const { return best_row < 0 ? 0 : 1; }
  bool full() const { return true; }
  double worstDist() const { return widened(best); }
  bool addPoint(double dist, std::uint32_t slot) {
    const std::int32_t row = rows[slot];
    if (before(dist, row, best, best_row < 0 ? std::numeric_limits<std::int32_t>::max() : best_row)) {
      best = dist;
      best_row = row;
    }
    return true;
  }
};

// The k best candidates, kept sorted in `out[0, count)`.
struct KnnSet {
  const std::int32_t* rows;
  PointCloudIndex::Neighbour* out;
  int k;
  int count = 0;

  std::size_t size() const { return static_cast<std::size_t>(count); }
  bool full() const { return count == k; }
  double worstDist() const { return count < k ? kInfinity : widened(out[k - 1].sq_distance); }
  bool addPoint(double dist, std::uint32_t slot) {
    const std::int32_t row = rows[slot];
    if (count == k && !before(dist, row, out[k - 1].sq_distance, out[k - 1].index)) return true;
    int j = count < k ? count++ : k - 1;
    for (; j > 0 && before(dist, row, out[j - 1].sq_distance, out[j - 1].index); --j) out[j] = out[j - 1];
    out[j] = PointCloudIndex::Neighbour{row, dist};
    return true;
  }
};

Eigen::Vector3d rowOf(const Eigen::MatrixX3d& m, Eigen::Index i) { return m.row(i).transpose(); }

// Least-squares plane of `points` rows listed in `rows`.
struct Plane {
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();  // unit, smallest principal axis
};

template <class Rows>
Plane fitPlane(const Eigen::MatrixX3d& points, const Rows& rows, int count) {
  Plane plane;
  for (int j = 0; j < count; ++j) plane.centroid += rowOf(points, rows[j].index);
  plane.centroid /= static_cast<double>(count);
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
  for (int j = 0; j < count; ++j) {
    const Eigen::Vector3d d = rowOf(points, rows[j].index) - plane.centroid;
    covariance.noalias() += d * d.transpose();
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(covariance);
  plane.normal = solver.eigenvectors().col(0);  // eigenvalues ascending
  return plane;
}

double boundingBoxDiagonalOfFinite(const Eigen::MatrixX3d& points) {
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(kInfinity), hi = Eigen::Vector3d::Constant(-kInfinity);
  for (Eigen::Index i = 0; i < points.rows(); ++i) {
    const Eigen::Vector3d p = rowOf(points, i);
    if (!p.allFinite()) continue;
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  return (hi - lo).allFinite() ? (hi - lo).norm() : 0.0;
}

}  // namespace

struct PointCloudIndex::Impl {
  std::vector<double> xyz;          // indexed points in tree order, x y z each
  std::vector<std::int32_t> rows;   // tree slot -> row of the caller's points
  Cloud cloud;
  std::unique_ptr<KdTree> tree;     // null when no point is indexed

  // The query as nanoflann reads it; false when nothing can be found.
  bool toQuery(const Eigen::Vector3d& q, double* out) const {
    if (!tree || !q.allFinite()) return false;
    out[0] = q.x();
    out[1] = q.y();
    out[2] = q.z();
    return true;
  }
};

PointCloudIndex::PointCloudIndex() : impl_(std::make_unique<Impl>()) {}

PointCloudIndex::PointCloudIndex(const Eigen::MatrixX3d& points) : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  m.xyz.reserve(3 * static_cast<std::size_t>(points.rows()));
  m.rows.reserve(static_cast<std::size_t>(points.rows()));
  for (Eigen::Index i = 0; i < points.rows(); ++i) {
    if (!points.row(i).allFinite()) continue;
    for (int c = 0; c < 3; ++c) m.xyz.push_back(points(i, c));
    m.rows.push_back(static_cast<std::int32_t>(i));
  }
  if (m.rows.empty()) return;
  m.cloud = Cloud{m.xyz.data(), m.rows.size()};
  m.tree = std::make_unique<KdTree>(3, m.cloud, nanoflann::KDTreeSingleIndexAdaptorParams(kLeafSize));
  // Points and rows in tree order; nanoflann's permutation (the public vAcc)
  // becomes the identity.
  auto& order = m.tree->vAcc;
  std::vector<double> xyz(m.xyz.size());
  std::vector<std::int32_t> rows(m.rows.size());
  for (std::size_t j = 0; j < order.size(); ++j) {
    for (std::size_t c = 0; c < 3; ++c) xyz[3 * j + c] = m.xyz[3 * order[j] + c];
    rows[j] = m.rows[order[j]];
    order[j] = static_cast<std::uint32_t>(j);
  }
  m.xyz.swap(xyz);
  m.rows.swap(rows);
  m.cloud.xyz = m.xyz.data();
}

PointCloudIndex::~PointCloudIndex() = default;
PointCloudIndex::PointCloudIndex(PointCloudIndex&&) noexcept = default;
PointCloudIndex& PointCloudIndex::operator=(PointCloudIndex&&) noexcept = default;

PointCloudIndex::Neighbour PointCloudIndex::nearest(const Eigen::Vector3d& query) const {
  double q[3];
  if (!impl_ || !impl_->toQuery(query, q)) return {};
  NearestSet set{impl_->rows.data()};
  impl_->tree->findNeighbors(set, q, nanoflann::SearchParams(0, 0.0f, false));
  return set.best_row < 0 ? Neighbour{} : Neighbour{set.best_row, set.best};
}

std::vector<PointCloudIndex::Neighbour> PointCloudIndex::nearest(const Eigen::MatrixX3d& queries) const {
  std::vector<Neighbour> out(static_cast<std::size_t>(queries.rows()));
  parallelFor(queries.rows(), [&](std::ptrdiff_t begin, std::ptrdiff_t end) {
    for (std::ptrdiff_t i = begin; i < end; ++i) out[static_cast<std::size_t>(i)] = nearest(rowOf(queries, i));
  });
  return out;
}

std::vector<PointCloudIndex::Neighbour> PointCloudIndex::nearest(const Eigen::Vector3d& query, int k) const {
  double q[3];
  if (k <= 0 || !impl_ || !impl_->toQuery(query, q)) return {};
  std::vector<Neighbour> out(static_cast<std::size_t>(std::min(k, size())));
  KnnSet set{impl_->rows.data(), out.data(), static_cast<int>(out.size())};
  impl_->tree->findNeighbors(set, q, nanoflann::SearchParams(0, 0.0f, false));
  out.resize(set.size());
  return out;
}

int PointCloudIndex::size() const { return impl_ ? static_cast<int>(impl_->rows.size()) : 0; }

std::size_t PointCloudIndex::memoryBytes() const {
  if (!impl_) return 0;
  const Impl& m = *impl_;
  std::size_t bytes = sizeof(Impl) + m.xyz.capacity() * sizeof(double) + m.rows.capacity() * sizeof(std::int32_t);
  if (m.tree) bytes += sizeof(KdTree) + m.tree->usedMemory(*m.tree);  // its node pool and permutation
  return bytes;
}

Eigen::MatrixX3d estimateCloudNormals(const Eigen::MatrixX3d& points, const PointCloudIndex& index, int k) {
  Eigen::MatrixX3d normals = Eigen::MatrixX3d::Zero(points.rows(), 3);
  parallelFor(points.rows(), [&](std::ptrdiff_t begin, std::ptrdiff_t end) {
    for (std::ptrdiff_t i = begin; i < end; ++i) {
      const auto near = index.nearest(rowOf(points, i), k);
      if (near.empty()) continue;
      assert(near.back().index < points.rows());
      Eigen::Vector3d n = fitPlane(points, near, static_cast<int>(near.size())).normal;
      // Deterministic sign: the largest-magnitude component (the first of
      // equals) positive.
      Eigen::Index largest = 0;
      n.cwiseAbs().maxCoeff(&largest);
      if (n(largest) < 0.0) n = -n;
      normals.row(i) = n.transpose();
    }
  });
  return normals;
}

int orientNormalsLike(Eigen::MatrixX3d& normals, const Eigen::MatrixX3d& reference_normals) {
  assert(normals.rows() == reference_normals.rows());
  const Eigen::Index n = std::min(normals.rows(), reference_normals.rows());
  int flipped = 0;
  for (Eigen::Index i = 0; i < n; ++i) {
    if (normals.row(i).dot(reference_normals.row(i)) < 0.0) {
      normals.row(i) = -normals.row(i);
      ++flipped;
    }
  }
  return flipped;
}

std::vector<char> cloudBorderPoints(const Eigen::MatrixX3d& points, const Eigen::MatrixX3d& normals,
                                    const PointCloudIndex& index, int k, double max_gap_deg) {
  assert(normals.rows() == points.rows());
  std::vector<char> border(static_cast<std::size_t>(points.rows()), 0);
  const double max_gap = max_gap_deg * std::numbers::pi / 180.0;
  parallelFor(points.rows(), [&](std::ptrdiff_t begin, std::ptrdiff_t end) {
    std::vector<double> angles;
    for (std::ptrdiff_t i = begin; i < end; ++i) {
      const Eigen::Vector3d p = rowOf(points, i);
      Eigen::Vector3d n = rowOf(normals, i);
      if (!p.allFinite() || !(n.norm() > 0.0) || !n.allFinite()) continue;  // no plane to look in
      n.normalize();
      // Tangent basis (u, v): u across the normal's smallest component.
      const Eigen::Vector3d u =
          (std::abs(n.x()) < 0.9 ? n.cross(Eigen::Vector3d::UnitX()) : n.cross(Eigen::Vector3d::UnitY())).normalized();
      const Eigen::Vector3d v = n.cross(u);
      // k neighbours besides the point: one more, less itself and its copies.
      angles.clear();
      for (const auto& nb : index.nearest(p, k + 1)) {
        if (nb.index == i || nb.sq_distance == 0.0) continue;
        const Eigen::Vector3d d = rowOf(points, nb.index) - p;
        const double x = d.dot(u), y = d.dot(v);
        // A neighbour straight along the normal has no direction in the plane.
        if (x * x + y * y <= 1e-12 * nb.sq_distance) continue;
        angles.push_back(std::atan2(y, x));
        if (static_cast<int>(angles.size()) == k) break;
      }
      if (angles.size() < 2) {  // isolated: nothing on any side
        border[static_cast<std::size_t>(i)] = 1;
        continue;
      }
      std::sort(angles.begin(), angles.end());
      double gap = angles.front() + 2.0 * std::numbers::pi - angles.back();
      for (std::size_t j = 1; j < angles.size(); ++j) gap = std::max(gap, angles[j] - angles[j - 1]);
      border[static_cast<std::size_t>(i)] = gap > max_gap ? 1 : 0;
    }
  });
  return border;
}

// Share of the neighbours' spacing a spike's offset must exceed. On the s02
// scan cloud (33k points, 0.3 mm noise, ~1.5 mm spacing) 0.5 also flagged 22
// noise points 0.7-1.2 mm off the true surface; 0.75 and 1.0 flag the same
// 35: the 31 points more than 1.5 mm off it away from the eye caps, 3 cap
// points and one skin point beside a cap.
constexpr double kSpacingShare = 0.75;

std::vector<char> cloudSpikes(const Eigen::MatrixX3d& points, const PointCloudIndex& index, int k, double factor) {
  std::vector<char> spikes(static_cast<std::size_t>(points.rows()), 0);
  // A noise-free plane puts every point exactly on its neighbours' plane:
  // this floor keeps rounding from flagging it.
  const double floor = 1e-9 * boundingBoxDiagonalOfFinite(points);
  parallelFor(points.rows(), [&](std::ptrdiff_t begin, std::ptrdiff_t end) {
    std::vector<PointCloudIndex::Neighbour> around;
    for (std::ptrdiff_t i = begin; i < end; ++i) {
      const Eigen::Vector3d p = rowOf(points, i);
      // The neighbours without the point and its exact copies: a duplicated
      // spike must not hold its own plane up.
      around.clear();
      for (const auto& nb : index.nearest(p, k + 1)) {
        if (nb.index != i && nb.sq_distance > 0.0 && static_cast<int>(around.size()) < k) around.push_back(nb);
      }
      const int m = static_cast<int>(around.size());
      if (m < 3) continue;  // no plane
      const Plane plane = fitPlane(points, around, m);
      const double offset = std::abs(plane.normal.dot(p - plane.centroid));
      double mean_abs = 0.0;
      for (const auto& nb : around) mean_abs += std::abs(plane.normal.dot(rowOf(points, nb.index) - plane.centroid));
      mean_abs /= m;
      // The sampling spacing from the neighbours alone (each one's distance to
      // the nearest other), not from the point: a spike far from everything
      // would otherwise set its own, large spacing.
      double spacing = 0.0;
      for (int a = 0; a < m; ++a) {
        double nearest_sq = kInfinity;
        const Eigen::Vector3d qa = rowOf(points, around[a].index);
        for (int b = 0; b < m; ++b) {
          if (b != a) nearest_sq = std::min(nearest_sq, (rowOf(points, around[b].index) - qa).squaredNorm());
        }
        spacing += std::sqrt(nearest_sq);
      }
      spacing /= m;
      const double threshold = std::max({factor * mean_abs, floor, kSpacingShare * spacing});
      spikes[static_cast<std::size_t>(i)] = offset > threshold ? 1 : 0;
    }
  });
  return spikes;
}

}  // namespace core
