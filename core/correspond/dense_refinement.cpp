// The warp's later stages (core/correspond/warp_stages.h): the dense map
// refined through its centres, local rounds, the guide, the dense map fitted
// to it, and the target located on it.
#include <algorithm>
#include <array>
#include <cmath>
#include <numeric>

#include "core/correspond/warp_stages.h"

namespace core {

namespace {

double percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0.0;
  const std::size_t k = std::min(v.size() - 1, static_cast<std::size_t>(std::ceil(q * static_cast<double>(v.size()))) - (q > 0 ? 1 : 0));
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(k), v.end());
  return v[k];
}

// The guide with only `rows` (ascending source vertices) projected: the
// others keep their warped position and count as neither matched nor
// unmatched (distance 0).
GuideModel projectRowsToTarget(const Eigen::MatrixX3d& warped, const Eigen::MatrixX3d& normals,
                               const std::vector<int>& rows, const ClosestPointIndex& target_index,
                               double target_diagonal, const ProjectionOptions& projection,
                               const std::vector<std::uint64_t>& masks) {
  const GuideModel projected = projectToTarget(selectRows(warped, rows), selectRows(normals, rows), target_index,
                                               target_diagonal, projection, selectMasks(masks, rows));
  GuideModel guide;
  guide.positions = warped;
  guide.on_target.resize(static_cast<std::size_t>(warped.rows()));
  guide.distance = Eigen::VectorXd::Zero(warped.rows());
  guide.unmatched = projected.unmatched;
  for (std::size_t k = 0; k < rows.size(); ++k) {
    const auto i = static_cast<Eigen::Index>(k);
    guide.positions.row(rows[k]) = projected.positions.row(i);
    guide.on_target[static_cast<std::size_t>(rows[k])] = projected.on_target[k];
    guide.distance(rows[k]) = projected.distance(i);
  }
  return guide;
}

// The rows `rows` of a guide, in that order.
GuideModel selectGuideRows(const GuideModel& guide, const std::vector<int>& rows) {
  GuideModel out;
  out.positions = selectRows(guide.positions, rows);
  out.distance.resize(static_cast<Eigen::Index>(rows.size()));
  out.on_target.reserve(rows.size());
  for (std::size_t k = 0; k < rows.size(); ++k) {
    const SurfacePoint& sp = guide.on_target[static_cast<std::size_t>(rows[k])];
    out.on_target.push_back(sp);
    out.distance(static_cast<Eigen::Index>(k)) = guide.distance(rows[k]);
    out.unmatched += sp.found() ? 0 : 1;
  }
  return out;
}

// Where the warped source should move, per source vertex: the sum of w*d
// and of w over the pulls on it (normalised convolution, below). Packed so
// that one cache line holds two vertices: the passes gather neighbours, and
// this keeps each gather to one load.
using Pull = std::array<double, 4>;

// Trusted projection displacements (projected - warped) of the sampled
// vertices `rows` (guide row k belongs to vertex rows[k]), one pull each.
void addProjectionPulls(std::vector<Pull>& pulls, const Eigen::MatrixX3d& warped, const std::vector<int>& rows,
                        const GuideModel& guide, double trust) {
  for (std::size_t k = 0; k < rows.size(); ++k) {
    const auto g = static_cast<Eigen::Index>(k);
    if (!guide.on_target[k].found() || guide.distance(g) > trust) continue;
    const Eigen::RowVector3d d = guide.positions.row(g) - warped.row(rows[k]);
    Pull& p = pulls[static_cast<std::size_t>(rows[k])];
    p = Pull{p[0] + d(0), p[1] + d(1), p[2] + d(2), p[3] + 1.0};
  }
}

// Target vertices matched to points of the warped source (WarpOptions::
// target_pulls): each pulls its point, spread over the point's face corners
// by its barycentrics. The points move with the surface between rounds.
struct TargetPulls {
  std::vector<int> vertices;            // target vertices
  std::vector<double> weight;           // how many target vertices each stands for
  std::vector<SurfacePoint> on_source;  // their points: source face + barycentrics
};

