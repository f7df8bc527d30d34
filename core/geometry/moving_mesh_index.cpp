// Bounding-volume hierarchy over a fixed set of faces: binary, each range of
// rest-pose face centroids cut at the middle of its longest extent, leaves of
// at most kLeafFaces faces. fit() recomputes the faces (as ClosestPointIndex
// stores them) and every node's axis-aligned box from the new positions,
// children before parents. A query descends nearest box first and skips a
// node whose box is farther than the best face so far; the box bound is exact
// up to a relative 1e-9 of slack, so rounding never drops a tie. The tree
// stays valid however far the vertices move (boxes only grow looser), which
// is what lets it be built once per rig: the guide is the source warped by a
// smooth map, so its faces stay grouped about as well as at rest. Measured on
// the ICT guide (22k faces; 1 thread, medians of 15): built once 1.3 ms, fit
// 0.7 ms, 5.9k located target vertices 4.7 ms, against 4.2 ms to build a
// ClosestPointIndex on the guide and 4.0 ms for the same queries on it.
// Tried: median splits (queries 0.8 ms faster on the 5.9k, build 3.1 ms),
// Morton-order splits (build 1.1 ms, queries 20% slower), float boxes in the
// nodes (slower), a bounding ball per face before the plane test (no gain),
// leaves of 2 or 8 faces (slower), both children's boxes stored in the
// parent (3% faster queries: not worth a second layout).
#include "core/geometry/moving_mesh_index.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <utility>

#include "core/geometry/mesh.h"
#include "core/geometry/point_triangle.h"

namespace core {
namespace {

using namespace point_triangle;

// Faces per leaf (2 and 8 are slower on the ICT guide).
constexpr int kLeafFaces = 4;
// Levels split at the middle of the extent before median splits take over
// (which bounds the depth, and so a query's stack).
constexpr int kMidpointDepth = 32;
// Box bounds are compared with this much slack (relative, on squared
// distances) so that rounding in the box distance never prunes a face that
// ties the best.
constexpr double kBoxSlack = 1.0 + 1e-9;

struct Node {
  std::int32_t child = -1;  // first of two adjacent children; -1: a leaf
  std::int32_t first = 0;   // leaf: its faces are order[first, first + count)
  std::int32_t count = 0;
};

struct Box {
  double lo[3] = {std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity(),
                  std::numeric_limits<double>::infinity()};
  double hi[3] = {-std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity(),
                  -std::numeric_limits<double>::infinity()};
  void add(const P3& p) {
    lo[0] = std::min(lo[0], p.x);
    lo[1] = std::min(lo[1], p.y);
    lo[2] = std::min(lo[2], p.z);
    hi[0] = std::max(hi[0], p.x);
    hi[1] = std::max(hi[1], p.y);
    hi[2] = std::max(hi[2], p.z);
  }
  void add(const Box& b) {
    for (int k = 0; k < 3; ++k) {
      lo[k] = std::min(lo[k], b.lo[k]);
      hi[k] = std::max(hi[k], b.hi[k]);
    }
  }
  // Squared distance from q to the box (0 inside; infinite for an empty box).
  double squaredDistance(const P3& q) const {
    const double dx = std::max({lo[0] - q.x, 0.0, q.x - hi[0]});
    const double dy = std::max({lo[1] - q.y, 0.0, q.y - hi[1]});
    const double dz = std::max({lo[2] - q.z, 0.0, q.z - hi[2]});
    return dx * dx + dy * dy + dz * dz;
  }
  // Squared distance from q to the box's centre.
  double squaredCentreDistance(const P3& q) const {
    const double dx = q.x - 0.5 * (lo[0] + hi[0]);
    const double dy = q.y - 0.5 * (lo[1] + hi[1]);
    const double dz = q.z - 0.5 * (lo[2] + hi[2]);
    return dx * dx + dy * dy + dz * dz;
  }
};

}  // namespace

struct MovingMeshIndex::Impl {
  Eigen::MatrixX3i triangles;
  std::vector<Node> nodes;           // nodes[0] is the root; parents before children
  std::vector<std::int32_t> order;   // face numbers in leaf order
};

struct MovingMeshIndex::Fitted::Impl {
  const MovingMeshIndex::Impl* hierarchy = nullptr;
  std::vector<Face> faces;              // in leaf order; id -1: unusable at these positions
  std::vector<Box> boxes;               // per node
  std::vector<std::uint64_t> labels;    // in leaf order; empty: no labels given
  std::uint64_t present_labels = 0;
  double max_abs = 0.0;                 // largest vertex coordinate magnitude
  int usable_faces = 0;

