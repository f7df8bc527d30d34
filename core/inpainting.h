// Harmonic inpainting on a triangle mesh: values at unknown vertices solve
// L_uu X_u = -L_uk X_k with the uniform graph Laplacian, so they blend their
// trusted surroundings smoothly (after Abdrashitov et al. 2023, "Robust skin
// weights transfer via weight inpainting").
#pragma once

#include <vector>

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include "core/error.h"

namespace core {

// Vertex-vertex uniform Laplacian of a triangle mesh (#V by #V, symmetric,
// off-diagonal -1 per edge, diagonal = degree).
Eigen::SparseMatrix<double> uniformLaplacian(Eigen::Index vertex_count, const Eigen::MatrixX3i& triangles);

// values: #V by k; rows of vertices with known[v] == 0 are replaced. Unknown
// vertices in components without any known vertex keep their input rows.
// Returns an error only when the system cannot be factorised.
Result<Eigen::MatrixXd> inpaintHarmonic(const Eigen::SparseMatrix<double>& laplacian, const std::vector<char>& known,
                                        const Eigen::MatrixXd& values);

}  // namespace core
