// Rig components JSON (docs/COMPONENTS.md). nlohmann::json is used privately
// here (file format edge); nothing JSON leaves this file. The field readers
// throw a private FieldError, caught in parseComponents: each reader then
// reads as a plain list of its fields, and nothing thrown leaves this file.
#include "core/io/components_io.h"

#include <array>
#include <cmath>
#include <initializer_list>
#include <limits>
#include <set>

#include <nlohmann/json.hpp>

#include "core/components/cluster.h"
#include "core/io/json_text.h"
#include "core/io/mesh_io.h"

namespace core {

namespace {

using Json = nlohmann::json;
using OrderedJson = nlohmann::ordered_json;

struct FieldError {
  std::string message;  // "<where>: <field> ..." without the file label
};

[[noreturn]] void fail(const std::string& where, const std::string& what) { throw FieldError{where + ": " + what}; }

void checkKeys(const Json& object, const std::string& where, std::initializer_list<const char*> allowed) {
  if (!object.is_object()) fail(where, "must be an object");
  for (const auto& [key, value] : object.items()) {
    bool known = false;
    for (const char* a : allowed) known = known || key == a;
    if (!known) {
      std::vector<std::string> names(allowed.begin(), allowed.end());
      fail(where, "unknown key \"" + key + "\"" + didYouMean(key, names));
    }
  }
}

double toNumber(const Json& value, const std::string& where, const std::string& field) {
  if (!value.is_number()) fail(where, field + " must be a number");
  const double v = value.get<double>();
  if (!std::isfinite(v)) fail(where, field + " is not finite");
  return v;
}

double number(const Json& object, const char* key, const std::string& where, double fallback) {
  return object.contains(key) ? toNumber(object[key], where, key) : fallback;
}

int toInt(const Json& value, const std::string& where, const std::string& field) {
  if (!value.is_number_integer()) fail(where, field + " must be an integer");
  const long long v = value.get<long long>();
  if (v < std::numeric_limits<int>::min() || v > std::numeric_limits<int>::max()) fail(where, field + " is out of range");
  return static_cast<int>(v);
}

int integer(const Json& object, const char* key, const std::string& where, int fallback) {
  return object.contains(key) ? toInt(object[key], where, key) : fallback;
}

const Json& required(const Json& object, const char* key, const std::string& where) {
  if (!object.contains(key)) fail(where, std::string("missing \"") + key + "\"");
  return object[key];
}

std::string text(const Json& object, const char* key, const std::string& where) {
  const Json& v = required(object, key, where);
  if (!v.is_string()) fail(where, std::string(key) + " must be a string");
  return v.get<std::string>();
}

bool boolean(const Json& object, const char* key, const std::string& where, bool fallback) {
  if (!object.contains(key)) return fallback;
  if (!object[key].is_boolean()) fail(where, std::string(key) + " must be true or false");
  return object[key].get<bool>();
}

const Json& array(const Json& object, const char* key, const std::string& where) {
  static const Json kEmpty = Json::array();
  if (!object.contains(key)) return kEmpty;
  if (!object[key].is_array()) fail(where, std::string(key) + " must be an array");
  return object[key];
}

template <int N>
Eigen::Matrix<double, N, 1> toVector(const Json& value, const std::string& where, const std::string& field) {
  if (!value.is_array() || value.size() != N) fail(where, field + " must be an array of " + std::to_string(N) + " numbers");
  Eigen::Matrix<double, N, 1> v;
  for (int k = 0; k < N; ++k) v(k) = toNumber(value[static_cast<std::size_t>(k)], where, field);
  return v;
}

Eigen::Vector3d vec3(const Json& object, const char* key, const std::string& where, const Eigen::Vector3d& fallback) {
  return object.contains(key) ? toVector<3>(object[key], where, key) : fallback;
}

// Each item of the array at `key`, read by read(item, "key[i]").
template <class T, class Read>
std::vector<T> arrayOf(const Json& object, const char* key, const std::string& where, Read&& read) {
  std::vector<T> out;
  const Json& values = array(object, key, where);
  out.reserve(values.size());
  for (std::size_t i = 0; i < values.size(); ++i) out.push_back(read(values[i], std::string(key) + "[" + std::to_string(i) + "]"));
  return out;
}

std::vector<double> numbers(const Json& object, const char* key, const std::string& where) {
  return arrayOf<double>(object, key, where, [&](const Json& v, const std::string& field) { return toNumber(v, where, field); });
}

std::vector<int> integers(const Json& object, const char* key, const std::string& where) {
  return arrayOf<int>(object, key, where, [&](const Json& v, const std::string& field) { return toInt(v, where, field); });
}

// [x, y, z, w], normalised unless already unit to rounding (so a written
// document reads back bit-identical).
Eigen::Quaterniond quaternion(const Json& value, const std::string& where, const std::string& field) {
  const Eigen::Vector4d v = toVector<4>(value, where, field);
  const double norm = v.norm();
  if (!(norm > 1e-12)) fail(where, field + " must be a non-zero quaternion [x, y, z, w]");
  Eigen::Quaterniond q(v(3), v(0), v(1), v(2));
  if (std::abs(norm - 1.0) > 1e-14) q.normalize();
  return q;
}

Binding binding(const Json& value, const std::string& where, const std::string& field) {
  const std::string here = where + ": " + field;
  checkKeys(value, here, {"position", "vertex", "face", "barycentric"});
  const int kinds = int(value.contains("position")) + int(value.contains("vertex")) + int(value.contains("face"));
  if (kinds != 1) fail(where, field + " needs exactly one of \"position\", \"vertex\" or \"face\" + \"barycentric\"");
  if (value.contains("position")) return Binding::atPosition(toVector<3>(value["position"], where, field + ".position"));
  if (value.contains("vertex")) return Binding::atVertex(toInt(value["vertex"], where, field + ".vertex"));
  if (!value.contains("barycentric")) fail(where, field + ".face needs \"barycentric\" [a, b, c]");
  return Binding::onFace(toInt(value["face"], where, field + ".face"),
                         toVector<3>(value["barycentric"], where, field + ".barycentric"));
}

std::string elementWhere(const char* array_name, std::size_t i, const Json& e, const char* name_key = "name") {
  std::string where = std::string(array_name) + "[" + std::to_string(i) + "]";
  if (e.is_object() && e.contains(name_key) && e[name_key].is_string()) where += " \"" + e[name_key].get<std::string>() + "\"";
  return where;
}

template <class Fn>
void forEach(const Json& doc, const char* key, Fn&& fn) {
  const Json& items = array(doc, key, key);
  for (std::size_t i = 0; i < items.size(); ++i) fn(items[i], elementWhere(key, i, items[i], std::string(key) == "crease_clusters" ? "cluster" : "name"));
}

// {"locator": n} | {"joint": n} | {"vertex": i}, "weight"
ConstraintTarget constraintTarget(const Json& e, const std::string& where, const std::string& field) {
  checkKeys(e, where + ": " + field, {"locator", "joint", "vertex", "weight"});
  ConstraintTarget t;
  const int kinds = int(e.contains("locator")) + int(e.contains("joint")) + int(e.contains("vertex"));
  if (kinds != 1) fail(where, field + " needs exactly one of \"locator\", \"joint\" or \"vertex\"");
  if (e.contains("vertex")) {
    t.kind = TargetKind::kVertex;
    t.vertex = toInt(e["vertex"], where, field + ".vertex");
  } else {
    t.kind = e.contains("locator") ? TargetKind::kLocator : TargetKind::kJoint;
    const char* key = e.contains("locator") ? "locator" : "joint";
    if (!e[key].is_string()) fail(where, field + "." + key + " must be a string");
    t.name = e[key].get<std::string>();
  }
  t.weight = number(e, "weight", where, 1.0);
  return t;
}

std::vector<ConstraintTarget> constraintTargets(const Json& e, const std::string& where) {
  std::vector<ConstraintTarget> out;
  const Json& items = array(e, "targets", where);
  for (std::size_t i = 0; i < items.size(); ++i) out.push_back(constraintTarget(items[i], where, "targets[" + std::to_string(i) + "]"));
  return out;
}

// {"cluster": n} | {"locator": n}: the kind and name of what moves a point or is driven.
std::pair<TargetKind, std::string> clusterOrLocator(const Json& e, const std::string& where, const std::string& field) {
  const int kinds = int(e.contains("cluster")) + int(e.contains("locator"));
  if (kinds != 1) fail(where, field + " needs exactly one of \"cluster\" or \"locator\"");
  const char* key = e.contains("cluster") ? "cluster" : "locator";
  if (!e[key].is_string()) fail(where, field + "." + key + " must be a string");
  return {e.contains("cluster") ? TargetKind::kCluster : TargetKind::kLocator, e[key].get<std::string>()};
}

std::vector<PointDriver> pointDrivers(const Json& e, const std::string& where) {
  std::vector<PointDriver> out;
  const Json& items = array(e, "drivers", where);
  for (std::size_t i = 0; i < items.size(); ++i) {
    const std::string field = "drivers[" + std::to_string(i) + "]";
    checkKeys(items[i], where + ": " + field, {"point", "cluster", "locator", "weight"});
    PointDriver d;
    d.point = toInt(required(items[i], "point", where + ": " + field), where, field + ".point");
    std::tie(d.kind, d.name) = clusterOrLocator(items[i], where, field);
    d.weight = number(items[i], "weight", where, 1.0);
    out.push_back(d);
  }
  return out;
}

std::vector<Binding> bindings(const Json& e, const char* key, const std::string& where) {
  return arrayOf<Binding>(e, key, where, [&](const Json& v, const std::string& field) { return binding(v, where, field); });
}

std::pair<double, double> range(const Json& e, const std::string& where, double lo, double hi) {
  if (!e.contains("range")) return {lo, hi};
  const Eigen::Vector2d r = toVector<2>(e["range"], where, "range");
  return {r(0), r(1)};
}

template <class Enum, std::size_t N>
Enum enumByName(const Json& value, const std::string& where, const std::string& field,
                const std::array<std::pair<const char*, Enum>, N>& table) {
  if (!value.is_string()) fail(where, field + " must be a string");
  const std::string name = value.get<std::string>();
  std::vector<std::string> names;
  for (const auto& [n, e] : table) {
    if (name == n) return e;
    names.push_back(n);
  }
  std::string what = field + ": unknown value \"" + name + "\" (one of " + joinNames(names) + ")";
  fail(where, what);
}

constexpr std::array<std::pair<const char*, ClusterChannel>, 10> kClusterChannels{{
    {"translate_x", ClusterChannel::kTranslateX}, {"translate_y", ClusterChannel::kTranslateY},
    {"translate_z", ClusterChannel::kTranslateZ}, {"rotate_x", ClusterChannel::kRotateX},
    {"rotate_y", ClusterChannel::kRotateY},       {"rotate_z", ClusterChannel::kRotateZ},
    {"scale_x", ClusterChannel::kScaleX},         {"scale_y", ClusterChannel::kScaleY},
    {"scale_z", ClusterChannel::kScaleZ},         {"scale", ClusterChannel::kScale}}};
constexpr std::array<std::pair<const char*, JointChannel>, 3> kJointChannels{
    {{"rotate_x", JointChannel::kRotateX}, {"rotate_y", JointChannel::kRotateY}, {"rotate_z", JointChannel::kRotateZ}}};
constexpr std::array<std::pair<const char*, MuscleDriveMode>, 2> kMuscleModes{
    {{"axial_scale", MuscleDriveMode::kAxialScale}, {"translate", MuscleDriveMode::kTranslate}}};

void readRigObjects(const Json& doc, ComponentsDocument& out) {
  forEach(doc, "locators", [&](const Json& e, const std::string& where) {
    checkKeys(e, where, {"name", "binding"});
    out.locators.push_back(Locator{text(e, "name", where), binding(required(e, "binding", where), where, "binding")});
  });
  forEach(doc, "clusters", [&](const Json& e, const std::string& where) {
    checkKeys(e, where, {"name", "pivot", "members", "translate", "rotate_quaternion", "rotate_euler_deg", "scale", "joint"});
    Cluster c;
    c.name = text(e, "name", where);
    c.pivot = binding(required(e, "pivot", where), where, "pivot");
    const Json& members = array(e, "members", where);
    for (std::size_t i = 0; i < members.size(); ++i) {
      const std::string field = "members[" + std::to_string(i) + "]";
      checkKeys(members[i], where + ": " + field, {"vertex", "weight"});
      c.members.push_back(ClusterMember{toInt(required(members[i], "vertex", where + ": " + field), where, field + ".vertex"),
                                        number(members[i], "weight", where, 1.0)});
    }
    c.translate = vec3(e, "translate", where, Eigen::Vector3d::Zero());
    if (e.contains("rotate_quaternion") && e.contains("rotate_euler_deg")) {
      fail(where, "give rotate_quaternion or rotate_euler_deg, not both");
    }
    if (e.contains("rotate_quaternion")) c.rotate = quaternion(e["rotate_quaternion"], where, "rotate_quaternion");
    if (e.contains("rotate_euler_deg")) {
      c.rotate = Eigen::Quaterniond(eulerDegreesToRotation(toVector<3>(e["rotate_euler_deg"], where, "rotate_euler_deg")));
    }
    c.scale = vec3(e, "scale", where, Eigen::Vector3d::Ones());
    if (e.contains("joint")) {
      c.joint = text(e, "joint", where);
      if (c.joint.empty()) fail(where, "joint must be a non-empty name (a joint of the rig)");
    }
    out.clusters.push_back(std::move(c));
  });
  forEach(doc, "point_constraints", [&](const Json& e, const std::string& where) {
    checkKeys(e, where, {"name", "constrained", "targets", "maintain_offset"});
    out.point_constraints.push_back(PointConstraint{text(e, "name", where), text(e, "constrained", where),
                                                    constraintTargets(e, where), boolean(e, "maintain_offset", where, true)});
  });
  forEach(doc, "aim_constraints", [&](const Json& e, const std::string& where) {
    checkKeys(e, where, {"name", "constrained", "constrained_joint", "targets", "aim_axis", "up_axis", "world_up"});
    if (e.contains("constrained") == e.contains("constrained_joint")) {
      fail(where, "needs exactly one of \"constrained\" (a locator or cluster) or \"constrained_joint\"");
    }
    const bool joint = e.contains("constrained_joint");
    out.aim_constraints.push_back(AimConstraint{text(e, "name", where), text(e, joint ? "constrained_joint" : "constrained", where),
                                                constraintTargets(e, where),
                                                vec3(e, "aim_axis", where, Eigen::Vector3d::UnitZ()),
                                                vec3(e, "up_axis", where, Eigen::Vector3d::UnitY()),
                                                vec3(e, "world_up", where, Eigen::Vector3d::UnitY()), joint});
  });
}

void readCurvesAndDeformers(const Json& doc, ComponentsDocument& out) {
  forEach(doc, "curves", [&](const Json& e, const std::string& where) {
    checkKeys(e, where, {"name", "degree", "knots", "points", "weights", "drivers"});
    out.curves.push_back(NurbsCurve{text(e, "name", where), integer(e, "degree", where, 3), numbers(e, "knots", where),
                                    bindings(e, "points", where), numbers(e, "weights", where), pointDrivers(e, where)});
  });
  forEach(doc, "surfaces", [&](const Json& e, const std::string& where) {
    checkKeys(e, where, {"name", "degree_u", "degree_v", "knots_u", "knots_v", "count_u", "count_v", "points", "weights"});
    out.surfaces.push_back(NurbsSurface{text(e, "name", where), integer(e, "degree_u", where, 3), integer(e, "degree_v", where, 3),
                                        numbers(e, "knots_u", where), numbers(e, "knots_v", where),
                                        toInt(required(e, "count_u", where), where, "count_u"),
                                        toInt(required(e, "count_v", where), where, "count_v"), bindings(e, "points", where),
                                        numbers(e, "weights", where)});
  });
  forEach(doc, "wires", [&](const Json& e, const std::string& where) {
    checkKeys(e, where, {"name", "base_curve", "curve", "dropoff_distance", "rotation", "scale", "envelope", "members"});
    out.wires.push_back(Wire{text(e, "name", where), text(e, "base_curve", where), text(e, "curve", where),
                             toNumber(required(e, "dropoff_distance", where), where, "dropoff_distance"),
                             number(e, "rotation", where, 1.0), number(e, "scale", where, 0.0),
                             number(e, "envelope", where, 1.0), integers(e, "members", where)});
  });
  forEach(doc, "lattices", [&](const Json& e, const std::string& where) {
    checkKeys(e, where, {"name", "origin", "axes", "divisions", "points", "drivers", "members"});
    Lattice l;
    l.name = text(e, "name", where);
    l.origin = vec3(e, "origin", where, Eigen::Vector3d::Zero());
    if (e.contains("axes")) {
      const Json& axes = e["axes"];
      if (!axes.is_array() || axes.size() != 3) fail(where, "axes must be 3 edge vectors [[S], [T], [U]]");
      for (int k = 0; k < 3; ++k) l.axes.col(k) = toVector<3>(axes[static_cast<std::size_t>(k)], where, "axes[" + std::to_string(k) + "]");
    }
    if (e.contains("divisions")) {
      const Json& d = e["divisions"];
      if (!d.is_array() || d.size() != 3) fail(where, "divisions must be 3 integers");
      for (int k = 0; k < 3; ++k) l.divisions(k) = toInt(d[static_cast<std::size_t>(k)], where, "divisions");
    }
    const Json& points = array(e, "points", where);
    for (std::size_t i = 0; i < points.size(); ++i) l.points.push_back(toVector<3>(points[i], where, "points[" + std::to_string(i) + "]"));
    l.drivers = pointDrivers(e, where);
    l.members = integers(e, "members", where);
    out.lattices.push_back(std::move(l));
  });
  forEach(doc, "push_to_surfaces", [&](const Json& e, const std::string& where) {
    checkKeys(e, where, {"name", "surface", "direction", "members", "carried_by", "keep_rest_depth"});
    PushToSurface p;
    p.name = text(e, "name", where);
    const Json& s = required(e, "surface", where);
    checkKeys(s, where + ": surface", {"triangles", "sphere", "ellipsoid"});
    if (s.size() != 1) fail(where, "surface needs exactly one of \"triangles\", \"sphere\" or \"ellipsoid\"");
    if (s.contains("triangles")) {
      p.surface.kind = CollisionShapeKind::kTriangles;
      const Json& tris = s["triangles"];
      if (!tris.is_array()) fail(where, "surface.triangles must be an array of [a, b, c]");
      for (std::size_t t = 0; t < tris.size(); ++t) {
        const std::string field = "surface.triangles[" + std::to_string(t) + "]";
        if (!tris[t].is_array() || tris[t].size() != 3) fail(where, field + " must be 3 vertex indices");
        p.surface.triangles.emplace_back(toInt(tris[t][0], where, field), toInt(tris[t][1], where, field), toInt(tris[t][2], where, field));
      }
    } else if (s.contains("sphere")) {
      const Json& sphere = s["sphere"];
      checkKeys(sphere, where + ": surface.sphere", {"center", "radius"});
      p.surface.kind = CollisionShapeKind::kSphere;
      p.surface.center = binding(required(sphere, "center", where), where, "surface.sphere.center");
      p.surface.radius = toNumber(required(sphere, "radius", where), where, "surface.sphere.radius");
    } else {
      const Json& ellipsoid = s["ellipsoid"];
      checkKeys(ellipsoid, where + ": surface.ellipsoid", {"center", "radii", "rotation_quaternion"});
      p.surface.kind = CollisionShapeKind::kEllipsoid;
      p.surface.center = binding(required(ellipsoid, "center", where), where, "surface.ellipsoid.center");
      p.surface.radii = toVector<3>(required(ellipsoid, "radii", where), where, "surface.ellipsoid.radii");
      if (ellipsoid.contains("rotation_quaternion")) {
        p.surface.rotation = quaternion(ellipsoid["rotation_quaternion"], where, "surface.ellipsoid.rotation_quaternion");
      }
    }
    if (e.contains("direction")) {
      if (e["direction"].is_string()) {
        if (e["direction"].get<std::string>() != "closest") {
          fail(where, "direction must be \"closest\", a vector [x, y, z] or {\"from\": binding}");
        }
      } else if (e["direction"].is_object()) {
        checkKeys(e["direction"], where + ": direction", {"from"});
        p.direction = PushDirection::kFromPoint;
        p.from = binding(required(e["direction"], "from", where), where, "direction.from");
      } else {
        p.direction = PushDirection::kVector;
        p.vector = toVector<3>(e["direction"], where, "direction");
      }
    }
    p.members = integers(e, "members", where);
    if (e.contains("carried_by")) {
      p.carried_by = text(e, "carried_by", where);
      if (p.carried_by.empty()) fail(where, "carried_by must be a non-empty name (a cluster)");
    }
    p.keep_rest_depth = boolean(e, "keep_rest_depth", where, false);
    out.push_to_surfaces.push_back(std::move(p));
  });
}

void readDrives(const Json& doc, ComponentsDocument& out) {
  forEach(doc, "muscles", [&](const Json& e, const std::string& where) {
    checkKeys(e, where, {"name", "origin", "insertion", "range", "drives"});
    Muscle m;
    m.name = text(e, "name", where);
    m.origin = binding(required(e, "origin", where), where, "origin");
    m.insertion = binding(required(e, "insertion", where), where, "insertion");
    std::tie(m.min_contraction, m.max_contraction) = range(e, where, 0.0, 0.5);
    const Json& drives = array(e, "drives", where);
    for (std::size_t i = 0; i < drives.size(); ++i) {
      const std::string field = "drives[" + std::to_string(i) + "]";
      checkKeys(drives[i], where + ": " + field, {"cluster", "locator", "mode", "weight"});
      MuscleDrive d;
      std::tie(d.kind, d.name) = clusterOrLocator(drives[i], where, field);
      if (drives[i].contains("mode")) d.mode = enumByName(drives[i]["mode"], where, field + ".mode", kMuscleModes);
      d.weight = number(drives[i], "weight", where, 1.0);
      m.drives.push_back(d);
    }
    out.muscles.push_back(std::move(m));
  });
  forEach(doc, "crease_clusters", [&](const Json& e, const std::string& where) {
    checkKeys(e, where, {"cluster", "triggers"});
    CreaseCluster c;
    c.cluster = text(e, "cluster", where);
    const Json& triggers = array(e, "triggers", where);
    for (std::size_t i = 0; i < triggers.size(); ++i) {
      const std::string field = "triggers[" + std::to_string(i) + "]";
      checkKeys(triggers[i], where + ": " + field, {"muscle", "weight"});
      c.triggers.push_back(CreaseTrigger{text(triggers[i], "muscle", where + ": " + field), number(triggers[i], "weight", where, 1.0)});
    }
    out.crease_clusters.push_back(std::move(c));
  });
  forEach(doc, "controls", [&](const Json& e, const std::string& where) {
    checkKeys(e, where, {"name", "range", "default", "drives"});
    Control c;
    c.name = text(e, "name", where);
    std::tie(c.min, c.max) = range(e, where, 0.0, 1.0);
    c.default_value = number(e, "default", where, 0.0);
    const Json& drives = array(e, "drives", where);
    for (std::size_t i = 0; i < drives.size(); ++i) {
      const Json& d = drives[i];
      const std::string field = "drives[" + std::to_string(i) + "]";
      checkKeys(d, where + ": " + field, {"muscle", "cluster", "morph", "joint", "locator", "channel", "gain"});
      ControlDrive drive;
      constexpr std::array<std::pair<const char*, DriveTargetKind>, 5> kKinds{{{"muscle", DriveTargetKind::kMuscle},
                                                                               {"cluster", DriveTargetKind::kCluster},
                                                                               {"morph", DriveTargetKind::kMorph},
                                                                               {"joint", DriveTargetKind::kJoint},
                                                                               {"locator", DriveTargetKind::kLocator}}};
      const char* key = nullptr;
      int kinds = 0;
      for (const auto& [name, kind] : kKinds) {
        if (!d.contains(name)) continue;
        ++kinds;
        key = name;
        drive.kind = kind;
      }
      if (kinds != 1) fail(where, field + " needs exactly one of \"muscle\", \"cluster\", \"morph\", \"joint\" or \"locator\"");
      if (!d[key].is_string()) fail(where, field + "." + key + " must be a string");
      drive.name = d[key].get<std::string>();
      const bool has_channel = drive.kind == DriveTargetKind::kCluster || drive.kind == DriveTargetKind::kJoint ||
                               drive.kind == DriveTargetKind::kLocator;
      if (has_channel && !d.contains("channel")) fail(where, field + " needs a \"channel\"");
      if (!has_channel && d.contains("channel")) fail(where, field + ".channel applies to cluster, joint and locator drives only");
      if (drive.kind == DriveTargetKind::kCluster || drive.kind == DriveTargetKind::kLocator) {
        drive.cluster_channel = enumByName(d["channel"], where, field + ".channel", kClusterChannels);
      }
      if (drive.kind == DriveTargetKind::kJoint) drive.joint_channel = enumByName(d["channel"], where, field + ".channel", kJointChannels);
      drive.gain = number(d, "gain", where, 1.0);
      c.drives.push_back(drive);
    }
    out.controls.push_back(std::move(c));
  });
  if (doc.contains("presets")) {
    const Json& presets = doc["presets"];
    if (!presets.is_object()) fail("presets", "must be an object keyed by preset name");
    for (const auto& [name, preset] : presets.items()) {
      const std::string where = "presets \"" + name + "\"";
      checkKeys(preset, where, {"controls"});
      const Json& controls = required(preset, "controls", where);
      if (!controls.is_object()) fail(where, "controls must be an object of control name -> value");
      Preset p;
      for (const auto& [control, value] : controls.items()) p.controls[control] = toNumber(value, where, "controls.\"" + control + "\"");
      out.presets[name] = std::move(p);
    }
  }
}

OrderedJson writeVec(const Eigen::Vector3d& v) { return OrderedJson::array({v(0), v(1), v(2)}); }

OrderedJson writeBinding(const Binding& b) {
  OrderedJson j = OrderedJson::object();
  switch (b.kind) {
    case BindingKind::kPosition: j["position"] = writeVec(b.position); break;
    case BindingKind::kVertex: j["vertex"] = b.vertex; break;
    case BindingKind::kFace:
      j["face"] = b.face;
      j["barycentric"] = writeVec(b.barycentric);
      break;
  }
  return j;
}

OrderedJson writeQuaternion(const Eigen::Quaterniond& q) { return OrderedJson::array({q.x(), q.y(), q.z(), q.w()}); }

OrderedJson writeTargets(const std::vector<ConstraintTarget>& targets) {
  OrderedJson out = OrderedJson::array();
  for (const ConstraintTarget& t : targets) {
    OrderedJson j;
    if (t.kind == TargetKind::kVertex) j["vertex"] = t.vertex;
    else j[t.kind == TargetKind::kLocator ? "locator" : "joint"] = t.name;
    j["weight"] = t.weight;
    out.push_back(std::move(j));
  }
  return out;
}

OrderedJson writeDrivers(const std::vector<PointDriver>& drivers) {
  OrderedJson out = OrderedJson::array();
  for (const PointDriver& d : drivers) {
    OrderedJson j;
    j["point"] = d.point;
    j[d.kind == TargetKind::kCluster ? "cluster" : "locator"] = d.name;
    j["weight"] = d.weight;
    out.push_back(std::move(j));
  }
  return out;
}

OrderedJson writeBindings(const std::vector<Binding>& bindings) {
  OrderedJson out = OrderedJson::array();
  for (const Binding& b : bindings) out.push_back(writeBinding(b));
  return out;
}

template <class T>
OrderedJson writeArray(const std::vector<T>& values) {
  OrderedJson out = OrderedJson::array();
  for (const T& v : values) out.push_back(v);
  return out;
}

void writeRigObjects(const ComponentsDocument& doc, OrderedJson& out) {
  for (const Locator& l : doc.locators) out["locators"].push_back(OrderedJson{{"name", l.name}, {"binding", writeBinding(l.binding)}});
  for (const Cluster& c : doc.clusters) {
    OrderedJson j{{"name", c.name}, {"pivot", writeBinding(c.pivot)}, {"members", OrderedJson::array()}};
    for (const ClusterMember& m : c.members) j["members"].push_back(OrderedJson{{"vertex", m.vertex}, {"weight", m.weight}});
    j["translate"] = writeVec(c.translate);
    j["rotate_quaternion"] = writeQuaternion(c.rotate);
    j["scale"] = writeVec(c.scale);
    if (!c.joint.empty()) j["joint"] = c.joint;
    out["clusters"].push_back(std::move(j));
  }
  for (const PointConstraint& c : doc.point_constraints) {
    out["point_constraints"].push_back(OrderedJson{{"name", c.name}, {"constrained", c.constrained},
                                                   {"targets", writeTargets(c.targets)}, {"maintain_offset", c.maintain_offset}});
  }
  for (const AimConstraint& c : doc.aim_constraints) {
    out["aim_constraints"].push_back(OrderedJson{{"name", c.name}, {c.joint ? "constrained_joint" : "constrained", c.constrained},
                                                 {"targets", writeTargets(c.targets)}, {"aim_axis", writeVec(c.aim_axis)},
                                                 {"up_axis", writeVec(c.up_axis)}, {"world_up", writeVec(c.world_up)}});
  }
}

void writeCurvesAndDeformers(const ComponentsDocument& doc, OrderedJson& out) {
  for (const NurbsCurve& c : doc.curves) {
    out["curves"].push_back(OrderedJson{{"name", c.name}, {"degree", c.degree}, {"knots", writeArray(c.knots)},
                                        {"points", writeBindings(c.points)}, {"weights", writeArray(c.weights)},
                                        {"drivers", writeDrivers(c.drivers)}});
  }
  for (const NurbsSurface& s : doc.surfaces) {
    out["surfaces"].push_back(OrderedJson{{"name", s.name}, {"degree_u", s.degree_u}, {"degree_v", s.degree_v},
                                          {"knots_u", writeArray(s.knots_u)}, {"knots_v", writeArray(s.knots_v)},
                                          {"count_u", s.count_u}, {"count_v", s.count_v},
                                          {"points", writeBindings(s.points)}, {"weights", writeArray(s.weights)}});
  }
  for (const Wire& w : doc.wires) {
    out["wires"].push_back(OrderedJson{{"name", w.name}, {"base_curve", w.base_curve}, {"curve", w.curve},
                                       {"dropoff_distance", w.dropoff_distance}, {"rotation", w.rotation},
                                       {"scale", w.scale}, {"envelope", w.envelope}, {"members", writeArray(w.members)}});
  }
  for (const Lattice& l : doc.lattices) {
    OrderedJson points = OrderedJson::array();
    for (const Eigen::Vector3d& p : l.points) points.push_back(writeVec(p));
    out["lattices"].push_back(OrderedJson{
        {"name", l.name}, {"origin", writeVec(l.origin)},
        {"axes", OrderedJson::array({writeVec(l.axes.col(0)), writeVec(l.axes.col(1)), writeVec(l.axes.col(2))})},
        {"divisions", OrderedJson::array({l.divisions(0), l.divisions(1), l.divisions(2)})},
        {"points", std::move(points)}, {"drivers", writeDrivers(l.drivers)}, {"members", writeArray(l.members)}});
  }
  for (const PushToSurface& p : doc.push_to_surfaces) {
    OrderedJson surface;
    const CollisionShape& s = p.surface;
    if (s.kind == CollisionShapeKind::kTriangles) {
      surface["triangles"] = OrderedJson::array();
      for (const Eigen::Vector3i& t : s.triangles) surface["triangles"].push_back(OrderedJson::array({t(0), t(1), t(2)}));
    } else if (s.kind == CollisionShapeKind::kSphere) {
      surface["sphere"] = OrderedJson{{"center", writeBinding(s.center)}, {"radius", s.radius}};
    } else {
      surface["ellipsoid"] = OrderedJson{{"center", writeBinding(s.center)}, {"radii", writeVec(s.radii)},
                                         {"rotation_quaternion", writeQuaternion(s.rotation)}};
    }
    OrderedJson direction = p.direction == PushDirection::kClosest  ? OrderedJson("closest")
                            : p.direction == PushDirection::kVector ? writeVec(p.vector)
                                                                     : OrderedJson{{"from", writeBinding(p.from)}};
    OrderedJson j{{"name", p.name}, {"surface", std::move(surface)}, {"direction", std::move(direction)},
                  {"members", writeArray(p.members)}};
    if (!p.carried_by.empty()) j["carried_by"] = p.carried_by;
    if (p.keep_rest_depth) j["keep_rest_depth"] = true;
    out["push_to_surfaces"].push_back(std::move(j));
  }
}

void writeDrives(const ComponentsDocument& doc, OrderedJson& out) {
  for (const Muscle& m : doc.muscles) {
    OrderedJson drives = OrderedJson::array();
    for (const MuscleDrive& d : m.drives) {
      drives.push_back(OrderedJson{{d.kind == TargetKind::kCluster ? "cluster" : "locator", d.name},
                                   {"mode", d.mode == MuscleDriveMode::kAxialScale ? "axial_scale" : "translate"},
                                   {"weight", d.weight}});
    }
    out["muscles"].push_back(OrderedJson{{"name", m.name}, {"origin", writeBinding(m.origin)},
                                         {"insertion", writeBinding(m.insertion)},
                                         {"range", OrderedJson::array({m.min_contraction, m.max_contraction})},
                                         {"drives", std::move(drives)}});
  }
  for (const CreaseCluster& c : doc.crease_clusters) {
    OrderedJson triggers = OrderedJson::array();
    for (const CreaseTrigger& t : c.triggers) triggers.push_back(OrderedJson{{"muscle", t.muscle}, {"weight", t.weight}});
    out["crease_clusters"].push_back(OrderedJson{{"cluster", c.cluster}, {"triggers", std::move(triggers)}});
  }
  for (const Control& c : doc.controls) {
    OrderedJson drives = OrderedJson::array();
    for (const ControlDrive& d : c.drives) {
      OrderedJson j;
      switch (d.kind) {
        case DriveTargetKind::kMuscle: j["muscle"] = d.name; break;
        case DriveTargetKind::kCluster:
          j["cluster"] = d.name;
          j["channel"] = clusterChannelName(d.cluster_channel);
          break;
        case DriveTargetKind::kLocator:
          j["locator"] = d.name;
          j["channel"] = clusterChannelName(d.cluster_channel);
          break;
        case DriveTargetKind::kMorph: j["morph"] = d.name; break;
        case DriveTargetKind::kJoint:
          j["joint"] = d.name;
          j["channel"] = jointChannelName(d.joint_channel);
          break;
      }
      j["gain"] = d.gain;
      drives.push_back(std::move(j));
    }
    out["controls"].push_back(OrderedJson{{"name", c.name}, {"range", OrderedJson::array({c.min, c.max})},
                                          {"default", c.default_value}, {"drives", std::move(drives)}});
  }
  out["presets"] = OrderedJson::object();
  for (const auto& [name, preset] : doc.presets) {
    OrderedJson controls = OrderedJson::object();
    for (const auto& [control, value] : preset.controls) controls[control] = value;
    out["presets"][name] = OrderedJson{{"controls", std::move(controls)}};
  }
}

}  // namespace

Result<ComponentsDocument> parseComponents(std::string_view json_text, const std::string& label) {
  auto parsed = parseJsonText(json_text, label);
  if (!parsed) return parsed.error();
  const Json& doc = *parsed;
  ComponentsDocument out;
  try {
    checkKeys(doc, "document", {"format", "version", "locators", "clusters", "point_constraints", "aim_constraints",
                                "curves", "surfaces", "wires", "lattices", "push_to_surfaces", "muscles",
                                "crease_clusters", "controls", "presets"});
    if (!doc.contains("format") || doc["format"] != kComponentsFormat) {
      fail("format", std::string("must be \"") + kComponentsFormat + "\"");
    }
    out.version = toInt(required(doc, "version", "document"), "version", "version");
    if (out.version != kComponentsVersion) {
      return makeError(ErrorCode::kUnsupported, label + ": version " + std::to_string(out.version) +
                                                    " is not supported (this reader reads " +
                                                    std::to_string(kComponentsVersion) + ")");
    }
    readRigObjects(doc, out);
    readCurvesAndDeformers(doc, out);
    readDrives(doc, out);
  } catch (const FieldError& e) {
    return makeError(ErrorCode::kParse, label + ": " + e.message);
  } catch (const nlohmann::json::exception& e) {  // a type mismatch a check above missed
    return makeError(ErrorCode::kParse, label + ": " + e.what());
  }
  if (auto ok = validateComponents(out, label); !ok) return ok.error();
  return out;
}

Result<ComponentsDocument> readComponents(const std::filesystem::path& path) {
  auto bytes = readFileBytes(path);
  if (!bytes) return bytes.error();
  return parseComponents(std::string(bytes->begin(), bytes->end()), path.filename().string());
}

Result<ComponentsDocument> parseRigComponents(std::string_view json_text, const std::string& label, const Mesh& face) {
  auto doc = parseComponents(json_text, label);
  if (!doc) return doc.error();
  const ComponentsMeshCounts counts{static_cast<long long>(face.vertexCount()),
                                    static_cast<long long>(face.triangleCount())};
  if (auto ok = validateComponents(*doc, label, counts); !ok) return ok.error();
  return doc;
}

Result<ComponentsDocument> readRigComponents(const std::filesystem::path& path, const Mesh& face) {
  auto bytes = readFileBytes(path);
  if (!bytes) return bytes.error();
  return parseRigComponents(std::string(bytes->begin(), bytes->end()), path.filename().string(), face);
}

std::string formatComponents(const ComponentsDocument& doc) {
  OrderedJson out;
  out["format"] = kComponentsFormat;
  out["version"] = doc.version;
  for (const char* key : {"locators", "clusters", "point_constraints", "aim_constraints", "curves", "surfaces", "wires",
                          "lattices", "push_to_surfaces", "muscles", "crease_clusters", "controls"}) {
    out[key] = OrderedJson::array();
  }
  writeRigObjects(doc, out);
  writeCurvesAndDeformers(doc, out);
  writeDrives(doc, out);
  return out.dump(1, ' ', false, nlohmann::json::error_handler_t::replace) + "\n";
}

}  // namespace core
