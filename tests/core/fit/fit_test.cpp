// fitScan on the ICT reference (core/fit/fit.h): the reference fitted to
// exact resamples of its own surface gives itself back; a scan turned, scaled
// to other units and shifted gives the fit turned, scaled and shifted alike;
// the rebuilt rig keeps the reference's weights, binds its joints to the
// fitted mesh and carries its deltas into the scan's frame and units. Skips
// when ../shared/data is absent.
#include "core/fit/fit.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <memory>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "core/geometry/closest_point.h"
#include "core/io/mesh_io.h"
#include "core/synthetic/synthetic_rig.h"
#include "tests/core/fit/fit_fixtures.h"
#include "tests/test_support.h"

namespace {

using rigport_test::FitReferenceCase;

// Per-vertex distances between two #V by 3 arrays: median, 99th percentile,
// largest, and the worst vertices with theirs.
struct VertexErrors {
  double median = 0.0, p99 = 0.0, max = 0.0;
  std::vector<std::pair<int, double>> worst;  // up to 8, largest first
};

VertexErrors vertexErrors(const Eigen::MatrixX3d& a, const Eigen::MatrixX3d& b) {
  VertexErrors out;
  const Eigen::VectorXd d = (a - b).rowwise().norm();
  std::vector<std::pair<int, double>> all;
  for (Eigen::Index v = 0; v < d.size(); ++v) all.emplace_back(static_cast<int>(v), d(v));
  std::sort(all.begin(), all.end(), [](const auto& x, const auto& y) { return x.second > y.second; });
  if (all.empty()) return out;
  out.max = all.front().second;
  out.median = all[all.size() / 2].second;
  out.p99 = all[all.size() / 100].second;
  out.worst.assign(all.begin(), all.begin() + static_cast<std::ptrdiff_t>(std::min<std::size_t>(8, all.size())));
  return out;
}

std::string describe(const VertexErrors& e, double unit_mm) {
  char text[160];
  std::snprintf(text, sizeof text, "median %.3g mm, p99 %.3g mm, max %.3g mm; worst vertices:", e.median * unit_mm,
                e.p99 * unit_mm, e.max * unit_mm);
  std::string out = text;
  for (const auto& [v, d] : e.worst) {
    std::snprintf(text, sizeof text, " %d (%.3g mm)", v, d * unit_mm);
    out += text;
  }
  return out;
}

// Distance of each of `points` to the mesh's surface, ascending.
std::vector<double> offSurface(const core::Mesh& mesh, const Eigen::MatrixX3d& points) {
  const core::ClosestPointIndex index(mesh.positions, mesh.triangles);
  std::vector<double> out;
  for (const core::SurfacePoint& p : index.closestPoints(points)) out.push_back(std::sqrt(p.sq_distance));
  std::sort(out.begin(), out.end());
  return out;
}

// The reference's own landmarks as positions on its surface.
core::LandmarkSet referenceLandmarks(const core::PreparedRig& rig) {
  return rigport_test::positionLandmarks(rig.surface.landmarks, rig.surface.landmark_positions);
}

// A rotation of 30 degrees about a tilted axis, ten times the size (cm -> mm)
// and a shift.
core::Similarity turnedToMillimetres() {
  core::Similarity s;
  s.rotation = Eigen::AngleAxisd(30.0 * std::numbers::pi / 180.0, Eigen::Vector3d(1.0, 2.0, 0.5).normalized())
                   .toRotationMatrix();
  s.scale = 10.0;
  s.translation = Eigen::Vector3d(120.0, -35.0, 48.0);
  return s;
}

#define REQUIRE_ICT_REFERENCE(ref)                                              \
  RIGPORT_REQUIRE_SHARED_DATA(data);                                            \
  const FitReferenceCase& ref = rigport_test::ictFitReference(data);            \
  ASSERT_TRUE(ref.reference) << "ICT reference did not load: " << ref.error

// ICT is in cm: 0.1 mm = 0.01 units.
constexpr double kCmToMm = 10.0;
constexpr double kSelfFitLimit = 0.01;

// The reference fitted to its own surface split 1-to-4 (every reference
// vertex is a scan vertex, every scan point on the reference) with its own
// landmarks gives itself back.
TEST(FitScan, SelfFitOnTheSubdividedReferenceGivesTheReferenceBack) {
  REQUIRE_ICT_REFERENCE(ref);
  const core::Mesh& rest = ref.rig->surface.mesh;
  const core::Mesh scan = rigport_test::subdivideMidpoints(rest);
  const auto fit = core::fitScan(*ref.reference, scan, referenceLandmarks(*ref.rig), "reference 1-to-4");
  ASSERT_TRUE(fit) << fit.error().message;
  const core::FitReport& r = fit->report;
  const VertexErrors e = vertexErrors(fit->rig.mesh.positions, rest.positions);
  std::printf("self-fit, reference subdivided 1-to-4 (%lld points): %s\n", static_cast<long long>(scan.vertexCount()),
              describe(e, kCmToMm).c_str());
  std::printf("  verdict %s, units %s, alignment rms %.3g, face coverage %.4f, skin coverage %.4f, flipped %d\n",
              r.verdict.c_str(), r.scan.units.c_str(), r.alignment.rms_residual, r.face_coverage, r.skin_coverage,
              r.flipped_triangles);
  EXPECT_EQ(r.verdict, "ok");
  EXPECT_EQ(r.scan.units, "cm");
  EXPECT_TRUE(r.alignment.landmarks_dropped.empty());
  EXPECT_LE(e.max, kSelfFitLimit) << describe(e, kCmToMm);
  EXPECT_EQ(r.flipped_triangles, 0);
}

// The generated rig's landmarks lie inside faces (face + barycentric), off
// the vertices that stand for them by up to 2.3 mm: each is pulled to its
// click offset as its vertex is, so its own surface still gives it back,
// and the landmarks' residuals are the landmarks' own (0), not their
// vertices' offsets.
TEST(FitScan, SelfFitOfTheGeneratedRigWithLandmarksInsideFacesGivesItBack) {
  const FitReferenceCase& ref = rigport_test::syntheticFitReference();
  ASSERT_TRUE(ref.reference) << ref.error;
  const core::Mesh& rest = ref.rig->surface.mesh;
  double offset = 0.0;
  for (std::size_t l = 0; l < ref.rig->surface.landmark_vertices.size(); ++l) {
    offset = std::max(offset, (rest.positions.row(ref.rig->surface.landmark_vertices[l]) -
                               ref.rig->surface.landmark_positions.row(static_cast<Eigen::Index>(l)))
                                  .norm());
  }
  ASSERT_GT(offset, 1e-3 * ref.rig->surface.diagonal);  // the case under test: landmarks off their vertices
  core::Mesh scan;
  scan.positions = rest.positions;
  scan.triangles = rest.triangles;
  const auto fit = core::fitScan(*ref.reference, scan, referenceLandmarks(*ref.rig), "generated head");
  ASSERT_TRUE(fit) << fit.error().message;
  const double limit = 1e-9 * ref.rig->surface.diagonal;
  const VertexErrors e = vertexErrors(fit->rig.mesh.positions, rest.positions);
  EXPECT_LE(e.max, limit) << describe(e, 1000.0) << " (landmarks up to " << offset * 1000.0 << " mm off their vertices)";
  ASSERT_EQ(fit->report.landmarks.size(), ref.rig->surface.landmarks.landmarks.size());
  for (const core::FitLandmarkResidual& l : fit->report.landmarks) {
    EXPECT_LE(l.aligned, limit) << l.name;
    EXPECT_LE(l.fitted, limit) << l.name;
  }
  EXPECT_EQ(fit->report.verdict, "ok");
}

// The same on a ~50,000-point cloud drawn evenly on the reference's surface
// with its interpolated normals. No scan point is a reference vertex: each
// vertex is matched to its nearest sample and that sample's tangent plane,
// so the fit is only as exact as the sampling, and the 0.1 mm of the
// subdivided surface does not hold. Measured (48,972 points 1.45 mm apart):
// off the reference's surface median 0.013 mm, max 0.28 mm (a sample's
// tangent plane ~1 mm from the vertex, on curved lids, mouth corners, ears);
// vertex error median 0.135 mm, max 0.52 mm (vertices 10575, 624, 602, 5900),
// mostly along the surface: the last stages' point_share (0.1) pulls each
// vertex towards its nearest sample. The limits are those with a margin, as
// fractions of the spacing. The face coverage (0.89: ~480 vertices matched
// to the border band along the reference's own eye and mouth rims, ~190
// rejected by normal angle) makes the verdict warn. The cloud is even, as a
// scanner's: drawn uniformly at random, 22% of it is read as border
// (scan_test, DISABLED_RandomCloudOfAPlaneHasNoBordersInside), the face
// coverage falls to 0.66 and the verdict to fail.
TEST(FitScan, SelfFitOnACloudSampledOnTheReferenceStaysWithinTheSampling) {
  REQUIRE_ICT_REFERENCE(ref);
  const core::Mesh& rest = ref.rig->surface.mesh;
  constexpr double kSpacing = 0.145;  // cm
  const core::Mesh scan = rigport_test::sampleSurfaceEvenly(rest, rest.normals, kSpacing, 600000, 3);
  const auto fit = core::fitScan(*ref.reference, scan, referenceLandmarks(*ref.rig), "reference cloud");
  ASSERT_TRUE(fit) << fit.error().message;
  const core::FitReport& r = fit->report;
  const VertexErrors e = vertexErrors(fit->rig.mesh.positions, rest.positions);
  const std::vector<double> off = offSurface(rest, fit->rig.mesh.positions);
  std::printf("self-fit, %lld-point cloud on the reference (%.2f mm apart): %s\n",
              static_cast<long long>(scan.vertexCount()), kSpacing * kCmToMm, describe(e, kCmToMm).c_str());
  std::printf("  off the reference's surface: median %.3g mm, p99 %.3g mm, max %.3g mm\n", off[off.size() / 2] * kCmToMm,
              off[off.size() * 99 / 100] * kCmToMm, off.back() * kCmToMm);
  std::printf("  verdict %s, units %s, border points %d, spikes %d, face coverage %.4f, skin coverage %.4f, flipped %d\n",
              r.verdict.c_str(), r.scan.units.c_str(), r.scan.border_points, r.scan.spikes, r.face_coverage,
              r.skin_coverage, r.flipped_triangles);
  EXPECT_NE(r.verdict, "fail");
  EXPECT_FALSE(r.scan.normals_computed);
  EXPECT_EQ(r.scan.units, "cm");
  EXPECT_EQ(r.flipped_triangles, 0);
  EXPECT_LE(off.back(), 0.3 * kSpacing);
  EXPECT_LE(e.median, 0.15 * kSpacing) << describe(e, kCmToMm);
  EXPECT_LE(e.max, 0.5 * kSpacing) << describe(e, kCmToMm);
}

// A real scan in cm (scan_s03_obj) and the same scan turned 30 degrees about
// a tilted axis, in mm and shifted, each with its landmarks moved alike: the
// second fit is the first moved alike, its units found as mm, its deltas
// turned and ten times as long.
TEST(FitScan, ScanTurnedScaledToMillimetresAndShiftedMovesTheFitAlike) {
  REQUIRE_ICT_REFERENCE(ref);
  auto scan = core::readMesh(data / "scans" / "scan_s03_obj.obj");
  ASSERT_TRUE(scan) << scan.error().message;
  auto landmarks = core::readLandmarks(data / "scans" / "scan_s03_obj.landmarks.json");
  ASSERT_TRUE(landmarks) << landmarks.error().message;
  const core::Similarity move = turnedToMillimetres();
  const auto fit = core::fitScan(*ref.reference, scan->mesh, *landmarks, "scan_s03_obj");
  const auto moved = core::fitScan(*ref.reference, rigport_test::transformed(scan->mesh, move),
                                   rigport_test::transformedLandmarks(*landmarks, move), "scan_s03_obj moved");
  ASSERT_TRUE(fit) << fit.error().message;
  ASSERT_TRUE(moved) << moved.error().message;
  EXPECT_EQ(fit->report.scan.units, "cm");
  EXPECT_EQ(moved->report.scan.units, "mm");
  EXPECT_DOUBLE_EQ(fit->report.unit_scale, 1.0);
  EXPECT_DOUBLE_EQ(moved->report.unit_scale, 10.0);
  EXPECT_NEAR(moved->report.scan.size_ratio, fit->report.scan.size_ratio, 1e-9 * fit->report.scan.size_ratio);

  const Eigen::MatrixX3d expected = rigport_test::transformedPoints(fit->rig.mesh.positions, move);
  const double diagonal = core::boundingBoxDiagonal(expected);
  const VertexErrors e = vertexErrors(moved->rig.mesh.positions, expected);
  std::printf("equivariance on scan_s03_obj: fitted positions off by max %.3g of the diagonal (%.3g mm), median %.3g; "
              "verdicts %s / %s\n",
              e.max / diagonal, e.max, e.median / diagonal, fit->report.verdict.c_str(), moved->report.verdict.c_str());
  EXPECT_LE(e.max, 1e-3 * diagonal) << describe(e, 1.0);
  EXPECT_EQ(fit->report.verdict, moved->report.verdict);

  ASSERT_EQ(moved->rig.morph_targets.size(), fit->rig.morph_targets.size());
  double worst_delta = 0.0, largest_delta = 0.0;
  for (std::size_t k = 0; k < fit->rig.morph_targets.size(); ++k) {
    const Eigen::MatrixX3d turned = move.scale * fit->rig.morph_targets[k].position_deltas * move.rotation.transpose();
    worst_delta = std::max(worst_delta, (moved->rig.morph_targets[k].position_deltas - turned).cwiseAbs().maxCoeff());
    largest_delta = std::max(largest_delta, turned.cwiseAbs().maxCoeff());
  }
  std::printf("  deltas off by max %.3g mm (largest delta component %.3g mm)\n", worst_delta, largest_delta);
  EXPECT_LE(worst_delta, 1e-3 * largest_delta);
}

// Input no fit can use is an error naming the cause, before any work; a
// scan that is no head comes back as a fit whose verdict fails.
class FitScanRefuses : public ::testing::Test {
 protected:
  void SetUp() override {
    const FitReferenceCase& synthetic = rigport_test::syntheticFitReference();
    ASSERT_TRUE(synthetic.reference) << synthetic.error;
    reference_ = &synthetic;
  }
  // The reference's own mesh as a scan (metres) and its landmarks on it.
  const core::Mesh& scan() const { return reference_->rig->surface.mesh; }
  core::LandmarkSet landmarks() const { return referenceLandmarks(*reference_->rig); }
  const FitReferenceCase* reference_ = nullptr;
};

TEST_F(FitScanRefuses, AnEmptyOrTinyScan) {
  const auto empty = core::fitScan(*reference_->reference, core::Mesh{}, {}, "empty.ply");
  ASSERT_FALSE(empty);
  EXPECT_EQ(empty.error().code, core::ErrorCode::kInvalidMesh);
  EXPECT_NE(empty.error().message.find("empty.ply"), std::string::npos) << empty.error().message;
  core::Mesh tiny;
  tiny.positions = scan().positions.topRows(10);
  const auto ten = core::fitScan(*reference_->reference, tiny, {}, "ten.ply");
  ASSERT_FALSE(ten);
  EXPECT_EQ(ten.error().code, core::ErrorCode::kInvalidMesh);
  EXPECT_NE(ten.error().message.find("10 points"), std::string::npos) << ten.error().message;
}

TEST_F(FitScanRefuses, ALandmarkFiveCentimetresOffTheScanNamingIt) {
  core::LandmarkSet off = landmarks();
  const int l = off.indexOf("nose_base_2");
  ASSERT_GE(l, 0);
  off.landmarks[static_cast<std::size_t>(l)].position += Eigen::Vector3d(0.0, 0.0, 0.05);  // 5 cm, in metres
  const auto fit = core::fitScan(*reference_->reference, scan(), off, "head.ply");
  ASSERT_FALSE(fit);
  EXPECT_EQ(fit.error().code, core::ErrorCode::kInvalidLandmarks);
  EXPECT_NE(fit.error().message.find("nose_base_2"), std::string::npos) << fit.error().message;
  EXPECT_NE(fit.error().message.find("off the mesh"), std::string::npos) << fit.error().message;
}

TEST_F(FitScanRefuses, ALandmarkNameTheReferenceDoesNotHave) {
  core::LandmarkSet unknown = landmarks();
  unknown.landmarks[3].name = "left_earlobe";
  const auto fit = core::fitScan(*reference_->reference, scan(), unknown, "head.ply");
  ASSERT_FALSE(fit);
  EXPECT_EQ(fit.error().code, core::ErrorCode::kInvalidLandmarks);
  EXPECT_NE(fit.error().message.find("left_earlobe"), std::string::npos) << fit.error().message;
}

TEST_F(FitScanRefuses, LandmarkAlignmentWithoutLandmarks) {
  core::FitOptions options;
  options.alignment = core::FitAlignmentMode::kLandmarks;
  const auto fit = core::fitScan(*reference_->reference, scan(), {}, "head.ply", options);
  ASSERT_FALSE(fit);
  EXPECT_EQ(fit.error().code, core::ErrorCode::kInvalidLandmarks);
}

TEST_F(FitScanRefuses, AReferenceWithoutLandmarks) {
  // A rig prepared as usual (its landmarks span 3D), then stripped of them.
  core::SyntheticRig generated = core::generateRig();
  auto prepared_rig = core::prepareRig(std::move(generated.rig), std::move(generated.landmarks), "bare rig");
  ASSERT_TRUE(prepared_rig) << prepared_rig.error().message;
  auto bare = std::make_shared<core::PreparedRig>(std::move(*prepared_rig));
  bare->surface.landmarks.landmarks.clear();
  bare->surface.landmark_positions.resize(0, 3);
  bare->surface.landmark_vertices.clear();
  const auto prepared = core::prepareFitReference(bare);
  ASSERT_FALSE(prepared);
  EXPECT_EQ(prepared.error().code, core::ErrorCode::kInvalidLandmarks);
  EXPECT_NE(prepared.error().message.find("landmarks"), std::string::npos) << prepared.error().message;
}

TEST_F(FitScanRefuses, ToGoOnWhenAStageHookSaysStop) {
  core::FitOptions options;
  options.on_stage = [](std::string_view stage, double) { return stage != "align"; };
  const auto fit = core::fitScan(*reference_->reference, scan(), landmarks(), "head.ply", options);
  ASSERT_FALSE(fit);
  EXPECT_EQ(fit.error().code, core::ErrorCode::kCancelled);
  EXPECT_NE(fit.error().message.find("align"), std::string::npos) << fit.error().message;
}

// A sphere the size of a head in mm, without landmarks: the search finds no
// head (docs/FIT.md 2.2, the gate's inlier fraction), and the verdict fails
// saying so; the fit itself still comes back, for the diagnostics.
TEST(FitScan, SphereWithoutLandmarksFailsItsVerdictNamingTheAlignment) {
  REQUIRE_ICT_REFERENCE(ref);
  const rigport_test::Icosphere sphere = rigport_test::unitIcosphere(5);
  core::Mesh scan;
  scan.positions = 95.0 * sphere.positions;  // RMS radius 95 mm, as ICT's 9.5 cm
  scan.triangles = sphere.triangles;
  const auto fit = core::fitScan(*ref.reference, scan, {}, "sphere.ply");
  ASSERT_TRUE(fit) << fit.error().message;
  const core::FitReport& r = fit->report;
  std::string reasons;
  for (const std::string& reason : r.reasons) reasons += reason + "; ";
  std::printf("sphere: verdict %s, inlier fraction %.3f; %s\n", r.verdict.c_str(), r.alignment.inlier_fraction,
              reasons.c_str());
  EXPECT_EQ(r.verdict, "fail");
  EXPECT_EQ(r.alignment.method, "search");
  EXPECT_NE(reasons.find("alignment"), std::string::npos) << reasons;
}

}  // namespace
