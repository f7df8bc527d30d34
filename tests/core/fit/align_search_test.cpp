#include "core/fit/align_search.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <numbers>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "core/base/parallel.h"
#include "core/base/timing.h"
#include "core/io/mesh_io.h"
#include "core/synthetic/synthetic_head.h"
#include "tests/test_support.h"

namespace {

double rad(double deg) { return deg * std::numbers::pi / 180.0; }

// Roll (Z), then pitch (X), then yaw (Y): a head turned while upright.
Eigen::Matrix3d headTurn(double yaw_deg, double pitch_deg, double roll_deg) {
  return (Eigen::AngleAxisd(rad(yaw_deg), Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(rad(pitch_deg), Eigen::Vector3d::UnitX()) *
          Eigen::AngleAxisd(rad(roll_deg), Eigen::Vector3d::UnitZ()))
      .toRotationMatrix();
}

double angleDeg(const Eigen::Matrix3d& a, const Eigen::Matrix3d& b) {
  const double c = std::clamp(((a.transpose() * b).trace() - 1.0) / 2.0, -1.0, 1.0);
  return std::acos(c) * 180.0 / std::numbers::pi;
}

struct ScanPoints {
  Eigen::MatrixX3d points;
  Eigen::MatrixX3d normals;
};

// The synthetic head as a scan: another sampling of the same surface (so the
// truth is exact), the neck cropped, 0.5 mm noise, then turned, scaled by 10
// and shifted.
ScanPoints syntheticScan(const Eigen::Matrix3d& turn, double scale, const Eigen::Vector3d& shift) {
  core::HeadResolution resolution;
  resolution.columns = 80;
  resolution.rows = 60;
  resolution.jitter = 0.3;
  resolution.seed = 7;
  const core::Mesh head = core::generateHead({}, resolution).mesh;
  std::mt19937 rng(11);
  std::normal_distribution<double> noise(0.0, 0.0005);
  std::vector<Eigen::Index> rows;
  for (Eigen::Index v = 0; v < head.vertexCount(); ++v) {
    if (head.positions(v, 1) > -0.085) rows.push_back(v);
  }
  ScanPoints scan;
  scan.points.resize(static_cast<Eigen::Index>(rows.size()), 3);
  scan.normals.resize(scan.points.rows(), 3);
  for (std::size_t k = 0; k < rows.size(); ++k) {
    const auto i = static_cast<Eigen::Index>(k);
    scan.points.row(i) = head.positions.row(rows[k]) + Eigen::RowVector3d(noise(rng), noise(rng), noise(rng));
    scan.normals.row(i) = head.normals.row(rows[k]);
  }
  scan.points = ((scale * scan.points * turn.transpose()).rowwise() + shift.transpose()).eval();
  scan.normals = (scan.normals * turn.transpose()).eval();
  return scan;
}

// What real scans add: a hole, spikes, a detached piece (an eyeball cap) and
// normals of arbitrary sign.
ScanPoints damaged(ScanPoints scan, const Eigen::Matrix3d& turn, double scale, const Eigen::Vector3d& shift) {
  std::mt19937 rng(5);
  std::uniform_int_distribution<int> pick(0, 49);
  const Eigen::Vector3d cheek = scale * turn * Eigen::Vector3d(0.05, -0.03, 0.06) + shift;
  std::vector<Eigen::RowVector3d> points, normals;
  for (Eigen::Index i = 0; i < scan.points.rows(); ++i) {
    if ((scan.points.row(i).transpose() - cheek).norm() < scale * 0.02) continue;  // a hole
    Eigen::RowVector3d p = scan.points.row(i);
    if (pick(rng) == 0) p += scale * 0.02 * scan.normals.row(i);  // a 2% spike, 2 cm out
    points.push_back(p);
    normals.push_back(pick(rng) % 2 == 0 ? Eigen::RowVector3d(-scan.normals.row(i)) : Eigen::RowVector3d(scan.normals.row(i)));
  }
  const Eigen::Vector3d cap_centre = scale * turn * Eigen::Vector3d(0.03, 0.02, 0.10) + shift;
  for (int k = 0; k < 300; ++k) {  // a 1 cm cap in front of the eye
    const double a = rad(k * 137.5), r = std::sqrt(k / 300.0);
    const Eigen::Vector3d local(r * std::cos(a), r * std::sin(a), std::sqrt(std::max(0.0, 1.0 - r * r)));
    points.push_back((cap_centre + scale * 0.01 * turn * local).transpose());
    normals.push_back((turn * local).transpose());
  }
  scan.points.resize(static_cast<Eigen::Index>(points.size()), 3);
  scan.normals.resize(scan.points.rows(), 3);
  for (std::size_t k = 0; k < points.size(); ++k) {
    scan.points.row(static_cast<Eigen::Index>(k)) = points[k];
    scan.normals.row(static_cast<Eigen::Index>(k)) = normals[k];
  }
  return scan;
}

TEST(AlignSearch, FindsTheSyntheticHeadTurnedScaledAndShifted) {
  const core::SearchReference reference = core::prepareSearchReference(core::generateHead().mesh);
  const Eigen::Vector3d shift(0.4, -1.2, 2.5);
  double worst_angle = 0.0, worst_scale = 0.0;
  for (const double yaw : {-45.0, -25.0, 0.0, 25.0, 45.0}) {
    for (const auto& [pitch, roll] : {std::pair{0.0, 0.0}, {-20.0, -20.0}, {20.0, 20.0}, {20.0, -20.0}, {-20.0, 20.0}}) {
      const Eigen::Matrix3d turn = headTurn(yaw, pitch, roll);
      const ScanPoints scan = syntheticScan(turn, 10.0, shift);
      const auto found = core::alignBySearch(reference, scan.points, scan.normals, true, {});
      ASSERT_TRUE(found.ok()) << found.error().message;
      const double angle = angleDeg(found->reference_to_scan.rotation, turn);
      const double scale_error = std::abs(found->reference_to_scan.scale / 10.0 - 1.0);
      EXPECT_LT(angle, 1.0) << "yaw " << yaw << " pitch " << pitch << " roll " << roll;
      EXPECT_LT(scale_error, 0.005) << "yaw " << yaw << " pitch " << pitch << " roll " << roll;
      EXPECT_LT((found->reference_to_scan.translation - shift).norm(), 0.01) << "yaw " << yaw;
      EXPECT_GT(found->inlier_fraction, 0.9);
      worst_angle = std::max(worst_angle, angle);
      worst_scale = std::max(worst_scale, scale_error);
    }
  }
  std::printf("synthetic, 25 poses: worst rotation error %.3f deg, worst scale error %.4f\n", worst_angle, worst_scale);
}

TEST(AlignSearch, ShrugsOffHolesSpikesADetachedPieceAndUnorientedNormals) {
  const core::SearchReference reference = core::prepareSearchReference(core::generateHead().mesh);
  const Eigen::Vector3d shift(-3.0, 0.5, 1.0);
  for (const auto& [yaw, pitch, roll] : {std::tuple{40.0, 15.0, -10.0}, {-40.0, -15.0, 10.0}, {0.0, 20.0, 0.0}}) {
    const Eigen::Matrix3d turn = headTurn(yaw, pitch, roll);
    const ScanPoints scan = damaged(syntheticScan(turn, 10.0, shift), turn, 10.0, shift);
    const auto found = core::alignBySearch(reference, scan.points, scan.normals, false, {});
    ASSERT_TRUE(found.ok()) << found.error().message;
    const double angle = angleDeg(found->reference_to_scan.rotation, turn);
    std::printf("damaged synthetic yaw %+.0f: rotation error %.3f deg, scale error %+.4f, inliers %.3f\n", yaw, angle,
                found->reference_to_scan.scale / 10.0 - 1.0, found->inlier_fraction);
    EXPECT_LT(angle, 1.0) << "yaw " << yaw;
    EXPECT_LT(std::abs(found->reference_to_scan.scale / 10.0 - 1.0), 0.01) << "yaw " << yaw;
  }
}

TEST(AlignSearch, ResultsDoNotDependOnTheThreadCount) {
  const core::SearchReference reference = core::prepareSearchReference(core::generateHead().mesh);
  const ScanPoints scan = syntheticScan(headTurn(30.0, -10.0, 5.0), 10.0, Eigen::Vector3d(1.0, 0.0, 0.0));
  auto run = [&](int threads) {
    const core::ScopedThreadCount scoped(threads);
    return core::alignBySearch(reference, scan.points, scan.normals, true, {});
  };
  const auto one = run(1);
  const auto three = run(3);
  ASSERT_TRUE(one.ok() && three.ok());
  EXPECT_EQ(one->reference_to_scan.rotation, three->reference_to_scan.rotation);
  EXPECT_EQ(one->reference_to_scan.scale, three->reference_to_scan.scale);
  EXPECT_EQ(one->reference_to_scan.translation, three->reference_to_scan.translation);
  EXPECT_EQ(one->score, three->score);
  EXPECT_EQ(one->runner_up_score, three->runner_up_score);
}

TEST(AlignSearch, RefusesTooFewUsablePointsAndMismatchedArguments) {
  const core::SearchReference reference = core::prepareSearchReference(core::generateHead().mesh);
  const Eigen::MatrixX3d points = rigport_test::randomPoints(150, 3);
  std::vector<char> usable(150, 1);
  std::fill(usable.begin(), usable.begin() + 60, 0);
  const auto few = core::alignBySearch(reference, points, {}, false, usable);
  ASSERT_FALSE(few.ok());
  EXPECT_EQ(few.error().code, core::ErrorCode::kInvalidMesh);
  EXPECT_NE(few.error().message.find("90 usable points"), std::string::npos) << few.error().message;

  const auto normals = core::alignBySearch(reference, points, Eigen::MatrixX3d::Zero(10, 3), false, {});
  ASSERT_FALSE(normals.ok());
  EXPECT_EQ(normals.error().code, core::ErrorCode::kInvalidArgument);

  const auto flags = core::alignBySearch(reference, points, {}, false, std::vector<char>(20, 1));
  ASSERT_FALSE(flags.ok());
  EXPECT_EQ(flags.error().code, core::ErrorCode::kInvalidArgument);

  core::SearchOptions options;
  options.keep_fraction = 0.0;
  const auto bad = core::alignBySearch(reference, points, {}, false, {}, options);
  ASSERT_FALSE(bad.ok());
  EXPECT_EQ(bad.error().code, core::ErrorCode::kInvalidArgument);
}

// --- The ICT reference and the scans of ../shared/data ---

class AlignSearchData : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    const auto data = rigport_test::sharedDataDir();
    if (!data) return;
    auto loaded = core::readMesh(*data / "ict" / "source_face_skinned.glb");
    ASSERT_TRUE(loaded.ok()) << loaded.error().message;
    reference_mesh_ = new core::Mesh(std::move(loaded->mesh));
    reference_ = new core::SearchReference(core::prepareSearchReference(*reference_mesh_));
  }
  static void TearDownTestSuite() {
    delete reference_;
    delete reference_mesh_;
    reference_ = nullptr;
    reference_mesh_ = nullptr;
  }
  // The true reference_to_scan: Umeyama from the reference to its true fit (same vertices).
  static core::Similarity truth(const std::filesystem::path& gt) {
    auto fitted = core::readMesh(gt);
    EXPECT_TRUE(fitted.ok()) << fitted.error().message;
    if (!fitted.ok() || fitted->mesh.vertexCount() != reference_mesh_->vertexCount()) return {};
    return core::fitSimilarity(reference_mesh_->positions, fitted->mesh.positions);
  }
  static core::Mesh* reference_mesh_;
  static core::SearchReference* reference_;
};
core::Mesh* AlignSearchData::reference_mesh_ = nullptr;
core::SearchReference* AlignSearchData::reference_ = nullptr;

