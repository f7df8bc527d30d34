// The warp's first stages (core/correspond/warp_stages.h): the target set up
// once for every match, the landmark warp, the target oriented as the source,
// and its openings (rims and the lips' and lids' sides) matched.
#include <algorithm>
#include <cmath>
#include <cstdio>

#include <Eigen/Geometry>

#include "core/base/timing.h"
#include "core/correspond/warp_stages.h"
#include "core/geometry/similarity.h"

namespace core {

namespace {

// Beyond this landmark misfit (WarpReport::landmark_misfit_deg) the
// landmarks are taken for another mesh's: faces measured 2.4-11 degrees (ICT
// identities, exaggerated 3x, the cartoon), landmarks of another vertex
// order 68-84.
constexpr double kLandmarkMisfitDeg = 30.0;

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
                                 const ClosestPointIndex& index, int& detached_pieces, int& detached_vertices) {
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
  detached_pieces = static_cast<int>(std::count(skin.begin(), skin.end(), 0));
  if (detached_pieces == 0) return {};
  std::vector<int> number(static_cast<std::size_t>(pieces.count), -1);
  for (int piece = 0, next = 0; piece < pieces.count; ++piece) {
    if (!skin[static_cast<std::size_t>(piece)]) number[static_cast<std::size_t>(piece)] = next++;
  }
  std::vector<int> detached(static_cast<std::size_t>(target.vertexCount()), -1);
  for (Eigen::Index v = 0; v < target.vertexCount(); ++v) {
    const int piece = pieces.vertex_piece[static_cast<std::size_t>(v)];
    if (piece >= 0 && !skin[static_cast<std::size_t>(piece)]) {
      detached[static_cast<std::size_t>(v)] = number[static_cast<std::size_t>(piece)];
      ++detached_vertices;
    }
  }
  return detached;
}

// The faces the source is matched to: those of detached pieces made
// degenerate, which the index skips (face numbers stay those of the target).
Eigen::MatrixX3i skinTriangles(Eigen::MatrixX3i triangles, const std::vector<int>& detached) {
  for (Eigen::Index f = 0; f < triangles.rows() && !detached.empty(); ++f) {
    if (detached[static_cast<std::size_t>(triangles(f, 0))] >= 0) triangles.row(f).setConstant(triangles(f, 0));
  }
  return triangles;
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

Eigen::MatrixX3d selectRows(const Eigen::MatrixX3d& m, const std::vector<int>& rows) {
  Eigen::MatrixX3d out(static_cast<Eigen::Index>(rows.size()), 3);
  for (std::size_t k = 0; k < rows.size(); ++k) out.row(static_cast<Eigen::Index>(k)) = m.row(rows[k]);
  return out;
}

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

std::vector<std::uint64_t> selectMasks(const std::vector<std::uint64_t>& masks, const std::vector<int>& rows) {
  std::vector<std::uint64_t> out;
  if (masks.empty()) return out;
  out.reserve(rows.size());
  for (const int r : rows) out.push_back(masks[static_cast<std::size_t>(r)]);
  return out;
}

Result<PreparedTarget> prepareTarget(Mesh mesh, LandmarkSet landmarks, const std::string& label) {
  const auto t0 = Clock::now();
  if (auto ok = validateSurfaceMesh(mesh, label); !ok) return ok.error();
  ClosestPointIndex index(mesh.positions, mesh.triangles);
  auto landmark_positions = resolveLandmarks(landmarks, mesh, label, &index);
  if (!landmark_positions) return landmark_positions.error();
  PreparedTarget target;
  target.mesh = std::move(mesh);
  target.label = label;
  target.landmarks = std::move(landmarks);
  target.landmark_positions = std::move(*landmark_positions);
  target.index = std::move(index);
  const Mesh& m = target.mesh;
  target.normals = m.normals.rows() == m.vertexCount() ? m.normals : computeSeamlessVertexNormals(m.positions, m.triangles);
  target.representative = coincidentVertexRepresentatives(m.positions);
  target.adjacency = vertexAdjacency(m.triangles, m.vertexCount());
  target.detached = detachedPieces(m, target.representative, target.landmarks, target.landmark_positions, target.index,
                                   target.detached_pieces, target.detached_vertices);
  if (!target.detached.empty()) target.index = ClosestPointIndex(m.positions, skinTriangles(m.triangles, target.detached));
  target.diagonal = boundingBoxDiagonal(m.positions);
  target.prepare_ms = msSince(t0);
  return target;
}

Result<WarpTarget> setUpTarget(const PreparedSource& source, PreparedTarget prepared, const WarpOptions& options,
                               WarpReport& report) {
  WarpTarget target;
  static_cast<PreparedTarget&>(target) = std::move(prepared);
  const std::string& target_label = target.label;
  const bool source_regions = !source.face_regions.empty(), target_regions = target.mesh.regions.size() > 0;
  report.region_matching = options.region_matching && source_regions && target_regions;
  // Labelled rigs onto unlabelled scans are the usual case; labels painted on
  // a target for nothing are worth a word.
  if (options.region_matching && target_regions && !source_regions) {
    report.warnings.push_back(target_label + " carries _" + std::string(kRegionAttribute) +
                              " labels but the source does not: matching is not region-constrained");
  }
  if (report.region_matching) {
    if (auto ok = checkRegionLabels(source.mesh.regions, target.mesh.regions, target_label, report.warnings); !ok) {
      return ok.error();
    }
    // Label sets per target face (corner order does not matter: also those
    // of the turned copy of orientTarget).
    target.face_regions = faceRegionSets(target.mesh.regions, target.mesh.triangles);
    target.index.setFaceLabels(target.face_regions);
  }
  report.detached_pieces = target.detached_pieces;
  report.detached_vertices = target.detached_vertices;
  if (!target.detached.empty()) {
    report.warnings.push_back(target_label + ": " + std::to_string(report.detached_pieces) + " closed piece" +
                              (report.detached_pieces == 1 ? "" : "s") + " with no landmark on " +
                              (report.detached_pieces == 1 ? "it" : "them") + " (" +
                              std::to_string(report.detached_vertices) +
                              " vertices: eyes, teeth?) not matched as skin; a transfer moves each rigidly with "
                              "the joint that dominates the skin weights where it sits, without shape deltas");
  }
  return target;
}

Result<LandmarkFit> fitLandmarkWarp(const PreparedSource& source, const LandmarkSet& target_landmarks,
                                    const WarpTarget& target, const std::string& target_label,
                                    const WarpOptions& options, WarpReport& report) {
  auto pairs = pairLandmarks(source.landmarks, source.landmark_positions, target_landmarks,
                             target.landmark_positions, target_label);
  if (!pairs) return pairs.error();
  LandmarkFit fit;
  fit.pairs = std::move(*pairs);
  TpsOptions& tps_options = fit.tps_options;
  tps_options = options.landmark_tps;
  tps_options.leave_one_out = true;
  auto factorization = TpsFactorization::create(fit.pairs.source, tps_options, fit.pairs.names);
  if (!factorization) return Error{factorization.error().code, target_label + ": " + factorization.error().message};
  // Target landmarks must span 3D as well, or the warp flattens the face.
  if (auto ok = checkTpsCentres(fit.pairs.target, tps_options, fit.pairs.names); !ok) {
    return Error{ok.error().code, target_label + ": " + ok.error().message};
  }
  fit.warp = factorization->fit(fit.pairs.target);
  const TpsLeaveOneOut loo = factorization->leaveOneOut(fit.pairs.target);
  const Eigen::MatrixX3d fitted = fit.warp.apply(fit.pairs.source);
  report.landmark_count = static_cast<int>(fit.pairs.names.size());
  double sum_sq = 0.0;
  for (std::size_t i = 0; i < fit.pairs.names.size(); ++i) {
    const double r = (fitted.row(static_cast<Eigen::Index>(i)) - fit.pairs.target.row(static_cast<Eigen::Index>(i))).norm();
    sum_sq += r * r;
    report.landmark_max_residual = std::max(report.landmark_max_residual, r);
    report.landmark_residuals.push_back({fit.pairs.names[i], r, i < loo.residuals.size() ? loo.residuals[i] : 0.0});
  }
  report.landmark_rms_residual = std::sqrt(sum_sq / static_cast<double>(fit.pairs.names.size()));
  for (int i : loo.suspicious) report.suspicious_landmarks.push_back(fit.pairs.names[static_cast<std::size_t>(i)]);
  report.bending_energy = fit.warp.bendingEnergy();
  report.landmark_misfit_deg = landmarkMisfitDeg(fit.pairs.source, fit.pairs.target);
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
  if (fit.warp.affine().topRows<3>().determinant() < 0.0) {
    report.warnings.push_back("the landmark warp mirrors the source onto " + target_label +
                              ": check that its left/right landmark names are not swapped (fine only if the "
                              "target is a mirror-image character)");
  }
  return fit;
}

void orientTarget(const PreparedSource& source, const TpsWarp& landmark_warp, const Mesh& target,
                  const std::string& target_label, WarpTarget& prepared, WarpReport& report) {
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
        landmark_warp.apply(sampled),
        normalsThroughWarp(landmark_warp, sampled, selectRows(source.mesh.normals, rows)), prepared.index, target);
  }
  const std::string facing_against =
      std::to_string(std::lround(50.0 * (1.0 - report.orientation_agreement))) + "% of sampled matches face against it";
  std::optional<Mesh>& adjusted = prepared.adjusted;
  if (report.orientation_agreement < 0.0 && !report.landmarks_misfit) {
    adjusted = target;
    adjusted->triangles.col(1).swap(adjusted->triangles.col(2));
    adjusted->normals = -adjusted->normals;
    prepared.index = ClosestPointIndex(adjusted->positions, skinTriangles(adjusted->triangles, prepared.detached),
                                       prepared.face_regions);
    report.target_turned = true;
    report.warnings.push_back(target_label + ": its faces face the opposite way to the source (" +
                              facing_against + "): matched with its faces turned; the output keeps its own winding");
  }
  if (std::abs(report.orientation_agreement) < 0.5 && !report.landmarks_misfit) {
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
  const Mesh& matched = prepared.matched();
  if (matched.normals.rows() == matched.vertexCount()) {
    WindingNormals checked = normalsAgreeingWithWinding(matched.normals, matched.positions, matched.triangles);
    report.target_normals_against_winding = checked.replaced;
    if (checked.replaced > 0) {
      if (!adjusted) adjusted = target;
      adjusted->normals = std::move(checked.normals);
      report.warnings.push_back(target_label + ": " + against(checked.replaced, target.vertexCount()) +
                                ": matched by their face normals there; the output keeps its normals as they are");
    }
  } else {
    // A file without normals: the prepared ones for every match that follows
    // (target pulls and location); a turned copy's from its own winding.
    if (adjusted) {
      adjusted->normals = computeSeamlessVertexNormals(adjusted->positions, adjusted->triangles);
    } else {
      adjusted = target;
      adjusted->normals = prepared.normals;
    }
  }
  report.source_normals_against_winding = source.normals_against_winding;
  if (source.normals_against_winding > 0) {
    report.warnings.push_back(source.label + ": " + against(source.normals_against_winding, source.mesh.vertexCount()) +
                              ": matched by their face normals there");
  }
}

OpeningMatch matchOpenings(const PreparedSource& source, const TpsWarp& landmark_warp, const Mesh& target,
                           WarpTarget& prepared, const WarpOptions& options, WarpReport& report) {
  // Rims matched as warped by the landmarks. Those no landmark pins (a neck
  // cut) join the warp as paired points: far from the face's landmarks the
  // warp only extrapolates, and a neck shaped otherwise lands on the wrong
  // side of the target's, where projection would keep it. In the dense-map
  // rounds every matched rim's centres are put on the target's rim (the slide
  // along a tube that projection cannot see).
  // The openings' sides are found whenever rims or sides are matched, also
  // when _REGION labels or nothing filter the matches (the transfer's quality
  // check reads them); with side_matching and no labels they filter.
  const Mesh& matched = prepared.matched();
  OpeningMatch openings;
  const bool sides_wanted = (options.side_matching || options.rim_matching) && !source.openings.empty();
  if ((options.rim_matching || options.rim_location || sides_wanted) && !source.rims.empty()) {
    openings.target_rims = meshRims(matched, prepared.representative);
  }
  openings.rim_match.assign(source.rims.size(), -1);
  // The source's rim vertices as the landmarks warp them (the only rows
  // matchRims and pairRimPoints read; the others keep source positions).
  if ((options.rim_matching || sides_wanted) && !source.rims.empty()) {
    openings.rims_warped = source.mesh.positions;
    std::vector<int> rows;
    for (const Rim& rim : source.rims) rows.insert(rows.end(), rim.vertices.begin(), rim.vertices.end());
    const Eigen::MatrixX3d warped = landmark_warp.apply(selectRows(source.mesh.positions, rows));
    for (std::size_t k = 0; k < rows.size(); ++k) openings.rims_warped.row(rows[k]) = warped.row(static_cast<Eigen::Index>(k));
    openings.rim_match = matchRims(source.rims, openings.rims_warped, openings.target_rims, matched.positions, options.rims);
  }
  // Lips and lids kept to their sides (WarpOptions::side_matching): the
  // openings' sides filter every match from here on, as _REGION labels do.
  if (report.region_matching) {
    openings.source_masks = source.region_bits;
    openings.source_face_labels = source.face_regions;
  }
  openings.target_masks =
      report.region_matching ? vertexRegionBits(target.regions) : std::vector<std::uint64_t>();
  if (sides_wanted) {
    openings.target_sides = targetOpeningSides(source, landmark_warp, openings.rim_match, openings.target_rims, matched,
                                             prepared.adjacency, prepared.representative, options.sides, report);
    openings.sides_filter = options.side_matching && !report.region_matching && !openings.target_sides.empty();
    if (openings.sides_filter) {
      openings.source_masks = source.side_masks;
      openings.source_face_labels = source.side_face_sets;
      openings.target_masks = sideMasks(openings.target_sides);
      prepared.index.setFaceLabels(sideFaceSets(openings.target_sides, matched.triangles));
    }
  }
  if (!options.rim_matching) std::fill(openings.rim_match.begin(), openings.rim_match.end(), -1);
  return openings;
}

void addRimPointsToWarp(const PreparedSource& source, const OpeningMatch& openings, const Mesh& matched,
                        const std::string& target_label, const WarpOptions& options, LandmarkFit& fit,
                        WarpReport& report) {
  if (options.rim_matching && !source.rims.empty()) {
    report.matched_rims =
        static_cast<int>(std::count_if(openings.rim_match.begin(), openings.rim_match.end(), [](int t) { return t >= 0; }));
    if (options.rim_warp_points > 0) {
      Eigen::MatrixX3d centres = fit.pairs.source, targets = fit.pairs.target;
      const double pinned_within = 0.02 * source.diagonal;
      for (std::size_t r = 0; r < source.rims.size(); ++r) {
        const Rim& rim = source.rims[r];
        if (openings.rim_match[r] < 0 || rimNearPoints(rim, source.mesh.positions, fit.pairs.source, pinned_within)) continue;
        // No denser than the rim's own vertices (a small hole's pairs would crowd the TPS).
        const int count = std::min(options.rim_warp_points, static_cast<int>(rim.vertices.size()));
        const RimPairs rim_pairs =
            pairRimPoints(rim, source.mesh.positions, openings.rims_warped,
                          openings.target_rims[static_cast<std::size_t>(openings.rim_match[r])], matched.positions, count);
        const Eigen::Index n = centres.rows(), m = rim_pairs.source.rows();
        centres.conservativeResize(n + m, 3);
        targets.conservativeResize(n + m, 3);
        centres.bottomRows(m) = rim_pairs.source;
        targets.bottomRows(m) = rim_pairs.target;
        ++report.rims_in_warp;
      }
      if (report.rims_in_warp > 0) {
        TpsOptions rim_tps = fit.tps_options;
        rim_tps.leave_one_out = false;
        auto rim_warp = fitTps(centres, targets, rim_tps);
        if (rim_warp) {
          fit.warp = std::move(*rim_warp);
        } else {
          report.rims_in_warp = 0;
          report.warnings.push_back(target_label + ": the landmark warp with the matched rims' points failed (" +
                                    rim_warp.error().message + "): the landmarks alone warp the source");
        }
      }
    }
  }
}

}  // namespace core