  SurfacePoint query(const Vec3& qv, const Vec3* normal, std::uint64_t label_mask, const Limits& limits) const;
};

MovingMeshIndex::MovingMeshIndex(const Eigen::MatrixX3d& rest_positions, const Eigen::MatrixX3i& triangles)
    : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  m.triangles = triangles;
  const auto nf = static_cast<std::int32_t>(triangles.rows());
  m.order.resize(static_cast<std::size_t>(nf));
  m.nodes.reserve(2 * static_cast<std::size_t>(nf) / kLeafFaces + 1);
  m.nodes.emplace_back();
  if (nf == 0) return;
  // Centroids decide only the grouping (not the answers), so floats do; a
  // non-finite one counts as the origin so that the ordering below stays a
  // strict one. Each face's centroid travels with it through the splits
  // (contiguous, no indirection).
  struct Item {
    std::array<float, 3> centroid;
    std::int32_t face;
  };
  std::vector<Item> items(static_cast<std::size_t>(nf));
  for (std::int32_t f = 0; f < nf; ++f) {
    Item& item = items[static_cast<std::size_t>(f)];
    item.face = f;
    for (int k = 0; k < 3; ++k) {
      const double c = (rest_positions(triangles(f, 0), k) + rest_positions(triangles(f, 1), k) +
                        rest_positions(triangles(f, 2), k)) / 3.0;
      constexpr double kFloatMax = std::numeric_limits<float>::max();
      item.centroid[static_cast<std::size_t>(k)] = std::isfinite(c) ? static_cast<float>(std::clamp(c, -kFloatMax, kFloatMax)) : 0.0f;
    }
  }
  struct Range {
    std::int32_t node, begin, end, depth;
  };
  std::vector<Range> pending{{0, 0, nf, 0}};
  while (!pending.empty()) {
    const Range r = pending.back();
    pending.pop_back();
    if (r.end - r.begin <= kLeafFaces) {
      m.nodes[static_cast<std::size_t>(r.node)].first = r.begin;
      m.nodes[static_cast<std::size_t>(r.node)].count = r.end - r.begin;
      continue;
    }
    std::array<float, 3> lo = items[static_cast<std::size_t>(r.begin)].centroid, hi = lo;
    for (std::int32_t i = r.begin; i < r.end; ++i) {
      const auto& c = items[static_cast<std::size_t>(i)].centroid;
      for (std::size_t k = 0; k < 3; ++k) {
        lo[k] = std::min(lo[k], c[k]);
        hi[k] = std::max(hi[k], c[k]);
      }
    }
    std::size_t axis = 0;
    for (std::size_t k = 1; k < 3; ++k) {
      if (hi[k] - lo[k] > hi[axis] - lo[axis]) axis = k;
    }
    // Split at the middle of the centroids' extent (one partition pass: as
    // good for queries as a median split here, and a third of its build
    // time). Below kMidpointDepth levels (centroids spread so unevenly that
    // each cut peels off a few faces), and when all fall on one side, split
    // at the median instead: the depth stays below kMidpointDepth + log2(faces).
    std::int32_t mid = r.begin;
    if (r.depth < kMidpointDepth) {
      const float cut = 0.5f * (lo[axis] + hi[axis]);
      const auto split = std::partition(items.begin() + r.begin, items.begin() + r.end,
                                        [axis, cut](const Item& item) { return item.centroid[axis] < cut; });
      mid = static_cast<std::int32_t>(split - items.begin());
    }
    if (mid == r.begin || mid == r.end) {
      mid = r.begin + (r.end - r.begin) / 2;
      std::nth_element(items.begin() + r.begin, items.begin() + mid, items.begin() + r.end,
                       [axis](const Item& a, const Item& b) {
                         return a.centroid[axis] < b.centroid[axis] ||
                                (a.centroid[axis] == b.centroid[axis] && a.face < b.face);
                       });
    }
    const auto child = static_cast<std::int32_t>(m.nodes.size());
    m.nodes[static_cast<std::size_t>(r.node)].child = child;
    m.nodes.emplace_back();
    m.nodes.emplace_back();
    pending.push_back({child + 1, mid, r.end, r.depth + 1});
    pending.push_back({child, r.begin, mid, r.depth + 1});
  }
  for (std::size_t i = 0; i < items.size(); ++i) m.order[i] = items[i].face;
}

