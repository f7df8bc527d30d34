// Shared by the components tests: a flat grid mesh, a document using every
// kind of component on it, and the document under a similarity.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "core/components/components.h"
#include "core/components/lattice.h"
#include "core/geometry/mesh.h"

namespace components_test {

// (n+1)^2 vertices on [-1, 1]^2 at z = 0, vertex (i, j) = j * (n + 1) + i at
// x = -1 + 2i/n, y = -1 + 2j/n; 2 n^2 triangles.
inline core::Mesh gridMesh(int n = 10) {
  core::Mesh m;
  m.positions.resize((n + 1) * (n + 1), 3);
  for (int j = 0; j <= n; ++j) {
    for (int i = 0; i <= n; ++i) m.positions.row(j * (n + 1) + i) << -1.0 + 2.0 * i / n, -1.0 + 2.0 * j / n, 0.0;
  }
  m.triangles.resize(2 * n * n, 3);
  int f = 0;
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      const int a = j * (n + 1) + i, b = a + 1, c = a + n + 1, d = c + 1;
      m.triangles.row(f++) << a, b, d;
      m.triangles.row(f++) << a, d, c;
    }
  }
  return m;
}

inline int gridVertex(int i, int j, int n = 10) { return j * (n + 1) + i; }

// Every component kind on gridMesh(10). Control "smile" drives only what a
// similarity carries along (muscles, uniform scale, morphs, joints); "open"
// drives a translate channel, along the model's axes.
inline core::ComponentsDocument fullDocument() {
  using namespace core;
  ComponentsDocument doc;
  doc.locators = {{"chin", Binding::atVertex(gridVertex(5, 0))},
                  {"nose", Binding::atVertex(gridVertex(5, 5))},
                  {"brow", Binding::atPosition({0.0, 0.8, 0.3})}};
  Cluster lip{"lip_c", Binding::atVertex(gridVertex(5, 4)), {}};
  for (int i = 2; i <= 8; ++i) {
    lip.members.push_back({gridVertex(i, 4), 1.0});
    lip.members.push_back({gridVertex(i, 3), 0.5});
  }
  lip.translate = {0.0, 0.0, 0.05};
  lip.rotate = Eigen::Quaterniond(Eigen::AngleAxisd(0.2, Eigen::Vector3d(0.3, 0.1, 1.0).normalized()));
  Cluster crease{"crease_l", Binding::onFace(10, {0.2, 0.3, 0.5}), {{gridVertex(2, 6), 1.0}, {gridVertex(3, 6), 0.7}}};
  crease.translate = {0.0, 0.0, -0.02};
  crease.scale = Eigen::Vector3d::Constant(1.1);
  Cluster aimed{"aimed", Binding::atVertex(gridVertex(8, 7)), {{gridVertex(8, 7), 1.0}, {gridVertex(9, 7), 1.0}, {gridVertex(8, 8), 0.5}}};
  doc.clusters = {lip, crease, aimed};
  doc.point_constraints = {
      {"lip_follow", "lip_c", {{TargetKind::kLocator, "chin", -1, 1.0}, {TargetKind::kVertex, "", gridVertex(5, 2), 3.0}}, true},
      {"brow_follow", "brow", {{TargetKind::kLocator, "nose", -1, 1.0}}, true}};
  doc.aim_constraints = {{"aim_nose", "aimed", {{TargetKind::kLocator, "nose", -1, 1.0}}, Eigen::Vector3d::UnitX(),
                          Eigen::Vector3d::UnitZ(), Eigen::Vector3d::UnitZ()}};
  NurbsCurve base{"lip_base", 3, {0, 0, 0, 0, 0.5, 1, 1, 1, 1}, {}, {}, {}};
  for (int i = 1; i <= 9; i += 2) base.points.push_back(Binding::atVertex(gridVertex(i, 6)));
  NurbsCurve lip_curve = base;
  lip_curve.name = "lip";
  lip_curve.drivers = {{2, TargetKind::kCluster, "lip_c", 1.0}, {3, TargetKind::kLocator, "nose", 1.0}};
  doc.curves = {base, lip_curve};
  NurbsSurface cheek{"cheek", 1, 1, {0, 0, 1, 1}, {0, 0, 1, 1}, 2, 2,
                     {Binding::atVertex(0), Binding::atVertex(1), Binding::atVertex(11), Binding::atVertex(12)}, {}};
  doc.surfaces = {cheek};
  doc.wires = {{"upper_lip", "lip_base", "lip", 0.3, 1.0, 0.5, 1.0, {}}};
  Lattice jaw;
  jaw.name = "jaw";
  jaw.origin = {-0.5, -1.1, -0.2};
  jaw.axes = Eigen::Vector3d(1.0, 0.8, 0.4).asDiagonal();
  jaw.divisions = {3, 2, 2};
  jaw.points = latticeRestPoints(jaw);
  jaw.points[4] += Eigen::Vector3d(0.0, 0.05, 0.1);
  jaw.drivers = {{0, TargetKind::kCluster, "crease_l", 1.0}};
  doc.lattices = {jaw};
  PushToSurface skull;
  skull.name = "skull";
  skull.surface.kind = CollisionShapeKind::kSphere;
  skull.surface.center = Binding::atPosition({0.0, 0.0, -0.9});
  skull.surface.radius = 0.95;
  doc.push_to_surfaces = {skull};
  doc.muscles = {{"zygomatic", Binding::atVertex(gridVertex(10, 10)), Binding::atVertex(gridVertex(5, 5)), 0.0, 0.5,
                  {{TargetKind::kCluster, "lip_c", MuscleDriveMode::kAxialScale, 1.0},
                   {TargetKind::kLocator, "nose", MuscleDriveMode::kTranslate, 0.5}}}};
  doc.crease_clusters = {{"crease_l", {{"zygomatic", 2.0}}}};
  Control smile{"smile", 0.0, 1.0, 0.0, {}};
  smile.drives = {{DriveTargetKind::kMuscle, "zygomatic", ClusterChannel::kTranslateX, JointChannel::kRotateX, 0.4},
                  {DriveTargetKind::kCluster, "lip_c", ClusterChannel::kScale, JointChannel::kRotateX, 0.1},
                  {DriveTargetKind::kMorph, "mouth_smile", ClusterChannel::kTranslateX, JointChannel::kRotateX, 1.0},
                  {DriveTargetKind::kJoint, "jaw", ClusterChannel::kTranslateX, JointChannel::kRotateX, 10.0}};
  Control open{"open", -1.0, 1.0, 0.0, {}};
  open.drives = {{DriveTargetKind::kCluster, "lip_c", ClusterChannel::kTranslateY, JointChannel::kRotateX, 0.05}};
  doc.controls = {smile, open};
  doc.presets["smile"].controls = {{"smile", 1.0}};
  doc.presets["half"].controls = {{"smile", 0.5}, {"open", -0.25}};
  return doc;
}

