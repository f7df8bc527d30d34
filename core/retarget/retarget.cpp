// Facial mocap retargeting by RBF with Euclidean, geodesic and hybrid
// distances. Papers: 002 (Ramos Carretero 2019, "AnimFace") chapters 4-5:
// eq. 5.1, algorithm 4.1 (marker transfer; here with a similarity + TPS
// Jacobian calibration instead of 1:1 offsets), algorithm 4.2 (per-frame RBF;
// here all frames in one solve). The distances (algorithms 5.3-5.4) are in
// marker_distances.cpp. Umeyama 1991 (similarity), Bookstein 1989 (TPS).
//
// Baking: the displacement field X (#frames by 3#V) equals C Q^T, with C the
// solved weights in an orthonormal basis of the kernel columns (#frames by
// 3r, r <= #markers + terms) and Q orthonormal (#V by r). Its SVD is that of
// the small C, so rank selection never forms X; the kept modes are evaluated
// on the vertices with one (#V by #markers) x (#markers by 3 rank) product.
#include "core/retarget/retarget.h"

#include "core/base/timing.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numeric>

#include <Eigen/Eigenvalues>
#include <Eigen/SVD>
#include <nlohmann/json.hpp>

#include "core/solve/geodesic.h"
#include "core/base/parallel.h"
#include "core/geometry/similarity.h"
#include "core/solve/tps.h"

