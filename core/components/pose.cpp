// evaluatePose: the stages in the documented order, each reading the earlier
// stages' products. Per-family maths is in cluster.cpp, constraints.cpp,
// nurbs.cpp, wire.cpp, lattice.cpp and push_to_surface.cpp.
#include "core/components/pose.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <set>

#include "core/components/cluster.h"
#include "core/components/constraints.h"
#include "core/components/lattice.h"
#include "core/components/nurbs.h"
#include "core/components/push_to_surface.h"
#include "core/components/wire.h"

namespace core {

namespace {

constexpr int kClusterChannels = 10;  // ClusterChannel values
using Channels = std::array<double, kClusterChannels>;

// What the stages share: rest state (bound once) and the pose being built.
struct PoseState {
  const Eigen::MatrixX3d& rest;
  const Eigen::MatrixX3i& triangles;
  const ComponentsDocument& doc;
  const PoseOptions& options;
  ComponentsPose pose;
  std::vector<double> muscle_drive_sums;           // per muscle: sum of control drives
  std::vector<Channels> cluster_channels;          // per cluster: summed control drives
  std::vector<Eigen::Vector3d> locator_rest;       // per locator
  std::vector<Eigen::Vector3d> locator_current;    // per locator
  std::vector<Eigen::Vector3d> pivot_rest;         // per cluster
  std::vector<Eigen::Vector3d> pivot_offset;       // per cluster: moved by its point constraint
  std::vector<Eigen::Matrix3d> cluster_aim;        // per cluster: aim rotation relative to rest
  std::vector<Eigen::Affine3d> cluster_muscles;    // per cluster: muscle transforms composed
  std::vector<Eigen::Affine3d> cluster_final;      // per cluster: the full transform
};

Status applyControls(PoseState& s, const std::map<std::string, double>& control_values) {
  const ComponentsDocument& doc = s.doc;
  for (const auto& [name, value] : control_values) {
    if (indexByName(doc.controls, name) < 0) {
      return makeError(ErrorCode::kInvalidArgument,
                       "controls: unknown control \"" + name + "\"" + didYouMean(name, namesOf(doc.controls)));
    }
    if (!std::isfinite(value)) {
      return makeError(ErrorCode::kInvalidArgument, "controls: \"" + name + "\" is not a finite number");
    }
  }
  s.muscle_drive_sums.assign(doc.muscles.size(), 0.0);
  s.cluster_channels.assign(doc.clusters.size(), Channels{});
  for (const Control& control : doc.controls) {
    const auto given = control_values.find(control.name);
    double value = given != control_values.end() ? given->second : control.default_value;
    if (value < control.min || value > control.max) {
      s.pose.clamped_controls.push_back(control.name);
      value = std::clamp(value, control.min, control.max);
    }
    s.pose.control_values[control.name] = value;
    for (const ControlDrive& drive : control.drives) {
      const double amount = drive.gain * value;
      switch (drive.kind) {
        case DriveTargetKind::kMuscle:
          s.muscle_drive_sums[static_cast<std::size_t>(indexByName(doc.muscles, drive.name))] += amount;
          break;
        case DriveTargetKind::kCluster:
          s.cluster_channels[static_cast<std::size_t>(indexByName(doc.clusters, drive.name))]
                            [static_cast<std::size_t>(drive.cluster_channel)] += amount;
          break;
        case DriveTargetKind::kLocator:
          s.locator_current[static_cast<std::size_t>(indexByName(doc.locators, drive.name))](
              static_cast<int>(drive.cluster_channel)) += amount;  // translate_x/y/z: validated
          break;
        case DriveTargetKind::kMorph: s.pose.morph_weights[drive.name] += amount; break;
        case DriveTargetKind::kJoint: {
          auto [it, fresh] = s.pose.joint_rotations.emplace(drive.name, Eigen::Vector3d::Zero());
          it->second(static_cast<int>(drive.joint_channel)) += amount;
          break;
        }
      }
    }
  }
  return Ok{};
}

// Muscles contract by their drives (clamped to range) and transform the
// clusters and locators they drive.
Status applyMuscles(PoseState& s) {
  const ComponentsDocument& doc = s.doc;
  for (std::size_t m = 0; m < doc.muscles.size(); ++m) {
    const Muscle& muscle = doc.muscles[m];
    const double c = std::clamp(s.muscle_drive_sums[m], muscle.min_contraction, muscle.max_contraction);
    s.pose.muscle_contractions[muscle.name] = c;
    const Eigen::Vector3d origin = resolveBinding(muscle.origin, s.rest, s.triangles);
    const Eigen::Vector3d insertion = resolveBinding(muscle.insertion, s.rest, s.triangles);
    if (!((insertion - origin).norm() > 0.0)) {
      return makeError(ErrorCode::kInvalidArgument, "muscles[" + std::to_string(m) + "] \"" + muscle.name +
                                                        "\": origin and insertion coincide on this mesh");
    }
    for (const MuscleDrive& drive : muscle.drives) {
      const Eigen::Affine3d t = muscleTransform(origin, insertion, c, drive.mode, drive.weight);
      if (drive.kind == TargetKind::kCluster) {
        auto& composed = s.cluster_muscles[static_cast<std::size_t>(indexByName(doc.clusters, drive.name))];
        composed = t * composed;
      } else {
        auto& p = s.locator_current[static_cast<std::size_t>(indexByName(doc.locators, drive.name))];
        p = t * p;
      }
    }
  }
  return Ok{};
}

// A constraint target's position now and at rest.
struct TargetPositions {
  Eigen::MatrixX3d now, rest;
  std::vector<double> weights;
};

Result<TargetPositions> targetPositions(const PoseState& s, const std::vector<ConstraintTarget>& targets,
                                        const std::string& where, bool need_rest) {
  TargetPositions out;
  out.now.resize(static_cast<Eigen::Index>(targets.size()), 3);
  out.rest.resize(static_cast<Eigen::Index>(targets.size()), 3);
  for (std::size_t t = 0; t < targets.size(); ++t) {
    const ConstraintTarget& target = targets[t];
    const auto row = static_cast<Eigen::Index>(t);
    out.weights.push_back(target.weight);
    if (target.kind == TargetKind::kLocator) {
      const auto l = static_cast<std::size_t>(indexByName(s.doc.locators, target.name));
      out.now.row(row) = s.locator_current[l].transpose();
      out.rest.row(row) = s.locator_rest[l].transpose();
    } else if (target.kind == TargetKind::kVertex) {
      out.now.row(row) = s.rest.row(target.vertex);  // vertices have not moved before the clusters
      out.rest.row(row) = s.rest.row(target.vertex);
    } else {
      const auto now = s.options.joint_positions.find(target.name);
      const auto rest = s.options.joint_rest_positions.find(target.name);
      if (now == s.options.joint_positions.end() || (need_rest && rest == s.options.joint_rest_positions.end())) {
        return makeError(ErrorCode::kInvalidArgument,
                         where + ": joint \"" + target.name + "\" has no position" + (need_rest ? " (posed and rest)" : "") +
                             " in PoseOptions");
      }
      out.now.row(row) = now->second.transpose();
      out.rest.row(row) = need_rest ? rest->second.transpose() : now->second.transpose();
    }
  }
  return out;
}

// The turn an aim constraint gives its object (a cluster, a joint) from
// its rest aim, model frame.
Eigen::Matrix3d aimTurn(const AimConstraint& c, const Eigen::Vector3d& now, const Eigen::Vector3d& goal,
                        const Eigen::Vector3d& rest, const Eigen::Vector3d& rest_goal) {
  return aimRotation(now, goal, c.aim_axis, c.up_axis, c.world_up) *
         aimRotation(rest, rest_goal, c.aim_axis, c.up_axis, c.world_up).transpose();
}

// Constraints in dependency order: an object after the locators it targets
// (validateComponents rejected cycles).
Status applyConstraints(PoseState& s) {
  const ComponentsDocument& doc = s.doc;
  std::map<std::string, int> point_of, aim_of;
  for (std::size_t i = 0; i < doc.point_constraints.size(); ++i) point_of[doc.point_constraints[i].constrained] = static_cast<int>(i);
  for (std::size_t i = 0; i < doc.aim_constraints.size(); ++i) {
    if (!doc.aim_constraints[i].joint) aim_of[doc.aim_constraints[i].constrained] = static_cast<int>(i);
  }
  std::set<std::string> done;
  std::function<Status(const std::string&)> evaluate = [&](const std::string& object) -> Status {
    if (!done.insert(object).second) return Ok{};
    const int locator = indexByName(doc.locators, object);
    const int cluster = indexByName(doc.clusters, object);
    auto dependOn = [&](const std::vector<ConstraintTarget>& targets) -> Status {
      for (const ConstraintTarget& t : targets) {
        if (t.kind != TargetKind::kLocator) continue;
        if (auto ok = evaluate(t.name); !ok) return ok;
      }
      return Ok{};
    };
    auto current = [&]() -> Eigen::Vector3d {
      return locator >= 0 ? s.locator_current[static_cast<std::size_t>(locator)]
                          : Eigen::Vector3d(s.pivot_rest[static_cast<std::size_t>(cluster)] + s.pivot_offset[static_cast<std::size_t>(cluster)]);
    };
    auto rest = [&]() -> Eigen::Vector3d {
      return locator >= 0 ? s.locator_rest[static_cast<std::size_t>(locator)] : s.pivot_rest[static_cast<std::size_t>(cluster)];
    };
    if (const auto p = point_of.find(object); p != point_of.end()) {
      const PointConstraint& c = doc.point_constraints[static_cast<std::size_t>(p->second)];
      if (auto ok = dependOn(c.targets); !ok) return ok;
      const std::string where = "point_constraints[" + std::to_string(p->second) + "] \"" + c.name + "\"";
      auto targets = targetPositions(s, c.targets, where, c.maintain_offset);
      if (!targets) return targets.error();
      Eigen::Vector3d goal = weightedAverage(targets->now, targets->weights);
      if (c.maintain_offset) goal += rest() - weightedAverage(targets->rest, targets->weights);
      if (locator >= 0) {
        s.locator_current[static_cast<std::size_t>(locator)] = goal;
      } else {
        s.pivot_offset[static_cast<std::size_t>(cluster)] = goal - s.pivot_rest[static_cast<std::size_t>(cluster)];
      }
    }
    if (const auto a = aim_of.find(object); a != aim_of.end()) {
      const AimConstraint& c = doc.aim_constraints[static_cast<std::size_t>(a->second)];
      if (auto ok = dependOn(c.targets); !ok) return ok;
      const std::string where = "aim_constraints[" + std::to_string(a->second) + "] \"" + c.name + "\"";
      auto targets = targetPositions(s, c.targets, where, cluster >= 0);
      if (!targets) return targets.error();
      const Eigen::Vector3d goal = weightedAverage(targets->now, targets->weights);
      if ((goal - current()).norm() < 1e-12) {
        return makeError(ErrorCode::kInvalidArgument, where + ": the targets' average coincides with \"" + object + "\"");
      }
      if (locator >= 0) {
        s.pose.locator_rotations[object] = aimRotation(current(), goal, c.aim_axis, c.up_axis, c.world_up);
      } else {
        const Eigen::Vector3d rest_goal = weightedAverage(targets->rest, targets->weights);
        if ((rest_goal - rest()).norm() < 1e-12) {
          return makeError(ErrorCode::kInvalidArgument, where + ": at rest the targets' average coincides with \"" + object + "\"");
        }
        s.cluster_aim[static_cast<std::size_t>(cluster)] = aimTurn(c, current(), goal, rest(), rest_goal);
      }
    }
    return Ok{};
  };
  for (const auto& c : doc.point_constraints) {
    if (auto ok = evaluate(c.constrained); !ok) return ok;
  }
  for (const auto& c : doc.aim_constraints) {
    if (!c.joint) {
      if (auto ok = evaluate(c.constrained); !ok) return ok;
    }
  }
  // Joints last: they aim at locators (now all placed) and nothing in the
  // document follows a joint's turn.
  for (std::size_t i = 0; i < doc.aim_constraints.size(); ++i) {
    const AimConstraint& c = doc.aim_constraints[i];
    if (!c.joint) continue;
    const std::string where = "aim_constraints[" + std::to_string(i) + "] \"" + c.name + "\"";
    const auto now = s.options.joint_positions.find(c.constrained);
    const auto rest = s.options.joint_rest_positions.find(c.constrained);
    if (now == s.options.joint_positions.end() || rest == s.options.joint_rest_positions.end()) {
      return makeError(ErrorCode::kInvalidArgument,
                       where + ": joint \"" + c.constrained + "\" has no position (posed and rest) in PoseOptions");
    }
    auto targets = targetPositions(s, c.targets, where, true);
    if (!targets) return targets.error();
    const Eigen::Vector3d goal = weightedAverage(targets->now, targets->weights);
    const Eigen::Vector3d rest_goal = weightedAverage(targets->rest, targets->weights);
    if ((goal - now->second).norm() < 1e-12 || (rest_goal - rest->second).norm() < 1e-12) {
      return makeError(ErrorCode::kInvalidArgument, where + ": the targets' average coincides with joint \"" + c.constrained + "\"");
    }
    s.pose.joint_aims[c.constrained] = aimTurn(c, now->second, goal, rest->second, rest_goal);
  }
  return Ok{};
}

// Each cluster's transform (authored, crease activation, channels, aim,
// pivot motion, muscles) applied to its members, in document order.
void applyClusters(PoseState& s, Eigen::MatrixX3d& positions) {
  const ComponentsDocument& doc = s.doc;
  std::vector<double> activation(doc.clusters.size(), 1.0);
  for (const CreaseCluster& crease : doc.crease_clusters) {
    double a = 0.0;
    for (const CreaseTrigger& t : crease.triggers) a += t.weight * s.pose.muscle_contractions.at(t.muscle);
    activation[static_cast<std::size_t>(indexByName(doc.clusters, crease.cluster))] = std::clamp(a, 0.0, 1.0);
  }
  for (std::size_t c = 0; c < doc.clusters.size(); ++c) {
    const Cluster& cluster = doc.clusters[c];
    const Channels& ch = s.cluster_channels[c];
    const double a = activation[c];
    const Eigen::Vector3d translate = a * cluster.translate + Eigen::Vector3d(ch[0], ch[1], ch[2]);
    const Eigen::Matrix3d rotation = s.cluster_aim[c] *
                                     Eigen::Quaterniond::Identity().slerp(a, cluster.rotate).toRotationMatrix() *
                                     eulerDegreesToRotation(Eigen::Vector3d(ch[3], ch[4], ch[5]));
    const Eigen::Vector3d scale = Eigen::Vector3d::Ones() + a * (cluster.scale - Eigen::Vector3d::Ones()) +
                                  Eigen::Vector3d(ch[6], ch[7], ch[8]) + Eigen::Vector3d::Constant(ch[9]);
    const Eigen::Affine3d own = clusterTransform(s.pivot_rest[c], translate + s.pivot_offset[c], rotation, scale);
    s.cluster_final[c] = own * s.cluster_muscles[c];
    s.pose.cluster_transforms[cluster.name] = s.cluster_final[c];
    applyCluster(positions, cluster.members, s.cluster_final[c]);
  }
}

// Control points at rest (bound on the rest mesh), moved by their drivers.
std::vector<Eigen::Vector3d> drivenPoints(const PoseState& s, std::vector<Eigen::Vector3d> points,
                                          const std::vector<PointDriver>& drivers) {
  for (const PointDriver& d : drivers) {
    Eigen::Vector3d& p = points[static_cast<std::size_t>(d.point)];
    if (d.kind == TargetKind::kCluster) {
      p += d.weight * (s.cluster_final[static_cast<std::size_t>(indexByName(s.doc.clusters, d.name))] * p - p);
    } else {
      const auto l = static_cast<std::size_t>(indexByName(s.doc.locators, d.name));
      p += d.weight * (s.locator_current[l] - s.locator_rest[l]);
    }
  }
  return points;
}

CurveGeometry curveGeometry(const NurbsCurve& curve, const std::vector<Eigen::Vector3d>& points) {
  CurveGeometry g;
  g.degree = curve.degree;
  g.knots = curve.knots;
  g.weights = curve.weights;
  g.points.resize(static_cast<Eigen::Index>(points.size()), 3);
  for (std::size_t i = 0; i < points.size(); ++i) g.points.row(static_cast<Eigen::Index>(i)) = points[i].transpose();
  return g;
}

// A sphere or ellipsoid push carried by a cluster's transform: its centre
// and `from` (resolved where they are now) moved by it, its axes and
// `vector` turned by its rotation (the cluster's scale is not applied to
// the surface's size).
PushToSurface carriedPush(const PushToSurface& push, const Eigen::Affine3d& carry, const Eigen::MatrixX3d& positions,
                          const Eigen::MatrixX3i& triangles) {
  PushToSurface moved = push;
  Eigen::Matrix3d turn, scaling;
  carry.computeRotationScaling(&turn, &scaling);
  moved.surface.center = Binding::atPosition(carry * resolveBinding(push.surface.center, positions, triangles));
  moved.surface.rotation = Eigen::Quaterniond(turn * push.surface.rotation.toRotationMatrix()).normalized();
  if (push.direction == PushDirection::kFromPoint) {
    moved.from = Binding::atPosition(carry * resolveBinding(push.from, positions, triangles));
  }
  moved.vector = turn * push.vector;
  return moved;
}

}  // namespace

Result<ComponentsPose> evaluatePose(const Eigen::MatrixX3d& rest_positions, const Eigen::MatrixX3i& triangles,
                                    const ComponentsDocument& doc, const std::map<std::string, double>& control_values,
                                    const PoseOptions& options) {
  ComponentsMeshCounts counts;
  counts.vertex_count = rest_positions.rows();
  counts.triangle_count = triangles.rows();
  if (!options.validated) {
    if (auto ok = validateComponents(doc, "components", counts); !ok) return ok.error();
  }
  if (!rest_positions.allFinite()) return makeError(ErrorCode::kInvalidMesh, "components: rest positions are not finite");

  PoseState s{rest_positions, triangles, doc, options, {}, {}, {}, {}, {}, {}, {}, {}, {}, {}};
  const std::size_t clusters = doc.clusters.size();
  for (const Locator& l : doc.locators) s.locator_rest.push_back(resolveBinding(l.binding, rest_positions, triangles));
  s.locator_current = s.locator_rest;
  for (const Cluster& c : doc.clusters) s.pivot_rest.push_back(resolveBinding(c.pivot, rest_positions, triangles));
  s.pivot_offset.assign(clusters, Eigen::Vector3d::Zero());
  s.cluster_aim.assign(clusters, Eigen::Matrix3d::Identity());
  s.cluster_muscles.assign(clusters, Eigen::Affine3d::Identity());
  s.cluster_final.assign(clusters, Eigen::Affine3d::Identity());

  // controls -> muscles and constraints -> clusters
  if (auto ok = applyControls(s, control_values); !ok) return ok.error();
  if (auto ok = applyMuscles(s); !ok) return ok.error();
  if (auto ok = applyConstraints(s); !ok) return ok.error();
  for (std::size_t l = 0; l < doc.locators.size(); ++l) s.pose.locator_positions[doc.locators[l].name] = s.locator_current[l];
  Eigen::MatrixX3d positions = rest_positions;
  applyClusters(s, positions);

  // -> wire CVs
  std::vector<CurveGeometry> curves;
  for (const NurbsCurve& curve : doc.curves) {
    std::vector<Eigen::Vector3d> points;
    for (const Binding& b : curve.points) points.push_back(resolveBinding(b, rest_positions, triangles));
    points = drivenPoints(s, std::move(points), curve.drivers);
    curves.push_back(curveGeometry(curve, points));
    s.pose.curve_points[curve.name] = std::move(points);
  }

  // -> deformers: wires, then lattices
  for (const Wire& wire : doc.wires) {
    evaluateWire(positions, curves[static_cast<std::size_t>(indexByName(doc.curves, wire.base_curve))],
                 curves[static_cast<std::size_t>(indexByName(doc.curves, wire.curve))], wire);
  }
  for (const Lattice& lattice : doc.lattices) {
    std::vector<Eigen::Vector3d> points = lattice.points.empty() ? latticeRestPoints(lattice) : lattice.points;
    points = drivenPoints(s, std::move(points), lattice.drivers);
    positions = evaluateLattice(positions, lattice, points);
    s.pose.lattice_points[lattice.name] = std::move(points);
  }

  // -> skull push
  for (const PushToSurface& push : doc.push_to_surfaces) {
    const Eigen::VectorXd levels = push.keep_rest_depth ? surfaceLevels(rest_positions, triangles, push) : Eigen::VectorXd();
    if (push.carried_by.empty()) {
      positions = evaluatePushToSurface(positions, triangles, push, levels);
    } else {
      const Eigen::Affine3d& carry = s.cluster_final[static_cast<std::size_t>(indexByName(doc.clusters, push.carried_by))];
      positions = evaluatePushToSurface(positions, triangles, carriedPush(push, carry, positions, triangles), levels);
    }
  }

  if (!positions.allFinite()) return makeError(ErrorCode::kInvalidArgument, "components: the pose is not finite");
  s.pose.positions = std::move(positions);
  return std::move(s.pose);
}

}  // namespace core
