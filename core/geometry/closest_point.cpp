// Exact closest point on a triangle mesh.
//
// Point-triangle test: Ericson 2005, "Real-Time Collision Detection", 5.1.5
// (Voronoi regions of corners, edges and face), with a fallback to the closest
// of the three edges as segments for degenerate and sliver triangles.
//
// Index (built on nanoflann's KD-tree): every non-degenerate triangle is cut by
// longest-edge bisection into pieces whose covering radius h_s (from the centre
// of the piece's smallest enclosing ball to its farthest corner) is at most a
// target tied to the upper-quartile edge; each piece contributes one sample point s.
// If the closest point of triangle t to q lies in the piece of s, then
// |q - s| <= d(q, t) + h_s. Hence
//   (1) t needs an exact test only when |q - s| - h_s <= best distance so far;
//   (2) the tree search may prune at radius best + max h_s.
// The query is one depth-first nanoflann traversal with a custom result set
// whose radius (worstDist) shrinks as better triangles are found: no k-NN pass
// and no radius doubling, and filtered queries just keep the radius open until
// a compatible face is found, so results stay exact under filters. A face's
// plane distance is a second cheap lower bound before the exact test.
// Triangles far larger than the median need too many pieces; they go to
// coarser levels (own tree, own max h), searched after the fine one.
// Samples are floats relative to the mesh centre; every bound carries the
// rounding slack that keeps it conservative, and exact tests use the double
// input positions, so results equal a brute-force scan with
// closestPointOnTriangle() (ties go to the lower face index).
//
// Behaviour worth knowing: without face_labels the label mask is ignored; a
// non-finite query, a negative or NaN max_distance, or a mask sharing no bit
// with any face's label set give face = -1; the query normal is used as given (unit
// expected); faces with non-finite corners are skipped like degenerate ones.
// Vertex coordinates must stay within float range of the mesh centre (~1e18),
// and squared sample distances within float's normal range: meshes from
// ~1e-17 to ~1e18 units across.
#include "core/geometry/closest_point.h"

#include <algorithm>
#include <array>
#include <cassert>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <utility>
#include <vector>

#include "core/geometry/mesh.h"
#include "core/geometry/point_triangle.h"

#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wshadow"
#pragma GCC diagnostic ignored "-Wpedantic"
#pragma GCC diagnostic ignored "-Wunused-parameter"
#include <nanoflann.hpp>
#pragma GCC diagnostic pop