void addTargetPulls(std::vector<Pull>& pulls, const Eigen::MatrixX3d& warped, const Eigen::MatrixX3i& triangles,
                    const TargetPulls& target_pulls, const Eigen::MatrixX3d& target_positions) {
  for (std::size_t i = 0; i < target_pulls.vertices.size(); ++i) {
    const SurfacePoint& sp = target_pulls.on_source[i];
    const Eigen::RowVector3d point = interpolateOnFace(warped, triangles, sp.face, sp.barycentric);
    const Eigen::RowVector3d d = target_positions.row(target_pulls.vertices[i]) - point;
    for (int k = 0; k < 3; ++k) {
      const double w = target_pulls.weight[i] * sp.barycentric(k);
      Pull& p = pulls[static_cast<std::size_t>(triangles(sp.face, k))];
      p = Pull{p[0] + w * d(0), p[1] + w * d(1), p[2] + w * d(2), p[3] + w};
    }
  }
}

// The pulls spread over the source mesh by normalised convolution: smooth
// w*d and w with the same uniform Laplacian passes and divide, so every
// vertex borrows from its pulled neighbours (0 where none reaches).
Eigen::MatrixX3d smoothedPulls(const PreparedSource& source, std::vector<Pull> acc, int passes) {
  const auto nv = static_cast<Eigen::Index>(acc.size());
  std::vector<Pull> next(acc.size());
  for (int pass = 0; pass < passes; ++pass) {
    for (std::size_t v = 0; v < acc.size(); ++v) {
      const int begin = source.adjacency.offsets[v];
      const int end = source.adjacency.offsets[v + 1];
      Pull sum = acc[v];
      for (int k = begin; k < end; ++k) {
        const Pull& u = acc[static_cast<std::size_t>(source.adjacency.indices[static_cast<std::size_t>(k)])];
        for (int c = 0; c < 4; ++c) sum[c] += u[c];
      }
      const double inv = 1.0 / (1 + end - begin);
      for (int c = 0; c < 4; ++c) next[v][c] = sum[c] * inv;
    }
    acc.swap(next);
  }
  Eigen::MatrixX3d out = Eigen::MatrixX3d::Zero(nv, 3);
  for (Eigen::Index v = 0; v < nv; ++v) {
    const Pull& a = acc[static_cast<std::size_t>(v)];
    if (a[3] > 1e-6) out.row(v) << a[0] / a[3], a[1] / a[3], a[2] / a[3];
  }
  return out;
}

// A sample of the target's vertices (an independent set: each stands for
// itself and the neighbours it covers; none on detached pieces) matched to
// their closest points on the warped source, within target_pull_max_distance
// and with normals within target_pull_max_angle_deg (region-constrained like
// every match: `target_masks`, per target vertex region bits or empty);
// `target` carries vertex normals (runWarp's target as matched). About a
// quarter of the queries of the whole target (mean of the nine ICT targets'
// E medians 0.0685 against 0.0676 with every vertex).
TargetPulls matchTargetPulls(const PreparedSource& source, const Eigen::MatrixX3d& warped, const Mesh& target,
                             const VertexAdjacency& target_adjacency, const std::vector<std::uint64_t>& source_face_labels,
                             const std::vector<std::uint64_t>& target_masks, const std::vector<int>& detached,
                             const WarpReport& report, const WarpOptions& options) {
  TargetPulls out;
  const VertexSample sample = independentVertexSample(target_adjacency);
  for (std::size_t k = 0; k < sample.vertices.size(); ++k) {
    const int v = sample.vertices[k];
    if (!detached.empty() && detached[static_cast<std::size_t>(v)] >= 0) continue;
    out.vertices.push_back(v);
    out.weight.push_back(sample.weight[k]);
  }
  const MovingMeshIndex::Fitted on_warped =
      source.guide_index->fit(warped, target_masks.empty() ? std::vector<std::uint64_t>() : source_face_labels);
  ClosestPointOptions cp;
  cp.max_normal_angle_deg = options.target_pull_max_angle_deg;
  cp.max_distance = options.target_pull_max_distance * report.target_diagonal;
  ClosestPointFilters filters;
  filters.normals = selectRows(target.normals, out.vertices);
  if (!target_masks.empty()) filters.label_masks = selectMasks(target_masks, out.vertices);
  const std::vector<SurfacePoint> hits = on_warped.closestPoints(selectRows(target.positions, out.vertices), cp, filters);
  std::size_t kept = 0;
  for (std::size_t i = 0; i < hits.size(); ++i) {
    if (!hits[i].found()) continue;
    out.vertices[kept] = out.vertices[i];
    out.weight[kept] = out.weight[i];
    out.on_source.push_back(hits[i]);
    ++kept;
  }
  out.vertices.resize(kept);
  out.weight.resize(kept);
  return out;
}

