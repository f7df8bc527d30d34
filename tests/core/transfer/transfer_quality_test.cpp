#include "core/transfer/transfer_quality.h"

#include <gtest/gtest.h>

#include "core/io/rig_io.h"
#include "core/synthetic/synthetic_rig.h"
#include "core/transfer/transfer.h"
#include "tests/test_support.h"

namespace {

core::QualitySource qualitySource(const core::PreparedRig& source) {
  return {source.surface.mesh.triangles, source.surface.adjacency, source.surface.vertex_sides, source.rig.morph_targets};
}

// The output's jawOpen with one lower-lip vertex's delta swapped with the
// nearest upper-lip vertex's (a lip vertex left behind: a fang, and its twin).
TEST(TransferQuality, AVertexGivenTheOtherLipsDeltaIsCaughtAndNamed) {
  const core::SyntheticRig& target = rigport_test::saggingMouthTarget();
  core::Mesh scan = target.rig.mesh;
  scan.regions.resize(0);
  auto result = core::transferRig(rigport_test::preparedTouchingLipsSource(), scan, rigport_test::tenLandmarks(target), "target");
  ASSERT_TRUE(result) << result.error().message;
  ASSERT_TRUE(result->report.quality.clean()) << result->report.quality.summary();
  EXPECT_EQ(result->report.quality.per_vertex.size(), scan.vertexCount());

  std::vector<core::MorphTarget> shapes = result->rig.morph_targets;
  ASSERT_EQ(shapes[0].name, "jawOpen");
  Eigen::MatrixX3d& jaw = shapes[0].position_deltas;
  const Eigen::VectorXi& truth = target.rig.attributes.labels.at("REGION");
  // The lower-lip vertex that moves most, and the upper-lip vertex nearest it.
  Eigen::Index lower = -1, upper = -1;
  for (Eigen::Index v = 0; v < truth.size(); ++v) {
    if (truth(v) == core::kRegionLowerLip && (lower < 0 || jaw.row(v).norm() > jaw.row(lower).norm())) lower = v;
  }
  ASSERT_GE(lower, 0);
  for (Eigen::Index v = 0; v < truth.size(); ++v) {
    const double d = (scan.positions.row(v) - scan.positions.row(lower)).norm();
    if (truth(v) == core::kRegionUpperLip && (upper < 0 || d < (scan.positions.row(upper) - scan.positions.row(lower)).norm())) upper = v;
  }
  ASSERT_GE(upper, 0);
  jaw.row(lower).swap(jaw.row(upper));

  auto warp = core::runWarp(rigport_test::preparedTouchingLipsSource().surface, scan, rigport_test::tenLandmarks(target), "target");
  ASSERT_TRUE(warp) << warp.error().message;
  const core::QualityReport report = core::checkTransferQuality(scan, warp->target.adjacency, shapes, warp->locations,
                                                                warp->target_sides, qualitySource(rigport_test::preparedTouchingLipsSource()));
  EXPECT_FALSE(report.clean());
  ASSERT_EQ(report.shapes.size(), 1u);
  EXPECT_EQ(report.shapes[0].shape, "jawOpen");
  EXPECT_EQ(report.shapes[0].vertices, 2);
  EXPECT_EQ(report.shape_outliers, 2);
  EXPECT_GT(report.shapes[0].worst, 0.7);
  EXPECT_EQ(report.per_vertex(lower), 1.0);
  EXPECT_EQ(report.per_vertex(upper), 1.0);
  ASSERT_FALSE(report.worst.empty());
  EXPECT_TRUE(report.worst[0].vertex == lower || report.worst[0].vertex == upper);
  EXPECT_EQ(report.summary(), "jawOpen (2 vertices)");
}

// A crease the rig's own shape has is not the transfer's fault: a source
// vertex moving as none of its ring does, carried onto a copy of the source,
// is judged against the source.
TEST(TransferQuality, TheRigsOwnCreaseIsNotBlamedOnTheTransfer) {
  core::Rig rig = rigport_test::touchingLipsSource().rig;
  Eigen::MatrixX3d& jaw = rig.morph_targets[0].position_deltas;
  const Eigen::Index spike = 1000;
  jaw.row(spike) = Eigen::RowVector3d(0.0, 0.02, 0.0);  // up, where the skin around does not move
  auto prepared = core::prepareRig(rig, rigport_test::touchingLipsSource().landmarks, "creased");
  ASSERT_TRUE(prepared) << prepared.error().message;
  auto copy = core::transferRig(*prepared, rig.mesh, rigport_test::touchingLipsSource().landmarks, "copy");
  ASSERT_TRUE(copy) << copy.error().message;
  EXPECT_NEAR(copy->rig.morph_targets[0].position_deltas(spike, 1), 0.02, 1e-6);
  EXPECT_TRUE(copy->report.quality.clean()) << copy->report.quality.summary();
  // Judged without the source's shapes, the same output is an outlier.
  const std::vector<core::MorphTarget> none;
  const core::QualitySource blind{prepared->surface.mesh.triangles, prepared->surface.adjacency,
                                  prepared->surface.vertex_sides, none};
  EXPECT_EQ(core::checkTransferQuality(rig.mesh, prepared->surface.adjacency, copy->rig.morph_targets, {}, {}, blind).summary(),
            "jawOpen (1 vertex)");
}

// A target vertex on one side of an opening located on the other side's
// faces is a crossing.
TEST(TransferQuality, ALocationAcrossAnOpeningIsACrossing) {
  const core::PreparedRig& source = rigport_test::preparedTouchingLipsSource();
  const core::Mesh& mesh = source.surface.mesh;
  const std::vector<int>& sides = source.surface.vertex_sides;
  // A copy of the source located on itself, vertex by vertex.
  core::TargetLocations at;
  at.on_source.resize(static_cast<std::size_t>(mesh.vertexCount()));
  std::vector<int> face_of(static_cast<std::size_t>(mesh.vertexCount()), -1);
  for (Eigen::Index f = 0; f < mesh.triangleCount(); ++f) {
    for (int k = 0; k < 3; ++k) face_of[static_cast<std::size_t>(mesh.triangles(f, k))] = static_cast<int>(f);
  }
  for (Eigen::Index v = 0; v < mesh.vertexCount(); ++v) {
    core::SurfacePoint& sp = at.on_source[static_cast<std::size_t>(v)];
    sp.face = face_of[static_cast<std::size_t>(v)];
    for (int k = 0; k < 3; ++k) sp.barycentric(k) = mesh.triangles(sp.face, k) == v ? 1.0 : 0.0;
  }
  EXPECT_EQ(core::checkTransferQuality(mesh, source.surface.adjacency, {}, at, sides, qualitySource(source)).crossed_vertices, 0);
  // One vertex of one side put on a face whose corners are all on the other.
  Eigen::Index moved = -1, onto = -1;
  for (Eigen::Index v = 0; v < mesh.vertexCount() && moved < 0; ++v) {
    if (sides[static_cast<std::size_t>(v)] < 0) continue;
    for (Eigen::Index f = 0; f < mesh.triangleCount() && onto < 0; ++f) {
      bool across = true;
      for (int k = 0; k < 3; ++k) across &= core::oppositeSides(sides[static_cast<std::size_t>(v)], sides[static_cast<std::size_t>(mesh.triangles(f, k))]);
      if (across) onto = f;
    }
    if (onto >= 0) moved = v;
  }
  ASSERT_GE(moved, 0);
  at.on_source[static_cast<std::size_t>(moved)].face = static_cast<int>(onto);
  const core::QualityReport report =
      core::checkTransferQuality(mesh, source.surface.adjacency, {}, at, sides, qualitySource(source));
  EXPECT_EQ(report.crossed_vertices, 1);
  EXPECT_EQ(report.per_vertex(moved), 1.0);
  EXPECT_EQ(report.summary(), "1 vertex located across an opening (the other lip or lid)");
}

// strict: the same transfer matched without the sides and the repair (so
// that lips cross) fails, naming the shapes; without strict it succeeds and
// says so in its warnings.
TEST(TransferQuality, StrictFailsATransferThatFailsItsCheck) {
  const core::SyntheticRig& target = rigport_test::saggingMouthTarget();
  core::Mesh scan = target.rig.mesh;
  scan.regions.resize(0);
  core::TransferOptions crossing;
  crossing.warp.side_matching = false;
  crossing.repair_unsure = false;
  crossing.diagnostic_attributes = true;
  auto warned = core::transferRig(rigport_test::preparedTouchingLipsSource(), scan, rigport_test::tenLandmarks(target), "sag.glb", crossing);
  ASSERT_TRUE(warned) << warned.error().message;
  ASSERT_FALSE(warned->report.quality.clean());
  // The output carries the check per vertex (_QUALITY), and is valid glTF.
  const Eigen::MatrixXd& quality = warned->rig.attributes.fields.at("QUALITY");
  ASSERT_EQ(quality.rows(), scan.vertexCount());
  EXPECT_EQ(quality.sum(), warned->report.quality.crossed_vertices + warned->report.quality.shape_outliers);
  const auto dir = rigport_test::makeTempDir("quality");
  ASSERT_TRUE(core::writeRigGlb(warned->rig, dir / "sag.glb"));
  EXPECT_GLTF_VALID(dir / "sag.glb");
  const std::string summary = warned->report.quality.summary();
  EXPECT_NE(summary.find("located across an opening (the other lip or lid), moving in jawOpen ("), std::string::npos)
      << summary;
  EXPECT_EQ(warned->report.warnings.back(), "sag.glb: unsure vertices, check them before use: " + summary);

  crossing.strict = true;
  auto failed = core::transferRig(rigport_test::preparedTouchingLipsSource(), scan, rigport_test::tenLandmarks(target), "sag.glb", crossing);
  ASSERT_FALSE(failed);
  EXPECT_EQ(failed.error().code, core::ErrorCode::kQualityGate);
  EXPECT_EQ(failed.error().message, "sag.glb: the transfer failed its quality check (strict): " + summary);

  // With the sides (and the repair) the same target passes strict.
  core::TransferOptions strict;
  strict.strict = true;
  EXPECT_TRUE(core::transferRig(rigport_test::preparedTouchingLipsSource(), scan, rigport_test::tenLandmarks(target), "sag.glb", strict));
}

}  // namespace
