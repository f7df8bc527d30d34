// Blend shape (morph target) transfer: each target vertex takes the source
// delta interpolated at its location on the source, mapped by a 3x3
// adaptation (rotation, similarity or local Jacobian of the source -> target
// map: "adapted to the target model proportions", papers 000 ch. 4.7) and
// scaled by the exaggeration factor (000 sec. 5.4.2).
#pragma once

#include <map>
#include <string>
#include <vector>

#include "core/correspond/correspondence.h"
#include "core/solve/inpainting.h"
#include "core/rig/rig.h"

namespace core {

struct ShapeTransferOptions {
  Exaggeration exaggeration;  // gain on every delta, by morph target name
};

// adaptation: #Vt matrices (one per target vertex) or a single one for all.
// Normal deltas, when the source has them, are recomputed on the target from
// the transferred position deltas: computeVertexNormals of the displaced
// target minus that of the rest target (not minus target.normals, which may be
// authored: a delta is the change of shading the shape makes, added to
// whatever normals the mesh carries).
// mismatched: the inpainting of the target's mismatched vertices (see
// TargetLocations::mismatched; built once by transferRig), or null when there
// are none.
std::vector<MorphTarget> transferMorphTargets(const std::vector<MorphTarget>& source,
                                              const Eigen::MatrixX3i& source_triangles,
                                              const TargetLocations& locations,
                                              const std::vector<Eigen::Matrix3d>& adaptation, const Mesh& target,
                                              const HarmonicInpainting* mismatched,
                                              const ShapeTransferOptions& options = {});

// The unknown vertices of `inpainting` take position deltas blended from
// their surroundings in every shape (one solve for all), never a copy from
// the wrong lip or lid; those on a piece with no known vertex (an eyeball in
// the face's mesh) have nothing to blend from and do not move. Used for the
// mismatched vertices (above), and for vertices the quality check found
// moving as none of their ring does (transferRig).
void inpaintShapeDeltas(const HarmonicInpainting& inpainting, std::vector<MorphTarget>& shapes);

// Recomputes the normal deltas of every shape that has them (rows > 0) from
// its position deltas, as transferMorphTargets makes them.
void updateNormalDeltas(const Mesh& target, std::vector<MorphTarget>& shapes);

}  // namespace core
