#include "core/components/push_to_surface.h"

#include <gtest/gtest.h>

#include "core/components/pose.h"
#include "core/io/components_io.h"
#include "tests/test_support.h"

namespace {

core::PushToSurface sphere(double radius) {
  core::PushToSurface p;
  p.name = "skull";
  p.surface.kind = core::CollisionShapeKind::kSphere;
  p.surface.center = core::Binding::atPosition({1.0, 0.0, 0.0});
  p.surface.radius = radius;
  return p;
}

TEST(PushToSurface, InsideASpherePushedOutRadiallyOutsideKept) {
  Eigen::MatrixX3d points(2, 3);
  points << 1.5, 0.0, 0.0,  // inside (0.5 from the centre)
      3.0, 0.0, 0.0;        // outside
  const Eigen::MatrixX3d out = core::evaluatePushToSurface(points, Eigen::MatrixX3i(0, 3), sphere(1.0));
  EXPECT_LT((out.row(0) - Eigen::RowVector3d(2.0, 0.0, 0.0)).norm(), 1e-12);
  EXPECT_EQ(out.row(1), points.row(1));
}

TEST(PushToSurface, AlongAVectorToWhereItLeaves) {
  core::PushToSurface p = sphere(1.0);
  p.direction = core::PushDirection::kVector;
  p.vector = {0.0, 0.0, 2.0};
  Eigen::MatrixX3d points(1, 3);
  points << 1.6, 0.0, 0.0;
  const Eigen::MatrixX3d out = core::evaluatePushToSurface(points, Eigen::MatrixX3i(0, 3), p);
  EXPECT_LT((out.row(0) - Eigen::RowVector3d(1.6, 0.0, 0.8)).norm(), 1e-12);  // 0.6^2 + 0.8^2 = 1
}

TEST(PushToSurface, FromAPointAlongTheRayThroughEachVertex) {
  // The sculptor of paper 001: rays from a point, here 0.5 behind the unit
  // sphere's centre. (0.3, 0, 0) leaves along (0.3, 0, 0.5): |p + t d| = 1 at
  // t = -p.d + sqrt((p.d)^2 - |p|^2 + 1) = 0.81199..., (0.71779, 0, 0.69627).
  core::PushToSurface p = sphere(1.0);
  p.surface.center = core::Binding::atPosition(Eigen::Vector3d::Zero());
  p.direction = core::PushDirection::kFromPoint;
  p.from = core::Binding::atPosition({0.0, 0.0, -0.5});
  Eigen::MatrixX3d points(3, 3);
  points << 0.3, 0.0, 0.0,  // inside
      0.0, 0.0, -0.5,       // at the rays' start: no direction, stays
      2.0, 0.0, 0.0;        // outside
  const Eigen::MatrixX3d out = core::evaluatePushToSurface(points, Eigen::MatrixX3i(0, 3), p);
  EXPECT_LT((out.row(0) - Eigen::RowVector3d(0.7177689, 0.0, 0.6962814)).norm(), 1e-6);
  EXPECT_NEAR(out.row(0).norm(), 1.0, 1e-12);
  const Eigen::Vector3d ray = (out.row(0) - Eigen::RowVector3d(0, 0, -0.5)).transpose();
  EXPECT_LT(ray.normalized().cross(Eigen::Vector3d(0.3, 0.0, 0.5).normalized()).norm(), 1e-12);  // on the ray
  EXPECT_EQ(out.row(1), points.row(1));
  EXPECT_EQ(out.row(2), points.row(2));
}

TEST(PushToSurface, EllipsoidAlongItsAxes) {
  core::PushToSurface p;
  p.surface.kind = core::CollisionShapeKind::kEllipsoid;
  p.surface.center = core::Binding::atPosition(Eigen::Vector3d::Zero());
  p.surface.radii = {2.0, 1.0, 1.0};
  p.surface.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ()));  // long axis along y
  Eigen::MatrixX3d points(2, 3);
  points << 0.0, 1.0, 0.0,  // inside (on the long axis)
      1.5, 0.0, 0.0;        // outside (short axis is 1 along x)
  const Eigen::MatrixX3d out = core::evaluatePushToSurface(points, Eigen::MatrixX3i(0, 3), p);
  EXPECT_LT((out.row(0) - Eigen::RowVector3d(0.0, 2.0, 0.0)).norm(), 1e-12);
  EXPECT_EQ(out.row(1), points.row(1));
}

TEST(PushToSurface, TriangleSurfaceOfMeshVertices) {
  // The icosphere is the collision surface; three more vertices are the skin.
  const auto ico = rigport_test::unitIcosphere(3);
  const Eigen::Index n = ico.positions.rows();
  Eigen::MatrixX3d positions(n + 3, 3);
  positions.topRows(n) = ico.positions;
  positions.row(n) << 0.5, 0.1, 0.0;      // inside
  positions.row(n + 1) << 0.0, 0.0, 1.3;  // outside
  positions.row(n + 2) << -0.1, -0.6, 0.3;  // inside
  core::PushToSurface p;
  p.surface.kind = core::CollisionShapeKind::kTriangles;
  for (Eigen::Index f = 0; f < ico.triangles.rows(); ++f) p.surface.triangles.push_back(ico.triangles.row(f).transpose());
  const Eigen::MatrixX3d out = core::evaluatePushToSurface(positions, ico.triangles, p);
  EXPECT_EQ(out.topRows(n), positions.topRows(n));  // the surface's own vertices stay
  EXPECT_EQ(out.row(n + 1), positions.row(n + 1));
  for (Eigen::Index v : {n, n + 2}) {
    // On the polyhedron (radius between its inradius and 1), in the point's direction roughly.
    EXPECT_GT(out.row(v).norm(), 0.98) << v;
    EXPECT_LE(out.row(v).norm(), 1.0 + 1e-12) << v;
    EXPECT_GT(out.row(v).normalized().dot(positions.row(v).normalized()), 0.99) << v;
  }
  // Along a vector: the inside point leaves through +x.
  p.direction = core::PushDirection::kVector;
  p.vector = Eigen::Vector3d::UnitX();
  const Eigen::MatrixX3d along = core::evaluatePushToSurface(positions, ico.triangles, p);
  EXPECT_NEAR(along(n, 1), 0.1, 1e-12);
  EXPECT_GT(along(n, 0), 0.98);
}

