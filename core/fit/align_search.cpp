// Landmark-free alignment (docs/FIT.md 2.2): trimmed similarity ICP, scan ->
// reference, from a grid of upright starts. Everything is solved as the
// scan_to_reference map (the scan is mostly a subset of the reference, so every
// scan sample has a true counterpart there) and inverted at the end. Each ICP
// step is a Gauss-Newton point-to-plane similarity step (pointToPlaneStep),
// pairs weighted by the reference's vertex density (faceDensities).
#include "core/fit/align_search.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <string>
#include <utility>

#include <Eigen/Geometry>

#include "core/correspond/correspondence.h"

namespace core {
namespace {

constexpr int kMinUsablePoints = 100;
constexpr double kInlierDistance = 0.006;       // of the reference diagonal
constexpr double kDistinctAngleDeg = 10.0;      // hypotheses closer than this are one pose
// ICP stops early once an iteration moves the map less than this (rotation in
// degrees; scale relative; translation of the reference diagonal, 0.05 mm on
// ICT): far below what an identity's shape leaves undetermined (degrees).
constexpr double kConvergedAngleDeg = 0.05;
constexpr double kConvergedRelative = 2e-4;
constexpr double kConvergedMove = 1e-4;
// A start that comes this close to a pose settled before it joins it (stops):
// many starts fall into one basin, and refining each again buys nothing.
constexpr double kSamePoseAngleDeg = 3.0;
constexpr double kSamePoseRelative = 0.01;  // scale; translation of the diagonal

double degToRad(double deg) { return deg * std::numbers::pi / 180.0; }

// Angle of the rotation taking `a` to `b`, degrees.
double rotationAngleDeg(const Eigen::Matrix3d& a, const Eigen::Matrix3d& b) {
  const double c = std::clamp(((a.transpose() * b).trace() - 1.0) / 2.0, -1.0, 1.0);
  return std::acos(c) * 180.0 / std::numbers::pi;
}

Similarity inverse(const Similarity& s) {
  Similarity inv;
  inv.rotation = s.rotation.transpose();
  inv.scale = 1.0 / s.scale;
  inv.translation = -inv.scale * (inv.rotation * s.translation);
  return inv;
}

// The scan's usable points in farthest-point order: any prefix is itself a
// spread sample, so the coarse and fine stages share one sampling.
struct ScanSample {
  Eigen::MatrixX3d points;   // #S by 3, scan frame
  Eigen::MatrixX3d normals;  // #S by 3 unit normals, or 0 rows
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();  // of all usable points
  double rms_radius = 0.0;
};

// One start (and later, fitted) pose and how well it fits.
struct Hypothesis {
  Similarity scan_to_reference;
  double trimmed_rms = std::numeric_limits<double>::infinity();
  double inlier_fraction = 0.0;
  double score = std::numeric_limits<double>::infinity();
  bool failed = false;  // too few compatible pairs to fit
  bool merged = false;  // reached the pose of one settled before it: not a pose of its own
};

// What one correspondence pass found under a pose.
struct Pairs {
  Eigen::MatrixX3d mapped;     // kept scan points under the pose (reference frame)
  Eigen::MatrixX3d reference;  // their closest reference points
  Eigen::MatrixX3d normals;    // the reference's unit normals there (zero where it has none)
  Eigen::VectorXd weights;     // the reference's vertex density there
  double trimmed_rms = std::numeric_limits<double>::infinity();
  double inlier_fraction = 0.0;
};

// One Gauss-Newton step of the similarity that moves the kept pairs' mapped
// points onto the reference: point-to-plane plus a weak point-to-point pull
// (it pins the sliding a plane leaves free). Umeyama on the closest points
// (point-to-point) crawls along the surface: on the synthetic head it was still
// 2 degrees and 1% off after 6 + 20 iterations, where this is within 0.1
// degree after ~5.
Similarity pointToPlaneStep(const Similarity& current, const Pairs& pairs) {
  constexpr double kPointWeight = 0.05;
  const Eigen::Index n = pairs.mapped.rows();
  const Eigen::RowVector3d centre = pairs.mapped.colwise().mean();
  // Unknowns x = (log scale, rotation vector, translation), about `centre`.
  Eigen::Matrix<double, 7, 7> a = Eigen::Matrix<double, 7, 7>::Zero();
  Eigen::Matrix<double, 7, 1> b = Eigen::Matrix<double, 7, 1>::Zero();
  for (Eigen::Index i = 0; i < n; ++i) {
    const Eigen::Vector3d q = (pairs.mapped.row(i) - centre).transpose();
    const Eigen::Vector3d e = (pairs.mapped.row(i) - pairs.reference.row(i)).transpose();
    const Eigen::Vector3d nrm = pairs.normals.row(i).transpose();
    // d(mapped)/dx = [q, -[q]x, I]
    Eigen::Matrix<double, 3, 7> j;
    j.col(0) = q;
    j.block<3, 3>(0, 1) << 0.0, q.z(), -q.y(), -q.z(), 0.0, q.x(), q.y(), -q.x(), 0.0;
    j.block<3, 3>(0, 4).setIdentity();
    const Eigen::Matrix<double, 1, 7> row = nrm.transpose() * j;
    const double w = pairs.weights(i);
    a += w * (row.transpose() * row + kPointWeight * (j.transpose() * j));
    b -= w * (row.transpose() * nrm.dot(e) + kPointWeight * (j.transpose() * e));
  }
  a.diagonal().array() += 1e-12 * a.trace();
  const Eigen::Matrix<double, 7, 1> x = a.ldlt().solve(b);
  const Eigen::Vector3d w = x.segment<3>(1);
  const Eigen::Matrix3d turn =
      w.norm() > 0.0 ? Eigen::AngleAxisd(w.norm(), w / w.norm()).toRotationMatrix() : Eigen::Matrix3d::Identity();
  const double grow = std::exp(x(0));
  // new(p) = grow * turn * (current(p) - centre) + centre + shift
  Similarity next;
  next.rotation = turn * current.rotation;
  next.scale = grow * current.scale;
  next.translation = grow * turn * (current.translation - centre.transpose()) + centre.transpose() + x.segment<3>(4);
  return next;
}

// Per face, the reference's vertex density (1 / area, median 1, clamped to
// [1/20, 20]): pairs weighted by it fit the pose as the reference's vertices
// would (the face, densely meshed, counts more than the skull behind it).
std::vector<double> faceDensities(const SearchReference& reference) {
  const Eigen::Index f = reference.triangles.rows();
  std::vector<double> area(static_cast<std::size_t>(f));
  for (Eigen::Index i = 0; i < f; ++i) {
    const Eigen::Vector3d a = reference.positions.row(reference.triangles(i, 0)).transpose();
    const Eigen::Vector3d b = reference.positions.row(reference.triangles(i, 1)).transpose();
    const Eigen::Vector3d c = reference.positions.row(reference.triangles(i, 2)).transpose();
    area[static_cast<std::size_t>(i)] = (b - a).cross(c - a).norm();
  }
  std::vector<double> weight(area.size(), 1.0);
  if (area.empty()) return weight;
  std::vector<double> sorted = area;
  std::nth_element(sorted.begin(), sorted.begin() + static_cast<std::ptrdiff_t>(sorted.size() / 2), sorted.end());
  const double median = sorted[sorted.size() / 2];
  for (std::size_t i = 0; i < area.size(); ++i) weight[i] = area[i] > 0.0 ? std::clamp(median / area[i], 0.05, 20.0) : 1.0;
  return weight;
}

class Search {
 public:
  Search(const SearchReference& reference, const ScanSample& sample, bool normals_oriented,
         const SearchOptions& options)
      : reference_(reference), sample_(sample), oriented_(normals_oriented), options_(options),
        min_cos_(std::cos(degToRad(std::clamp(options.max_normal_angle_deg, 0.0, 180.0)))),
        inlier_distance_(kInlierDistance * reference.diagonal), face_weight_(faceDensities(reference)) {}

