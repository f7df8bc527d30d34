// The reference muscle rig (core/muscle_rig) on generated heads: it builds
// and validates with the paper's counts, rest is the identity, every preset
// moves the face the way its expression should (measured in the face's own
// frame), the upper-lip wires leave the lower lip alone, the rig scales with
// the face, and a missing landmark is named.
#include <algorithm>
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
  EXPECT_EQ(doc.push_to_surfaces.size(), 1u);
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
