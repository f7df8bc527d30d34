// Rig components: the plain data of a deformer rig laid on a face mesh
// (locators, clusters, constraints, NURBS curves and surfaces, wires,
// lattices, push-to-surface, muscles, crease clusters, controls, presets), as
// read from and written to the "rigport.components" JSON document
// (core/io/components_io.h, docs/COMPONENTS.md). Every position is a Binding,
// so the same document rebuilds its components on any copy of the topology.
// Evaluation lives beside this file (pose.h and one file per deformer family).
#pragma once

#include <map>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "core/base/error.h"

namespace core {

inline constexpr const char* kComponentsFormat = "rigport.components";
inline constexpr int kComponentsVersion = 1;

// Where a point of a component sits: a fixed position, or on the mesh.
enum class BindingKind { kPosition, kVertex, kFace };

struct Binding {
  BindingKind kind = BindingKind::kPosition;
  Eigen::Vector3d position = Eigen::Vector3d::Zero();     // kPosition: model units
  int vertex = -1;                                         // kVertex: vertex index
  int face = -1;                                           // kFace: triangle index
  Eigen::Vector3d barycentric = Eigen::Vector3d::Zero();   // kFace: corner weights, >= 0, sum 1

  static Binding atPosition(const Eigen::Vector3d& p);
  static Binding atVertex(int v);
  static Binding onFace(int f, const Eigen::Vector3d& barycentric);
  bool operator==(const Binding&) const = default;
};

// The binding's point on a mesh whose current vertex positions are
// `positions` (#V by 3) with `triangles` (#F by 3). Indices must be in range
// (validateComponents checks them).
Eigen::Vector3d resolveBinding(const Binding& binding, const Eigen::MatrixX3d& positions,
                               const Eigen::MatrixX3i& triangles);

struct Locator {
  std::string name;
  Binding binding;
  bool operator==(const Locator&) const = default;
};

struct ClusterMember {
  int vertex = -1;
  double weight = 1.0;  // fraction of the cluster's motion the vertex follows
  bool operator==(const ClusterMember&) const = default;
};

// A weighted rigid-plus-scale transform about a pivot. The authored
// translate/rotate/scale applies at every pose (identity for most clusters);
// control drives add to its channels; a crease cluster's authored transform
// is its full crease, scaled by the activation of its trigger muscles.
// A cluster may carry a joint of the rig (`joint`, JSON "joint"): the joint
// takes the cluster's turn and its origin moves as the cluster moves that
// point, so what the joint carries (teeth, child joints) follows the
// cluster's members; the face itself follows the cluster, not that joint's
// skinning (poseRig), so a face skinned to the joint is not moved twice.
struct Cluster {
  std::string name;
  Binding pivot;
  std::vector<ClusterMember> members;
  Eigen::Vector3d translate = Eigen::Vector3d::Zero();            // model units
  Eigen::Quaterniond rotate = Eigen::Quaterniond::Identity();     // unit; JSON: quaternion or Euler degrees
  Eigen::Vector3d scale = Eigen::Vector3d::Ones();                // about the pivot, along the model's axes
  std::string joint{};                                            // a joint (node) name of the rig; empty: none
  bool operator==(const Cluster& o) const {
    return name == o.name && pivot == o.pivot && members == o.members && translate == o.translate &&
           rotate.coeffs() == o.rotate.coeffs() && scale == o.scale && joint == o.joint;
  }
};

// What a constraint target, a curve driver or a muscle drive points at.
enum class TargetKind { kLocator, kJoint, kVertex, kCluster };

struct ConstraintTarget {
  TargetKind kind = TargetKind::kLocator;  // kLocator, kJoint or kVertex
  std::string name;                        // kLocator, kJoint
  int vertex = -1;                         // kVertex
  double weight = 1.0;                     // >= 0; weights are normalised over the targets
  bool operator==(const ConstraintTarget&) const = default;
};

// The constrained locator (its position) or cluster (its pivot, hence its
// motion) follows the normalised weighted average of the targets.
struct PointConstraint {
  std::string name;
  std::string constrained;  // a locator or cluster name
  std::vector<ConstraintTarget> targets;
  // Keep the rest offset between the object and the targets' average, so the
  // rest pose moves nothing.
  bool maintain_offset = true;
  bool operator==(const PointConstraint&) const = default;
};

// Turns the object so its aim axis points at the targets' weighted average,
// its up axis as close to world_up as the aim allows. A cluster turns by the
// change from its rest aim (the rest pose deforms nothing); so does a joint
// of the rig (paper 001's eye rig: the eye turned by a locator it aims at),
// which the pose hands to the skeleton (ComponentsPose::joint_aims).
struct AimConstraint {
  std::string name;
  std::string constrained;  // a locator or cluster name; with `joint`, a joint (node) name of the rig
  std::vector<ConstraintTarget> targets;
  Eigen::Vector3d aim_axis = Eigen::Vector3d::UnitZ();  // object frame
  Eigen::Vector3d up_axis = Eigen::Vector3d::UnitY();   // object frame, not parallel to aim_axis
  Eigen::Vector3d world_up = Eigen::Vector3d::UnitY();  // model frame
  bool joint = false;  // JSON: "constrained_joint" instead of "constrained"
  bool operator==(const AimConstraint&) const = default;
};

// A point of a curve or a lattice moved by a cluster (its weighted
// transform) or a locator (its displacement from rest).
struct PointDriver {
  int point = -1;                          // control point index
  TargetKind kind = TargetKind::kCluster;  // kCluster or kLocator
  std::string name;
  double weight = 1.0;
  bool operator==(const PointDriver&) const = default;
};

// A NURBS curve: n control points, degree p, n + p + 1 knots (non-decreasing),
// domain [knots[p], knots[n]].
struct NurbsCurve {
  std::string name;
  int degree = 3;
  std::vector<double> knots;
  std::vector<Binding> points;
  std::vector<double> weights;  // empty: all 1 (non-rational)
  std::vector<PointDriver> drivers;
  bool operator==(const NurbsCurve&) const = default;
};

// A NURBS surface: count_u x count_v control points, row u-major
// (index = i * count_v + j).
struct NurbsSurface {
  std::string name;
  int degree_u = 3;
  int degree_v = 3;
  std::vector<double> knots_u;
  std::vector<double> knots_v;
  int count_u = 0;
  int count_v = 0;
  std::vector<Binding> points;
  std::vector<double> weights;  // empty: all 1
  bool operator==(const NurbsSurface&) const = default;
};

// Maya-style wire: points near the base curve follow the deforming curve.
struct Wire {
  std::string name;
  std::string base_curve;  // curve name: the wire at rest
  std::string curve;       // curve name: the deforming wire (same degree, knots and point count)
  double dropoff_distance = 1.0;  // d0 > 0, model units: no influence at or beyond it
  double rotation = 1.0;   // how much of the curve's local turn the points follow (0..1)
  double scale = 0.0;      // how much of the curve's local stretch scales the points' offsets (0..1)
  double envelope = 1.0;   // overall gain
  std::vector<int> members;  // vertices it may move; empty: all
  bool operator==(const Wire&) const = default;
};

// Free-form deformation (Sederberg & Parry 1986). The rest lattice is the
// regular grid of the box origin + s*axes[0] + t*axes[1] + u*axes[2],
// s,t,u in [0,1], with divisions[k] points along each axis.
struct Lattice {
  std::string name;
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
  Eigen::Matrix3d axes = Eigen::Matrix3d::Identity();  // columns: the box's S, T, U edges
  Eigen::Vector3i divisions{2, 2, 2};                  // points per axis, each >= 2
  // Deformed control points, index (i * divisions[1] + j) * divisions[2] + k;
  // empty: the rest grid.
  std::vector<Eigen::Vector3d> points;
  std::vector<PointDriver> drivers;
  std::vector<int> members;  // empty: all
  bool operator==(const Lattice&) const = default;
};

enum class CollisionShapeKind { kTriangles, kSphere, kEllipsoid };

// A closed collision surface: triangles over mesh vertices (a skull proxy
// inside the head), or an implicit sphere or ellipsoid.
struct CollisionShape {
  CollisionShapeKind kind = CollisionShapeKind::kSphere;
  std::vector<Eigen::Vector3i> triangles;  // kTriangles: mesh vertex indices, outward winding
  Binding center;                          // kSphere, kEllipsoid
  double radius = 1.0;                     // kSphere
  Eigen::Vector3d radii = Eigen::Vector3d::Ones();                   // kEllipsoid, along its axes
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();      // kEllipsoid: its axes
  bool operator==(const CollisionShape& o) const {
    return kind == o.kind && triangles == o.triangles && center == o.center && radius == o.radius &&
           radii == o.radii && rotation.coeffs() == o.rotation.coeffs();
  }
};

// kFromPoint: along the ray from a point through the vertex (paper 001's
// sculptor deformer: rays traced from the eye's centre out of the cornea).
enum class PushDirection { kClosest, kVector, kFromPoint };

// Points inside the collision surface are pushed out onto it.
struct PushToSurface {
  std::string name;
  CollisionShape surface;
  PushDirection direction = PushDirection::kClosest;
  Eigen::Vector3d vector = Eigen::Vector3d::UnitZ();  // kVector: the push direction
  Binding from;                                       // kFromPoint: where the rays start
  std::vector<int> members;  // empty: all vertices not on the surface itself
  // A cluster whose transform carries a sphere or ellipsoid (its centre,
  // axes, `from` and `vector`) from where its bindings put it: an eyelid
  // sculptor on the cornea turns with the eye's gaze cluster. Empty: none.
  std::string carried_by{};
  // A sphere or ellipsoid push whose members never go deeper into it than
  // they sat at rest (a member inside at rest stays at its rest depth, not
  // pushed onto the surface): rest is the identity with every member kept.
  bool keep_rest_depth = false;
  bool operator==(const PushToSurface&) const = default;
};

enum class MuscleDriveMode {
  kAxialScale,  // scaled about the origin along the muscle's axis by 1 - weight*c (the paper's joint scaling)
  kTranslate,   // moved by -weight*c*(insertion - origin): slides toward the origin
};

struct MuscleDrive {
  TargetKind kind = TargetKind::kCluster;  // kCluster or kLocator
  std::string name;
  MuscleDriveMode mode = MuscleDriveMode::kAxialScale;
  double weight = 1.0;
  bool operator==(const MuscleDrive&) const = default;
};

// A muscle pulls from its insertion toward its origin; contraction c is
// the sum of its control drives clamped to [min_contraction, max_contraction].
struct Muscle {
  std::string name;
  Binding origin;
  Binding insertion;
  double min_contraction = 0.0;
  double max_contraction = 0.5;  // < 1: a full contraction would collapse the element
  std::vector<MuscleDrive> drives;
  bool operator==(const Muscle&) const = default;
};

struct CreaseTrigger {
  std::string muscle;
  double weight = 1.0;
  bool operator==(const CreaseTrigger&) const = default;
};

// The cluster's authored transform applied by activation
// clamp(sum weight * contraction, 0, 1) of its trigger muscles.
struct CreaseCluster {
  std::string cluster;
  std::vector<CreaseTrigger> triggers;
  bool operator==(const CreaseCluster&) const = default;
};

enum class DriveTargetKind { kMuscle, kCluster, kMorph, kJoint, kLocator };

// Cluster channels a control may drive (added to the authored transform);
// a locator takes the translate channels (moved from its binding).
enum class ClusterChannel {
  kTranslateX, kTranslateY, kTranslateZ,  // model units
  kRotateX, kRotateY, kRotateZ,           // degrees, applied X then Y then Z
  kScaleX, kScaleY, kScaleZ, kScale,      // added to the scale (kScale: to all three)
};
enum class JointChannel { kRotateX, kRotateY, kRotateZ };  // degrees

// One term of a control's linear map: target += gain * control value.
struct ControlDrive {
  DriveTargetKind kind = DriveTargetKind::kMuscle;
  std::string name;  // muscle, cluster, morph target, joint or locator name
  ClusterChannel cluster_channel = ClusterChannel::kTranslateX;  // kCluster; kLocator: translate channels only
  JointChannel joint_channel = JointChannel::kRotateX;           // kJoint
  double gain = 1.0;
  bool operator==(const ControlDrive&) const = default;
};

struct Control {
  std::string name;
  double min = 0.0;
  double max = 1.0;
  double default_value = 0.0;  // JSON "default"
  std::vector<ControlDrive> drives;
  bool operator==(const Control&) const = default;
};

struct Preset {
  std::map<std::string, double> controls;
  bool operator==(const Preset&) const = default;
};

struct ComponentsDocument {
  int version = kComponentsVersion;
  std::vector<Locator> locators;
  std::vector<Cluster> clusters;
  std::vector<PointConstraint> point_constraints;
  std::vector<AimConstraint> aim_constraints;
  std::vector<NurbsCurve> curves;
  std::vector<NurbsSurface> surfaces;
  std::vector<Wire> wires;
  std::vector<Lattice> lattices;
  std::vector<PushToSurface> push_to_surfaces;
  std::vector<Muscle> muscles;
  std::vector<CreaseCluster> crease_clusters;
  std::vector<Control> controls;
  std::map<std::string, Preset> presets;
  bool operator==(const ComponentsDocument&) const = default;
};

// Index of the element named `name` in `items` (by `.name`), -1 when absent.
template <class T>
int indexByName(const std::vector<T>& items, const std::string& name) {
  for (std::size_t i = 0; i < items.size(); ++i) {
    if (items[i].name == name) return static_cast<int>(i);
  }
  return -1;
}

// The `.name` of each element, in order.
template <class T>
std::vector<std::string> namesOf(const std::vector<T>& items) {
  std::vector<std::string> names;
  names.reserve(items.size());
  for (const T& item : items) names.push_back(item.name);
  return names;
}

// Calls deform(v) for each member vertex, or for every vertex when `members`
// is empty (a deformer's "all").
template <class F>
void forEachMember(const std::vector<int>& members, Eigen::Index vertex_count, F&& deform) {
  if (members.empty()) {
    for (Eigen::Index v = 0; v < vertex_count; ++v) deform(v);
  } else {
    for (const int v : members) deform(static_cast<Eigen::Index>(v));
  }
}

// The mesh a document is checked against; -1: not known (ranges unchecked).
struct ComponentsMeshCounts {
  long long vertex_count = -1;
  long long triangle_count = -1;
};

// Checks what the JSON reader cannot see alone: names unique and every
// reference known ("did you mean"), ranges, shapes of knots and grids,
// constraint cycles and, with `counts`, vertex and face indices in range.
// Messages read `<label>: wires[2] "upper_lip": dropoff_distance must be > 0`.
Status validateComponents(const ComponentsDocument& doc, const std::string& label,
                          const ComponentsMeshCounts& counts = {});

// validateComponents against a mesh of `vertex_count` vertices (faces unchecked).
Status validate(const ComponentsDocument& doc, long long vertex_count);

// The control values of preset `name`: each control's default, overridden by
// the preset's values.
Result<std::map<std::string, double>> presetControls(const ComponentsDocument& doc, const std::string& name);

// Stable names used in the JSON and in messages.
const char* clusterChannelName(ClusterChannel channel);
const char* jointChannelName(JointChannel channel);

}  // namespace core
