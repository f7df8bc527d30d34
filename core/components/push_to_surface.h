// Push-to-surface: points inside a closed collision surface (a skull proxy
// made of mesh triangles, or an implicit sphere or ellipsoid) pushed out onto it.
#pragma once

#include <Eigen/Core>

#include "core/components/components.h"

namespace core {

// positions: #V by 3 current vertex positions (the triangle surface and the
// shapes' centre bindings are taken from them); triangles: the mesh's #F by 3
// (for face bindings). Each member (push.members; empty: every vertex not on
// the triangle surface) inside the surface moves onto it:
//   kClosest: to the closest surface point (triangles: exact, inside told by
//             the angle-weighted pseudo-normal, Baerentzen & Aanaes 2005;
//             sphere: radially; ellipsoid: radially in its unit-sphere frame)
//   kVector:  along push.vector to where it leaves the surface.
//   kFromPoint: along the ray from push.from through it, to where it leaves
//             the surface (a vertex at push.from stays).
// `levels` (sphere and ellipsoid; empty: all 1): per vertex, the level set
// of the shape's unit-sphere frame it is pushed onto instead, |q| = level
// (surfaceLevels of the rest: keep_rest_depth). Returns #V by 3.
Eigen::MatrixX3d evaluatePushToSurface(const Eigen::MatrixX3d& positions, const Eigen::MatrixX3i& triangles,
                                       const PushToSurface& push, const Eigen::VectorXd& levels = {});

// Sphere and ellipsoid: #V levels, each member's |q| in the shape's
// unit-sphere frame, at most 1 (1 outside, and for non-members): how deep
// it sits.
Eigen::VectorXd surfaceLevels(const Eigen::MatrixX3d& positions, const Eigen::MatrixX3i& triangles,
                              const PushToSurface& push);

}  // namespace core
