// The reference muscle rig (core/muscle_rig) on generated heads: it builds
// and validates with the paper's counts, rest is the identity, every preset
// moves the face the way its expression should (measured in the face's own
// frame), the upper-lip wires leave the lower lip alone, the rig scales with
// the face, and a missing landmark is named.
#include <algorithm>
#include <cmath>
#include <set>

#include <gtest/gtest.h>

#include "core/components/pose.h"
#include "core/muscle_rig/muscle_rig.h"
#include "core/synthetic/synthetic_head.h"
#include "tests/core/muscle_rig/muscle_rig_fixture.h"

namespace rigport_test {
namespace {

core::SyntheticHead headWithParting() {
  core::HeadShape shape;
  shape.mouth_open = 0.012;  // lips as two sheets, as scanned faces have them
  return core::generateHead(shape);
}

TEST(MuscleRig, BuildsThePapersMusclesWiresControlsAndPresets) {
  const auto head = headWithParting();
  auto rig = core::buildMuscleRig(head.mesh, head.landmarks);
  ASSERT_TRUE(rig.ok()) << rig.error().message;
  const core::ComponentsDocument& doc = rig->components;
  EXPECT_EQ(doc.muscles.size(), 26u);  // 12 per side, procerus, mentalis
  EXPECT_EQ(doc.wires.size(), 16u);    // Table 4.1
  EXPECT_EQ(doc.presets.size(), 15u);  // section 6.2.3
  for (const char* name : {"joy", "sadness", "anger", "fear", "surprise", "disgust"}) EXPECT_TRUE(doc.presets.count(name)) << name;
  EXPECT_FALSE(doc.crease_clusters.empty());
  EXPECT_EQ(doc.push_to_surfaces.size(), 5u);  // the skull, two eyelid and two cornea sculptors
  EXPECT_GE(doc.controls.size(), 26u + 3u);  // a descriptive control per muscle, jaw, two blinks
  EXPECT_TRUE(core::validateComponents(doc, "rig", {head.mesh.positions.rows(), head.mesh.triangles.rows()}).ok());
}

TEST(MuscleRig, RestPoseMovesNothing) {
  const auto head = headWithParting();
  auto rig = core::buildMuscleRig(head.mesh, head.landmarks);
  ASSERT_TRUE(rig.ok()) << rig.error().message;
  auto pose = core::evaluatePose(head.mesh.positions, head.mesh.triangles, rig->components, {});
  ASSERT_TRUE(pose.ok()) << pose.error().message;
  EXPECT_LT((pose->positions - head.mesh.positions).cwiseAbs().maxCoeff(), 1e-12);
}

TEST(MuscleRig, EveryPresetMovesTheFace) {
  const auto head = headWithParting();
  auto rig = core::buildMuscleRig(head.mesh, head.landmarks);
  ASSERT_TRUE(rig.ok()) << rig.error().message;
  auto frame = core::buildFaceFrame(head.mesh, head.landmarks, "head");
  ASSERT_TRUE(frame.ok());
  for (const auto& [name, preset] : rig->components.presets) {
    auto pose = core::evaluatePose(head.mesh.positions, head.mesh.triangles, rig->components, preset.controls);
    ASSERT_TRUE(pose.ok()) << name << ": " << pose.error().message;
    EXPECT_TRUE(pose->clamped_controls.empty()) << name;
    const double largest = (pose->positions - head.mesh.positions).rowwise().norm().maxCoeff() / frame->iod;
    EXPECT_GT(largest, 0.03) << name << " barely moves the face";
    EXPECT_LT(largest, 0.6) << name << " tears the face";
  }
}

TEST(MuscleRig, ExpressionsMoveTheFaceTheWayTheyShould) {
  const auto head = headWithParting();
  auto rig = core::buildMuscleRig(head.mesh, head.landmarks);
  ASSERT_TRUE(rig.ok()) << rig.error().message;
  expectExpressionDirections(head.mesh, head.landmarks, *rig);
}

TEST(MuscleRig, UpperLipWiresLeaveTheLowerLipAlone) {
  const auto head = headWithParting();
  auto rig = core::buildMuscleRig(head.mesh, head.landmarks);
  ASSERT_TRUE(rig.ok()) << rig.error().message;
  // The deformation sets: no lower-lip landmark vertex in an upper-lip wire.
  auto positions = core::resolveLandmarks(head.landmarks, head.mesh, "head");
  ASSERT_TRUE(positions.ok());
  const std::vector<int> vertices = core::landmarkVertices(head.landmarks, head.mesh, *positions);
  std::set<int> lower_lip;
  for (const char* name : {"mouth_outer_7", "mouth_outer_8", "mouth_outer_9", "mouth_outer_10", "mouth_outer_11",
                           "mouth_inner_5", "mouth_inner_6", "mouth_inner_7"}) {
    lower_lip.insert(vertices[static_cast<std::size_t>(head.landmarks.indexOf(name))]);
  }
  for (const core::Wire& wire : rig->components.wires) {
    if (wire.name.rfind("mouth_upper", 0) != 0) continue;
    for (const int v : wire.members) EXPECT_FALSE(lower_lip.count(v)) << wire.name << " moves lower-lip vertex " << v;
  }
  // And in motion: raising the upper lip (sneer) leaves the lower lip's centre where it was.
  const auto motion = landmarkMotion(head.mesh, head.landmarks, *rig, {{"sneer_L", 1.0}, {"sneer_R", 1.0}});
  EXPECT_GT(motion.at("mouth_outer_3").y(), 0.02);
  EXPECT_LT(motion.at("mouth_outer_9").norm(), 0.1 * motion.at("mouth_outer_3").norm());
  EXPECT_LT(motion.at("mouth_inner_6").norm(), 0.1 * motion.at("mouth_outer_3").norm());
}

TEST(MuscleRig, TheEyesLookTheLidsFollowAndTheLowerLidsRise) {
  const auto head = headWithParting();
  auto rig = core::buildMuscleRig(head.mesh, head.landmarks);
  ASSERT_TRUE(rig.ok()) << rig.error().message;
  const core::ComponentsDocument& doc = rig->components;
  for (const char* name : {"eye_centre_L", "eye_centre_R", "eye_aim_L", "eye_aim_R", "eyes_aim"}) {
    EXPECT_GE(core::indexByName(doc.locators, name), 0) << name;
  }
  // Gaze left (the subject's): both eyes' lid rims move left (+x in the
  // face's frame), by a share of the eye's turn, and nothing else of note.
  const auto left = landmarkMotion(head.mesh, head.landmarks, *rig, {{"look_left", 1.0}});
  for (const char* name : {"eye_left_1", "eye_left_4", "eye_right_1", "eye_right_4"}) {
    EXPECT_GT(left.at(name).x(), 0.002) << name;
    EXPECT_LT(left.at(name).norm(), 0.1) << name;
  }
  EXPECT_LT(left.at("mouth_outer_3").norm(), 1e-12);
  const auto up = landmarkMotion(head.mesh, head.landmarks, *rig, {{"look_up", 1.0}});
  EXPECT_GT(up.at("eye_left_1").y(), 0.002);
  // The lower lid rises alone: its side, its lid.
  const auto raise = landmarkMotion(head.mesh, head.landmarks, *rig, {{"raise_lower_lid_L", 1.0}});
  EXPECT_GT(raise.at("eye_left_4").y(), 0.005);
  EXPECT_LT(raise.at("eye_left_1").norm(), 1e-3 * raise.at("eye_left_4").norm() + 1e-12);
  EXPECT_LT(raise.at("eye_right_4").norm(), 1e-12);
  const auto widen = landmarkMotion(head.mesh, head.landmarks, *rig, {{"widen_eye_R", 1.0}});
  EXPECT_GT(widen.at("eye_right_1").y(), 0.005);
  EXPECT_LT(widen.at("eye_right_4").norm(), 1e-3 * widen.at("eye_right_1").norm() + 1e-12);
  // The sculptors keep the lids out of the eyeball, even closed over an eye
  // looking down: no member deeper in than at rest (the eyeball's sphere is
  // fixed; the cornea's turns with the gaze cluster, as the pose reports it).
  auto pose = core::evaluatePose(head.mesh.positions, head.mesh.triangles, doc,
                                 {{"blink_L", 1.0}, {"blink_R", 1.0}, {"look_down", 1.0}, {"raise_lower_lid_L", 1.0}});
  ASSERT_TRUE(pose.ok()) << pose.error().message;
  int sculptors = 0, corneas = 0;
  for (const core::PushToSurface& push : doc.push_to_surfaces) {
    const bool cornea = push.name.rfind("cornea_sculptor", 0) == 0;
    if (!cornea && push.name.rfind("eyelid_sculptor", 0) != 0) continue;
    (cornea ? corneas : sculptors) += 1;
    EXPECT_EQ(push.direction, core::PushDirection::kFromPoint);
    EXPECT_TRUE(push.keep_rest_depth);
    EXPECT_EQ(cornea, !push.carried_by.empty());
    const Eigen::Vector3d rest_centre = push.surface.center.position;
    const Eigen::Vector3d centre = cornea ? Eigen::Vector3d(pose->cluster_transforms.at(push.carried_by) * rest_centre) : rest_centre;
    for (const int v : push.members) {
      const double at_rest = std::min((head.mesh.positions.row(v).transpose() - rest_centre).norm(), push.surface.radius);
      EXPECT_GE((pose->positions.row(v).transpose() - centre).norm(), at_rest - 1e-9) << push.name << " " << v;
    }
  }
  EXPECT_EQ(sculptors, 2);
  EXPECT_EQ(corneas, 2);
}

TEST(MuscleRig, AnEyeJointOfTheRigIsAimedWithTheEye) {
  const auto head = headWithParting();
  auto plain = core::buildMuscleRig(head.mesh, head.landmarks);
  ASSERT_TRUE(plain.ok()) << plain.error().message;
  const auto& locators = plain->components.locators;
  const Eigen::Vector3d eye = locators[static_cast<std::size_t>(core::indexByName(locators, "eye_centre_L"))].binding.position;
  core::MuscleRigOptions options;
  // A joint a little off the placed centre is the eye's; one far off is not.
  auto at = [](const Eigen::Vector3d& p) {
    Eigen::Matrix4d t = Eigen::Matrix4d::Identity();
    t.topRightCorner<3, 1>() = p;
    return t;
  };
  options.joints = {{"LeftEye", at(eye + Eigen::Vector3d(0.002, -0.001, 0.0))}, {"Head", at(eye + Eigen::Vector3d(0.0, -0.2, -0.1))}};
  std::map<std::string, Eigen::Vector3d> joint_positions;
  for (const auto& [name, t] : options.joints) joint_positions[name] = t.topRightCorner<3, 1>();
  auto rig = core::buildMuscleRig(head.mesh, head.landmarks, options);
  ASSERT_TRUE(rig.ok()) << rig.error().message;
  int joint_aims = 0;
  for (const core::AimConstraint& aim : rig->components.aim_constraints) {
    if (!aim.joint) continue;
    ++joint_aims;
    EXPECT_EQ(aim.constrained, "LeftEye");
  }
  EXPECT_EQ(joint_aims, 1);
  const auto& moved = rig->components.locators;
  EXPECT_EQ(moved[static_cast<std::size_t>(core::indexByName(moved, "eye_centre_L"))].binding.position, joint_positions.at("LeftEye"));
  core::PoseOptions joints;
  joints.joint_positions = joints.joint_rest_positions = joint_positions;
  auto pose = core::evaluatePose(head.mesh.positions, head.mesh.triangles, rig->components, {{"look_left", 1.0}}, joints);
  ASSERT_TRUE(pose.ok()) << pose.error().message;
  // 30 degrees to the subject's left: the eye's forward turns that far.
  auto frame = core::buildFaceFrame(head.mesh, head.landmarks, "head");
  ASSERT_TRUE(frame.ok());
  const Eigen::Vector3d forward = pose->joint_aims.at("LeftEye") * frame->forward;
  EXPECT_NEAR(std::acos(std::clamp(forward.dot(frame->forward), -1.0, 1.0)) * 180.0 / M_PI, 30.0, 1.0);
  EXPECT_GT(forward.dot(frame->right), 0.4);
}

TEST(MuscleRig, ScalesWithTheFace) {
  const auto head = headWithParting();
  core::SyntheticHead big = head;
  big.mesh.positions *= 10.0;  // centimetres instead of metres... any unit
  auto small_rig = core::buildMuscleRig(head.mesh, head.landmarks);
  auto big_rig = core::buildMuscleRig(big.mesh, big.landmarks);
  ASSERT_TRUE(small_rig.ok() && big_rig.ok());
  for (const char* preset : {"joy", "surprise", "anger"}) {
    const auto a = presetMotion(head.mesh, head.landmarks, *small_rig, preset);
    const auto b = presetMotion(big.mesh, big.landmarks, *big_rig, preset);
    for (const auto& [name, d] : a) EXPECT_LT((d - b.at(name)).norm(), 1e-6) << preset << " at " << name;
  }
}

TEST(MuscleRig, OtherHeadsTakeTheRigToo) {
  for (unsigned seed : {1u, 2u, 3u}) {
    core::HeadShape shape = core::randomHeadShape(seed);
    shape.mouth_open = 0.01;
    const auto head = core::generateHead(shape);
    auto rig = core::buildMuscleRig(head.mesh, head.landmarks);
    ASSERT_TRUE(rig.ok()) << "seed " << seed << ": " << rig.error().message;
    expectExpressionDirections(head.mesh, head.landmarks, *rig);
  }
}

TEST(MuscleRig, MissingLandmarkIsNamed) {
  auto head = headWithParting();
  auto& list = head.landmarks.landmarks;
  list.erase(std::remove_if(list.begin(), list.end(), [](const core::Landmark& l) { return l.name == "mouth_outer_6"; }),
             list.end());
  core::MuscleRigOptions options;
  options.label = "head.landmarks.json";
  auto rig = core::buildMuscleRig(head.mesh, head.landmarks, options);
  ASSERT_FALSE(rig.ok());
  EXPECT_NE(rig.error().message.find("mouth_outer_6"), std::string::npos) << rig.error().message;
  EXPECT_NE(rig.error().message.find("head.landmarks.json"), std::string::npos) << rig.error().message;
}

}  // namespace
}  // namespace rigport_test
