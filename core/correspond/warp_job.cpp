#include "core/correspond/warp_job.h"

#include "core/base/timing.h"

#include <algorithm>
#include <array>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <numeric>

#include <Eigen/Geometry>

#include "core/correspond/warp_stages.h"
#include "core/geometry/similarity.h"

namespace core {

WarpOptions plainWarpOptions() {
  WarpOptions options;
  options.refine_iterations = 0;
  options.local_rounds = 0;
  options.rim_matching = false;
  options.rim_location = false;
  options.side_matching = false;
  return options;
}

WarpOptions lightWarpOptions() {
  WarpOptions options;
  options.refine_iterations = 0;
  options.local_rounds = 1;
  options.target_pulls = false;
  options.smooth_guide = false;
  options.rim_location = false;
  return options;
}

std::size_t PreparedSource::memoryBytes() const {
  std::size_t bytes = sizeof(*this);
  bytes += static_cast<std::size_t>(mesh.positions.size() + mesh.normals.size() + mesh.uvs.size()) * sizeof(double);
  bytes += static_cast<std::size_t>(mesh.triangles.size()) * sizeof(int);
  bytes += static_cast<std::size_t>(dense_centres.size() + landmark_positions.size()) * sizeof(double);
  bytes += landmark_vertices.size() * sizeof(int);
  bytes += (adjacency.offsets.size() + adjacency.indices.size() + projection_sample.size()) * sizeof(int);
  bytes += (face_regions.size() + region_bits.size() + side_masks.size() + side_face_sets.size()) * sizeof(std::uint64_t);
  bytes += vertex_sides.size() * sizeof(int) + openings.size() * sizeof(Opening);
  bytes += rim_vertices.rim.size() * sizeof(int) + static_cast<std::size_t>(rim_vertices.tangent.size()) * sizeof(double);
  for (const Rim& rim : rims) bytes += rim.vertices.size() * 4 * sizeof(int);
  bytes += static_cast<std::size_t>(mesh.regions.size()) * sizeof(int);
  if (dense_factorization) bytes += dense_factorization->memoryBytes();
  bytes += static_cast<std::size_t>(dense_bending.size()) * sizeof(double);
  if (guide_index) bytes += guide_index->memoryBytes();
  return bytes;
}

Result<PreparedSource> prepareSource(Mesh mesh, LandmarkSet landmarks, const std::string& label,
                                     const PrepareOptions& options) {
  const auto t0 = Clock::now();
  if (auto ok = validateSurfaceMesh(mesh, label); !ok) return ok.error();
  if (options.dense_centres < 0) return makeError(ErrorCode::kInvalidArgument, "dense_centres must be >= 0");
  PreparedSource prepared;
  prepared.label = label;
  if (mesh.normals.rows() != mesh.positions.rows()) {
    mesh.normals = computeSeamlessVertexNormals(mesh.positions, mesh.triangles);
  } else {
    WindingNormals checked = normalsAgreeingWithWinding(mesh.normals, mesh.positions, mesh.triangles);
    prepared.normals_against_winding = checked.replaced;
    mesh.normals = std::move(checked.normals);
  }
  prepared.mesh = std::move(mesh);
  prepared.diagonal = boundingBoxDiagonal(prepared.mesh.positions);

  auto positions = resolveLandmarks(landmarks, prepared.mesh, label);
  if (!positions) return positions.error();
  prepared.landmarks = std::move(landmarks);
  prepared.landmark_positions = std::move(*positions);
  prepared.landmark_vertices = landmarkVertices(prepared.landmarks, prepared.mesh, prepared.landmark_positions);
  {
    // The full landmark set must span 3D on its own (names in errors).
    std::vector<std::string> names;
    for (const auto& lm : prepared.landmarks.landmarks) names.push_back(lm.name);
    if (auto ok = checkTpsCentres(prepared.landmark_positions, {}, names); !ok) {
      return Error{ok.error().code, label + ": " + ok.error().message};
    }
  }

  // Dense map centres: landmarks first (so they can be pinned to the target's),
  // then a farthest-point sample that keeps away from them.
  if (options.dense_centres > 0) {
    std::vector<int> sample = farthestPointSample(prepared.mesh.positions, options.dense_centres);
    const double min_gap = 1e-3 * prepared.diagonal;
    Eigen::MatrixX3d centres(prepared.landmark_positions.rows() + static_cast<Eigen::Index>(sample.size()), 3);
    centres.topRows(prepared.landmark_positions.rows()) = prepared.landmark_positions;
    Eigen::Index n = prepared.landmark_positions.rows();
    for (int v : sample) {
      const Eigen::RowVector3d p = prepared.mesh.positions.row(v);
      if (((centres.topRows(n).rowwise() - p).rowwise().squaredNorm().array() < min_gap * min_gap).any()) continue;
      centres.row(n++) = p;
      prepared.dense_vertices.push_back(v);
    }
    prepared.dense_centres = centres.topRows(n);
    TpsOptions dense;
    dense.regularization = options.dense_regularization * prepared.diagonal;
    dense.leave_one_out = false;
    auto f = TpsFactorization::create(prepared.dense_centres, dense);
    if (!f) return Error{f.error().code, label + ": dense map: " + f.error().message};
    prepared.dense_factorization = std::move(*f);
    // The sliding's products run in float (slideInTangentPlanes).
    prepared.dense_bending =
        prepared.dense_factorization->bendingEnergyMatrix(TpsFactorization::BendingPrecision::kSingle);
  }
  // Vertex adjacency for smoothing on the source; the projection sample is a
  // maximal independent set of it (every vertex sampled or next to a sampled one).
  prepared.adjacency = vertexAdjacency(prepared.mesh.triangles, prepared.mesh.vertexCount());
  prepared.projection_sample = independentVertexSample(prepared.adjacency).vertices;
  {
    const std::vector<int> representative = coincidentVertexRepresentatives(prepared.mesh.positions);
    prepared.rims = meshRims(prepared.mesh, representative);
    if (!prepared.rims.empty()) prepared.rim_vertices = rimVertices(prepared.rims, prepared.mesh, representative);
    prepared.openings = findOpenings(prepared.mesh, prepared.rims, prepared.landmark_positions);
    if (!prepared.openings.empty()) {
      prepared.vertex_sides =
          openingSides(prepared.mesh, prepared.adjacency, representative, prepared.rims, prepared.openings);
      prepared.side_masks = sideMasks(prepared.vertex_sides);
      prepared.side_face_sets = sideFaceSets(prepared.vertex_sides, prepared.mesh.triangles);
    }
  }
  if (prepared.mesh.regions.size() > 0) {
    prepared.face_regions = faceRegionSets(prepared.mesh.regions, prepared.mesh.triangles);
    prepared.region_bits = vertexRegionBits(prepared.mesh.regions);
  }
  prepared.guide_index.emplace(prepared.mesh.positions, prepared.mesh.triangles);
  prepared.prepare_ms = msSince(t0);
  return prepared;
}


namespace {

// The source as a fit placed it on the target (correspondThroughFit): each
// dense-map landmark centre moves with its vertex.
SurfaceWarp surfaceFromFit(const PreparedSource& source, const Eigen::MatrixX3d& fitted) {
  SurfaceWarp surface;
  surface.positions = fitted;
  surface.normals = computeVertexNormals(fitted, source.mesh.triangles);
  surface.landmark_targets = source.landmark_positions;
  for (Eigen::Index l = 0; l < surface.landmark_targets.rows(); ++l) {
    const int v = source.landmark_vertices[static_cast<std::size_t>(l)];
    surface.landmark_targets.row(l) += fitted.row(v) - source.mesh.positions.row(v);
  }
  return surface;
}

// runWarp, or with `fitted` (correspondThroughFit) the fit in place of the
// dense refinement and local rounds.
Result<WarpResult> correspond(const PreparedSource& source, PreparedTarget target_prepared, const WarpOptions& options,
                              const Eigen::MatrixX3d* fitted) {
  const auto t_start = Clock::now();
  if (!source.guide_index) {
    return makeError(ErrorCode::kInvalidArgument, "the source was not prepared (prepareSource) before the warp");
  }
  WarpResult result;
  WarpReport& report = result.report;
  const double target_prepare_ms = target_prepared.prepare_ms;

  // --- warp: landmark TPS on the shared names
  auto t0 = Clock::now();
  auto prepared = setUpTarget(source, std::move(target_prepared), options, report);
  if (!prepared) return prepared.error();
  const Mesh& target = prepared->mesh;
  const std::string& target_label = prepared->label;
  report.source_vertices = static_cast<int>(source.mesh.vertexCount());
  report.source_triangles = static_cast<int>(source.mesh.triangleCount());
  report.target_vertices = static_cast<int>(target.vertexCount());
  report.target_triangles = static_cast<int>(target.triangleCount());
  report.target_diagonal = prepared->diagonal;
  auto fit = fitLandmarkWarp(source, prepared->landmarks, *prepared, target_label, options, report);
  if (!fit) return fit.error();
  report.warp_ms = target_prepare_ms + msSince(t0);

  // --- correspond: refine through the dense map, project, locate
  t0 = Clock::now();
  ProjectionOptions projection = options.projection;
  orientTarget(source, fit->warp, target, target_label, *prepared, report);
  const Mesh& matched = prepared->matched();
  OpeningMatch openings = matchOpenings(source, fit->warp, target, *prepared, options, report);
  addRimPointsToWarp(source, openings, matched, target_label, options, *fit, report);
  SurfaceWarp surface;
  if (fitted) {
    surface = surfaceFromFit(source, *fitted);
    report.guide_from = "fit";
  } else {
    surface = warpSurface(source, *fit, openings, *prepared, matched, projection, options, report);
    runLocalRounds(source, openings, *prepared, matched, projection, options, surface, report);
  }
  ProjectedGuide projected = projectGuide(source, surface, openings, *prepared, projection, options, report);
  result.dense_map = fitDenseMap(source, surface, projected.guide);
  LocatedTarget located = locateTarget(source, target, surface, projected.guide, openings, *prepared, options, report);
  report.correspond_ms = msSince(t0);
  summariseGuide(source, projected, surface, located, report);

  result.landmark_warp = std::move(fit->warp);
  result.landmark_pairs = std::move(fit->pairs);
  result.warped_positions = std::move(surface.positions);
  result.guide = std::move(projected.guide);
  result.locations = std::move(located.locations);
  result.target_sides = std::move(openings.target_sides);
  result.target = std::move(static_cast<PreparedTarget&>(*prepared));
  report.total_ms = target_prepare_ms + msSince(t_start);
  return result;
}

}  // namespace

Result<WarpResult> runWarp(const PreparedSource& source, PreparedTarget target, const WarpOptions& options) {
  return correspond(source, std::move(target), options, nullptr);
}

Result<WarpResult> correspondThroughFit(const PreparedSource& source, PreparedTarget target,
                                        const Eigen::MatrixX3d& fitted_source, const WarpOptions& options) {
  if (fitted_source.rows() != source.mesh.vertexCount()) {
    return makeError(ErrorCode::kInvalidArgument, target.label + ": the fit has " + std::to_string(fitted_source.rows()) +
                                                      " vertices, the source " + std::to_string(source.mesh.vertexCount()));
  }
  return correspond(source, std::move(target), options, &fitted_source);
}

Result<WarpResult> runWarp(const PreparedSource& source, const Mesh& target, const LandmarkSet& target_landmarks,
                           const std::string& target_label, const WarpOptions& options) {
  auto prepared = prepareTarget(target, target_landmarks, target_label);
  if (!prepared) return prepared.error();
  return runWarp(source, std::move(*prepared), options);
}

}  // namespace core
