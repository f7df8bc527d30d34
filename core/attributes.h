// Vertex attribute transfer (papers 004 sec. 3.5): integer labels by
// barycentric-weighted majority, float fields by interpolation, UV sets with
// the source's seams (the target split where a seam crosses it).
#pragma once

#include <Eigen/SparseCore>

#include "core/correspondence.h"
#include "core/inpainting.h"
#include "core/rig.h"

namespace core {

// Labels, fields and colours (UV sets: transferUvLayout). Mismatched target
// vertices (see TargetLocations) take labels by majority of their neighbours
// (target_laplacian: uniformLaplacian of the target, as the adjacency; may be
// empty when no vertex is mismatched) and fields/colours by harmonic
// inpainting (`mismatched`, null when no vertex is mismatched).
VertexAttributes transferAttributes(const Mesh& source_mesh, const VertexAttributes& source,
                                    const TargetLocations& locations, const Eigen::SparseMatrix<double>& target_laplacian,
                                    const HarmonicInpainting* mismatched);

// The source's UV sets on the target, seams and all. Each target triangle
// takes its UVs from one side of any source seam: a corner whose location is
// on that side (reachable across source edges whose ends carry one UV in
// every set) interpolates it; a corner across the seam extends that side
// affinely from its source face nearest the corner. The side is the corners'
// own when they lie on one, else that of the source face nearest their mean
// location. A target vertex whose triangles give it different UVs is split:
// it keeps those of its own location and gets a copy per other UV, appended
// after the target's vertices, so no triangle stretches across the atlas
// (wrap-around charts included). Every located vertex, mismatched ones too,
// takes the UVs of its location; vertices with none are inpainted on the
// split mesh.
struct TransferredUvLayout {
  Eigen::MatrixX3i triangles;          // the target's, corners re-pointed to their copies
  std::vector<int> copy_of;            // the target vertex each appended vertex copies
  std::vector<Eigen::MatrixX2d> sets;  // per source set: #Vt + copy_of.size() rows
  int extrapolated = 0;                // vertices whose UVs extend a side past its seam
};
Result<TransferredUvLayout> transferUvLayout(const Mesh& source_mesh, const std::vector<Eigen::MatrixX2d>& source_sets,
                                             const Mesh& target, const TargetLocations& locations);

}  // namespace core
