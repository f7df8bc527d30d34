// Free-form deformation: Sederberg & Parry 1986, trivariate Bernstein.
#include "core/components/lattice.h"

#include <cassert>
#include <cmath>

#include <Eigen/LU>

namespace core {

double bernstein(int n, int i, double t) {
  if (i < 0 || i > n) return 0.0;
  double binomial = 1.0;
  for (int k = 1; k <= i; ++k) binomial = binomial * (n - i + k) / k;
  return binomial * std::pow(t, i) * std::pow(1.0 - t, n - i);
}

std::vector<Eigen::Vector3d> latticeRestPoints(const Lattice& lattice) {
  const Eigen::Vector3i& d = lattice.divisions;
  std::vector<Eigen::Vector3d> points;
  points.reserve(static_cast<std::size_t>(d.prod()));
  for (int i = 0; i < d(0); ++i) {
    for (int j = 0; j < d(1); ++j) {
      for (int k = 0; k < d(2); ++k) {
        const Eigen::Vector3d stu(double(i) / (d(0) - 1), double(j) / (d(1) - 1), double(k) / (d(2) - 1));
        points.push_back(lattice.origin + lattice.axes * stu);
      }
    }
  }
  return points;
}

Eigen::Vector3d latticeCoordinates(const Lattice& lattice, const Eigen::Vector3d& p) {
  return lattice.axes.partialPivLu().solve(p - lattice.origin);
}

Eigen::MatrixX3d evaluateLattice(const Eigen::MatrixX3d& positions, const Lattice& lattice,
                                 const std::vector<Eigen::Vector3d>& deformed_points) {
  const Eigen::Vector3i& d = lattice.divisions;
  assert(deformed_points.size() == static_cast<std::size_t>(d.prod()));
  const std::vector<Eigen::Vector3d> rest = latticeRestPoints(lattice);
  std::vector<Eigen::Vector3d> moves(rest.size());
  bool any = false;
  for (std::size_t q = 0; q < rest.size(); ++q) {
    moves[q] = deformed_points[q] - rest[q];
    any = any || !moves[q].isZero(0.0);
  }
  Eigen::MatrixX3d out = positions;
  if (!any) return out;
  const auto inverse = lattice.axes.partialPivLu();
  constexpr double kInside = 1e-12;  // points on the box's faces count as inside
  auto deform = [&](Eigen::Index v) {
    const Eigen::Vector3d stu = inverse.solve(positions.row(v).transpose() - lattice.origin);
    if (stu.minCoeff() < -kInside || stu.maxCoeff() > 1.0 + kInside) return;
    std::vector<double> bu(static_cast<std::size_t>(d(2)));
    for (int k = 0; k < d(2); ++k) bu[static_cast<std::size_t>(k)] = bernstein(d(2) - 1, k, stu(2));
    Eigen::Vector3d move = Eigen::Vector3d::Zero();
    for (int i = 0; i < d(0); ++i) {
      const double bs = bernstein(d(0) - 1, i, stu(0));
      for (int j = 0; j < d(1); ++j) {
        const double bst = bs * bernstein(d(1) - 1, j, stu(1));
        for (int k = 0; k < d(2); ++k) {
          move += bst * bu[static_cast<std::size_t>(k)] * moves[static_cast<std::size_t>((i * d(1) + j) * d(2) + k)];
        }
      }
    }
    out.row(v) += move.transpose();
  };
  forEachMember(lattice.members, positions.rows(), deform);
  return out;
}

}  // namespace core
