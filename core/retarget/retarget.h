// Facial mocap retargeting: marker trajectories drive a mesh by RBF
// interpolation of the marker displacements (paper 002, chapters 4-5), with
// Euclidean, geodesic or hybrid marker-to-vertex distances, baked into a few
// morph targets plus a morph-weight animation.
//
//   computeMarkerDistances(mesh, markers)  -> MarkerDistances  (cacheable per mesh + marker set)
//   retargetMocap(mesh, distances, clip)   -> RetargetOutput   (Rig + RetargetReport)
//
// Pipeline (retargetMocap, read top to bottom in retarget.cpp):
//   calibrate  rest frame -> placed markers by a similarity (Umeyama); each
//              frame's displacement (frame - rest, mocap units) mapped into
//              mesh space by the similarity's rotation and scale and by the
//              local Jacobian of a TPS from the aligned rest markers to the
//              placed markers (a face of other proportions gets proportionate
//              motion). Units: the TRC is usually cm, the mesh metres; the
//              similarity scale absorbs the unit change (and the actor's size).
//   factorise  RbfFactorization of the marker-marker distances (once per clip)
//   solve      all frames at once: #markers by 3*#frames right-hand sides
//   bake       the #frames by 3*#V displacement field is never formed: it is
//              (weights) x (basis), so its SVD comes from small matrices and
//              only the kept modes are evaluated on the vertices (one product)
//   assemble   Rig: mesh + morph targets "mode_00".. + animation "mocap"
#pragma once

#include <map>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "core/base/error.h"
#include "core/solve/geodesic.h"
#include "core/io/landmarks.h"
#include "core/geometry/mesh.h"
#include "core/solve/rbf.h"
#include "core/rig/rig.h"
#include "core/io/trc_io.h"

namespace core {

enum class DistanceMethod {
  kEuclidean,  // straight line (paper 5.1): fast, but pulls the lips/lids across the holes together
  kGeodesic,   // along the surface (heat method, core/solve/geodesic.h) (paper 5.2)
  kHybrid,     // geodesic near the holes, Euclidean elsewhere, blended (paper 5.3, algorithms 5.3-5.4)
};

const char* distanceMethodName(DistanceMethod method);  // "euclidean", "geodesic", "hybrid"

struct HybridOptions {
  // Geodesic regions as vertex index sets (e.g. from a REGION label); empty: found around the feature holes.
  std::vector<std::vector<int>> regions;
  // Automatic regions: vertices within this times a feature hole's extent (mouth, eye width) of it (boundaryLoops).
  double region_factor = 0.5;
  // Outside the regions the geodesic weight decays as exp(-d / blend_gamma); 0 = 0.02 x mesh bbox diagonal.
  double blend_gamma = 0.0;
};

struct MarkerDistanceOptions {
  DistanceMethod method = DistanceMethod::kHybrid;  // marker-to-vertex distance
  HybridOptions hybrid;      // kHybrid: the geodesic regions and the blend
  GeodesicOptions geodesic;  // heat-method solver (geodesic and hybrid)
};

// A hole loop made a geodesic region (hybrid).
struct GeodesicRegion {
  int loop = -1;              // index into core::boundaryLoops(mesh) (longest first), -1 for a given region
  int loop_vertices = 0;      // vertices on the loop
  double extent = 0.0;        // largest distance between two loop vertices, model units
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  int region_vertices = 0;    // vertices inside the region
};

// Distances between markers placed on one mesh, and from them to every
// vertex: everything of a job that depends only on (mesh, marker set,
// method). Immutable once made: share it (e.g. std::shared_ptr<const ...>)
// between jobs and threads.
struct MarkerDistances {
  DistanceMethod method = DistanceMethod::kEuclidean;
  std::vector<std::string> marker_names;  // #M, in the marker set's order
  Eigen::MatrixX3d marker_positions;      // #M by 3 placed markers on the mesh, model units
  Eigen::MatrixXd marker_marker;          // #M by #M, symmetric, zero diagonal, model units
  Eigen::MatrixXd vertex_marker;          // #V by #M vertex-to-marker distances (+Inf: unreachable along the surface)
  Eigen::VectorXd geodesic_weight;        // #V hybrid blend weights in [0, 1] (0 rows unless hybrid)
  std::vector<GeodesicRegion> regions;    // hybrid: the geodesic regions used
  int boundary_loops = 0;                 // hole loops of the mesh (hybrid)
  double mesh_diagonal = 0.0;             // bounding-box diagonal, model units
  double compute_ms = 0.0;                // time to make this object

