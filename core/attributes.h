// Vertex attribute transfer (papers 004 sec. 3.5): UV sets seam-aware (the
// UVs of the containing source triangle's own corners, so never across a UV
// seam), integer labels by barycentric-weighted majority, float fields by
// interpolation.
#pragma once

#include <Eigen/SparseCore>

#include "core/correspondence.h"
#include "core/inpainting.h"
#include "core/rig.h"

namespace core {

struct AttributeTransferOptions {
  bool uvs = false;  // replace the target's TEXCOORD_0 (and extra sets) with the source's
};

struct TransferredAttributes {
  Eigen::MatrixX2d uvs;                 // #Vt by 2 when uvs were transferred, else 0 rows
  VertexAttributes attributes;          // labels and fields (+ extra UV sets when asked)
};

// Mismatched target vertices (see TargetLocations) take labels by majority of
// their neighbours (target_laplacian: uniformLaplacian of the target, as the
// adjacency; may be empty when no vertex is mismatched) and fields/colours by
// harmonic inpainting (`mismatched`, null when no vertex is mismatched).
TransferredAttributes transferAttributes(const Mesh& source_mesh, const VertexAttributes& source,
                                         const TargetLocations& locations, const Eigen::SparseMatrix<double>& target_laplacian,
                                         const HarmonicInpainting* mismatched, const AttributeTransferOptions& options = {});

}  // namespace core