TEST(PushToSurface, KeepingRestDepthAMemberInsideAtRestGoesNoDeeper) {
  // Unit sphere at the origin. (0.5, 0, 0) rests at level 0.5 and, moved in
  // to (0.2, 0, 0), goes back to 0.5; (2, 0, 0) rests outside and, moved to
  // (0.3, 0, 0), goes onto the surface.
  core::PushToSurface p = sphere(1.0);
  p.surface.center = core::Binding::atPosition(Eigen::Vector3d::Zero());
  p.keep_rest_depth = true;
  Eigen::MatrixX3d rest(2, 3), posed(2, 3);
  rest << 0.5, 0.0, 0.0, 2.0, 0.0, 0.0;
  posed << 0.2, 0.0, 0.0, 0.3, 0.0, 0.0;
  const Eigen::VectorXd levels = core::surfaceLevels(rest, Eigen::MatrixX3i(0, 3), p);
  EXPECT_NEAR(levels(0), 0.5, 1e-12);
  EXPECT_EQ(levels(1), 1.0);
  EXPECT_LT((core::evaluatePushToSurface(rest, Eigen::MatrixX3i(0, 3), p, levels) - rest).norm(), 1e-12);  // rest: identity
  const Eigen::MatrixX3d out = core::evaluatePushToSurface(posed, Eigen::MatrixX3i(0, 3), p, levels);
  EXPECT_LT((out.row(0) - Eigen::RowVector3d(0.5, 0.0, 0.0)).norm(), 1e-12);
  EXPECT_LT((out.row(1) - Eigen::RowVector3d(1.0, 0.0, 0.0)).norm(), 1e-12);
}

TEST(PushToSurface, CarriedByAClusterTheSurfaceAndItsRaysMoveWithIt) {
  // The cluster "eye" moves 1 along +X at turn = 1, carrying the unit
  // sphere and its rays' start from the origin to (1, 0, 0): vertex 1 at
  // (1.5, 0, 0), outside at rest, is then inside and leaves along the ray
  // from (1, 0, 0) at (2, 0, 0). Vertex 0 is the cluster's member only.
  auto doc = core::parseComponents(R"({"format": "rigport.components", "version": 1,
      "clusters": [{"name": "eye", "pivot": {"position": [0, 0, 0]}, "members": [{"vertex": 0}]}],
      "push_to_surfaces": [{"name": "cornea", "surface": {"sphere": {"center": {"position": [0, 0, 0]}, "radius": 1}},
                            "direction": {"from": {"position": [0, 0, 0]}}, "members": [1], "carried_by": "eye",
                            "keep_rest_depth": true}],
      "controls": [{"name": "turn", "drives": [{"cluster": "eye", "channel": "translate_x", "gain": 1}]}]})",
                                   "eye.json");
  ASSERT_TRUE(doc) << doc.error().message;
  Eigen::MatrixX3d rest(2, 3);
  rest << 0.0, 3.0, 0.0, 1.5, 0.0, 0.0;
  auto at_rest = core::evaluatePose(rest, Eigen::MatrixX3i(0, 3), *doc, {});
  ASSERT_TRUE(at_rest) << at_rest.error().message;
  EXPECT_LT((at_rest->positions - rest).norm(), 1e-12);
  auto turned = core::evaluatePose(rest, Eigen::MatrixX3i(0, 3), *doc, {{"turn", 1.0}});
  ASSERT_TRUE(turned) << turned.error().message;
  EXPECT_LT((turned->positions.row(1) - Eigen::RowVector3d(2.0, 0.0, 0.0)).norm(), 1e-12);
  EXPECT_LT((turned->positions.row(0) - Eigen::RowVector3d(1.0, 3.0, 0.0)).norm(), 1e-12);

  // A cluster the document lacks, and a triangle surface carried, are named.
  core::ComponentsDocument bad = *doc;
  bad.push_to_surfaces[0].carried_by = "eey";
  auto unknown = core::validate(bad, 2);
  ASSERT_FALSE(unknown);
  EXPECT_NE(unknown.error().message.find("carried_by: unknown cluster \"eey\" (did you mean \"eye\"?)"), std::string::npos)
      << unknown.error().message;
  bad = *doc;
  bad.push_to_surfaces[0].surface.kind = core::CollisionShapeKind::kTriangles;
  bad.push_to_surfaces[0].surface.triangles = {Eigen::Vector3i(0, 1, 0)};
  auto triangles = core::validate(bad, 2);
  ASSERT_FALSE(triangles);
  EXPECT_NE(triangles.error().message.find("keep_rest_depth: only a sphere or ellipsoid"), std::string::npos)
      << triangles.error().message;
}

}  // namespace
