#include "core/fit/align.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <string>
#include <vector>

namespace core {

namespace {

constexpr double kDegrees = 180.0 / std::numbers::pi;

struct Unit {
  const char* name;
  double metres;
};
constexpr std::array<Unit, 4> kUnits{{{"mm", 0.001}, {"cm", 0.01}, {"m", 1.0}, {"in", 0.0254}}};

Similarity fitRows(const LandmarkPairs& pairs, const std::vector<char>& kept) {
  const auto n = static_cast<Eigen::Index>(std::count(kept.begin(), kept.end(), 1));
  Eigen::MatrixX3d source(n, 3), target(n, 3);
  for (Eigen::Index i = 0, k = 0; i < pairs.source.rows(); ++i) {
    if (!kept[static_cast<std::size_t>(i)]) continue;
    source.row(k) = pairs.source.row(i);
    target.row(k++) = pairs.target.row(i);
  }
  return fitSimilarity(source, target);
}

}  // namespace

Result<LandmarkAlignment> alignByLandmarks(const LandmarkPairs& pairs, double drop_distance, AlignmentReport& report) {
  const Eigen::Index n = pairs.source.rows();
  if (n < 4) {
    return Error{ErrorCode::kInvalidLandmarks, "the scan's landmarks share " + std::to_string(n) +
                                                   " names with the reference's; the alignment needs at least 4"};
  }
  LandmarkAlignment out;
  out.kept.assign(static_cast<std::size_t>(n), 1);
  // Leave-one-out misfit: a click far off is named and dropped, once (with
  // 4 landmarks nothing can be left out).
  if (n > 4) {
    std::vector<double> misfit(static_cast<std::size_t>(n));
    for (Eigen::Index i = 0; i < n; ++i) {
      std::vector<char> others(static_cast<std::size_t>(n), 1);
      others[static_cast<std::size_t>(i)] = 0;
      const Similarity s = fitRows(pairs, others);
      misfit[static_cast<std::size_t>(i)] = (s.apply(pairs.source.row(i).transpose()) - pairs.target.row(i).transpose()).norm();
    }
    std::vector<double> sorted = misfit;
    std::nth_element(sorted.begin(), sorted.begin() + n / 2, sorted.end());
    const double median = sorted[static_cast<std::size_t>(n / 2)];
    const auto worst = static_cast<Eigen::Index>(std::max_element(misfit.begin(), misfit.end()) - misfit.begin());
    if (misfit[static_cast<std::size_t>(worst)] > std::max(3.0 * median, drop_distance)) {
      out.kept[static_cast<std::size_t>(worst)] = 0;
      report.landmarks_dropped.push_back(pairs.names[static_cast<std::size_t>(worst)]);
    }
  }
  out.reference_to_scan = fitRows(pairs, out.kept);
  report.method = "landmarks";
  report.rms_residual = out.reference_to_scan.rms_residual;
  return out;
}

Result<ScanUnits> scanUnits(double scale, double reference_rms_radius, const std::string& given) {
  // The reference's unit: the one that makes its RMS radius a head's (6-16
  // cm), the nearest to ~10 cm (log scale) when two do (cm and in overlap).
  const Unit* reference_unit = nullptr;
  double closest = std::numeric_limits<double>::infinity();
  for (const Unit& u : kUnits) {
    const double radius_cm = reference_rms_radius * u.metres * 100.0;
    const double off = std::abs(std::log(radius_cm / 10.0));
    if (radius_cm >= 6.0 && radius_cm <= 16.0 && off < closest) {
      closest = off;
      reference_unit = &u;
    }
  }
  if (reference_unit == nullptr) {
    return Error{ErrorCode::kInvalidArgument,
                 "the reference is no head's size in mm, cm, m or in (RMS radius " + std::to_string(reference_rms_radius) +
                     "): give the scan's \"units\""};
  }
  ScanUnits out;
  double best = std::numeric_limits<double>::infinity();
  for (const Unit& u : kUnits) {
    const double unit_scale = reference_unit->metres / u.metres;
    const double off = std::abs(std::log(scale / unit_scale));
    if (given == u.name || (given == "auto" && off < best)) {
      best = off;
      out.name = u.name;
      out.unit_scale = unit_scale;
    }
  }
  if (out.name.empty()) {
    return Error{ErrorCode::kInvalidArgument, "units \"" + given + "\" is not one of auto, mm, cm, m, in"};
  }
  out.size_ratio = scale / out.unit_scale;
  return out;
}

Eigen::Vector3d yawPitchRollDeg(const Eigen::Matrix3d& r) {
  // r = Ry(yaw) * Rx(pitch) * Rz(roll)
  const double pitch = std::asin(std::clamp(-r(1, 2), -1.0, 1.0));
  const double yaw = std::atan2(r(0, 2), r(2, 2));
  const double roll = std::atan2(r(1, 0), r(1, 1));
  return Eigen::Vector3d(yaw, pitch, roll) * kDegrees;
}

}  // namespace core