namespace core {
namespace {

using namespace point_triangle;


// ---------------------------------------------------------------------------
// Sampling

// A sample point in float, relative to the index origin (the mesh bounding-box
// centre, so precision follows the mesh size, not its position). Its covering
// radius h is measured from the rounded position and rounded up, so the
// covering property holds exactly for the stored point.
struct Sample {
  float p[3];
  std::int32_t face;
  float h;
};
static_assert(sizeof(Sample) == 20, "compact samples: more of the tree stays in cache");

// nanoflann dataset adaptor over a sample array. Point and cell distances
// are computed in float (4-12% faster queries than double, measured); every
// bound that uses them carries a relative slack far above float rounding.
struct SampleCloud {
  const Sample* data = nullptr;
  std::size_t size = 0;
  std::size_t kdtree_get_point_count() const { return size; }
  float kdtree_get_pt(std::uint32_t i, std::size_t dim) const {
    return data[i].p[dim];
  }
  template <class Bbox>
  bool kdtree_get_bbox(Bbox&) const {
    return false;
  }
};

using KdTree = nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<float, SampleCloud, float, std::uint32_t>,
                                                   SampleCloud, 3, std::uint32_t>;

// nanoflann leaf_max_size. Larger than the usual 10: leaf scans are cheap and
// predictable, node visits are branchy (measured ~10% faster than 12).
constexpr int kLeafSize = 32;

float roundUpToFloat(double h) {
  float f = static_cast<float>(h);
  if (static_cast<double>(f) < h) f = std::nextafter(f, std::numeric_limits<float>::infinity());
  return f;
}

// Centre of the smallest ball containing triangle (a, b, c): the midpoint of
// the longest edge for right and obtuse triangles, else the circumcentre. Any
// point would be correct (the covering radius is measured from it); this one
// minimises the radius, 5-20% below the centroid's on typical pieces.
Vec3 coveringCentre(const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 e[3] = {b - a, c - b, a - c};
  const double l[3] = {e[0].squaredNorm(), e[1].squaredNorm(), e[2].squaredNorm()};
  const int i = (l[0] >= l[1] && l[0] >= l[2]) ? 0 : (l[1] >= l[2] ? 1 : 2);
  const Vec3* v[3] = {&a, &b, &c};
  if (l[i] >= l[(i + 1) % 3] + l[(i + 2) % 3]) return 0.5 * (*v[i] + *v[(i + 1) % 3]);  // angle opposite >= 90
  const Vec3 ab = b - a, ac = c - a;
  const Vec3 n = ab.cross(ac);
  const Vec3 centre = a + (ac.squaredNorm() * n.cross(ab) + ab.squaredNorm() * ac.cross(n)) / (2.0 * n.squaredNorm());
  return centre.allFinite() ? centre : (a + b + c) / 3.0;
}

constexpr int kMaxPieces = 64;  // most pieces per triangle on one level

// One piece's sample: its covering centre rounded to float, and the covering
// radius measured from the rounded point (so it holds for the stored sample).
struct Piece {
  Eigen::Vector3f centre;
  double h;
};
inline Piece coverPiece(const Vec3& a, const Vec3& b, const Vec3& c) {
  const Eigen::Vector3f gf = coveringCentre(a, b, c).cast<float>();
  const Vec3 gr = gf.cast<double>();
  return {gf, std::sqrt(std::max({(a - gr).squaredNorm(), (b - gr).squaredNorm(), (c - gr).squaredNorm()}))};
}

inline Sample makeSample(const Piece& piece, int face, double slack) {
  return Sample{{piece.centre.x(), piece.centre.y(), piece.centre.z()}, face,
                roundUpToFloat(piece.h * (1.0 + 1e-9) + slack)};
}

// Covers triangle (a, b, c) (relative to the index origin) by longest-edge
// bisection until every piece's covering radius (from its rounded covering
// centre to its farthest corner) is <= h_target. Appends the samples and returns true, or returns
// false (appending nothing) when more than `cap` pieces would be needed.
// `slack` (absolute) absorbs rounding in later distance computations.
bool sampleTriangle(const Vec3& a, const Vec3& b, const Vec3& c, int face, double h_target, int cap, double slack,
                    std::vector<Sample>& out) {
  assert(cap <= kMaxPieces);
  if (const Piece whole = coverPiece(a, b, c); whole.h <= h_target) {  // most triangles: one piece, no stack
    if (cap < 1) return false;
    out.push_back(makeSample(whole, face, slack));
    return true;
  }
  const std::size_t start = out.size();
  // Pending pieces: at most cap + 1 at any time (checked below), so a fixed
  // array serves without allocation.
  std::array<std::array<Vec3, 3>, kMaxPieces + 2> stack;
  int depth = 0;
  stack[depth++] = {a, b, c};
  while (depth > 0) {
    const std::array<Vec3, 3> t = stack[--depth];
    const Piece piece = coverPiece(t[0], t[1], t[2]);
    if (piece.h <= h_target) {
      if (static_cast<int>(out.size() - start) >= cap) {
        out.resize(start);
        return false;
      }
      out.push_back(makeSample(piece, face, slack));
      continue;
    }
    if (static_cast<int>(out.size() - start) + depth + 2 > cap) {
      out.resize(start);
      return false;
    }
    // Split the longest edge (i, i+1) at its midpoint.
    const double l0 = (t[1] - t[0]).squaredNorm();
    const double l1 = (t[2] - t[1]).squaredNorm();
    const double l2 = (t[0] - t[2]).squaredNorm();
    const int i = (l0 >= l1 && l0 >= l2) ? 0 : (l1 >= l2 ? 1 : 2);
    const Vec3& p0 = t[i];
    const Vec3& p1 = t[(i + 1) % 3];
    const Vec3& p2 = t[(i + 2) % 3];
    const Vec3 m = 0.5 * (p0 + p1);
    stack[depth++] = {p0, m, p2};
    stack[depth++] = {m, p1, p2};
  }
  return true;
}

}  // namespace

// ---------------------------------------------------------------------------

struct ClosestPointIndex::Impl {
  struct Level {
    std::vector<Sample> samples;
    double h_max = 0.0;
    SampleCloud cloud;
    std::unique_ptr<KdTree> tree;
  };

