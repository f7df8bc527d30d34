#include "core/correspond/correspondence.h"

#include <cstdint>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numeric>
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

// The synthetic head with its neck drawn out (everything below the chin
// stretched down): the face landmarks say nothing about it, and projection
// cannot pull the warped neck along the tube, so without rims the source's
// neck cut stops short of the target's and the rim region goes unmatched.
TEST(Correspondence, MatchedRimsPullTheNeckCutOntoTheTargets) {
  const auto source = core::generateHead();
  core::SyntheticHead target = core::generateHead(core::randomHeadShape(7, 0.1), core::HeadResolution{88, 70, true, 0.2, 7});
  const double chin = target.mesh.positions.col(1).minCoeff() * 0.55;
  for (Eigen::Index v = 0; v < target.mesh.positions.rows(); ++v) {
    const double y = target.mesh.positions(v, 1);
    if (y < chin) target.mesh.positions(v, 1) = chin + 1.6 * (y - chin);
  }
  target.mesh.normals = core::computeVertexNormals(target.mesh.positions, target.mesh.triangles);
  auto prepared = core::prepareSource(source.mesh, source.landmarks, "source");
  ASSERT_TRUE(prepared);
  ASSERT_FALSE(prepared->rims.empty());
  core::WarpOptions without;
  without.rim_matching = false;
  auto off = core::runWarp(*prepared, target.mesh, target.landmarks, "long_neck", without);
  auto on = core::runWarp(*prepared, target.mesh, target.landmarks, "long_neck");
  ASSERT_TRUE(off && on);
  EXPECT_EQ(off->report.matched_rims, 0);
  EXPECT_GE(on->report.matched_rims, 1);
  // Mean distance of the guide's outer-rim vertices (the source's longest
  // rim: neck cut and back opening) to the target's outer rim.
  const std::vector<core::Rim> target_rims =
      core::meshRims(target.mesh, core::coincidentVertexRepresentatives(target.mesh.positions));
  auto rimGap = [&](const core::WarpResult& r) {
    double sum = 0.0;
    for (int v : prepared->rims[0].vertices) {
      sum += std::sqrt(core::closestPointOnRim(r.guide.positions.row(v).transpose(),
                                               (prepared->rim_vertices.tangent.row(v) * r.landmark_warp.affine().topRows<3>()).transpose(),
                                               target_rims[0], target.mesh.positions)
                           .sq_distance);
    }
    return sum / static_cast<double>(prepared->rims[0].vertices.size());
  };
  const double gap_off = rimGap(*off), gap_on = rimGap(*on);
  std::printf("[ long neck ] outer rim gap %.4f -> %.4f (diagonal %.3f), low-confidence vertices %d -> %d\n", gap_off,
              gap_on, on->report.target_diagonal, off->report.low_confidence_vertices, on->report.low_confidence_vertices);
  EXPECT_LT(gap_on, 0.5 * gap_off);
  EXPECT_LT(on->report.low_confidence_vertices, off->report.low_confidence_vertices);
}

// Same topology: target vertex v's true source point is source vertex v.
// The mean distance of the located points of `vertices` from theirs; a
// vertex located nowhere counts `miss`.
double meanDistanceFromTrueSource(const core::WarpResult& r, const core::Mesh& source,
                                  const std::vector<Eigen::Index>& vertices, double miss) {
  double sum = 0.0;
  for (Eigen::Index v : vertices) {
    const core::SurfacePoint& at = r.locations.on_source[static_cast<std::size_t>(v)];
    if (!at.found()) {
      sum += miss;
      continue;
    }
    Eigen::RowVector3d p = Eigen::RowVector3d::Zero();
    for (int c = 0; c < 3; ++c) p += at.barycentric(c) * source.positions.row(source.triangles(at.face, c));
    sum += (p - source.positions.row(v)).norm();
  }
  return sum / static_cast<double>(vertices.size());
}

// The generated head bent by a smooth space warp (same topology), and the 10
// landmarks a sparse target would name (eye and mouth corners, nose tip and
// wings, chin); `others` gets the indices of the rest.
core::SyntheticHead bentHead(const core::SyntheticHead& source) {
  const double h = source.mesh.positions.col(1).maxCoeff() - source.mesh.positions.col(1).minCoeff();
  core::SyntheticHead target = source;
  for (Eigen::Index v = 0; v < target.mesh.positions.rows(); ++v) {
    const double y = target.mesh.positions(v, 1) / h, x = target.mesh.positions(v, 0) / h;
    target.mesh.positions(v, 2) *= 1.0 + 0.4 * y * y;
    target.mesh.positions(v, 1) += 0.06 * h * std::sin(5.0 * x);
  }
  target.mesh.normals = core::computeVertexNormals(target.mesh.positions, target.mesh.triangles);
  return target;
}

