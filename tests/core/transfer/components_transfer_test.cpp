// A rig's components document carried to another head
// (core/transfer/components_transfer.h): the target's document is valid on
// the target's mesh, its surface-bound points land where the rig's are on
// the target, and posing it moves the target as the same pose baked into a
// blend shape and transferred does (the consistency the papers' influence
// object transfer relies on).
#include "core/transfer/components_transfer.h"

#include <gtest/gtest.h>

#include <cstdio>

#include "core/components/bake.h"
#include "core/components/pose.h"
#include "core/io/landmarks.h"
#include "tests/core/transfer/transfer_rigs.h"
#include "tests/test_support.h"

namespace {

using namespace rigport_test::transfer;

Eigen::Vector3d landmarkAt(const core::SyntheticRig& rig, const std::string& name) {
  auto at = core::resolveLandmarks(rig.landmarks, rig.rig.mesh, "rig");
  EXPECT_TRUE(at);
  for (std::size_t i = 0; i < rig.landmarks.landmarks.size(); ++i) {
    if (rig.landmarks.landmarks[i].name == name) return at->row(static_cast<Eigen::Index>(i)).transpose();
  }
  ADD_FAILURE() << "no landmark " << name;
  return Eigen::Vector3d::Zero();
}

// A mouth-corner cluster (members within a radius, weight falling off) lifted
// by control "smile", a locator at the corner, a free locator in front.
core::ComponentsDocument mouthDocument(const core::SyntheticRig& source) {
  const core::Mesh& mesh = source.rig.mesh;
  const Eigen::Vector3d corner = landmarkAt(source, "mouth_outer_0");
  const double diagonal = core::boundingBoxDiagonal(mesh.positions);
  const double radius = 0.08 * diagonal;
  core::ComponentsDocument doc;
  core::Cluster cluster;
  cluster.name = "mouth_corner_R";
  int nearest = 0;
  double best = 1e300;
  for (Eigen::Index v = 0; v < mesh.vertexCount(); ++v) {
    const double d = (mesh.positions.row(v).transpose() - corner).norm();
    if (d < best) best = d, nearest = static_cast<int>(v);
    if (d < radius) cluster.members.push_back({static_cast<int>(v), 1.0 - d / radius});
  }
  cluster.pivot = core::Binding::atVertex(nearest);
  doc.clusters.push_back(cluster);
  doc.locators.push_back({"corner", core::Binding::atVertex(nearest)});
  doc.locators.push_back({"in_front", core::Binding::atPosition(corner + Eigen::Vector3d(0, 0, 0.1 * diagonal))});
  core::Control smile;
  smile.name = "smile";
  smile.drives.push_back({core::DriveTargetKind::kCluster, cluster.name, core::ClusterChannel::kTranslateY,
                          core::JointChannel::kRotateX, 0.02 * diagonal});
  doc.controls.push_back(smile);
  doc.presets["smile_R"].controls = {{"smile", 1.0}};
  return doc;
}

TEST(TransferComponents, TheTargetsDocumentIsValidAndPosesAsTheBakedShapeTransfers) {
  const core::SyntheticRig& source = sourceRig();
  core::Rig rig = source.rig;
  const core::ComponentsDocument doc = mouthDocument(source);
  auto baked = core::bakePresets(rig, doc);  // the same pose as a blend shape of the rig
  ASSERT_TRUE(baked) << baked.error().message;
  auto prepared = core::prepareRig(rig, source.landmarks, "source");
  ASSERT_TRUE(prepared) << prepared.error().message;
  prepared->components = doc;
  const core::SyntheticRig& target = otherHead();
  auto out = core::transferRig(*prepared, target.rig.mesh, target.landmarks, "other head");
  ASSERT_TRUE(out) << out.error().message;
  ASSERT_TRUE(out->components.has_value());
  const core::ComponentsDocument& moved = *out->components;
  const core::Mesh& mesh = out->rig.mesh;
  const double diagonal = core::boundingBoxDiagonal(mesh.positions);

  // Valid on the target's mesh; bound to it (not free) where the rig's was.
  core::ComponentsMeshCounts counts;
  counts.vertex_count = mesh.vertexCount();
  counts.triangle_count = mesh.triangleCount();
  ASSERT_TRUE(core::validateComponents(moved, "moved", counts));
  EXPECT_EQ(moved.locators[0].binding.kind, core::BindingKind::kFace);
  EXPECT_EQ(moved.locators[1].binding.kind, core::BindingKind::kPosition);
  const Eigen::Vector3d corner = core::resolveBinding(moved.locators[0].binding, mesh.positions, mesh.triangles);
  EXPECT_LT((corner - landmarkAt(target, "mouth_outer_0")).norm(), 0.01 * diagonal);
  ASSERT_FALSE(moved.clusters[0].members.empty());
  for (const core::ClusterMember& m : moved.clusters[0].members) {
    EXPECT_GT(m.weight, 0.0);
    EXPECT_LE(m.weight, 1.0 + 1e-9);
    EXPECT_LT((mesh.positions.row(m.vertex).transpose() - corner).norm(), 0.12 * diagonal) << m.vertex;
  }

  // Posing the moved document against the baked preset, transferred as a shape.
  auto pose = core::evaluatePose(mesh.positions, mesh.triangles, moved, {{"smile", 1.0}});
  ASSERT_TRUE(pose) << pose.error().message;
  const Eigen::MatrixX3d posed = pose->positions - mesh.positions;
  const core::MorphTarget* shape = nullptr;
  for (const core::MorphTarget& t : out->rig.morph_targets) {
    if (t.name == "smile_R") shape = &t;
  }
  ASSERT_NE(shape, nullptr);
  const double e = (posed - shape->position_deltas).rowwise().norm().sum() / shape->position_deltas.rowwise().norm().sum();
  std::printf("posed components vs transferred baked shape: E = %.4f\n", e);
  EXPECT_LE(e, 0.10);
}

TEST(TransferComponents, VertexCopiesJoinTheirOriginalsSets) {
  core::ComponentsDocument doc;
  core::Cluster c;
  c.name = "c";
  c.members = {{1, 0.5}, {2, 1.0}};
  doc.clusters.push_back(c);
  core::Wire w;
  w.name = "w";
  w.members = {2};
  doc.wires.push_back(w);
  core::addVertexCopies(doc, {2, 0, 1}, 4);  // vertices 4, 5, 6 copy 2, 0, 1
  EXPECT_EQ(doc.clusters[0].members,
            (std::vector<core::ClusterMember>{{1, 0.5}, {2, 1.0}, {6, 0.5}, {4, 1.0}}));
  EXPECT_EQ(doc.wires[0].members, (std::vector<int>{2, 4}));
}

}  // namespace
