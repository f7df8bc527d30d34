// The warp job, read top to bottom: prepare (once per source, cacheable) ->
// landmark TPS warp -> optional non-rigid refinement through the dense map
// and local rounds -> project onto the target (guide model) -> locate target
// vertices on the (smoothed) guide. Each stage is a function of plain data;
// the report carries what a TD needs to trust (or not) the correspondence.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "core/correspond/correspondence.h"
#include "core/io/landmarks.h"
#include "core/geometry/mesh.h"
#include "core/geometry/moving_mesh_index.h"
#include "core/correspond/opening_sides.h"
#include "core/correspond/rims.h"
#include "core/geometry/closest_point.h"
#include "core/solve/tps.h"

namespace core {

struct PrepareOptions {
  // Dense-map centres: the source landmarks plus this many farthest-point samples of the source vertices.
  int dense_centres = 400;
  // Dense-map regularisation, a fraction of the source bbox diagonal (smooths projection noise; 0 interpolates).
  double dense_regularization = 0.002;
};

// Everything that depends only on the source: immutable, shared between jobs.
struct PreparedSource {
  Mesh mesh;                           // source surface (normals filled in)
  std::string label;                   // file or rig name, for messages
  LandmarkSet landmarks;
  Eigen::MatrixX3d landmark_positions; // #L by 3 on the source mesh
  std::vector<int> landmark_vertices;  // #L: landmarkVertices (for each landmark's normal, region, rim)
  double diagonal = 0.0;               // source bbox diagonal
  std::vector<int> dense_vertices;     // source vertices used as dense-map centres (after the landmarks)
  Eigen::MatrixX3d dense_centres;      // #L + #dense_vertices by 3: landmark positions, then samples
  std::optional<TpsFactorization> dense_factorization;
  // Its bendingEnergyMatrix (#centres squared), for sliding the centres.
  Eigen::MatrixXd dense_bending;
  // The source faces grouped for closest-point queries at any positions:
  // fitted to each job's warped source (for the target pulls) and (smoothed)
  // guide (to locate the target's vertices on it).
  std::optional<MovingMeshIndex> guide_index;
  VertexAdjacency adjacency;  // of the source's vertices
  // Source vertices projected in the local rounds (a maximal independent set
  // of the adjacency, ~1/4 of the vertices): the rounds' smoothed steps need
  // only this density, and the guide itself is projected in full.
  std::vector<int> projection_sample;
  // Region-constrained matching (empty when the source has no region
  // labels): faceRegionSets and vertexRegionBits of the source.
  std::vector<std::uint64_t> face_regions;
  std::vector<std::uint64_t> region_bits;
  // Open boundaries of the source (meshRims) and its vertices on them
  // (rimVertices; empty without rims).
  std::vector<Rim> rims;
  RimVertices rim_vertices;
  // Openings (the mouth, the eyes: rims a source landmark lies on, split at
  // their corners), each vertex's side of them (openingSides), and those as
  // closest-point label bits (sideMasks, sideFaceSets); empty without openings.
  std::vector<Opening> openings;
  std::vector<int> vertex_sides;
  std::vector<std::uint64_t> side_masks;
  std::vector<std::uint64_t> side_face_sets;
  // Source vertex normals that pointed against the faces' winding and were
  // replaced by the face normal in `mesh` (normalsAgreeingWithWinding).
  int normals_against_winding = 0;
  double prepare_ms = 0.0;