// Source vertex v lies on a source rim that matched a target rim (rim_match:
// per source rim, its target rim or -1).
bool onMatchedRim(const PreparedSource& source, int v, const std::vector<int>& rim_match) {
  if (source.rim_vertices.rim.empty()) return false;
  const int r = source.rim_vertices.rim[static_cast<std::size_t>(v)];
  return r >= 0 && rim_match[static_cast<std::size_t>(r)] >= 0;
}

// Dense centres on a matched source rim (rim_match: per source rim, its
// target rim or -1) go to the closest point of that target rim instead of the
// surface. Row k of `projected` is source vertex rows[k] at queries.row(k);
// rim tangents are carried by the landmark warp's linear part `frame`.
void projectRimCentres(GuideModel& projected, const Eigen::MatrixX3d& queries, const std::vector<int>& rows,
                       const PreparedSource& source, const Eigen::Matrix3d& frame, const std::vector<int>& rim_match,
                       const std::vector<Rim>& target_rims, const Mesh& target) {
  if (source.rim_vertices.rim.empty()) return;
  for (Eigen::Index k = 0; k < queries.rows(); ++k) {
    const int v = rows[static_cast<std::size_t>(k)];
    if (!onMatchedRim(source, v, rim_match)) continue;
    const Eigen::Vector3d tangent = (source.rim_vertices.tangent.row(v) * frame).transpose();
    const int r = source.rim_vertices.rim[static_cast<std::size_t>(v)];
    const Rim& rim = target_rims[static_cast<std::size_t>(rim_match[static_cast<std::size_t>(r)])];
    const SurfacePoint sp = closestPointOnRim(queries.row(k).transpose(), tangent, rim, target.positions);
    if (!sp.found()) continue;
    if (!projected.on_target[static_cast<std::size_t>(k)].found()) --projected.unmatched;
    projected.on_target[static_cast<std::size_t>(k)] = sp;
    projected.positions.row(k) = sp.point.transpose();
    projected.distance(k) = std::sqrt(sp.sq_distance);
  }
}

// The refinement's sliding step (slideInTangentPlanes). Free centre k is
// row rows[k] of `centre_targets`, projected to projected.on_target[k] with
// query normal query_normals.row(k) and region mask query_masks[k] (none when
// empty); those listed in `sliding` slide in the plane of the target face
// they were projected to and are projected again the same way. One that then
// finds no compatible face keeps its projection.
struct SlideResult {
  Eigen::MatrixX3d centre_targets;
  int slid = 0;             // centres that slid
  double mean_slide = 0.0;  // their mean slide
};