core::LandmarkSet sparseLandmarks(const core::LandmarkSet& all, std::vector<Eigen::Index>* others = nullptr) {
  const std::set<std::string> named = {"eye_right_0", "eye_right_3", "eye_left_0", "eye_left_3", "nose_bridge_3",
                                       "nose_base_0", "nose_base_4", "mouth_outer_0", "mouth_outer_6", "jaw_08"};
  core::LandmarkSet sparse;
  for (std::size_t l = 0; l < all.landmarks.size(); ++l) {
    if (named.count(all.landmarks[l].name)) {
      sparse.landmarks.push_back(all.landmarks[l]);
    } else if (others) {
      others->push_back(static_cast<Eigen::Index>(l));
    }
  }
  return sparse;
}

// The generated head with its lips pushed out along the normals by a
// Gaussian bump (amplitude and width relative to the head height) well beyond
// what the landmarks say, as on an exaggerated identity. Same topology:
// target vertex v is source vertex v; `lips` gets the vertices within two
// widths of the mouth's centre.
core::SyntheticHead fullerLips(const core::SyntheticHead& source, double amplitude, double width,
                               std::vector<Eigen::Index>& lips) {
  const double h = source.mesh.positions.col(1).maxCoeff() - source.mesh.positions.col(1).minCoeff();
  auto landmarks = core::resolveLandmarks(source.landmarks, source.mesh, "source");
  EXPECT_TRUE(landmarks);
  const Eigen::RowVector3d mouth = 0.5 * (landmarks->row(source.landmarks.indexOf("mouth_outer_3")) +
                                          landmarks->row(source.landmarks.indexOf("mouth_outer_9")));
  core::SyntheticHead target = source;
  const double sigma = width * h;
  for (Eigen::Index v = 0; v < source.mesh.vertexCount(); ++v) {
    const double r2 = (source.mesh.positions.row(v) - mouth).squaredNorm() / (sigma * sigma);
    if (r2 > 9.0) continue;
    target.mesh.positions.row(v) += amplitude * h * std::exp(-0.5 * r2) * source.mesh.normals.row(v);
    if (r2 < 4.0) lips.push_back(v);
  }
  target.mesh.normals = core::computeVertexNormals(target.mesh.positions, target.mesh.triangles);
  return target;
}

// The target warped with a WarpOptions switch off, and with the defaults (on).
struct OffAndOn {
  core::Result<core::WarpResult> off, on;
};
OffAndOn warpOffAndOn(bool core::WarpOptions::*member, const core::SyntheticHead& source, const core::Mesh& target,
                      const core::LandmarkSet& landmarks) {
  auto prepared = core::prepareSource(source.mesh, source.landmarks, "source");
  if (!prepared) return {prepared.error(), prepared.error()};
  core::WarpOptions off;
  off.*member = false;
  return {core::runWarp(*prepared, target, landmarks, "off", off), core::runWarp(*prepared, target, landmarks, "on")};
}

// Projection from the warped source lands on the front of the fuller lips
// and never reaches the parts of the target it does not already cover; the
// target's own vertices pulling the surface do.
TEST(Correspondence, TargetPullsReachWhatProjectionDoesNot) {
  const auto source = core::generateHead();
  std::vector<Eigen::Index> lips;
  const core::SyntheticHead target = fullerLips(source, 0.06, 0.05, lips);
  auto [off, on] = warpOffAndOn(&core::WarpOptions::target_pulls, source, target.mesh, target.landmarks);
  ASSERT_TRUE(off && on);
  EXPECT_EQ(off->report.target_pulls, 0);
  // About a quarter of the vertices are sampled; nearly all of them match.
  EXPECT_GT(on->report.target_pulls, target.mesh.vertexCount() / 6);
  const double h = source.mesh.positions.col(1).maxCoeff() - source.mesh.positions.col(1).minCoeff();
  const double error_off = meanDistanceFromTrueSource(*off, source.mesh, lips, h);
  const double error_on = meanDistanceFromTrueSource(*on, source.mesh, lips, h);
  std::printf("[ fuller lips ] %zu vertices, mean distance from their true source point %.5f -> %.5f (head height "
              "%.3f, %d target pulls)\n", lips.size(), error_off, error_on, h, on->report.target_pulls);
  EXPECT_LT(error_on, 0.9 * error_off);
}