  std::size_t memoryBytes() const;
};

Result<PreparedSource> prepareSource(Mesh mesh, LandmarkSet landmarks, const std::string& label,
                                     const PrepareOptions& options = {});

// Everything that depends only on the target, prepared once per job, as the
// source is once per rig: read by every stage of the warp and the transfer.
struct PreparedTarget {
  Mesh mesh;                            // as read (its normals, if any, as in the file)
  std::string label;                    // the target's file name, for messages
  LandmarkSet landmarks;
  Eigen::MatrixX3d landmark_positions;  // #L by 3 on the mesh
  Eigen::MatrixX3d normals;             // the file's normals, or computeSeamlessVertexNormals without them
  std::vector<int> representative;      // coincidentVertexRepresentatives (split points' copies)
  VertexAdjacency adjacency;            // vertexAdjacency of its triangles (split points apart)
  // Closed pieces no landmark is on (eyes, teeth): per vertex its piece, -1 for skin (empty: none).
  std::vector<int> detached;
  int detached_pieces = 0, detached_vertices = 0;
  ClosestPointIndex index;              // closest points on its skin faces (detached pieces skipped)
  double diagonal = 0.0;                // bounding-box diagonal
  double prepare_ms = 0.0;
};

// Checks the target (a surface mesh; landmarks on it) and prepares it.
Result<PreparedTarget> prepareTarget(Mesh mesh, LandmarkSet landmarks, const std::string& label);

struct WarpOptions {
  TpsOptions landmark_tps;             // regularisation of the landmark warp (0 = exact)
  // Non-rigid ICP rounds: fit the dense map to the guide, re-warp, re-project. 0 = the papers' plain warp.
  int refine_iterations = 2;
  // Refinement centres slide along the target to where the dense map bends least (slideInTangentPlanes).
  bool slide_centres = true;
  // Projections farther than this (fraction of the target diagonal) do not pull their dense centre in refinement.
  double refine_max_distance = 0.1;
  // Local rounds after the dense map: the projection sample's trusted steps, smoothed over the source, applied.
  int local_rounds = 2;
  // Jacobi passes of normalised convolution that smooth each local round's steps.
  int smoothing_passes = 10;
  // In the local rounds a sample of the target's vertices pulls its closest points on the warped source too.
  bool target_pulls = true;
  // Target pulls: matches farther than this (fraction of the target diagonal) do not pull.
  double target_pull_max_distance = 0.015;
  // Target pulls: matches whose normals differ by more than this (degrees) do not pull.
  double target_pull_max_angle_deg = 60.0;
  // After local rounds, target vertices are located on the smoothed guide; false: on the guide (the papers').
  bool smooth_guide = true;
  // Project every source vertex for WarpResult::guide; false (a transfer): only those the location reads.
  bool full_guide = true;
  // With region labels on both meshes (Mesh::regions) every match stays in its region (faceRegionSets).
  bool region_matching = true;
  // Matches and inpainting (cutAcrossSides) stay on their side of the mouth and eyes; false: sides only checked.
  bool side_matching = true;
  OpeningSideOptions sides;            // how openings and their sides are found
  // Source rims matched to the target's after the landmark warp (matchRims), pulling their dense centres onto them.
  bool rim_matching = true;
  RimMatchOptions rims;                // when two rims match
  // Point pairs per matched rim no landmark pins (a neck cut) added to the landmark warp (pairRimPoints); 0: none.
  int rim_warp_points = 24;
  // Located target rim vertices move to the guide's rim, running their way (closestPointOnRim).
  bool rim_location = true;
  // Rim location: only onto a rim point within this fraction of the target diagonal of the vertex.
  double rim_location_max_distance = 0.015;
  // Rim location: only onto a rim point at most this many times as far from the vertex as its surface point.
  double rim_location_max_ratio = 2.0;
  ProjectionOptions projection;        // the warped source projected onto the target (the guide)
  LocateOptions locate;                // the target's vertices located on the guide
};

// The papers' pipeline as written: landmark TPS, projection (the guide),
// location on the guide; no dense-map refinement, local rounds or rims
// (`rigport warp --plain`).
WarpOptions plainWarpOptions();
// The fast pipeline (`rigport warp --light`): one local round with rims
// matched; no dense-map refinement, target pulls or smoothed guide.
WarpOptions lightWarpOptions();

struct LandmarkResidual {
  std::string name;
  double fit = 0.0;            // |warp(source) - target| at the landmark
  double leave_one_out = 0.0;  // |target - warp without this landmark (source)|
};

struct WarpReport {
  // landmarks
  int landmark_count = 0;
  double landmark_rms_residual = 0.0;
  double landmark_max_residual = 0.0;
  double bending_energy = 0.0;
  // How far the target's landmarks are from the source's under the best
  // similarity: atan(rms misfit / (scale x rms spread)), degrees. Faces of
  // other identities and styles: a few degrees to ~15 (ICT identities 3-4,
  // exaggerated 3x 10-11); landmarks of another mesh land anywhere (40+).
  double landmark_misfit_deg = 0.0;
  // Over 30 degrees: taken for another mesh's landmarks, warned about first;
  // the winding, size and pose warnings they would cause are not given.
  bool landmarks_misfit = false;
  std::vector<LandmarkResidual> landmark_residuals;
  std::vector<std::string> suspicious_landmarks;
  // correspondence (target units)
  double mean_distance = 0.0;
  double p95_distance = 0.0;
  double max_distance = 0.0;
  int flipped_triangles = 0;
  int collapsed_triangles = 0;
  int unmatched_source_vertices = 0;
  int projected_source_vertices = 0;  // source vertices projected for the guide (WarpOptions::full_guide)
  int low_confidence_vertices = 0;
  int detached_pieces = 0;            // closed target pieces without landmarks (eyes, teeth) not matched as skin
  int detached_vertices = 0;          // their vertices (low-confidence, mismatched)
  int matched_rims = 0;               // source rims matched to a target rim (matchRims)
  int rims_in_warp = 0;               // of those, rims whose paired points joined the landmark warp
  std::string guide_from = "warp";    // what placed the source on the target: "warp", or "fit" (correspondThroughFit)
  int refine_iterations = 0;
  int target_pulls = 0;               // target vertices that pulled the warped source in the local rounds
  int rim_located_vertices = 0;       // target rim vertices located on a source rim (WarpOptions::rim_location)
  int slid_centres = 0;               // dense centres slid along the target in the last refinement round
  double mean_slide = 0.0;            // mean slide in the first round (the largest), target units
  bool region_matching = false;       // matches were region-constrained
  int sided_openings = 0;             // source openings matched on the target with their two sides (side_matching)
  int sided_target_vertices = 0;      // target vertices on one side of an opening
  // faceOrientationAgreement of the target after the landmark warp (+1: its
  // faces face as the source's); below 0 the target was matched with its
  // faces turned (target_turned) and a warning says so.
  double orientation_agreement = 0.0;
  bool target_turned = false;
  // Vertex normals pointing against their faces' winding (a flipped-normals
  // export), on the source and on the target as matched: those vertices are
  // matched by their face normal, and a warning says so.
  int source_normals_against_winding = 0;
  int target_normals_against_winding = 0;
  std::vector<std::string> warnings;  // e.g. region labels on one side only, a turned target, a mirroring warp, flipped normals
  // meshes
  int source_vertices = 0;
  int source_triangles = 0;
  int target_vertices = 0;
  int target_triangles = 0;
  double target_diagonal = 0.0;
  // stage timings, milliseconds
  double prepare_ms = 0.0;     // 0 when the prepared source came from a cache
  double warp_ms = 0.0;
  double correspond_ms = 0.0;
  double total_ms = 0.0;
};

struct WarpResult {
  // TPS from the source landmarks to the target's, with the paired points of
  // rims no landmark pins (WarpOptions::rim_warp_points) when there are any.
  TpsWarp landmark_warp;
  LandmarkPairs landmark_pairs;        // the landmarks the warp was fitted to (shared names)
  Eigen::MatrixX3d warped_positions;   // #Vs by 3 source after the (last) warp
  GuideModel guide;
  // The dense map: TPS from the dense source centres to their final guide
  // positions (landmark centres to the target landmarks). Carries everything
  // off the surface (joints, deformer points) and, through its Jacobian,
  // vectors. Empty (no centres) when the source was prepared without them.
  std::optional<TpsWarp> dense_map;
  TargetLocations locations;
  // #Vt: each target vertex's side of an opening, numbered as the source's
  // (PreparedSource::vertex_sides; openingSides); empty when no opening was
  // matched with its sides, or neither sides nor rims were matched.
  std::vector<int> target_sides;
  PreparedTarget target;  // as prepared; its index as the warp left it (label sets set, turned with target_turned)
  WarpReport report;
};

// The warp of a target prepared for this job (prepareTarget); the target is
// handed back in WarpResult::target for the stages after.
Result<WarpResult> runWarp(const PreparedSource& source, PreparedTarget target, const WarpOptions& options = {});
// The same, preparing the target first.
Result<WarpResult> runWarp(const PreparedSource& source, const Mesh& target, const LandmarkSet& target_landmarks,
                           const std::string& target_label, const WarpOptions& options = {});

// The correspondence through a fit of the source onto the target (core/fit;
// the transfer's `"correspondence": "fit"`): `fitted_source` is every source
// vertex fitted onto the target (#Vs by 3, target frame). The landmark warp
// still pairs the landmarks, turns the target and matches its rims and
// openings; the fit takes the place of the dense refinement and the local
// rounds: the guide is the fit projected onto the target, and the dense map
// is fitted to it.
Result<WarpResult> correspondThroughFit(const PreparedSource& source, PreparedTarget target,
                                        const Eigen::MatrixX3d& fitted_source, const WarpOptions& options = {});

}  // namespace core
