#include "core/correspond/warp_job.h"

#include <algorithm>
#include <array>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <numeric>

#include <Eigen/Geometry>

#include "core/geometry/similarity.h"

namespace core {

namespace {

// Beyond this landmark misfit (WarpReport::landmark_misfit_deg) the
// landmarks are taken for another mesh's: faces measured 2.4-11 degrees (ICT
// identities, exaggerated 3x, the cartoon), landmarks of another vertex
// order 68-84.
constexpr double kLandmarkMisfitDeg = 30.0;

using Clock = std::chrono::steady_clock;

double msSince(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

double percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0.0;
  const std::size_t k = std::min(v.size() - 1, static_cast<std::size_t>(std::ceil(q * static_cast<double>(v.size()))) - (q > 0 ? 1 : 0));
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(k), v.end());
  return v[k];
}

Eigen::MatrixX3d selectRows(const Eigen::MatrixX3d& m, const std::vector<int>& rows) {
  Eigen::MatrixX3d out(static_cast<Eigen::Index>(rows.size()), 3);
  for (std::size_t k = 0; k < rows.size(); ++k) out.row(static_cast<Eigen::Index>(k)) = m.row(rows[k]);
  return out;
}

// Unit normals at `points` carried through `warp` (J^-T n).
Eigen::MatrixX3d normalsThroughWarp(const TpsWarp& warp, const Eigen::MatrixX3d& points, const Eigen::MatrixX3d& normals) {
  const std::vector<Eigen::Matrix3d> jacobians = warp.jacobians(points);
  Eigen::MatrixX3d out(points.rows(), 3);
  for (Eigen::Index k = 0; k < points.rows(); ++k) {
    const Eigen::Vector3d n =
        jacobians[static_cast<std::size_t>(k)].inverse().transpose() * normals.row(k).transpose();
    out.row(k) = n.normalized().transpose();
  }
  return out;
}

// The entries `rows` of per-vertex masks (empty stays empty: no constraint).
std::vector<std::uint64_t> selectMasks(const std::vector<std::uint64_t>& masks, const std::vector<int>& rows) {
  std::vector<std::uint64_t> out;
  if (masks.empty()) return out;
  out.reserve(rows.size());
  for (const int r : rows) out.push_back(masks[static_cast<std::size_t>(r)]);
  return out;
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
  cp.threads = options.threads;
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

// Region labels on one side only cannot match: warns about them by number
// (numbering mix-ups), and refuses label sets with nothing in common.
Status checkRegionLabels(const Eigen::VectorXi& source, const Eigen::VectorXi& target, const std::string& target_label,
                         std::vector<std::string>& warnings) {
  auto present = [](const Eigen::VectorXi& regions) {
    std::uint64_t bits = 0;
    for (Eigen::Index v = 0; v < regions.size(); ++v) bits |= std::uint64_t{1} << regions(v);
    return bits;
  };
  auto labels = [](std::uint64_t bits) {
    std::string out;
    for (int l = 0; l <= kMaxRegionLabel; ++l) {
      if ((bits >> l) & 1u) out += (out.empty() ? "" : ", ") + std::to_string(l);
    }
    return out;
  };
  // "region label 3 occurs" / "region labels 3, 4 occur"
  auto listed = [&](std::uint64_t bits) {
    return std::popcount(bits) == 1 ? "region label " + labels(bits) + " occurs" : "region labels " + labels(bits) + " occur";
  };
  const std::uint64_t on_source = present(source), on_target = present(target);
  if ((on_source & on_target) == 0) {
    return makeError(ErrorCode::kInvalidArgument,
                     target_label + ": its _" + std::string(kRegionAttribute) + " labels (" + labels(on_target) +
                         ") share none with the source's (" + labels(on_source) +
                         "): nothing could match; check the numbering, or set region_matching to false");
  }
  if (const std::uint64_t only = on_source & ~on_target; only != 0) {
    warnings.push_back(listed(only) + " on the source but not on " + target_label +
                       ": those source vertices cannot match (left unmatched)");
  }
  if (const std::uint64_t only = on_target & ~on_source; only != 0) {
    warnings.push_back(listed(only) + " on " + target_label +
                       " but not on the source: those target vertices cannot be located (inpainted)");
  }
  return Ok{};
}

// Closed pieces of the target that no landmark is on: eyeballs or teeth
// modelled in the face's mesh. Lids resting on an eyeball would otherwise
// project onto it. Per vertex the number of its detached piece (0, 1, ...)
// or -1; empty when there are none (one piece, or every piece open or
// landmarked). Open pieces stay skin (an ear modelled apart has a rim where
// it meets the head).
std::vector<int> detachedPieces(const Mesh& target, const std::vector<int>& representative,
                                 const LandmarkSet& landmarks, const Eigen::MatrixX3d& landmark_positions,
                                 const ClosestPointIndex& index, WarpReport& report) {
  const MeshPieces pieces = meshPieces(target, representative);
  if (pieces.count < 2) return {};
  std::vector<char> skin(static_cast<std::size_t>(pieces.count), 0);
  for (const int v : landmarkVertices(landmarks, target, landmark_positions, &index)) {
    const int piece = v >= 0 ? pieces.vertex_piece[static_cast<std::size_t>(v)] : -1;
    if (piece >= 0) skin[static_cast<std::size_t>(piece)] = 1;
  }
  for (const BoundaryLoop& loop : boundaryLoops(weldedTopology(target, representative))) {
    if (loop.vertices.empty()) continue;
    skin[static_cast<std::size_t>(pieces.vertex_piece[static_cast<std::size_t>(loop.vertices.front())])] = 1;
  }
  report.detached_pieces = static_cast<int>(std::count(skin.begin(), skin.end(), 0));
  if (report.detached_pieces == 0) return {};
  std::vector<int> number(static_cast<std::size_t>(pieces.count), -1);
  for (int piece = 0, next = 0; piece < pieces.count; ++piece) {
    if (!skin[static_cast<std::size_t>(piece)]) number[static_cast<std::size_t>(piece)] = next++;
  }
  std::vector<int> detached(static_cast<std::size_t>(target.vertexCount()), -1);
  for (Eigen::Index v = 0; v < target.vertexCount(); ++v) {
    const int piece = pieces.vertex_piece[static_cast<std::size_t>(v)];
    if (piece >= 0 && !skin[static_cast<std::size_t>(piece)]) {
      detached[static_cast<std::size_t>(v)] = number[static_cast<std::size_t>(piece)];
      ++report.detached_vertices;
    }
  }
  return detached;
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

// The landmarks' misfit to the best similarity, as an angle: atan(rms
// residual / (scale x rms spread)), degrees; the better of the similarity
// and its mirror image (swapped left/right names are warned about apart).
double landmarkMisfitDeg(const Eigen::MatrixX3d& source, const Eigen::MatrixX3d& target) {
  const Eigen::MatrixX3d centred = source.rowwise() - source.colwise().mean();
  const double spread = std::sqrt(centred.rowwise().squaredNorm().mean());
  if (!(spread > 0.0)) return 0.0;
  double best = 90.0;
  for (const double mirror : {1.0, -1.0}) {
    Eigen::MatrixX3d seen = target;
    seen.col(0) *= mirror;
    const Similarity similarity = fitSimilarity(source, seen);
    if (similarity.scale > 0.0) {
      best = std::min(best, std::atan(similarity.rms_residual / (similarity.scale * spread)) * 180.0 / std::numbers::pi);
    }
  }
  return best;
}

// The target's openings: each source opening whose rim matched a target rim
// (rim_match), split at the target rim's vertices nearest to where the
// source's corners land under the landmark warp (they lie next to the
// landmarks that placed them, where the warp is sure), so that side s is
// side s on both. Per target vertex its side (openingSides, numbered as the
// source's), or empty when no opening matched. Counts them in the report.
std::vector<int> targetOpeningSides(const PreparedSource& source, const TpsWarp& landmark_warp,
                                    const std::vector<int>& rim_match, const std::vector<Rim>& target_rims,
                                    const Mesh& target, const VertexAdjacency& adjacency,
                                    const std::vector<int>& representative, const OpeningSideOptions& options,
                                    WarpReport& report) {
  std::vector<Opening> openings(source.openings.size());
  for (std::size_t k = 0; k < source.openings.size(); ++k) {
    const Opening& opening = source.openings[k];
    const int t = rim_match[static_cast<std::size_t>(opening.rim)];
    if (t < 0) continue;
    Eigen::MatrixX3d corners(2, 3);
    for (int c = 0; c < 2; ++c) {
      const std::vector<int>& loop = source.rims[static_cast<std::size_t>(opening.rim)].vertices;
      corners.row(c) = source.mesh.positions.row(loop[static_cast<std::size_t>(opening.corners[static_cast<std::size_t>(c)])]);
    }
    openings[k] = openingAtCorners(target_rims[static_cast<std::size_t>(t)], t, target.positions,
                                   landmark_warp.apply(corners));
    report.sided_openings += openings[k].rim >= 0 ? 1 : 0;
  }
  if (report.sided_openings == 0) return {};
  std::vector<int> sides = openingSides(target, adjacency, representative, target_rims, openings, options);
  report.sided_target_vertices = static_cast<int>(std::count_if(sides.begin(), sides.end(), [](int s) { return s >= 0; }));
  return sides;
}

}  // namespace

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
    dense.threads = options.threads;
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

Result<WarpResult> runWarp(const PreparedSource& source, const Mesh& target, const LandmarkSet& target_landmarks,
                           const std::string& target_label, const WarpOptions& options) {
  const auto t_start = Clock::now();
  if (!source.guide_index) {
    return makeError(ErrorCode::kInvalidArgument, "the source was not prepared (prepareSource) before the warp");
  }
  if (auto ok = validateSurfaceMesh(target, target_label); !ok) return ok.error();
  WarpResult result;
  WarpReport& report = result.report;
  report.source_vertices = static_cast<int>(source.mesh.vertexCount());
  report.source_triangles = static_cast<int>(source.mesh.triangleCount());
  report.target_vertices = static_cast<int>(target.vertexCount());
  report.target_triangles = static_cast<int>(target.triangleCount());
  report.target_diagonal = boundingBoxDiagonal(target.positions);

  // --- warp: landmark TPS on the shared names
  auto t0 = Clock::now();
  const bool source_regions = !source.face_regions.empty(), target_regions = target.regions.size() > 0;
  report.region_matching = options.region_matching && source_regions && target_regions;
  // Labelled rigs onto unlabelled scans are the usual case; labels painted on
  // a target for nothing are worth a word.
  if (options.region_matching && target_regions && !source_regions) {
    report.warnings.push_back(target_label + " carries _" + std::string(kRegionAttribute) +
                              " labels but the source does not: matching is not region-constrained");
  }
  if (report.region_matching) {
    if (auto ok = checkRegionLabels(source.mesh.regions, target.regions, target_label, report.warnings); !ok) {
      return ok.error();
    }
  }
  // Label sets per target face (corner order does not matter: also those of
  // the turned copy below).
  const std::vector<std::uint64_t> target_face_regions =
      report.region_matching ? faceRegionSets(target.regions, target.triangles) : std::vector<std::uint64_t>();
  ClosestPointIndex target_index(target.positions, target.triangles, target_face_regions);
  const std::vector<std::uint64_t> no_masks;
  auto target_positions = resolveLandmarks(target_landmarks, target, target_label, &target_index);
  if (!target_positions) return target_positions.error();
  const std::vector<int> target_representative = coincidentVertexRepresentatives(target.positions);
  result.target_adjacency = vertexAdjacency(target.triangles, target.vertexCount());
  const std::vector<int> detached = detachedPieces(target, target_representative, target_landmarks, *target_positions,
                                                    target_index, report);
  // The faces the source is matched to: detached ones made degenerate, which
  // the index skips (face numbers stay those of the target).
  auto skinTriangles = [&](Eigen::MatrixX3i triangles) {
    for (Eigen::Index f = 0; f < triangles.rows() && !detached.empty(); ++f) {
      if (detached[static_cast<std::size_t>(triangles(f, 0))] >= 0) triangles.row(f).setConstant(triangles(f, 0));
    }
    return triangles;
  };
  if (!detached.empty()) {
    target_index = ClosestPointIndex(target.positions, skinTriangles(target.triangles), target_face_regions);
    report.warnings.push_back(target_label + ": " + std::to_string(report.detached_pieces) + " closed piece" +
                              (report.detached_pieces == 1 ? "" : "s") + " with no landmark on " +
                              (report.detached_pieces == 1 ? "it" : "them") + " (" +
                              std::to_string(report.detached_vertices) +
                              " vertices: eyes, teeth?) not matched as skin; a transfer moves each rigidly with "
                              "the joint that dominates the skin weights where it sits, without shape deltas");
  }
  auto pairs = pairLandmarks(source.landmarks, source.landmark_positions, target_landmarks, *target_positions,
                             target_label);
  if (!pairs) return pairs.error();
  TpsOptions tps_options = options.landmark_tps;
  tps_options.threads = options.threads;
  tps_options.leave_one_out = true;
  auto factorization = TpsFactorization::create(pairs->source, tps_options, pairs->names);
  if (!factorization) return Error{factorization.error().code, target_label + ": " + factorization.error().message};
  // Target landmarks must span 3D as well, or the warp flattens the face.
  if (auto ok = checkTpsCentres(pairs->target, tps_options, pairs->names); !ok) {
    return Error{ok.error().code, target_label + ": " + ok.error().message};
  }
  result.landmark_warp = factorization->fit(pairs->target);
  const TpsLeaveOneOut loo = factorization->leaveOneOut(pairs->target);
  const Eigen::MatrixX3d fitted = result.landmark_warp.apply(pairs->source);
  report.landmark_count = static_cast<int>(pairs->names.size());
  double sum_sq = 0.0;
  for (std::size_t i = 0; i < pairs->names.size(); ++i) {
    const double r = (fitted.row(static_cast<Eigen::Index>(i)) - pairs->target.row(static_cast<Eigen::Index>(i))).norm();
    sum_sq += r * r;
    report.landmark_max_residual = std::max(report.landmark_max_residual, r);
    report.landmark_residuals.push_back({pairs->names[i], r, i < loo.residuals.size() ? loo.residuals[i] : 0.0});
  }
  report.landmark_rms_residual = std::sqrt(sum_sq / static_cast<double>(pairs->names.size()));
  for (int i : loo.suspicious) report.suspicious_landmarks.push_back(pairs->names[static_cast<std::size_t>(i)]);
  report.bending_energy = result.landmark_warp.bendingEnergy();
  report.landmark_misfit_deg = landmarkMisfitDeg(pairs->source, pairs->target);
  // Landmarks of another mesh (indices in range, of another vertex order or
  // topology) land anywhere on the target: the warp folds the source over
  // it, and what follows (a "turned" or inconsistently wound target, a
  // "scaled copy") would be blamed on the mesh. Said first, naming them.
  report.landmarks_misfit = report.landmark_misfit_deg > kLandmarkMisfitDeg;
  const bool landmarks_misfit = report.landmarks_misfit;
  if (landmarks_misfit) {
    char misfit[32];
    std::snprintf(misfit, sizeof misfit, "%.0f", report.landmark_misfit_deg);
    report.warnings.push_back(
        target_label + ": its landmarks do not lie as the source's do on any face (they miss the best similarity by " +
        misfit + " degrees; faces of other identities and styles miss by 2-15): they are probably those of another "
        "mesh or vertex order; check the landmarks file before trusting this result");
  }
  // Swapped left/right landmark names make the warp a mirror image: every
  // residual stays small, so only the sign of the linear part tells.
  if (result.landmark_warp.affine().topRows<3>().determinant() < 0.0) {
    report.warnings.push_back("the landmark warp mirrors the source onto " + target_label +
                              ": check that its left/right landmark names are not swapped (fine only if the "
                              "target is a mirror-image character)");
  }
  report.warp_ms = msSince(t0);

  // --- correspond: refine through the dense map, project, locate
  t0 = Clock::now();
  ProjectionOptions projection = options.projection;
  projection.threads = options.threads;
  const Eigen::MatrixX3i& tris = source.mesh.triangles;
  // The whole source is warped once the rims have had their say (below);
  // until then only the vertices sampled here and the rims' are.
  // A target whose faces face the other way (winding reversed on export, or
  // a mirroring warp) would fail every normal test below and be matched
  // across the surface; it is matched as a copy turned the source's way
  // (same faces, corners 1 and 2 swapped, normals negated). The sampled
  // vertices' normals are carried by the warp's Jacobian (J^-T n).
  {
    constexpr int kOrientationSamples = 256;
    const Eigen::Index nv = source.mesh.vertexCount();
    const Eigen::Index stride = std::max<Eigen::Index>(1, nv / kOrientationSamples);
    std::vector<int> rows;
    for (Eigen::Index v = 0; v < nv; v += stride) rows.push_back(static_cast<int>(v));
    const Eigen::MatrixX3d sampled = selectRows(source.mesh.positions, rows);
    report.orientation_agreement = faceOrientationAgreement(
        result.landmark_warp.apply(sampled),
        normalsThroughWarp(result.landmark_warp, sampled, selectRows(source.mesh.normals, rows)), target_index, target);
  }
  const std::string facing_against =
      std::to_string(std::lround(50.0 * (1.0 - report.orientation_agreement))) + "% of sampled matches face against it";
  Mesh adjusted;  // the target as matched, when that differs from the file
  const Mesh* matched = &target;
  if (report.orientation_agreement < 0.0 && !landmarks_misfit) {
    adjusted = target;
    adjusted.triangles.col(1).swap(adjusted.triangles.col(2));
    adjusted.normals = -adjusted.normals;
    target_index = ClosestPointIndex(adjusted.positions, skinTriangles(adjusted.triangles), target_face_regions);
    matched = &adjusted;
    report.target_turned = true;
    report.warnings.push_back(target_label + ": its faces face the opposite way to the source (" +
                              facing_against + "): matched with its faces turned; the output keeps its own winding");
  }
  if (std::abs(report.orientation_agreement) < 0.5 && !landmarks_misfit) {
    report.warnings.push_back(target_label + ": its face orientation is inconsistent (" + facing_against +
                              "): normal-based matching is unreliable; unify its winding");
  }
  // Vertex normals pointing against their faces (flipped on export, or the
  // winding reversed alone) would fail the location's normal test at every
  // such vertex, which would then be inpainted: those are matched by their
  // face normal instead. Checked after the turn, so only the normals that
  // disagree with the faces count.
  auto against = [](int count, Eigen::Index vertices) {
    return std::to_string(count) + " of its " + std::to_string(vertices) + " vertex normals (" +
           std::to_string(std::lround(100.0 * count / static_cast<double>(std::max<Eigen::Index>(1, vertices)))) +
           "%) point against its faces' winding";
  };
  if (matched->normals.rows() == matched->vertexCount()) {
    WindingNormals checked = normalsAgreeingWithWinding(matched->normals, matched->positions, matched->triangles);
    report.target_normals_against_winding = checked.replaced;
    if (checked.replaced > 0) {
      if (matched != &adjusted) {
        adjusted = target;
        matched = &adjusted;
      }
      adjusted.normals = std::move(checked.normals);
      report.warnings.push_back(target_label + ": " + against(checked.replaced, target.vertexCount()) +
                                ": matched by their face normals there; the output keeps its normals as they are");
    }
  } else {
    // A file without normals: computed once here for every match below
    // (target pulls and location).
    if (matched != &adjusted) {
      adjusted = target;
      matched = &adjusted;
    }
    adjusted.normals = computeSeamlessVertexNormals(adjusted.positions, adjusted.triangles);
  }
  report.source_normals_against_winding = source.normals_against_winding;
  if (source.normals_against_winding > 0) {
    report.warnings.push_back(source.label + ": " + against(source.normals_against_winding, source.mesh.vertexCount()) +
                              ": matched by their face normals there");
  }
  // Rims matched as warped by the landmarks. Those no landmark pins (a neck
  // cut) join the warp as paired points: far from the face's landmarks the
  // warp only extrapolates, and a neck shaped otherwise lands on the wrong
  // side of the target's, where projection would keep it. In the dense-map
  // rounds every matched rim's centres are put on the target's rim (the slide
  // along a tube that projection cannot see).
  // The openings' sides are found whenever rims or sides are matched, also
  // when _REGION labels or nothing filter the matches (the transfer's quality
  // check reads them); with side_matching and no labels they filter.
  const bool sides_wanted = (options.side_matching || options.rim_matching) && !source.openings.empty();
  bool sides_filter = false;
  std::vector<Rim> target_rims;
  if ((options.rim_matching || options.rim_location || sides_wanted) && !source.rims.empty()) {
    target_rims = meshRims(*matched, target_representative);
  }
  std::vector<int> rim_match(source.rims.size(), -1);
  // The source's rim vertices as the landmarks warp them (the only rows
  // matchRims and pairRimPoints read; the others keep source positions).
  Eigen::MatrixX3d rims_warped;
  if ((options.rim_matching || sides_wanted) && !source.rims.empty()) {
    rims_warped = source.mesh.positions;
    std::vector<int> rows;
    for (const Rim& rim : source.rims) rows.insert(rows.end(), rim.vertices.begin(), rim.vertices.end());
    const Eigen::MatrixX3d warped = result.landmark_warp.apply(selectRows(source.mesh.positions, rows));
    for (std::size_t k = 0; k < rows.size(); ++k) rims_warped.row(rows[k]) = warped.row(static_cast<Eigen::Index>(k));
    rim_match = matchRims(source.rims, rims_warped, target_rims, matched->positions, options.rims);
  }
  // Lips and lids kept to their sides (WarpOptions::side_matching): the
  // openings' sides filter every match from here on, as _REGION labels do.
  std::vector<std::uint64_t> source_masks = report.region_matching ? source.region_bits : no_masks;
  std::vector<std::uint64_t> source_face_labels = report.region_matching ? source.face_regions : no_masks;
  std::vector<std::uint64_t> target_masks =
      report.region_matching ? vertexRegionBits(target.regions) : std::vector<std::uint64_t>();
  if (sides_wanted) {
    result.target_sides = targetOpeningSides(source, result.landmark_warp, rim_match, target_rims, *matched,
                                             result.target_adjacency, target_representative, options.sides, report);
    sides_filter = options.side_matching && !report.region_matching && !result.target_sides.empty();
    if (sides_filter) {
      source_masks = source.side_masks;
      source_face_labels = source.side_face_sets;
      target_masks = sideMasks(result.target_sides);
      target_index.setFaceLabels(sideFaceSets(result.target_sides, matched->triangles));
    }
  }
  if (!options.rim_matching) std::fill(rim_match.begin(), rim_match.end(), -1);
  if (options.rim_matching && !source.rims.empty()) {
    report.matched_rims =
        static_cast<int>(std::count_if(rim_match.begin(), rim_match.end(), [](int t) { return t >= 0; }));
    if (options.rim_warp_points > 0) {
      Eigen::MatrixX3d centres = pairs->source, targets = pairs->target;
      const double pinned_within = 0.02 * source.diagonal;
      for (std::size_t r = 0; r < source.rims.size(); ++r) {
        const Rim& rim = source.rims[r];
        if (rim_match[r] < 0 || rimNearPoints(rim, source.mesh.positions, pairs->source, pinned_within)) continue;
        // No denser than the rim's own vertices (a small hole's pairs would crowd the TPS).
        const int count = std::min(options.rim_warp_points, static_cast<int>(rim.vertices.size()));
        const RimPairs rim_pairs =
            pairRimPoints(rim, source.mesh.positions, rims_warped,
                          target_rims[static_cast<std::size_t>(rim_match[r])], matched->positions, count);
        const Eigen::Index n = centres.rows(), m = rim_pairs.source.rows();
        centres.conservativeResize(n + m, 3);
        targets.conservativeResize(n + m, 3);
        centres.bottomRows(m) = rim_pairs.source;
        targets.bottomRows(m) = rim_pairs.target;
        ++report.rims_in_warp;
      }
      if (report.rims_in_warp > 0) {
        TpsOptions rim_tps = tps_options;
        rim_tps.leave_one_out = false;
        auto rim_warp = fitTps(centres, targets, rim_tps);
        if (rim_warp) {
          result.landmark_warp = std::move(*rim_warp);
        } else {
          report.rims_in_warp = 0;
          report.warnings.push_back(target_label + ": the landmark warp with the matched rims' points failed (" +
                                    rim_warp.error().message + "): the landmarks alone warp the source");
        }
      }
    }
  }
  // The whole source is warped once: by the dense map at the end of the
  // refinement (its centres' normals start from the landmark warp's
  // Jacobian, as the sampled ones above), or without a refinement here.
  const bool refine = source.dense_factorization && options.refine_iterations > 0;
  Eigen::MatrixX3d warped_normals;
  if (!refine) {
    result.warped_positions = result.landmark_warp.apply(source.mesh.positions);
    warped_normals = computeVertexNormals(result.warped_positions, tris);
  }
  // Targets of the dense map's landmark centres: the job's target landmarks;
  // for source landmarks the target does not use, the warp's image, then
  // where the refinement puts them.
  Eigen::MatrixX3d landmark_targets = result.landmark_warp.apply(source.landmark_positions);
  std::vector<char> landmark_used(static_cast<std::size_t>(landmark_targets.rows()), 0);
  for (std::size_t i = 0; i < pairs->names.size(); ++i) {
    const int l = source.landmarks.indexOf(pairs->names[i]);
    landmark_targets.row(l) = pairs->target.row(static_cast<Eigen::Index>(i));
    landmark_used[static_cast<std::size_t>(l)] = 1;
  }
  if (refine) {
    // Non-rigid ICP on the dense centres only: project the free ones (the
    // farthest-point samples, and the source landmarks the target does not
    // use), fit the dense map to the trusted projections, move the free
    // centres (and their normals, by the map's Jacobian) and repeat. The full
    // surface is warped once at the end. The job's landmarks stay pinned.
    const Eigen::Index nl = source.landmark_positions.rows();
    const double trust = options.refine_max_distance * report.target_diagonal;
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
    const std::vector<std::uint64_t> free_masks = selectMasks(source_masks, vertices);
    Eigen::MatrixX3d free_positions = result.landmark_warp.apply(free_sources);
    Eigen::MatrixX3d free_normals = normalsThroughWarp(result.landmark_warp, free_sources, free_source_normals);
    const Eigen::Matrix3d rim_frame = result.landmark_warp.affine().topRows<3>();
    Eigen::MatrixX3d centre_targets(source.dense_centres.rows(), 3);
    TpsWarp dense;
    for (int it = 0; it < options.refine_iterations; ++it) {
      GuideModel projected = projectToTarget(free_positions, free_normals, target_index, report.target_diagonal,
                                             projection, free_masks);
      projectRimCentres(projected, free_positions, vertices, source, rim_frame, rim_match, target_rims, *matched);
      centre_targets.topRows(nl) = landmark_targets;
      std::vector<int> sliding;  // free centres
      for (std::size_t k = 0; k < rows.size(); ++k) {
        const auto i = static_cast<Eigen::Index>(k);
        const bool trusted = projected.on_target[k].found() && projected.distance(i) <= trust;
        centre_targets.row(rows[k]) = trusted ? projected.positions.row(i) : free_positions.row(i);
        if (trusted && !onMatchedRim(source, vertices[k], rim_match)) sliding.push_back(static_cast<int>(k));
      }
      if (options.slide_centres && source.dense_bending.size() > 0) {
        SlideResult slide = slideOnTarget(source.dense_bending, centre_targets, rows, sliding, projected,
                                          free_normals, free_masks, *matched, target_index, report.target_diagonal,
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
    for (std::size_t k = 0; k < rows.size() && rows[k] < nl; ++k) landmark_targets.row(rows[k]) = centre_targets.row(rows[k]);
    result.warped_positions = dense.apply(source.mesh.positions);
    warped_normals = computeVertexNormals(result.warped_positions, tris);
  }
  // Local rounds: only the sampled vertices are projected to compute each
  // step (the smoothing spreads their displacements over the rest); the last
  // projection, the guide, covers every vertex. Target vertices pull too
  // (WarpOptions::target_pulls), matched once to the surface as the dense
  // map left it.
  const double trust = options.refine_max_distance * report.target_diagonal;
  TargetPulls target_pulls;
  if (options.local_rounds > 0 && options.target_pulls) {
    target_pulls = matchTargetPulls(source, result.warped_positions, *matched, result.target_adjacency,
                                    source_face_labels, target_masks, detached, report, options);
    report.target_pulls = static_cast<int>(target_pulls.vertices.size());
  }
  for (int round = 0; round < options.local_rounds; ++round) {
    const std::vector<int>& rows = source.projection_sample;
    const GuideModel sampled =
        projectToTarget(selectRows(result.warped_positions, rows), selectRows(warped_normals, rows), target_index,
                        report.target_diagonal, projection, selectMasks(source_masks, rows));
    std::vector<Pull> pulls(static_cast<std::size_t>(result.warped_positions.rows()), Pull{0.0, 0.0, 0.0, 0.0});
    addProjectionPulls(pulls, result.warped_positions, rows, sampled, trust);
    addTargetPulls(pulls, result.warped_positions, tris, target_pulls, matched->positions);
    result.warped_positions += smoothedPulls(source, std::move(pulls), options.smoothing_passes);
    warped_normals = computeVertexNormals(result.warped_positions, tris);
  }
  // The guide: the source projected onto the target. A transfer reads it
  // only at the projection sample (the smoothed guide below) and at the dense
  // centres' vertices (the dense map), so unless the job returns the guide
  // (WarpOptions::full_guide) or locates the target on it, only those are
  // projected: ~30% of the vertices.
  const bool on_smoothed_guide = options.smooth_guide && options.local_rounds > 0;
  std::vector<int> guide_rows(static_cast<std::size_t>(result.warped_positions.rows()));
  std::iota(guide_rows.begin(), guide_rows.end(), 0);
  if (options.full_guide || !on_smoothed_guide) {
    result.guide = projectToTarget(result.warped_positions, warped_normals, target_index, report.target_diagonal,
                                   projection, source_masks);
  } else {
    std::vector<char> read(guide_rows.size(), 0);
    for (const int v : source.projection_sample) read[static_cast<std::size_t>(v)] = 1;
    for (const int v : source.dense_vertices) read[static_cast<std::size_t>(v)] = 1;
    std::erase_if(guide_rows, [&](int v) { return read[static_cast<std::size_t>(v)] == 0; });
    result.guide = projectRowsToTarget(result.warped_positions, warped_normals, guide_rows, target_index,
                                       report.target_diagonal, projection, source_masks);
  }
  report.projected_source_vertices = static_cast<int>(guide_rows.size());
  if (source.dense_factorization) {
    const Eigen::Index nl = source.landmark_positions.rows();
    Eigen::MatrixX3d centre_targets(source.dense_centres.rows(), 3);
    centre_targets.topRows(nl) = landmark_targets;
    for (std::size_t k = 0; k < source.dense_vertices.size(); ++k) {
      centre_targets.row(nl + static_cast<Eigen::Index>(k)) = result.guide.positions.row(source.dense_vertices[k]);
    }
    result.dense_map = source.dense_factorization->fit(centre_targets);
  }
  // The target is located on the smoothed guide (WarpOptions::smooth_guide):
  // one more local round's smoothed displacement of the projection sample,
  // without target pulls; or on the guide itself.
  Eigen::MatrixX3d located_on = result.guide.positions;
  if (on_smoothed_guide) {
    const std::vector<int>& rows = source.projection_sample;
    std::vector<Pull> pulls(static_cast<std::size_t>(result.warped_positions.rows()), Pull{0.0, 0.0, 0.0, 0.0});
    addProjectionPulls(pulls, result.warped_positions, rows, selectGuideRows(result.guide, rows), trust);
    located_on = result.warped_positions + smoothedPulls(source, std::move(pulls), options.smoothing_passes);
  }
  LocateOptions locate = options.locate;
  locate.threads = options.threads;
  result.locations = locateOnGuide(*matched, located_on, *source.guide_index, locate, source_face_labels, target_masks,
                                   sides_filter ? result.target_sides : std::vector<int>());
  if (options.rim_location && !target_rims.empty()) {
    report.rim_located_vertices = locateRimVertices(
        result.locations, *matched, target_rims, target_representative, source, located_on, source_face_labels,
        target_masks, report.target_diagonal, options);
  }
  for (Eigen::Index v = 0; v < target.vertexCount() && !detached.empty(); ++v) {
    if (detached[static_cast<std::size_t>(v)] < 0) continue;
    if (result.locations.confidence(v) > 0.0) ++result.locations.low_confidence;
    result.locations.confidence(v) = 0.0;
    result.locations.mismatched(v) = 1;
  }
  result.locations.detached_piece = detached;
  report.correspond_ms = msSince(t0);

  std::vector<double> d;
  d.reserve(guide_rows.size());
  for (const int v : guide_rows) d.push_back(result.guide.distance(v));
  report.mean_distance = d.empty() ? 0.0 : std::accumulate(d.begin(), d.end(), 0.0) / static_cast<double>(d.size());
  report.max_distance = d.empty() ? 0.0 : *std::max_element(d.begin(), d.end());
  report.p95_distance = percentile(d, 0.95);
  // Folds of the surface the target was located on.
  const FoldReport folds = countFolds(result.warped_positions, located_on, tris);
  report.flipped_triangles = folds.flipped;
  report.collapsed_triangles = folds.collapsed;
  report.unmatched_source_vertices = result.guide.unmatched;
  report.low_confidence_vertices = result.locations.low_confidence;
  report.total_ms = msSince(t_start);
  return result;
}

}  // namespace core