// Where projection crowds the guide's vertices (around much fuller lips,
// matched with 10 landmarks), its triangles fold and locations on them
// scatter; on the smoothed guide the lips land closer to their true points.
TEST(Correspondence, SmoothedGuideLocatesCloserThanTheGuide) {
  const auto source = core::generateHead();
  std::vector<Eigen::Index> lips;
  const core::SyntheticHead target = fullerLips(source, 0.10, 0.03, lips);
  auto [off, on] =
      warpOffAndOn(&core::WarpOptions::smooth_guide, source, target.mesh, sparseLandmarks(target.landmarks));
  ASSERT_TRUE(off && on);
  EXPECT_TRUE(off->guide.positions == on->guide.positions);  // the guide itself is the same
  const double h = source.mesh.positions.col(1).maxCoeff() - source.mesh.positions.col(1).minCoeff();
  const double error_off = meanDistanceFromTrueSource(*off, source.mesh, lips, h);
  const double error_on = meanDistanceFromTrueSource(*on, source.mesh, lips, h);
  std::printf("[ much fuller lips, 10 landmarks ] %zu vertices located on the guide / the smoothed guide: mean "
              "distance from their true source point %.5f -> %.5f\n", lips.size(), error_off, error_on);
  EXPECT_LT(error_on, 0.95 * error_off);
}

// A transfer projects only the guide vertices it reads (the projection
// sample and the dense centres' vertices); where the target is located, the
// dense map and the vertices projected are exactly those of the full guide.
TEST(Correspondence, APartialGuideLocatesExactlyAsTheFullOne) {
  const auto source = core::generateHead();
  std::vector<Eigen::Index> lips;
  const core::SyntheticHead target = fullerLips(source, 0.06, 0.05, lips);
  auto [partial, full] = warpOffAndOn(&core::WarpOptions::full_guide, source, target.mesh, target.landmarks);
  ASSERT_TRUE(partial && full);
  const Eigen::Index nv = source.mesh.vertexCount();
  EXPECT_EQ(full->report.projected_source_vertices, nv);
  EXPECT_GT(partial->report.projected_source_vertices, 0);
  EXPECT_LT(partial->report.projected_source_vertices, nv / 2);
  int projected = 0;
  for (Eigen::Index v = 0; v < nv; ++v) {
    if (partial->guide.on_target[static_cast<std::size_t>(v)].found()) {
      ++projected;
      EXPECT_EQ(partial->guide.positions.row(v), full->guide.positions.row(v)) << "source vertex " << v;
    } else {
      EXPECT_EQ(partial->guide.positions.row(v), partial->warped_positions.row(v)) << "source vertex " << v;
    }
  }
  EXPECT_EQ(projected + partial->report.unmatched_source_vertices, partial->report.projected_source_vertices);
  ASSERT_TRUE(partial->dense_map && full->dense_map);
  EXPECT_EQ(partial->dense_map->apply(source.mesh.positions), full->dense_map->apply(source.mesh.positions));
  const core::TargetLocations& a = partial->locations;
  const core::TargetLocations& b = full->locations;
  for (Eigen::Index v = 0; v < target.mesh.vertexCount(); ++v) {
    const auto i = static_cast<std::size_t>(v);
    ASSERT_EQ(a.on_source[i].face, b.on_source[i].face) << "target vertex " << v;
    EXPECT_EQ(a.on_source[i].barycentric, b.on_source[i].barycentric) << "target vertex " << v;
  }
  EXPECT_EQ(a.confidence, b.confidence);
  EXPECT_EQ(a.mismatched, b.mismatched);
  EXPECT_EQ(partial->report.flipped_triangles, full->report.flipped_triangles);

  // Located on the guide itself (no smoothed guide), every vertex is projected.
  auto prepared = core::prepareSource(source.mesh, source.landmarks, "source");
  ASSERT_TRUE(prepared);
  core::WarpOptions light = core::lightWarpOptions();
  light.full_guide = false;
  auto on_guide = core::runWarp(*prepared, target.mesh, target.landmarks, "light", light);
  ASSERT_TRUE(on_guide);
  EXPECT_EQ(on_guide->report.projected_source_vertices, nv);
}