  // Runs `iterations` ICP steps on the first `count` samples, then scores the
  // result; stops early, merged, once it reaches one of `settled`'s poses.
  void refine(Hypothesis& h, int count, int iterations, const std::vector<Hypothesis>& settled) const {
    for (int it = 0;; ++it) {
      const Pairs pairs = match(h.scan_to_reference, count);
      h.trimmed_rms = pairs.trimmed_rms;
      h.inlier_fraction = pairs.inlier_fraction;
      h.failed = pairs.mapped.rows() < 7;
      h.score = h.failed ? std::numeric_limits<double>::infinity()
                         : pairs.trimmed_rms / reference_.diagonal + (1.0 - pairs.inlier_fraction);
      if (h.failed || it == iterations) return;
      const Similarity next = pointToPlaneStep(h.scan_to_reference, pairs);
      if (!(next.scale > 0.0) || !next.translation.allFinite() || !next.rotation.allFinite()) return;
      const bool converged = converges(h.scan_to_reference, next);
      h.scan_to_reference = next;
      if (converged) iterations = it + 1;  // one more pass scores the final pose
      h.merged = std::any_of(settled.begin(), settled.end(), [&](const Hypothesis& s) {
        return !s.failed && !s.merged && samePose(s.scan_to_reference, next);
      });
      if (h.merged) return;
    }
  }

