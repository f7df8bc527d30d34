// Wire deformer (Singh & Fiume, "Wires", SIGGRAPH 1998, as Maya's wire
// deformer): points near a base curve follow its deformed copy.
#pragma once

#include <Eigen/Core>

#include "core/components/components.h"
#include "core/components/nurbs.h"

namespace core {

// Dropoff of influence with the normalised distance x = d / d0:
// f(x) = (1 - x^2)^2 on [0, 1], 0 beyond. f(0) = 1, f(1) = 0, f'(0) = f'(1) = 0.
double wireDropoff(double x);

// positions: #V by 3, the points entering the wire (model units). For each
// member p (wire.members, empty: all): u = closest parameter on `base`, d =
// |p - base(u)|; if d < d0 = wire.dropoff_distance, p moves by
//   envelope * f(d / d0) * [(deformed(u) - base(u)) + (s R (p - base(u)) - (p - base(u)))]
// where R turns base'(u) to deformed'(u) (slerped from identity by
// wire.rotation) and s = 1 + wire.scale * (|deformed'(u)| / |base'(u)| - 1).
// `base` and `deformed` share degree and knots. In place: each member reads
// only its own row before moving it (no copy of the mesh per wire).
void evaluateWire(Eigen::MatrixX3d& positions, const CurveGeometry& base, const CurveGeometry& deformed,
                  const Wire& wire);

}  // namespace core