// p -> scale * rotation * p + translation applied to the document's
// positions, lengths and directions. Exact for documents whose clusters
// scale uniformly and whose controls drive no translate or rotate channel.
struct SimilarityMap {
  double scale = 1.0;
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();
  Eigen::Vector3d point(const Eigen::Vector3d& p) const { return scale * rotation * p + translation; }
  Eigen::Vector3d vector(const Eigen::Vector3d& v) const { return scale * rotation * v; }
  Eigen::Quaterniond turn(const Eigen::Quaterniond& q) const {
    return Eigen::Quaterniond(rotation * q.toRotationMatrix() * rotation.transpose());
  }
  void binding(core::Binding& b) const {
    if (b.kind == core::BindingKind::kPosition) b.position = point(b.position);
  }
  core::ComponentsDocument document(core::ComponentsDocument doc) const {
    for (auto& l : doc.locators) binding(l.binding);
    for (auto& c : doc.clusters) {
      binding(c.pivot);
      c.translate = vector(c.translate);
      c.rotate = turn(c.rotate);
    }
    for (auto& a : doc.aim_constraints) a.world_up = rotation * a.world_up;
    for (auto& c : doc.curves) {
      for (auto& b : c.points) binding(b);
    }
    for (auto& w : doc.wires) w.dropoff_distance *= scale;
    for (auto& l : doc.lattices) {
      l.origin = point(l.origin);
      l.axes = scale * rotation * l.axes;
      for (auto& p : l.points) p = point(p);
    }
    for (auto& p : doc.push_to_surfaces) {
      binding(p.surface.center);
      p.surface.radius *= scale;
      p.surface.radii *= scale;
      p.surface.rotation = Eigen::Quaterniond(rotation) * p.surface.rotation;
      p.vector = rotation * p.vector;
    }
    for (auto& m : doc.muscles) {
      binding(m.origin);
      binding(m.insertion);
    }
    return doc;
  }
  Eigen::MatrixX3d positions(const Eigen::MatrixX3d& p) const {
    Eigen::MatrixX3d out(p.rows(), 3);
    for (Eigen::Index i = 0; i < p.rows(); ++i) out.row(i) = point(p.row(i).transpose()).transpose();
    return out;
  }
};

}  // namespace components_test
