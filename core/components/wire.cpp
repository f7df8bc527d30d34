// Wire deformer: Singh & Fiume 1998; Maya's dropoff (1 - x^2)^2.
#include "core/components/wire.h"

#include <cmath>

#include <Eigen/Geometry>

namespace core {

double wireDropoff(double x) {
  x = std::abs(x);
  if (x >= 1.0) return 0.0;
  const double a = 1.0 - x * x;
  return a * a;
}

void evaluateWire(Eigen::MatrixX3d& positions, const CurveGeometry& base, const CurveGeometry& deformed,
                  const Wire& wire) {
  const CurveClosestParameter closest(base);
  auto deform = [&](Eigen::Index v) {
    const Eigen::Vector3d p = positions.row(v).transpose();
    const double u = closest.closestParameter(p);
    const Eigen::Vector3d on_base = curvePoint(base, u);
    const Eigen::Vector3d offset = p - on_base;
    const double f = wireDropoff(offset.norm() / wire.dropoff_distance);
    if (f == 0.0) return;
    Eigen::Vector3d move = curvePoint(deformed, u) - on_base;
    const Eigen::Vector3d base_tangent = curveDerivative(base, u);
    const Eigen::Vector3d deformed_tangent = curveDerivative(deformed, u);
    // The offset from the curve turns and stretches with the curve there
    // (a tangent of zero length carries no direction: nothing to follow).
    if (base_tangent.norm() > 1e-12 && deformed_tangent.norm() > 1e-12) {
      const Eigen::Quaterniond turn = Eigen::Quaterniond::FromTwoVectors(base_tangent, deformed_tangent);
      // (slerp's ends exactly, without its acos and sines: the usual factors)
      const Eigen::Quaterniond partial = wire.rotation == 1.0   ? turn
                                         : wire.rotation == 0.0 ? Eigen::Quaterniond::Identity()
                                                                : Eigen::Quaterniond::Identity().slerp(wire.rotation, turn);
      const double stretch = 1.0 + wire.scale * (deformed_tangent.norm() / base_tangent.norm() - 1.0);
      move += stretch * (partial * offset) - offset;
    }
    positions.row(v) += (wire.envelope * f * move).transpose();
  };
  forEachMember(wire.members, positions.rows(), deform);
}

}  // namespace core