 private:
  bool samePose(const Similarity& a, const Similarity& b) const {
    const double moved = (a.apply(sample_.centroid) - b.apply(sample_.centroid)).norm();
    return rotationAngleDeg(a.rotation, b.rotation) < kSamePoseAngleDeg &&
           std::abs(a.scale / b.scale - 1.0) < kSamePoseRelative && moved < kSamePoseRelative * reference_.diagonal;
  }

  bool converges(const Similarity& a, const Similarity& b) const {
    // The translation compared where it acts: at the mapped scan centroid.
    const double moved = (a.apply(sample_.centroid) - b.apply(sample_.centroid)).norm();
    return rotationAngleDeg(a.rotation, b.rotation) < kConvergedAngleDeg &&
           std::abs(a.scale - b.scale) < kConvergedRelative * a.scale && moved < kConvergedMove * reference_.diagonal;
  }

  // The reference normal at a closest point (barycentric blend of its corners').
  Eigen::Vector3d referenceNormal(const SurfacePoint& p) const {
    Eigen::Vector3d n = Eigen::Vector3d::Zero();
    for (int c = 0; c < 3; ++c) n += p.barycentric(c) * reference_.normals.row(reference_.triangles(p.face, c)).transpose();
    const double len = n.norm();
    return len > 0.0 ? Eigen::Vector3d(n / len) : n;
  }

  Pairs match(const Similarity& scan_to_reference, int count) const {
    Eigen::MatrixX3d queries(count, 3);
    for (int i = 0; i < count; ++i) queries.row(i) = scan_to_reference.apply(sample_.points.row(i).transpose()).transpose();
    const std::vector<SurfacePoint> found = reference_.index->closestPoints(queries);

    const bool check_normals = sample_.normals.rows() > 0;
    std::vector<std::pair<double, int>> compatible;  // (distance, sample): a total order, so the trim is deterministic
    compatible.reserve(static_cast<std::size_t>(count));
    int inliers = 0;
    Eigen::MatrixX3d normals(count, 3);
    for (int i = 0; i < count; ++i) {
      const SurfacePoint& p = found[static_cast<std::size_t>(i)];
      if (!p.found()) continue;
      const Eigen::Vector3d normal = referenceNormal(p);
      if (check_normals) {  // a zero normal (either side) is no test
        const Eigen::Vector3d n = scan_to_reference.rotation * sample_.normals.row(i).transpose();
        const double c = n.dot(normal);
        if (n.squaredNorm() > 0.0 && normal.squaredNorm() > 0.0 && (oriented_ ? c : std::abs(c)) < min_cos_) continue;
      }
      normals.row(i) = normal.transpose();
      const double d = std::sqrt(p.sq_distance);
      if (d <= inlier_distance_) ++inliers;
      compatible.emplace_back(d, i);
    }
    Pairs pairs;
    pairs.inlier_fraction = count > 0 ? static_cast<double>(inliers) / count : 0.0;
    const auto keep = std::min(compatible.size(), static_cast<std::size_t>(std::ceil(
                                                      options_.keep_fraction * static_cast<double>(compatible.size()))));
    if (keep < 7) return pairs;
    std::nth_element(compatible.begin(), compatible.begin() + static_cast<std::ptrdiff_t>(keep - 1), compatible.end());
    pairs.mapped.resize(static_cast<Eigen::Index>(keep), 3);
    pairs.reference.resize(static_cast<Eigen::Index>(keep), 3);
    pairs.normals.resize(static_cast<Eigen::Index>(keep), 3);
    pairs.weights.resize(static_cast<Eigen::Index>(keep));
    double sum_sq = 0.0;
    for (std::size_t k = 0; k < keep; ++k) {
      const auto [d, i] = compatible[k];
      pairs.mapped.row(static_cast<Eigen::Index>(k)) = queries.row(i);
      pairs.reference.row(static_cast<Eigen::Index>(k)) = found[static_cast<std::size_t>(i)].point.transpose();
      pairs.normals.row(static_cast<Eigen::Index>(k)) = normals.row(i);
      const int face = found[static_cast<std::size_t>(i)].face;
      pairs.weights(static_cast<Eigen::Index>(k)) = face_weight_[static_cast<std::size_t>(face)];
      sum_sq += d * d;
    }
    pairs.trimmed_rms = std::sqrt(sum_sq / static_cast<double>(keep));
    return pairs;
  }