MovingMeshIndex::~MovingMeshIndex() = default;
MovingMeshIndex::MovingMeshIndex(MovingMeshIndex&&) noexcept = default;
MovingMeshIndex& MovingMeshIndex::operator=(MovingMeshIndex&&) noexcept = default;

const Eigen::MatrixX3i& MovingMeshIndex::triangles() const { return impl_->triangles; }

std::size_t MovingMeshIndex::memoryBytes() const {
  if (!impl_) return 0;
  return sizeof(Impl) + static_cast<std::size_t>(impl_->triangles.size()) * sizeof(int) +
         impl_->nodes.capacity() * sizeof(Node) + impl_->order.capacity() * sizeof(std::int32_t);
}

MovingMeshIndex::Fitted MovingMeshIndex::fit(const Eigen::MatrixX3d& positions,
                                             const std::vector<std::uint64_t>& face_labels) const {
  auto fitted = std::make_unique<Fitted::Impl>();
  Fitted::Impl& m = *fitted;
  const Impl& h = *impl_;
  m.hierarchy = &h;
  const auto nf = static_cast<std::size_t>(h.triangles.rows());
  const bool labelled = face_labels.size() == nf && nf > 0;
  const double degenerate_eps = 1e-10 * boundingBoxDiagonal(positions);
  m.max_abs = positions.rows() > 0 ? positions.cwiseAbs().maxCoeff() : 0.0;
  m.faces.resize(nf);
  if (labelled) m.labels.resize(nf);
  for (std::size_t i = 0; i < nf; ++i) {
    const std::int32_t f = h.order[i];
    Face& face = m.faces[i];
    if (makeFace(positions, h.triangles, f, degenerate_eps, face)) {
      ++m.usable_faces;
    } else {
      face.id = -1;
    }
    if (labelled) {
      m.labels[i] = face_labels[static_cast<std::size_t>(f)];
      if (face.id >= 0) m.present_labels |= m.labels[i];
    }
  }
  m.boxes.assign(h.nodes.size(), Box{});
  for (std::size_t k = h.nodes.size(); k-- > 0;) {
    const Node& node = h.nodes[k];
    Box& box = m.boxes[k];
    if (node.child >= 0) {
      box.add(m.boxes[static_cast<std::size_t>(node.child)]);
      box.add(m.boxes[static_cast<std::size_t>(node.child) + 1]);
      continue;
    }
    for (std::int32_t i = node.first; i < node.first + node.count; ++i) {
      const Face& face = m.faces[static_cast<std::size_t>(i)];
      if (face.id < 0) continue;
      box.add(face.a);
      box.add(face.b);
      box.add(face.c);
    }
  }
  return Fitted(std::move(fitted));
}

