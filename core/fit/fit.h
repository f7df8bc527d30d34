// fitScan: the reference face fitted to a head scan and its rig rebuilt on the
// fitted copy by vertex index (paper 001 ch. 5 and 4.3), read top to bottom:
// prepare (cacheable, per reference rig) -> scan -> units -> align -> prior ->
// non-rigid fit -> gate -> rebuild. docs/FIT.md has the method and its numbers.
#pragma once

#include <array>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include "core/base/stage_hook.h"
#include "core/fit/align.h"
#include "core/fit/scan.h"
#include "core/transfer/transfer.h"

namespace core {

// Everything the fit needs that depends only on the reference rig: immutable,
// shared between jobs (the service caches it per rig, as a transfer's PreparedRig).
struct FitReference {
  std::shared_ptr<const PreparedRig> rig;  // the rig and its PreparedSource (normals, landmarks, dense map centres)
  Eigen::SparseMatrix<double> laplacian;   // uniform graph Laplacian, split points welded (membrane on displacement)
  Eigen::SparseMatrix<double> rim_laplacian;      // of the eye and mouth rims' own edges (stiffer: lids stay whole)
  Eigen::SparseMatrix<double> binding_laplacian;  // of the lip pairs below
  // Pairs of vertices of opposite lips that touch at rest (non-adjacent, closer
  // than 0.002 of the diagonal): bound so both lips move together (paper 5.7a).
  std::vector<std::array<int, 2>> lip_pairs;
  // The open boundaries other than the longest (the mouth, the eyes) as
  // vertex loops: each is pulled onto the scan's own rim there when it has one.
  std::vector<std::vector<int>> rims;
  std::vector<char> expressive;            // #V: within 0.063 d (3 cm on a head) of a landmark not named jaw_*
  std::vector<char> on_skin;               // #V: on a triangle (an isolated vertex is carried, never fitted)
  std::vector<char> near_rims;             // #V: within 0.02 d (1 cm on a head) of a rim vertex
  std::vector<int> representative;         // coincidentVertexRepresentatives of the reference
  double rms_radius = 0.0;                 // about the centroid, reference units
  SearchReference search;                  // what the landmark-free alignment needs (align.h)
  double prepare_ms = 0.0;
  std::size_t memoryBytes() const;
};

Result<FitReference> prepareFitReference(std::shared_ptr<const PreparedRig> rig);

enum class FitAlignmentMode { kAuto, kLandmarks, kSearch };  // auto: landmarks when >= 4 are given, else search
enum class FitFrame { kScan, kReference };                   // the output's frame and units

// One stage of the non-rigid fit's schedule (docs/FIT.md 2.4).
struct FitStage {
  double stiffness = 1.0;         // membrane weight on the displacement from the prior
  int iterations = 4;             // at most (a stage stops when the largest step is under 0.0002 d)
  double max_distance = 0.006;    // correspondences farther are rejected, fraction of the reference diagonal
  double max_normal_angle_deg = 45.0;  // correspondences whose normals differ more are rejected
  double landmark_weight = 1.0;   // per landmark
  // Share of the data term that pulls to the scan point itself (the rest to
  // its tangent plane): stiff stages drag whole regions, along the surface
  // too; the last ones let the surface slide (point-to-plane).
  double point_share = 0.1;
};
std::vector<FitStage> defaultFitSchedule();

struct FitOptions {
  FitAlignmentMode alignment = FitAlignmentMode::kAuto;
  std::string units = "auto";          // the scan's units: auto (by size), mm, cm, m, in
  SearchOptions search;                // the landmark-free alignment
  std::vector<FitStage> schedule = defaultFitSchedule();
  double binding_weight = 10.0;        // lip pairs kept together
  double rim_stiffness = 10.0;         // membrane weight multiplier on the eye and mouth rims' own edges
  double rim_weight = 1.0;             // pull of the reference's rims onto the scan's matching rims (mesh scans)
  // Stiff stages (point share 1) match each vertex to the scan point nearest
  // in position and normal, the normals' difference weighed as this fraction
  // of the diagonal (0: the closest point): features draw their like.
  double normal_matching = 0.03;
  bool reject_borders = true;          // correspondences on the scan's borders and holes are rejected
  bool reject_spikes = true;           // ... and on its spikes
  int fold_repair_rounds = 2;          // triangles flipped after the schedule: their neighbourhood stiffened, refitted
  FitFrame frame = FitFrame::kScan;
  TransferOptions rebuild;             // components, adaptation, max influences (its warp options are unused)
  bool diagnostic_attributes = false;  // add _FIT_DISTANCE and _FIT_COVERAGE to the output
  bool strict = false;                 // a warn verdict fails the fit
  StageHook on_stage;                  // "scan", "align", "fit", "gate", "rebuild"
};

struct DistanceStats {
  double median = 0.0, p95 = 0.0, max = 0.0;
};

struct FitStageReport {
  double stiffness = 0.0;
  int iterations = 0;
  int accepted = 0;                     // correspondences used in the last iteration
  int rim_matches = 0;                  // reference rim vertices pulled onto a scan rim
  int rejected_distance = 0, rejected_normal = 0, rejected_border = 0, rejected_spike = 0;
  double energy_data = 0.0, energy_smooth = 0.0, energy_landmarks = 0.0;
  double max_step = 0.0;                // reference units
};

struct FitLandmarkResidual {
  std::string name;
  double aligned = 0.0;  // after the similarity alone, scan units
  double fitted = 0.0;   // after the fit
};

struct FoundLandmark {
  std::string name;
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  // on the scan (its closest point), its frame and units
};

struct FitReport {
  ScanReport scan;
  AlignmentReport alignment;
  std::vector<FitLandmarkResidual> landmarks;
  // Without scan landmarks: where the reference's landmarks were found on the
  // scan (by a first, stiff pass of the fit).
  std::vector<FoundLandmark> found_landmarks;
  std::vector<FitStageReport> stages;
  DistanceStats face_distance;    // fitted expressive-face vertex to the scan, covered vertices, scan units
  DistanceStats skin_distance;    // the same over all covered vertices
  double face_coverage = 0.0;     // fraction of expressive-face vertices with a scan correspondence
  double skin_coverage = 0.0;
  int uncovered_vertices = 0;
  int flipped_triangles = 0;      // against the reference (turned by the alignment)
  int collapsed_triangles = 0;
  double unit_scale = 1.0;        // scan units per reference unit (the units' ratio, not the face's size)
  std::string verdict = "ok";     // ok | warn | fail
  std::vector<std::string> reasons;   // why not ok
  std::vector<std::string> warnings;
  int shapes = 0, joints = 0, animations = 0;
  std::vector<CarriedPart> parts;  // the rig's other meshes, as rebuilt (core/transfer/parts.h)
  // milliseconds
  double scan_ms = 0.0, align_ms = 0.0, fit_ms = 0.0, gate_ms = 0.0, rebuild_ms = 0.0, total_ms = 0.0;
};

struct FitResult {
  Rig rig;             // the reference rig rebuilt on the fitted mesh (reference topology and vertex order)
  std::optional<ComponentsDocument> components;  // the reference's document rebuilt, when it has one
  FitReport report;
};

// The fitted surface alone (no rebuild): the reference's vertices on the scan,
// in its frame and units, with the report up to the gate's verdict. The fit
// as a correspondence: a transfer located on it (`"correspondence": "fit"`,
// core/jobs/transfer_job.h).
struct FittedSurface {
  Eigen::MatrixX3d positions;  // #V reference vertices fitted, scan frame and units
  FitReport report;            // rebuild counts and rebuild_ms stay 0
};

Result<FittedSurface> fitSurface(const FitReference& reference, const Mesh& scan, const LandmarkSet& scan_landmarks,
                                 const std::string& scan_label, const FitOptions& options = {});

// `scan_landmarks` may be empty (then the alignment searches). Errors are for
// input that cannot be fitted at all (no points, NaN, unknown landmark names);
// a fit that ran but fails its gate comes back with verdict "fail" and its
// reasons, and the job body (core/jobs/fit_job.h) refuses to write it.
Result<FitResult> fitScan(const FitReference& reference, const Mesh& scan, const LandmarkSet& scan_landmarks,
                          const std::string& scan_label, const FitOptions& options = {});

}  // namespace core
