// Tests core/correspond/correspondence.cpp and the warp job (core/correspond/warp_job.h)
// as a whole: region labels keeping close sheets apart, an affine copy and
// another head matched, faces inside out or mirrored, landmarks of another
// mesh, folds, the farthest-point sample, and the inputs refused.
#include "core/correspond/correspondence.h"

#include <cstdint>
#include <cmath>
#include <limits>
#include <random>
#include <set>

#include <gtest/gtest.h>

#include "core/synthetic/synthetic_head.h"
#include "core/correspond/warp_job.h"
#include "tests/test_support.h"

namespace {

core::Mesh transformed(const core::Mesh& m, const Eigen::Matrix3d& a, const Eigen::RowVector3d& t) {
  core::Mesh out = m;
  out.positions = (m.positions * a.transpose()).rowwise() + t;
  out.normals = core::computeVertexNormals(out.positions, out.triangles);
  return out;
}

// A fan of four triangles around vertex 0: a face carries its corners'
// labels, a vertex its own.
TEST(Correspondence, RegionLabelSetsOfFacesAndVertices) {
  Eigen::MatrixX3i triangles(4, 3);
  triangles << 0, 1, 2,  //
      0, 2, 3,           //
      0, 3, 4,           //
      0, 4, 5;
  Eigen::VectorXi regions(7);
  regions << 1, 1, 2, 2, 5, 7, 63;  // vertex 6 is on no triangle
  auto bits = [](std::initializer_list<int> labels) {
    std::uint64_t m = 0;
    for (int l : labels) m |= std::uint64_t{1} << l;
    return m;
  };
  EXPECT_EQ(core::faceRegionSets(regions, triangles),
            (std::vector<std::uint64_t>{bits({1, 2}), bits({1, 2}), bits({1, 2, 5}), bits({1, 5, 7})}));
  EXPECT_EQ(core::vertexRegionBits(regions), (std::vector<std::uint64_t>{bits({1}), bits({1}), bits({2}), bits({2}),
                                                                          bits({5}), bits({7}), bits({63})}));
}

// Two coincident-looking sheets a hair apart (like pressed lips), labelled 1
// (upper, z = 0.001) and 2 (lower, z = 0): a vertex of the lower sheet lying
// nearer the upper one goes to the upper sheet without labels, and to its
// own with them, in both directions of the matching.
TEST(Correspondence, RegionLabelsKeepCloseSheetsApart) {
  const int n = 6;
  core::Mesh sheets;
  sheets.positions.resize(2 * n * n, 3);
  sheets.triangles.resize(2 * 2 * (n - 1) * (n - 1), 3);
  sheets.regions.resize(2 * n * n);
  Eigen::Index f = 0;
  for (int s = 0; s < 2; ++s) {
    for (int i = 0; i < n; ++i) {
      for (int j = 0; j < n; ++j) {
        const int v = s * n * n + i * n + j;
        sheets.positions.row(v) << i, j, s == 0 ? 0.001 : 0.0;
        sheets.regions(v) = s == 0 ? 1 : 2;
        if (i + 1 < n && j + 1 < n) {
          sheets.triangles.row(f++) << v, v + n, v + n + 1;
          sheets.triangles.row(f++) << v, v + n + 1, v + 1;
        }
      }
    }
  }
  sheets.normals = core::computeVertexNormals(sheets.positions, sheets.triangles);
  // One query vertex: on the lower sheet's label, nearer the upper sheet.
  core::Mesh probe;
  probe.positions.resize(3, 3);
  probe.positions << 2.3, 2.4, 0.0008,  //
      2.6, 2.4, 0.0008,                 //
      2.3, 2.7, 0.0008;
  probe.triangles.resize(1, 3);
  probe.triangles << 0, 1, 2;
  probe.regions = Eigen::VectorXi::Constant(3, 2);
  probe.normals = core::computeVertexNormals(probe.positions, probe.triangles);
  auto sheet = [&](int face) { return face < 2 * (n - 1) * (n - 1) ? 1 : 2; };  // upper sheet first

  // Location of the probe's vertices on the sheets (the guide).
  core::LocateOptions locate;
  const core::MovingMeshIndex sheet_faces(sheets.positions, sheets.triangles);
  const auto plain = core::locateOnGuide(probe, sheets.positions, sheet_faces, locate);
  const auto constrained = core::locateOnGuide(probe, sheets.positions, sheet_faces, locate,
                                               core::faceRegionSets(sheets.regions, sheets.triangles),
                                               core::vertexRegionBits(probe.regions));
  for (int v = 0; v < 3; ++v) {
    EXPECT_EQ(sheet(plain.on_source[static_cast<std::size_t>(v)].face), 1) << "vertex " << v;
    EXPECT_EQ(sheet(constrained.on_source[static_cast<std::size_t>(v)].face), 2) << "vertex " << v;
  }
  // Projection of the probe's vertices onto the sheets (the target).
  const core::ClosestPointIndex plain_index(sheets.positions, sheets.triangles);
  const core::ClosestPointIndex labelled_index(sheets.positions, sheets.triangles,
                                               core::faceRegionSets(sheets.regions, sheets.triangles));
  core::ProjectionOptions projection;
  const auto projected = core::projectToTarget(probe.positions, probe.normals, plain_index, 10.0, projection);
  const auto kept = core::projectToTarget(probe.positions, probe.normals, labelled_index, 10.0, projection,
                                          core::vertexRegionBits(probe.regions));
  for (int v = 0; v < 3; ++v) {
    EXPECT_EQ(sheet(projected.on_target[static_cast<std::size_t>(v)].face), 1) << "vertex " << v;
    EXPECT_EQ(sheet(kept.on_target[static_cast<std::size_t>(v)].face), 2) << "vertex " << v;
    EXPECT_NEAR(kept.positions(v, 2), 0.0, 1e-12);
  }
}

TEST(Correspondence, AffineCopyGivesAnExactGuideAndNoFolds) {
  const auto head = core::generateHead(core::HeadShape{}, core::HeadResolution{64, 56});
  Eigen::Matrix3d a;
  a << 1.2, 0.05, 0.0, -0.03, 0.9, 0.02, 0.0, 0.04, 1.1;
  const core::Mesh target = transformed(head.mesh, a, Eigen::RowVector3d(0.1, -0.2, 0.3));
  auto prepared = core::prepareSource(head.mesh, head.landmarks, "head");
  ASSERT_TRUE(prepared) << prepared.error().message;
  // face + barycentric landmarks resolve identically on the transformed copy
  auto result = core::runWarp(*prepared, target, head.landmarks, "copy");
  ASSERT_TRUE(result) << result.error().message;
  const double diag = result->report.target_diagonal;
  EXPECT_TRUE(rigport_test::matricesNear(result->guide.positions, target.positions, 1e-6 * diag));
  EXPECT_EQ(result->report.flipped_triangles, 0);
  EXPECT_EQ(result->report.unmatched_source_vertices, 0);
  EXPECT_LE(result->report.landmark_rms_residual, 1e-9 * diag);
  EXPECT_TRUE(result->report.suspicious_landmarks.empty());
  // Every target vertex is found on the guide at its own source vertex.
  for (Eigen::Index v = 0; v < target.vertexCount(); v += 97) {
    const auto& loc = result->locations.on_source[static_cast<std::size_t>(v)];
    ASSERT_TRUE(loc.found());
    Eigen::RowVector3d p = Eigen::RowVector3d::Zero();
    for (int k = 0; k < 3; ++k) p += loc.barycentric(k) * head.mesh.positions.row(head.mesh.triangles(loc.face, k));
    EXPECT_LT((p - head.mesh.positions.row(v)).norm(), 1e-6) << "vertex " << v;
    EXPECT_GT(result->locations.confidence(v), 0.99);
  }
}

TEST(Correspondence, OtherIdentityAndTopologyLandsOnTheTarget) {
  const auto source = core::generateHead();
  core::HeadResolution res;
  res.columns = 80;
  res.rows = 76;
  res.alternate_diagonals = true;
  res.jitter = 0.3;
  res.seed = 5;
  const auto target = core::generateHead(core::randomHeadShape(5, 0.2), res);
  auto prepared = core::prepareSource(source.mesh, source.landmarks, "source");
  ASSERT_TRUE(prepared);
  auto result = core::runWarp(*prepared, target.mesh, target.landmarks, "target");
  ASSERT_TRUE(result) << result.error().message;
  const auto& r = result->report;
  EXPECT_LE(r.landmark_rms_residual, 1e-9 * r.target_diagonal);
  EXPECT_LE(r.p95_distance, 0.005 * r.target_diagonal);
  EXPECT_LT(r.low_confidence_vertices, target.mesh.vertexCount() / 20);
  for (Eigen::Index v = 0; v < result->guide.positions.rows(); ++v) ASSERT_TRUE(result->guide.positions.row(v).allFinite());
}

// The same head with every face's corners 1 and 2 swapped (faces inside
// out, as some exporters write them), its normals turned to match and its
// face landmarks' barycentrics following their corners.
core::SyntheticHead reversedWinding(core::SyntheticHead head) {
  head.mesh.triangles.col(1).swap(head.mesh.triangles.col(2));
  head.mesh.normals = -head.mesh.normals;
  for (core::Landmark& l : head.landmarks.landmarks) std::swap(l.barycentric(1), l.barycentric(2));
  return head;
}

TEST(Correspondence, TargetWithReversedWindingIsMatchedAsIfTurned) {
  const auto source = core::generateHead();
  const auto target =
      core::generateHead(core::randomHeadShape(5, 0.2), core::HeadResolution{.columns = 80, .rows = 76, .alternate_diagonals = true, .jitter = 0.3, .seed = 5});
  auto prepared = core::prepareSource(source.mesh, source.landmarks, "source");
  ASSERT_TRUE(prepared);
  auto plain = core::runWarp(*prepared, target.mesh, target.landmarks, "target.glb");
  const auto inside_out = reversedWinding(target);
  auto reversed = core::runWarp(*prepared, inside_out.mesh, inside_out.landmarks, "inside_out.glb");
  ASSERT_TRUE(plain && reversed);
  EXPECT_GT(plain->report.orientation_agreement, 0.8);
  EXPECT_FALSE(plain->report.target_turned);
  EXPECT_TRUE(plain->report.warnings.empty());
  // Closest faces do not depend on the winding; their normals' signs do.
  EXPECT_EQ(reversed->report.orientation_agreement, -plain->report.orientation_agreement);
  EXPECT_TRUE(reversed->report.target_turned);
  ASSERT_EQ(reversed->report.warnings.size(), 1u);
  EXPECT_NE(reversed->report.warnings[0].find("inside_out.glb: its faces face the opposite way"), std::string::npos)
      << reversed->report.warnings[0];
  // Matched as if the faces were turned: the same guide and locations (up to
  // the rounding of swapped corners, which the sliding's float products carry
  // to ~1e-9), where unturned matching would reject
  // nearly every face by its normal.
  const double diag = plain->report.target_diagonal;
  EXPECT_TRUE(rigport_test::matricesNear(reversed->guide.positions, plain->guide.positions, 1e-9 * diag));
  EXPECT_EQ(reversed->report.low_confidence_vertices, plain->report.low_confidence_vertices);
  EXPECT_LT(plain->report.low_confidence_vertices, target.mesh.vertexCount() / 20);
  EXPECT_TRUE(rigport_test::matricesNear(reversed->locations.confidence, plain->locations.confidence, 1e-8));
}

TEST(Correspondence, MirroringWarpAndInconsistentWindingAreWarned) {
  const auto source = core::generateHead();
  auto prepared = core::prepareSource(source.mesh, source.landmarks, "source");
  ASSERT_TRUE(prepared);
  auto contains = [](const std::vector<std::string>& warnings, const std::string& text) {
    for (const auto& w : warnings) {
      if (w.find(text) != std::string::npos) return true;
    }
    return false;
  };
  // A mirror image with the landmarks on the same vertices: left and right
  // names swapped, as far as the warp can tell.
  const core::Mesh mirrored = transformed(source.mesh, Eigen::Vector3d(-1, 1, 1).asDiagonal(), Eigen::RowVector3d::Zero());
  auto m = core::runWarp(*prepared, mirrored, source.landmarks, "mirror.glb");
  ASSERT_TRUE(m) << m.error().message;
  EXPECT_TRUE(contains(m->report.warnings, "the landmark warp mirrors the source onto mirror.glb"));
  EXPECT_FALSE(m->report.landmarks_misfit);  // a mirror image fits its mirrored landmarks
  EXPECT_LT(m->report.landmark_misfit_deg, 1e-6);
  // Every other face inside out: no orientation to turn to.
  core::Mesh mixed = source.mesh;
  for (Eigen::Index f = 0; f < mixed.triangleCount(); f += 2) mixed.triangles.row(f) = mixed.triangles.row(f).reverse().eval();
  auto x = core::runWarp(*prepared, mixed, source.landmarks, "mixed.glb");
  ASSERT_TRUE(x) << x.error().message;
  EXPECT_LT(std::abs(x->report.orientation_agreement), 0.5);
  EXPECT_TRUE(contains(x->report.warnings, "mixed.glb: its face orientation is inconsistent"));
  EXPECT_FALSE(contains(x->report.warnings, "mirrors"));
}

// Landmarks of another mesh, their indices in range (another vertex order):
// they land anywhere on the target. The warning names them, not the mesh's
// winding or size, which their warp would otherwise be taken for.
TEST(Correspondence, LandmarksOfAnotherMeshAreNamedNotTheWinding) {
  const auto source = core::generateHead();
  auto prepared = core::prepareSource(source.mesh, source.landmarks, "source");
  ASSERT_TRUE(prepared);
  const core::HeadResolution res{.columns = 70, .rows = 66, .alternate_diagonals = true, .jitter = 0.25, .seed = 9};
  const auto other = core::generateHead(core::randomHeadShape(9, 0.2), res);
  auto own = core::runWarp(*prepared, other.mesh, other.landmarks, "other.glb");
  ASSERT_TRUE(own) << own.error().message;
  EXPECT_FALSE(own->report.landmarks_misfit);
  EXPECT_GT(own->report.landmark_misfit_deg, 0.5);
  EXPECT_LT(own->report.landmark_misfit_deg, 15.0);
  // The source's landmarks (faces of its own topology) given to the other head.
  core::LandmarkSet foreign = source.landmarks;
  for (auto& l : foreign.landmarks) l.face %= static_cast<int>(other.mesh.triangleCount());
  auto wrong = core::runWarp(*prepared, other.mesh, foreign, "other.glb");
  ASSERT_TRUE(wrong) << wrong.error().message;
  EXPECT_TRUE(wrong->report.landmarks_misfit);
  EXPECT_GT(wrong->report.landmark_misfit_deg, 30.0);
  ASSERT_FALSE(wrong->report.warnings.empty());
  EXPECT_EQ(wrong->report.warnings[0].rfind("other.glb: its landmarks do not lie as the source's do on any face", 0), 0u)
      << wrong->report.warnings[0];
  for (const std::string& w : wrong->report.warnings) {
    EXPECT_EQ(w.find("orientation"), std::string::npos) << w;
    EXPECT_EQ(w.find("face the opposite way"), std::string::npos) << w;
  }
  EXPECT_FALSE(wrong->report.target_turned);
}

TEST(Correspondence, AnUnpreparedSourceIsAnErrorNotACrash) {
  const auto head = core::generateHead();
  const core::PreparedSource unprepared;  // as a default-constructed cache slot would be
  auto result = core::runWarp(unprepared, head.mesh, head.landmarks, "head.glb");
  ASSERT_FALSE(result);
  EXPECT_EQ(result.error().code, core::ErrorCode::kInvalidArgument);
  EXPECT_NE(result.error().message.find("prepareSource"), std::string::npos) << result.error().message;
}

TEST(Correspondence, RefinementBringsTheSurfaceCloserThanThePlainWarp) {
  const auto source = core::generateHead();
  const auto target = core::generateHead(core::randomHeadShape(11, 0.25), core::HeadResolution{90, 80, true, 0.2, 11});
  auto prepared = core::prepareSource(source.mesh, source.landmarks, "source");
  ASSERT_TRUE(prepared);
  core::WarpOptions plain;
  plain.refine_iterations = 0;
  plain.local_rounds = 0;
  auto a = core::runWarp(*prepared, target.mesh, target.landmarks, "t", plain);
  auto b = core::runWarp(*prepared, target.mesh, target.landmarks, "t");
  ASSERT_TRUE(a && b);
  EXPECT_LT(b->report.mean_distance, a->report.mean_distance);
  EXPECT_EQ(b->report.refine_iterations, core::WarpOptions{}.refine_iterations);
}

TEST(Correspondence, FoldsAreCounted) {
  const auto head = core::generateHead(core::HeadShape{}, core::HeadResolution{16, 16});
  Eigen::MatrixX3d crumpled = head.mesh.positions;
  // Mirror one triangle's corner through its opposite edge: that triangle flips.
  const Eigen::Vector3i t = head.mesh.triangles.row(100);
  const Eigen::RowVector3d mid = 0.5 * (crumpled.row(t(1)) + crumpled.row(t(2)));
  crumpled.row(t(0)) = 2 * mid - crumpled.row(t(0));
  const auto folds = core::countFolds(head.mesh.positions, crumpled, head.mesh.triangles);
  EXPECT_GE(folds.flipped, 1);
  EXPECT_EQ(core::countFolds(head.mesh.positions, head.mesh.positions, head.mesh.triangles).flipped, 0);
}

TEST(Correspondence, FarthestPointSampleIsSpreadAndDeterministic) {
  const auto head = core::generateHead(core::HeadShape{}, core::HeadResolution{32, 32});
  const auto a = core::farthestPointSample(head.mesh.positions, 50);
  const auto b = core::farthestPointSample(head.mesh.positions, 50);
  EXPECT_EQ(a, b);
  std::set<int> unique(a.begin(), a.end());
  EXPECT_EQ(unique.size(), 50u);
}

// The plain O(n k) farthest-point loop the bucketed sample must reproduce,
// ties (first vertex among equal distances) included.
std::vector<int> farthestPointSampleByScan(const Eigen::MatrixX3d& positions, int count) {
  const Eigen::Index n = positions.rows();
  std::vector<int> chosen;
  const Eigen::RowVector3d centroid = positions.colwise().mean();
  Eigen::Index next = 0;
  (positions.rowwise() - centroid).rowwise().squaredNorm().minCoeff(&next);
  std::vector<double> sq(static_cast<std::size_t>(n), std::numeric_limits<double>::infinity());
  for (int k = 0; k < std::min<Eigen::Index>(count, n); ++k) {
    chosen.push_back(static_cast<int>(next));
    const Eigen::RowVector3d p = positions.row(next);
    double best = -1.0;
    for (Eigen::Index v = 0; v < n; ++v) {
      const double dx = positions(v, 0) - p(0), dy = positions(v, 1) - p(1), dz = positions(v, 2) - p(2);
      const double d = dx * dx + dy * dy + dz * dz;
      auto& s = sq[static_cast<std::size_t>(v)];
      s = d < s ? d : s;
      if (s > best) {
        best = s;
        next = v;
      }
    }
  }
  return chosen;
}

TEST(Correspondence, FarthestPointSampleMatchesThePlainScan) {
  const auto head = core::generateHead(core::HeadShape{}, core::HeadResolution{48, 48});
  EXPECT_EQ(core::farthestPointSample(head.mesh.positions, 465), farthestPointSampleByScan(head.mesh.positions, 465));
  // Integer lattice points: many exactly equal distances, so ties decide.
  Eigen::MatrixX3d lattice(9 * 7 * 5, 3);
  int row = 0;
  for (int i = 0; i < 9; ++i)
    for (int j = 0; j < 7; ++j)
      for (int k = 0; k < 5; ++k) lattice.row(row++) << i, j, k;
  EXPECT_EQ(core::farthestPointSample(lattice, 315), farthestPointSampleByScan(lattice, 315));
  // Flat (all z equal), with duplicated points, and scattered at random.
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-10.0, 10.0);
  Eigen::MatrixX3d flat(400, 3);
  for (Eigen::Index v = 0; v < flat.rows(); ++v) flat.row(v) << u(rng), u(rng), 2.0;
  flat.bottomRows(50) = flat.topRows(50);
  EXPECT_EQ(core::farthestPointSample(flat, 400), farthestPointSampleByScan(flat, 400));
  Eigen::MatrixX3d cloud(3000, 3);
  for (Eigen::Index v = 0; v < cloud.rows(); ++v) cloud.row(v) << u(rng), 0.1 * u(rng), u(rng) * u(rng);
  EXPECT_EQ(core::farthestPointSample(cloud, 700), farthestPointSampleByScan(cloud, 700));
}