TEST_F(AlignSearchData, FindsEachScansPoseAndSize) {
  RIGPORT_REQUIRE_SHARED_DATA(data);
  ASSERT_NE(reference_, nullptr);
  struct Case {
    const char* file;
    const char* gt;
    double max_angle_deg;
    double max_scale_error;
  };
  // s02: its identity's own shape tilts the surface fit ~5 degrees (pitch)
  // from the vertex-to-vertex truth; the truth's own surface, aligned as a
  // scan, lands as far off (TheCloudsTiltIsItsIdentitys). The cartoon is stylised.
  const Case cases[] = {
      {"scan_s01.ply", "scan_s01.gt.glb", 2.0, 0.03},
      {"scan_s02_cloud.ply", "scan_s02_cloud.gt.glb", 7.0, 0.04},  // scale moves with the tilt: +1-3% measured
      {"scan_s03_obj.obj", "scan_s03_obj.gt.glb", 2.0, 0.03},
      {"scan_s04_cartoon.ply", "scan_s04_cartoon.gt.glb", 5.0, 0.03},
  };
  for (const Case& c : cases) {
    auto scan = core::readMesh(data / "scans" / c.file);
    ASSERT_TRUE(scan.ok()) << scan.error().message;
    const core::Similarity expected = truth(data / "scans" / c.gt);
    // Mesh normals follow the winding; the cloud's come from its file, oriented.
    core::Result<core::SearchAlignment> found = core::makeError(core::ErrorCode::kIo, "not run");
    // CPU time as well: wall time on a shared machine measures the neighbours.
    const std::clock_t cpu0 = std::clock();
    const auto t0 = core::Clock::now();
    {
      const core::ScopedThreadCount single(1);
      found = core::alignBySearch(*reference_, scan->mesh.positions, scan->mesh.normals, true, {});
    }
    const double ms = core::msSince(t0);
    const double cpu_ms = 1000.0 * static_cast<double>(std::clock() - cpu0) / CLOCKS_PER_SEC;
    ASSERT_TRUE(found.ok()) << c.file << ": " << found.error().message;
    const double angle = angleDeg(found->reference_to_scan.rotation, expected.rotation);
    const double scale_error = found->reference_to_scan.scale / expected.scale - 1.0;
    std::printf("%-21s %6d points: rotation error %.2f deg, scale error %+.4f, trimmed rms %.3f cm, inliers %.3f, "
                "score %.3f, runner-up %.3f at %.1f deg, 1 thread: %.0f ms (%.0f ms CPU)\n",
                c.file, static_cast<int>(scan->mesh.vertexCount()), angle, scale_error, found->trimmed_rms,
                found->inlier_fraction, found->score, found->runner_up_score, found->runner_up_angle_deg, ms, cpu_ms);
    EXPECT_LT(angle, c.max_angle_deg) << c.file;
    EXPECT_LT(std::abs(scale_error), c.max_scale_error) << c.file;
    EXPECT_GT(found->inlier_fraction, 0.4) << c.file;
  }
}