SlideResult slideOnTarget(const Eigen::MatrixXd& bending, const Eigen::MatrixX3d& centre_targets,
                          const std::vector<int>& rows, const std::vector<int>& sliding, const GuideModel& projected,
                          const Eigen::MatrixX3d& query_normals, const std::vector<std::uint64_t>& query_masks,
                          const Mesh& target, const ClosestPointIndex& target_index, double target_diagonal,
                          const ProjectionOptions& projection) {
  std::vector<int> sliding_rows(sliding.size());
  Eigen::MatrixX3d face_normals(static_cast<Eigen::Index>(sliding.size()), 3);
  for (std::size_t i = 0; i < sliding.size(); ++i) {
    sliding_rows[i] = rows[static_cast<std::size_t>(sliding[i])];
    const int f = projected.on_target[static_cast<std::size_t>(sliding[i])].face;
    const Eigen::Vector3d a = target.positions.row(target.triangles(f, 0));
    const Eigen::Vector3d b = target.positions.row(target.triangles(f, 1));
    const Eigen::Vector3d c = target.positions.row(target.triangles(f, 2));
    face_normals.row(static_cast<Eigen::Index>(i)) = (b - a).cross(c - a).transpose();
  }
  const Eigen::MatrixX3d slid = slideInTangentPlanes(bending, centre_targets, sliding_rows, face_normals);
  const GuideModel again = projectToTarget(selectRows(slid, sliding_rows), selectRows(query_normals, sliding),
                                           target_index, target_diagonal, projection, selectMasks(query_masks, sliding));
  SlideResult out{centre_targets};
  double total = 0.0;
  for (std::size_t i = 0; i < sliding.size(); ++i) {
    const auto row = static_cast<Eigen::Index>(sliding_rows[i]);
    if (!again.on_target[i].found()) continue;
    out.centre_targets.row(row) = again.positions.row(static_cast<Eigen::Index>(i));
    total += (out.centre_targets.row(row) - centre_targets.row(row)).norm();
    ++out.slid;
  }
  out.mean_slide = out.slid > 0 ? total / out.slid : 0.0;
  return out;
}

