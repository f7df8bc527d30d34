// A rig's components document carried to the target (papers 000 4.7.2-4.7.3:
// influence objects through the dense correspondence), so the target gets a
// document of its own, bound to its own mesh:
// - every point (locators, cluster pivots, curve and surface control points,
//   muscle origins and insertions, collision centres, lattice boxes) through
//   the dense map; a point bound to the rig's surface is bound to the
//   target's (face + barycentric, at the closest target point), a free one
//   stays free;
// - member weights (clusters) and member sets (wires, lattices, pushes) as
//   the attribute transfer carries fields: interpolated at each target
//   vertex's location, the lip and lid guards and inpainting included;
// - a vertex named alone (a constraint target, a collision triangle's corner)
//   becomes the target vertex nearest where the dense map puts it;
// - lengths (dropoff distances, radii, translations) scaled and directions
//   and rotations turned by the global similarity, as joints' frames are.
#pragma once

#include <Eigen/SparseCore>

#include "core/components/components.h"
#include "core/correspond/correspondence.h"
#include "core/geometry/closest_point.h"
#include "core/solve/inpainting.h"
#include "core/solve/tps.h"

namespace core {

// What the transfer hands the components: the correspondence and the target.
struct ComponentsCorrespondence {
  const Mesh& source_mesh;
  const TpsWarp& dense_map;
  const Mesh& target_mesh;
  const ClosestPointIndex& target_index;      // the target's skin faces
  const TargetLocations& locations;           // each target vertex on the source
  const Eigen::SparseMatrix<double>& target_laplacian;
  const HarmonicInpainting* mismatched;       // null when no target vertex is mismatched
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();  // global, source -> target
  double scale = 1.0;                                      // global, source -> target
};

ComponentsDocument transferComponents(const ComponentsDocument& source, const ComponentsCorrespondence& map);

// The reference's document on a copy of its own topology (the fit, paper 001
// 4.3): bindings by vertex or face, member sets and lone vertices kept
// exactly, so they follow the fitted mesh; free points (position bindings,
// lattice boxes) through `dense_map`; lengths scaled and frames turned by
// the similarity (`rotation`, `scale`), as in a transfer.
ComponentsDocument rebuildComponents(const ComponentsDocument& reference, const TpsWarp& dense_map,
                                     const Eigen::Matrix3d& rotation, double scale);

// Target vertices appended as copies (UV seams carried over: `copy_of[i]` is
// the vertex that vertex `first + i` copies) join every member set their
// original is in, with its weight.
void addVertexCopies(ComponentsDocument& doc, const std::vector<int>& copy_of, int first);

}  // namespace core
