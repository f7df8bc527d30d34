// MovingMeshIndex: exact closest point on a mesh whose vertices move while
// its faces stay: the rig's source surface carried onto each target (the
// guide). Which faces are grouped together depends only on the faces and the
// rest positions, so that hierarchy is built once per rig; each job fits its
// bounding boxes to the new positions in one pass and queries it (0.7 ms for
// the ICT face's 22k faces, against ~4.2 ms to build a ClosestPointIndex on
// them; its queries are ~15% slower). Answers equal a brute-force scan with
// closestPointOnTriangle() and ClosestPointIndex's on the same positions: same
// faces, barycentrics and distances, ties to the lower face index, the same
// filters.
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include <Eigen/Core>

#include "core/geometry/closest_point.h"

namespace core {

class MovingMeshIndex {
 public:
  // rest_positions: #V by 3; triangles: #F by 3 (indices into the positions
  // every fit() is given).
  MovingMeshIndex(const Eigen::MatrixX3d& rest_positions, const Eigen::MatrixX3i& triangles);
  ~MovingMeshIndex();
  MovingMeshIndex(MovingMeshIndex&&) noexcept;
  MovingMeshIndex& operator=(MovingMeshIndex&&) noexcept;
  MovingMeshIndex(const MovingMeshIndex&) = delete;
  MovingMeshIndex& operator=(const MovingMeshIndex&) = delete;

  // The faces at `positions` (#V by 3, the same vertices), ready for queries.
  // Degenerate faces there (repeated corners, twice-area below
  // (1e-10 * diagonal)^2, non-finite corners) are skipped, as by
  // ClosestPointIndex. face_labels: empty, or #F label bit sets as for
  // ClosestPointIndex. Refers to this index, which must outlive it.
  class Fitted {
   public:
    ~Fitted();
    Fitted(Fitted&&) noexcept;
    Fitted& operator=(Fitted&&) noexcept;
    Fitted(const Fitted&) = delete;
    Fitted& operator=(const Fitted&) = delete;

    // As ClosestPointIndex::closestPoints: #Q by 3 queries, multi-threaded;
    // result i belongs to row i.
    std::vector<SurfacePoint> closestPoints(const Eigen::MatrixX3d& queries, const ClosestPointOptions& options = {},
                                            const ClosestPointFilters& filters = {}) const;
    int faceCount() const;  // usable (non-degenerate) faces at these positions

   private:
    friend class MovingMeshIndex;
    struct Impl;
    explicit Fitted(std::unique_ptr<Impl> impl);
    std::unique_ptr<Impl> impl_;
  };
  Fitted fit(const Eigen::MatrixX3d& positions, const std::vector<std::uint64_t>& face_labels = {}) const;

  const Eigen::MatrixX3i& triangles() const;
  std::size_t memoryBytes() const;  // approximate heap footprint (for cache accounting)

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace core