// Target vertices on a rim located on a source rim of the guide
// (`guide_positions`) instead of its surface (WarpOptions::rim_location): the
// rim point, among edges running the vertex's way, closest to its surface
// location. The surface location says which side (lip, lid) the vertex is
// on; from the vertex itself, near a slit's corner, a staircase rim's step
// of the other side can be nearer. A vertex the location refused (its
// surface point across a thin gap) searches from itself and is taken back
// when the rim point is on another face. `source_face_labels`,
// `target_masks`: the source faces' label sets and each target vertex's bits
// (region labels or opening sides), or empty (no filter). Confidence there is the distance
// term alone: a rim vertex's normal averages the faces of one side only
// (normal_cosine keeps the surface location's). Returns how many moved.
int locateRimVertices(TargetLocations& locations, const Mesh& target, const std::vector<Rim>& target_rims,
                      const std::vector<int>& target_representative, const PreparedSource& source,
                      const Eigen::MatrixX3d& guide_positions, const std::vector<std::uint64_t>& source_face_labels,
                      const std::vector<std::uint64_t>& target_masks, double target_diagonal,
                      const WarpOptions& options) {
  // A vertex a tenth of an edge from a rim vertex is a rim point too.
  constexpr double kNearRim = 0.1;
  RimVertices on_rim = rimVertices(target_rims, target, target_representative);
  addNearRimVertices(on_rim, target, target_representative, kNearRim);
  const Eigen::MatrixX3i& triangles = source.mesh.triangles;
  const double max_distance = options.rim_location_max_distance * target_diagonal;
  // A hair's breadth, so that a vertex on both the rim and the surface (a
  // target of the source's own topology) is not refused by the ratio.
  const double tie = 1e-4 * target_diagonal;
  const double confidence_distance = options.locate.low_confidence_distance * target_diagonal;
  // The longest source rims only, as in matchRims, each skipped where its box
  // is out of reach: a scan full of small holes must not cost a quadratic search.
  const std::size_t rim_count = std::min(source.rims.size(), static_cast<std::size_t>(std::max(0, options.rims.max_rims)));
  std::vector<Eigen::AlignedBox3d> rim_boxes(rim_count);
  for (std::size_t r = 0; r < rim_count; ++r) {
    for (int u : source.rims[r].vertices) rim_boxes[r].extend(guide_positions.row(u).transpose());
  }
  int moved = 0;
  for (Eigen::Index v = 0; v < target.vertexCount(); ++v) {
    // A vertex with no compatible guide face stays as it is (inpainted).
    SurfacePoint& located = locations.on_source[static_cast<std::size_t>(v)];
    if (on_rim.rim[static_cast<std::size_t>(v)] < 0 || !located.found()) continue;
    // A vertex the location refused (matched across a thin gap: the other
    // lip) searches the rims from itself; any other from its surface point.
    const bool refused = locations.mismatched(v) != 0;
    const Eigen::Vector3d p = target.positions.row(v).transpose();
    const Eigen::Vector3d from =
        refused ? p
                : Eigen::Vector3d(
                      interpolateOnFace(guide_positions, triangles, located.face, located.barycentric).transpose());
    const Eigen::Vector3d tangent = on_rim.tangent.row(v).transpose();
    SurfacePoint best;
    for (std::size_t r = 0; r < rim_count; ++r) {
      if (rim_boxes[r].exteriorDistance(p) > max_distance) continue;
      const SurfacePoint sp = closestPointOnRim(from, tangent, source.rims[r], guide_positions);
      if (!sp.found() || sp.sq_distance >= best.sq_distance) continue;
      if (!target_masks.empty() && (source_face_labels[static_cast<std::size_t>(sp.face)] &
                                    target_masks[static_cast<std::size_t>(v)]) == 0) {
        continue;
      }
      best = sp;
    }
    if (!best.found()) continue;
    const double d = (best.point - p).norm();
    if (d > max_distance || d > options.rim_location_max_ratio * std::sqrt(located.sq_distance) + tie) continue;
    // The rim point of a refused vertex on the very face the location refused
    // says nothing new (a staircase rim's step of the other lip ran its way).
    if (refused && best.face == located.face) continue;
    locations.mismatched(v) = 0;
    const bool was_low = locations.confidence(v) == 0.0;
    located = best;
    located.sq_distance = d * d;
    locations.distance(v) = d;
    locations.confidence(v) = confidence_distance > 0.0 ? std::max(0.0, 1.0 - d / confidence_distance) : 1.0;
    locations.low_confidence += (locations.confidence(v) == 0.0 ? 1 : 0) - (was_low ? 1 : 0);
    ++moved;
  }
  return moved;
}

// Projections farther than this from where they started are not trusted.
double trustedDistance(const WarpOptions& options, const WarpReport& report) {
  return options.refine_max_distance * report.target_diagonal;
}

// The target is located on the smoothed guide, not the guide itself.
bool locatesOnSmoothedGuide(const WarpOptions& options) { return options.smooth_guide && options.local_rounds > 0; }

}  // namespace