// A neck pushed far forward below the chin (as on a strongly exaggerated
// identity): the face's landmarks say nothing of it, so the landmark warp
// leaves the source's neck on the wrong side of the target's, where closest
// points hold it. The neck cut, matched and paired point for point, joins the
// warp and brings it over. Same topology: target vertex v is source vertex v.
TEST(Correspondence, NeckCutJoinsTheWarpWhenNoLandmarkPinsIt) {
  const auto source = core::generateHead();
  core::SyntheticHead target = source;
  const double bottom = source.mesh.positions.col(1).minCoeff(), chin = 0.55 * bottom;
  const double depth = source.mesh.positions.col(2).maxCoeff() - source.mesh.positions.col(2).minCoeff();
  std::vector<Eigen::Index> neck;  // sheared forward, by 3/4 of the head's depth at the cut
  for (Eigen::Index v = 0; v < target.mesh.positions.rows(); ++v) {
    const double below = chin - target.mesh.positions(v, 1);
    if (below <= 0.0) continue;
    target.mesh.positions(v, 2) += 0.75 * depth * below / (chin - bottom);
    neck.push_back(v);
  }
  target.mesh.normals = core::computeVertexNormals(target.mesh.positions, target.mesh.triangles);
  auto prepared = core::prepareSource(source.mesh, source.landmarks, "source");
  ASSERT_TRUE(prepared);
  core::WarpOptions landmarks_only;
  landmarks_only.rim_warp_points = 0;
  auto off = core::runWarp(*prepared, target.mesh, target.landmarks, "neck_forward", landmarks_only);
  auto on = core::runWarp(*prepared, target.mesh, target.landmarks, "neck_forward");
  ASSERT_TRUE(off && on);
  EXPECT_EQ(off->report.rims_in_warp, 0);
  EXPECT_EQ(on->report.rims_in_warp, 1);  // the outer rim; the mouth and eyes carry landmarks
  const double slide_off = meanDistanceFromTrueSource(*off, source.mesh, neck, depth);
  const double slide_on = meanDistanceFromTrueSource(*on, source.mesh, neck, depth);
  std::printf("[ neck forward ] %zu neck vertices, mean distance from their true source point %.4f -> %.4f "
              "(head depth %.3f)\n", neck.size(), slide_off, slide_on, depth);
  EXPECT_LT(slide_on, 0.5 * slide_off);
}

// Points displaced within their own tangent planes off an affine image slide
// back onto it: the affine map is the only one of zero bending energy that
// the fixed points allow.
TEST(Correspondence, SlidingInTangentPlanesRestoresAnAffineMap) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Eigen::MatrixX3d centres(40, 3);
  for (Eigen::Index i = 0; i < 40; ++i) centres.row(i) << u(rng), u(rng), u(rng);
  Eigen::Matrix3d a;
  a << 1.2, 0.1, -0.3, 0.0, 0.8, 0.2, 0.1, -0.1, 1.1;
  const Eigen::MatrixX3d affine = (centres * a.transpose()).rowwise() + Eigen::RowVector3d(0.5, -1.0, 2.0);
  auto factorization = core::TpsFactorization::create(centres);
  ASSERT_TRUE(factorization);
  const Eigen::MatrixXd bending = factorization->bendingEnergyMatrix();
  std::vector<int> sliding;
  Eigen::MatrixX3d normals(25, 3);
  Eigen::MatrixX3d displaced = affine;
  for (int i = 0; i < 25; ++i) {
    const int row = 15 + i;
    sliding.push_back(row);
    const Eigen::Vector3d n = Eigen::Vector3d(u(rng), u(rng), u(rng)).normalized();
    normals.row(i) = 3.0 * n.transpose();  // any length
    const Eigen::Vector3d in_plane = n.unitOrthogonal() * u(rng) + n.cross(n.unitOrthogonal()) * u(rng);
    displaced.row(row) += 0.2 * in_plane.transpose();
  }
  const double before = (displaced.transpose() * bending * displaced).trace();
  const Eigen::MatrixX3d slid = core::slideInTangentPlanes(bending, displaced, sliding, normals, 200);
  EXPECT_GT(before, 1e-3);
  EXPECT_LT((slid.transpose() * bending * slid).trace(), 1e-12 * before + 1e-14);
  EXPECT_TRUE(rigport_test::matricesNear(slid, affine, 1e-6));
  // Fixed rows did not move; sliding rows moved within their planes.
  EXPECT_TRUE(slid.topRows(15).isApprox(displaced.topRows(15)));
  for (int i = 0; i < 25; ++i) {
    EXPECT_NEAR((slid.row(15 + i) - displaced.row(15 + i)).dot(normals.row(i).normalized()), 0.0, 1e-12);
  }
  // A point without a plane (zero or NaN normal) stays; the others still slide.
  normals.row(0).setZero();
  normals.row(1).setConstant(std::numeric_limits<double>::quiet_NaN());
  const Eigen::MatrixX3d planeless = core::slideInTangentPlanes(bending, displaced, sliding, normals, 200);
  ASSERT_TRUE(planeless.allFinite());
  EXPECT_EQ(planeless.row(15), displaced.row(15));
  EXPECT_EQ(planeless.row(16), displaced.row(16));
  EXPECT_LT((planeless.transpose() * bending * planeless).trace(), 0.5 * before);
}

