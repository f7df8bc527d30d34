// The rig's last deformation stages (paper 001, Figure 4.21): the jaw and the
// eyelids ("bone movements", here clusters so any mesh takes them without a
// skeleton), skin creases triggered by muscles, and the skull the forehead
// skin is pushed out of (section 4.3.2; a sphere fitted under the forehead
// stands for the paper's lofted NURBS skull).
#include <algorithm>
#include <cmath>

#include "core/muscle_rig/muscle_rig_parts.h"

namespace core::muscle_rig_detail {

namespace {

// The model axis closest to `direction` and the sign that matches it: cluster
// rotation channels turn about model axes.
std::pair<ClusterChannel, double> rotationChannelAbout(const Eigen::Vector3d& direction) {
  Eigen::Index axis = 0;
  direction.cwiseAbs().maxCoeff(&axis);
  const ClusterChannel channels[] = {ClusterChannel::kRotateX, ClusterChannel::kRotateY, ClusterChannel::kRotateZ};
  return {channels[axis], direction(axis) >= 0.0 ? 1.0 : -1.0};
}

}  // namespace

std::string nearestJoint(const MuscleRigOptions& options, const Eigen::Vector3d& point, double reach) {
  std::string best;
  double best_distance = reach;
  for (const auto& [name, transform] : options.joints) {
    const double d = (transform.topRightCorner<3, 1>() - point).norm();
    if (d < best_distance) {
      best_distance = d;
      best = name;
    }
  }
  return best;
}

void addTranslateDrives(Control& control, const std::string& cluster, const Eigen::Vector3d& offset, DriveTargetKind kind) {
  const ClusterChannel channels[] = {ClusterChannel::kTranslateX, ClusterChannel::kTranslateY, ClusterChannel::kTranslateZ};
  for (int k = 0; k < 3; ++k) {
    if (offset(k) != 0.0) control.drives.push_back({kind, cluster, channels[k], JointChannel::kRotateX, offset(k)});
  }
}

void addJawAndLids(ComponentsDocument& doc, const Mesh& face, const FaceFrame& f, const FaceRegions& regions,
                   const MuscleRigOptions& options) {
  // Jaw: the lower face turns about the hinge axis between the ears
  // (jaw_00/jaw_16, the outline's top), full weight below the mouth line and
  // between the jaw angles, fading towards the ears and down the neck.
  Cluster jaw;
  jaw.name = "jaw";
  // The hinge (temporomandibular joint) sits a little below and behind the
  // outline's top; the rig's jaw joint, when it has one there, is the hinge,
  // and the cluster carries it, so the lower teeth and gums skinned to it
  // open with the face (the face follows the cluster, not the joint).
  Eigen::Vector3d hinge = 0.5 * (f.at("jaw_00") + f.at("jaw_16")) - 0.17 * f.iod * (f.up + f.forward);
  const std::string jaw_joint = nearestJoint(options, hinge, 0.25 * f.iod);
  if (!jaw_joint.empty()) hinge = options.joints.at(jaw_joint).topRightCorner<3, 1>();
  jaw.joint = jaw_joint;
  jaw.pivot = Binding::atPosition(hinge);
  const double corner_x = std::max(std::abs(f.toFrame(f.at("mouth_outer_0")).x()), std::abs(f.toFrame(f.at("mouth_outer_6")).x()));
  const double chin_y = f.toFrame(f.at("jaw_08")).y();
  const auto skinned = options.joint_weights.find(jaw_joint);
  const bool use_skin = !jaw_joint.empty() && skinned != options.joint_weights.end() &&
                        skinned->second.size() == face.positions.rows() && skinned->second.maxCoeff() > 0.5;
  for (Eigen::Index v = 0; use_skin && v < face.positions.rows(); ++v) {
    if (skinned->second(v) > 1e-3) jaw.members.push_back({static_cast<int>(v), skinned->second(v)});
  }
  for (Eigen::Index v = 0; !use_skin && v < face.positions.rows(); ++v) {
    if (regions.upperLip(v)) continue;
    const double x = std::abs(regions.local(v, 0)), y = regions.local(v, 1), z = regions.local(v, 2);
    const double below = regions.mouth.heightAt(regions.local(v, 0)) - y;
    double w = smoothStep(1.0 - (x - corner_x - 0.1) / 0.6) * smoothStep(below / 0.08 + 0.5);
    if (y < chin_y) w *= smoothStep(1.0 - (chin_y - y) / 0.5);
    if (z < -1.0) w = 0.0;
    if (w > 1e-3) jaw.members.push_back({static_cast<int>(v), w});
  }
  doc.clusters.push_back(jaw);
  const auto [jaw_channel, jaw_sign] = rotationChannelAbout(f.right);
  Control jaw_open{"jaw_open", 0.0, 1.0, 0.0, {}};
  jaw_open.drives.push_back({DriveTargetKind::kCluster, "jaw", jaw_channel, JointChannel::kRotateX, jaw_sign * options.jaw_open_degrees});
  doc.controls.push_back(jaw_open);
  // Jaw sideways and jutting (Table 6.1: "jaw rotations and jutting").
  for (const int s : {+1, -1}) {
    Control sideways{std::string("jaw") + (s > 0 ? "_left" : "_right"), 0.0, 1.0, 0.0, {}};
    addTranslateDrives(sideways, "jaw", 0.08 * s * f.iod * f.right);
    doc.controls.push_back(sideways);
  }
  Control jut{"jaw_forward", 0.0, 1.0, 0.0, {}};
  addTranslateDrives(jut, "jaw", 0.06 * f.iod * f.forward);
  doc.controls.push_back(jut);

  // Upper eyelids: the lid skin between the lid rim and the brow slides
  // down over the eye by the eye's opening (the paper's levator palpebrae
  // joints), full at the rim and fading up to the brow.
  for (const int s : {+1, -1}) {
    const std::string eye = s > 0 ? "eye_left_" : "eye_right_";
    Eigen::Vector3d centre = Eigen::Vector3d::Zero();
    for (int i = 0; i < 6; ++i) centre += f.toFrame(f.at(eye + std::to_string(i))) / 6.0;
    const double half_width = 0.5 * std::abs(f.toFrame(f.at(eye + "0")).x() - f.toFrame(f.at(eye + "3")).x());
    const double rim = 0.5 * (f.toFrame(f.at(eye + "1")).y() + f.toFrame(f.at(eye + "2")).y());
    const double opening = rim - 0.5 * (f.toFrame(f.at(eye + "4")).y() + f.toFrame(f.at(eye + "5")).y());
    const std::string brow = s > 0 ? "brow_left_2" : "brow_right_2";
    const double brow_y = f.toFrame(f.at(brow)).y();
    Cluster lid;
    lid.name = std::string("upper_lid") + sideSuffix(s);
    lid.pivot = Binding::atPosition(f.toModel(centre));
    for (Eigen::Index v = 0; v < face.positions.rows(); ++v) {
      const double dx = std::abs(regions.local(v, 0) - centre.x()) / (1.15 * half_width);
      const double y = regions.local(v, 1), z = regions.local(v, 2);
      if (dx >= 1.0 || y < centre.y() - 0.02 || z < centre.z() - 0.25) continue;
      const double up = y > rim ? smoothStep(1.0 - (y - rim) / std::max(0.7 * (brow_y - rim), 1e-6)) : 1.0;
      const double w = up * smoothStep(1.0 - dx) * smoothStep((y - centre.y() + 0.02) / 0.04);
      if (w > 1e-3) lid.members.push_back({static_cast<int>(v), w});
    }
    if (lid.members.empty()) continue;
    doc.clusters.push_back(lid);
    Control blink{std::string("blink") + sideSuffix(s), 0.0, 1.0, 0.0, {}};
    addTranslateDrives(blink, lid.name, -0.9 * opening * f.iod * f.up);
    doc.controls.push_back(blink);
    // The other way: the upper lid raised off the eye (surprise, fear).
    Control widen{std::string("widen_eye") + sideSuffix(s), 0.0, 1.0, 0.0, {}};
    addTranslateDrives(widen, lid.name, 0.3 * opening * f.iod * f.up);
    doc.controls.push_back(widen);
  }
}

void addCreasesAndSkull(ComponentsDocument& doc, const Mesh& face, const FaceFrame& f, const FaceRegions& regions) {
  // Forehead furrows (frontalis) and the glabella's vertical lines
  // (corrugators): thin bands sunk into the skin, by muscle activation.
  const double brow_y = 0.5 * (f.toFrame(f.at("brow_left_2")).y() + f.toFrame(f.at("brow_right_2")).y());
  auto band = [&](const std::string& name, auto weight_of, const Eigen::Vector3d& translate,
                  std::vector<CreaseTrigger> triggers) {
    Cluster c;
    c.name = name;
    c.pivot = Binding::atPosition(f.origin);
    for (Eigen::Index v = 0; v < face.positions.rows(); ++v) {
      const double w = weight_of(regions.local(v, 0), regions.local(v, 1), regions.local(v, 2));
      if (w > 1e-3) c.members.push_back({static_cast<int>(v), w});
    }
    if (c.members.empty()) return;
    c.translate = translate;
    doc.clusters.push_back(c);
    doc.crease_clusters.push_back({name, std::move(triggers)});
  };
  for (const int s : {+1, -1}) {
    const std::string x = sideSuffix(s);
    for (const double row : {0.35, 0.55}) {
      band("forehead_crease_" + std::to_string(static_cast<int>(row * 100)) + x,
           [&](double px, double py, double pz) {
             if (!onSide(px, s) || pz < -0.6) return 0.0;
             const double t = (py - brow_y - row) / 0.04;
             return std::exp(-t * t) * smoothStep(1.0 - (s * px - 0.1) / 0.6);
           },
           -0.006 * f.iod * f.forward, {{"frontalis_inner" + x, 1.2}, {"frontalis_outer" + x, 1.2}});
    }
  }
  band("glabella_crease",
       [&](double px, double py, double pz) {
         if (pz < -0.6 || py < brow_y - 0.15 || py > brow_y + 0.3) return 0.0;
         const double t = (std::abs(px) - 0.08) / 0.06;
         return std::exp(-t * t);
       },
       -0.005 * f.iod * f.forward, {{"corrugator_L", 1.0}, {"corrugator_R", 1.0}, {"procerus", 0.5}});

  // Skull: a sphere under the forehead, as large as the forehead's curvature
  // allows, shrunk until no forehead vertex is inside at rest.
  const Eigen::Vector3d brow_centre = 0.5 * (f.at("brow_left_0") + f.at("brow_right_4"));
  const Eigen::Vector3d centre = brow_centre + f.iod * (0.3 * f.up - 1.1 * f.forward);
  PushToSurface skull;
  skull.name = "skull";
  skull.surface.kind = CollisionShapeKind::kSphere;
  skull.surface.center = Binding::atPosition(centre);
  double radius = 1e30;
  for (Eigen::Index v = 0; v < face.positions.rows(); ++v) {
    const double y = regions.local(v, 1);
    if (y < regions.lids_top || std::abs(regions.local(v, 0)) > 0.9 || regions.local(v, 2) < f.toFrame(centre).z()) continue;
    skull.members.push_back(static_cast<int>(v));
    radius = std::min(radius, (face.positions.row(v).transpose() - centre).norm());
  }
  if (skull.members.empty()) return;
  skull.surface.radius = 0.97 * radius;  // below the skin at rest: rest = identity
  doc.push_to_surfaces.push_back(skull);
}

}  // namespace core::muscle_rig_detail
