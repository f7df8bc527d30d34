// Open boundaries ("rims": the neck cut, the mouth slit, the eye holes) of
// source and target matched to each other. Closest-point projection pins the
// guide only across the target surface, never along it: on a tube-like part
// (the neck) nothing stops the warped source sliding, so its rim ends short of
// or beyond the target's and the target's rim region is left uncovered. A
// source rim matched to a target rim is put on it instead, which pins the
// slide along the tube.
#pragma once

#include <vector>

#include <Eigen/Core>

#include "core/geometry/closest_point.h"
#include "core/geometry/mesh.h"

namespace core {

// A rim: a closed boundary loop (vertices, the face of each edge, length).
using Rim = BoundaryLoop;

// Closed boundary loops of the mesh with split points welded (copies at one
// position, e.g. along UV seams, are one point: a seam is not a rim), longest
// first. Open chains of an inconsistently wound mesh are left out.
// `representative` is coincidentVertexRepresentatives(mesh.positions), which
// the caller usually needs again (rimVertices).
std::vector<Rim> meshRims(const Mesh& mesh, const std::vector<int>& representative);

struct RimMatchOptions {
  // Rims match when each one's mean distance to the other is within this fraction of the source rim's rms radius,
  double max_mismatch = 1.0;
  // ... their lengths are within this ratio of each other, and each is the other's closest candidate.
  double max_length_ratio = 1.5;
  // Only this many of the longest rims of each mesh are candidates.
  int max_rims = 16;
};

// Per source rim: the index of its target rim, or -1.
std::vector<int> matchRims(const std::vector<Rim>& source_rims, const Eigen::MatrixX3d& warped_source,
                           const std::vector<Rim>& target_rims, const Eigen::MatrixX3d& target_positions,
                           const RimMatchOptions& options = {});

// Per vertex of `mesh`: the rim it lies on (index into `rims`) or -1, and the
// rim's unit tangent there in the loop's direction (zero off the rims). Every
// copy of a split rim point gets its point's (`representative` as for meshRims).
struct RimVertices {
  std::vector<int> rim;
  Eigen::MatrixX3d tangent;
};
RimVertices rimVertices(const std::vector<Rim>& rims, const Mesh& mesh, const std::vector<int>& representative);

// Points off the rims but joined by an edge to a rim point and within
// `fraction` of that point's mean edge length of it (a sliver a remesher
// left at a constrained border: one at 6% of an edge on a remeshed ICT eye)
// join its rim with its tangent, every copy of them alike (`representative`
// as for rimVertices). Returns how many vertices joined.
int addNearRimVertices(RimVertices& on_rim, const Mesh& mesh, const std::vector<int>& representative, double fraction);

// Closest point of `p` on the rim's polyline among the edges running the way
// of `tangent` (dot > 0), as a point on the face owning that edge
// (barycentrics on the edge's two corners); not found when no edge does.
// Both sides of a slit (the lips of a closed mouth) are on one loop, running
// opposite ways: the direction keeps a point of one side off the other.
// `positions`: the rim's mesh's vertices (or the same mesh moved, a guide).
SurfacePoint closestPointOnRim(const Eigen::Vector3d& p, const Eigen::Vector3d& tangent, const Rim& rim,
                               const Eigen::MatrixX3d& positions);

// Points paired along a source rim and its matched target rim: `count`
// points at equal arc-length steps of the source rim as warped
// (`warped_source`), on the source mesh (`source_positions`), and the target
// rim's points at the same arc-length fractions, shifted round the loop by
// the offset that brings the two sets closest (both loops run their faces'
// way). The offset makes the pairs independent of where the warp left the
// rim along the target's: a rim slid round or along a tube still pairs point
// for point.
struct RimPairs {
  Eigen::MatrixX3d source;  // count x 3, on the source mesh
  Eigen::MatrixX3d target;  // count x 3, on the target rim
};
// True when any of `points` lies within `distance` of the rim's polyline.
bool rimNearPoints(const Rim& rim, const Eigen::MatrixX3d& positions, const Eigen::MatrixX3d& points, double distance);

RimPairs pairRimPoints(const Rim& source_rim, const Eigen::MatrixX3d& source_positions,
                       const Eigen::MatrixX3d& warped_source, const Rim& target_rim,
                       const Eigen::MatrixX3d& target_positions, int count);

}  // namespace core