SurfaceWarp warpSurface(const PreparedSource& source, const LandmarkFit& fit, const OpeningMatch& openings,
                        const WarpTarget& prepared, const Mesh& matched, const ProjectionOptions& projection,
                        const WarpOptions& options, WarpReport& report) {
  // The whole source is warped once: by the dense map at the end of the
  // refinement (its centres' normals start from the landmark warp's
  // Jacobian, as the sampled ones above), or without a refinement here.
  const bool refine = source.dense_factorization && options.refine_iterations > 0;
  SurfaceWarp surface;
  if (!refine) {
    surface.positions = fit.warp.apply(source.mesh.positions);
    surface.normals = computeVertexNormals(surface.positions, source.mesh.triangles);
  }
  // Targets of the dense map's landmark centres: the job's target landmarks;
  // for source landmarks the target does not use, the warp's image, then
  // where the refinement puts them.
  surface.landmark_targets = fit.warp.apply(source.landmark_positions);
  std::vector<char> landmark_used(static_cast<std::size_t>(surface.landmark_targets.rows()), 0);
  for (std::size_t i = 0; i < fit.pairs.names.size(); ++i) {
    const int l = source.landmarks.indexOf(fit.pairs.names[i]);
    surface.landmark_targets.row(l) = fit.pairs.target.row(static_cast<Eigen::Index>(i));
    landmark_used[static_cast<std::size_t>(l)] = 1;
  }
  if (refine) {
    // Non-rigid ICP on the dense centres only: project the free ones (the
    // farthest-point samples, and the source landmarks the target does not
    // use), fit the dense map to the trusted projections, move the free
    // centres (and their normals, by the map's Jacobian) and repeat. The full
    // surface is warped once at the end. The job's landmarks stay pinned.
    const Eigen::Index nl = source.landmark_positions.rows();
    const double trust = trustedDistance(options, report);
    std::vector<int> rows, vertices;  // per free centre: its row of the centres, its (nearest) source vertex
    for (Eigen::Index l = 0; l < nl; ++l) {
      if (landmark_used[static_cast<std::size_t>(l)]) continue;
      rows.push_back(static_cast<int>(l));
      vertices.push_back(source.landmark_vertices[static_cast<std::size_t>(l)]);
    }
    for (std::size_t k = 0; k < source.dense_vertices.size(); ++k) {
      rows.push_back(static_cast<int>(nl + static_cast<Eigen::Index>(k)));
      vertices.push_back(source.dense_vertices[k]);
    }
    const Eigen::MatrixX3d free_sources = selectRows(source.dense_centres, rows);
    const Eigen::MatrixX3d free_source_normals = selectRows(source.mesh.normals, vertices);
    const std::vector<std::uint64_t> free_masks = selectMasks(openings.source_masks, vertices);
    Eigen::MatrixX3d free_positions = fit.warp.apply(free_sources);
    Eigen::MatrixX3d free_normals = normalsThroughWarp(fit.warp, free_sources, free_source_normals);
    const Eigen::Matrix3d rim_frame = fit.warp.affine().topRows<3>();
    Eigen::MatrixX3d centre_targets(source.dense_centres.rows(), 3);
    TpsWarp dense;
    for (int it = 0; it < options.refine_iterations; ++it) {
      GuideModel projected = projectToTarget(free_positions, free_normals, prepared.index, report.target_diagonal,
                                             projection, free_masks);
      projectRimCentres(projected, free_positions, vertices, source, rim_frame, openings.rim_match, openings.target_rims, matched);
      centre_targets.topRows(nl) = surface.landmark_targets;
      std::vector<int> sliding;  // free centres
      for (std::size_t k = 0; k < rows.size(); ++k) {
        const auto i = static_cast<Eigen::Index>(k);
        const bool trusted = projected.on_target[k].found() && projected.distance(i) <= trust;
        centre_targets.row(rows[k]) = trusted ? projected.positions.row(i) : free_positions.row(i);
        if (trusted && !onMatchedRim(source, vertices[k], openings.rim_match)) sliding.push_back(static_cast<int>(k));
      }
      if (options.slide_centres && source.dense_bending.size() > 0) {
        SlideResult slide = slideOnTarget(source.dense_bending, centre_targets, rows, sliding, projected,
                                          free_normals, free_masks, matched, prepared.index, report.target_diagonal,
                                          projection);
        centre_targets = std::move(slide.centre_targets);
        report.slid_centres = slide.slid;
        if (it == 0) report.mean_slide = slide.mean_slide;
      }
      dense = source.dense_factorization->fit(centre_targets);
      report.refine_iterations = it + 1;
      if (it + 1 == options.refine_iterations) break;
      // Free centres and their normals through the new map (normals by J^-T).
      free_positions = dense.apply(free_sources);
      free_normals = normalsThroughWarp(dense, free_sources, free_source_normals);
    }
    for (std::size_t k = 0; k < rows.size() && rows[k] < nl; ++k) surface.landmark_targets.row(rows[k]) = centre_targets.row(rows[k]);
    surface.positions = dense.apply(source.mesh.positions);
    surface.normals = computeVertexNormals(surface.positions, source.mesh.triangles);
  }
  return surface;
}