  const SearchReference& reference_;
  const ScanSample& sample_;
  bool oriented_;
  const SearchOptions& options_;
  double min_cos_;
  double inlier_distance_;
  std::vector<double> face_weight_;
};

Status checkOptions(const SearchOptions& o) {
  auto bad = [](const std::string& what) { return makeError(ErrorCode::kInvalidArgument, "alignment search: " + what); };
  if (!(o.max_yaw_deg >= 0.0 && o.max_yaw_deg <= 180.0)) return bad("max_yaw_deg must be in [0, 180]");
  if (!(o.yaw_step_deg > 0.0)) return bad("yaw_step_deg must be positive");
  if (!(o.max_tilt_deg >= 0.0 && o.max_tilt_deg <= 90.0)) return bad("max_tilt_deg must be in [0, 90]");
  if (o.coarse_samples < 3 || o.fine_samples < 3) return bad("coarse_samples and fine_samples must be at least 3");
  if (o.coarse_iterations < 0 || o.fine_iterations < 0) return bad("iterations must not be negative");
  if (o.refined_hypotheses < 1) return bad("refined_hypotheses must be at least 1");
  if (!(o.keep_fraction > 0.0 && o.keep_fraction <= 1.0)) return bad("keep_fraction must be in (0, 1]");
  if (!(o.max_normal_angle_deg >= 0.0)) return bad("max_normal_angle_deg must not be negative");
  return Ok{};
}

Result<ScanSample> sampleScan(const Eigen::MatrixX3d& points, const Eigen::MatrixX3d& normals,
                              const std::vector<char>& usable, int count) {
  const Eigen::Index n = points.rows();
  if (normals.rows() != 0 && normals.rows() != n) {
    return makeError(ErrorCode::kInvalidArgument, "alignment search: scan normals must be 0 or " + std::to_string(n) +
                                                      " rows, not " + std::to_string(normals.rows()));
  }
  if (!usable.empty() && static_cast<Eigen::Index>(usable.size()) != n) {
    return makeError(ErrorCode::kInvalidArgument, "alignment search: usable flags must be 0 or " + std::to_string(n) +
                                                      ", not " + std::to_string(usable.size()));
  }
  std::vector<Eigen::Index> rows;
  rows.reserve(static_cast<std::size_t>(n));
  for (Eigen::Index i = 0; i < n; ++i) {
    if ((usable.empty() || usable[static_cast<std::size_t>(i)]) && points.row(i).allFinite()) rows.push_back(i);
  }
  if (static_cast<int>(rows.size()) < kMinUsablePoints) {
    return makeError(ErrorCode::kInvalidMesh, "alignment search: the scan has " + std::to_string(rows.size()) +
                                                  " usable points; at least " + std::to_string(kMinUsablePoints) +
                                                  " are needed");
  }
  Eigen::MatrixX3d kept(static_cast<Eigen::Index>(rows.size()), 3);
  for (std::size_t k = 0; k < rows.size(); ++k) kept.row(static_cast<Eigen::Index>(k)) = points.row(rows[k]);

  ScanSample sample;
  sample.centroid = kept.colwise().mean().transpose();
  sample.rms_radius = std::sqrt((kept.rowwise() - sample.centroid.transpose()).rowwise().squaredNorm().mean());
  if (!(sample.rms_radius > 0.0)) {
    return makeError(ErrorCode::kInvalidMesh, "alignment search: the scan's usable points all coincide");
  }
  const std::vector<int> order = farthestPointSample(kept, count);
  sample.points.resize(static_cast<Eigen::Index>(order.size()), 3);
  if (normals.rows() > 0) sample.normals = Eigen::MatrixX3d::Zero(sample.points.rows(), 3);
  for (std::size_t k = 0; k < order.size(); ++k) {
    const auto row = rows[static_cast<std::size_t>(order[k])];
    sample.points.row(static_cast<Eigen::Index>(k)) = points.row(row);
    // A broken normal stays zero: its pairs skip the normal test.
    if (normals.rows() > 0 && normals.row(row).allFinite()) {
      sample.normals.row(static_cast<Eigen::Index>(k)) = normals.row(row);
    }
  }
  return sample;
}

// The grid of starts: rotation yaw (Y) after pitch (X), reference -> scan;
// scale from the rms radii; the scan centroid onto the reference's front.
std::vector<Hypothesis> startHypotheses(const SearchReference& reference, const ScanSample& sample,
                                        const SearchOptions& options) {
  std::vector<double> yaws;
  const int steps = static_cast<int>(std::floor(2.0 * options.max_yaw_deg / options.yaw_step_deg + 1e-9));
  for (int k = 0; k <= steps; ++k) yaws.push_back(-options.max_yaw_deg + k * options.yaw_step_deg);
  std::vector<double> pitches = {0.0};
  if (options.max_tilt_deg > 0.0) pitches = {-options.max_tilt_deg, 0.0, options.max_tilt_deg};

  const double scale = reference.rms_radius / sample.rms_radius;  // scan -> reference
  std::vector<Hypothesis> starts;
  for (const double pitch : pitches) {
    for (const double yaw : yaws) {
      const Eigen::Matrix3d to_scan = (Eigen::AngleAxisd(degToRad(yaw), Eigen::Vector3d::UnitY()) *
                                       Eigen::AngleAxisd(degToRad(pitch), Eigen::Vector3d::UnitX()))
                                          .toRotationMatrix();
      Hypothesis h;
      h.scan_to_reference.rotation = to_scan.transpose();
      h.scan_to_reference.scale = scale;
      h.scan_to_reference.translation = reference.front_centroid - scale * (to_scan.transpose() * sample.centroid);
      starts.push_back(h);
    }
  }
  return starts;
}

// Indices of `hypotheses` by score, best first (ties: lower index); merged
// ones last, as they stopped before they were scored at their final pose.
double rank(const Hypothesis& h) { return h.merged ? std::numeric_limits<double>::infinity() : h.score; }

std::vector<int> byScore(const std::vector<Hypothesis>& hypotheses) {
  std::vector<int> order(hypotheses.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = static_cast<int>(i);
  auto at = [&](int i) { return rank(hypotheses[static_cast<std::size_t>(i)]); };
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) { return at(a) < at(b); });
  return order;
}

}  // namespace

