// The fit's own check (docs/FIT.md 2.9): no ground truth in a job, so what a
// TD would look at: distance to the scan where it has data, how much of the
// face it covers, folds against the reference, landmarks, the alignment.
#include <algorithm>
#include <cstdio>
#include <string>
#include <vector>

#include "core/correspond/correspondence.h"
#include "core/fit/fit_stages.h"

namespace core {

namespace {

// The search's inlier fraction below which no head was found: a sphere
// scores 0.18, the scans 0.46-0.66 (a real face is not the reference, so
// even its true fit scores about 0.43-0.57 at the 0.006 d tolerance).
constexpr double kMinInlierFraction = 0.3;

DistanceStats statsOf(std::vector<double> values) {
  DistanceStats out;
  if (values.empty()) return out;
  std::sort(values.begin(), values.end());
  const auto at = [&](double q) { return values[static_cast<std::size_t>(q * static_cast<double>(values.size() - 1) + 0.5)]; };
  out.median = at(0.5);
  out.p95 = at(0.95);
  out.max = values.back();
  return out;
}

template <class... Args>
std::string formatted(const char* format, Args... args) {
  char text[200];
  std::snprintf(text, sizeof text, format, args...);
  return text;
}

}  // namespace

void gateFit(const FitReference& reference, const FrameMap& frame, const NonRigidFit& fit, const FitOptions& options,
             FitReport& report) {
  (void)options;
  const double to_scan = frame.reference_to_scan.scale;
  const double diagonal = reference.rig->surface.diagonal;
  std::vector<double> face, skin;
  int face_total = 0, skin_total = 0;
  for (std::size_t v = 0; v < fit.covered.size(); ++v) {
    if (!reference.on_skin[v]) continue;
    ++skin_total;
    if (reference.expressive[v]) ++face_total;
    if (!fit.covered[v]) continue;
    skin.push_back(fit.distance[v] * to_scan);
    if (reference.expressive[v]) face.push_back(fit.distance[v] * to_scan);
  }
  report.face_distance = statsOf(face);
  report.skin_distance = statsOf(skin);
  report.face_coverage = face_total > 0 ? static_cast<double>(face.size()) / face_total : 0.0;
  report.skin_coverage = skin_total > 0 ? static_cast<double>(skin.size()) / skin_total : 0.0;
  report.uncovered_vertices = skin_total - static_cast<int>(skin.size());
  const Mesh& mesh = reference.rig->surface.mesh;
  const FoldReport folds = countFolds(mesh.positions, fit.positions, mesh.triangles);
  report.flipped_triangles = folds.flipped;
  report.collapsed_triangles = folds.collapsed;

  // Thresholds as fractions of the reference's diagonal (1 mm ~ 0.0021 d on a head).
  const double d_scan = diagonal * to_scan;
  const double triangles = static_cast<double>(std::max<Eigen::Index>(1, mesh.triangleCount()));
  auto fail = [&](std::string why) { report.reasons.push_back(std::move(why)); report.verdict = "fail"; };
  auto warn = [&](std::string why) {
    report.reasons.push_back(std::move(why));
    if (report.verdict == "ok") report.verdict = "warn";
  };
  if (report.alignment.method == "search" && report.alignment.inlier_fraction < kMinInlierFraction) {
    fail(formatted("the alignment found no head: %.0f%% of the scan lies on the reference (needs %.0f%%); is it a "
                   "head, scanned roughly upright?", 100.0 * report.alignment.inlier_fraction, 100.0 * kMinInlierFraction));
  }
  if (report.face_coverage < 0.7) {
    fail(formatted("the scan covers %.0f%% of the face (needs 70%%)", 100.0 * report.face_coverage));
  } else if (report.face_coverage < 0.9) {
    warn(formatted("the scan covers %.0f%% of the face", 100.0 * report.face_coverage));
  }
  if (report.face_distance.p95 > 0.01 * d_scan) {
    fail(formatted("the fitted face is %.3g scan units from the scan at its 95th percentile (limit %.3g)",
                   report.face_distance.p95, 0.01 * d_scan));
  }
  const double flipped = folds.flipped / triangles;
  if (flipped > 0.01) {
    fail(formatted("%d triangles (%.2f%%) flipped against the reference", folds.flipped, 100.0 * flipped));
  } else if (flipped > 0.001) {
    warn(formatted("%d triangles (%.2f%%) flipped against the reference", folds.flipped, 100.0 * flipped));
  }
  for (const FitLandmarkResidual& l : report.landmarks) {
    if (l.fitted > 0.02 * d_scan) {
      fail("landmark " + l.name + formatted(" is %.3g scan units from the scan's (limit %.3g)", l.fitted, 0.02 * d_scan));
    } else if (l.fitted > 0.006 * d_scan) {
      warn("landmark " + l.name + formatted(" is %.3g scan units from the scan's (over %.3g)", l.fitted, 0.006 * d_scan));
    }
  }
  // A mesh scan whose openings did not take all of the reference's rims
  // (closed eyes, a coarse mesh's small holes): the lids or lips there follow
  // the surface alone, and landmarks read off the fit there are unsure.
  const int rims = static_cast<int>(reference.rims.size());
  if (!report.scan.point_cloud && options.rim_weight > 0.0 && fit.matched_rims < rims) {
    report.warnings.push_back(formatted("%d of the reference's %d mouth and eye rims found no opening of the scan to lie "
                                        "on (closed, or much smaller there): the fit there follows the surface alone",
                                        rims - fit.matched_rims, rims));
  }
  for (const std::string& name : report.alignment.landmarks_dropped) {
    report.warnings.push_back("landmark " + name + " disagrees with the others and was left out of the alignment");
  }
  if (report.scan.size_ratio < 0.7 || report.scan.size_ratio > 1.4) {
    warn(formatted("the head is %.2f times the reference's size in %s: check the units", report.scan.size_ratio,
                   report.scan.units.c_str()));
  }
  if (report.alignment.method == "search" && report.alignment.runner_up_ratio > 0.9) {
    warn(formatted("the alignment is ambiguous: another pose scores %.0f%% as well",
                   100.0 * report.alignment.runner_up_ratio));
  }
}

}  // namespace core
