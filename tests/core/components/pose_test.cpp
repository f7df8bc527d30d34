#include "core/components/pose.h"

#include <gtest/gtest.h>

#include "core/components/cluster.h"
#include "core/components/wire.h"
#include "tests/core/components/components_fixture.h"

namespace {

using components_test::fullDocument;
using components_test::gridMesh;
using components_test::gridVertex;

// The document without what moves the mesh at rest (authored cluster
// transform, a moved lattice point, the push sphere).
core::ComponentsDocument restNeutralDocument() {
  core::ComponentsDocument doc = fullDocument();
  doc.clusters[0].translate.setZero();
  doc.clusters[0].rotate.setIdentity();
  doc.lattices[0].points.clear();
  doc.push_to_surfaces.clear();
  return doc;
}

TEST(Pose, RestControlsLeaveTheMeshAtRest) {
  const core::Mesh mesh = gridMesh();
  auto pose = core::evaluatePose(mesh.positions, mesh.triangles, restNeutralDocument(), {});
  ASSERT_TRUE(pose) << pose.error().message;
  EXPECT_LT((pose->positions - mesh.positions).norm(), 1e-12);
  EXPECT_EQ(pose->muscle_contractions.at("zygomatic"), 0.0);
  EXPECT_LT((pose->locator_positions.at("brow") - Eigen::Vector3d(0.0, 0.8, 0.3)).norm(), 1e-12);  // offset kept
}

TEST(Pose, ControlsDriveMusclesClustersMorphsAndJoints) {
  const core::Mesh mesh = gridMesh();
  const core::ComponentsDocument doc = restNeutralDocument();
  auto pose = core::evaluatePose(mesh.positions, mesh.triangles, doc, {{"smile", 0.5}});
  ASSERT_TRUE(pose) << pose.error().message;
  EXPECT_DOUBLE_EQ(pose->muscle_contractions.at("zygomatic"), 0.2);
  EXPECT_DOUBLE_EQ(pose->morph_weights.at("mouth_smile"), 0.5);
  EXPECT_DOUBLE_EQ(pose->joint_rotations.at("jaw").x(), 5.0);
  // The nose locator slides toward the muscle's origin by 0.5 * 0.2 of the muscle.
  const Eigen::Vector3d origin = mesh.positions.row(gridVertex(10, 10)).transpose();
  const Eigen::Vector3d nose_rest = mesh.positions.row(gridVertex(5, 5)).transpose();
  EXPECT_LT((pose->locator_positions.at("nose") - (nose_rest + 0.1 * (origin - nose_rest))).norm(), 1e-12);
  // The brow follows the nose (its point constraint, offset kept).
  EXPECT_LT((pose->locator_positions.at("brow") - Eigen::Vector3d(0.0, 0.8, 0.3) - 0.1 * (origin - nose_rest)).norm(), 1e-12);
  // Order: the wire's CV 2 is moved by the posed lip cluster, CV 3 by the nose's displacement.
  const Eigen::Affine3d& lip = pose->cluster_transforms.at("lip_c");
  const Eigen::Vector3d cv2 = mesh.positions.row(gridVertex(5, 6)).transpose();
  EXPECT_LT((pose->curve_points.at("lip")[2] - lip * cv2).norm(), 1e-12);
  const Eigen::Vector3d cv3 = mesh.positions.row(gridVertex(7, 6)).transpose();
  EXPECT_LT((pose->curve_points.at("lip")[3] - (cv3 + 0.1 * (origin - nose_rest))).norm(), 1e-12);
  EXPECT_GT((pose->positions - mesh.positions).norm(), 1e-3);
  // A lip member far from the wire, lattice and skull moved by the lip cluster alone.
  const int v = gridVertex(8, 3);
  const Eigen::Vector3d p = mesh.positions.row(v).transpose();
  EXPECT_LT((pose->positions.row(v).transpose() - (p + 0.5 * (lip * p - p))).norm(), 1e-12);
}

TEST(Pose, ControlValuesAreClampedAndReported) {
  const core::Mesh mesh = gridMesh();
  auto pose = core::evaluatePose(mesh.positions, mesh.triangles, fullDocument(), {{"smile", 3.0}});
  ASSERT_TRUE(pose) << pose.error().message;
  EXPECT_EQ(pose->clamped_controls, std::vector<std::string>{"smile"});
  EXPECT_DOUBLE_EQ(pose->control_values.at("smile"), 1.0);
  EXPECT_DOUBLE_EQ(pose->muscle_contractions.at("zygomatic"), 0.4);
}

TEST(Pose, UnknownControlAndNonFiniteValueAreErrors) {
  const core::Mesh mesh = gridMesh();
  auto unknown = core::evaluatePose(mesh.positions, mesh.triangles, fullDocument(), {{"smiel", 1.0}});
  ASSERT_FALSE(unknown);
  EXPECT_NE(unknown.error().message.find("unknown control \"smiel\" (did you mean \"smile\"?)"), std::string::npos)
      << unknown.error().message;
  auto nan = core::evaluatePose(mesh.positions, mesh.triangles, fullDocument(), {{"open", std::nan("")}});
  ASSERT_FALSE(nan);
  EXPECT_NE(nan.error().message.find("\"open\" is not a finite number"), std::string::npos) << nan.error().message;
}

TEST(Pose, JointTargetsNeedJointPositions) {
  const core::Mesh mesh = gridMesh();
  core::ComponentsDocument doc = fullDocument();
  doc.point_constraints[1].targets = {{core::TargetKind::kJoint, "head", -1, 1.0}};
  auto missing = core::evaluatePose(mesh.positions, mesh.triangles, doc, {});
  ASSERT_FALSE(missing);
  EXPECT_NE(missing.error().message.find("point_constraints[1] \"brow_follow\": joint \"head\""), std::string::npos)
      << missing.error().message;
  core::PoseOptions options;
  options.joint_rest_positions["head"] = {0.0, 0.0, 1.0};
  options.joint_positions["head"] = {0.0, 0.1, 1.0};
  auto pose = core::evaluatePose(mesh.positions, mesh.triangles, doc, {}, options);
  ASSERT_TRUE(pose) << pose.error().message;
  EXPECT_LT((pose->locator_positions.at("brow") - Eigen::Vector3d(0.0, 0.9, 0.3)).norm(), 1e-12);
}

TEST(Pose, PresetGivesItsControlsOverDefaults) {
  auto values = core::presetControls(fullDocument(), "half");
  ASSERT_TRUE(values) << values.error().message;
  EXPECT_DOUBLE_EQ(values->at("smile"), 0.5);
  EXPECT_DOUBLE_EQ(values->at("open"), -0.25);
  auto missing = core::presetControls(fullDocument(), "smiel");
  ASSERT_FALSE(missing);
  EXPECT_NE(missing.error().message.find("did you mean \"smile\""), std::string::npos) << missing.error().message;
}

// A similarity applied to the mesh and the components gives the posed mesh
// under that similarity.
TEST(Pose, EquivariantUnderASimilarity) {
  const core::Mesh mesh = gridMesh();
  const core::ComponentsDocument doc = fullDocument();
  components_test::SimilarityMap map;
  map.scale = 1.7;
  map.rotation = Eigen::AngleAxisd(0.9, Eigen::Vector3d(0.2, -1.0, 0.4).normalized()).toRotationMatrix();
  map.translation = {0.3, -2.0, 5.0};
  for (double smile : {0.0, 0.35, 1.0}) {
    auto pose = core::evaluatePose(mesh.positions, mesh.triangles, doc, {{"smile", smile}});
    ASSERT_TRUE(pose) << pose.error().message;
    auto mapped = core::evaluatePose(map.positions(mesh.positions), mesh.triangles, map.document(doc), {{"smile", smile}});
    ASSERT_TRUE(mapped) << mapped.error().message;
    EXPECT_GT((pose->positions - mesh.positions).norm(), 1e-3);  // something moved
    const Eigen::MatrixX3d expected = map.positions(pose->positions);
    for (Eigen::Index v = 0; v < expected.rows(); ++v) {
      EXPECT_LT((mapped->positions.row(v) - expected.row(v)).norm(), 1e-9) << "vertex " << v << " smile " << smile;
    }
    EXPECT_LT((mapped->locator_positions.at("brow") - map.point(pose->locator_positions.at("brow"))).norm(), 1e-9);
  }
}

TEST(Pose, InvalidDocumentIsRefusedAgainstTheMesh) {
  const core::Mesh mesh = gridMesh(2);  // 9 vertices: the document's indices are out of range
  auto pose = core::evaluatePose(mesh.positions, mesh.triangles, fullDocument(), {});
  ASSERT_FALSE(pose);
  EXPECT_NE(pose.error().message.find("out of range"), std::string::npos) << pose.error().message;
}

}  // namespace