  // Indexed (non-degenerate) faces, stored in the order their first sample
  // appears in the trees so that the faces of one leaf share cache lines.
  // Samples refer to these slots; `id` is the caller's face index.
  std::vector<Face> faces;
  std::vector<std::uint64_t> labels;  // label bit set per slot; empty: no labels given
  std::uint64_t present_labels = 0;   // union of the indexed faces' label sets
  Eigen::Index face_count = 0;        // faces of the mesh (indexed or not)
  std::vector<std::unique_ptr<Level>> levels;  // finest first
  Vec3 origin = Vec3::Zero();                  // sample coordinates are relative to it
  double origin_max_abs = 0.0;
  double max_abs = 0.0;                        // largest vertex coordinate magnitude
  int indexed_faces = 0;
  std::size_t tree_bytes = 0;

  struct Search;
  SurfacePoint query(const Vec3& q, const Vec3* normal, std::uint64_t label_mask, const Limits& limits) const;
};

// nanoflann result set that evaluates triangles as their samples are reached.
// worstDist() is the squared pruning radius (best + level h_max)^2; nanoflann
// re-reads it at every branch, so the search tightens as it goes. Samples of a
// leaf are only queued by addPoint() and evaluated nearest first at the next
// worstDist() call (before any further pruning decision), so the first good
// triangle bounds the rest of the leaf.
struct ClosestPointIndex::Impl::Search {
  Search(const Impl& index, const Vec3& query) : impl(index), q(toP3(query)) { recent.fill(-1); }

  const Impl& impl;
  const P3 q;
  // Filters.
  const P3* normal = nullptr;  // null: no normal filter; else &normal_value
  P3 normal_value{0.0, 0.0, 0.0};
  double min_cos = -2.0;
  std::uint64_t label_mask = ~std::uint64_t{0};
  bool use_labels = false;
  // The last faces examined, so that a face reached through several samples
  // is usually evaluated once. Purely a shortcut: re-evaluating a face gives
  // the same answer, so no per-face table (and no thread-local state) is needed.
  static constexpr int kRecent = 8;
  std::array<std::int32_t, kRecent> recent;
  int recent_next = 0;
  // Current level.
  const Sample* samples = nullptr;
  double level_h = 0.0;
  // Rounding allowance of the plane-distance bound.
  double plane_eps = 0.0;
  // Bound on |q - (float query used in the tree)|: added to every covering
  // radius so that tree distances (from the rounded query) stay conservative.
  double query_eps = 0.0;
  // Best so far.
  double best_sq = std::numeric_limits<double>::infinity();
  double best_d = std::numeric_limits<double>::infinity();
  TriHit best;
  int best_face = -1;
  double radius_sq = std::numeric_limits<double>::infinity();
  // Samples queued since the last worstDist() call (one leaf at most).
  struct Pending {
    double dist_sq;
    std::uint32_t index;
  };
  std::array<Pending, kLeafSize> pending;
  int pending_count = 0;

  // Slightly generous bounds so that rounding never prunes an exact tie.
  // nanoflann computes sample and cell distances from float coordinates in
  // float: a squared distance carries a relative error of a few 1e-7, so the
  // sample test inflates its reach by 1e-6 (2e-6 squared) and the tree radius
  // by 1e-5.
  static constexpr double kInflate = 1.0 + 1e-6;
  static constexpr double kTreeInflate = 1.0 + 1e-5;

  void setLevel(const Level& level) {
    samples = level.samples.data();
    level_h = level.h_max;
    updateRadius();
  }
  void updateRadius() {
    const double r = (best_d + level_h + query_eps) * kTreeInflate;
    radius_sq = r * r;
  }

  // nanoflann result-set interface.
  std::size_t size() const { return 0; }
  bool full() const { return true; }
  float worstDist() {
    flush();
    return static_cast<float>(radius_sq);
  }
  bool addPoint(float dist_sq, std::uint32_t index) {
    if (best_face >= 0) {
      consider(dist_sq, samples[index]);
      return true;
    }
    if (pending_count == kLeafSize) flush();
    pending[pending_count++] = Pending{dist_sq, index};
    return true;
  }

