// (internal to core/correspond) The stages of runWarp (warp_job.cpp), each a
// function of plain data in and out, in the order it runs them:
//
//   target_setup.cpp
//     setUpTarget         region matching on the prepared target (prepareTarget: index, landmarks, split copies, detached pieces)
//     fitLandmarkWarp     TPS on the shared landmark names: residuals, leave-one-out, misfit and mirror warnings
//     orientTarget        the target as matched: turned when it faces away, normals that agree with its winding
//     matchOpenings       rims matched, the openings' sides, the filters every later match uses
//     addRimPointsToWarp  rims no landmark pins join the landmark warp as paired points
//   dense_refinement.cpp
//     warpSurface         the dense map refined on its centres (non-rigid ICP); the whole source warped once
//     runLocalRounds      projection and target pulls, smoothed over the source, round after round
//     projectGuide        the guide: the warped source projected onto the target
//     fitDenseMap         the dense map from the source's centres to the guide
//     locateTarget        target vertices located on the (smoothed) guide; rims; detached pieces
//     summariseGuide      the guide's distances and the folds, for the report
//
// What the stages share of the target lives in WarpTarget, prepared once.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "core/correspond/warp_job.h"
#include "core/geometry/closest_point.h"

namespace core {

// The target as the stages match to it: the prepared target, with its index's
// label sets (regions, sides) and, when it faces away or its normals disagree
// with its winding, the adjusted copy matched instead of the file's mesh.
struct WarpTarget : PreparedTarget {
  std::vector<std::uint64_t> face_regions;  // label sets per face (region matching), else empty
  std::optional<Mesh> adjusted;             // the target as matched, when that differs from the file
  const Mesh& matched() const { return adjusted ? *adjusted : mesh; }
};

struct LandmarkFit {
  LandmarkPairs pairs;      // source and target landmarks by shared name
  TpsOptions tps_options;   // the landmark TPS's, for the rims' points too
  TpsWarp warp;             // landmarks (and, after addRimPointsToWarp, rim points) -> target
};

// Rims, the openings' sides and the match filters they give.
struct OpeningMatch {
  std::vector<Rim> target_rims;
  std::vector<int> rim_match;         // per source rim: its target rim, or -1 (all -1 without rim matching)
  Eigen::MatrixX3d rims_warped;       // source rim vertices as the landmarks warp them (other rows: source)
  std::vector<int> target_sides;      // WarpResult::target_sides
  bool sides_filter = false;          // the sides filter the matches (side_matching, no _REGION labels)
  // Per source vertex / source face / target vertex: label bits every match
  // must share (_REGION labels or sides); empty: no constraint.
  std::vector<std::uint64_t> source_masks, source_face_labels, target_masks;
};

// The whole source warped onto the target, and its normals.
struct SurfaceWarp {
  Eigen::MatrixX3d positions, normals;
  Eigen::MatrixX3d landmark_targets;  // where the dense map's landmark centres go
};

struct ProjectedGuide {
  GuideModel guide;
  std::vector<int> rows;  // source vertices projected (all, or what a transfer reads)
};

struct LocatedTarget {
  TargetLocations locations;
  Eigen::MatrixX3d located_on;  // the surface located on (the smoothed guide, or the guide)
};

// Carried by the warp's Jacobian (J^-T n), unit length.
Eigen::MatrixX3d normalsThroughWarp(const TpsWarp& warp, const Eigen::MatrixX3d& points, const Eigen::MatrixX3d& normals);
Eigen::MatrixX3d selectRows(const Eigen::MatrixX3d& m, const std::vector<int>& rows);
// The entries `rows` of per-vertex masks (empty stays empty: no constraint).
std::vector<std::uint64_t> selectMasks(const std::vector<std::uint64_t>& masks, const std::vector<int>& rows);

Result<WarpTarget> setUpTarget(const PreparedSource& source, PreparedTarget target, const WarpOptions& options,
                               WarpReport& report);
Result<LandmarkFit> fitLandmarkWarp(const PreparedSource& source, const LandmarkSet& target_landmarks,
                                    const WarpTarget& target, const std::string& target_label,
                                    const WarpOptions& options, WarpReport& report);
void orientTarget(const PreparedSource& source, const TpsWarp& landmark_warp, const Mesh& target,
                  const std::string& target_label, WarpTarget& prepared, WarpReport& report);
OpeningMatch matchOpenings(const PreparedSource& source, const TpsWarp& landmark_warp, const Mesh& target,
                           WarpTarget& prepared, const WarpOptions& options, WarpReport& report);
void addRimPointsToWarp(const PreparedSource& source, const OpeningMatch& openings, const Mesh& matched,
                        const std::string& target_label, const WarpOptions& options, LandmarkFit& fit,
                        WarpReport& report);

SurfaceWarp warpSurface(const PreparedSource& source, const LandmarkFit& fit, const OpeningMatch& openings,
                        const WarpTarget& prepared, const Mesh& matched, const ProjectionOptions& projection,
                        const WarpOptions& options, WarpReport& report);
void runLocalRounds(const PreparedSource& source, const OpeningMatch& openings, const WarpTarget& prepared,
                    const Mesh& matched, const ProjectionOptions& projection, const WarpOptions& options,
                    SurfaceWarp& surface, WarpReport& report);
ProjectedGuide projectGuide(const PreparedSource& source, const SurfaceWarp& surface, const OpeningMatch& openings,
                            const WarpTarget& prepared, const ProjectionOptions& projection, const WarpOptions& options,
                            WarpReport& report);
std::optional<TpsWarp> fitDenseMap(const PreparedSource& source, const SurfaceWarp& surface, const GuideModel& guide);
LocatedTarget locateTarget(const PreparedSource& source, const Mesh& target, const SurfaceWarp& surface,
                           const GuideModel& guide, const OpeningMatch& openings, const WarpTarget& prepared,
                           const WarpOptions& options, WarpReport& report);
void summariseGuide(const PreparedSource& source, const ProjectedGuide& projected, const SurfaceWarp& surface,
                    const LocatedTarget& located, WarpReport& report);

}  // namespace core
