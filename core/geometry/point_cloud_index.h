// PointCloudIndex: nearest points of a point cloud (a k-d tree; nanoflann is
// hidden behind PImpl in point_cloud_index.cpp), and what a scan given as
// points alone needs from its neighbourhoods: normals and border points.
#pragma once

#include <limits>
#include <memory>
#include <vector>

#include <Eigen/Core>

namespace core {

class PointCloudIndex {
 public:
  struct Neighbour {
    int index = -1;  // row of the indexed points, -1 when none
    double sq_distance = std::numeric_limits<double>::infinity();
  };

  PointCloudIndex();  // of no points: every query finds none
  // Copies the points (#N by 3); rows with a non-finite coordinate are not indexed.
  explicit PointCloudIndex(const Eigen::MatrixX3d& points);
  ~PointCloudIndex();
  PointCloudIndex(PointCloudIndex&&) noexcept;
  PointCloudIndex& operator=(PointCloudIndex&&) noexcept;
  PointCloudIndex(const PointCloudIndex&) = delete;
  PointCloudIndex& operator=(const PointCloudIndex&) = delete;

  // Const, thread-safe. Ties go to the lower index; a non-finite query finds none.
  Neighbour nearest(const Eigen::Vector3d& query) const;
  // Batch: #Q by 3 queries, parallelFor; result i belongs to row i.
  std::vector<Neighbour> nearest(const Eigen::MatrixX3d& queries) const;
  // The k nearest (fewer when the cloud is smaller), ascending by distance, ties by index.
  std::vector<Neighbour> nearest(const Eigen::Vector3d& query, int k) const;

  int size() const;  // indexed points
  std::size_t memoryBytes() const;  // approximate heap footprint (for cache accounting)

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Unit normals of a cloud from the plane of each point's `k` nearest
// neighbours (the smallest principal axis of their covariance). Their sign is
// arbitrary but deterministic (the largest-magnitude component is positive):
// orient them before use (orientNormalsLike). Zero rows for non-finite points.
Eigen::MatrixX3d estimateCloudNormals(const Eigen::MatrixX3d& points, const PointCloudIndex& index, int k = 12);

// Flips each of `normals` whose dot product with the matching row of
// `reference_normals` is negative; returns how many were flipped.
int orientNormalsLike(Eigen::MatrixX3d& normals, const Eigen::MatrixX3d& reference_normals);

// Points on the border of a cloud sampled from a surface (a crop, a hole):
// seen in its tangent plane, the directions to its `k` nearest neighbours
// leave an angular gap wider than `max_gap_deg` (a point with fewer than two
// such directions is a border point too; one with a zero or non-finite normal
// is not). #N flags (1 = border).
std::vector<char> cloudBorderPoints(const Eigen::MatrixX3d& points, const Eigen::MatrixX3d& normals,
                                    const PointCloudIndex& index, int k = 16, double max_gap_deg = 90.0);

// Points off the least-squares plane of their `k` nearest neighbours (the
// point itself and its exact copies left out) by more than `factor` times
// those neighbours' mean distance to it (spikes: a scanner's outliers). The
// offset must also exceed 0.75 of the neighbours' spacing (the mean distance
// from each to the nearest other: an offset within the sampling's own scale,
// as at a crease or in noise, is not a spike) and 1e-9 of the cloud's
// bounding-box diagonal (so rounding on a noise-free plane is not). #N flags
// (1 = spike).
std::vector<char> cloudSpikes(const Eigen::MatrixX3d& points, const PointCloudIndex& index, int k = 12,
                              double factor = 6.0);

}  // namespace core