// Matched with 10 landmarks, as a sparse target would be: sliding the dense
// centres locates the bent head closer to the truth than projection alone.
TEST(Correspondence, SlidingCentresLocateASparselyLandmarkedTargetCloser) {
  const auto source = core::generateHead();
  const core::SyntheticHead target = bentHead(source);
  const core::LandmarkSet sparse = sparseLandmarks(target.landmarks);
  ASSERT_EQ(sparse.landmarks.size(), 10u);
  auto prepared = core::prepareSource(source.mesh, source.landmarks, "source");
  ASSERT_TRUE(prepared);
  core::WarpOptions projected_only;
  projected_only.slide_centres = false;
  auto off = core::runWarp(*prepared, target.mesh, sparse, "bent", projected_only);
  auto on = core::runWarp(*prepared, target.mesh, sparse, "bent");
  ASSERT_TRUE(off && on);
  EXPECT_EQ(off->report.slid_centres, 0);
  EXPECT_GT(on->report.slid_centres, 200);
  EXPECT_GT(on->report.mean_slide, 0.0);
  std::vector<Eigen::Index> every(static_cast<std::size_t>(target.mesh.vertexCount()));
  std::iota(every.begin(), every.end(), Eigen::Index{0});
  const double h = source.mesh.positions.col(1).maxCoeff() - source.mesh.positions.col(1).minCoeff();
  const double error_off = meanDistanceFromTrueSource(*off, source.mesh, every, h);
  const double error_on = meanDistanceFromTrueSource(*on, source.mesh, every, h);
  std::printf("[ bent head, 10 landmarks ] mean distance from the true source point %.5f -> %.5f (head height %.3f), "
              "%d centres slid %.5f on average\n", error_off, error_on, h, on->report.slid_centres, on->report.mean_slide);
  EXPECT_LT(error_on, 0.95 * error_off);
}

// A target whose eye holes end in a curled margin (as a lid's does): each
// eye-rim vertex stands a little off the surface and beyond the source's
// border, so its closest point on the guide falls inside the lid, short of
// the border it is. Located on the guide's rim instead, it lands next to its
// true point. Same topology: target vertex v is source vertex v.
// The generated head's eye rims (rims 1 and 2; rim 0 is the open back and
// neck) curled off like a lid margin: each rim vertex moved away from its
// hole along the surface by 0.3 of the rim's mean edge and lifted off the
// surface by as much. Returns the moved vertices.
std::vector<Eigen::Index> curlEyeRims(const core::SyntheticHead& source, const std::vector<core::Rim>& rims,
                                      core::SyntheticHead& target) {
  std::vector<Eigen::Index> moved;
  for (std::size_t r = 1; r < rims.size(); ++r) {
    const core::Rim& rim = rims[r];
    Eigen::RowVector3d centre = Eigen::RowVector3d::Zero();
    for (int v : rim.vertices) centre += source.mesh.positions.row(v);
    centre /= static_cast<double>(rim.vertices.size());
    const double step = 0.3 * rim.length / static_cast<double>(rim.vertices.size());
    for (int v : rim.vertices) {
      const Eigen::RowVector3d n = source.mesh.normals.row(v);
      Eigen::RowVector3d away = source.mesh.positions.row(v) - centre;
      away -= away.dot(n) * n;
      target.mesh.positions.row(v) += step * (away.normalized() + n);
      moved.push_back(v);
    }
  }
  return moved;
}

