// Presets baked into morph targets (core/components/bake.h) on the generated
// rig: a baked target is the preset's pose minus the rest plus the rig's own
// shapes it drives and the joints it turns, held at the rest skeleton;
// recorded as a baked preset in the GLB, replaced when baked again; parts
// get targets of their own when a preset moves them; bad names leave the rig
// as it was.
#include "core/components/bake.h"

#include <gtest/gtest.h>

#include <algorithm>

#include "core/components/pose.h"
#include "core/components/pose_spec.h"
#include "core/rig/skinning.h"
#include "core/io/rig_io.h"
#include "core/synthetic/synthetic_rig.h"
#include "tests/test_support.h"

namespace {

using core::ComponentsDocument;

int targetIndex(const core::Rig& rig, const std::string& name) {
  for (std::size_t t = 0; t < rig.morph_targets.size(); ++t) {
    if (rig.morph_targets[t].name == name) return static_cast<int>(t);
  }
  return -1;
}

// A brow cluster raised by control "raise" (which also half-opens the jaw
// shape) and a jaw turned by control "turn"; presets "surprise" and "talk".
ComponentsDocument browDocument(const core::Rig& rig, double lift) {
  ComponentsDocument doc;
  core::Cluster brow;
  brow.name = "brow";
  brow.pivot = core::Binding::atVertex(0);
  for (int v = 0; v < 40; ++v) brow.members.push_back({v * 7, 1.0});
  doc.clusters.push_back(brow);
  core::Control raise;
  raise.name = "raise";
  raise.drives.push_back({core::DriveTargetKind::kCluster, "brow", core::ClusterChannel::kTranslateY,
                          core::JointChannel::kRotateX, lift});
  raise.drives.push_back({core::DriveTargetKind::kMorph, "jawOpen", core::ClusterChannel::kTranslateX,
                          core::JointChannel::kRotateX, 0.5});
  doc.controls.push_back(raise);
  core::Control turn;
  turn.name = "turn";
  turn.drives.push_back({core::DriveTargetKind::kJoint, "jaw", core::ClusterChannel::kTranslateX,
                         core::JointChannel::kRotateX, 10.0});
  doc.controls.push_back(turn);
  doc.presets["surprise"].controls = {{"raise", 1.0}};
  doc.presets["talk"].controls = {{"raise", 0.5}, {"turn", 1.0}};
  EXPECT_TRUE(core::validate(doc, rig.mesh.vertexCount()));
  return doc;
}

TEST(BakePresets, ABakedPresetIsItsPoseAndTheShapesItDrives) {
  core::Rig rig = core::generateRig().rig;
  const double lift = 0.01 * core::boundingBoxDiagonal(rig.mesh.positions);
  const ComponentsDocument doc = browDocument(rig, lift);
  const std::size_t before = rig.morph_targets.size();
  const int jaw_open = targetIndex(rig, "jawOpen");
  ASSERT_GE(jaw_open, 0);
  const Eigen::MatrixX3d jaw_deltas = rig.morph_targets[static_cast<std::size_t>(jaw_open)].position_deltas;

  const core::Rig unbaked = rig;
  auto report = core::bakePresets(rig, doc);
  ASSERT_TRUE(report) << report.error().message;
  EXPECT_EQ(report->baked, (std::vector<std::string>{"surprise", "talk"}));
  ASSERT_EQ(rig.morph_targets.size(), before + 2);
  EXPECT_EQ(rig.baked_presets, (std::vector<std::string>{"surprise", "talk"}));
  EXPECT_EQ(rig.morph_default_weights.size(), static_cast<Eigen::Index>(before + 2));
  for (const core::Animation& a : rig.animations) {
    for (const core::AnimationChannel& c : a.channels) {
      if (c.path == core::AnimationPath::kWeights) {
        EXPECT_EQ(c.values.cols(), static_cast<Eigen::Index>(before + 2));
      }
    }
  }
  // "surprise": the brow members lifted, everything moved by half the jaw shape.
  const Eigen::MatrixX3d& surprise = rig.morph_targets[before].position_deltas;
  Eigen::MatrixX3d expected = 0.5 * jaw_deltas;
  for (int v = 0; v < 40; ++v) expected(v * 7, 1) += lift;
  EXPECT_TRUE(rigport_test::matricesNear(surprise, expected, 1e-12 * lift));
  // "talk" turns the jaw joint: the target holds the turn, so played at the rest skeleton it shows
  // the face poseRig poses (skinned with the jaw turned).
  EXPECT_TRUE(report->warnings.empty());
  core::PoseSpec talk;
  talk.preset = "talk";
  auto posed = core::poseRig(unbaked, &doc, talk);
  ASSERT_TRUE(posed) << posed.error().message;
  core::Pose played;
  played.nodes = rig.nodes;
  played.morph_weights = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(rig.morph_targets.size()));
  played.morph_weights(static_cast<Eigen::Index>(before + 1)) = 1.0;
  const Eigen::MatrixX3d shown = core::poseMesh(rig, played);
  EXPECT_TRUE(rigport_test::matricesNear(shown, posed->rig.mesh.positions, 1e-9 * lift));
  EXPECT_GT((posed->rig.mesh.positions - core::poseMesh(unbaked, core::Pose{rig.nodes, Eigen::VectorXd::Zero(static_cast<Eigen::Index>(before))}))
                .rowwise().norm().maxCoeff(), 10.0 * lift);  // the jaw did turn

  // Written and read back: the baked presets recorded, the file valid.
  const auto path = rigport_test::makeTempDir("bake_presets") / "baked.glb";
  ASSERT_TRUE(core::writeRigGlb(rig, path));
  EXPECT_GLTF_VALID(path);
  auto back = core::readRig(path);
  ASSERT_TRUE(back) << back.error().message;
  EXPECT_EQ(back->rig.baked_presets, rig.baked_presets);

  // Baked again with another lift: replaced, not added.
  const ComponentsDocument higher = browDocument(rig, 2.0 * lift);
  auto again = core::bakePresets(back->rig, higher, {"surprise"});
  ASSERT_TRUE(again) << again.error().message;
  ASSERT_EQ(back->rig.morph_targets.size(), before + 2);
  EXPECT_NEAR(back->rig.morph_targets[before].position_deltas(0, 1) - 0.5 * jaw_deltas(0, 1), 2.0 * lift, 1e-6 * lift);
}

TEST(BakePresets, BadNamesLeaveTheRigAsItWas) {
  core::Rig rig = core::generateRig().rig;
  ComponentsDocument doc = browDocument(rig, 0.01);
  const std::size_t before = rig.morph_targets.size();
  auto unknown = core::bakePresets(rig, doc, {"surprised"});
  ASSERT_FALSE(unknown);
  EXPECT_NE(unknown.error().message.find("did you mean \"surprise\""), std::string::npos) << unknown.error().message;
  doc.presets["jawOpen"].controls = {{"raise", 1.0}};
  auto clash = core::bakePresets(rig, doc);
  ASSERT_FALSE(clash);
  EXPECT_NE(clash.error().message.find("jawOpen"), std::string::npos) << clash.error().message;
  doc.presets.erase("jawOpen");
  doc.controls[0].drives[1].name = "jawOpne";
  auto shape = core::bakePresets(rig, doc);
  ASSERT_FALSE(shape);
  EXPECT_NE(shape.error().message.find("did you mean \"jawOpen\""), std::string::npos) << shape.error().message;
  EXPECT_EQ(rig.morph_targets.size(), before);
  EXPECT_TRUE(rig.baked_presets.empty());
}

}  // namespace