void runLocalRounds(const PreparedSource& source, const OpeningMatch& openings, const WarpTarget& prepared,
                    const Mesh& matched, const ProjectionOptions& projection, const WarpOptions& options,
                    SurfaceWarp& surface, WarpReport& report) {
  // Local rounds: only the sampled vertices are projected to compute each
  // step (the smoothing spreads their displacements over the rest); the last
  // projection, the guide, covers every vertex. Target vertices pull too
  // (WarpOptions::target_pulls), matched once to the surface as the dense
  // map left it.
  const double trust = trustedDistance(options, report);
  TargetPulls target_pulls;
  if (options.local_rounds > 0 && options.target_pulls) {
    target_pulls = matchTargetPulls(source, surface.positions, matched, prepared.adjacency,
                                    openings.source_face_labels, openings.target_masks, prepared.detached, report, options);
    report.target_pulls = static_cast<int>(target_pulls.vertices.size());
  }
  for (int round = 0; round < options.local_rounds; ++round) {
    const std::vector<int>& rows = source.projection_sample;
    const GuideModel sampled =
        projectToTarget(selectRows(surface.positions, rows), selectRows(surface.normals, rows), prepared.index,
                        report.target_diagonal, projection, selectMasks(openings.source_masks, rows));
    std::vector<Pull> pulls(static_cast<std::size_t>(surface.positions.rows()), Pull{0.0, 0.0, 0.0, 0.0});
    addProjectionPulls(pulls, surface.positions, rows, sampled, trust);
    addTargetPulls(pulls, surface.positions, source.mesh.triangles, target_pulls, matched.positions);
    surface.positions += smoothedPulls(source, std::move(pulls), options.smoothing_passes);
    surface.normals = computeVertexNormals(surface.positions, source.mesh.triangles);
  }
}

ProjectedGuide projectGuide(const PreparedSource& source, const SurfaceWarp& surface, const OpeningMatch& openings,
                            const WarpTarget& prepared, const ProjectionOptions& projection, const WarpOptions& options,
                            WarpReport& report) {
  // The guide: the source projected onto the target. A transfer reads it
  // only at the projection sample (the smoothed guide below) and at the dense
  // centres' vertices (the dense map), so unless the job returns the guide
  // (WarpOptions::full_guide) or locates the target on it, only those are
  // projected: ~30% of the vertices.
  const bool on_smoothed_guide = locatesOnSmoothedGuide(options);
  ProjectedGuide out;
  std::vector<int>& guide_rows = out.rows;
  guide_rows.resize(static_cast<std::size_t>(surface.positions.rows()));
  std::iota(guide_rows.begin(), guide_rows.end(), 0);
  if (options.full_guide || !on_smoothed_guide) {
    out.guide = projectToTarget(surface.positions, surface.normals, prepared.index, report.target_diagonal,
                                   projection, openings.source_masks);
  } else {
    std::vector<char> read(guide_rows.size(), 0);
    for (const int v : source.projection_sample) read[static_cast<std::size_t>(v)] = 1;
    for (const int v : source.dense_vertices) read[static_cast<std::size_t>(v)] = 1;
    std::erase_if(guide_rows, [&](int v) { return read[static_cast<std::size_t>(v)] == 0; });
    out.guide = projectRowsToTarget(surface.positions, surface.normals, guide_rows, prepared.index,
                                       report.target_diagonal, projection, openings.source_masks);
  }
  report.projected_source_vertices = static_cast<int>(guide_rows.size());
  return out;
}