TEST(Correspondence, RimVerticesAreLocatedOnTheGuidesRims) {
  const auto source = core::generateHead();
  core::SyntheticHead target = source;
  const std::vector<core::Rim> rims =
      core::meshRims(source.mesh, core::coincidentVertexRepresentatives(source.mesh.positions));
  ASSERT_EQ(rims.size(), 3u);  // the open back and neck, two eye holes (the lips are closed)
  const std::vector<Eigen::Index> eye_rims = curlEyeRims(source, rims, target);
  target.mesh.normals = core::computeVertexNormals(target.mesh.positions, target.mesh.triangles);
  auto [off, on] = warpOffAndOn(&core::WarpOptions::rim_location, source, target.mesh, target.landmarks);
  ASSERT_TRUE(off && on);
  EXPECT_EQ(off->report.rim_located_vertices, 0);
  EXPECT_GT(on->report.rim_located_vertices, static_cast<int>(eye_rims.size()) / 2);
  const double h = source.mesh.positions.col(1).maxCoeff() - source.mesh.positions.col(1).minCoeff();
  const double error_off = meanDistanceFromTrueSource(*off, source.mesh, eye_rims, h);
  const double error_on = meanDistanceFromTrueSource(*on, source.mesh, eye_rims, h);
  std::printf("[ curled eye margins ] %zu eye-rim vertices, mean distance from their true source point %.5f -> "
              "%.5f (%d target vertices located on the guide's rims)\n", eye_rims.size(), error_off, error_on,
              on->report.rim_located_vertices);
  EXPECT_LT(error_on, 0.5 * error_off);
}

