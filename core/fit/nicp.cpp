// The non-rigid fit (docs/FIT.md 2.4): Amberg et al.'s schedule of
// decreasing stiffness on paper 001's energies (eq. 5.4), every term linear
// in the positions (appendix A), one sparse solve per iteration.
#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>
#include <vector>

#include <Eigen/Eigenvalues>
#include <Eigen/SparseCholesky>

#include "core/base/parallel.h"
#include "core/fit/fit_stages.h"
#include "core/correspond/correspondence.h"

namespace core {

namespace {

// Isolated vertices (on no face) have no term of their own: a tiny pull to
// the prior keeps the system positive definite (appendix A's C^T C is only
// semidefinite without it).
constexpr double kTikhonov = 1e-6;
// A stage ends when no vertex moved more than this fraction of the diagonal.
constexpr double kConvergedStep = 2e-4;
// A fold repair stiffens the flipped triangles' vertices and this many rings around them.
constexpr int kFoldRepairRings = 2;

// Scan matches of scan-frame queries brought into the reference frame.
void toReferenceFrame(const FrameMap& frame, std::vector<ScanMatch>& matches) {
  for (ScanMatch& m : matches) {
    if (!m.found) continue;
    m.point = frame.toReference(m.point);
    m.normal = frame.directionToReference(m.normal);
    m.distance /= frame.reference_to_scan.scale;
  }
}

struct IterationTerms {
  Eigen::VectorXd weight;       // #V data weight (0: rejected)
  Eigen::MatrixX3d target;      // #V data target (tangent-plane projection blended with the point)
  std::vector<double> distance; // #V to the match, -1 when rejected
  FitStageReport counts;
};

// Data term of one iteration: each reference vertex's scan match, rejected
// by distance, normal angle, borders and spikes, weighted by Tukey's
// biweight. Point-to-plane is linearised as a pull to the current position's
// projection onto the match's tangent plane, blended with a pull to the match
// itself (the stage's point_share): one matrix serves x, y and z.
IterationTerms dataTerms(const FitReference& reference, const ScanSurface& scan, const FrameMap& frame,
                         const Eigen::MatrixX3d& x, const FitStage& stage, const FitOptions& options) {
  const Eigen::Index n = x.rows();
  const Mesh& mesh = reference.rig->surface.mesh;
  const Eigen::MatrixX3d normals = computeSeamlessVertexNormals(x, mesh.triangles);
  const double diagonal = reference.rig->surface.diagonal;
  // Stages that drag whole regions (point share 1) match by position and
  // normal, so that the scan's features place the surface along itself; near
  // the rims, whose normals turn within millimetres, the closest point.
  const FrameMatches found =
      stage.point_share >= 1.0 && options.normal_matching > 0.0
          ? matchAlikeInReferenceFrame(scan, frame, x, normals, options.normal_matching * diagonal, reference.near_rims)
          : matchInReferenceFrame(scan, frame, x);
  const double tau = stage.max_distance * diagonal;
  const double cos_max = std::cos(stage.max_normal_angle_deg * std::numbers::pi / 180.0);
  const bool unsigned_normals = scan.report.normals_computed;
  IterationTerms out;
  out.weight = Eigen::VectorXd::Zero(n);
  out.target = x;
  out.distance.assign(static_cast<std::size_t>(n), -1.0);
  for (Eigen::Index v = 0; v < n; ++v) {
    const auto vi = static_cast<std::size_t>(v);
    if (!reference.on_skin[vi] || (!reference.representative.empty() && reference.representative[vi] != v)) continue;
    const ScanMatch& m = found.matches[vi];
    if (!m.found || m.distance > tau) {
      ++out.counts.rejected_distance;
      continue;
    }
    if (options.reject_borders && (m.flags & (kScanBorder | kScanDetached))) {
      ++out.counts.rejected_border;
      continue;
    }
    if (options.reject_spikes && (m.flags & kScanSpike)) {
      ++out.counts.rejected_spike;
      continue;
    }
    const Eigen::Vector3d nv = normals.row(v).transpose();
    const double cosine = nv.dot(m.normal);
    if ((unsigned_normals ? std::abs(cosine) : cosine) < cos_max) {
      ++out.counts.rejected_normal;
      continue;
    }
    const double r = m.distance / tau;
    const double w = (1.0 - r * r) * (1.0 - r * r);
    const Eigen::Vector3d p = x.row(v).transpose();
    const Eigen::Vector3d on_plane = p - m.normal * m.normal.dot(p - m.point);
    out.weight(v) = w;
    out.target.row(v) = ((1.0 - stage.point_share) * on_plane + stage.point_share * m.point).transpose();
    out.distance[vi] = m.distance;
    out.counts.energy_data += w * std::pow(m.normal.dot(p - m.point), 2);
    ++out.counts.accepted;
  }
  return out;
}

// The closest point to `p` on a closed polyline (scan vertex indices).
Eigen::Vector3d closestOnLoop(const Eigen::MatrixX3d& positions, const std::vector<int>& loop, const Eigen::Vector3d& p) {
  Eigen::Vector3d best = positions.row(loop.front()).transpose();
  double best_sq = (best - p).squaredNorm();
  for (std::size_t i = 0; i < loop.size(); ++i) {
    const Eigen::Vector3d a = positions.row(loop[i]).transpose();
    const Eigen::Vector3d b = positions.row(loop[(i + 1) % loop.size()]).transpose();
    const Eigen::Vector3d ab = b - a;
    const double t = ab.squaredNorm() > 0.0 ? std::clamp((p - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0) : 0.0;
    const Eigen::Vector3d q = a + t * ab;
    if ((q - p).squaredNorm() < best_sq) {
      best_sq = (q - p).squaredNorm();
      best = q;
    }
  }
  return best;
}

// Rim term (mesh scans): each reference rim (mouth, eyes) with a scan rim
// (matchScanRims) pulls its vertices onto that rim, where the surface term
// rejects them (their closest points are on the scan's border). The scan
// keeps its eye holes and mouth slit where the reference has its rims
// (docs/FIT.md 0).
void addRimTerms(const FitReference& reference, const ScanSurface& scan, const FrameMap& frame,
                 const Eigen::MatrixX3d& x, const FitStage& stage, const FitOptions& options, IterationTerms& out) {
  if (options.rim_weight <= 0.0 || scan.rims.empty()) return;
  const double tau = stage.max_distance * reference.rig->surface.diagonal * frame.reference_to_scan.scale;
  const std::vector<int> matched = matchScanRims(reference, scan, frame, x);
  for (std::size_t r = 0; r < reference.rims.size(); ++r) {
    if (matched[r] < 0) continue;
    for (const int v : reference.rims[r]) {
      const Eigen::Vector3d p = frame.toScan(x.row(v).transpose());
      const Eigen::Vector3d q = closestOnLoop(scan.mesh.positions, scan.rims[static_cast<std::size_t>(matched[r])], p);
      const double distance = (q - p).norm();
      if (distance > tau) continue;
      const double ratio = distance / tau;
      out.weight(v) = options.rim_weight * (1.0 - ratio * ratio) * (1.0 - ratio * ratio);
      out.target.row(v) = frame.toReference(q).transpose();
      out.distance[static_cast<std::size_t>(v)] = distance / frame.reference_to_scan.scale;
      ++out.counts.rim_matches;
    }
  }
}

// Copies of a split point (UV seams) take their representative's position.
void joinCopies(const std::vector<int>& representative, Eigen::MatrixX3d& x) {
  for (std::size_t v = 0; v < representative.size(); ++v) {
    if (representative[v] != static_cast<int>(v)) x.row(static_cast<Eigen::Index>(v)) = x.row(representative[v]);
  }
}

}  // namespace

std::vector<int> matchScanRims(const FitReference& reference, const ScanSurface& scan, const FrameMap& frame,
                               const Eigen::MatrixX3d& x) {
  std::vector<int> out(reference.rims.size(), -1);
  auto shape = [](const std::vector<int>& loop, auto&& at) {
    Eigen::Vector3d centre = Eigen::Vector3d::Zero();
    double length = 0.0;
    for (std::size_t i = 0; i < loop.size(); ++i) {
      centre += at(loop[i]);
      length += (at(loop[(i + 1) % loop.size()]) - at(loop[i])).norm();
    }
    return std::pair<Eigen::Vector3d, double>(centre / static_cast<double>(loop.size()), length);
  };
  std::vector<std::pair<Eigen::Vector3d, double>> scan_rims;
  for (const auto& loop : scan.rims) {
    scan_rims.push_back(shape(loop, [&](int v) { return Eigen::Vector3d(scan.mesh.positions.row(v).transpose()); }));
  }
  for (std::size_t r = 0; r < reference.rims.size(); ++r) {
    const auto [centre, length] = shape(reference.rims[r], [&](int v) { return frame.toScan(x.row(v).transpose()); });
    double nearest = length / (2.0 * std::numbers::pi);  // the rim's mean radius
    for (std::size_t s = 0; s < scan_rims.size(); ++s) {
      const double ratio = scan_rims[s].second / length;
      const double distance = (scan_rims[s].first - centre).norm();
      if (ratio > 0.5 && ratio < 2.0 && distance < nearest) {
        nearest = distance;
        out[r] = static_cast<int>(s);
      }
    }
  }
  return out;
}

LandmarkTargets rimCorners(const FitReference& reference, const ScanSurface& scan, const FrameMap& frame,
                           const Eigen::MatrixX3d& x) {
  LandmarkTargets out;
  const std::vector<int> matched = matchScanRims(reference, scan, frame, x);
  std::vector<Eigen::Vector3d> targets;
  for (std::size_t r = 0; r < reference.rims.size(); ++r) {
    if (matched[r] < 0) continue;
    const std::vector<int>& loop = reference.rims[r];
    Eigen::Vector3d centre = Eigen::Vector3d::Zero();
    for (const int v : loop) centre += x.row(v).transpose();
    centre /= static_cast<double>(loop.size());
    Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
    for (const int v : loop) covariance += (x.row(v).transpose() - centre) * (x.row(v).transpose() - centre).transpose();
    const Eigen::Vector3d axis = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(covariance).eigenvectors().col(2);
    const std::vector<int>& scan_loop = scan.rims[static_cast<std::size_t>(matched[r])];
    for (const double side : {-1.0, 1.0}) {
      int corner = loop.front();
      for (const int v : loop) {
        if (side * axis.dot(x.row(v).transpose()) > side * axis.dot(x.row(corner).transpose())) corner = v;
      }
      Eigen::Vector3d best = frame.toReference(scan.mesh.positions.row(scan_loop.front()).transpose());
      for (const int s : scan_loop) {
        const Eigen::Vector3d p = frame.toReference(scan.mesh.positions.row(s).transpose());
        if (side * axis.dot(p) > side * axis.dot(best)) best = p;
      }
      out.vertices.push_back(corner);
      targets.push_back(best);
    }
  }
  out.targets.resize(static_cast<Eigen::Index>(targets.size()), 3);
  for (std::size_t i = 0; i < targets.size(); ++i) out.targets.row(static_cast<Eigen::Index>(i)) = targets[i].transpose();
  return out;
}

FrameMatches matchInReferenceFrame(const ScanSurface& scan, const FrameMap& frame, const Eigen::MatrixX3d& positions) {
  Eigen::MatrixX3d queries(positions.rows(), 3);
  for (Eigen::Index v = 0; v < positions.rows(); ++v) queries.row(v) = frame.toScan(positions.row(v).transpose()).transpose();
  FrameMatches out;
  out.matches = scan.nearest(queries);
  toReferenceFrame(frame, out.matches);
  return out;
}

FrameMatches matchAlikeInReferenceFrame(const ScanSurface& scan, const FrameMap& frame, const Eigen::MatrixX3d& positions,
                                        const Eigen::MatrixX3d& normals, double normal_weight,
                                        const std::vector<char>& closest) {
  std::vector<Eigen::Index> by_point, alike;
  for (Eigen::Index v = 0; v < positions.rows(); ++v) (closest[static_cast<std::size_t>(v)] ? by_point : alike).push_back(v);
  auto queriesOf = [&](const std::vector<Eigen::Index>& rows) {
    Eigen::MatrixX3d q(static_cast<Eigen::Index>(rows.size()), 3);
    for (std::size_t i = 0; i < rows.size(); ++i) {
      q.row(static_cast<Eigen::Index>(i)) = frame.toScan(positions.row(rows[i]).transpose()).transpose();
    }
    return q;
  };
  Eigen::MatrixX3d alike_normals(static_cast<Eigen::Index>(alike.size()), 3);
  for (std::size_t i = 0; i < alike.size(); ++i) {
    alike_normals.row(static_cast<Eigen::Index>(i)) = (frame.reference_to_scan.rotation * normals.row(alike[i]).transpose()).transpose();
  }
  std::vector<ScanMatch> nearest = scan.nearest(queriesOf(by_point));
  std::vector<ScanMatch> alike_matches =
      scan.nearestAlike(queriesOf(alike), alike_normals, normal_weight * frame.reference_to_scan.scale);
  toReferenceFrame(frame, nearest);
  toReferenceFrame(frame, alike_matches);
  FrameMatches out;
  out.matches.resize(static_cast<std::size_t>(positions.rows()));
  for (std::size_t i = 0; i < by_point.size(); ++i) out.matches[static_cast<std::size_t>(by_point[i])] = nearest[i];
  for (std::size_t i = 0; i < alike.size(); ++i) out.matches[static_cast<std::size_t>(alike[i])] = alike_matches[i];
  return out;
}

Result<NonRigidFit> fitNonRigid(const FitReference& reference, const ScanSurface& scan, const FrameMap& frame,
                                const Eigen::MatrixX3d& prior, const LandmarkTargets& landmarks,
                                const FitOptions& options) {
  const Eigen::Index n = prior.rows();
  const double diagonal = reference.rig->surface.diagonal;
  const Mesh& mesh = reference.rig->surface.mesh;
  Eigen::SparseMatrix<double> identity(n, n);
  identity.setIdentity();
  // The pattern is the same for every iteration (the data and landmark terms
  // are diagonal, a fold repair stiffens mesh edges): analysed once.
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver;
  solver.analyzePattern(reference.laplacian + reference.rim_laplacian + reference.binding_laplacian + identity);

  NonRigidFit out;
  out.positions = prior;
  // One iteration at `stage` with membrane `smooth`: match, assemble, solve.
  auto iterate = [&](const FitStage& stage, const Eigen::SparseMatrix<double>& smooth,
                     FitStageReport& report) -> Status {
    IterationTerms terms = dataTerms(reference, scan, frame, out.positions, stage, options);
    addRimTerms(reference, scan, frame, out.positions, stage, options, terms);
    Eigen::SparseMatrix<double> a =
        smooth + options.binding_weight * reference.binding_laplacian + kTikhonov * stage.stiffness * identity;
    Eigen::MatrixX3d rhs = a * prior;
    for (Eigen::Index v = 0; v < n; ++v) {
      if (terms.weight(v) <= 0.0) continue;
      a.coeffRef(v, v) += terms.weight(v);
      rhs.row(v) += terms.weight(v) * terms.target.row(v);
    }
    for (std::size_t l = 0; l < landmarks.vertices.size(); ++l) {
      const int v = landmarks.vertices[l];
      a.coeffRef(v, v) += stage.landmark_weight;
      rhs.row(v) += stage.landmark_weight * landmarks.targets.row(static_cast<Eigen::Index>(l));
    }
    solver.factorize(a);
    if (solver.info() != Eigen::Success) {
      return Error{ErrorCode::kIllConditioned,
                   "the fit's system could not be factorised (stiffness " + std::to_string(stage.stiffness) + ")"};
    }
    Eigen::MatrixX3d next = solver.solve(rhs);
    joinCopies(reference.representative, next);
    const double step = (next - out.positions).rowwise().norm().maxCoeff();
    out.positions = std::move(next);
    report.stiffness = stage.stiffness;
    ++report.iterations;
    report.accepted = terms.counts.accepted;
    report.rim_matches = terms.counts.rim_matches;
    report.rejected_distance = terms.counts.rejected_distance;
    report.rejected_normal = terms.counts.rejected_normal;
    report.rejected_border = terms.counts.rejected_border;
    report.rejected_spike = terms.counts.rejected_spike;
    report.energy_data = terms.counts.energy_data;
    report.max_step = step;
    return Ok{};
  };
  auto membrane = [&](double stiffness) -> Eigen::SparseMatrix<double> {
    return stiffness * (reference.laplacian + (options.rim_stiffness - 1.0) * reference.rim_laplacian);
  };
  auto finish = [&](const FitStage& stage, const Eigen::SparseMatrix<double>& smooth, FitStageReport& report) {
    const Eigen::MatrixX3d d = out.positions - prior;
    report.energy_smooth = (d.transpose() * (smooth * d)).trace();
    double landmark_energy = 0.0;
    for (std::size_t l = 0; l < landmarks.vertices.size(); ++l) {
      landmark_energy +=
          (out.positions.row(landmarks.vertices[l]) - landmarks.targets.row(static_cast<Eigen::Index>(l))).squaredNorm();
    }
    report.energy_landmarks = stage.landmark_weight * landmark_energy;
    out.stages.push_back(report);
  };

  for (const FitStage& stage : options.schedule) {
    const Eigen::SparseMatrix<double> smooth = membrane(stage.stiffness);
    FitStageReport report;
    for (int iteration = 0; iteration < stage.iterations; ++iteration) {
      if (auto ok = iterate(stage, smooth, report); !ok) return ok.error();
      if (report.max_step < kConvergedStep * diagonal) break;
    }
    finish(stage, smooth, report);
  }

  // Fold repair: triangles turned over against the prior (whose faces face
  // the scan's way) get their neighbourhood stiffened to the first stage's
  // stiffness, and the last stage runs again there.
  const VertexAdjacency adjacency = vertexAdjacency(mesh.triangles, n);
  std::vector<char> stiffened(static_cast<std::size_t>(n), 0);
  for (int round = 0; round < options.fold_repair_rounds; ++round) {
    const FoldReport folds = countFolds(prior, out.positions, mesh.triangles);
    if (folds.flipped_faces.empty()) break;
    std::vector<int> frontier;
    for (const int f : folds.flipped_faces) {
      for (int k = 0; k < 3; ++k) frontier.push_back(mesh.triangles(f, k));
    }
    for (int ring = 0; ring <= kFoldRepairRings; ++ring) {
      std::vector<int> next;
      for (const int v : frontier) {
        if (stiffened[static_cast<std::size_t>(v)]) continue;
        stiffened[static_cast<std::size_t>(v)] = 1;
        ++out.repaired_vertices;
        for (int i = adjacency.offsets[static_cast<std::size_t>(v)]; i < adjacency.offsets[static_cast<std::size_t>(v) + 1]; ++i) {
          next.push_back(adjacency.indices[static_cast<std::size_t>(i)]);
        }
      }
      if (ring < kFoldRepairRings) frontier = std::move(next);
    }
    std::vector<std::array<int, 2>> edges;
    for (Eigen::Index v = 0; v < n; ++v) {
      if (!stiffened[static_cast<std::size_t>(v)]) continue;
      for (int i = adjacency.offsets[static_cast<std::size_t>(v)]; i < adjacency.offsets[static_cast<std::size_t>(v) + 1]; ++i) {
        const int u = adjacency.indices[static_cast<std::size_t>(i)];
        if (u > v && stiffened[static_cast<std::size_t>(u)]) edges.push_back({static_cast<int>(v), u});
      }
    }
    const FitStage& last = options.schedule.back();
    const Eigen::SparseMatrix<double> smooth =
        membrane(last.stiffness) + (options.schedule.front().stiffness - last.stiffness) * edgeLaplacian(n, edges);
    FitStageReport report;
    for (int iteration = 0; iteration < last.iterations; ++iteration) {
      if (auto ok = iterate(last, smooth, report); !ok) return ok.error();
    }
    finish(last, smooth, report);
    ++out.fold_repairs;
  }

  // The final correspondences, at the last stage's limits, for the gate.
  IterationTerms last = dataTerms(reference, scan, frame, out.positions, options.schedule.back(), options);
  addRimTerms(reference, scan, frame, out.positions, options.schedule.back(), options, last);
  out.covered.assign(static_cast<std::size_t>(n), 0);
  out.distance = last.distance;
  for (const int rim : matchScanRims(reference, scan, frame, out.positions)) out.matched_rims += rim >= 0 ? 1 : 0;
  for (Eigen::Index v = 0; v < n; ++v) out.covered[static_cast<std::size_t>(v)] = last.weight(v) > 0.0;
  return out;
}

}  // namespace core
