// Harmonic inpainting on a triangle mesh: values at unknown vertices solve
// L_uu X_u = -L_uk X_k with the uniform graph Laplacian, so they blend their
// trusted surroundings smoothly (after Abdrashitov et al. 2023, "Robust skin
// weights transfer via weight inpainting").
#pragma once

#include <memory>
#include <vector>

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include "core/base/error.h"

namespace core {

// Vertex-vertex uniform Laplacian of a triangle mesh (#V by #V, symmetric,
// off-diagonal -1 per edge, diagonal = degree). Vertices at identical
// positions (split at UV seams or hard edges) are joined: faces connect
// through the lowest-indexed copy, each other copy by one edge to it, so
// inpainted values agree across a seam.
Eigen::SparseMatrix<double> uniformLaplacian(const Eigen::MatrixX3d& positions, const Eigen::MatrixX3i& triangles);

// The same with the joined vertices given: representative[v] is the copy v
// joins (itself when none; empty: every vertex its own).
Eigen::SparseMatrix<double> uniformLaplacian(const Eigen::MatrixX3i& triangles, Eigen::Index vertex_count,
                                             const std::vector<int>& representative);

// The factorised system of one known/unknown split. Only the known vertices
// next to unknown ones (the boundary) enter the right-hand side, so callers
// with many value sets (every blend shape) pass #boundary rows, not #V.
class HarmonicInpainting {
 public:
  // Error only when the system cannot be factorised.
  static Result<HarmonicInpainting> create(const Eigen::SparseMatrix<double>& laplacian,
                                           const std::vector<char>& known);

  const std::vector<int>& unknown() const { return unknown_; }    // vertices solved for, ascending
  const std::vector<int>& boundary() const { return boundary_; }  // known neighbours of unknowns, ascending
  // False for unknown vertices in components without any known vertex: their
  // solved rows are meaningless and callers keep what they had.
  bool reached(std::size_t unknown_index) const { return reached_[unknown_index] != 0; }

  // boundary_values: #boundary by k (row i = values at boundary()[i]).
  // Returns #unknown by k (row i = values at unknown()[i]).
  Eigen::MatrixXd solve(const Eigen::MatrixXd& boundary_values) const;

  // values: #V by k; returns them with the reached unknown rows solved.
  Eigen::MatrixXd apply(const Eigen::MatrixXd& values) const;

 private:
  struct Coupling {
    int unknown_index;
    int boundary_index;
    double weight;  // -L(unknown, boundary)
  };
  struct Solver;
  std::vector<int> unknown_;
  std::vector<int> boundary_;
  std::vector<char> reached_;
  std::vector<Coupling> couplings_;
  std::shared_ptr<const Solver> solver_;
};

// values: #V by k; rows of vertices with known[v] == 0 are replaced. Unknown
// vertices in components without any known vertex keep their input rows.
// Returns an error only when the system cannot be factorised.
Result<Eigen::MatrixXd> inpaintHarmonic(const Eigen::SparseMatrix<double>& laplacian, const std::vector<char>& known,
                                        const Eigen::MatrixXd& values);

}  // namespace core
