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

#include "core/closest_point.h"
#include "core/mesh.h"

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
  // A source rim (as warped) and a target rim match when each one's mean
  // distance to the other is within this fraction of the source rim's rms
  // radius, their lengths are within max_length_ratio of each other, and each
  // is the other's closest candidate.
  double max_mismatch = 0.5;
  double max_length_ratio = 1.5;
  // Only the longest rims of each side are candidates (a face has a handful;
  // a scan full of small holes or an unwelded soup must not cost a quadratic
  // search).
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

// Closest point of `p` on the rim's polyline among the edges running the way
// of `tangent` (dot > 0), as a point on the face owning that edge
// (barycentrics on the edge's two corners); not found when no edge does.
// Both sides of a slit (the lips of a closed mouth) are on one loop, running
// opposite ways: the direction keeps a point of one side off the other.
SurfacePoint closestPointOnRim(const Eigen::Vector3d& p, const Eigen::Vector3d& tangent, const Rim& rim,
                               const Mesh& mesh);

}  // namespace core