TEST(Correspondence, RejectsPointCloudTargetsAndBadLandmarks) {
  const auto head = core::generateHead(core::HeadShape{}, core::HeadResolution{32, 32});
  auto prepared = core::prepareSource(head.mesh, head.landmarks, "source");
  ASSERT_TRUE(prepared);
  core::Mesh cloud;
  cloud.positions = head.mesh.positions;
  auto r = core::runWarp(*prepared, cloud, head.landmarks, "cloud.ply");
  ASSERT_FALSE(r);
  EXPECT_NE(r.error().message.find("cloud.ply"), std::string::npos);

  core::LandmarkSet coplanar;
  for (const char* n : {"jaw_00", "jaw_16", "eye_left_0", "eye_right_0", "nose_bridge_3"}) {
    core::Landmark lm;
    lm.name = n;
    lm.kind = core::LandmarkKind::kPosition;
    coplanar.landmarks.push_back(lm);
  }
  // Positions: all on the plane z = const, so the target set is flat.
  core::Mesh flat = head.mesh;
  flat.positions.col(2).setConstant(0.0);
  for (auto& lm : coplanar.landmarks) lm.position = flat.positions.row(0).transpose();
  auto c = core::runWarp(*prepared, flat, coplanar, "flat");
  ASSERT_FALSE(c);
}

}  // namespace
