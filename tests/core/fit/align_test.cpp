// alignByLandmarks, scanUnits and yawPitchRollDeg (core/fit/align.h): a
// click far off is dropped and named (never with only 4), too few landmarks
// are refused; units are read from a head's size in mm, cm, m and inches.
#include "core/fit/align.h"

#include <cmath>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "core/synthetic/synthetic_head.h"
#include "tests/test_support.h"

namespace {

double angleDeg(const Eigen::Matrix3d& a, const Eigen::Matrix3d& b) {
  const double c = std::clamp(((a.transpose() * b).trace() - 1.0) / 2.0, -1.0, 1.0);
  return std::acos(c) * 180.0 / std::numbers::pi;
}

// The 12 landmarks the scans carry (docs/FIT.md section 0).
const std::vector<std::string> kScanLandmarkNames = {"eye_right_0",   "eye_right_3", "eye_left_0",   "eye_left_3",
                                                     "nose_bridge_3", "nose_base_0", "nose_base_4",  "mouth_outer_0",
                                                     "mouth_outer_6", "jaw_08",      "brow_right_2", "brow_left_2"};

// The synthetic head's (metres) landmarks named `names`, and the same under
// a similarity to centimetres (turned 25 degrees, x100, shifted), with 0.5 mm
// of noise on the clicks.
struct Clicks {
  core::LandmarkPairs pairs;
  core::Similarity truth;
};

Clicks headClicks(const std::vector<std::string>& names) {
  const core::SyntheticHead head = core::generateHead();
  auto positions = core::resolveLandmarks(head.landmarks, head.mesh, "head");
  EXPECT_TRUE(positions) << positions.error().message;
  Clicks out;
  out.truth.rotation = Eigen::AngleAxisd(25.0 * std::numbers::pi / 180.0, Eigen::Vector3d(0.3, 1.0, 0.2).normalized())
                           .toRotationMatrix();
  out.truth.scale = 100.0;
  out.truth.translation = Eigen::Vector3d(4.0, -12.0, 30.0);
  std::mt19937 rng(9);
  std::normal_distribution<double> noise(0.0, 0.05);  // cm
  const auto n = static_cast<Eigen::Index>(names.size());
  out.pairs.source.resize(n, 3);
  out.pairs.target.resize(n, 3);
  for (Eigen::Index i = 0; i < n; ++i) {
    const int l = head.landmarks.indexOf(names[static_cast<std::size_t>(i)]);
    EXPECT_GE(l, 0) << names[static_cast<std::size_t>(i)];
    const Eigen::Vector3d p = positions->row(l).transpose();
    out.pairs.names.push_back(names[static_cast<std::size_t>(i)]);
    out.pairs.source.row(i) = p.transpose();
    out.pairs.target.row(i) = (out.truth.apply(p) + Eigen::Vector3d(noise(rng), noise(rng), noise(rng))).transpose();
  }
  return out;
}

constexpr double kDropCm = 1.0;  // what fitScan passes on a head: 0.02 of the diagonal, ~1 cm

TEST(AlignByLandmarks, KeepsEveryGoodClickAndFindsTheSimilarity) {
  const Clicks clicks = headClicks(kScanLandmarkNames);
  core::AlignmentReport report;
  const auto aligned = core::alignByLandmarks(clicks.pairs, kDropCm, report);
  ASSERT_TRUE(aligned) << aligned.error().message;
  EXPECT_TRUE(report.landmarks_dropped.empty());
  EXPECT_EQ(std::count(aligned->kept.begin(), aligned->kept.end(), 1), 12);
  EXPECT_EQ(report.method, "landmarks");
  EXPECT_LT(angleDeg(aligned->reference_to_scan.rotation, clicks.truth.rotation), 0.5);
  EXPECT_NEAR(aligned->reference_to_scan.scale, 100.0, 1.0);
  EXPECT_GT(report.rms_residual, 0.0);
  EXPECT_LT(report.rms_residual, 0.2);  // the clicks' noise, cm
}

TEST(AlignByLandmarks, DropsAndNamesAClickFiveCentimetresOff) {
  Clicks clicks = headClicks(kScanLandmarkNames);
  const int moved = 5;  // nose_base_0
  clicks.pairs.target.row(moved) += Eigen::RowVector3d(3.0, 0.0, 4.0);  // 5 cm
  core::AlignmentReport report;
  const auto aligned = core::alignByLandmarks(clicks.pairs, kDropCm, report);
  ASSERT_TRUE(aligned) << aligned.error().message;
  ASSERT_EQ(report.landmarks_dropped.size(), 1u);
  EXPECT_EQ(report.landmarks_dropped.front(), "nose_base_0");
  for (std::size_t i = 0; i < aligned->kept.size(); ++i) EXPECT_EQ(aligned->kept[i], i == moved ? 0 : 1) << i;
  // Without it the similarity is the true one again.
  EXPECT_LT(angleDeg(aligned->reference_to_scan.rotation, clicks.truth.rotation), 0.5);
  EXPECT_NEAR(aligned->reference_to_scan.scale, 100.0, 1.0);
  EXPECT_LT(report.rms_residual, 0.2);
}

TEST(AlignByLandmarks, WithExactlyFourNothingIsDropped) {
  Clicks clicks = headClicks({"eye_right_0", "eye_left_3", "nose_base_0", "jaw_08"});
  clicks.pairs.target.row(2) += Eigen::RowVector3d(3.0, 0.0, 4.0);  // 5 cm off
  core::AlignmentReport report;
  const auto aligned = core::alignByLandmarks(clicks.pairs, kDropCm, report);
  ASSERT_TRUE(aligned) << aligned.error().message;
  EXPECT_TRUE(report.landmarks_dropped.empty());
  EXPECT_EQ(aligned->kept, std::vector<char>(4, 1));
  EXPECT_GT(report.rms_residual, 0.5);  // the misfit is kept, and shows
}

TEST(AlignByLandmarks, RefusesFewerThanFour) {
  const Clicks clicks = headClicks({"eye_right_0", "eye_left_3", "jaw_08"});
  core::AlignmentReport report;
  const auto aligned = core::alignByLandmarks(clicks.pairs, kDropCm, report);
  ASSERT_FALSE(aligned);
  EXPECT_EQ(aligned.error().code, core::ErrorCode::kInvalidLandmarks);
  EXPECT_NE(aligned.error().message.find("share 3"), std::string::npos) << aligned.error().message;
  EXPECT_NE(aligned.error().message.find("at least 4"), std::string::npos) << aligned.error().message;
}

// A head's RMS radius (ICT: 9.50 cm) as each unit would give it.
constexpr double kHeadRadiusCm = 9.5;
constexpr double kSize = 1.08;  // this head against the reference's, units removed

struct UnitCase {
  const char* name;
  double per_cm;  // units per cm
};
constexpr UnitCase kUnitCases[] = {{"mm", 10.0}, {"cm", 1.0}, {"m", 0.01}, {"in", 1.0 / 2.54}};

TEST(ScanUnits, FindsEachUnitFromAHeadsSize) {
  for (const UnitCase& reference : kUnitCases) {
    const double reference_radius = kHeadRadiusCm * reference.per_cm;
    for (const UnitCase& scan : kUnitCases) {
      const double unit_scale = scan.per_cm / reference.per_cm;  // scan units per reference unit
      for (const double size : {0.8, kSize, 1.35}) {
        const auto units = core::scanUnits(size * unit_scale, reference_radius, "auto");
        ASSERT_TRUE(units) << units.error().message;
        EXPECT_EQ(units->name, scan.name) << "reference in " << reference.name << ", size " << size;
        EXPECT_NEAR(units->unit_scale, unit_scale, 1e-12 * unit_scale) << reference.name << " -> " << scan.name;
        EXPECT_NEAR(units->size_ratio, size, 1e-12) << reference.name << " -> " << scan.name;
      }
    }
  }
}

TEST(ScanUnits, GivenUnitsAreTakenAndOnlyTheSizeMeasured) {
  const double reference_radius = kHeadRadiusCm;  // cm
  const auto mm = core::scanUnits(10.0 * kSize, reference_radius, "mm");
  ASSERT_TRUE(mm) << mm.error().message;
  EXPECT_EQ(mm->name, "mm");
  EXPECT_DOUBLE_EQ(mm->unit_scale, 10.0);
  EXPECT_NEAR(mm->size_ratio, kSize, 1e-12);
  // Given cm for a scan ten times the size: taken, and the size says so.
  const auto cm = core::scanUnits(10.0 * kSize, reference_radius, "cm");
  ASSERT_TRUE(cm) << cm.error().message;
  EXPECT_EQ(cm->name, "cm");
  EXPECT_DOUBLE_EQ(cm->unit_scale, 1.0);
  EXPECT_NEAR(cm->size_ratio, 10.0 * kSize, 1e-12);
  const auto in = core::scanUnits(10.0 * kSize, reference_radius, "in");
  ASSERT_TRUE(in) << in.error().message;
  EXPECT_NEAR(in->unit_scale, 1.0 / 2.54, 1e-12);
}

TEST(ScanUnits, RefusesAnUnknownUnitAndAReferenceOfNoHeadsSize) {
  const auto unknown = core::scanUnits(10.0, kHeadRadiusCm, "furlong");
  ASSERT_FALSE(unknown);
  EXPECT_EQ(unknown.error().code, core::ErrorCode::kInvalidArgument);
  EXPECT_NE(unknown.error().message.find("furlong"), std::string::npos) << unknown.error().message;
  const auto huge = core::scanUnits(1.0, 5e4, "auto");
  ASSERT_FALSE(huge);
  EXPECT_EQ(huge.error().code, core::ErrorCode::kInvalidArgument);
}

TEST(YawPitchRoll, ReadsBackTheAnglesOfAnUprightTurn) {
  const double yaw = 35.0, pitch = -12.0, roll = 8.0;
  const auto rad = [](double deg) { return deg * std::numbers::pi / 180.0; };
  const Eigen::Matrix3d r = (Eigen::AngleAxisd(rad(yaw), Eigen::Vector3d::UnitY()) *
                             Eigen::AngleAxisd(rad(pitch), Eigen::Vector3d::UnitX()) *
                             Eigen::AngleAxisd(rad(roll), Eigen::Vector3d::UnitZ()))
                                .toRotationMatrix();
  const Eigen::Vector3d ypr = core::yawPitchRollDeg(r);
  EXPECT_NEAR(ypr(0), yaw, 1e-9);
  EXPECT_NEAR(ypr(1), pitch, 1e-9);
  EXPECT_NEAR(ypr(2), roll, 1e-9);
}

}  // namespace
