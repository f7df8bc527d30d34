// (internal) fitScan's stages in the order they run, each plain data in and
// out. Everything between align and rebuild works in the reference's frame
// and units: the scan is reached through the alignment (queries mapped to the
// scan, answers mapped back), so nothing of the scan is copied or re-indexed.
#pragma once

#include <array>
#include <vector>

#include <Eigen/Core>

#include "core/fit/fit.h"

namespace core {

// The alignment as the stages use it: reference frame <-> scan frame.
struct FrameMap {
  Similarity reference_to_scan;
  Eigen::Vector3d toScan(const Eigen::Vector3d& p) const { return reference_to_scan.apply(p); }
  Eigen::Vector3d toReference(const Eigen::Vector3d& p) const {
    return reference_to_scan.rotation.transpose() * (p - reference_to_scan.translation) / reference_to_scan.scale;
  }
  Eigen::Vector3d directionToReference(const Eigen::Vector3d& n) const { return reference_to_scan.rotation.transpose() * n; }
};

// The graph Laplacian of the given edges alone (#n by #n; weight 1 each).
Eigen::SparseMatrix<double> edgeLaplacian(Eigen::Index n, const std::vector<std::array<int, 2>>& edges);

// Scan correspondences of reference-frame positions, in the reference frame.
struct FrameMatches {
  std::vector<ScanMatch> matches;  // point, normal and distance in reference units and frame
};
FrameMatches matchInReferenceFrame(const ScanSurface& scan, const FrameMap& frame, const Eigen::MatrixX3d& positions);
// The same by position and normal (ScanSurface::nearestAlike; `normals` and
// `normal_weight` in the reference frame and units), except for the vertices
// `closest` marks, which take the closest point.
FrameMatches matchAlikeInReferenceFrame(const ScanSurface& scan, const FrameMap& frame, const Eigen::MatrixX3d& positions,
                                        const Eigen::MatrixX3d& normals, double normal_weight,
                                        const std::vector<char>& closest);

// Per reference rim (FitReference::rims) the scan rim it lies on at
// positions `x` (reference frame), or -1: centroids within the rim's mean
// radius, lengths within a factor 2.
std::vector<int> matchScanRims(const FitReference& reference, const ScanSurface& scan, const FrameMap& frame,
                               const Eigen::MatrixX3d& x);

// Soft landmark constraints of the non-rigid fit: reference vertex -> target (reference frame).
struct LandmarkTargets {
  std::vector<int> vertices;
  Eigen::MatrixX3d targets;
};

// The fit's start (docs/FIT.md 2.3), reference frame: the reference under
// the affine map that best lays it on the scan (trimmed ICP from the
// alignment, the landmarks as heavy pairs: a head wider, deeper or smaller
// than the reference). Where the scan has no data the fit keeps this shape.
// Not the landmarks' thin-plate spline (the plain warp's start): its affine
// part is fitted to points on the face alone and sends the scalp, ears and
// neck centimetres astray (whole-skin p95 19-24 mm against 5-12 mm).
Eigen::MatrixX3d fitPrior(const FitReference& reference, const ScanSurface& scan, const FrameMap& frame,
                          const LandmarkTargets& landmarks);

// Landmarks read off the scan itself when none were given: each matched
// rim's two ends along its longest axis (the eyes' corners, the mouth's) and
// the scan rim's ends along the same axis.
LandmarkTargets rimCorners(const FitReference& reference, const ScanSurface& scan, const FrameMap& frame,
                           const Eigen::MatrixX3d& x);

// The landmarks' misfit at `prior` spread over the face by a thin-plate
// spline through them, pinned to `prior` far from them (docs/FIT.md 2.3).
Eigen::MatrixX3d correctAtLandmarks(const FitReference& reference, const LandmarkTargets& landmarks,
                                    Eigen::MatrixX3d prior);

struct NonRigidFit {
  Eigen::MatrixX3d positions;      // #V fitted, reference frame
  std::vector<char> covered;       // #V: had an accepted scan correspondence in the last iteration
  std::vector<double> distance;    // #V: to that correspondence, reference units (-1: uncovered)
  std::vector<FitStageReport> stages;
  int matched_rims = 0;            // reference rims lying on a scan rim at the end (matchScanRims)
  int fold_repairs = 0;            // rounds of fold repair run
  int repaired_vertices = 0;       // vertices stiffened by them
};

// The schedule of FitOptions::schedule from `prior` (reference frame).
Result<NonRigidFit> fitNonRigid(const FitReference& reference, const ScanSurface& scan, const FrameMap& frame,
                                const Eigen::MatrixX3d& prior, const LandmarkTargets& landmarks,
                                const FitOptions& options);

// The gate (docs/FIT.md 2.9): distances, coverage, folds, verdict into `report`.
void gateFit(const FitReference& reference, const FrameMap& frame, const NonRigidFit& fit, const FitOptions& options,
             FitReport& report);

// The rig rebuilt by vertex index (paper 001 4.3) on `fitted` (reference
// frame); the reference's components document too, when it has one.
Result<Rig> rebuildRig(const FitReference& reference, const FrameMap& frame, const Eigen::MatrixX3d& fitted,
                       double unit_scale, const FitOptions& options, FitReport& report,
                       std::optional<ComponentsDocument>& components);

}  // namespace core
