// The eye rig of paper 001 ("Eyes", Figures 4.35-4.36): gaze by aim
// constraints, the lids around the eye following the gaze, lower-lid
// clusters, and eyelid sculptors (a push-to-surface onto a sphere along
// rays from the eye's centre) so that a lid moved over the eye rides over
// it instead of cutting into it.
// The face mesh has no eyeball: its centre and size are placed from the eye
// landmarks (an eyeball's radius is about 12 mm against an outer-corner
// distance of about 90-100 mm), or taken from an eye joint of the rig.
#include <algorithm>
#include <cmath>
#include <map>
#include <numbers>

#include "core/muscle_rig/muscle_rig_parts.h"

namespace core::muscle_rig_detail {

namespace {

constexpr double kEyeRadius = 0.125;     // iod
constexpr double kCentreBehind = 0.9;    // eye radii from the lid opening's centre back to the eyeball's
constexpr double kAimDistance = 5.0;     // iod in front of the eyes: a conversational gaze target
constexpr double kLidFollow = 0.25;      // share of the gaze turn the lids around the eye follow
constexpr double kUpperLidFollow = 0.45; // of the eye's opening: the upper lid's slide at a full look up or down
constexpr double kJointReach = 0.15;     // iod: an eye joint this close to the placed centre is the eye's
// Lids nearer the placed centre than this (eye radii) mean the centre is
// wrong: no sculptor then.
constexpr double kMinEyeRadius = 0.5;
constexpr double kSculptorShare = 0.97;  // of the lid margins' distance: the lids' thickness off the eyeball
constexpr double kSculptorReach = 1.6;   // of the lid margins' distance: the sculptors' members around the eye
// The cornea, in eyeball radii: a sphere this far in front of the eye's
// centre, of this radius (its apex 1.1 radii out; human and ICT eyes both
// bulge ~10% past the sclera).
constexpr double kCorneaOffset = 0.6;
constexpr double kCorneaRadius = 0.5;

struct EyeGeometry {
  Eigen::Vector3d centre_frame;  // the lid opening's centre, frame coordinates
  double half_width = 0.0;       // frame units
  double upper_rim = 0.0;        // frame y of the upper lid's rim
  double lower_rim = 0.0;        // frame y of the lower lid's rim
  double brow = 0.0;             // frame y of the brow above
};

EyeGeometry eyeGeometry(const FaceFrame& f, int side) {
  const std::string eye = side > 0 ? "eye_left_" : "eye_right_";
  EyeGeometry g;
  g.centre_frame = Eigen::Vector3d::Zero();
  for (int i = 0; i < 6; ++i) g.centre_frame += f.toFrame(f.at(eye + std::to_string(i))) / 6.0;
  g.half_width = 0.5 * std::abs(f.toFrame(f.at(eye + "0")).x() - f.toFrame(f.at(eye + "3")).x());
  g.upper_rim = 0.5 * (f.toFrame(f.at(eye + "1")).y() + f.toFrame(f.at(eye + "2")).y());
  g.lower_rim = 0.5 * (f.toFrame(f.at(eye + "4")).y() + f.toFrame(f.at(eye + "5")).y());
  g.brow = f.toFrame(f.at(side > 0 ? "brow_left_2" : "brow_right_2")).y();
  return g;
}

// Lid vertices around one eye, weighted: full between the rims' heights,
// fading above the upper rim towards the brow and below the lower rim
// towards the cheek; `upper`/`lower` choose which lids.
std::vector<ClusterMember> lidMembers(const FaceRegions& regions, const EyeGeometry& g, bool upper, bool lower) {
  std::vector<ClusterMember> members;
  const Eigen::Vector3d& c = g.centre_frame;
  const double fade_up = std::max(0.7 * (g.brow - g.upper_rim), 1e-6);
  const double fade_down = 0.25;
  for (Eigen::Index v = 0; v < regions.local.rows(); ++v) {
    const double dx = std::abs(regions.local(v, 0) - c.x()) / (1.15 * g.half_width);
    const double y = regions.local(v, 1), z = regions.local(v, 2);
    if (dx >= 1.0 || z < c.z() - 0.25) continue;
    const bool is_upper = y >= c.y();
    if ((is_upper && !upper) || (!is_upper && !lower)) continue;
    double w = smoothStep(1.0 - dx);
    if (is_upper) {
      if (y > g.upper_rim) w *= smoothStep(1.0 - (y - g.upper_rim) / fade_up);
      if (!lower) w *= smoothStep((y - c.y() + 0.02) / 0.04);  // an upper lid alone keeps off the lower lid
    } else {
      if (y < g.lower_rim) w *= smoothStep(1.0 - (g.lower_rim - y) / fade_down);
      if (!upper) w *= smoothStep((c.y() + 0.02 - y) / 0.04);
    }
    if (w > 1e-3) members.push_back({static_cast<int>(v), w});
  }
  return members;
}

// `members` with their weights scaled by `gain`, the negligible dropped.
std::vector<ClusterMember> scaledMembers(const std::vector<ClusterMember>& members, double gain) {
  std::vector<ClusterMember> out;
  for (const ClusterMember& m : members) {
    if (gain * m.weight > 1e-3) out.push_back({m.vertex, gain * m.weight});
  }
  return out;
}

}  // namespace

void addEyes(ComponentsDocument& doc, const Mesh& face, const FaceFrame& f, const FaceRegions& regions,
             const MuscleRigOptions& options) {
  const double radius = kEyeRadius * f.iod;
  Eigen::Vector3d aims_mid = Eigen::Vector3d::Zero();
  std::vector<std::string> aims;
  std::map<int, EyeGeometry> eyes;  // by side
  for (const int s : {+1, -1}) {
    const std::string x = sideSuffix(s);
    const EyeGeometry& g = eyes[s] = eyeGeometry(f, s);
    const std::vector<ClusterMember> lids = lidMembers(regions, g, true, true);
    Eigen::Vector3d centre = f.toModel(g.centre_frame) - kCentreBehind * radius * f.forward;
    const std::string joint = nearestJoint(options, centre, kJointReach * f.iod);
    if (!joint.empty()) centre = options.joints.at(joint).topRightCorner<3, 1>();
    const Eigen::Vector3d aim = centre + kAimDistance * f.iod * f.forward;
    doc.locators.push_back({"eye_centre" + x, Binding::atPosition(centre)});
    doc.locators.push_back({"eye_aim" + x, Binding::atPosition(aim)});
    aims_mid += 0.5 * aim;
    aims.push_back("eye_aim" + x);

    // The lids follow the gaze: a cluster about the eye's centre, turned by
    // the aim, moving the lids by a share of it.
    Cluster gaze;
    gaze.name = "eye_gaze" + x;
    gaze.pivot = Binding::atPosition(centre);
    gaze.members = scaledMembers(lids, kLidFollow);
    const ConstraintTarget target{TargetKind::kLocator, "eye_aim" + x, -1, 1.0};
    if (!gaze.members.empty()) {
      doc.clusters.push_back(gaze);
      doc.aim_constraints.push_back({"eye_gaze_aim" + x, gaze.name, {target}, f.forward, f.up, f.up, false});
    }
    if (!joint.empty()) doc.aim_constraints.push_back({"eye_joint_aim" + x, joint, {target}, f.forward, f.up, f.up, true});

    // Lower lid: rises over the eye (squint, the cheeks of a smile).
    Cluster lower;
    lower.name = "lower_lid" + x;
    lower.pivot = Binding::atPosition(centre);
    lower.members = lidMembers(regions, g, false, true);
    if (!lower.members.empty()) {
      doc.clusters.push_back(lower);
      Control raise{"raise_lower_lid" + x, 0.0, 1.0, 0.0, {}};
      addTranslateDrives(raise, lower.name, 0.35 * (g.upper_rim - g.lower_rim) * f.iod * f.up);
      doc.controls.push_back(raise);
    }

    // Eyelid sculptor: lid vertices pushed inside the eyeball go back out
    // along rays from its centre. The paper's sphere is the cornea's (its
    // lids turn about the eye's centre, so only the cornea's bulge is in
    // the way); here the lids slide, so the sphere is the eyeball the lid
    // margins rest on (their four landmarks' distance from the centre).
    // Its deformation set: the face around the eye (lids and corners), each
    // vertex kept no deeper than it sits at rest (rest = identity; the ICT
    // lids' inner sheet rests inside the eyeball).
    const std::string eye = s > 0 ? "eye_left_" : "eye_right_";
    double margin = 0.0;
    for (const char* k : {"1", "2", "4", "5"}) margin += 0.25 * (f.at(eye + k) - centre).norm();
    const double sphere = kSculptorShare * margin;
    PushToSurface sculptor;
    sculptor.name = "eyelid_sculptor" + x;
    sculptor.surface.kind = CollisionShapeKind::kSphere;
    sculptor.surface.center = Binding::atPosition(centre);
    sculptor.surface.radius = sphere;
    sculptor.direction = PushDirection::kFromPoint;
    sculptor.from = Binding::atPosition(centre);
    sculptor.keep_rest_depth = true;
    for (Eigen::Index v = 0; v < face.positions.rows(); ++v) {  // lids, corners and all around: rest depth kept
      if ((face.positions.row(v).transpose() - centre).norm() < kSculptorReach * margin) sculptor.members.push_back(static_cast<int>(v));
    }
    if (!sculptor.members.empty() && sphere > kMinEyeRadius * radius) doc.push_to_surfaces.push_back(sculptor);

    // Cornea sculptor: the cornea's bulge turns with the eye, under the
    // lids and corners; a sphere on it carried by the gaze cluster (whose
    // transform is the eye's full turn) pushes the lid vertices it reaches
    // back out along rays from its centre. Deformation set: the
    // eyeball sculptor's.
    if (gaze.members.empty() || sphere <= kMinEyeRadius * radius) continue;
    // The eye looks out through its lid opening at rest: the cornea lies on
    // the line from the centre through the opening's centre (the face's
    // forward when the centre was placed from it; a rig's eye joint may sit
    // off that line, and the face's forward may tilt by some degrees).
    const Eigen::Vector3d look = (f.toModel(g.centre_frame) - centre).normalized();
    const Eigen::Vector3d cornea_centre = centre + kCorneaOffset * margin * look;
    PushToSurface cornea;
    cornea.name = "cornea_sculptor" + x;
    cornea.surface.kind = CollisionShapeKind::kSphere;
    cornea.surface.center = Binding::atPosition(cornea_centre);
    cornea.surface.radius = kCorneaRadius * margin;
    cornea.direction = PushDirection::kFromPoint;
    cornea.from = Binding::atPosition(cornea_centre);
    cornea.carried_by = gaze.name;
    cornea.keep_rest_depth = true;
    cornea.members = sculptor.members;
    doc.push_to_surfaces.push_back(cornea);
  }
  // Both aims are children of one gaze locator (the paper's larger control shape).
  doc.locators.push_back({"eyes_aim", Binding::atPosition(aims_mid)});
  for (const std::string& aim : aims) {
    doc.point_constraints.push_back({aim + "_follow", aim, {{TargetKind::kLocator, "eyes_aim", -1, 1.0}}, true});
  }
  const double across = kAimDistance * f.iod * std::tan(30.0 * std::numbers::pi / 180.0);
  const double vertical = kAimDistance * f.iod * std::tan(25.0 * std::numbers::pi / 180.0);
  const std::pair<const char*, Eigen::Vector3d> looks[] = {{"look_left", across * f.right},
                                                           {"look_right", -across * f.right},
                                                           {"look_up", vertical * f.up},
                                                           {"look_down", -vertical * f.up}};
  for (const auto& [name, offset] : looks) {
    Control look{name, 0.0, 1.0, 0.0, {}};
    addTranslateDrives(look, "eyes_aim", offset, DriveTargetKind::kLocator);
    // The upper lid rides on the eye: it follows a vertical gaze most of
    // the way (more than the shared turn of the gaze clusters gives).
    const double vertical_share = offset.dot(f.up) / vertical;
    for (const int s : {+1, -1}) {
      const std::string lid = std::string("upper_lid") + sideSuffix(s);
      const EyeGeometry& g = eyes.at(s);
      if (vertical_share != 0.0 && indexByName(doc.clusters, lid) >= 0) {
        addTranslateDrives(look, lid, kUpperLidFollow * vertical_share * (g.upper_rim - g.lower_rim) * f.iod * f.up);
      }
    }
    doc.controls.push_back(look);
  }
}

}  // namespace core::muscle_rig_detail