std::size_t SearchReference::memoryBytes() const {
  std::size_t bytes = sizeof(*this);
  bytes += static_cast<std::size_t>(positions.size() + normals.size()) * sizeof(double);
  bytes += static_cast<std::size_t>(triangles.size()) * sizeof(int);
  if (index) bytes += sizeof(ClosestPointIndex) + index->memoryBytes();
  return bytes;
}

SearchReference prepareSearchReference(const Mesh& reference) {
  SearchReference r;
  r.positions = reference.positions;
  r.triangles = reference.triangles;
  r.normals = reference.normals.rows() == reference.positions.rows()
                  ? reference.normals
                  : computeVertexNormals(reference.positions, reference.triangles);
  r.index = std::make_shared<const ClosestPointIndex>(r.positions, r.triangles);
  const Eigen::Index n = r.positions.rows();
  if (n == 0) return r;

  const Eigen::RowVector3d centroid = r.positions.colwise().mean();
  r.rms_radius = std::sqrt((r.positions.rowwise() - centroid).rowwise().squaredNorm().mean());
  r.diagonal = (r.positions.colwise().maxCoeff() - r.positions.colwise().minCoeff()).norm();
  // The front: vertices facing +Z, on a triangle (an isolated vertex's normal means nothing).
  std::vector<char> on_face(static_cast<std::size_t>(n), 0);
  for (Eigen::Index f = 0; f < r.triangles.rows(); ++f) {
    for (int c = 0; c < 3; ++c) on_face[static_cast<std::size_t>(r.triangles(f, c))] = 1;
  }
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  int front = 0;
  for (Eigen::Index v = 0; v < n; ++v) {
    if (!on_face[static_cast<std::size_t>(v)] || !(r.normals(v, 2) > 0.0)) continue;
    sum += r.positions.row(v).transpose();
    ++front;
  }
  r.front_centroid = front > 0 ? Eigen::Vector3d(sum / front) : Eigen::Vector3d(centroid.transpose());
  return r;
}

