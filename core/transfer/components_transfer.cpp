// transferComponents: see components_transfer.h.

#include "core/transfer/components_transfer.h"

#include <map>
#include <string>
#include <vector>

#include "core/transfer/attributes.h"

namespace core {

namespace {

// Member weights below this after interpolation are no longer members.
constexpr double kMemberWeightFloor = 1e-4;
// A set member (0/1) stays one where at least half its location's corners are.
constexpr double kSetMemberThreshold = 0.5;

// How the document's geometry moves to the target. With a target index,
// bound points are bound again on the target's surface (transfer); without
// one the target is a copy of the source's topology (fit), so bindings by
// vertex and face and lone vertices stay exactly as they are.
class ComponentsMapper {
 public:
  ComponentsMapper(const TpsWarp& dense_map, const Eigen::Matrix3d& rotation, double scale, const Mesh* source_mesh,
                   const Mesh* target_mesh, const ClosestPointIndex* target_index)
      : dense_map_(dense_map), rotation_(rotation), scale_(scale), source_mesh_(source_mesh),
        target_mesh_(target_mesh), target_index_(target_index) {}

  Eigen::Vector3d point(const Eigen::Vector3d& p) const { return dense_map_.apply(p); }
  Eigen::Vector3d direction(const Eigen::Vector3d& d) const { return rotation_ * d; }
  double length(double l) const { return scale_ * l; }
  Eigen::Quaterniond rotation(const Eigen::Quaterniond& q) const {
    const Eigen::Quaterniond r(rotation_);
    return (r * q * r.conjugate()).normalized();
  }
  const Eigen::Matrix3d& rotationMatrix() const { return rotation_; }

  Binding binding(const Binding& b) const {
    if (b.kind == BindingKind::kPosition) return Binding::atPosition(point(b.position));
    if (!target_index_) return b;
    const Eigen::Vector3d at = point(resolveBinding(b, source_mesh_->positions, source_mesh_->triangles));
    const SurfacePoint sp = target_index_->closestPoint(at);
    return sp.found() ? Binding::onFace(sp.face, sp.barycentric) : Binding::atPosition(at);
  }

  // The target vertex nearest where the map puts source vertex v.
  int vertex(int v) const {
    if (!target_index_) return v;
    const Eigen::Vector3d at = point(source_mesh_->positions.row(v).transpose());
    const SurfacePoint sp = target_index_->closestPoint(at);
    if (!sp.found()) return 0;
    int corner = 0;
    sp.barycentric.maxCoeff(&corner);
    return target_mesh_->triangles(sp.face, corner);
  }

 private:
  const TpsWarp& dense_map_;
  Eigen::Matrix3d rotation_;
  double scale_;
  const Mesh* source_mesh_;
  const Mesh* target_mesh_;
  const ClosestPointIndex* target_index_;
};

// Every member set of the document as one column of a single source field
// (#Vs by #sets), carried by one attribute transfer: one interpolation and
// one inpainting solve for all of them, not one per set.
class MemberFields {
 public:
  explicit MemberFields(Eigen::Index source_vertices) : n_(source_vertices) {}

  void add(const std::string& key, const std::vector<std::pair<int, double>>& members) {
    column_[key] = static_cast<Eigen::Index>(members_.size());
    members_.push_back(members);
  }
  void carry(const ComponentsCorrespondence& map) {
    VertexAttributes source;
    Eigen::MatrixXd field = Eigen::MatrixXd::Zero(n_, static_cast<Eigen::Index>(members_.size()));
    for (std::size_t c = 0; c < members_.size(); ++c) {
      for (const auto& [v, w] : members_[c]) field(v, static_cast<Eigen::Index>(c)) = w;
    }
    source.fields["members"] = std::move(field);
    target_ = std::move(transferAttributes(map.source_mesh, source, map.locations, map.target_laplacian, map.mismatched)
                            .fields.at("members"));
  }
  std::vector<ClusterMember> weighted(const std::string& key) const {
    std::vector<ClusterMember> out;
    const Eigen::Index c = column_.at(key);
    for (Eigen::Index v = 0; v < target_.rows(); ++v) {
      if (target_(v, c) > kMemberWeightFloor) out.push_back({static_cast<int>(v), target_(v, c)});
    }
    return out;
  }
  std::vector<int> set(const std::string& key) const {
    std::vector<int> out;
    const Eigen::Index c = column_.at(key);
    for (Eigen::Index v = 0; v < target_.rows(); ++v) {
      if (target_(v, c) >= kSetMemberThreshold) out.push_back(static_cast<int>(v));
    }
    return out;
  }

