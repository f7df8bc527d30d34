#include "core/io/landmarks.h"

#include <gtest/gtest.h>

#include "core/geometry/closest_point.h"
#include "core/solve/tps.h"
#include "core/synthetic/synthetic_head.h"
#include "tests/test_support.h"

namespace {

core::Mesh unitTetrahedron() {
  core::Mesh m;
  m.positions.resize(4, 3);
  m.positions << 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1;
  m.triangles.resize(4, 3);
  m.triangles << 0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3;
  return m;
}

void expectError(const std::string& json, const std::string& fragment) {
  auto r = core::parseLandmarks(json, "lm.json");
  ASSERT_FALSE(r) << json;
  EXPECT_NE(r.error().message.find(fragment), std::string::npos) << r.error().message;
  EXPECT_EQ(r.error().message.rfind("lm.json", 0), 0u) << "message names the file: " << r.error().message;
}

TEST(Landmarks, ParsesAllThreeKinds) {
  auto r = core::parseLandmarks(R"({"landmarks":[{"name":"a","vertex":2},{"name":"b","position":[0.1,0.2,0.3]},
      {"name":"c","face":1,"barycentric":[0.2,0.3,0.5]}]})",
                                "lm.json");
  ASSERT_TRUE(r) << r.error().message;
  ASSERT_EQ(r->landmarks.size(), 3u);
  EXPECT_EQ(r->landmarks[0].kind, core::LandmarkKind::kVertex);
  EXPECT_EQ(r->landmarks[0].vertex, 2);
  EXPECT_EQ(r->landmarks[1].kind, core::LandmarkKind::kPosition);
  EXPECT_DOUBLE_EQ(r->landmarks[1].position.z(), 0.3);
  EXPECT_EQ(r->landmarks[2].kind, core::LandmarkKind::kFace);
  EXPECT_EQ(r->indexOf("c"), 2);
  EXPECT_EQ(r->indexOf("zz"), -1);
}

TEST(Landmarks, RoundTripsThroughFormat) {
  const auto head = core::generateHead();
  auto back = core::parseLandmarks(core::formatLandmarks(head.landmarks), "head.json");
  ASSERT_TRUE(back);
  ASSERT_EQ(back->landmarks.size(), head.landmarks.landmarks.size());
  for (std::size_t i = 0; i < back->landmarks.size(); ++i) {
    EXPECT_EQ(back->landmarks[i].name, head.landmarks.landmarks[i].name);
    EXPECT_EQ(back->landmarks[i].face, head.landmarks.landmarks[i].face);
    EXPECT_TRUE(back->landmarks[i].barycentric.isApprox(head.landmarks.landmarks[i].barycentric, 1e-12));
  }
}

TEST(Landmarks, RejectsMalformedEntriesNamingThem) {
  expectError("{not json", "not valid JSON");
  expectError(R"({"points":[]})", "'landmarks' array");
  expectError(R"({"landmarks":[{"vertex":1}]})", "landmarks[0]");
  expectError(R"({"landmarks":[{"name":"a","vertex":1},{"name":"a","vertex":2}]})", "duplicate name 'a'");
  expectError(R"({"landmarks":[{"name":"a","vertex":1,"position":[0,0,0]}]})", "exactly one of");
  expectError(R"({"landmarks":[{"name":"a"}]})", "exactly one of");
  expectError(R"({"landmarks":[{"name":"a","vertex":-3}]})", "non-negative integer");
  expectError(R"({"landmarks":[{"name":"a","position":[0,1]}]})", "array of 3 numbers");
  expectError(R"({"landmarks":[{"name":"a","face":0}]})", "needs 'barycentric'");
  expectError(R"({"landmarks":[{"name":"nose","face":0,"barycentric":[0.5,0.5,0.5]}]})", "sum to 1");
  expectError(R"({"landmarks":[{"name":"nose","face":0,"barycentric":[1.5,-0.5,0]}]})", "('nose')");
  // Untrusted text that would crash a recursive reader, or a number out of
  // range: errors naming the file, not an abort.
  expectError(std::string(100000, '[') + std::string(100000, ']'), "JSON nested deeper than 64 levels");
  expectError(R"({"landmarks":[{"name":"a","position":[1e400,0,0]}]})", "not valid JSON");
  expectError(std::string(64, '[') + std::string(64, ']'), "'landmarks' array");  // 64 levels: parsed, then refused
}


TEST(Landmarks, ResolvesOnTheMeshAndRejectsOutOfRangeOrOffMesh) {
  const core::Mesh mesh = unitTetrahedron();
  auto ok = core::parseLandmarks(R"({"landmarks":[{"name":"a","vertex":3},{"name":"b","face":0,
      "barycentric":[0.5,0.25,0.25]},{"name":"c","position":[0.5,0.5,0.0]}]})",
                                 "t.json");
  ASSERT_TRUE(ok);
  auto p = core::resolveLandmarks(*ok, mesh, "t.json");
  ASSERT_TRUE(p) << p.error().message;
  EXPECT_TRUE(rigport_test::matricesNear(p->row(0), Eigen::RowVector3d(0, 0, 1), 0));
  EXPECT_TRUE(rigport_test::matricesNear(p->row(1), Eigen::RowVector3d(0.25, 0.25, 0), 1e-15));

  auto bad_vertex = core::parseLandmarks(R"({"landmarks":[{"name":"chin","vertex":4}]})", "t.json");
  auto r1 = core::resolveLandmarks(*bad_vertex, mesh, "t.json");
  ASSERT_FALSE(r1);
  EXPECT_NE(r1.error().message.find("'chin'"), std::string::npos);
  EXPECT_NE(r1.error().message.find("vertex 4 is out of range"), std::string::npos) << r1.error().message;

  auto bad_face = core::parseLandmarks(R"({"landmarks":[{"name":"x","face":4,"barycentric":[1,0,0]}]})", "t.json");
  EXPECT_FALSE(core::resolveLandmarks(*bad_face, mesh, "t.json"));

  auto off = core::parseLandmarks(R"({"landmarks":[{"name":"far","position":[3,3,3]}]})", "t.json");
  auto r2 = core::resolveLandmarks(*off, mesh, "t.json");
  ASSERT_FALSE(r2);
  EXPECT_NE(r2.error().message.find("off the mesh"), std::string::npos) << r2.error().message;
}

