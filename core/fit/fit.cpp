#include "core/fit/fit.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>
#include <vector>

#include "core/base/timing.h"
#include "core/fit/fit_stages.h"
#include "core/geometry/point_cloud_index.h"
#include "core/solve/inpainting.h"

namespace core {

namespace {

// Lips that touch at rest: vertices closer than this fraction of the
// diagonal (1 mm on a head) ...
constexpr double kLipContact = 0.002;
// ... that the mesh does not join within this many rings.
constexpr int kLipRings = 4;
// Stages of the first pass of a fit without landmarks.
constexpr std::size_t kFirstPassStages = 3;
// The expressive face: within this fraction of the diagonal (3 cm on a
// head) of a landmark that is not on the jaw line.
constexpr double kExpressiveRadius = 0.063;
// Vertices this close to a rim (1 cm on a head) are matched to the closest
// scan point in every stage (FitOptions::normal_matching): the lips' and
// lids' normals turn within millimetres.
constexpr double kNearRimRadius = 0.02;

// Marks with `stamp` the vertices within `rings` edges of v (v included).
void markRingsAround(const VertexAdjacency& adjacency, int v, int rings, std::vector<int>& mark, int stamp) {
  std::vector<int> frontier{v};
  mark[static_cast<std::size_t>(v)] = stamp;
  for (int r = 0; r < rings; ++r) {
    std::vector<int> next;
    for (const int u : frontier) {
      for (int i = adjacency.offsets[static_cast<std::size_t>(u)]; i < adjacency.offsets[static_cast<std::size_t>(u) + 1]; ++i) {
        const int w = adjacency.indices[static_cast<std::size_t>(i)];
        if (mark[static_cast<std::size_t>(w)] == stamp) continue;
        mark[static_cast<std::size_t>(w)] = stamp;
        next.push_back(w);
      }
    }
    frontier = std::move(next);
  }
}

// Each vertex's nearest vertex across a touching gap (the lips), as pairs.
std::vector<std::array<int, 2>> touchingPairs(const Mesh& mesh, const std::vector<int>& representative,
                                              const std::vector<char>& on_skin, double diagonal) {
  const Eigen::Index n = mesh.vertexCount();
  const VertexAdjacency adjacency = vertexAdjacency(weldedTopology(mesh, representative).triangles, n);
  const PointCloudIndex index(mesh.positions);
  const double limit = kLipContact * diagonal;
  std::vector<int> mark(static_cast<std::size_t>(n), -1);
  std::vector<std::array<int, 2>> pairs;
  for (Eigen::Index v = 0; v < n; ++v) {
    const auto vi = static_cast<std::size_t>(v);
    if (!on_skin[vi] || (!representative.empty() && representative[vi] != v)) continue;
    const auto near = index.nearest(mesh.positions.row(v).transpose(), 8);
    bool ring_marked = false;
    for (const auto& nb : near) {
      if (nb.index == v || std::sqrt(nb.sq_distance) >= limit) continue;
      if (!on_skin[static_cast<std::size_t>(nb.index)]) continue;
      if (!representative.empty() && representative[static_cast<std::size_t>(nb.index)] != nb.index) continue;
      if (!ring_marked) {
        markRingsAround(adjacency, static_cast<int>(v), kLipRings, mark, static_cast<int>(v));
        ring_marked = true;
      }
      if (mark[static_cast<std::size_t>(nb.index)] == static_cast<int>(v)) continue;  // joined by the mesh
      if (nb.index > v) pairs.push_back({static_cast<int>(v), nb.index});
      else pairs.push_back({nb.index, static_cast<int>(v)});
      break;  // the nearest only
    }
  }
  std::sort(pairs.begin(), pairs.end());
  pairs.erase(std::unique(pairs.begin(), pairs.end()), pairs.end());
  return pairs;
}

}  // namespace

Eigen::SparseMatrix<double> edgeLaplacian(Eigen::Index n, const std::vector<std::array<int, 2>>& edges) {
  std::vector<Eigen::Triplet<double>> entries;
  entries.reserve(edges.size() * 4);
  for (const auto& [a, b] : edges) {
    entries.emplace_back(a, a, 1.0);
    entries.emplace_back(b, b, 1.0);
    entries.emplace_back(a, b, -1.0);
    entries.emplace_back(b, a, -1.0);
  }
  Eigen::SparseMatrix<double> out(n, n);
  out.setFromTriplets(entries.begin(), entries.end());
  return out;
}

std::vector<FitStage> defaultFitSchedule() {
  // stiffness, iterations, max distance (x d), max normal angle, landmark weight, point share (docs/FIT.md 2.4)
  return {{10.0, 3, 0.050, 70.0, 200.0, 1.0},
          {3.0, 3, 0.030, 60.0, 60.0, 1.0},
          {1.0, 4, 0.015, 60.0, 20.0, 0.5},
          {0.3, 4, 0.008, 45.0, 5.0, 0.1},
          {0.1, 4, 0.006, 45.0, 1.0, 0.1}};
}

std::size_t FitReference::memoryBytes() const {
  const auto sparse = [](const Eigen::SparseMatrix<double>& m) {
    return static_cast<std::size_t>(m.nonZeros()) * (sizeof(double) + sizeof(int));
  };
  std::size_t rim_bytes = 0;
  for (const auto& r : rims) rim_bytes += r.size() * sizeof(int);
  return rim_bytes + sparse(laplacian) + sparse(rim_laplacian) + sparse(binding_laplacian) + lip_pairs.size() * 8 +
         expressive.size() + on_skin.size() + near_rims.size() + representative.size() * 4 + search.memoryBytes();
}

Result<FitReference> prepareFitReference(std::shared_ptr<const PreparedRig> rig) {
  const auto started = Clock::now();
  FitReference out;
  const PreparedSource& surface = rig->surface;
  const Mesh& mesh = surface.mesh;
  const Eigen::Index n = mesh.vertexCount();
  if (surface.landmarks.landmarks.size() < 4) {
    return Error{ErrorCode::kInvalidLandmarks, surface.label + ": the reference needs landmarks (at least 4) to fit scans"};
  }
  out.representative = coincidentVertexRepresentatives(mesh.positions);
  out.laplacian = uniformLaplacian(mesh.triangles, n, out.representative);
  out.on_skin.assign(static_cast<std::size_t>(n), 0);
  for (Eigen::Index f = 0; f < mesh.triangleCount(); ++f) {
    if (isDegenerateTriangle(mesh.positions, mesh.triangles.row(f), surface.diagonal)) continue;
    for (int k = 0; k < 3; ++k) out.on_skin[static_cast<std::size_t>(mesh.triangles(f, k))] = 1;
  }
  // Rims: every open boundary but the longest (the neck cut).
  std::vector<std::array<int, 2>> rim_edges;
  const std::vector<BoundaryLoop> loops = boundaryLoops(weldedTopology(mesh, out.representative));
  for (std::size_t l = 1; l < loops.size(); ++l) {
    const std::vector<int>& loop = loops[l].vertices;
    if (loops[l].closed && loop.size() >= 3) out.rims.push_back(loop);
    for (std::size_t i = 0; i < loop.size(); ++i) {
      if (i + 1 < loop.size() || loops[l].closed) rim_edges.push_back({loop[i], loop[(i + 1) % loop.size()]});
    }
  }
  out.rim_laplacian = edgeLaplacian(n, rim_edges);
  out.lip_pairs = touchingPairs(mesh, out.representative, out.on_skin, surface.diagonal);
  out.binding_laplacian = edgeLaplacian(n, out.lip_pairs);
  out.near_rims.assign(static_cast<std::size_t>(n), 0);
  {
    std::vector<int> rim_vertices;
    for (const auto& rim : out.rims) rim_vertices.insert(rim_vertices.end(), rim.begin(), rim.end());
    Eigen::MatrixX3d rim_points(static_cast<Eigen::Index>(rim_vertices.size()), 3);
    for (std::size_t i = 0; i < rim_vertices.size(); ++i) rim_points.row(static_cast<Eigen::Index>(i)) = mesh.positions.row(rim_vertices[i]);
    const double radius = kNearRimRadius * surface.diagonal;
    const std::vector<PointCloudIndex::Neighbour> nearest_rim = PointCloudIndex(rim_points).nearest(mesh.positions);
    for (Eigen::Index v = 0; v < n; ++v) {
      const PointCloudIndex::Neighbour& nb = nearest_rim[static_cast<std::size_t>(v)];
      if (nb.index >= 0 && nb.sq_distance < radius * radius) out.near_rims[static_cast<std::size_t>(v)] = 1;
    }
  }
  // The expressive face.
  std::vector<Eigen::Vector3d> inner;
  for (std::size_t l = 0; l < surface.landmarks.landmarks.size(); ++l) {
    if (surface.landmarks.landmarks[l].name.rfind("jaw", 0) != 0) {
      inner.push_back(surface.landmark_positions.row(static_cast<Eigen::Index>(l)).transpose());
    }
  }
  if (inner.empty()) {
    for (Eigen::Index l = 0; l < surface.landmark_positions.rows(); ++l) inner.push_back(surface.landmark_positions.row(l).transpose());
  }
  const double radius = kExpressiveRadius * surface.diagonal;
  out.expressive.assign(static_cast<std::size_t>(n), 0);
  for (Eigen::Index v = 0; v < n; ++v) {
    if (!out.on_skin[static_cast<std::size_t>(v)]) continue;
    for (const Eigen::Vector3d& p : inner) {
      if ((mesh.positions.row(v).transpose() - p).squaredNorm() <= radius * radius) {
        out.expressive[static_cast<std::size_t>(v)] = 1;
        break;
      }
    }
  }
  const Eigen::RowVector3d centroid = mesh.positions.colwise().mean();
  out.rms_radius = std::sqrt((mesh.positions.rowwise() - centroid).rowwise().squaredNorm().mean());
  out.search = prepareSearchReference(mesh);
  out.rig = std::move(rig);
  out.prepare_ms = msSince(started);
  return out;
}

namespace {

// The scan's landmarks paired with the reference's and the alignment.
struct AlignedScan {
  FrameMap frame;
  LandmarkTargets targets;            // in the reference frame (for the fit)
  Eigen::MatrixX3d scan_landmarks;    // #kept, scan frame
  std::vector<std::string> names;     // #kept
};

Result<AlignedScan> alignScan(const FitReference& reference, const ScanSurface& scan, const LandmarkSet& scan_landmarks,
                              const std::string& label, const FitOptions& options, FitReport& report) {
  const PreparedSource& surface = reference.rig->surface;
  const bool use_landmarks =
      options.alignment == FitAlignmentMode::kLandmarks ||
      (options.alignment == FitAlignmentMode::kAuto && scan_landmarks.landmarks.size() >= 4);
  AlignedScan out;
  std::optional<LandmarkPairs> pairs;
  if (!scan_landmarks.landmarks.empty()) {
    auto positions = resolveLandmarks(scan_landmarks, scan.mesh, label + " landmarks",
                                      scan.isCloud() ? nullptr : &scan.surface_index);
    if (!positions) return positions.error();
    auto paired = pairLandmarks(surface.landmarks, surface.landmark_positions, scan_landmarks, *positions, label);
    if (!paired) return paired.error();
    pairs = std::move(*paired);
  }
  if (use_landmarks) {
    if (!pairs) return Error{ErrorCode::kInvalidLandmarks, label + ": alignment \"landmarks\" needs the scan's landmarks"};
    // A click off by more than ~1 cm on a head (after the others agree) is dropped.
    const double drop = 0.02 * surface.diagonal * std::max(1e-12, scan.diagonal / surface.diagonal);
    auto aligned = alignByLandmarks(*pairs, drop, report.alignment);
    if (!aligned) return aligned.error();
    out.frame.reference_to_scan = aligned->reference_to_scan;
  } else {
    std::vector<char> usable(scan.flags.size());
    for (std::size_t v = 0; v < usable.size(); ++v) usable[v] = !(scan.flags[v] & (kScanSpike | kScanDetached));
    auto searched = alignBySearch(reference.search, scan.mesh.positions, scan.normals, !scan.report.normals_computed,
                                  usable, options.search);
    if (!searched) return searched.error();
    out.frame.reference_to_scan = searched->reference_to_scan;
    AlignmentReport& a = report.alignment;
    a.method = "search";
    a.rms_residual = searched->trimmed_rms * searched->reference_to_scan.scale;
    a.inlier_fraction = searched->inlier_fraction;
    a.hypotheses = searched->hypotheses;
    a.runner_up_ratio = searched->runner_up_score > 0.0 ? searched->score / searched->runner_up_score : 0.0;
  }
  // Every given landmark constrains the fit, also one the alignment left out:
  // on a stylised face a true landmark can miss any similarity by centimetres,
  // and a wrong click gives way to the scan as the landmark weight fades.
  if (pairs) {
    out.names = pairs->names;
    out.scan_landmarks = pairs->target;
  }
  // Landmark constraints of the fit: each kept landmark's reference vertex
  // pulled to the scan's landmark brought into the reference frame, offset
  // as the vertex is from the reference's landmark (a landmark on a face or
  // at a position lies off its vertex; it moves with its vertex, as the
  // rebuild's dense map has it).
  out.targets.targets.resize(out.scan_landmarks.rows(), 3);
  for (std::size_t i = 0; i < out.names.size(); ++i) {
    const auto l = static_cast<std::size_t>(surface.landmarks.indexOf(out.names[i]));
    const int v = surface.landmark_vertices[l];
    out.targets.vertices.push_back(v);
    const auto row = static_cast<Eigen::Index>(i);
    out.targets.targets.row(row) = out.frame.toReference(out.scan_landmarks.row(row).transpose()).transpose() +
                                   surface.mesh.positions.row(v) - surface.landmark_positions.row(static_cast<Eigen::Index>(l));
  }
  const Similarity& s = out.frame.reference_to_scan;
  AlignmentReport& a = report.alignment;
  a.rotation_deg = Eigen::AngleAxisd(s.rotation).angle() * 180.0 / std::numbers::pi;
  const Eigen::Vector3d ypr = yawPitchRollDeg(s.rotation);
  a.yaw_deg = ypr(0);
  a.pitch_deg = ypr(1);
  a.roll_deg = ypr(2);
  a.scale = s.scale;
  a.translation = s.translation;
  return out;
}

// Without landmarks, two passes: the stiff stages from a prior placed by the
// corners of the scan's own eye holes and mouth slit (meshes), then the
// reference's landmarks read off that fit place the prior of the full
// schedule, as clicked ones would (face median 1.29-1.48 -> 1.15-1.20 mm on
// the ordinary scans). The landmarks found are reported.
Result<NonRigidFit> fitWithoutLandmarks(const FitReference& reference, const ScanSurface& scan, const FrameMap& frame,
                                        const FitOptions& options, FitReport& report) {
  Eigen::MatrixX3d prior = fitPrior(reference, scan, frame, {});
  const LandmarkTargets corners = rimCorners(reference, scan, frame, prior);
  prior = correctAtLandmarks(reference, corners, std::move(prior));
  FitOptions stiff = options;
  stiff.schedule.resize(std::min<std::size_t>(stiff.schedule.size(), kFirstPassStages));
  stiff.fold_repair_rounds = 0;
  auto first = fitNonRigid(reference, scan, frame, prior, {}, stiff);
  if (!first) return first.error();
  report.stages = first->stages;
  const PreparedSource& surface = reference.rig->surface;
  LandmarkTargets found;
  found.vertices = surface.landmark_vertices;
  found.targets.resize(static_cast<Eigen::Index>(found.vertices.size()), 3);
  for (std::size_t i = 0; i < found.vertices.size(); ++i) {
    found.targets.row(static_cast<Eigen::Index>(i)) = first->positions.row(found.vertices[i]);
  }
  auto second = fitNonRigid(reference, scan, frame, fitPrior(reference, scan, frame, found), {}, options);
  if (!second) return second.error();
  // Reported where the full fit puts them, on the scan itself (its closest
  // surface point, a cloud's nearest point): usable as the scan's landmarks.
  Eigen::MatrixX3d at(static_cast<Eigen::Index>(found.vertices.size()), 3);
  for (std::size_t i = 0; i < found.vertices.size(); ++i) {
    at.row(static_cast<Eigen::Index>(i)) = frame.toScan(second->positions.row(found.vertices[i]).transpose()).transpose();
  }
  const std::vector<ScanMatch> on_scan = scan.nearest(at);
  for (std::size_t i = 0; i < found.vertices.size(); ++i) {
    const Eigen::Vector3d where = on_scan[i].found ? on_scan[i].point : Eigen::Vector3d(at.row(static_cast<Eigen::Index>(i)).transpose());
    report.found_landmarks.push_back({surface.landmarks.landmarks[i].name, where});
  }
  return second;
}

// Everything of a fit but the rebuild: scan -> units -> align -> prior ->
// non-rigid fit -> gate (its verdict in `report`).
struct SurfaceFitRun {
  FrameMap frame;
  NonRigidFit fitted;
  double unit_scale = 1.0;
};

Result<SurfaceFitRun> runSurfaceFit(const FitReference& reference, const Mesh& scan_mesh, const LandmarkSet& scan_landmarks,
                                    const std::string& scan_label, const FitOptions& options, FitReport& report) {
  auto stage = [&](const char* name, double fraction) { return !options.on_stage || options.on_stage(name, fraction); };
  auto stopped = [&](const char* name) {
    return Error{ErrorCode::kCancelled, scan_label + ": fit stopped before stage '" + name + "'"};
  };
  if (options.schedule.empty()) return Error{ErrorCode::kInvalidArgument, "the fit's schedule has no stage"};

  if (!stage("scan", 0.05)) return stopped("scan");
  auto t = Clock::now();
  auto scan = prepareScan(scan_mesh, scan_label);
  if (!scan) return scan.error();
  report.scan_ms = msSince(t);

  if (!stage("align", 0.15)) return stopped("align");
  t = Clock::now();
  auto aligned = alignScan(reference, *scan, scan_landmarks, scan_label, options, report);
  if (!aligned) return aligned.error();
  auto units = scanUnits(aligned->frame.reference_to_scan.scale, reference.rms_radius, options.units);
  if (!units) return units.error();
  scan->report.units = units->name;
  scan->report.unit_scale = units->unit_scale;
  scan->report.size_ratio = units->size_ratio;
  report.unit_scale = units->unit_scale;
  report.align_ms = msSince(t);

  if (!stage("fit", 0.25)) return stopped("fit");
  t = Clock::now();
  auto fitted = aligned->targets.vertices.empty()
                    ? fitWithoutLandmarks(reference, *scan, aligned->frame, options, report)
                    : fitNonRigid(reference, *scan, aligned->frame,
                                  fitPrior(reference, *scan, aligned->frame, aligned->targets), aligned->targets, options);
  if (!fitted) return fitted.error();
  report.stages.insert(report.stages.end(), fitted->stages.begin(), fitted->stages.end());
  report.fit_ms = msSince(t);

  if (!stage("gate", 0.8)) return stopped("gate");
  t = Clock::now();
  for (std::size_t i = 0; i < aligned->names.size(); ++i) {
    const auto row = static_cast<Eigen::Index>(i);
    const Eigen::Vector3d clicked = aligned->scan_landmarks.row(row).transpose();
    const PreparedSource& surface = reference.rig->surface;
    const auto l = static_cast<Eigen::Index>(surface.landmarks.indexOf(aligned->names[i]));
    const int v = aligned->targets.vertices[i];
    // The reference's landmark, and where it went: with its vertex.
    const Eigen::Vector3d rest = surface.landmark_positions.row(l).transpose();
    const Eigen::Vector3d moved = rest + (fitted->positions.row(v) - surface.mesh.positions.row(v)).transpose();
    report.landmarks.push_back({aligned->names[i], (aligned->frame.toScan(rest) - clicked).norm(),
                                (aligned->frame.toScan(moved) - clicked).norm()});
  }
  report.scan = scan->report;
  gateFit(reference, aligned->frame, *fitted, options, report);
  report.gate_ms = msSince(t);
  return SurfaceFitRun{aligned->frame, std::move(*fitted), units->unit_scale};
}

}  // namespace

Result<FittedSurface> fitSurface(const FitReference& reference, const Mesh& scan, const LandmarkSet& scan_landmarks,
                                 const std::string& scan_label, const FitOptions& options) {
  const auto started = Clock::now();
  FittedSurface out;
  auto run = runSurfaceFit(reference, scan, scan_landmarks, scan_label, options, out.report);
  if (!run) return run.error();
  out.positions.resize(run->fitted.positions.rows(), 3);
  for (Eigen::Index v = 0; v < out.positions.rows(); ++v) {
    out.positions.row(v) = run->frame.toScan(run->fitted.positions.row(v).transpose()).transpose();
  }
  out.report.total_ms = msSince(started);
  return out;
}

Result<FitResult> fitScan(const FitReference& reference, const Mesh& scan_mesh, const LandmarkSet& scan_landmarks,
                          const std::string& scan_label, const FitOptions& options) {
  const auto started = Clock::now();
  auto stage = [&](const char* name, double fraction) { return !options.on_stage || options.on_stage(name, fraction); };
  FitResult result;
  FitReport& report = result.report;
  auto run = runSurfaceFit(reference, scan_mesh, scan_landmarks, scan_label, options, report);
  if (!run) return run.error();
  const FrameMap& frame = run->frame;
  const NonRigidFit& fitted = run->fitted;

  if (!stage("rebuild", 0.9)) {
    return Error{ErrorCode::kCancelled, scan_label + ": fit stopped before stage 'rebuild'"};
  }
  const auto t = Clock::now();
  auto rig = rebuildRig(reference, frame, fitted.positions, run->unit_scale, options, report, result.components);
  if (!rig) return rig.error();
  result.rig = std::move(*rig);
  if (options.diagnostic_attributes) {
    const Eigen::Index n = fitted.positions.rows();
    Eigen::MatrixXd distance(n, 1), coverage(n, 1);
    const double to_output = options.frame == FitFrame::kScan ? frame.reference_to_scan.scale : 1.0;
    for (Eigen::Index v = 0; v < n; ++v) {
      const double d = fitted.distance[static_cast<std::size_t>(v)];
      distance(v, 0) = d >= 0.0 ? d * to_output : -1.0;
      coverage(v, 0) = fitted.covered[static_cast<std::size_t>(v)] ? 1.0 : 0.0;
    }
    result.rig.attributes.fields["FIT_DISTANCE"] = std::move(distance);
    result.rig.attributes.fields["FIT_COVERAGE"] = std::move(coverage);
  }
  report.rebuild_ms = msSince(t);
  report.total_ms = msSince(started);
  return result;
}

}  // namespace core