Result<SearchAlignment> alignBySearch(const SearchReference& reference, const Eigen::MatrixX3d& scan_points,
                                      const Eigen::MatrixX3d& scan_normals, bool normals_oriented,
                                      const std::vector<char>& usable, const SearchOptions& options) {
  if (auto ok = checkOptions(options); !ok) return ok.error();
  if (!reference.index || reference.index->faceCount() == 0 || !(reference.diagonal > 0.0)) {
    return makeError(ErrorCode::kInvalidMesh, "alignment search: the reference has no faces");
  }
  auto sampled = sampleScan(scan_points, scan_normals, usable, std::max(options.coarse_samples, options.fine_samples));
  if (!sampled) return sampled.error();
  const ScanSample& sample = *sampled;
  const int count = static_cast<int>(sample.points.rows());
  const Search search(reference, sample, normals_oriented, options);

  // Coarse: every start, few samples and iterations.
  std::vector<Hypothesis> coarse = startHypotheses(reference, sample, options);
  {
    std::vector<Hypothesis> settled;
    for (Hypothesis& h : coarse) {
      search.refine(h, std::min(count, options.coarse_samples), options.coarse_iterations, settled);
      settled.push_back(h);
    }
  }

  // Fine: the best distinct poses (starts that converged to one pose are refined once).
  std::vector<int> refined;
  for (const int i : byScore(coarse)) {
    const Hypothesis& h = coarse[static_cast<std::size_t>(i)];
    if (h.failed || static_cast<int>(refined.size()) == options.refined_hypotheses) break;
    if (h.merged) continue;
    const bool distinct = std::all_of(refined.begin(), refined.end(), [&](int j) {
      const Eigen::Matrix3d& other = coarse[static_cast<std::size_t>(j)].scan_to_reference.rotation;
      return rotationAngleDeg(h.scan_to_reference.rotation, other) > kDistinctAngleDeg;
    });
    if (distinct) refined.push_back(i);
  }
  if (refined.empty()) {
    return makeError(ErrorCode::kInvalidMesh, "alignment search: no start found enough scan points facing the reference");
  }
  std::vector<Hypothesis> fine;
  for (const int i : refined) {
    Hypothesis h = coarse[static_cast<std::size_t>(i)];
    search.refine(h, std::min(count, options.fine_samples), options.fine_iterations, fine);
    fine.push_back(h);
  }
  const std::vector<int> fine_order = byScore(fine);
  const Hypothesis& best = fine[static_cast<std::size_t>(fine_order.front())];
  if (best.failed) {
    return makeError(ErrorCode::kInvalidMesh, "alignment search: no start found enough scan points facing the reference");
  }

  SearchAlignment out;
  out.reference_to_scan = inverse(best.scan_to_reference);
  out.reference_to_scan.rms_residual = best.trimmed_rms * out.reference_to_scan.scale;
  out.trimmed_rms = best.trimmed_rms;
  out.inlier_fraction = best.inlier_fraction;
  out.score = best.score;
  out.hypotheses = static_cast<int>(coarse.size());

  // Runner-up: the best refined pose of its own far from the winner (none when
  // every refined start ended in the winner's basin).
  const Hypothesis* runner_up = nullptr;
  for (const int i : fine_order) {
    const Hypothesis& h = fine[static_cast<std::size_t>(i)];
    if (!h.failed && !h.merged &&
        rotationAngleDeg(h.scan_to_reference.rotation, best.scan_to_reference.rotation) > kDistinctAngleDeg) {
      runner_up = &h;
      break;
    }
  }
  if (runner_up != nullptr) {
    out.runner_up_score = runner_up->score;
    out.runner_up_angle_deg = rotationAngleDeg(runner_up->scan_to_reference.rotation, best.scan_to_reference.rotation);
  }
  return out;
}

}  // namespace core