// A remesher can leave a vertex a few percent of an edge from a rim vertex
// (a sliver at the constrained border). It stands off the surface as the rim
// does and is located as a rim point: beside its rim vertex on the guide's
// rim, not on the curled margin.
TEST(Correspondence, VerticesAtARimAreLocatedAsRimPoints) {
  const auto source = core::generateHead();
  core::SyntheticHead target = source;
  const std::vector<core::Rim> rims =
      core::meshRims(source.mesh, core::coincidentVertexRepresentatives(source.mesh.positions));
  ASSERT_EQ(rims.size(), 3u);
  std::vector<char> on_rim(static_cast<std::size_t>(source.mesh.vertexCount()), 0);
  for (const core::Rim& rim : rims) {
    for (int v : rim.vertices) on_rim[static_cast<std::size_t>(v)] = 1;
  }
  std::vector<char> has_landmark(static_cast<std::size_t>(source.mesh.triangles.rows()), 0);
  for (const core::Landmark& l : source.landmarks.landmarks) has_landmark[static_cast<std::size_t>(l.face)] = 1;
  curlEyeRims(source, rims, target);
  // Every fourth eye-rim vertex gets a sliver: a new vertex 5% of the way
  // from it to the centroid of a face it has with two off-rim corners, moved
  // with it; the face is split in three.
  std::vector<Eigen::Index> slivers;
  std::vector<Eigen::RowVector3d> truth;  // the sliver's point on the source
  std::vector<Eigen::Vector3i> added;
  const Eigen::Index nv = source.mesh.vertexCount();
  std::vector<Eigen::RowVector3d> positions;
  std::vector<int> sliver_of;  // its rim vertex
  for (std::size_t r = 1; r < rims.size(); ++r) {
    for (std::size_t i = 0; i < rims[r].vertices.size(); i += 4) {
      const int v = rims[r].vertices[i];
      for (Eigen::Index f = 0; f < source.mesh.triangles.rows(); ++f) {
        const Eigen::Vector3i t = source.mesh.triangles.row(f).transpose();
        int k = 0;
        while (k < 3 && t(k) != v) ++k;
        if (k == 3 || has_landmark[static_cast<std::size_t>(f)] || on_rim[static_cast<std::size_t>(t((k + 1) % 3))] ||
            on_rim[static_cast<std::size_t>(t((k + 2) % 3))]) {
          continue;
        }
        auto sliver = [&](const Eigen::MatrixX3d& p) {
          const Eigen::RowVector3d centroid = (p.row(t(0)) + p.row(t(1)) + p.row(t(2))) / 3.0;
          return Eigen::RowVector3d(p.row(v) + 0.05 * (centroid - p.row(v)));
        };
        const auto w = static_cast<int>(nv + static_cast<Eigen::Index>(positions.size()));
        truth.push_back(sliver(source.mesh.positions));
        positions.push_back(sliver(source.mesh.positions) + target.mesh.positions.row(v) - source.mesh.positions.row(v));
        slivers.push_back(w);
        sliver_of.push_back(v);
        target.mesh.triangles.row(f) << t(0), t(1), w;
        added.push_back({t(1), t(2), w});
        added.push_back({t(2), t(0), w});
        has_landmark[static_cast<std::size_t>(f)] = 1;  // split once
        break;
      }
    }
  }
  ASSERT_GT(slivers.size(), 4u);
  target.mesh.positions.conservativeResize(nv + static_cast<Eigen::Index>(positions.size()), 3);
  target.mesh.regions.conservativeResize(target.mesh.positions.rows());
  for (std::size_t i = 0; i < positions.size(); ++i) {
    target.mesh.positions.row(nv + static_cast<Eigen::Index>(i)) = positions[i];
    target.mesh.regions(nv + static_cast<Eigen::Index>(i)) = source.mesh.regions(sliver_of[i]);
  }
  ASSERT_EQ(target.mesh.uvs.rows(), 0);
  const Eigen::Index nf = target.mesh.triangles.rows();
  target.mesh.triangles.conservativeResize(nf + static_cast<Eigen::Index>(added.size()), 3);
  for (std::size_t i = 0; i < added.size(); ++i) target.mesh.triangles.row(nf + static_cast<Eigen::Index>(i)) = added[i].transpose();
  target.mesh.normals = core::computeVertexNormals(target.mesh.positions, target.mesh.triangles);

  auto [off, on] = warpOffAndOn(&core::WarpOptions::rim_location, source, target.mesh, target.landmarks);
  ASSERT_TRUE(off && on) << (off ? on.error().message : off.error().message);
  auto error = [&](const core::WarpResult& r) {
    double sum = 0.0;
    for (std::size_t i = 0; i < slivers.size(); ++i) {
      const core::SurfacePoint& at = r.locations.on_source[static_cast<std::size_t>(slivers[i])];
      EXPECT_TRUE(at.found()) << "sliver " << slivers[i];
      if (at.found()) sum += (core::interpolateOnFace(source.mesh.positions, source.mesh.triangles, at.face, at.barycentric) - truth[i]).norm();
    }
    return sum / static_cast<double>(slivers.size());
  };
  const double error_off = error(*off), error_on = error(*on);
  std::printf("[ slivers at curled eye rims ] %zu slivers, mean distance from their true source point %.5f -> %.5f\n",
              slivers.size(), error_off, error_on);
  EXPECT_LT(error_on, 0.5 * error_off);
}

