// buildMuscleRig: the reference muscle rig of paper 001 (section 4.3.2,
// Table 4.1) on any face with the 68 iBUG landmarks. Muscles pull locators
// at their insertions towards origins set behind the skin (the paper's 0.95
// scaling towards the skull); the locators' motion, weighted per control
// point as the paper's cluster point constraints, moves the CVs of 16 linear
// wires (the paper found linear curves as good as cubic ones, and cheaper).
#include "core/muscle_rig/muscle_rig.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <map>
#include <queue>

#include "core/muscle_rig/muscle_rig_parts.h"

namespace core {

namespace {

using namespace muscle_rig_detail;

// Landmark names of one side of the face, medial to lateral.
struct SideNames {
  std::string eye_inner, eye_outer, lid_upper_inner, lid_upper_outer, lid_lower_outer, lid_lower_inner;
  std::vector<std::string> brow;  // inner to outer
  std::string corner, upper_mid, upper_peak, lower_mid, lower_side, ala;
};

SideNames sideNames(int side) {
  if (side > 0) {
    return {"eye_left_0", "eye_left_3", "eye_left_1", "eye_left_2", "eye_left_4", "eye_left_5",
            {"brow_left_0", "brow_left_1", "brow_left_2", "brow_left_3", "brow_left_4"},
            "mouth_outer_6", "mouth_outer_5", "mouth_outer_4", "mouth_outer_7", "mouth_outer_8", "nose_base_4"};
  }
  return {"eye_right_3", "eye_right_0", "eye_right_2", "eye_right_1", "eye_right_5", "eye_right_4",
          {"brow_right_4", "brow_right_3", "brow_right_2", "brow_right_1", "brow_right_0"},
          "mouth_outer_0", "mouth_outer_1", "mouth_outer_2", "mouth_outer_11", "mouth_outer_10", "nose_base_0"};
}

// A muscle as built: where its locator is and how far it moves the skin.
struct BuiltMuscle {
  double travel = 0.0;  // model units the skin should move at full contraction
  double pull = 0.0;    // model units the locator moves at full contraction (0.5 * length)
};

constexpr double kMaxContraction = 0.5;

class Builder {
 public:
  Builder(const Mesh& face, const FaceFrame& frame, const MuscleRigOptions& options)
      : face_(face), frame_(frame), options_(options) {}

  // A muscle whose insertion is the skin vertex nearest `insertion` and whose
  // origin lies `muscle_depth` behind the skin vertex nearest `origin`;
  // `travel`: skin motion at full contraction, iod.
  void addMuscle(ComponentsDocument& doc, const std::string& name, const Eigen::Vector3d& origin,
                 const Eigen::Vector3d& insertion, double travel) {
    const int insertion_vertex = frame_.nearestVertex(insertion);
    const Eigen::Vector3d skin_origin = face_.positions.row(frame_.nearestVertex(origin)).transpose();
    Muscle muscle;
    muscle.name = name;
    muscle.origin = Binding::atPosition(skin_origin - options_.muscle_depth * frame_.iod * frame_.forward);
    muscle.insertion = Binding::atVertex(insertion_vertex);
    muscle.max_contraction = kMaxContraction;
    muscle.drives.push_back({TargetKind::kLocator, name + "_pull", MuscleDriveMode::kTranslate, 1.0});
    doc.muscles.push_back(muscle);
    doc.locators.push_back({name + "_pull", Binding::atVertex(insertion_vertex)});
    const double length = (face_.positions.row(insertion_vertex).transpose() - resolveBinding(muscle.origin, face_.positions, face_.triangles)).norm();
    built_[name] = {options_.expression_gain * travel * frame_.iod, kMaxContraction * std::max(length, 1e-12)};
  }

  // The driver weight that makes a CV follow `muscle` by `share` of its travel.
  double driverWeight(const std::string& muscle, double share) const {
    const BuiltMuscle& m = built_.at(muscle);
    return share * m.travel / m.pull;
  }