 private:
  Eigen::Index n_;
  std::vector<std::vector<std::pair<int, double>>> members_;
  std::map<std::string, Eigen::Index> column_;
  Eigen::MatrixXd target_;  // #Vt by #sets
};

std::vector<std::pair<int, double>> asWeighted(const std::vector<int>& set) {
  std::vector<std::pair<int, double>> out;
  for (const int v : set) out.emplace_back(v, 1.0);
  return out;
}

std::vector<std::pair<int, double>> asWeighted(const std::vector<ClusterMember>& members) {
  std::vector<std::pair<int, double>> out;
  for (const ClusterMember& m : members) out.emplace_back(m.vertex, m.weight);
  return out;
}

void mapTargets(std::vector<ConstraintTarget>& targets, const ComponentsMapper& m) {
  for (ConstraintTarget& t : targets) {
    if (t.kind == TargetKind::kVertex) t.vertex = m.vertex(t.vertex);
  }
}

void mapCollision(CollisionShape& s, const ComponentsMapper& m) {
  for (Eigen::Vector3i& t : s.triangles) t = Eigen::Vector3i(m.vertex(t(0)), m.vertex(t(1)), m.vertex(t(2)));
  s.center = m.binding(s.center);
  s.radius = m.length(s.radius);
  s.radii *= m.length(1.0);
  s.rotation = m.rotation(s.rotation);
}

// Everything but member sets: points, bindings, lone vertices, lengths, frames.
void mapGeometry(ComponentsDocument& doc, const ComponentsMapper& m) {
  for (Locator& l : doc.locators) l.binding = m.binding(l.binding);
  for (Cluster& c : doc.clusters) {
    c.pivot = m.binding(c.pivot);
    c.translate = m.length(1.0) * m.direction(c.translate);
    c.rotate = m.rotation(c.rotate);
  }
  for (PointConstraint& p : doc.point_constraints) mapTargets(p.targets, m);
  for (AimConstraint& a : doc.aim_constraints) {
    mapTargets(a.targets, m);
    a.world_up = m.direction(a.world_up);
  }
  for (NurbsCurve& c : doc.curves) {
    for (Binding& b : c.points) b = m.binding(b);
  }
  for (NurbsSurface& s : doc.surfaces) {
    for (Binding& b : s.points) b = m.binding(b);
  }
  for (Wire& w : doc.wires) w.dropoff_distance = m.length(w.dropoff_distance);
  for (Lattice& l : doc.lattices) {
    l.origin = m.point(l.origin);
    l.axes = m.length(1.0) * (m.rotationMatrix() * l.axes);
    for (Eigen::Vector3d& p : l.points) p = m.point(p);
  }
  for (PushToSurface& p : doc.push_to_surfaces) {
    mapCollision(p.surface, m);
    p.vector = m.direction(p.vector);
    p.from = m.binding(p.from);
  }
  for (Muscle& mu : doc.muscles) {
    mu.origin = m.binding(mu.origin);
    mu.insertion = m.binding(mu.insertion);
  }
  // Controls driving a cluster's or locator's translation move it in model units.
  for (Control& c : doc.controls) {
    for (ControlDrive& d : c.drives) {
      const bool moves = d.kind == DriveTargetKind::kCluster || d.kind == DriveTargetKind::kLocator;
      const bool translate = moves && (d.cluster_channel == ClusterChannel::kTranslateX ||
                                                                     d.cluster_channel == ClusterChannel::kTranslateY ||
                                                                     d.cluster_channel == ClusterChannel::kTranslateZ);
      if (translate) d.gain = m.length(d.gain);
    }
  }
}

}  // namespace

ComponentsDocument transferComponents(const ComponentsDocument& source, const ComponentsCorrespondence& map) {
  const ComponentsMapper m(map.dense_map, map.rotation, map.scale, &map.source_mesh, &map.target_mesh,
                           &map.target_index);
  ComponentsDocument out = source;
  // Member sets first: one attribute transfer for all. An empty set means
  // "every vertex" and stays empty.
  MemberFields fields(map.source_mesh.vertexCount());
  for (const Cluster& c : source.clusters) fields.add("cluster:" + c.name, asWeighted(c.members));
  for (const Wire& w : source.wires) {
    if (!w.members.empty()) fields.add("wire:" + w.name, asWeighted(w.members));
  }
  for (const Lattice& l : source.lattices) {
    if (!l.members.empty()) fields.add("lattice:" + l.name, asWeighted(l.members));
  }
  for (const PushToSurface& p : source.push_to_surfaces) {
    if (!p.members.empty()) fields.add("push:" + p.name, asWeighted(p.members));
  }
  fields.carry(map);
  for (Cluster& c : out.clusters) c.members = fields.weighted("cluster:" + c.name);
  for (Wire& w : out.wires) {
    if (!w.members.empty()) w.members = fields.set("wire:" + w.name);
  }
  for (Lattice& l : out.lattices) {
    if (!l.members.empty()) l.members = fields.set("lattice:" + l.name);
  }
  for (PushToSurface& p : out.push_to_surfaces) {
    if (!p.members.empty()) p.members = fields.set("push:" + p.name);
  }
  mapGeometry(out, m);
  return out;
}

ComponentsDocument rebuildComponents(const ComponentsDocument& reference, const TpsWarp& dense_map,
                                     const Eigen::Matrix3d& rotation, double scale) {
  ComponentsDocument out = reference;
  mapGeometry(out, ComponentsMapper(dense_map, rotation, scale, nullptr, nullptr, nullptr));
  return out;
}

void addVertexCopies(ComponentsDocument& doc, const std::vector<int>& copy_of, int first) {
  if (copy_of.empty()) return;
  std::vector<std::vector<int>> copies(static_cast<std::size_t>(first));
  for (std::size_t i = 0; i < copy_of.size(); ++i) {
    copies[static_cast<std::size_t>(copy_of[i])].push_back(first + static_cast<int>(i));
  }
  auto extendSet = [&](std::vector<int>& set) {
    const std::size_t n = set.size();
    for (std::size_t k = 0; k < n; ++k) {
      for (const int c : copies[static_cast<std::size_t>(set[k])]) set.push_back(c);
    }
  };
  for (Cluster& c : doc.clusters) {
    const std::size_t n = c.members.size();
    for (std::size_t k = 0; k < n; ++k) {
      for (const int copy : copies[static_cast<std::size_t>(c.members[k].vertex)]) c.members.push_back({copy, c.members[k].weight});
    }
  }
  for (Wire& w : doc.wires) extendSet(w.members);
  for (Lattice& l : doc.lattices) extendSet(l.members);
  for (PushToSurface& p : doc.push_to_surfaces) extendSet(p.members);
}

}  // namespace core
