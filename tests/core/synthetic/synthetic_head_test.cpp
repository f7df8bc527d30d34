#include "core/synthetic/synthetic_head.h"

#include <set>

#include <gtest/gtest.h>

#include "core/solve/tps.h"

namespace {

TEST(SyntheticHead, Has68UniqueLandmarksOnValidFaces) {
  const auto head = core::generateHead();
  ASSERT_EQ(head.landmarks.landmarks.size(), 68u);
  std::set<std::string> names;
  for (const auto& lm : head.landmarks.landmarks) {
    names.insert(lm.name);
    ASSERT_GE(lm.face, 0);
    ASSERT_LT(lm.face, head.mesh.triangleCount());
    EXPECT_NEAR(lm.barycentric.sum(), 1.0, 1e-12);
    EXPECT_GE(lm.barycentric.minCoeff(), 0.0);
  }
  EXPECT_EQ(names.size(), 68u);
  EXPECT_TRUE(names.count("jaw_00") && names.count("jaw_16") && names.count("nose_bridge_3") &&
              names.count("mouth_inner_7") && names.count("eye_left_5"));
  EXPECT_TRUE(core::validateMesh(head.mesh, "head"));
}

TEST(SyntheticHead, LandmarksSitAtAnatomicalPlaces) {
  const auto head = core::generateHead();
  auto p = core::resolveLandmarks(head.landmarks, head.mesh, "head");
  ASSERT_TRUE(p);
  auto at = [&](const std::string& n) { return Eigen::Vector3d(p->row(head.landmarks.indexOf(n))); };
  // Nose tip is the most forward landmark; eyes above the mouth; subject's left is +X.
  for (Eigen::Index i = 0; i < p->rows(); ++i) EXPECT_LE((*p)(i, 2), at("nose_bridge_3").z() + 1e-12);
  EXPECT_GT(at("eye_left_0").y(), at("mouth_outer_3").y());
  EXPECT_GT(at("eye_left_3").x(), 0.0);
  EXPECT_LT(at("eye_right_0").x(), 0.0);
  EXPECT_LT(at("jaw_08").y(), at("mouth_outer_9").y());  // chin below the lower lip
  EXPECT_GT(at("mouth_outer_6").x(), at("mouth_outer_0").x());
}

TEST(SyntheticHead, ResolutionAndIdentityChangeTopologyAndProportions) {
  const auto a = core::generateHead();
  core::HeadResolution res;
  res.columns = 70;
  res.rows = 60;
  res.alternate_diagonals = true;
  res.jitter = 0.3;
  res.seed = 3;
  const auto b = core::generateHead(core::randomHeadShape(3, 0.2), res);
  EXPECT_NE(a.mesh.vertexCount(), b.mesh.vertexCount());
  EXPECT_NE(a.mesh.triangleCount(), b.mesh.triangleCount());
  // Landmark sets remain usable for a TPS.
  auto pa = core::resolveLandmarks(a.landmarks, a.mesh, "a");
  auto pb = core::resolveLandmarks(b.landmarks, b.mesh, "b");
  ASSERT_TRUE(pa && pb);
  EXPECT_TRUE(core::fitTps(*pa, *pb));
  // Same seed, same mesh.
  const auto b2 = core::generateHead(core::randomHeadShape(3, 0.2), res);
  EXPECT_TRUE(b.mesh.positions == b2.mesh.positions);
}

TEST(SyntheticHead, OpenMouthCutsASlitBetweenTheLips) {
  core::HeadShape open;
  open.mouth_open = 0.03;
  const auto closed = core::generateHead();
  const auto opened = core::generateHead(open);
  EXPECT_LT(opened.mesh.triangleCount(), closed.mesh.triangleCount());
  auto p = core::resolveLandmarks(opened.landmarks, opened.mesh, "open");
  ASSERT_TRUE(p);
  const double gap = ((*p).row(opened.landmarks.indexOf("mouth_inner_2")) - (*p).row(opened.landmarks.indexOf("mouth_inner_6"))).norm();
  EXPECT_GT(gap, 0.004);  // metres: the inner lips are apart
}

}  // namespace