std::optional<TpsWarp> fitDenseMap(const PreparedSource& source, const SurfaceWarp& surface, const GuideModel& guide) {
  if (source.dense_factorization) {
    const Eigen::Index nl = source.landmark_positions.rows();
    Eigen::MatrixX3d centre_targets(source.dense_centres.rows(), 3);
    centre_targets.topRows(nl) = surface.landmark_targets;
    for (std::size_t k = 0; k < source.dense_vertices.size(); ++k) {
      centre_targets.row(nl + static_cast<Eigen::Index>(k)) = guide.positions.row(source.dense_vertices[k]);
    }
    return source.dense_factorization->fit(centre_targets);
  }
  return std::nullopt;
}

LocatedTarget locateTarget(const PreparedSource& source, const Mesh& target, const SurfaceWarp& surface,
                           const GuideModel& guide, const OpeningMatch& openings, const WarpTarget& prepared,
                           const WarpOptions& options, WarpReport& report) {
  // The target is located on the smoothed guide (WarpOptions::smooth_guide):
  // one more local round's smoothed displacement of the projection sample,
  // without target pulls; or on the guide itself.
  const Mesh& matched = prepared.matched();
  const bool on_smoothed_guide = locatesOnSmoothedGuide(options);
  const double trust = trustedDistance(options, report);
  LocatedTarget out;
  Eigen::MatrixX3d& located_on = out.located_on;
  located_on = guide.positions;
  if (on_smoothed_guide) {
    const std::vector<int>& rows = source.projection_sample;
    std::vector<Pull> pulls(static_cast<std::size_t>(surface.positions.rows()), Pull{0.0, 0.0, 0.0, 0.0});
    addProjectionPulls(pulls, surface.positions, rows, selectGuideRows(guide, rows), trust);
    located_on = surface.positions + smoothedPulls(source, std::move(pulls), options.smoothing_passes);
  }
  out.locations = locateOnGuide(matched, located_on, *source.guide_index, options.locate, openings.source_face_labels,
                                openings.target_masks, openings.sides_filter ? openings.target_sides : std::vector<int>(),
                                &prepared.representative);
  if (options.rim_location && !openings.target_rims.empty()) {
    report.rim_located_vertices = locateRimVertices(
        out.locations, matched, openings.target_rims, prepared.representative, source, located_on, openings.source_face_labels,
        openings.target_masks, report.target_diagonal, options);
  }
  for (Eigen::Index v = 0; v < target.vertexCount() && !prepared.detached.empty(); ++v) {
    if (prepared.detached[static_cast<std::size_t>(v)] < 0) continue;
    if (out.locations.confidence(v) > 0.0) ++out.locations.low_confidence;
    out.locations.confidence(v) = 0.0;
    out.locations.mismatched(v) = 1;
  }
  out.locations.detached_piece = prepared.detached;
  return out;
}

void summariseGuide(const PreparedSource& source, const ProjectedGuide& projected, const SurfaceWarp& surface,
                    const LocatedTarget& located, WarpReport& report) {
  std::vector<double> d;
  d.reserve(projected.rows.size());
  for (const int v : projected.rows) d.push_back(projected.guide.distance(v));
  report.mean_distance = d.empty() ? 0.0 : std::accumulate(d.begin(), d.end(), 0.0) / static_cast<double>(d.size());
  report.max_distance = d.empty() ? 0.0 : *std::max_element(d.begin(), d.end());
  report.p95_distance = percentile(d, 0.95);
  // Folds of the surface the target was located on.
  const FoldReport folds = countFolds(surface.positions, located.located_on, source.mesh.triangles);
  report.flipped_triangles = folds.flipped;
  report.collapsed_triangles = folds.collapsed;
  report.unmatched_source_vertices = projected.guide.unmatched;
  report.low_confidence_vertices = located.locations.low_confidence;
}

}  // namespace core
