// Dense correspondence (papers 004 sec. 3.3 "STK", 000 ch. 4.7.1): the warped
// source surface is stuck onto the target by closest-point projection, giving
// the guide model (source topology lying on the target surface); then every
// target vertex is located on the guide, i.e. on the source surface.
#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "core/geometry/closest_point.h"
#include "core/geometry/moving_mesh_index.h"
#include "core/geometry/mesh.h"
#include "core/correspond/opening_sides.h"

namespace core {

struct ProjectionOptions {
  // Target faces whose normal differs more than this (degrees) from the warped source vertex's are not candidates.
  double max_normal_angle_deg = 160.0;
  // Candidates beyond this fraction of the target bbox diagonal are ignored (the vertex stays warped, unmatched).
  double max_distance = 0.1;
};

// The source surface lying on the target.
struct GuideModel {
  Eigen::MatrixX3d positions;          // #Vs by 3: projected position, or the warped one when unmatched
  std::vector<SurfacePoint> on_target; // #Vs: target face + barycentric (face -1 when unmatched)
  Eigen::VectorXd distance;            // #Vs: warped source vertex -> guide position, target units
  int unmatched = 0;                   // source vertices with no compatible target face in range
};

// Region-constrained matching, when source and target both carry region
// labels (Mesh::regions, the same label numbers on both): a vertex may only
// match faces touching its region, i.e. with a corner of its label. Faces
// across a region border belong to both sides, so borders stay reachable,
// while a lower-lip vertex can never reach an upper-lip face however close.
// Face label sets (bit l: a corner has label l) and vertex label bits, as the
// ClosestPointIndex label filter takes them.
std::vector<std::uint64_t> faceRegionSets(const Eigen::VectorXi& vertex_regions, const Eigen::MatrixX3i& triangles);
std::vector<std::uint64_t> vertexRegionBits(const Eigen::VectorXi& vertex_regions);

// warped_positions / warped_normals: #Vs by 3, the source after the warp.
// region_masks: empty, or the vertexRegionBits of each row's source vertex
// (the index must then carry the target's faceRegionSets).
GuideModel projectToTarget(const Eigen::MatrixX3d& warped_positions, const Eigen::MatrixX3d& warped_normals,
                           const ClosestPointIndex& target_index, double target_diagonal,
                           const ProjectionOptions& options, std::vector<std::uint64_t> region_masks = {});

// How the target's faces face, seen from the warped source: the mean over
// the given points (warped source vertices, a sample chosen by the caller)
// of the sign of (their normal . normal of the closest target face,
// unfiltered). About +1 when the target's winding agrees with the source's,
// about -1 when it is reversed (faces inside out, or a warp that mirrors the
// source onto an unmirrored mesh), near 0 when the target's own winding is
// inconsistent. 0 when nothing matched.
double faceOrientationAgreement(const Eigen::MatrixX3d& warped_points, const Eigen::MatrixX3d& warped_normals,
                                const ClosestPointIndex& target_index, const Mesh& target);

// Sliding centres (Bookstein's sliding semilandmarks). Closest-point
// projection settles where a dense-map centre lies across the target surface
// but not where along it: that stays wherever the landmark warp put it. Here
// the rows of `targets` listed in `sliding` move within their tangent planes
// (plane normal: the matching row of `normals`), the other rows stay, so that
// the bending energy tr(Y^T B Y) of the spline through the result is least
// (`bending`: TpsFactorization::bendingEnergyMatrix of the centres).
// Conjugate gradients, at most `iterations`. A row with a zero or non-finite
// normal stays. The moved points leave a curved surface by the curvature over
// the slide: project them back.
Eigen::MatrixX3d slideInTangentPlanes(const Eigen::MatrixXd& bending, const Eigen::MatrixX3d& targets,
                                      const std::vector<int>& sliding, const Eigen::MatrixX3d& normals,
                                      int iterations = 30);

// Triangles of the guide whose orientation flips against the warped source
// (folds of plain projection) and triangles that collapse to zero area.
struct FoldReport {
  int flipped = 0;
  int collapsed = 0;
  std::vector<int> flipped_faces;  // ascending
};
FoldReport countFolds(const Eigen::MatrixX3d& warped_positions, const Eigen::MatrixX3d& guide_positions,
                      const Eigen::MatrixX3i& triangles);

struct LocateOptions {
  // Guide faces whose normal differs more than this (degrees) from the target vertex's are not candidates.
  double max_normal_angle_deg = 90.0;
  // Confidence falls linearly to 0 at this distance (fraction of the target bbox diagonal): "low confidence".
  double low_confidence_distance = 0.05;
  // ... and at this normal disagreement (degrees).
  double low_confidence_angle_deg = 30.0;
  // Also low confidence: farther from the guide than this many mean incident edge lengths. 0 disables.
  double max_relative_distance = 0.5;
  // Near an opening (target_sides): a location whose normal differs more yields to one within an edge that agrees.
  double opening_normal_angle_deg = 45.0;
};

// Every target vertex located on the guide = on the source surface.
struct TargetLocations {
  std::vector<SurfacePoint> on_source;  // #Vt: source face + barycentric (face -1: no compatible guide face)
  Eigen::VectorXd distance;             // #Vt: target vertex -> guide surface, target units
  Eigen::VectorXd normal_cosine;        // #Vt: cos(angle) target vertex normal vs guide face normal
  Eigen::VectorXd confidence;           // #Vt in [0, 1]: 1 = on the guide with agreeing normal
  // #Vt, 1 where the location must not be used at all: no compatible guide
  // face, or matched across a thin gap (max_relative_distance). Values there
  // are inpainted; other low-confidence vertices keep their (sharp) values.
  Eigen::VectorXi mismatched;
  int low_confidence = 0;               // vertices beyond a threshold (confidence 0)
  // #Vt or empty: the detached piece (closed, no landmark on it: an eyeball,
  // teeth) each vertex is on, numbered from 0, or -1 on the skin. Set by the
  // warp job; such vertices are also low-confidence and mismatched.
  std::vector<int> detached_piece;
};

// guide_faces: the source's faces (MovingMeshIndex, built once per rig), whose
// vertices are at guide_positions. source_face_labels and target_masks: both
// empty, or the source's face label sets and each target vertex's label bits
// (faceRegionSets and vertexRegionBits, or sideFaceSets and sideMasks): each
// target vertex is located only on guide faces sharing a bit with it.
// target_sides: empty, or openingSides of the target (vertices near an
// opening take a location whose normal agrees, see
// LocateOptions::opening_normal_angle_deg). target_representative: the
// target's coincidentVertexRepresentatives when the caller has them (null:
// computed here).
TargetLocations locateOnGuide(const Mesh& target, const Eigen::MatrixX3d& guide_positions,
                              const MovingMeshIndex& guide_faces, const LocateOptions& options,
                              const std::vector<std::uint64_t>& source_face_labels = {},
                              const std::vector<std::uint64_t>& target_masks = {},
                              const std::vector<int>& target_sides = {},
                              const std::vector<int>* target_representative = nullptr);

// Farthest-point sample of `count` vertices (deterministic, starting from the
// vertex nearest the centroid). Used for the dense-map centres.
std::vector<int> farthestPointSample(const Eigen::MatrixX3d& positions, int count);

}  // namespace core
