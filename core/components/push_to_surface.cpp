// Push-to-surface. Inside test for triangle surfaces: angle-weighted
// pseudo-normals (Baerentzen & Aanaes, "Signed distance computation using the
// angle weighted pseudonormal", IEEE TVCG 2005); ray exit: Moller & Trumbore 1997.
#include "core/components/push_to_surface.h"

#include <cmath>
#include <limits>
#include <map>
#include <set>
#include <utility>

#include "core/geometry/closest_point.h"
#include "core/geometry/mesh.h"

namespace core {

namespace {

constexpr double kBarycentricZero = 1e-9;

// The closed triangle surface with its pseudo-normals at every feature.
struct TriangleSurface {
  Eigen::MatrixX3i triangles;                     // #S by 3 mesh vertex indices
  Eigen::MatrixX3d face_normals;                  // #S by 3 unit
  std::map<int, Eigen::Vector3d> vertex_normals;  // angle-weighted
  std::map<std::pair<int, int>, Eigen::Vector3d> edge_normals;  // sum of the two faces'
};

TriangleSurface makeTriangleSurface(const Eigen::MatrixX3d& positions, const CollisionShape& shape) {
  TriangleSurface s;
  s.triangles.resize(static_cast<Eigen::Index>(shape.triangles.size()), 3);
  for (std::size_t t = 0; t < shape.triangles.size(); ++t) s.triangles.row(static_cast<Eigen::Index>(t)) = shape.triangles[t].transpose();
  s.face_normals = computeFaceNormals(positions, s.triangles);
  for (Eigen::Index f = 0; f < s.triangles.rows(); ++f) {
    const Eigen::Vector3d n = s.face_normals.row(f).transpose();
    for (int k = 0; k < 3; ++k) {
      const int a = s.triangles(f, k), b = s.triangles(f, (k + 1) % 3), c = s.triangles(f, (k + 2) % 3);
      const Eigen::Vector3d e1 = (positions.row(b) - positions.row(a)).transpose();
      const Eigen::Vector3d e2 = (positions.row(c) - positions.row(a)).transpose();
      const double angle = std::atan2(e1.cross(e2).norm(), e1.dot(e2));
      auto [vit, vfresh] = s.vertex_normals.emplace(a, Eigen::Vector3d::Zero());
      vit->second += angle * n;
      auto [eit, efresh] = s.edge_normals.emplace(std::minmax(a, b), Eigen::Vector3d::Zero());
      eit->second += n;
    }
  }
  return s;
}

// The pseudo-normal at the feature of face `face` the barycentrics fall on.
Eigen::Vector3d featureNormal(const TriangleSurface& s, int face, const Eigen::Vector3d& barycentric) {
  int corners[3];
  int count = 0;
  for (int k = 0; k < 3; ++k) {
    if (barycentric(k) > kBarycentricZero) corners[count++] = k;
  }
  if (count == 1) return s.vertex_normals.at(s.triangles(face, corners[0]));
  if (count == 2) return s.edge_normals.at(std::minmax(s.triangles(face, corners[0]), s.triangles(face, corners[1])));
  return s.face_normals.row(face).transpose();
}

// The largest t > 0 of p + t d on a triangle nearest to p along d: where the
// ray first leaves the closed surface. Infinity when it meets none.
double rayExit(const Eigen::MatrixX3d& positions, const TriangleSurface& s, const Eigen::Vector3d& p,
               const Eigen::Vector3d& d) {
  double best = std::numeric_limits<double>::infinity();
  for (Eigen::Index f = 0; f < s.triangles.rows(); ++f) {
    const Eigen::Vector3d a = positions.row(s.triangles(f, 0)).transpose();
    const Eigen::Vector3d e1 = positions.row(s.triangles(f, 1)).transpose() - a;
    const Eigen::Vector3d e2 = positions.row(s.triangles(f, 2)).transpose() - a;
    const Eigen::Vector3d h = d.cross(e2);
    const double det = e1.dot(h);
    if (std::abs(det) < 1e-300) continue;
    const Eigen::Vector3d to_p = p - a;
    const double u = to_p.dot(h) / det;
    if (u < -kBarycentricZero || u > 1.0 + kBarycentricZero) continue;
    const Eigen::Vector3d q = to_p.cross(e1);
    const double v = d.dot(q) / det;
    if (v < -kBarycentricZero || u + v > 1.0 + kBarycentricZero) continue;
    const double t = e2.dot(q) / det;
    if (t > 0.0 && t < best) best = t;
  }
  return best;
}

// A sphere's or ellipsoid's frame, where it is the unit sphere.
struct UnitFrame {
  Eigen::Vector3d center;
  Eigen::Matrix3d rotation;
  Eigen::Vector3d radii;
  Eigen::Vector3d toUnit(const Eigen::Vector3d& p) const { return (rotation.transpose() * (p - center)).cwiseQuotient(radii); }
  Eigen::Vector3d toUnitDirection(const Eigen::Vector3d& d) const { return (rotation.transpose() * d).cwiseQuotient(radii); }
  Eigen::Vector3d fromUnit(const Eigen::Vector3d& q) const { return center + rotation * q.cwiseProduct(radii); }
};

UnitFrame unitFrame(const CollisionShape& shape, const Eigen::MatrixX3d& positions, const Eigen::MatrixX3i& triangles) {
  const bool sphere = shape.kind == CollisionShapeKind::kSphere;
  return UnitFrame{resolveBinding(shape.center, positions, triangles),
                   sphere ? Eigen::Matrix3d::Identity() : shape.rotation.toRotationMatrix(),
                   sphere ? Eigen::Vector3d::Constant(shape.radius) : shape.radii};
}

// The exit t > 0 of p + t d from the unit sphere (|p| < 1).
double unitSphereExit(const Eigen::Vector3d& p, const Eigen::Vector3d& d) {
  const double a = d.squaredNorm(), b = p.dot(d), c = p.squaredNorm() - 1.0;
  return (-b + std::sqrt(b * b - a * c)) / a;
}

}  // namespace

Eigen::MatrixX3d evaluatePushToSurface(const Eigen::MatrixX3d& positions, const Eigen::MatrixX3i& triangles,
                                       const PushToSurface& push, const Eigen::VectorXd& levels) {
  Eigen::MatrixX3d out = positions;
  const CollisionShape& shape = push.surface;
  std::vector<int> members = push.members;
  if (members.empty()) {
    std::set<int> on_surface;
    for (const Eigen::Vector3i& t : shape.triangles) on_surface.insert({t(0), t(1), t(2)});
    for (int v = 0; v < static_cast<int>(positions.rows()); ++v) {
      if (!on_surface.count(v)) members.push_back(v);
    }
  }
  const Eigen::Vector3d direction = push.vector.normalized();
  const Eigen::Vector3d from =
      push.direction == PushDirection::kFromPoint ? resolveBinding(push.from, positions, triangles) : Eigen::Vector3d::Zero();
  // kFromPoint: the ray from `from` through p; nothing to push along at `from` itself.
  auto rayThrough = [&](const Eigen::Vector3d& p, Eigen::Vector3d& ray) {
    const Eigen::Vector3d d = p - from;
    if (d.norm() < 1e-12) return false;
    ray = d.normalized();
    return true;
  };
  if (shape.kind == CollisionShapeKind::kTriangles) {
    const TriangleSurface surface = makeTriangleSurface(positions, shape);
    const ClosestPointIndex index(positions, surface.triangles);
    for (int v : members) {
      const Eigen::Vector3d p = positions.row(v).transpose();
      const SurfacePoint hit = index.closestPoint(p);
      if (!hit.found() || (p - hit.point).dot(featureNormal(surface, hit.face, hit.barycentric)) >= 0.0) continue;
      Eigen::Vector3d ray = direction;
      if (push.direction == PushDirection::kClosest) {
        out.row(v) = hit.point.transpose();
      } else if (push.direction == PushDirection::kVector || rayThrough(p, ray)) {
        const double t = rayExit(positions, surface, p, ray);
        if (std::isfinite(t)) out.row(v) = (p + t * ray).transpose();
      }
    }
    return out;
  }
  // Sphere and ellipsoid, in the frame where the shape is the unit sphere;
  // a vertex with a level L < 1 is pushed onto |q| = L (the exit t of a ray
  // from the sphere of radius L is the unit sphere's for q / L, d / L).
  const UnitFrame frame = unitFrame(shape, positions, triangles);
  const Eigen::Vector3d unit_direction = frame.toUnitDirection(direction);
  for (int v : members) {
    const double level = levels.size() > v ? std::max(levels(v), 1e-9) : 1.0;
    const Eigen::Vector3d q = frame.toUnit(positions.row(v).transpose()) / level;
    const double r = q.norm();
    if (r >= 1.0) continue;
    if (push.direction == PushDirection::kVector) {
      const Eigen::Vector3d d = unit_direction / level;
      out.row(v) = frame.fromUnit(level * (q + unitSphereExit(q, d) * d)).transpose();
    } else if (push.direction == PushDirection::kFromPoint) {
      Eigen::Vector3d ray;
      if (!rayThrough(positions.row(v).transpose(), ray)) continue;
      const Eigen::Vector3d d = frame.toUnitDirection(ray) / level;
      out.row(v) = frame.fromUnit(level * (q + unitSphereExit(q, d) * d)).transpose();
    } else {
      // At the very centre every direction is closest: take the push vector's.
      const Eigen::Vector3d radial = r > 1e-12 ? Eigen::Vector3d(q / r) : unit_direction.normalized();
      out.row(v) = frame.fromUnit(level * radial).transpose();
    }
  }
  return out;
}

Eigen::VectorXd surfaceLevels(const Eigen::MatrixX3d& positions, const Eigen::MatrixX3i& triangles,
                              const PushToSurface& push) {
  Eigen::VectorXd levels = Eigen::VectorXd::Ones(positions.rows());
  if (push.surface.kind == CollisionShapeKind::kTriangles) return levels;
  const UnitFrame frame = unitFrame(push.surface, positions, triangles);
  auto level = [&](Eigen::Index v) { levels(v) = std::min(1.0, frame.toUnit(positions.row(v).transpose()).norm()); };
  if (push.members.empty()) {
    for (Eigen::Index v = 0; v < positions.rows(); ++v) level(v);
  } else {
    for (const int v : push.members) level(v);
  }
  return levels;
}

}  // namespace core