  void flush() {
    if (pending_count == 0) return;
    // The nearest sample first: its triangle usually bounds the others out.
    int nearest = 0;
    for (int i = 1; i < pending_count; ++i) {
      if (pending[i].dist_sq < pending[nearest].dist_sq) nearest = i;
    }
    std::swap(pending[0], pending[nearest]);
    for (int i = 0; i < pending_count; ++i) consider(pending[i].dist_sq, samples[pending[i].index]);
    pending_count = 0;
  }

  void consider(double dist_sq, const Sample& s) {
    const double reach = (best_d + static_cast<double>(s.h) + query_eps) * kInflate;
    if (dist_sq > reach * reach) return;  // lower bound |q - s| - h_s exceeds the best
    const auto f = static_cast<std::uint32_t>(s.face);
    for (const std::int32_t g : recent) {
      if (g == s.face) return;
    }
    recent[recent_next] = s.face;
    recent_next = (recent_next + 1) % kRecent;
    if (use_labels && (impl.labels[f] & label_mask) == 0) return;
    const Face& face = impl.faces[f];
    if (normal != nullptr && dot(face.n, *normal) < min_cos) return;
    // Distance to the face's plane: a lower bound that often rejects
    // neighbours of the closest face before the full test. Only for
    // well-shaped faces, whose normal is accurate (direction error <~ 1e-13).
    if (face.well_shaped) {
      const double plane = std::abs(dot(face.n, q - face.a)) - plane_eps;
      if (plane > 0.0 && plane * plane > best_sq) return;
    }
    const TriHit r = closestOnTriangle(q, face.a, face.b, face.c, face.well_shaped);
    const int fi = face.id;
    if (r.sq_distance < best_sq || (r.sq_distance == best_sq && (best_face < 0 || fi < best_face))) {
      best = r;
      best_face = fi;
      best_sq = r.sq_distance;
      best_d = std::sqrt(best_sq);
      updateRadius();
    }
  }
};

SurfacePoint ClosestPointIndex::Impl::query(const Vec3& q, const Vec3* normal, std::uint64_t label_mask,
                                            const Limits& limits) const {
  if (levels.empty() || !q.allFinite() || !(limits.max_distance >= 0.0)) return {};
  const bool use_labels = !labels.empty();
  if (use_labels && (label_mask & present_labels) == 0) return {};  // no face can pass

  Search search(*this, q);
  search.use_labels = use_labels;
  search.label_mask = label_mask;
  if (normal != nullptr && limits.min_cos > -2.0) {
    search.normal_value = toP3(*normal);
    search.normal = &search.normal_value;
    search.min_cos = limits.min_cos;
  }
  if (std::isfinite(limits.max_distance)) {
    search.best_d = limits.max_distance;
    search.best_sq = limits.max_distance * limits.max_distance;
  }
  // The tree works in float relative to `origin`. Clamping keeps nanoflann's
  // float squares finite for absurdly far queries; their query_eps then just
  // widens the search (still exact, only slower).
  const Vec3 qc = q - origin;
  float qf[3];
  double err2 = 0.0;
  for (int k = 0; k < 3; ++k) {
    qf[k] = static_cast<float>(std::clamp(qc(k), -1e18, 1e18));
    const double e = qc(k) - static_cast<double>(qf[k]);
    err2 += e * e;
  }
  search.query_eps = std::sqrt(err2) + 1e-15 * (q.cwiseAbs().maxCoeff() + origin_max_abs);
  search.plane_eps = 1e-12 * (q.cwiseAbs().maxCoeff() + max_abs);
  const nanoflann::SearchParams params(0, 0.0f, false);
  for (const auto& level : levels) {
    search.setLevel(*level);
    level->tree->findNeighbors(search, qf, params);
    search.flush();
  }
  return search.best_face < 0 ? SurfacePoint{} : toSurfacePoint(search.best, search.best_face);
}

ClosestPointIndex::ClosestPointIndex(const Eigen::MatrixX3d& positions, const Eigen::MatrixX3i& triangles,
                                     std::vector<std::uint64_t> face_labels)
    : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  const Eigen::Index nf = triangles.rows();
  assert(face_labels.empty() || static_cast<Eigen::Index>(face_labels.size()) == nf);
  m.face_count = nf;
  const double diagonal = boundingBoxDiagonal(positions);
  const double max_abs = positions.rows() > 0 ? positions.cwiseAbs().maxCoeff() : 0.0;
  // Absolute slack on covering radii: distances to points ~max_abs from the
  // origin carry rounding of that order.
  const double slack = 1e-12 * (diagonal + max_abs);
  m.max_abs = max_abs;
  if (positions.rows() > 0) {
    m.origin = 0.5 * (positions.colwise().minCoeff() + positions.colwise().maxCoeff()).transpose();
    m.origin_max_abs = m.origin.cwiseAbs().maxCoeff();
  }