namespace core {

namespace {

// Calibration: per-marker linear maps of mocap displacements into mesh space.
struct Calibration {
  std::vector<Eigen::Matrix3d> maps;  // #M: J_i * s * R
  Similarity similarity;
  double similarity_rms = 0.0;
  double min_singular = 0.0, max_singular = 0.0;
};

Result<Calibration> calibrate(const Eigen::MatrixX3d& rest, const Eigen::MatrixX3d& placed, const RetargetOptions& options) {
  Calibration c;
  c.similarity = fitSimilarity(rest, placed);
  const Eigen::MatrixX3d aligned =
      ((c.similarity.scale * rest * c.similarity.rotation.transpose()).rowwise() + c.similarity.translation.transpose()).eval();
  c.similarity_rms = c.similarity.rms_residual;
  const Eigen::Matrix3d linear = c.similarity.scale * c.similarity.rotation;
  std::vector<Eigen::Matrix3d> jacobians(static_cast<std::size_t>(rest.rows()), Eigen::Matrix3d::Identity());
  if (options.calibration_jacobian) {
    TpsOptions tps;
    tps.regularization = options.calibration_regularization * boundingBoxDiagonal(placed);
    tps.leave_one_out = false;
    tps.threads = 1;
    auto warp = fitTps(aligned, placed, tps);
    if (!warp) return warp.error();
    jacobians = warp->jacobians(aligned);
  }
  c.min_singular = std::numeric_limits<double>::infinity();
  for (const Eigen::Matrix3d& j : jacobians) {
    const Eigen::Vector3d sv = Eigen::JacobiSVD<Eigen::Matrix3d>(j).singularValues();
    c.min_singular = std::min(c.min_singular, sv(2));
    c.max_singular = std::max(c.max_singular, sv(0));
    c.maps.push_back(j * linear);
  }
  return c;
}

// The bake of the displacement field into modes.
struct Modes {
  Eigen::MatrixXd coefficients;  // #K by 3*rank: RBF weights of each mode's x, y, z (already scaled)
  Eigen::MatrixXd weights;       // #frames by rank, max |w| = 1 per mode
  std::vector<double> singular_values;
  int rank = 0;
  double relative_error = 0.0, rms_error = 0.0, max_error_bound = 0.0;
  bool tolerance_met = true;
  Eigen::MatrixXd residual_coefficients;  // #K by 3*#frames (x block, y block, z block): for the measured max
};

// weights: #K by 3F solved RBF weights (column 3f + c); basis: #V by #K.
Modes compressModes(const Eigen::MatrixXd& weights, const Eigen::MatrixXd& basis, const BakeOptions& options,
                    bool keep_residual) {
  const Eigen::Index nk = weights.rows(), nf = weights.cols() / 3, nv = basis.rows();
  Modes out;
  // Orthonormal coordinates of the basis columns: G = Phi^T Phi = E L E^T,
  // Phi = Q L^1/2 E^T with Q orthonormal on the kept eigenvalues.
  const Eigen::MatrixXd gram = basis.transpose() * basis;
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> ge(gram);
  const Eigen::VectorXd lambda = ge.eigenvalues();
  const double lmax = lambda.maxCoeff();
  std::vector<Eigen::Index> kept;
  for (Eigen::Index i = 0; i < nk; ++i) {
    if (lambda(i) > 1e-12 * lmax && lmax > 0.0) kept.push_back(i);
  }
  const Eigen::Index r0 = static_cast<Eigen::Index>(kept.size());
  Eigen::MatrixXd t(nk, r0), t_inv(nk, r0);  // E L^1/2 and E L^-1/2
  for (Eigen::Index j = 0; j < r0; ++j) {
    const Eigen::Index i = kept[static_cast<std::size_t>(j)];
    t.col(j) = ge.eigenvectors().col(i) * std::sqrt(lambda(i));
    t_inv.col(j) = ge.eigenvectors().col(i) / std::sqrt(lambda(i));
  }
  // C = [W_x^T T, W_y^T T, W_z^T T]: #F by 3 r0.
  Eigen::MatrixXd c(nf, 3 * r0);
  for (int k = 0; k < 3; ++k) {
    const Eigen::Map<const Eigen::MatrixXd, 0, Eigen::OuterStride<>> wk(weights.data() + k * nk, nk, nf,
                                                                        Eigen::OuterStride<>(3 * nk));
    c.middleCols(k * r0, r0).noalias() = wk.transpose() * t;
  }
  const Eigen::MatrixXd h = c.transpose() * c;
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> he(h);
  const Eigen::Index n = h.rows();
  Eigen::VectorXd sigma2(n);
  Eigen::MatrixXd v(n, n);
  for (Eigen::Index j = 0; j < n; ++j) {  // descending
    sigma2(j) = std::max(0.0, he.eigenvalues()(n - 1 - j));
    v.col(j) = he.eigenvectors().col(n - 1 - j);
  }
  const Eigen::MatrixXd y = c * v;  // #F by n: U S
  const double total = sigma2.sum();
  for (Eigen::Index j = 0; j < std::min<Eigen::Index>(n, 2 * options.max_rank); ++j) out.singular_values.push_back(std::sqrt(sigma2(j)));

  // Rank selection.
  const Eigen::Index cap = std::min<Eigen::Index>({n, nf, static_cast<Eigen::Index>(std::max(1, options.max_rank))});
  Eigen::VectorXd tail(n + 1);  // tail(r) = sum_{j >= r} sigma2
  tail(n) = 0.0;
  for (Eigen::Index j = n - 1; j >= 0; --j) tail(j) = tail(j + 1) + sigma2(j);
  const double q_max = (basis * t_inv).rowwise().norm().maxCoeff();
  Eigen::VectorXd frame_residual2 = c.rowwise().squaredNorm();  // ||C_perp(f)||^2 at rank 0
  auto bound = [&](const Eigen::VectorXd& fr2) { return q_max * std::sqrt(std::max(0.0, fr2.maxCoeff())); };
  Eigen::Index rank = 0;
  if (total > 0.0) {
    rank = cap;
    for (Eigen::Index r = 0; r <= cap; ++r) {
      if (r > 0) frame_residual2 -= y.col(r - 1).cwiseAbs2();
      const bool met = options.metric == BakeError::kRelativeFrobenius ? std::sqrt(tail(r) / total) <= options.tolerance
                                                                       : bound(frame_residual2) <= options.tolerance;
      if (met) {
        rank = r;
        break;
      }
    }
    // frame_residual2 now matches `rank` (or cap when the tolerance was missed).
  }
  out.tolerance_met = total == 0.0 ||
                      (options.metric == BakeError::kRelativeFrobenius ? std::sqrt(tail(rank) / total) <= options.tolerance
                                                                       : bound(frame_residual2) <= options.tolerance);
  out.relative_error = total > 0.0 ? std::sqrt(tail(rank) / total) : 0.0;
  out.rms_error = std::sqrt(tail(rank) / static_cast<double>(std::max<Eigen::Index>(1, nv * nf)));
  out.max_error_bound = bound(frame_residual2);
  out.rank = static_cast<int>(std::max<Eigen::Index>(rank, 1));  // at least one (zero) target for a motionless clip

  out.coefficients = Eigen::MatrixXd::Zero(nk, 3 * out.rank);
  out.weights = Eigen::MatrixXd::Zero(nf, out.rank);
  for (Eigen::Index j = 0; j < rank; ++j) {
    const double s = std::sqrt(sigma2(j));
    if (s <= 0.0) continue;
    Eigen::Index fmax = 0;
    y.col(j).cwiseAbs().maxCoeff(&fmax);
    const double peak = y(fmax, j);  // signed: the peak weight is +1
    out.weights.col(j) = y.col(j) / peak;
    for (int k = 0; k < 3; ++k) out.coefficients.col(3 * j + k) = peak * (t_inv * v.block(k * r0, j, r0, 1));
  }
  if (keep_residual) {
    const Eigen::MatrixXd c_perp = c - y.leftCols(rank) * v.leftCols(rank).transpose();  // #F by 3 r0
    out.residual_coefficients.resize(nk, 3 * nf);
    for (int k = 0; k < 3; ++k) out.residual_coefficients.middleCols(k * nf, nf) = t_inv * c_perp.middleCols(k * r0, r0).transpose();
  }
  return out;
}

// Max over vertices and frames of the residual displacement's length.
double measureMaxError(const Eigen::MatrixXd& basis, const Eigen::MatrixXd& residual_coefficients, int threads) {
  const Eigen::Index nv = basis.rows(), nf = residual_coefficients.cols() / 3;
  constexpr Eigen::Index kChunk = 256;
  const Eigen::Index chunks = (nv + kChunk - 1) / kChunk;
  std::vector<double> chunk_max(static_cast<std::size_t>(chunks), 0.0);
  parallelFor(chunks, threads, [&](std::ptrdiff_t begin, std::ptrdiff_t end) {
    for (std::ptrdiff_t ch = begin; ch < end; ++ch) {
      const Eigen::Index v0 = ch * kChunk, rows = std::min(kChunk, nv - v0);
      const Eigen::MatrixXd e = basis.middleRows(v0, rows) * residual_coefficients;  // rows by 3F
      const Eigen::MatrixXd len2 = e.leftCols(nf).cwiseAbs2() + e.middleCols(nf, nf).cwiseAbs2() + e.rightCols(nf).cwiseAbs2();
      chunk_max[static_cast<std::size_t>(ch)] = std::sqrt(len2.maxCoeff());
    }
  }, 1);
  return chunks > 0 ? *std::max_element(chunk_max.begin(), chunk_max.end()) : 0.0;
}

Error invalidArgument(const std::string& message) { return makeError(ErrorCode::kInvalidArgument, message); }

// Rotation and translation taking a frame's head markers onto the rest
// frame's (Umeyama; the rotation does not depend on the scale).
struct RigidMotion {
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  Eigen::RowVector3d translation = Eigen::RowVector3d::Zero();
};

// frames: #frames x 3#markers (marker i in columns 3i..3i+2), rest: #markers x 3.
std::vector<RigidMotion> headMotion(const Eigen::MatrixXd& frames, const Eigen::MatrixX3d& rest,
                                    const std::vector<Eigen::Index>& head) {
  const auto nh = static_cast<Eigen::Index>(head.size());
  Eigen::MatrixX3d rest_head(nh, 3), frame_head(nh, 3);
  for (Eigen::Index h = 0; h < nh; ++h) rest_head.row(h) = rest.row(head[static_cast<std::size_t>(h)]);
  const Eigen::RowVector3d rest_mean = rest_head.colwise().mean();
  std::vector<RigidMotion> motion(static_cast<std::size_t>(frames.rows()));
  for (Eigen::Index f = 0; f < frames.rows(); ++f) {
    for (Eigen::Index h = 0; h < nh; ++h) frame_head.row(h) = frames.block(f, 3 * head[static_cast<std::size_t>(h)], 1, 3);
    RigidMotion& m = motion[static_cast<std::size_t>(f)];
    m.rotation = fitSimilarity(frame_head, rest_head).rotation;
    m.translation = rest_mean - frame_head.colwise().mean() * m.rotation.transpose();
  }
  return motion;
}

// The markers the expression moves least: aligned on the current set, each
// marker's rms distance from its rest position over the clip; the half at or
// below the median is the next set (two rounds from all markers). A jaw
// opening moves a third of the AnimFace markers by centimetres; aligned on
// all of them, the fit turns the whole head with it (measured on a still face
// with a known head motion and a 2 cm jaw, brow or cheek movement added: the
// removal left 0.13-0.27 cm of error on the average marker; on the stable
// half, none). Fewer than 6 markers: all.
std::vector<Eigen::Index> stableHeadMarkers(const Eigen::MatrixXd& frames, const Eigen::MatrixX3d& rest) {
  const Eigen::Index nm = rest.rows();
  std::vector<Eigen::Index> head(static_cast<std::size_t>(nm));
  std::iota(head.begin(), head.end(), Eigen::Index{0});
  if (nm < 6) return head;
  for (int round = 0; round < 2; ++round) {
    const std::vector<RigidMotion> motion = headMotion(frames, rest, head);
    std::vector<double> moved(static_cast<std::size_t>(nm), 0.0);
    for (Eigen::Index f = 0; f < frames.rows(); ++f) {
      const RigidMotion& m = motion[static_cast<std::size_t>(f)];
      for (Eigen::Index i = 0; i < nm; ++i) {
        const Eigen::RowVector3d aligned = frames.block(f, 3 * i, 1, 3) * m.rotation.transpose() + m.translation;
        moved[static_cast<std::size_t>(i)] += (aligned - rest.row(i)).squaredNorm();
      }
    }
    std::vector<double> sorted = moved;
    const auto middle = sorted.begin() + static_cast<std::ptrdiff_t>(nm / 2);
    std::nth_element(sorted.begin(), middle, sorted.end());
    head.clear();
    for (Eigen::Index i = 0; i < nm; ++i) {
      if (moved[static_cast<std::size_t>(i)] <= *middle) head.push_back(i);
    }
  }
  return head;
}

}  // namespace

Result<RetargetOutput> retargetMocap(const Mesh& mesh, const MarkerDistances& distances, const MarkerTrajectories& clip,
                                     const RetargetOptions& options) {
  const auto t_start = Clock::now();
  const Eigen::Index nv = mesh.vertexCount();
  const Eigen::Index nm = static_cast<Eigen::Index>(distances.marker_names.size());
  const int nf = clip.frameCount();
  if (distances.vertex_marker.rows() != nv || distances.vertex_marker.cols() != nm) {
    return invalidArgument("retarget: the marker distances were made on another mesh (" +
                           std::to_string(distances.vertex_marker.rows()) + " vertices, this one has " +
                           std::to_string(nv) + ")");
  }
  if (nf < 1) return invalidArgument("retarget: the clip has no frames");
  if (clip.positions.cols() != 3 * clip.markerCount()) {
    return invalidArgument("retarget: the clip has " + std::to_string(clip.positions.cols()) + " columns for " +
                           std::to_string(clip.markerCount()) + " markers");
  }
  if (!(clip.data_rate > 0.0 && std::isfinite(clip.data_rate))) {
    return invalidArgument("retarget: the clip's data rate " + std::to_string(clip.data_rate) + " is not > 0");
  }
  if (!clip.positions.allFinite()) return invalidArgument("retarget: the clip has non-finite marker positions");
  if (options.rest_frame < 0 || options.rest_frame >= nf) {
    return invalidArgument("retarget: rest frame " + std::to_string(options.rest_frame) + " is not in the clip's " +
                           std::to_string(nf) + " frames");
  }
  if (options.bake.exact && nf > options.bake.max_exact_frames) {
    return invalidArgument("retarget: exact per-frame output of " + std::to_string(nf) + " frames exceeds " +
                           std::to_string(options.bake.max_exact_frames) + " (use the compressed bake)");
  }
  if (!(options.bake.tolerance >= 0.0) || options.bake.max_rank < 1) {
    return invalidArgument("retarget: bake tolerance must be >= 0 and max_rank >= 1");
  }

  RetargetReport report;
  report.method = distances.method;
  report.kernel = options.kernel;
  report.frames = nf;
  report.markers = static_cast<int>(nm);
  report.vertices = static_cast<int>(nv);
  report.data_rate = clip.data_rate;
  report.filled_gaps = clip.filled_gaps;
  report.rest_frame = options.rest_frame;
  report.mocap_units_to_metres = clip.units_to_metres;
  report.mesh_diagonal = distances.mesh_diagonal;
  report.regions = distances.regions;
  report.boundary_loops = distances.boundary_loops;
  report.timings_ms["distances"] = 0.0;  // cached; the one-off overload fills it in

  // Markers by name in the clip.
  std::vector<int> column(static_cast<std::size_t>(nm));
  std::vector<Eigen::Index> present;
  std::vector<std::string> absent;
  for (Eigen::Index i = 0; i < nm; ++i) {
    const std::string& name = distances.marker_names[static_cast<std::size_t>(i)];
    column[static_cast<std::size_t>(i)] = clip.markerIndex(name);
    if (column[static_cast<std::size_t>(i)] >= 0) {
      present.push_back(i);
    } else {
      absent.push_back(name);
    }
  }
  if (!absent.empty()) {
    // Placed markers the clip does not carry (one lost in the session, a
    // placement shared by several sessions): the others drive the mesh, and
    // the report names the absent ones.
    if (present.empty()) {
      return makeError(ErrorCode::kInvalidLandmarks, "retarget: none of the " + std::to_string(nm) +
                                                         " placed markers is in the clip (placed: " + joinNames(absent) +
                                                         ")");
    }
    MarkerDistances carried = distances;
    carried.marker_names.clear();
    carried.marker_positions.resize(static_cast<Eigen::Index>(present.size()), 3);
    carried.marker_marker.resize(carried.marker_positions.rows(), carried.marker_positions.rows());
    carried.vertex_marker.resize(nv, carried.marker_positions.rows());
    for (std::size_t a = 0; a < present.size(); ++a) {
      const auto ia = static_cast<Eigen::Index>(a);
      carried.marker_names.push_back(distances.marker_names[static_cast<std::size_t>(present[a])]);
      carried.marker_positions.row(ia) = distances.marker_positions.row(present[a]);
      carried.vertex_marker.col(ia) = distances.vertex_marker.col(present[a]);
      for (std::size_t b = 0; b < present.size(); ++b) {
        carried.marker_marker(ia, static_cast<Eigen::Index>(b)) = distances.marker_marker(present[a], present[b]);
      }
    }
    RetargetOptions carried_options = options;
    for (const std::string& name : absent) {
      carried_options.stiffness.erase(name);
      std::erase(carried_options.head_markers, name);
    }
    auto out = retargetMocap(mesh, carried, clip, carried_options);
    if (out) out->report.markers_not_in_clip = std::move(absent);
    return out;
  }
  for (std::size_t c = 0; c < clip.marker_names.size(); ++c) {
    if (std::find(column.begin(), column.end(), static_cast<int>(c)) == column.end()) {
      report.unused_clip_markers.push_back(clip.marker_names[c]);
    }
  }

  // Calibrate: rest frame -> placed markers; displacements into mesh space.
  auto t0 = Clock::now();
  Eigen::MatrixX3d rest(nm, 3);
  for (Eigen::Index i = 0; i < nm; ++i) {
    rest.row(i) = clip.positions.block(options.rest_frame, 3 * column[static_cast<std::size_t>(i)], 1, 3);
  }
  if (auto ok = checkTpsCentres(distances.marker_positions); !ok) return ok.error();
  auto calibration = calibrate(rest, distances.marker_positions, options);
  if (!calibration) return calibration.error();
  report.similarity_scale = calibration->similarity.scale;
  report.similarity_rms = calibration->similarity_rms;
  report.jacobian_min_singular = calibration->min_singular;
  report.jacobian_max_singular = calibration->max_singular;
  // Rigid head motion per frame, measured on the head markers: the given
  // ones, or the stable half of the set (stableHeadMarkers).
  std::vector<Eigen::Index> head;
  for (const std::string& name : options.head_markers) {
    const auto it = std::find(distances.marker_names.begin(), distances.marker_names.end(), name);
    if (it == distances.marker_names.end()) return invalidArgument("retarget: unknown head marker " + name);
    head.push_back(it - distances.marker_names.begin());
  }
  Eigen::MatrixXd frames(nf, 3 * nm);  // the clip's columns in marker-set order
  for (Eigen::Index i = 0; i < nm; ++i) {
    frames.middleCols(3 * i, 3) = clip.positions.middleCols(3 * column[static_cast<std::size_t>(i)], 3);
  }
  if (head.empty()) head = stableHeadMarkers(frames, rest);
  if (head.size() < 3) return invalidArgument("retarget: at least 3 head markers are needed to remove head motion");
  for (Eigen::Index h : head) report.head_markers.push_back(distances.marker_names[static_cast<std::size_t>(h)]);
  const std::vector<RigidMotion> head_motion = headMotion(frames, rest, head);
  report.head_motion_removed = options.remove_head_motion;
  Eigen::MatrixXd rhs(nm, 3 * static_cast<Eigen::Index>(nf));  // column 3f + c
  Eigen::MatrixX3d frame(nm, 3);
  for (int f = 0; f < nf; ++f) {
    for (Eigen::Index i = 0; i < nm; ++i) frame.row(i) = frames.block(f, 3 * i, 1, 3);
    const Eigen::Matrix3d& rotation = head_motion[static_cast<std::size_t>(f)].rotation;
    const Eigen::RowVector3d& translation = head_motion[static_cast<std::size_t>(f)].translation;
    report.head_max_rotation_deg = std::max(report.head_max_rotation_deg,
                                            Eigen::AngleAxisd(rotation).angle() * 180.0 / 3.14159265358979323846);
    report.head_max_translation = std::max(report.head_max_translation,
                                           calibration->similarity.scale * translation.norm());
    if (options.remove_head_motion) frame = ((frame * rotation.transpose()).rowwise() + translation).eval();
    for (Eigen::Index i = 0; i < nm; ++i) {
      const Eigen::Vector3d d = (frame.row(i) - rest.row(i)).transpose();
      rhs.block(i, 3 * f, 1, 3) = (calibration->maps[static_cast<std::size_t>(i)] * d).transpose();
    }
  }
  for (int f = 0; f < nf; ++f) {
    for (Eigen::Index i = 0; i < nm; ++i) {
      report.max_marker_displacement = std::max(report.max_marker_displacement, rhs.block(i, 3 * f, 1, 3).norm());
    }
  }
  report.timings_ms["calibrate"] = msSince(t0);

  // Factorise the marker system.
  t0 = Clock::now();
  RbfOptions rbf;
  rbf.kernel = options.kernel;
  rbf.gamma = options.gamma > 0.0 ? options.gamma : kDefaultGammaFactor * distances.mesh_diagonal;
  rbf.polynomial = options.polynomial;
  const bool euclidean = distances.method == DistanceMethod::kEuclidean;
  if (!euclidean && rbf.polynomial == RbfPolynomial::kAffine) rbf.polynomial = RbfPolynomial::kConstant;
  rbf.stiffness_step = options.stiffness_step;
  if (!options.stiffness.empty()) {
    rbf.stiffness.assign(static_cast<std::size_t>(nm), 1.0);
    for (const auto& [name, s] : options.stiffness) {
      const auto it = std::find(distances.marker_names.begin(), distances.marker_names.end(), name);
      if (it == distances.marker_names.end()) return invalidArgument("retarget: stiffness for unknown marker " + name);
      rbf.stiffness[static_cast<std::size_t>(it - distances.marker_names.begin())] = s;
    }
  }
  const Eigen::MatrixX3d no_positions;
  auto factorization = RbfFactorization::create(distances.marker_marker, euclidean ? distances.marker_positions : no_positions, rbf);
  if (!factorization) return factorization.error();
  auto basis = factorization->basis(distances.vertex_marker, mesh.positions);
  if (!basis) return basis.error();
  report.gamma = rbf.gamma;
  report.polynomial_terms = factorization->polynomialTerms();
  report.condition = factorization->conditionEstimate();
  report.timings_ms["factorise"] = msSince(t0);

  // Solve all frames at once.
  t0 = Clock::now();
  const Eigen::MatrixXd weights = factorization->solve(rhs);  // #K by 3F
  report.timings_ms["solve"] = msSince(t0);

  // Evaluate at the markers (interpolation residual) and bake.
  t0 = Clock::now();
  const Eigen::MatrixXd at_markers = RbfFactorization::evaluate(factorization->centreBasis(), weights) - rhs;
  double sum2 = 0.0;
  for (int f = 0; f < nf; ++f) {
    for (Eigen::Index i = 0; i < nm; ++i) {
      const double e2 = at_markers.block(i, 3 * f, 1, 3).squaredNorm();
      sum2 += e2;
      report.marker_max_residual = std::max(report.marker_max_residual, std::sqrt(e2));
    }
  }
  report.marker_rms_residual = std::sqrt(sum2 / static_cast<double>(nm * nf));
  double evaluate_ms = msSince(t0);

  Rig rig;
  rig.mesh = mesh;
  if (rig.mesh.normals.rows() != nv) rig.mesh.normals = computeSeamlessVertexNormals(mesh.positions, mesh.triangles);
  rig.mesh_name = options.mesh_name;
  Node node;
  node.name = options.mesh_name;
  rig.nodes.push_back(node);
  rig.mesh_node = 0;
  AnimationChannel channel;
  channel.node = 0;
  channel.path = AnimationPath::kWeights;
  channel.interpolation = Interpolation::kLinear;
  channel.times = Eigen::VectorXd::LinSpaced(nf, 0.0, (nf - 1) / clip.data_rate);
  report.tolerance = options.bake.tolerance;
  double bake_ms = 0.0;
  if (options.bake.exact) {
    t0 = Clock::now();
    const Eigen::MatrixXd deltas = RbfFactorization::evaluate(*basis, weights);  // #V by 3F
    evaluate_ms += msSince(t0);
    t0 = Clock::now();
    for (int f = 0; f < nf; ++f) {
      MorphTarget target;
      target.name = "frame_" + std::to_string(f);
      target.position_deltas = deltas.middleCols(3 * f, 3);
      rig.morph_targets.push_back(std::move(target));
    }
    channel.values = Eigen::MatrixXd::Identity(nf, nf);
    report.exact = true;
    report.rank = nf;
    report.max_error_measured = true;
    bake_ms += msSince(t0);
  } else {
    t0 = Clock::now();
    const Modes modes = compressModes(weights, *basis, options.bake, options.bake.measure_max_error);
    bake_ms += msSince(t0);
    t0 = Clock::now();
    const Eigen::MatrixXd deltas = RbfFactorization::evaluate(*basis, modes.coefficients);  // #V by 3 rank
    if (options.bake.measure_max_error) {
      report.max_error = measureMaxError(*basis, modes.residual_coefficients, options.threads);
      report.max_error_measured = true;
    } else {
      report.max_error = modes.max_error_bound;
    }
    evaluate_ms += msSince(t0);
    t0 = Clock::now();
    char name[32];
    for (int j = 0; j < modes.rank; ++j) {
      std::snprintf(name, sizeof(name), "mode_%02d", j);
      MorphTarget target;
      target.name = name;
      target.position_deltas = deltas.middleCols(3 * j, 3);
      rig.morph_targets.push_back(std::move(target));
    }
    channel.values = modes.weights;
    report.rank = modes.rank;
    report.tolerance_met = modes.tolerance_met;
    report.relative_error = modes.relative_error;
    report.rms_error = modes.rms_error;
    report.singular_values = modes.singular_values;
    bake_ms += msSince(t0);
  }
  t0 = Clock::now();
  rig.morph_default_weights = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(rig.morph_targets.size()));
  Animation animation;
  animation.name = options.animation_name;
  animation.channels.push_back(std::move(channel));
  rig.animations.push_back(std::move(animation));
  bake_ms += msSince(t0);
  report.timings_ms["evaluate"] = evaluate_ms;
  report.timings_ms["bake"] = bake_ms;
  report.total_ms = msSince(t_start);
  Eigen::MatrixXd marker_displacements(nf, 3 * nm);
  for (int f = 0; f < nf; ++f) {
    for (Eigen::Index i = 0; i < nm; ++i) marker_displacements.block(f, 3 * i, 1, 3) = rhs.block(i, 3 * f, 1, 3);
  }
  return RetargetOutput{std::move(rig), std::move(report), std::move(marker_displacements)};
}