// A scan with holes of its own (here: 40 small ones on the back of the
// head) keeps their vertices where the surface location put them: no source
// rim is near them.
TEST(Correspondence, HolesTheSourceLacksKeepTheirSurfaceLocations) {
  const auto source = core::generateHead();
  core::SyntheticHead target = source;
  const Eigen::Index nf = source.mesh.triangles.rows();
  std::vector<char> keep(static_cast<std::size_t>(nf), 1);
  // Each hole one triangle, touching no rim and no other hole.
  std::vector<char> taken(static_cast<std::size_t>(source.mesh.vertexCount()), 0);
  for (const core::Rim& rim : core::meshRims(source.mesh, core::coincidentVertexRepresentatives(source.mesh.positions))) {
    for (int v : rim.vertices) taken[static_cast<std::size_t>(v)] = 1;
  }
  int holes = 0;
  for (Eigen::Index f = 0; f < nf && holes < 40; f += 37) {
    const Eigen::RowVector3i t = source.mesh.triangles.row(f);
    Eigen::RowVector3d centre = Eigen::RowVector3d::Zero();
    for (int c = 0; c < 3; ++c) centre += source.mesh.positions.row(t(c)) / 3.0;
    if (centre.z() > 0.0) continue;  // the side and back of the head (the face looks toward +z)
    if (taken[static_cast<std::size_t>(t(0))] || taken[static_cast<std::size_t>(t(1))] || taken[static_cast<std::size_t>(t(2))]) continue;
    for (int c = 0; c < 3; ++c) taken[static_cast<std::size_t>(t(c))] = 1;
    keep[static_cast<std::size_t>(f)] = 0;
    ++holes;
  }
  ASSERT_EQ(holes, 40);
  std::vector<int> new_index(static_cast<std::size_t>(nf), -1);
  Eigen::MatrixX3i kept(nf - holes, 3);
  for (Eigen::Index f = 0, k = 0; f < nf; ++f) {
    if (!keep[static_cast<std::size_t>(f)]) continue;
    new_index[static_cast<std::size_t>(f)] = static_cast<int>(k);
    kept.row(k++) = source.mesh.triangles.row(f);
  }
  target.mesh.triangles = kept;
  for (core::Landmark& l : target.landmarks.landmarks) {
    l.face = new_index[static_cast<std::size_t>(l.face)];
    ASSERT_GE(l.face, 0) << l.name;
  }
  auto [off, on] = warpOffAndOn(&core::WarpOptions::rim_location, source, target.mesh, target.landmarks);
  ASSERT_TRUE(off && on);
  const std::vector<core::Rim> rims =
      core::meshRims(target.mesh, core::coincidentVertexRepresentatives(target.mesh.positions));
  ASSERT_EQ(rims.size(), 3u + 40u);
  int hole_vertices = 0, moved = 0;
  for (const core::Rim& rim : rims) {
    if (rim.vertices.size() != 3) continue;  // one removed triangle
    for (int v : rim.vertices) {
      ++hole_vertices;
      const core::SurfacePoint& a = off->locations.on_source[static_cast<std::size_t>(v)];
      const core::SurfacePoint& b = on->locations.on_source[static_cast<std::size_t>(v)];
      moved += a.face != b.face || a.barycentric != b.barycentric;
    }
  }
  EXPECT_EQ(hole_vertices, 120);
  EXPECT_EQ(moved, 0);
  EXPECT_GT(on->report.rim_located_vertices, 0);  // the eye holes' and the back's rims still are
}

// The source landmarks a sparse target does not name are refined like the
// dense samples instead of staying where the landmark warp put them: the
// final dense map carries them closer to their true places on the target.
TEST(Correspondence, LandmarksTheTargetDoesNotNameFollowTheRefinement) {
  const auto source = core::generateHead();
  const core::SyntheticHead target = bentHead(source);
  auto truth = core::resolveLandmarks(target.landmarks, target.mesh, "bent");  // same topology: the true places
  ASSERT_TRUE(truth);
  std::vector<Eigen::Index> unnamed;
  const core::LandmarkSet sparse = sparseLandmarks(target.landmarks, &unnamed);
  auto prepared = core::prepareSource(source.mesh, source.landmarks, "source");
  ASSERT_TRUE(prepared);
  auto r = core::runWarp(*prepared, target.mesh, sparse, "bent");
  ASSERT_TRUE(r) << r.error().message;
  ASSERT_TRUE(r->dense_map);
  const Eigen::MatrixX3d by_warp = r->landmark_warp.apply(prepared->landmark_positions);
  const Eigen::MatrixX3d by_map = r->dense_map->apply(prepared->landmark_positions);
  const core::ClosestPointIndex surface(target.mesh.positions, target.mesh.triangles);
  double warp_error = 0.0, map_error = 0.0, warp_off = 0.0, map_off = 0.0;
  for (Eigen::Index l : unnamed) {
    warp_error += (by_warp.row(l) - truth->row(l)).norm();
    map_error += (by_map.row(l) - truth->row(l)).norm();
    warp_off += std::sqrt(surface.closestPoint(by_warp.row(l).transpose()).sq_distance);
    map_off += std::sqrt(surface.closestPoint(by_map.row(l).transpose()).sq_distance);
  }
  const double n = static_cast<double>(unnamed.size());
  std::printf("[ bent head, %zu of 68 landmarks ] the other landmarks from their true places: %.5f by the landmark "
              "warp, %.5f by the refined dense map; off the target surface %.5f and %.5f\n",
              sparse.landmarks.size(), warp_error / n, map_error / n, warp_off / n, map_off / n);
  EXPECT_LT(map_error, 0.95 * warp_error);
  EXPECT_LT(map_off, 0.5 * warp_off);
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
