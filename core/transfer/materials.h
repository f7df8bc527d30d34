// The face's materials on the target's triangles (transfer: the target keeps
// its own topology and UVs). Parts keep theirs as they are (same triangles).
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

#include "core/geometry/closest_point.h"
#include "core/rig/rig.h"

namespace core {

// Per target triangle, the material most of its corners lie on in the source
// (`on_source`: the dense correspondence, one point per target vertex);
// corners without a location vote for nothing, and a triangle with none takes
// the material most of the source face uses. Empty when the source has none.
std::vector<int> carryTriangleMaterials(const std::vector<int>& source_triangle_materials,
                                        const Eigen::MatrixX3i& target_triangles,
                                        const std::vector<SurfacePoint>& on_source);

// A texture is laid out on the source's UVs, which the target does not have:
// the face's textured materials lose their textures in `rig` (a material the
// parts share stays textured for them, the face gets a copy), images nothing
// uses any more are dropped. Returns a warning per material changed.
std::vector<std::string> untextureFaceMaterials(Rig& rig);

}  // namespace core
