// Lattice deformer: free-form deformation (Sederberg & Parry, "Free-Form
// Deformation of Solid Geometric Models", SIGGRAPH 1986).
#pragma once

#include <vector>

#include <Eigen/Core>

#include "core/components/components.h"

namespace core {

// Bernstein polynomial B_i^n(t) = C(n, i) t^i (1 - t)^(n - i).
double bernstein(int n, int i, double t);

// The rest lattice: the regular grid origin + axes * (i/l, j/m, k/n),
// index (i * divisions[1] + j) * divisions[2] + k (l = divisions[0] - 1, ...).
std::vector<Eigen::Vector3d> latticeRestPoints(const Lattice& lattice);

// (s, t, u) of p in the lattice's box: p = origin + axes * (s, t, u).
Eigen::Vector3d latticeCoordinates(const Lattice& lattice, const Eigen::Vector3d& p);

// positions: #V by 3. Each member (lattice.members, empty: all) inside the box
// (s, t, u in [0, 1]) moves by
//   sum_ijk B_i^l(s) B_j^m(t) B_k^n(u) (deformed_points[ijk] - rest[ijk]),
// which is Sederberg & Parry's FFD when the rest lattice is the regular grid
// (linear precision): the rest lattice deforms nothing. Points outside stay.
// deformed_points: as latticeRestPoints (drivers applied). Returns #V by 3.
Eigen::MatrixX3d evaluateLattice(const Eigen::MatrixX3d& positions, const Lattice& lattice,
                                 const std::vector<Eigen::Vector3d>& deformed_points);

}  // namespace core