  // Indexed faces in caller order first; re-slotted in tree order at the end.
  // Degeneracy and normal as isDegenerateTriangle() and computeFaceNormals()
  // (same operations, same bits), from one cross product.
  const double degenerate_eps = 1e-10 * diagonal;
  std::vector<Face> faces;
  faces.reserve(static_cast<std::size_t>(nf));
  std::vector<double> sq_edge_lengths;
  sq_edge_lengths.reserve(3 * static_cast<std::size_t>(nf));
  for (Eigen::Index f = 0; f < nf; ++f) {
    Face face;
    if (!makeFace(positions, triangles, f, degenerate_eps, face)) continue;
    faces.push_back(face);
    const P3 e0 = face.b - face.a, e1 = face.c - face.b, e2 = face.a - face.c;
    sq_edge_lengths.push_back(dot(e0, e0));
    sq_edge_lengths.push_back(dot(e1, e1));
    sq_edge_lengths.push_back(dot(e2, e2));
  }
  m.indexed_faces = static_cast<int>(faces.size());
  if (faces.empty()) return;

  // Covering radius target from the upper-quartile edge: most triangles get
  // one sample (1.0-1.2 per face), large or sliver ones a few. The value
  // trades tree size against candidates per query (tuned on the benchmark:
  // 0.5-1.0 are within 10%). The quartile rather than the median matters on
  // meshes with mixed triangle sizes: the ICT face's guide (22k faces) got
  // 60k samples from the median, 31k from the quartile, and builds +
  // queries took 15 -> 11 ms. A triangle needing more than kCap pieces moves
  // to the next level, whose target is kGrowth times coarser.
  constexpr double kSpacing = 0.7;
  constexpr double kEdgeQuantile = 0.75;
  constexpr int kCap = kMaxPieces;
  constexpr double kGrowth = 4.0;
  const auto quantile = static_cast<std::size_t>(kEdgeQuantile * static_cast<double>(sq_edge_lengths.size() - 1));
  std::nth_element(sq_edge_lengths.begin(), sq_edge_lengths.begin() + static_cast<std::ptrdiff_t>(quantile),
                   sq_edge_lengths.end());
  double h_target = kSpacing * std::sqrt(sq_edge_lengths[quantile]);

  std::vector<int> pending(faces.size());  // positions in `faces`
  for (std::size_t i = 0; i < faces.size(); ++i) pending[i] = static_cast<int>(i);
  while (!pending.empty()) {
    auto level = std::make_unique<Impl::Level>();
    level->samples.reserve(pending.size() + pending.size() / 4);
    std::vector<int> rest;
    for (const int f : pending) {
      const Face& face = faces[f];
      if (!sampleTriangle(toVec3(face.a) - m.origin, toVec3(face.b) - m.origin, toVec3(face.c) - m.origin, f, h_target,
                          kCap, slack, level->samples)) {
        rest.push_back(f);
      }
    }
    if (!level->samples.empty()) {
      for (const Sample& s : level->samples) level->h_max = std::max(level->h_max, static_cast<double>(s.h));
      level->cloud.data = level->samples.data();
      level->cloud.size = level->samples.size();
      level->tree = std::make_unique<KdTree>(3, level->cloud, nanoflann::KDTreeSingleIndexAdaptorParams(kLeafSize));
      // Store the samples in tree order so that a leaf reads one contiguous
      // run; nanoflann's permutation (the public vAcc) becomes the identity.
      auto& order = level->tree->vAcc;
      std::vector<Sample> sorted(level->samples.size());
      for (std::size_t j = 0; j < order.size(); ++j) sorted[j] = level->samples[order[j]];
      level->samples.swap(sorted);
      level->cloud.data = level->samples.data();
      for (std::size_t j = 0; j < order.size(); ++j) order[j] = static_cast<std::uint32_t>(j);
      m.tree_bytes += level->tree->usedMemory(*level->tree);
      m.levels.push_back(std::move(level));
    }
    pending.swap(rest);
    h_target *= kGrowth;
  }

