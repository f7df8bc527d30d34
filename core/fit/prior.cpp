#include <algorithm>
#include <cmath>
#include <vector>

#include "core/fit/fit_stages.h"
#include "core/geometry/similarity.h"
#include "core/solve/tps.h"

namespace core {

namespace {

constexpr int kIterations = 10;
constexpr double kKeepFraction = 0.95;   // trimmed ICP: the closest share of pairs fits each step
constexpr double kMinCosine = 0.5;       // pairs whose normals differ by more than 60 degrees are dropped
constexpr int kLandmarkRepeats = 20;     // each landmark counts as this many pairs
constexpr double kAnchorDistance = 0.1;  // fraction of the diagonal (5 cm on a head)

struct Pair {
  double distance;
  Eigen::Vector3d from, to;
};

Eigen::Vector3d applyAffine(const AffineMap& map, const Eigen::Vector3d& p) { return map.linear * p + map.translation; }

}  // namespace

// Anchors: dense-map centres farther than kAnchorDistance from every
// landmark, kept where the prior has them: the face's features move to the
// clicks, the rest of the head keeps its shape.
Eigen::MatrixX3d correctAtLandmarks(const FitReference& reference, const LandmarkTargets& landmarks,
                                    Eigen::MatrixX3d prior) {
  const PreparedSource& surface = reference.rig->surface;
  if (landmarks.vertices.size() < 4) return prior;
  const double anchor_distance = kAnchorDistance * surface.diagonal;
  std::vector<int> anchors;
  for (const int v : surface.dense_vertices) {
    bool far = true;
    for (const int l : landmarks.vertices) {
      far = far && (surface.mesh.positions.row(v) - surface.mesh.positions.row(l)).norm() > anchor_distance;
    }
    if (far) anchors.push_back(v);
  }
  const auto nl = static_cast<Eigen::Index>(landmarks.vertices.size());
  Eigen::MatrixX3d from(nl + static_cast<Eigen::Index>(anchors.size()), 3), to(from.rows(), 3);
  for (Eigen::Index i = 0; i < nl; ++i) {
    from.row(i) = prior.row(landmarks.vertices[static_cast<std::size_t>(i)]);
    to.row(i) = landmarks.targets.row(i);
  }
  for (std::size_t i = 0; i < anchors.size(); ++i) {
    from.row(nl + static_cast<Eigen::Index>(i)) = prior.row(anchors[i]);
    to.row(nl + static_cast<Eigen::Index>(i)) = prior.row(anchors[i]);
  }
  TpsOptions tps;
  tps.leave_one_out = false;
  auto warp = fitTps(from, to, tps);
  return warp ? warp->apply(prior) : prior;
}

Eigen::MatrixX3d fitPrior(const FitReference& reference, const ScanSurface& scan, const FrameMap& frame,
                          const LandmarkTargets& landmarks) {
  const PreparedSource& surface = reference.rig->surface;
  const Mesh& mesh = surface.mesh;
  std::vector<int> sample;
  for (const int v : surface.projection_sample) {
    if (reference.on_skin[static_cast<std::size_t>(v)]) sample.push_back(v);
  }
  AffineMap map;
  Eigen::MatrixX3d queries(static_cast<Eigen::Index>(sample.size()), 3);
  for (int iteration = 0; iteration < kIterations && !sample.empty(); ++iteration) {
    for (std::size_t i = 0; i < sample.size(); ++i) {
      queries.row(static_cast<Eigen::Index>(i)) = applyAffine(map, mesh.positions.row(sample[i]).transpose()).transpose();
    }
    const FrameMatches found = matchInReferenceFrame(scan, frame, queries);
    const Eigen::Matrix3d normal_map = map.linear.inverse().transpose();
    std::vector<Pair> pairs;
    for (std::size_t i = 0; i < sample.size(); ++i) {
      const ScanMatch& m = found.matches[i];
      if (!m.found || (m.flags & (kScanBorder | kScanSpike | kScanDetached))) continue;
      const Eigen::Vector3d n = (normal_map * mesh.normals.row(sample[i]).transpose()).normalized();
      const double cosine = n.dot(m.normal);
      if ((scan.report.normals_computed ? std::abs(cosine) : cosine) < kMinCosine) continue;
      pairs.push_back({m.distance, mesh.positions.row(sample[i]).transpose(), m.point});
    }
    if (pairs.size() < 16) break;
    std::sort(pairs.begin(), pairs.end(), [](const Pair& a, const Pair& b) { return a.distance < b.distance; });
    pairs.resize(static_cast<std::size_t>(kKeepFraction * static_cast<double>(pairs.size())));
    const auto rows = static_cast<Eigen::Index>(pairs.size() + kLandmarkRepeats * landmarks.vertices.size());
    Eigen::MatrixX3d from(rows, 3), to(rows, 3);
    Eigen::Index r = 0;
    for (const Pair& p : pairs) {
      from.row(r) = p.from.transpose();
      to.row(r++) = p.to.transpose();
    }
    for (std::size_t l = 0; l < landmarks.vertices.size(); ++l) {
      for (int k = 0; k < kLandmarkRepeats; ++k) {
        from.row(r) = mesh.positions.row(landmarks.vertices[l]);
        to.row(r++) = landmarks.targets.row(static_cast<Eigen::Index>(l));
      }
    }
    const auto fitted = fitAffine(from, to);
    if (!fitted || !(fitted->linear.determinant() > 0.0)) break;
    map = *fitted;
  }
  Eigen::MatrixX3d prior = (mesh.positions * map.linear.transpose()).rowwise() + map.translation.transpose();
  return correctAtLandmarks(reference, landmarks, std::move(prior));
}

}  // namespace core
