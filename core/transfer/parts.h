// The rig's other meshes (RigPart: eyeballs, teeth, tongue, lashes) carried
// to a target through the dense map, by vertex index: topology, vertex order,
// UVs, attributes and skin weights kept. A part made only of closed pieces
// is a solid (an eyeball, a set of teeth): it moves as one rigid body, the
// similarity that best fits the dense map over its vertices, so an eyeball
// stays a sphere and a tooth a tooth. Any other part (lashes, gums and
// tongue: open sheets) deforms, each vertex through the dense map
// (isSolid, core/geometry/mesh.h, tells them apart).
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "core/rig/rig.h"
#include "core/solve/tps.h"

namespace core {

struct CarriedPart {
  std::string name;
  bool rigid = false;         // moved as one rigid body (all its pieces closed)
  double scale = 1.0;         // a rigid part's similarity scale
  double fit_residual = 0.0;  // rms of the dense map about that similarity, model units (0 when deformed)
  // At rest, vertices standing in front of the face's skin (core/transfer/
  // parts_occlusion.h): the carried part on the target's face, and the rig's
  // part on its own. -1: not checked (no forward axis from the landmarks).
  int vertices_in_front = -1;
  int source_vertices_in_front = -1;
};

struct CarriedParts {
  std::vector<RigPart> parts;
  std::vector<CarriedPart> report;  // one per part
};

// `delta_adaptation(p)`: the 3x3 map of a deforming part's shape delta at
// source point p (the transfer's `adaptation`); a rigid part's deltas turn and
// scale with its body. `normal_rotation` turns a deforming part's normal deltas.
CarriedParts carryParts(const std::vector<RigPart>& parts, const TpsWarp& dense_map,
                        const std::function<Eigen::Matrix3d(const Eigen::Vector3d&)>& delta_adaptation,
                        const Eigen::Matrix3d& normal_rotation);

// What a rig without shapes or without a skin keeps of its parts: their
// shapes dropped when `shapes` is off, their weights when there is no skin.
void dropPartChannels(std::vector<RigPart>& parts, bool shapes, bool skinned);

}  // namespace core
