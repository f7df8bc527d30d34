// validateComponents: names, references, ranges, knot vectors, constraint
// cycles and (given the mesh's counts) index ranges of a components document.
// Field names in messages are the JSON keys (core/io/components_io.cpp).
#include <cmath>
#include <functional>
#include <set>
#include <sstream>

#include "core/components/components.h"

namespace core {

namespace {

std::string elementLabel(const char* array, std::size_t i, const std::string& name) {
  std::string s = std::string(array) + "[" + std::to_string(i) + "]";
  if (!name.empty()) s += " \"" + name + "\"";
  return s;
}

std::string formatNumber(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

class Checker {
 public:
  Checker(const ComponentsDocument& doc, const std::string& label, const ComponentsMeshCounts& counts)
      : doc_(doc), label_(label), counts_(counts), locator_names_(namesOf(doc.locators)),
        cluster_names_(namesOf(doc.clusters)), curve_names_(namesOf(doc.curves)), muscle_names_(namesOf(doc.muscles)),
        control_names_(namesOf(doc.controls)) {
  }

  Status run();

 private:
  Error fail(const std::string& where, const std::string& what) const {
    return makeError(ErrorCode::kInvalidArgument, label_ + ": " + where + ": " + what);
  }
  // "unknown locator "mouht" (did you mean "mouth"?)"
  Error unknown(const std::string& where, const std::string& field, const char* kind, const std::string& name,
                const std::vector<std::string>& known) const {
    return fail(where, field + ": unknown " + kind + " \"" + name + "\"" + didYouMean(name, known));
  }
  Status checkFinite(const std::string& where, const std::string& field, double v) const {
    if (!std::isfinite(v)) return fail(where, field + " is not finite");
    return Ok{};
  }
  Status checkVertex(const std::string& where, const std::string& field, long long v) const {
    if (v < 0) return fail(where, field + " " + std::to_string(v) + " is negative");
    if (counts_.vertex_count >= 0 && v >= counts_.vertex_count) {
      return fail(where, field + " " + std::to_string(v) + " is out of range (mesh has " +
                             std::to_string(counts_.vertex_count) + " vertices)");
    }
    return Ok{};
  }
  Status checkMembers(const std::string& where, const std::vector<int>& members) const {
    for (std::size_t m = 0; m < members.size(); ++m) {
      if (auto ok = checkVertex(where, "members[" + std::to_string(m) + "]", members[m]); !ok) return ok;
    }
    return Ok{};
  }
  Status checkBinding(const std::string& where, const std::string& field, const Binding& b) const;
  Status checkNames(const char* array, const std::vector<std::string>& names) const;
  Status checkTargets(const std::string& where, const std::vector<ConstraintTarget>& targets) const;
  Status checkDrivers(const std::string& where, const std::vector<PointDriver>& drivers, std::size_t point_count) const;
  Status checkKnots(const std::string& where, const std::string& suffix, int degree, const std::vector<double>& knots,
                    std::size_t count) const;
  Status checkWeights(const std::string& where, const std::vector<double>& weights, std::size_t count) const;
  Status checkClusters() const;
  Status checkConstraints() const;
  Status checkConstraintCycles() const;
  Status checkCurves() const;
  Status checkDeformers() const;
  Status checkMuscles() const;
  Status checkControls() const;

  const ComponentsDocument& doc_;
  const std::string& label_;
  ComponentsMeshCounts counts_;
  std::vector<std::string> locator_names_, cluster_names_, curve_names_, muscle_names_, control_names_;
};

Status Checker::checkBinding(const std::string& where, const std::string& field, const Binding& b) const {
  switch (b.kind) {
    case BindingKind::kPosition:
      if (!b.position.allFinite()) return fail(where, field + ".position is not finite");
      return Ok{};
    case BindingKind::kVertex: return checkVertex(where, field + ".vertex", b.vertex);
    case BindingKind::kFace:
      if (b.face < 0) return fail(where, field + ".face is negative");
      if (counts_.triangle_count >= 0 && b.face >= counts_.triangle_count) {
        return fail(where, field + ".face " + std::to_string(b.face) + " is out of range (mesh has " +
                               std::to_string(counts_.triangle_count) + " triangles)");
      }
      if (!b.barycentric.allFinite() || b.barycentric.minCoeff() < -1e-9 || std::abs(b.barycentric.sum() - 1.0) > 1e-6) {
        return fail(where, field + ".barycentric must be finite, non-negative and sum to 1");
      }
      return Ok{};
  }
  return Ok{};
}

Status Checker::checkNames(const char* array, const std::vector<std::string>& names) const {
  std::set<std::string> seen;
  for (std::size_t i = 0; i < names.size(); ++i) {
    if (names[i].empty()) return fail(elementLabel(array, i, ""), "name must be a non-empty string");
    if (!seen.insert(names[i]).second) return fail(elementLabel(array, i, names[i]), "duplicate name");
  }
  return Ok{};
}

Status Checker::checkTargets(const std::string& where, const std::vector<ConstraintTarget>& targets) const {
  if (targets.empty()) return fail(where, "targets must not be empty");
  double sum = 0.0;
  for (std::size_t t = 0; t < targets.size(); ++t) {
    const ConstraintTarget& target = targets[t];
    const std::string field = "targets[" + std::to_string(t) + "]";
    if (!std::isfinite(target.weight) || target.weight < 0.0) return fail(where, field + ".weight must be finite and >= 0");
    sum += target.weight;
    switch (target.kind) {
      case TargetKind::kLocator:
        if (indexByName(doc_.locators, target.name) < 0) {
          return unknown(where, field + ".locator", "locator", target.name, locator_names_);
        }
        break;
      case TargetKind::kJoint:
        if (target.name.empty()) return fail(where, field + ".joint must be a non-empty name");
        break;
      case TargetKind::kVertex:
        if (auto ok = checkVertex(where, field + ".vertex", target.vertex); !ok) return ok;
        break;
      case TargetKind::kCluster: return fail(where, field + ": a cluster cannot be a target");
    }
  }
  if (!(sum > 0.0)) return fail(where, "targets: weights sum to 0");
  return Ok{};
}

Status Checker::checkDrivers(const std::string& where, const std::vector<PointDriver>& drivers,
                             std::size_t point_count) const {
  for (std::size_t d = 0; d < drivers.size(); ++d) {
    const PointDriver& driver = drivers[d];
    const std::string field = "drivers[" + std::to_string(d) + "]";
    if (driver.point < 0 || static_cast<std::size_t>(driver.point) >= point_count) {
      return fail(where, field + ".point " + std::to_string(driver.point) + " is out of range (" +
                             std::to_string(point_count) + " points)");
    }
    if (auto ok = checkFinite(where, field + ".weight", driver.weight); !ok) return ok;
    if (driver.kind == TargetKind::kCluster && indexByName(doc_.clusters, driver.name) < 0) {
      return unknown(where, field + ".cluster", "cluster", driver.name, cluster_names_);
    }
    if (driver.kind == TargetKind::kLocator && indexByName(doc_.locators, driver.name) < 0) {
      return unknown(where, field + ".locator", "locator", driver.name, locator_names_);
    }
    if (driver.kind != TargetKind::kCluster && driver.kind != TargetKind::kLocator) {
      return fail(where, field + ": a point is driven by a cluster or a locator");
    }
  }
  return Ok{};
}

Status Checker::checkKnots(const std::string& where, const std::string& suffix, int degree,
                           const std::vector<double>& knots, std::size_t count) const {
  if (degree < 1) return fail(where, "degree" + suffix + " must be >= 1");
  if (count < static_cast<std::size_t>(degree) + 1) {
    return fail(where, "points: degree" + suffix + " " + std::to_string(degree) + " needs at least " +
                           std::to_string(degree + 1) + " points, got " + std::to_string(count));
  }
  if (knots.size() != count + static_cast<std::size_t>(degree) + 1) {
    return fail(where, "knots" + suffix + " must hold points + degree + 1 = " +
                           std::to_string(count + static_cast<std::size_t>(degree) + 1) + " values, got " +
                           std::to_string(knots.size()));
  }
  for (std::size_t k = 0; k < knots.size(); ++k) {
    if (!std::isfinite(knots[k])) return fail(where, "knots" + suffix + "[" + std::to_string(k) + "] is not finite");
    if (k > 0 && knots[k] < knots[k - 1]) return fail(where, "knots" + suffix + " must be non-decreasing");
  }
  if (!(knots[static_cast<std::size_t>(degree)] < knots[count])) return fail(where, "knots" + suffix + ": empty domain");
  return Ok{};
}

Status Checker::checkWeights(const std::string& where, const std::vector<double>& weights, std::size_t count) const {
  if (weights.empty()) return Ok{};
  if (weights.size() != count) {
    return fail(where, "weights must be empty or hold one value per point (" + std::to_string(count) + ")");
  }
  for (std::size_t w = 0; w < weights.size(); ++w) {
    if (!std::isfinite(weights[w]) || weights[w] <= 0.0) {
      return fail(where, "weights[" + std::to_string(w) + "] must be finite and > 0");
    }
  }
  return Ok{};
}

Status Checker::checkClusters() const {
  for (std::size_t i = 0; i < doc_.locators.size(); ++i) {
    const Locator& l = doc_.locators[i];
    if (auto ok = checkBinding(elementLabel("locators", i, l.name), "binding", l.binding); !ok) return ok;
  }
  for (std::size_t i = 0; i < doc_.clusters.size(); ++i) {
    const Cluster& c = doc_.clusters[i];
    const std::string where = elementLabel("clusters", i, c.name);
    if (indexByName(doc_.locators, c.name) >= 0) return fail(where, "name is also a locator's (constraints name either)");
    if (auto ok = checkBinding(where, "pivot", c.pivot); !ok) return ok;
    for (std::size_t m = 0; m < c.members.size(); ++m) {
      const std::string field = "members[" + std::to_string(m) + "]";
      if (auto ok = checkVertex(where, field + ".vertex", c.members[m].vertex); !ok) return ok;
      if (auto ok = checkFinite(where, field + ".weight", c.members[m].weight); !ok) return ok;
    }
    if (!c.translate.allFinite()) return fail(where, "translate is not finite");
    if (!c.scale.allFinite()) return fail(where, "scale is not finite");
    if (!c.rotate.coeffs().allFinite() || std::abs(c.rotate.norm() - 1.0) > 1e-6) {
      return fail(where, "rotate_quaternion must be a finite unit quaternion");
    }
  }
  return Ok{};
}

Status Checker::checkConstraints() const {
  auto checkObject = [&](const std::string& where, const std::string& name) -> Status {
    if (indexByName(doc_.locators, name) >= 0 || indexByName(doc_.clusters, name) >= 0) return Ok{};
    std::vector<std::string> known = locator_names_;
    known.insert(known.end(), cluster_names_.begin(), cluster_names_.end());
    return unknown(where, "constrained", "locator or cluster", name, known);
  };
  std::map<std::string, std::string> point_constrained, aim_constrained;
  for (std::size_t i = 0; i < doc_.point_constraints.size(); ++i) {
    const PointConstraint& c = doc_.point_constraints[i];
    const std::string where = elementLabel("point_constraints", i, c.name);
    if (auto ok = checkObject(where, c.constrained); !ok) return ok;
    if (auto [it, fresh] = point_constrained.emplace(c.constrained, where); !fresh) {
      return fail(where, "constrained: \"" + c.constrained + "\" is already constrained by " + it->second);
    }
    if (auto ok = checkTargets(where, c.targets); !ok) return ok;
  }
  std::map<std::string, std::string> carried;  // joint -> the cluster carrying it
  for (std::size_t i = 0; i < doc_.clusters.size(); ++i) {
    const Cluster& c = doc_.clusters[i];
    if (c.joint.empty()) continue;
    const std::string where = elementLabel("clusters", i, c.name);
    if (auto [it, fresh] = carried.emplace(c.joint, where); !fresh) {
      return fail(where, "joint: \"" + c.joint + "\" is already carried by " + it->second);
    }
  }
  for (std::size_t i = 0; i < doc_.aim_constraints.size(); ++i) {
    const AimConstraint& c = doc_.aim_constraints[i];
    const std::string where = elementLabel("aim_constraints", i, c.name);
    if (c.joint && c.constrained.empty()) return fail(where, "constrained_joint must be a non-empty name");
    if (const auto it = carried.find(c.constrained); c.joint && it != carried.end()) {
      return fail(where, "constrained_joint: \"" + c.constrained + "\" is carried by " + it->second +
                             " (a joint takes one motion from the components)");
    }
    if (!c.joint) {
      if (auto ok = checkObject(where, c.constrained); !ok) return ok;
    }
    // A joint and a locator may share a name: they are different objects.
    if (auto [it, fresh] = aim_constrained.emplace((c.joint ? "joint " : "") + c.constrained, where); !fresh) {
      return fail(where, "constrained: \"" + c.constrained + "\" is already constrained by " + it->second);
    }
    if (auto ok = checkTargets(where, c.targets); !ok) return ok;
    if (!c.aim_axis.allFinite() || c.aim_axis.norm() < 1e-12) return fail(where, "aim_axis must be a finite non-zero vector");
    if (!c.up_axis.allFinite() || c.up_axis.norm() < 1e-12) return fail(where, "up_axis must be a finite non-zero vector");
    if (!c.world_up.allFinite() || c.world_up.norm() < 1e-12) return fail(where, "world_up must be a finite non-zero vector");
    if (c.aim_axis.normalized().cross(c.up_axis.normalized()).norm() < 1e-6) {
      return fail(where, "up_axis must not be parallel to aim_axis");
    }
  }
  return checkConstraintCycles();
}

// An object depends on the locators its constraints target; a cycle (a
// locator constrained, through others, to itself) has no evaluation order.
Status Checker::checkConstraintCycles() const {
  std::map<std::string, std::vector<std::string>> depends;
  std::map<std::string, std::string> where_of;
  auto add = [&](const std::string& object, const std::vector<ConstraintTarget>& targets, const std::string& where) {
    where_of.emplace(object, where);
    for (const ConstraintTarget& t : targets) {
      if (t.kind == TargetKind::kLocator) depends[object].push_back(t.name);
    }
  };
  for (std::size_t i = 0; i < doc_.point_constraints.size(); ++i) {
    const auto& c = doc_.point_constraints[i];
    add(c.constrained, c.targets, elementLabel("point_constraints", i, c.name));
  }
  for (std::size_t i = 0; i < doc_.aim_constraints.size(); ++i) {
    const auto& c = doc_.aim_constraints[i];
    if (!c.joint) add(c.constrained, c.targets, elementLabel("aim_constraints", i, c.name));  // nothing targets a joint's aim
  }
  std::map<std::string, int> state;  // 1: on the path, 2: done
  std::vector<std::string> path;
  std::function<bool(const std::string&)> visit = [&](const std::string& node) {
    state[node] = 1;
    path.push_back(node);
    for (const std::string& next : depends[node]) {
      if (state[next] == 1) {
        path.push_back(next);
        return true;
      }
      if (state[next] == 0 && visit(next)) return true;
    }
    state[node] = 2;
    path.pop_back();
    return false;
  };
  for (const auto& [object, targets] : depends) {
    if (state[object] != 0) continue;
    if (visit(object)) {
      const std::string& closing = path.back();
      std::size_t start = 0;
      while (path[start] != closing) ++start;
      std::string chain;
      for (std::size_t k = start; k < path.size(); ++k) chain += (k > start ? " -> " : "") + path[k];
      return fail(where_of[closing], "constraint cycle: " + chain);
    }
  }
  return Ok{};
}

Status Checker::checkCurves() const {
  for (std::size_t i = 0; i < doc_.curves.size(); ++i) {
    const NurbsCurve& c = doc_.curves[i];
    const std::string where = elementLabel("curves", i, c.name);
    if (auto ok = checkKnots(where, "", c.degree, c.knots, c.points.size()); !ok) return ok;
    if (auto ok = checkWeights(where, c.weights, c.points.size()); !ok) return ok;
    for (std::size_t p = 0; p < c.points.size(); ++p) {
      if (auto ok = checkBinding(where, "points[" + std::to_string(p) + "]", c.points[p]); !ok) return ok;
    }
    if (auto ok = checkDrivers(where, c.drivers, c.points.size()); !ok) return ok;
  }
  for (std::size_t i = 0; i < doc_.surfaces.size(); ++i) {
    const NurbsSurface& s = doc_.surfaces[i];
    const std::string where = elementLabel("surfaces", i, s.name);
    if (s.count_u < 1 || s.count_v < 1 || s.points.size() != static_cast<std::size_t>(s.count_u) * s.count_v) {
      return fail(where, "points must hold count_u * count_v bindings");
    }
    if (auto ok = checkKnots(where, "_u", s.degree_u, s.knots_u, static_cast<std::size_t>(s.count_u)); !ok) return ok;
    if (auto ok = checkKnots(where, "_v", s.degree_v, s.knots_v, static_cast<std::size_t>(s.count_v)); !ok) return ok;
    if (auto ok = checkWeights(where, s.weights, s.points.size()); !ok) return ok;
    for (std::size_t p = 0; p < s.points.size(); ++p) {
      if (auto ok = checkBinding(where, "points[" + std::to_string(p) + "]", s.points[p]); !ok) return ok;
    }
  }
  return Ok{};
}

Status Checker::checkDeformers() const {
  for (std::size_t i = 0; i < doc_.wires.size(); ++i) {
    const Wire& w = doc_.wires[i];
    const std::string where = elementLabel("wires", i, w.name);
    const int base = indexByName(doc_.curves, w.base_curve);
    const int curve = indexByName(doc_.curves, w.curve);
    if (base < 0) return unknown(where, "base_curve", "curve", w.base_curve, curve_names_);
    if (curve < 0) return unknown(where, "curve", "curve", w.curve, curve_names_);
    const NurbsCurve& a = doc_.curves[static_cast<std::size_t>(base)];
    const NurbsCurve& b = doc_.curves[static_cast<std::size_t>(curve)];
    if (a.degree != b.degree || a.knots != b.knots || a.points.size() != b.points.size()) {
      return fail(where, "curve \"" + w.curve + "\" and base_curve \"" + w.base_curve +
                             "\" must share degree, knots and point count");
    }
    if (!std::isfinite(w.dropoff_distance) || w.dropoff_distance <= 0.0) {
      return fail(where, "dropoff_distance must be > 0 (got " + formatNumber(w.dropoff_distance) + ")");
    }
    if (auto ok = checkFinite(where, "rotation", w.rotation); !ok) return ok;
    if (auto ok = checkFinite(where, "scale", w.scale); !ok) return ok;
    if (auto ok = checkFinite(where, "envelope", w.envelope); !ok) return ok;
    if (auto ok = checkMembers(where, w.members); !ok) return ok;
  }
  for (std::size_t i = 0; i < doc_.lattices.size(); ++i) {
    const Lattice& l = doc_.lattices[i];
    const std::string where = elementLabel("lattices", i, l.name);
    if (l.divisions.minCoeff() < 2 || l.divisions.maxCoeff() > 64) return fail(where, "divisions must be in [2, 64]");
    if (!l.origin.allFinite()) return fail(where, "origin is not finite");
    if (!l.axes.allFinite() || std::abs(l.axes.determinant()) < 1e-12 * std::pow(l.axes.norm(), 3)) {
      return fail(where, "axes must be finite and span 3D");
    }
    const std::size_t count = static_cast<std::size_t>(l.divisions.prod());
    if (!l.points.empty() && l.points.size() != count) {
      return fail(where, "points must be empty or hold " + std::to_string(count) + " points (divisions' product)");
    }
    for (std::size_t p = 0; p < l.points.size(); ++p) {
      if (!l.points[p].allFinite()) return fail(where, "points[" + std::to_string(p) + "] is not finite");
    }
    if (auto ok = checkDrivers(where, l.drivers, count); !ok) return ok;
    if (auto ok = checkMembers(where, l.members); !ok) return ok;
  }
  for (std::size_t i = 0; i < doc_.push_to_surfaces.size(); ++i) {
    const PushToSurface& p = doc_.push_to_surfaces[i];
    const std::string where = elementLabel("push_to_surfaces", i, p.name);
    const CollisionShape& s = p.surface;
    if (s.kind == CollisionShapeKind::kTriangles) {
      if (s.triangles.empty()) return fail(where, "surface.triangles must not be empty");
      for (std::size_t t = 0; t < s.triangles.size(); ++t) {
        for (int k = 0; k < 3; ++k) {
          const std::string field = "surface.triangles[" + std::to_string(t) + "][" + std::to_string(k) + "]";
          if (auto ok = checkVertex(where, field, s.triangles[t](k)); !ok) return ok;
        }
      }
    } else {
      if (auto ok = checkBinding(where, "surface.center", s.center); !ok) return ok;
      if (s.kind == CollisionShapeKind::kSphere && (!std::isfinite(s.radius) || s.radius <= 0.0)) {
        return fail(where, "surface.radius must be > 0");
      }
      if (s.kind == CollisionShapeKind::kEllipsoid && (!s.radii.allFinite() || s.radii.minCoeff() <= 0.0)) {
        return fail(where, "surface.radii must be > 0");
      }
      if (s.kind == CollisionShapeKind::kEllipsoid &&
          (!s.rotation.coeffs().allFinite() || std::abs(s.rotation.norm() - 1.0) > 1e-6)) {
        return fail(where, "surface.rotation_quaternion must be a finite unit quaternion");
      }
    }
    if (p.direction == PushDirection::kVector && (!p.vector.allFinite() || p.vector.norm() < 1e-12)) {
      return fail(where, "direction must be \"closest\" or a finite non-zero vector");
    }
    if (p.direction == PushDirection::kFromPoint) {
      if (auto ok = checkBinding(where, "direction.from", p.from); !ok) return ok;
    }
    if (p.keep_rest_depth && s.kind == CollisionShapeKind::kTriangles) {
      return fail(where, "keep_rest_depth: only a sphere or ellipsoid keeps its members' rest depth");
    }
    if (!p.carried_by.empty()) {
      if (s.kind == CollisionShapeKind::kTriangles) {
        return fail(where, "carried_by: a triangle surface moves with its vertices; only a sphere or ellipsoid is carried");
      }
      if (indexByName(doc_.clusters, p.carried_by) < 0) {
        return unknown(where, "carried_by", "cluster", p.carried_by, cluster_names_);
      }
    }
    if (auto ok = checkMembers(where, p.members); !ok) return ok;
  }
  return Ok{};
}

Status Checker::checkMuscles() const {
  for (std::size_t i = 0; i < doc_.muscles.size(); ++i) {
    const Muscle& m = doc_.muscles[i];
    const std::string where = elementLabel("muscles", i, m.name);
    if (auto ok = checkBinding(where, "origin", m.origin); !ok) return ok;
    if (auto ok = checkBinding(where, "insertion", m.insertion); !ok) return ok;
    if (m.origin == m.insertion) return fail(where, "origin and insertion must differ");
    if (!std::isfinite(m.min_contraction) || !std::isfinite(m.max_contraction) || m.min_contraction > m.max_contraction) {
      return fail(where, "range must be finite with min <= max");
    }
    if (m.max_contraction >= 1.0) return fail(where, "range: max must be < 1 (a full contraction collapses the element)");
    for (std::size_t d = 0; d < m.drives.size(); ++d) {
      const MuscleDrive& drive = m.drives[d];
      const std::string field = "drives[" + std::to_string(d) + "]";
      if (drive.kind == TargetKind::kCluster && indexByName(doc_.clusters, drive.name) < 0) {
        return unknown(where, field + ".cluster", "cluster", drive.name, cluster_names_);
      }
      if (drive.kind == TargetKind::kLocator && indexByName(doc_.locators, drive.name) < 0) {
        return unknown(where, field + ".locator", "locator", drive.name, locator_names_);
      }
      if (!std::isfinite(drive.weight) || drive.weight < 0.0 || drive.weight * m.max_contraction >= 1.0) {
        return fail(where, field + ".weight must be >= 0 with weight * max contraction < 1");
      }
    }
  }
  std::set<std::string> creased;
  for (std::size_t i = 0; i < doc_.crease_clusters.size(); ++i) {
    const CreaseCluster& c = doc_.crease_clusters[i];
    const std::string where = elementLabel("crease_clusters", i, c.cluster);
    if (indexByName(doc_.clusters, c.cluster) < 0) return unknown(where, "cluster", "cluster", c.cluster, cluster_names_);
    if (!creased.insert(c.cluster).second) return fail(where, "cluster: already a crease cluster");
    if (c.triggers.empty()) return fail(where, "triggers must not be empty");
    for (std::size_t t = 0; t < c.triggers.size(); ++t) {
      const std::string field = "triggers[" + std::to_string(t) + "]";
      if (indexByName(doc_.muscles, c.triggers[t].muscle) < 0) {
        return unknown(where, field + ".muscle", "muscle", c.triggers[t].muscle, muscle_names_);
      }
      if (auto ok = checkFinite(where, field + ".weight", c.triggers[t].weight); !ok) return ok;
    }
  }
  return Ok{};
}

Status Checker::checkControls() const {
  for (std::size_t i = 0; i < doc_.controls.size(); ++i) {
    const Control& c = doc_.controls[i];
    const std::string where = elementLabel("controls", i, c.name);
    if (!std::isfinite(c.min) || !std::isfinite(c.max) || c.min > c.max) {
      return fail(where, "range must be finite with min <= max");
    }
    if (!std::isfinite(c.default_value) || c.default_value < c.min || c.default_value > c.max) {
      return fail(where, "default must lie in range");
    }
    for (std::size_t d = 0; d < c.drives.size(); ++d) {
      const ControlDrive& drive = c.drives[d];
      const std::string field = "drives[" + std::to_string(d) + "]";
      if (auto ok = checkFinite(where, field + ".gain", drive.gain); !ok) return ok;
      switch (drive.kind) {
        case DriveTargetKind::kMuscle:
          if (indexByName(doc_.muscles, drive.name) < 0) {
            return unknown(where, field + ".muscle", "muscle", drive.name, muscle_names_);
          }
          break;
        case DriveTargetKind::kCluster:
          if (indexByName(doc_.clusters, drive.name) < 0) {
            return unknown(where, field + ".cluster", "cluster", drive.name, cluster_names_);
          }
          break;
        case DriveTargetKind::kLocator:
          if (indexByName(doc_.locators, drive.name) < 0) {
            return unknown(where, field + ".locator", "locator", drive.name, locator_names_);
          }
          if (drive.cluster_channel != ClusterChannel::kTranslateX && drive.cluster_channel != ClusterChannel::kTranslateY &&
              drive.cluster_channel != ClusterChannel::kTranslateZ) {
            return fail(where, field + ".channel: a locator takes translate_x, translate_y or translate_z only");
          }
          break;
        case DriveTargetKind::kMorph:
        case DriveTargetKind::kJoint:
          if (drive.name.empty()) return fail(where, field + ": needs a non-empty name");
          break;
      }
    }
  }
  for (const auto& [name, preset] : doc_.presets) {
    const std::string where = "presets \"" + name + "\"";
    if (name.empty()) return fail("presets", "a preset name must be non-empty");
    for (const auto& [control, value] : preset.controls) {
      const int c = indexByName(doc_.controls, control);
      if (c < 0) return unknown(where, "controls", "control", control, control_names_);
      const Control& known = doc_.controls[static_cast<std::size_t>(c)];
      if (!std::isfinite(value) || value < known.min || value > known.max) {
        return fail(where, "controls.\"" + control + "\": " + formatNumber(value) + " is outside the control's range [" +
                               formatNumber(known.min) + ", " + formatNumber(known.max) + "]");
      }
    }
  }
  return Ok{};
}

Status Checker::run() {
  if (doc_.version != kComponentsVersion) {
    return makeError(ErrorCode::kUnsupported, label_ + ": version " + std::to_string(doc_.version) +
                                                  " is not supported (expected " + std::to_string(kComponentsVersion) + ")");
  }
  if (auto ok = checkNames("wires", namesOf(doc_.wires)); !ok) return ok;
  if (auto ok = checkNames("lattices", namesOf(doc_.lattices)); !ok) return ok;
  if (auto ok = checkNames("push_to_surfaces", namesOf(doc_.push_to_surfaces)); !ok) return ok;
  if (auto ok = checkNames("surfaces", namesOf(doc_.surfaces)); !ok) return ok;
  if (auto ok = checkNames("point_constraints", namesOf(doc_.point_constraints)); !ok) return ok;
  if (auto ok = checkNames("aim_constraints", namesOf(doc_.aim_constraints)); !ok) return ok;
  if (auto ok = checkNames("locators", locator_names_); !ok) return ok;
  if (auto ok = checkNames("clusters", cluster_names_); !ok) return ok;
  if (auto ok = checkNames("curves", curve_names_); !ok) return ok;
  if (auto ok = checkNames("muscles", muscle_names_); !ok) return ok;
  if (auto ok = checkNames("controls", control_names_); !ok) return ok;
  if (auto ok = checkClusters(); !ok) return ok;
  if (auto ok = checkConstraints(); !ok) return ok;
  if (auto ok = checkCurves(); !ok) return ok;
  if (auto ok = checkDeformers(); !ok) return ok;
  if (auto ok = checkMuscles(); !ok) return ok;
  return checkControls();
}

}  // namespace

Status validateComponents(const ComponentsDocument& doc, const std::string& label, const ComponentsMeshCounts& counts) {
  return Checker(doc, label, counts).run();
}

}  // namespace core