TEST(Landmarks, EachLandmarkHasAVertexStandingForIt) {
  const core::Mesh mesh = unitTetrahedron();
  auto set = core::parseLandmarks(R"({"landmarks":[{"name":"a","vertex":3},{"name":"b","face":0,
      "barycentric":[0.5,0.25,0.25]},{"name":"c","position":[0.2,0.6,0.0]}]})", "t.json");
  ASSERT_TRUE(set);
  auto p = core::resolveLandmarks(*set, mesh, "t.json");
  ASSERT_TRUE(p) << p.error().message;
  // Vertex 3; face 0's corner of weight 0.5 (vertex 0); the position's closest
  // face is face 0, where it is nearest vertex 2 (weights 0.2 / 0.6 / 0.2).
  const std::vector<int> expected = {3, 0, 2};
  EXPECT_EQ(core::landmarkVertices(*set, mesh, *p), expected);
  const core::ClosestPointIndex index(mesh.positions, mesh.triangles);
  EXPECT_EQ(core::landmarkVertices(*set, mesh, *p, &index), expected);
}

TEST(Landmarks, PairsByNameAndRejectsUnknownOrTooFewShared) {
  core::LandmarkSet source;
  Eigen::MatrixX3d sp(6, 3);
  for (int i = 0; i < 6; ++i) {
    source.landmarks.push_back({"l" + std::to_string(i), core::LandmarkKind::kVertex, i, {}, -1, {}});
    sp.row(i) << i, i * i, 1.0 / (i + 1);
  }
  core::LandmarkSet target;
  for (int i : {4, 1, 2, 0}) target.landmarks.push_back({"l" + std::to_string(i), core::LandmarkKind::kVertex, i, {}, -1, {}});
  Eigen::MatrixX3d tp = 2.0 * sp.topRows(4);
  auto pairs = core::pairLandmarks(source, sp, target, tp, "t.json");
  ASSERT_TRUE(pairs) << pairs.error().message;
  ASSERT_EQ(pairs->names, (std::vector<std::string>{"l0", "l1", "l2", "l4"}));  // source order
  EXPECT_TRUE(rigport_test::matricesNear(pairs->target.row(3), tp.row(0), 0));    // l4 was target row 0

  target.landmarks.push_back({"mystery", core::LandmarkKind::kVertex, 0, {}, -1, {}});
  auto unknown = core::pairLandmarks(source, sp, target, Eigen::MatrixX3d::Zero(5, 3), "t.json");
  ASSERT_FALSE(unknown);
  EXPECT_NE(unknown.error().message.find("'mystery'"), std::string::npos);

  target.landmarks.resize(3);
  auto few = core::pairLandmarks(source, sp, target, tp.topRows(3), "t.json");
  ASSERT_FALSE(few);
  EXPECT_NE(few.error().message.find("only 3"), std::string::npos) << few.error().message;
}

// What the warp needs of a target, checked before any work: the same errors a
// warp would give later, each naming the target.
TEST(Landmarks, WarpTargetCheckRefusesNoSurfaceTooFewNamesAndFlatLandmarks) {
  core::LandmarkSet source;
  for (int i = 0; i < 4; ++i) source.landmarks.push_back({"l" + std::to_string(i), core::LandmarkKind::kVertex, i, {}, -1, {}});
  const core::Mesh tetra = unitTetrahedron();
  const Eigen::MatrixX3d corners = tetra.positions;
  const core::TpsOptions tps;
  EXPECT_TRUE(core::checkWarpTarget(source, tetra, source, corners, "t.glb", tps));

  core::Mesh line = tetra;
  line.positions.col(1).setZero();
  line.positions.col(2).setZero();
  auto flat_mesh = core::checkWarpTarget(source, line, source, line.positions, "t.glb", tps);
  ASSERT_FALSE(flat_mesh);
  EXPECT_EQ(flat_mesh.error().code, core::ErrorCode::kInvalidMesh);
  EXPECT_EQ(flat_mesh.error().message, "t.glb: all 4 triangles have zero area (the mesh has no surface)");

  core::LandmarkSet three = source;
  three.landmarks.pop_back();
  auto few = core::checkWarpTarget(source, tetra, three, corners.topRows(3), "t.glb", tps);
  ASSERT_FALSE(few);
  EXPECT_EQ(few.error().code, core::ErrorCode::kInvalidLandmarks);
  EXPECT_NE(few.error().message.find("t.glb: only 3 landmark name(s) shared"), std::string::npos) << few.error().message;

  Eigen::MatrixX3d in_plane = corners;
  in_plane.row(3) << 0.5, 0.5, 0.0;  // all four landmarks on z = 0
  auto coplanar = core::checkWarpTarget(source, tetra, source, in_plane, "t.glb", tps);
  ASSERT_FALSE(coplanar);
  EXPECT_EQ(coplanar.error().code, core::ErrorCode::kIllConditioned);
  EXPECT_NE(coplanar.error().message.find("t.glb: landmarks are (nearly) coplanar"), std::string::npos)
      << coplanar.error().message;
}

}  // namespace
