// ClosestPointIndex: exact closest point on a triangle mesh (not nearest vertex).
// nanoflann is hidden behind PImpl in core/geometry/closest_point.cpp.
#pragma once

#include <cstdint>
#include <limits>
#include <memory>
#include <vector>

#include <Eigen/Core>

namespace core {

// A location on a mesh surface.
struct SurfacePoint {
  int face = -1;                                    // triangle index, -1 when no compatible face was found
  Eigen::Vector3d barycentric = Eigen::Vector3d::Zero();  // weights of the triangle's 3 corners, sum 1
  Eigen::Vector3d point = Eigen::Vector3d::Zero();  // closest point, model units
  double sq_distance = std::numeric_limits<double>::infinity();  // squared distance query -> point
  bool found() const { return face >= 0; }
};

struct ClosestPointOptions {
  // Reject faces whose normal differs from the query normal by more than this
  // (degrees). Only applies when query normals are given; >= 180 disables it.
  double max_normal_angle_deg = 180.0;
  // Faces farther than this (model units) are never returned; infinity = no limit.
  double max_distance = std::numeric_limits<double>::infinity();
};

// Per-query filters for batch queries; empty members mean "no filter".
struct ClosestPointFilters {
  Eigen::MatrixX3d normals;                // #Q by 3 unit query normals (normal-compatibility filter)
  std::vector<std::uint64_t> label_masks;  // #Q label bit sets: face f is allowed iff it shares a bit with face_labels[f]
};

class ClosestPointIndex {
 public:
  // positions: #V by 3; triangles: #F by 3. face_labels: empty, or #F bit
  // sets of region labels (bit l for label l in [0, 63]; a face may carry
  // several, e.g. the labels of its corners) used by the label filter: a
  // face with an empty set is never returned to a filtered query.
  // Degenerate triangles are skipped.
  ClosestPointIndex(const Eigen::MatrixX3d& positions, const Eigen::MatrixX3i& triangles,
                    std::vector<std::uint64_t> face_labels = {});
  ClosestPointIndex();  // of no faces: every query finds none
  ~ClosestPointIndex();
  ClosestPointIndex(ClosestPointIndex&&) noexcept;
  ClosestPointIndex& operator=(ClosestPointIndex&&) noexcept;
  ClosestPointIndex(const ClosestPointIndex&) = delete;
  ClosestPointIndex& operator=(const ClosestPointIndex&) = delete;

  // Replaces the face label sets (as given to the constructor; empty: no
  // labels) without rebuilding the hierarchy. Not thread-safe: before queries.
  void setFaceLabels(std::vector<std::uint64_t> face_labels);

  // Unfiltered query (const, thread-safe).
  SurfacePoint closestPoint(const Eigen::Vector3d& query) const;

  // Filtered query: `normal` (unit) may be nullptr; `label_mask` = ~0 allows
  // every labelled face.
  SurfacePoint closestPoint(const Eigen::Vector3d& query, const Eigen::Vector3d* normal, std::uint64_t label_mask,
                            const ClosestPointOptions& options) const;

  // Batch: #Q by 3 queries, multi-threaded; result i belongs to row i.
  std::vector<SurfacePoint> closestPoints(const Eigen::MatrixX3d& queries, const ClosestPointOptions& options = {},
                                          const ClosestPointFilters& filters = {}) const;

  std::size_t memoryBytes() const;  // approximate heap footprint (for cache accounting)
  int faceCount() const;            // indexed (non-degenerate) faces

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Exact closest point of `p` on triangle (a, b, c): point and barycentrics.
// Robust to degenerate (collinear) triangles. Used by the index and by tests as
// the brute-force reference.
SurfacePoint closestPointOnTriangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                    const Eigen::Vector3d& c);

}  // namespace core
