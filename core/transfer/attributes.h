// Vertex attribute transfer (papers 004 sec. 3.5): integer labels by
// barycentric-weighted majority, float fields by interpolation, UV sets with
// the source's seams (the target split where a seam crosses it).
#pragma once

#include <string>
#include <vector>

#include <Eigen/SparseCore>

#include "core/correspond/correspondence.h"
#include "core/solve/inpainting.h"
#include "core/rig/rig.h"

namespace core {

// Labels, fields and colours (UV sets: transferUvLayout). Mismatched target
// vertices (see TargetLocations) take labels by majority of their neighbours
// (target_laplacian: uniformLaplacian of the target, as the adjacency; may be
// empty when no vertex is mismatched) and fields/colours by harmonic
// inpainting (`mismatched`, null when no vertex is mismatched).
VertexAttributes transferAttributes(const Mesh& source_mesh, const VertexAttributes& source,
                                    const TargetLocations& locations, const Eigen::SparseMatrix<double>& target_laplacian,
                                    const HarmonicInpainting* mismatched);

// What transferUvLayout needs of the source alone, made once per rig
// (PreparedRig::uv_layout): its UV sets side by side, the faces around each
// point, the faces across each edge whose two ends carry one UV in every set
// (where the layout is continuous), and each face's centre and radius.
struct SourceUvLayout {
  Eigen::MatrixXd uvs;                  // #V by 2 x #sets
  std::vector<int> uv_of;               // #V: the lowest copy of its point with its UVs
  FacesAroundPoints around;             // by point
  std::vector<int> across_offsets;      // #F + 1
  std::vector<int> across_faces;        // faces across UV-continuous edges, by face
  RowMatrixX3d face_centres;            // #F
  Eigen::VectorXd face_radii;           // #F: farthest corner from the centre
  double same_uv = 0.0;                 // UVs of one vertex closer than this are one
  std::size_t memoryBytes() const;
};
// sets: TEXCOORD_0 and the extra sets, #V rows each (an error names the set
// that has not).
Result<SourceUvLayout> prepareUvLayout(const Mesh& source_mesh, const std::vector<Eigen::MatrixX2d>& sets,
                                       const std::string& label);

// The source's UV sets on the target, seams and all. Each target triangle
// takes its UVs from one side of any source seam: a corner whose location is
// on that side (reachable across source edges whose ends carry one UV in
// every set) interpolates it; a corner across the seam extends that side
// affinely from its source face nearest the corner. The side is the corners'
// own when they lie on one, else that of the source face nearest their mean
// location (corners at a point the target itself splits, on its own seam,
// leave the choice to the others). A target vertex whose triangles give it
// different UVs is split: it keeps those of its own location and gets a copy
// per other UV, appended after the target's vertices, so no triangle
// stretches across the atlas (wrap-around charts included). Every located
// vertex, mismatched ones too, takes the UVs of its location; vertices with
// none are inpainted on the split mesh.
struct TransferredUvLayout {
  Eigen::MatrixX3i triangles;          // the target's, corners re-pointed to their copies
  std::vector<int> copy_of;            // the target vertex each appended vertex copies
  std::vector<Eigen::MatrixX2d> sets;  // per source set: #Vt + copy_of.size() rows
  int extended_vertices = 0;           // vertices whose UVs extend a side past its seam
};
// target_point: the target's coincidentVertexRepresentatives (from the warp).
Result<TransferredUvLayout> transferUvLayout(const Mesh& source_mesh, const SourceUvLayout& layout, const Mesh& target,
                                             const TargetLocations& locations, const std::vector<int>& target_point);

}  // namespace core