Result<RetargetOutput> retargetMocap(const Mesh& mesh, const LandmarkSet& markers, const MarkerTrajectories& clip,
                                     const std::string& label, const MarkerDistanceOptions& distance_options,
                                     const RetargetOptions& options) {
  auto distances = computeMarkerDistances(mesh, markers, label, distance_options);
  if (!distances) return distances.error();
  auto out = retargetMocap(mesh, *distances, clip, options);
  if (out) {
    out->report.timings_ms["distances"] = distances->compute_ms;
    out->report.total_ms += distances->compute_ms;
  }
  return out;
}

std::string formatRetargetDiagnostics(const RetargetReport& r, const std::map<std::string, double>& extra_timings_ms,
                                      double total_ms) {
  using Json = nlohmann::ordered_json;
  Json doc;
  doc["method"] = distanceMethodName(r.method);
  doc["kernel"] = rbfKernelName(r.kernel);
  doc["gamma"] = r.gamma;
  doc["polynomial_terms"] = r.polynomial_terms;
  doc["condition"] = r.condition;
  doc["counts"] = {{"frames", r.frames}, {"markers", r.markers}, {"vertices", r.vertices}, {"data_rate", r.data_rate},
                   {"rest_frame", r.rest_frame}, {"unused_clip_markers", r.unused_clip_markers},
                   {"markers_not_in_clip", r.markers_not_in_clip}};
  doc["calibration"] = {{"mocap_units_to_metres", r.mocap_units_to_metres},
                        {"similarity_scale", r.similarity_scale},
                        {"similarity_rms", r.similarity_rms},
                        {"jacobian_min_singular", r.jacobian_min_singular},
                        {"jacobian_max_singular", r.jacobian_max_singular},
                        {"max_marker_displacement", r.max_marker_displacement},
                        {"head_motion_removed", r.head_motion_removed},
                        {"head_markers", r.head_markers},
                        {"head_max_rotation_deg", r.head_max_rotation_deg},
                        {"head_max_translation", r.head_max_translation}};
  Json gaps = Json::array();
  for (const TrcGap& g : r.filled_gaps) {
    gaps.push_back({{"marker", g.marker},
                    {"first_frame", g.first_frame},
                    {"frames", g.frame_count},
                    {"fill", g.fill == GapFill::kInterpolated ? "interpolated" : "neighbours"},
                    {"donors", g.donors}});
  }
  doc["gaps"] = gaps;
  doc["interpolation"] = {{"marker_max_residual", r.marker_max_residual}, {"marker_rms_residual", r.marker_rms_residual}};
  const double diag = r.mesh_diagonal > 0.0 ? r.mesh_diagonal : 1.0;
  doc["bake"] = {{"exact", r.exact},
                 {"rank", r.rank},
                 {"tolerance", r.tolerance},
                 {"tolerance_met", r.tolerance_met},
                 {"relative_error", r.relative_error},
                 {"rms_error", r.rms_error},
                 {"rms_error_percent_diagonal", 100.0 * r.rms_error / diag},
                 {"max_error", r.max_error},
                 {"max_error_percent_diagonal", 100.0 * r.max_error / diag},
                 {"max_error_measured", r.max_error_measured},
                 {"mesh_diagonal", r.mesh_diagonal},
                 {"singular_values", r.singular_values}};
  Json regions = Json::array();
  for (const GeodesicRegion& g : r.regions) {
    regions.push_back({{"loop", g.loop},
                       {"loop_vertices", g.loop_vertices},
                       {"extent", g.extent},
                       {"centroid", {g.centroid.x(), g.centroid.y(), g.centroid.z()}},
                       {"region_vertices", g.region_vertices}});
  }
  doc["geodesic_regions"] = {{"boundary_loops", r.boundary_loops}, {"regions", regions}};
  Json& t = doc["timings_ms"];
  for (const char* stage : {"distances", "calibrate", "factorise", "solve", "evaluate", "bake"}) {
    const auto it = r.timings_ms.find(stage);
    t[stage] = it != r.timings_ms.end() ? it->second : 0.0;
  }
  for (const auto& [name, ms] : extra_timings_ms) t[name] = ms;
  t["total"] = total_ms >= 0.0 ? total_ms : r.total_ms;
  return doc.dump(2, ' ', false, nlohmann::json::error_handler_t::replace) + "\n";
}

}  // namespace core