  // Slot faces by first appearance in the (tree-ordered) samples.
  std::vector<std::int32_t> slot(faces.size(), -1);
  m.faces.reserve(faces.size());
  for (auto& level : m.levels) {
    for (Sample& s : level->samples) {
      if (slot[s.face] < 0) {
        slot[s.face] = static_cast<std::int32_t>(m.faces.size());
        m.faces.push_back(faces[s.face]);
      }
      s.face = slot[s.face];
    }
  }
  assert(m.faces.size() == faces.size());
  setFaceLabels(std::move(face_labels));
}

void ClosestPointIndex::setFaceLabels(std::vector<std::uint64_t> face_labels) {
  Impl& m = *impl_;
  m.labels.clear();
  m.present_labels = 0;
  if (face_labels.empty() || static_cast<Eigen::Index>(face_labels.size()) != m.face_count) return;
  m.labels.resize(m.faces.size());
  for (std::size_t i = 0; i < m.faces.size(); ++i) {
    m.labels[i] = face_labels[static_cast<std::size_t>(m.faces[i].id)];
    m.present_labels |= m.labels[i];
  }
}

ClosestPointIndex::ClosestPointIndex() : ClosestPointIndex(Eigen::MatrixX3d(0, 3), Eigen::MatrixX3i(0, 3)) {}

ClosestPointIndex::~ClosestPointIndex() = default;
ClosestPointIndex::ClosestPointIndex(ClosestPointIndex&&) noexcept = default;
ClosestPointIndex& ClosestPointIndex::operator=(ClosestPointIndex&&) noexcept = default;

SurfacePoint ClosestPointIndex::closestPoint(const Eigen::Vector3d& query) const {
  if (!impl_) return {};  // moved-from
  return impl_->query(query, nullptr, ~std::uint64_t{0}, Limits(ClosestPointOptions{}));
}

SurfacePoint ClosestPointIndex::closestPoint(const Eigen::Vector3d& query, const Eigen::Vector3d* normal,
                                             std::uint64_t label_mask, const ClosestPointOptions& options) const {
  if (!impl_) return {};
  return impl_->query(query, normal, label_mask, Limits(options));
}

std::vector<SurfacePoint> ClosestPointIndex::closestPoints(const Eigen::MatrixX3d& queries,
                                                           const ClosestPointOptions& options,
                                                           const ClosestPointFilters& filters) const {
  if (!impl_) return std::vector<SurfacePoint>(static_cast<std::size_t>(queries.rows()));
  assert(filters.normals.rows() == 0 || filters.normals.rows() == queries.rows());
  assert(filters.label_masks.empty() || static_cast<Eigen::Index>(filters.label_masks.size()) == queries.rows());
  return queryRows(queries, options, filters,
                   [this](const Vec3& q, const Vec3* normal, std::uint64_t mask, const Limits& limits) {
                     return impl_->query(q, normal, mask, limits);
                   });
}

std::size_t ClosestPointIndex::memoryBytes() const {
  if (!impl_) return 0;
  const Impl& m = *impl_;
  std::size_t bytes = sizeof(Impl) + m.tree_bytes;
  bytes += m.faces.capacity() * sizeof(Face) + m.labels.capacity() * sizeof(std::uint64_t);
  for (const auto& level : m.levels) bytes += sizeof(Impl::Level) + level->samples.capacity() * sizeof(Sample);
  return bytes;
}

int ClosestPointIndex::faceCount() const { return impl_ ? impl_->indexed_faces : 0; }

// The result's face is 0 (the only triangle); the index calls the same inline
// routine, so both give bit-identical answers for the same corners.
SurfacePoint closestPointOnTriangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                    const Eigen::Vector3d& c) {
  const P3 pa = toP3(a), pb = toP3(b), pc = toP3(c);
  return toSurfacePoint(closestOnTriangle(toP3(p), pa, pb, pc, isWellShaped(pa, pb, pc)), 0);
}

}  // namespace core