SurfacePoint MovingMeshIndex::Fitted::Impl::query(const Vec3& qv, const Vec3* normal, std::uint64_t label_mask,
                                                  const Limits& limits) const {
  if (usable_faces == 0 || !qv.allFinite() || !(limits.max_distance >= 0.0)) return {};
  const bool use_labels = !labels.empty();
  if (use_labels && (label_mask & present_labels) == 0) return {};
  const P3 q = toP3(qv);
  const bool use_normal = normal != nullptr && limits.min_cos > -2.0;
  const P3 n = use_normal ? toP3(*normal) : P3{0.0, 0.0, 0.0};
  const double plane_eps = 1e-12 * (qv.cwiseAbs().maxCoeff() + max_abs);
  double best_sq = std::numeric_limits<double>::infinity();
  if (std::isfinite(limits.max_distance)) best_sq = limits.max_distance * limits.max_distance;
  TriHit best;
  int best_face = -1;
  // Depth < kMidpointDepth + log2(faces) + 1 <= 64, and each visit pops one
  // entry and pushes at most two.
  struct Entry {
    std::int32_t node;
    double sq_distance;
  };
  std::array<Entry, 96> stack;
  int top = 0;
  const std::vector<Node>& nodes = hierarchy->nodes;
  stack[top++] = {0, boxes[0].squaredDistance(q)};
  while (top > 0) {
    const Entry e = stack[--top];
    if (e.sq_distance > best_sq * kBoxSlack) continue;  // the best improved since it was pushed
    const Node& node = nodes[static_cast<std::size_t>(e.node)];
    if (node.child >= 0) {
      const std::int32_t a = node.child, b = node.child + 1;
      const double da = boxes[static_cast<std::size_t>(a)].squaredDistance(q);
      const double db = boxes[static_cast<std::size_t>(b)].squaredDistance(q);
      // The nearer child is pushed last, so visited first. A query inside
      // both boxes (on the surface, the usual case) goes to the one whose
      // centre is nearer: 20% fewer exact face tests on the ICT guide.
      const bool a_first = da < db || (da == db && boxes[static_cast<std::size_t>(a)].squaredCentreDistance(q) <=
                                                       boxes[static_cast<std::size_t>(b)].squaredCentreDistance(q));
      const Entry near = a_first ? Entry{a, da} : Entry{b, db};
      const Entry far = a_first ? Entry{b, db} : Entry{a, da};
      if (far.sq_distance <= best_sq * kBoxSlack) stack[top++] = far;
      if (near.sq_distance <= best_sq * kBoxSlack) stack[top++] = near;
      continue;
    }
    for (std::int32_t i = node.first; i < node.first + node.count; ++i) {
      const Face& face = faces[static_cast<std::size_t>(i)];
      if (face.id < 0) continue;
      if (use_labels && (labels[static_cast<std::size_t>(i)] & label_mask) == 0) continue;
      if (use_normal && dot(face.n, n) < limits.min_cos) continue;
      // Distance to the face's plane: a cheap lower bound (well-shaped faces
      // only, whose normal is accurate), as in ClosestPointIndex.
      if (face.well_shaped) {
        const double plane = std::abs(dot(face.n, q - face.a)) - plane_eps;
        if (plane > 0.0 && plane * plane > best_sq) continue;
      }
      const TriHit r = closestOnTriangle(q, face.a, face.b, face.c, face.well_shaped);
      if (r.sq_distance < best_sq || (r.sq_distance == best_sq && (best_face < 0 || face.id < best_face))) {
        best = r;
        best_face = face.id;
        best_sq = r.sq_distance;
      }
    }
  }
  return best_face < 0 ? SurfacePoint{} : toSurfacePoint(best, best_face);
}

MovingMeshIndex::Fitted::Fitted(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
MovingMeshIndex::Fitted::~Fitted() = default;
MovingMeshIndex::Fitted::Fitted(Fitted&&) noexcept = default;
MovingMeshIndex::Fitted& MovingMeshIndex::Fitted::operator=(Fitted&&) noexcept = default;

int MovingMeshIndex::Fitted::faceCount() const { return impl_ ? impl_->usable_faces : 0; }

std::vector<SurfacePoint> MovingMeshIndex::Fitted::closestPoints(const Eigen::MatrixX3d& queries,
                                                                 const ClosestPointOptions& options,
                                                                 const ClosestPointFilters& filters) const {
  if (!impl_) return std::vector<SurfacePoint>(static_cast<std::size_t>(queries.rows()));
  return queryRows(queries, options, filters,
                   [this](const Vec3& q, const Vec3* normal, std::uint64_t mask, const Limits& limits) {
                     return impl_->query(q, normal, mask, limits);
                   });
}

}  // namespace core
