// Landmark-free alignment of a head scan to the reference (docs/FIT.md 2.2):
// for a head scanned roughly upright (turned up to ~45 degrees about the
// vertical and ~20 about the others), a similarity found by trimmed ICP from
// a grid of yaw/pitch starts, scan -> reference, the best kept. Each ICP step
// is a point-to-plane similarity step on the kept pairs, weighted by the
// reference's vertex density (its densely meshed face counts as its vertices do).
#pragma once

#include <memory>
#include <vector>

#include <Eigen/Core>

#include "core/base/error.h"
#include "core/geometry/closest_point.h"
#include "core/geometry/mesh.h"
#include "core/geometry/similarity.h"

namespace core {

// What the search needs of the reference, prepared once per reference rig.
struct SearchReference {
  Eigen::MatrixX3d positions;      // #V reference vertices (reference units)
  Eigen::MatrixX3d normals;        // #V unit normals
  Eigen::MatrixX3i triangles;
  std::shared_ptr<const ClosestPointIndex> index;  // closest points on the reference's faces
  Eigen::Vector3d front_centroid = Eigen::Vector3d::Zero();  // centroid of the vertices facing +Z
  double rms_radius = 0.0;         // about the centroid of all vertices
  double diagonal = 0.0;           // bounding-box diagonal
  std::size_t memoryBytes() const;
};

// The reference must look down +Z with +Y up (glTF's convention; ICT, paper 001's Murphy).
SearchReference prepareSearchReference(const Mesh& reference);

struct SearchOptions {
  double max_yaw_deg = 60.0;       // start hypotheses span +-this about the vertical (Y), step yaw_step_deg
  double yaw_step_deg = 15.0;
  double max_tilt_deg = 15.0;      // pitch starts: -this, 0, +this
  int coarse_samples = 200;        // scan points per hypothesis (farthest-point sample)
  int coarse_iterations = 8;       // a start reaching an earlier start's pose stops there (one basin)
  int refined_hypotheses = 3;      // the best this many distinct (> 10 degrees apart) continue
  int fine_samples = 2000;
  int fine_iterations = 20;        // at most: ICP stops once a step moves the pose < 0.02 degrees
  double keep_fraction = 0.7;      // trimmed ICP: the closest this share of pairs fits each step
  double max_normal_angle_deg = 60.0;  // pairs whose normals differ more are dropped (unsigned when not oriented)
};

struct SearchAlignment {
  Similarity reference_to_scan;    // scan ~= scale * rotation * reference + translation
  double trimmed_rms = 0.0;        // of the kept pairs, reference units
  double inlier_fraction = 0.0;    // scan sample points within 0.006 of the reference diagonal after the fit (normals agreeing)
  double score = 0.0;              // trimmed_rms / diagonal + (1 - inlier_fraction); lower is better
  // The best refined hypothesis that ended more than 10 degrees from the
  // chosen one; both 0 when every refined start ended in the chosen one's basin.
  double runner_up_score = 0.0;
  double runner_up_angle_deg = 0.0;
  int hypotheses = 0;              // starts tried
};

// scan_points: #N by 3 in the scan's frame and units (any scale);
// scan_normals: #N unit normals or 0 rows; normals_oriented: false when their
// sign is arbitrary (a cloud's estimated normals). usable: empty or #N, 0 for
// points not to sample (spikes, detached pieces). Errors: fewer than 100 usable points.
Result<SearchAlignment> alignBySearch(const SearchReference& reference, const Eigen::MatrixX3d& scan_points,
                                      const Eigen::MatrixX3d& scan_normals, bool normals_oriented,
                                      const std::vector<char>& usable, const SearchOptions& options = {});

}  // namespace core