TEST_F(AlignSearchData, TheCloudsTiltIsItsIdentitys) {
  RIGPORT_REQUIRE_SHARED_DATA(data);
  ASSERT_NE(reference_, nullptr);
  auto fitted = core::readMesh(data / "scans" / "scan_s02_cloud.gt.glb");
  ASSERT_TRUE(fitted.ok()) << fitted.error().message;
  // The true fit's own surface as the scan: no noise, caps, spikes or crop,
  // only the identity's shape; its surface fit still tilts away from the
  // vertex-to-vertex truth (and is flat along that tilt: a few degrees either way).
  const auto found = core::alignBySearch(*reference_, fitted->mesh.positions, fitted->mesh.normals, true, {});
  ASSERT_TRUE(found.ok()) << found.error().message;
  const core::Similarity expected = core::fitSimilarity(reference_mesh_->positions, fitted->mesh.positions);
  const double angle = angleDeg(found->reference_to_scan.rotation, expected.rotation);
  std::printf("s02's true surface as the scan: %.2f deg from the vertex truth\n", angle);
  EXPECT_GT(angle, 3.0);
}

TEST_F(AlignSearchData, FindsTheCloudWithNormalsOfArbitrarySign) {
  RIGPORT_REQUIRE_SHARED_DATA(data);
  ASSERT_NE(reference_, nullptr);
  auto scan = core::readMesh(data / "scans" / "scan_s02_cloud.ply");
  ASSERT_TRUE(scan.ok()) << scan.error().message;
  const core::Similarity expected = truth(data / "scans" / "scan_s02_cloud.gt.glb");
  const auto oriented = core::alignBySearch(*reference_, scan->mesh.positions, scan->mesh.normals, true, {});
  // Every other normal flipped, as a cloud's estimated normals come.
  Eigen::MatrixX3d normals = scan->mesh.normals;
  for (Eigen::Index i = 0; i < normals.rows(); i += 2) normals.row(i) *= -1.0;
  const auto found = core::alignBySearch(*reference_, scan->mesh.positions, normals, false, {});
  ASSERT_TRUE(found.ok() && oriented.ok());
  const double angle = angleDeg(found->reference_to_scan.rotation, expected.rotation);
  const double from_oriented = angleDeg(found->reference_to_scan.rotation, oriented->reference_to_scan.rotation);
  std::printf("s02 unoriented: rotation error %.2f deg (%.2f from the oriented run), scale error %+.4f, inliers %.3f\n",
              angle, from_oriented, found->reference_to_scan.scale / expected.scale - 1.0, found->inlier_fraction);
  EXPECT_LT(angle, 7.0);
  EXPECT_LT(from_oriented, 3.0);  // along the flat tilt (TheCloudsTiltIsItsIdentitys)
  EXPECT_LT(std::abs(found->reference_to_scan.scale / expected.scale - 1.0), 0.03);
}

TEST_F(AlignSearchData, ASphereIsNoHead) {
  RIGPORT_REQUIRE_SHARED_DATA(data);
  ASSERT_NE(reference_, nullptr);
  // A head-sized ball in mm (10k points) with outward normals.
  const rigport_test::Icosphere sphere = rigport_test::unitIcosphere(5);
  const Eigen::MatrixX3d points = ((95.0 * sphere.positions).rowwise() + Eigen::RowVector3d(10.0, 20.0, -5.0)).eval();
  for (const bool oriented : {true, false}) {
    const auto found = core::alignBySearch(*reference_, points, sphere.positions, oriented, {});
    ASSERT_TRUE(found.ok()) << found.error().message;
    std::printf("sphere (normals %s): inliers %.3f, trimmed rms %.3f cm, score %.3f, runner-up %.3f at %.1f deg\n",
                oriented ? "oriented" : "unoriented", found->inlier_fraction, found->trimmed_rms, found->score,
                found->runner_up_score, found->runner_up_angle_deg);
    // The scans: 0.47-0.66 (FindsEachScansPoseAndSize asserts > 0.4).
    EXPECT_LT(found->inlier_fraction, 0.3);
    EXPECT_GT(found->score, 0.7);
  }
}

}  // namespace
