// Skin weight transfer (papers 000 ch. 4.7, 004 sec. 3.5): each target vertex
// takes the interpolated source weights at its location on the source; where
// the match is not trusted the weights are inpainted from trusted vertices by
// a Laplacian (harmonic) system on the target (after Abdrashitov et al. 2023,
// "Robust skin weights transfer via weight inpainting").
#pragma once

#include <Eigen/Core>

#include "core/correspond/correspondence.h"
#include "core/base/error.h"
#include "core/geometry/mesh.h"
#include "core/rig/rig.h"

namespace core {

struct SkinWeightOptions {
  int max_influences = 4;       // kept per vertex (largest), then renormalised
  bool inpaint = true;          // solve low-confidence vertices from confident ones
  double min_weight = 1e-6;     // weights below this are dropped before pruning
};

struct TransferredWeights {
  SkinWeights weights;            // #Vt by #joints, rows sum to 1
  Eigen::VectorXi inpainted;      // #Vt, 1 where the weights were inpainted
  int inpainted_vertices = 0;
  int pruned_vertices = 0;        // vertices that had more than max_influences
  int max_influences = 0;         // largest influence count written
};

// source_weights: #Vs by #joints; locations: every target vertex on the source
// (from locateOnGuide); a vertex is "confident" when its confidence > 0.
// Untrusted vertices are inpainted (harmonic) from confident ones over
// target_laplacian (uniformLaplacian of the target; may be empty when every
// vertex is confident).
Result<TransferredWeights> transferSkinWeights(const SkinWeights& source_weights,
                                               const Eigen::MatrixX3i& source_triangles,
                                               const TargetLocations& locations, Eigen::Index target_vertices,
                                               const Eigen::SparseMatrix<double>& target_laplacian,
                                               const SkinWeightOptions& options = {});

}  // namespace core