  std::size_t memoryBytes() const;        // for byte-bounded caches
};

// Resolves the markers on `mesh` (face/vertex landmarks; position landmarks
// are snapped to their nearest vertex for the geodesic sources) and computes
// the distances. `label` names the mesh/markers in messages.
Result<MarkerDistances> computeMarkerDistances(const Mesh& mesh, const LandmarkSet& markers, const std::string& label,
                                               const MarkerDistanceOptions& options = {});

enum class BakeError {
  kRelativeFrobenius,  // ||X - X_r||_F / ||X||_F over all frames and vertices (exact, from the spectrum)
  kMaxVertex,          // max over frames and vertices of |x - x_r|, model units, through a guaranteed upper bound
};

struct BakeOptions {
  BakeError metric = BakeError::kRelativeFrobenius;  // how the bake's error is measured
  // The smallest rank whose error (metric) is <= this.
  double tolerance = 0.05;
  int max_rank = 64;  // cap on morph targets (the tolerance may then be missed: see report.tolerance_met)
  // Exact per-frame output: one morph target per frame, one-hot LINEAR weights (short clips only).
  bool exact = false;
  int max_exact_frames = 300;  // exact: more frames than this is an Error
  // Also measure the true max vertex error over all frames (about as long as the rest of the job together).
  bool measure_max_error = false;
};

struct RetargetOptions {
  RbfKernel kernel = RbfKernel::kGaussian;          // RBF kernel
  // Kernel shape parameter (model units); 0 = kDefaultGammaFactor x the mesh's bounding-box diagonal.
  double gamma = 0.0;
  RbfPolynomial polynomial = RbfPolynomial::kAuto;  // affine is replaced by constant for geodesic/hybrid distances
  std::map<std::string, double> stiffness;          // marker name -> 1..9 (paper 002 4.3.5); absent = 1
  double stiffness_step = 0.05;                     // see RbfOptions::stiffness_step
  int rest_frame = 0;                               // 0-based frame whose marker positions are the neutral face
  // Remove rigid head motion first: each frame's markers rigidly aligned (Umeyama) to the rest frame's head_markers.
  bool remove_head_motion = true;
  // Markers the head motion is taken from; empty: the half of the markers the expression moves least in the clip.
  std::vector<std::string> head_markers;
  // Calibration TPS (aligned rest -> placed markers) regularisation, fraction of the placed markers' bbox diagonal.
  double calibration_regularization = 0.05;
  bool calibration_jacobian = true;  // false: similarity rotation + scale only
  BakeOptions bake;                  // the morph-target compression
  std::string mesh_name = "face";    // the output mesh's name
  std::string animation_name = "mocap";  // the output animation's name
};

inline constexpr double kDefaultGammaFactor = 0.1;

struct RetargetReport {
  DistanceMethod method = DistanceMethod::kEuclidean;
  RbfKernel kernel = RbfKernel::kGaussian;
  double gamma = 0.0;             // model units, as used
  int polynomial_terms = 0;
  double condition = 0.0;         // RBF system condition estimate
  int frames = 0;
  int markers = 0;
  int vertices = 0;
  double data_rate = 0.0;         // frames per second
  int rest_frame = 0;
  std::vector<std::string> unused_clip_markers;  // in the TRC but not in the marker set
  std::vector<std::string> markers_not_in_clip;  // placed but absent from the TRC: not used
  std::vector<TrcGap> filled_gaps;                // the clip's gaps and how they were filled (as read)

  // Calibration.
  double mocap_units_to_metres = 1.0;
  double similarity_scale = 0.0;          // mesh units per mocap unit
  double similarity_rms = 0.0;            // rest markers vs placed, after the similarity, model units
  double jacobian_min_singular = 0.0;     // TPS Jacobian singular values over the markers (1 = no local stretch)
  double jacobian_max_singular = 0.0;
  double max_marker_displacement = 0.0;   // calibrated, model units
  bool head_motion_removed = false;
  std::vector<std::string> head_markers;  // the markers head motion was measured on
  double head_max_rotation_deg = 0.0;     // largest rigid head rotation from the rest frame (measured either way)
  double head_max_translation = 0.0;      // largest rigid head translation, model units

  // Interpolation: the RBF at the markers vs the calibrated displacements over
  // all frames (about 0 without stiffness), model units.
  double marker_max_residual = 0.0;
  double marker_rms_residual = 0.0;

  // Bake.
  bool exact = false;
  int rank = 0;                           // morph targets
  double tolerance = 0.0;
  bool tolerance_met = true;
  double relative_error = 0.0;            // ||X - X_r||_F / ||X||_F
  double rms_error = 0.0;                 // rms over vertices and frames of |x - x_r|, model units
  double max_error = 0.0;                 // measured max when max_error_measured, else the guaranteed bound
  bool max_error_measured = false;
  double mesh_diagonal = 0.0;             // for % of diagonal
  std::vector<double> singular_values;    // leading (up to 2 x max_rank) of the displacement field

  // Hybrid.
  std::vector<GeodesicRegion> regions;
  int boundary_loops = 0;

  // Per-stage milliseconds ("distances" (0 on cached distances), "calibrate",
  // "factorise" (incl. the vertex kernel basis), "solve", "evaluate" (marker
  // residuals, vertex deltas of the kept modes), "bake" (SVD, rank, rig));
  // the caller adds e.g. "read", "write".
  std::map<std::string, double> timings_ms;
  double total_ms = 0.0;
};

struct RetargetOutput {
  Rig rig;  // mesh, morph targets, one node carrying the mesh, animation with a weights channel
  RetargetReport report;
  // #frames by 3*#markers calibrated marker displacements in mesh space (row f:
  // x0 y0 z0 x1 ...), in MarkerDistances::marker_names order: what the RBF interpolates.
  Eigen::MatrixXd marker_displacements;
};

// The job on precomputed distances (the mesh must be the one they were made on).
Result<RetargetOutput> retargetMocap(const Mesh& mesh, const MarkerDistances& distances,
                                     const MarkerTrajectories& clip, const RetargetOptions& options = {});

// One-off: computes the distances first (timed as "distances").
Result<RetargetOutput> retargetMocap(const Mesh& mesh, const LandmarkSet& markers, const MarkerTrajectories& clip,
                                     const std::string& label, const MarkerDistanceOptions& distance_options = {},
                                     const RetargetOptions& options = {});

// Diagnostics JSON (2-space indent, stable keys; see docs/DIAGNOSTICS.md):
// method, counts, calibration, interpolation, bake, regions, timings_ms.
// `extra_timings_ms` (e.g. read, write) join the timings; total_ms >= 0
// overrides report.total_ms.
std::string formatRetargetDiagnostics(const RetargetReport& report,
                                      const std::map<std::string, double>& extra_timings_ms = {},
                                      double total_ms = -1.0);

}  // namespace core