 private:
  const Mesh& face_;
  const FaceFrame& frame_;
  const MuscleRigOptions& options_;
  std::map<std::string, BuiltMuscle> built_;
};

void addMuscles(ComponentsDocument& doc, Builder& b, const FaceFrame& f) {
  for (const int s : {+1, -1}) {
    const SideNames n = sideNames(s);
    const std::string x = sideSuffix(s);
    const Eigen::Vector3d lid_lower = 0.5 * (f.at(n.lid_lower_inner) + f.at(n.lid_lower_outer));
    b.addMuscle(doc, "frontalis_inner" + x, f.offset(n.brow[1], s, 0.0, 0.9), f.offset(n.brow[1], s, 0.0, 0.12), 0.16);
    b.addMuscle(doc, "frontalis_outer" + x, f.offset(n.brow[3], s, 0.0, 0.9), f.offset(n.brow[3], s, 0.0, 0.12), 0.14);
    b.addMuscle(doc, "corrugator" + x, f.offset("nose_bridge_0", s, 0.08, -0.05), f.at(n.brow[2]), 0.08);
    b.addMuscle(doc, "orbicularis_oculi_inner" + x, f.offset(n.eye_inner, s, -0.05, 0.05),
                f.offset(n.eye_inner, s, 0.05, -0.35), 0.05);
    b.addMuscle(doc, "orbicularis_oculi_outer" + x, f.offset(n.eye_outer, s, 0.0, 0.12),
                lid_lower + f.iod * (-0.35 * f.up), 0.07);
    b.addMuscle(doc, "levator_labii_nasal" + x, f.offset("nose_bridge_1", s, 0.15, 0.0),
                f.offset(n.ala, s, 0.06, -0.12), 0.10);
    b.addMuscle(doc, "levator_labii_mid" + x, lid_lower + f.iod * (-0.3 * f.up), f.offset(n.upper_peak, s, 0.0, 0.05), 0.09);
    b.addMuscle(doc, "zygomatic_major" + x, f.offset(n.eye_outer, s, 0.3, -0.5), f.offset(n.corner, s, 0.05, 0.0), 0.17);
    b.addMuscle(doc, "risorius" + x, f.offset(n.corner, s, 0.9, 0.0), f.offset(n.corner, s, 0.03, 0.0), 0.13);
    b.addMuscle(doc, "orbicularis_oris_incisivis" + x, f.offset(n.corner, s, -0.35, 0.0), f.offset(n.corner, s, 0.02, 0.0), 0.10);
    b.addMuscle(doc, "triangularis" + x, f.offset(n.corner, s, 0.25, -0.7), f.offset(n.corner, s, 0.03, -0.03), 0.12);
    b.addMuscle(doc, "depressor_labii" + x, f.offset(n.lower_side, s, 0.1, -0.6), f.offset(n.lower_side, s, 0.0, -0.05), 0.10);
  }
  b.addMuscle(doc, "procerus", f.at("nose_bridge_2"), f.offset("nose_bridge_0", 1, 0.0, 0.15), 0.05);
  // Mentalis: origin and insertion switched (section 4.3.2): the chin pushes the lower lip up.
  b.addMuscle(doc, "mentalis", f.offset("mouth_outer_9", 1, 0.0, -0.05), f.offset("jaw_08", 1, 0.0, 0.35), 0.07);
}

enum class MemberSet { kUpperLip, kLowerLip, kAboveLids, kBelowLids };

struct WireSpec {
  std::string name;
  std::vector<Eigen::Vector3d> points;  // CV positions before snapping to vertices
  double dropoff = 0.3;                 // d0, iod
  MemberSet set = MemberSet::kUpperLip;
  int side = 0;                         // members restricted to this side; 0: both
  std::vector<std::pair<std::string, std::vector<double>>> drivers;  // muscle, share of its travel per CV
};

double distanceToPolyline(const Eigen::Vector3d& p, const std::vector<Eigen::Vector3d>& line) {
  double best = (p - line.front()).norm();
  for (std::size_t i = 1; i < line.size(); ++i) {
    const Eigen::Vector3d d = line[i] - line[i - 1];
    const double t = std::clamp((p - line[i - 1]).dot(d) / std::max(d.squaredNorm(), 1e-30), 0.0, 1.0);
    best = std::min(best, (p - (line[i - 1] + t * d)).norm());
  }
  return best;
}

// Base and deforming linear curves over the snapped CVs, the wire, its
// deformation set (members) and the CV drivers.
void addWire(ComponentsDocument& doc, const WireSpec& spec, const Mesh& face, const FaceFrame& f,
             const FaceRegions& regions, const Builder& b, const MuscleRigOptions& options) {
  NurbsCurve base;
  base.name = spec.name + "_base";
  base.degree = 1;
  const int n = static_cast<int>(spec.points.size());
  base.knots.push_back(0.0);
  for (int i = 0; i < n; ++i) base.knots.push_back(static_cast<double>(i));
  base.knots.push_back(static_cast<double>(n - 1));
  std::vector<Eigen::Vector3d> snapped;
  for (const Eigen::Vector3d& p : spec.points) {
    const int v = f.nearestVertex(p);
    base.points.push_back(Binding::atVertex(v));
    snapped.push_back(face.positions.row(v).transpose());
  }
  NurbsCurve deformed = base;
  deformed.name = spec.name + "_curve";
  for (const auto& [muscle, shares] : spec.drivers) {
    for (int i = 0; i < n; ++i) {
      if (shares[static_cast<std::size_t>(i)] == 0.0) continue;
      deformed.drivers.push_back({i, TargetKind::kLocator, muscle + "_pull", b.driverWeight(muscle, shares[static_cast<std::size_t>(i)])});
    }
  }
  Wire wire;
  wire.name = spec.name;
  wire.base_curve = base.name;
  wire.curve = deformed.name;
  wire.dropoff_distance = spec.dropoff * options.wire_dropoff * f.iod;
  wire.rotation = 0.0;  // linear wires: a turn at a CV would twist the lips
  for (Eigen::Index v = 0; v < face.positions.rows(); ++v) {
    const double x = regions.local(v, 0), y = regions.local(v, 1);
    if (spec.side != 0 && !onSide(x, spec.side)) continue;
    bool in_set = false;
    switch (spec.set) {
      case MemberSet::kUpperLip: in_set = regions.upperLip(v); break;
      case MemberSet::kLowerLip: in_set = !regions.upperLip(v); break;
      case MemberSet::kAboveLids: in_set = y > regions.lids_top; break;
      case MemberSet::kBelowLids: in_set = y < regions.lids_bottom && regions.upperLip(v); break;
    }
    if (in_set && distanceToPolyline(face.positions.row(v).transpose(), snapped) < wire.dropoff_distance) {
      wire.members.push_back(static_cast<int>(v));
    }
  }
  if (wire.members.empty()) wire.members.push_back(base.points.front().vertex);  // empty would mean "all"
  doc.curves.push_back(std::move(base));
  doc.curves.push_back(std::move(deformed));
  doc.wires.push_back(std::move(wire));
}

// The 16 wires of Table 4.1 with the muscles each connects to.
std::vector<WireSpec> wireSpecs(const FaceFrame& f) {
  std::vector<WireSpec> specs;
  for (const int s : {+1, -1}) {
    const SideNames n = sideNames(s);
    const std::string x = sideSuffix(s);
    std::vector<Eigen::Vector3d> brow;
    for (const std::string& name : n.brow) brow.push_back(f.at(name));
    const Eigen::Vector3d lid_lower = 0.5 * (f.at(n.lid_lower_inner) + f.at(n.lid_lower_outer));
    specs.push_back({"eyebrow" + x, brow, 0.3, MemberSet::kAboveLids, s,
                     {{"frontalis_inner" + x, {1.0, 0.8, 0.5, 0.25, 0.1}},
                      {"frontalis_outer" + x, {0.1, 0.3, 0.6, 0.9, 1.0}},
                      {"procerus", {0.9, 0.4, 0.1, 0.0, 0.0}},
                      // Light at the inner end: the two sides pull towards each
                      // other there, and the glabella between them must not fold.
                      {"corrugator" + x, {0.35, 0.8, 0.6, 0.2, 0.0}}}});
    specs.push_back({"forehead" + x,
                     {f.offset(n.brow[0], s, 0.0, 0.45), f.offset(n.brow[2], s, 0.0, 0.5), f.offset(n.brow[4], s, 0.0, 0.45)},
                     0.45, MemberSet::kAboveLids, s,
                     {{"frontalis_inner" + x, {0.6, 0.35, 0.1}},
                      {"frontalis_outer" + x, {0.1, 0.35, 0.6}},
                      {"procerus", {0.3, 0.05, 0.0}},
                      {"corrugator" + x, {0.1, 0.15, 0.0}}}});
    specs.push_back({"nose" + x, {f.offset(n.eye_inner, s, -0.05, -0.3), f.offset(n.eye_inner, s, 0.1, -0.45)}, 0.3,
                     MemberSet::kBelowLids, s, {{"orbicularis_oculi_inner" + x, {1.0, 0.7}}}});
    specs.push_back({"cheek" + x,
                     {f.offset(n.eye_inner, s, 0.05, -0.3), lid_lower - 0.35 * f.iod * f.up, f.offset(n.eye_outer, s, 0.1, -0.3)},
                     0.4, MemberSet::kBelowLids, s, {{"orbicularis_oculi_outer" + x, {0.5, 1.0, 0.8}}}});
    specs.push_back({"nasolabial" + x,
                     {f.offset(n.ala, s, 0.12, -0.02), 0.5 * (f.offset(n.ala, s, 0.15, 0.0) + f.offset(n.corner, s, 0.15, 0.05)),
                      f.offset(n.corner, s, 0.18, 0.05)},
                     0.3, MemberSet::kUpperLip, s,
                     {{"levator_labii_nasal" + x, {1.0, 0.5, 0.1}}, {"levator_labii_mid" + x, {0.6, 0.8, 0.4}}}});
    // The peak CV is shared with the centre wire and the lower side CV with
    // the lower centre wire: both wires move the vertices there, so each takes half.
    specs.push_back({"mouth_upper_corner" + x, {f.at(n.corner), f.at(n.upper_mid), f.at(n.upper_peak)}, 0.35,
                     MemberSet::kUpperLip, 0,
                     {{"levator_labii_nasal" + x, {0.1, 0.3, 0.3}}, {"levator_labii_mid" + x, {0.2, 0.5, 0.4}},
                      {"zygomatic_major" + x, {1.0, 0.6, 0.15}}, {"risorius" + x, {1.0, 0.6, 0.1}},
                      {"triangularis" + x, {1.0, 0.5, 0.08}}, {"orbicularis_oris_incisivis" + x, {1.0, 0.7, 0.2}}}});
    specs.push_back({"mouth_lower_corner" + x, {f.at(n.corner), f.at(n.lower_mid), f.at(n.lower_side)}, 0.35,
                     MemberSet::kLowerLip, 0,
                     {{"zygomatic_major" + x, {1.0, 0.5, 0.1}}, {"risorius" + x, {1.0, 0.6, 0.12}},
                      {"triangularis" + x, {1.0, 0.7, 0.18}}, {"depressor_labii" + x, {0.2, 0.6, 0.5}},
                      {"mentalis", {0.1, 0.4, 0.35}}, {"orbicularis_oris_incisivis" + x, {1.0, 0.7, 0.2}}}});
  }
  auto both = [](const std::string& muscle, double own_right, double centre, double own_left) {
    return std::vector<std::pair<std::string, std::vector<double>>>{{muscle + "_R", {own_right, centre, 0.0}},
                                                                    {muscle + "_L", {0.0, centre, own_left}}};
  };
  WireSpec upper{"mouth_upper_center", {f.at("mouth_outer_2"), f.at("mouth_outer_3"), f.at("mouth_outer_4")}, 0.3,
                 MemberSet::kUpperLip, 0, {}};
  WireSpec lower{"mouth_lower_center", {f.at("mouth_outer_10"), f.at("mouth_outer_9"), f.at("mouth_outer_8")}, 0.3,
                 MemberSet::kLowerLip, 0, {}};
  for (auto [muscle, peak, centre] : std::vector<std::tuple<std::string, double, double>>{
           {"levator_labii_nasal", 0.45, 0.4}, {"levator_labii_mid", 0.4, 0.4}, {"zygomatic_major", 0.12, 0.05},
           {"orbicularis_oris_incisivis", 0.2, 0.15}}) {
    for (auto& d : both(muscle, peak, centre / 2.0, peak)) upper.drivers.push_back(d);
  }
  for (auto [muscle, side, centre] : std::vector<std::tuple<std::string, double, double>>{
           {"zygomatic_major", 0.08, 0.0}, {"risorius", 0.1, 0.0}, {"triangularis", 0.15, 0.1},
           {"depressor_labii", 0.5, 0.6}, {"orbicularis_oris_incisivis", 0.2, 0.15}}) {
    for (auto& d : both(muscle, side, centre / 2.0, side)) lower.drivers.push_back(d);
  }
  lower.drivers.push_back({"mentalis", {0.4, 1.0, 0.4}});
  specs.push_back(upper);
  specs.push_back(lower);
  return specs;
}

// Near the mouth, each vertex takes the lip of its nearest lip landmark
// along the mesh's edges (multi-source Dijkstra): the two lips meet only at
// the corners, so their inner sheets keep their own side.
void labelLipsAlongSurface(const Mesh& face, const FaceFrame& frame, FaceRegions& r) {
  const auto n = static_cast<std::size_t>(face.positions.rows());
  std::vector<std::vector<std::pair<int, double>>> edges(n);
  for (Eigen::Index t = 0; t < face.triangles.rows(); ++t) {
    for (int k = 0; k < 3; ++k) {
      const int a = face.triangles(t, k), b = face.triangles(t, (k + 1) % 3);
      const double length = (face.positions.row(a) - face.positions.row(b)).norm();
      edges[static_cast<std::size_t>(a)].push_back({b, length});
      edges[static_cast<std::size_t>(b)].push_back({a, length});
    }
  }
  const double corner_x = std::max(std::abs(frame.toFrame(frame.at("mouth_outer_0")).x()),
                                   std::abs(frame.toFrame(frame.at("mouth_outer_6")).x()));
  const double mouth_y = r.mouth.heightAt(0.0);
  auto near_mouth = [&](std::size_t v) {
    return std::abs(r.local(static_cast<Eigen::Index>(v), 0)) < corner_x + 0.15 &&
           std::abs(r.local(static_cast<Eigen::Index>(v), 1) - mouth_y) < 0.3;
  };
  std::vector<double> distance(n, std::numeric_limits<double>::infinity());
  std::vector<char> label(n, 0);
  using Item = std::pair<double, int>;
  std::priority_queue<Item, std::vector<Item>, std::greater<>> queue;
  auto seed = [&](const char* name, char upper) {
    const int v = frame.nearestVertex(frame.at(name));
    distance[static_cast<std::size_t>(v)] = 0.0;
    label[static_cast<std::size_t>(v)] = upper;
    queue.push({0.0, v});
  };
  for (const char* name : {"mouth_outer_1", "mouth_outer_2", "mouth_outer_3", "mouth_outer_4", "mouth_outer_5",
                           "mouth_inner_1", "mouth_inner_2", "mouth_inner_3"}) seed(name, 1);
  for (const char* name : {"mouth_outer_7", "mouth_outer_8", "mouth_outer_9", "mouth_outer_10", "mouth_outer_11",
                           "mouth_inner_5", "mouth_inner_6", "mouth_inner_7"}) seed(name, 0);
  while (!queue.empty()) {
    const auto [d, v] = queue.top();
    queue.pop();
    if (d > distance[static_cast<std::size_t>(v)]) continue;
    for (const auto& [w, length] : edges[static_cast<std::size_t>(v)]) {
      const auto wi = static_cast<std::size_t>(w);
      if (!near_mouth(wi) || d + length >= distance[wi]) continue;
      distance[wi] = d + length;
      label[wi] = label[static_cast<std::size_t>(v)];
      queue.push({d + length, w});
    }
  }
  for (std::size_t v = 0; v < n; ++v) {
    if (std::isfinite(distance[v])) r.upper[v] = label[v];
  }
}

}  // namespace

namespace muscle_rig_detail {

FaceRegions buildFaceRegions(const Mesh& face, const FaceFrame& frame) {
  FaceRegions r;
  r.local.resize(face.positions.rows(), 3);
  for (Eigen::Index v = 0; v < face.positions.rows(); ++v) r.local.row(v) = frame.toFrame(face.positions.row(v).transpose()).transpose();
  r.mouth = buildMouthLine(frame);
  r.upper.resize(static_cast<std::size_t>(face.positions.rows()));
  for (Eigen::Index v = 0; v < face.positions.rows(); ++v) r.upper[static_cast<std::size_t>(v)] = r.local(v, 1) > r.mouth.heightAt(r.local(v, 0));
  labelLipsAlongSurface(face, frame, r);
  double top = -1e30, bottom = 1e30;
  for (const char* name : {"eye_left_1", "eye_left_2", "eye_right_1", "eye_right_2"}) top = std::max(top, frame.toFrame(frame.at(name)).y());
  for (const char* name : {"eye_left_4", "eye_left_5", "eye_right_4", "eye_right_5"}) bottom = std::min(bottom, frame.toFrame(frame.at(name)).y());
  r.lids_top = top + 0.08;
  r.lids_bottom = bottom - 0.06;
  return r;
}

}  // namespace muscle_rig_detail

Result<MuscleRig> buildMuscleRig(const Mesh& face, const LandmarkSet& landmarks, const MuscleRigOptions& options) {
  if (face.positions.rows() == 0 || face.triangles.rows() == 0) {
    return makeError(ErrorCode::kInvalidMesh, options.label + ": the face has no triangles");
  }
  auto frame = buildFaceFrame(face, landmarks, options.label);
  if (!frame) return frame.error();
  const FaceRegions regions = buildFaceRegions(face, *frame);
  MuscleRig rig;
  ComponentsDocument& doc = rig.components;
  Builder builder(face, *frame, options);
  addMuscles(doc, builder, *frame);
  for (const WireSpec& spec : wireSpecs(*frame)) addWire(doc, spec, face, *frame, regions, builder, options);
  addJawAndLids(doc, face, *frame, regions, options);
  addEyes(doc, face, *frame, regions, options);
  addCreasesAndSkull(doc, face, *frame, regions);
  addExpressionControls(doc);
  addExpressionPresets(doc);
  rig.muscle_names = namesOf(doc.muscles);
  ComponentsMeshCounts counts{face.positions.rows(), face.triangles.rows()};
  if (auto ok = validateComponents(doc, options.label + " muscle rig", counts); !ok) return ok.error();
  return rig;
}

}  // namespace core
