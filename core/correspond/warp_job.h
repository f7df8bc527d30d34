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
#include "core/solve/tps.h"

namespace core {

struct PrepareOptions {
  // Dense-map centres: the source landmarks plus this many farthest-point
  // samples of the source vertices.
  int dense_centres = 400;
  // Regularisation of the dense map as a fraction of the source bbox diagonal
  // (smooths projection noise; 0 interpolates).
  double dense_regularization = 0.002;
  int threads = 0;
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

struct WarpOptions {
  TpsOptions landmark_tps;             // regularisation of the landmark warp (0 = exact)
  // Non-rigid ICP rounds: fit the dense map to the current guide, re-warp the
  // source through it and re-project. 0 = the papers' plain warp + projection.
  int refine_iterations = 2;
  // In each refinement round the projected dense centres slide along the
  // target surface to where the dense map bends least
  // (slideInTangentPlanes): projection alone leaves them where the landmark
  // warp put them along the surface. The job's landmarks and centres on
  // matched rims stay.
  bool slide_centres = true;
  // Projections farther than this (fraction of the target diagonal) do not
  // pull their dense centre during refinement.
  double refine_max_distance = 0.1;
  // Local rounds after the dense map: the trusted projection displacements of
  // the projection sample are smoothed over the source mesh
  // (`smoothing_passes` Jacobi passes of normalised convolution) and applied;
  // the surface is projected again after the last round.
  // Corrects misfit finer than the dense centres' spacing.
  int local_rounds = 2;
  int smoothing_passes = 10;
  // In the local rounds the target's vertices pull too: a sample of them (an
  // independent set, each standing for the neighbours it covers) is matched
  // once, after the dense map, to the closest points on the warped source
  // (within target_pull_max_distance of the target diagonal, normals within
  // target_pull_max_angle_deg), and each pulls its point onto itself.
  // Projection from the source alone never reaches the parts of the target
  // the source does not already cover (a fuller lip, a deeper fold).
  bool target_pulls = true;
  double target_pull_max_distance = 0.015;
  double target_pull_max_angle_deg = 60.0;
  // After local rounds the target's vertices are located on the smoothed
  // guide: the warped source moved by the guide's displacement smoothed as in
  // the rounds. The guide's own triangles fold where projection crowds
  // vertices together, and locations on them scatter. Without local rounds
  // (the warped source may be far from the target) or with false: located
  // on the guide itself, as in the papers.
  bool smooth_guide = true;
  // Project every source vertex for the guide (WarpResult::guide), as a warp
  // job returns it. false (what a transfer asks): when the target is located
  // on the smoothed guide, only the vertices read from the guide are
  // projected (the projection sample and the dense centres' vertices); the
  // others keep their warped position. The locations are the same either way.
  bool full_guide = true;
  // When source and target both carry region labels (Mesh::regions), every
  // match (projection, refinement, location) stays within compatible regions;
  // see faceRegionSets. false: labels are ignored.
  bool region_matching = true;
  // The source's openings (the mouth, the eyes) are matched to the target's
  // rims, both split into their two sides (upper and lower lip, upper and
  // lower lid), and every match (projection, refinement, target pulls,
  // location) stays on its own side: a lower-lip vertex never takes the
  // upper lip's motion, however close the lips are; the inpainting of
  // untrusted vertices does not cross either (cutAcrossSides). _REGION labels
  // on both, when region_matching uses them, take the sides' place in the
  // matching. false: the sides (found whenever rims are matched) are only
  // read by the transfer's quality check.
  bool side_matching = true;
  OpeningSideOptions sides;
  // Source rims (neck cut, mouth, eyes) matched to target rims after the
  // landmark warp (matchRims); those no landmark pins join the warp (below),
  // and in the refinement every matched rim pulls its dense centres onto its
  // target rim instead of the surface. Only there: snapping the guide's rim
  // vertices themselves folds the triangles next to them (measured: 57 more
  // flipped triangles and eyeBlink_R E 0.18 -> 0.21 on a 10-landmark
  // target), while the dense map carries the rim's pull smoothly.
  // false: rims are matched like any other surface.
  bool rim_matching = true;
  RimMatchOptions rims;
  // Matched rims that no source landmark lies on (within 2% of the source
  // diagonal: a neck cut, not the mouth or eyes) join the landmark warp with
  // this many point pairs each, at most one per rim vertex (pairRimPoints):
  // far from the face's landmarks the warp only extrapolates. Rims the
  // landmarks pin are left out: pairs a few millimetres from a landmark's
  // exact target would bend the warp between them. 0: rims only act in the
  // refinement.
  int rim_warp_points = 24;
  // Target vertices on a rim, once located on the guide's surface, move to
  // the guide's rim: the rim point nearest their surface location among rim
  // edges running their way (closestPointOnRim). A border corresponds to a
  // border, and the surface location of a rim vertex falls short of the
  // source's rim, inside the lid (remeshed ICT identities: eye-hole vertices
  // 1-4 mm off). Only when that rim point is within
  // rim_location_max_distance (fraction of the target diagonal) of the
  // vertex and at most rim_location_max_ratio times as far from it as the
  // surface point: a coarse remesh's hole can cut across the lid, and a
  // vertex of it far from any source rim keeps its surface point. A vertex
  // the location refused (its surface point across a thin gap: the other
  // lip) is taken back when the rim point running its way, searched from the
  // vertex, lies on another face. Independent of rim_matching.
  bool rim_location = true;
  double rim_location_max_distance = 0.015;
  double rim_location_max_ratio = 2.0;
  ProjectionOptions projection;
  LocateOptions locate;
  int threads = 0;                     // 0 = hardware threads (stages that run in parallel)
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
  VertexAdjacency target_adjacency;  // of the target's vertices (vertexAdjacency; split points apart)
  // coincidentVertexRepresentatives of the target (split points' copies; empty: none).
  std::vector<int> target_representative;
  WarpReport report;
};

Result<WarpResult> runWarp(const PreparedSource& source, const Mesh& target, const LandmarkSet& target_landmarks,
                           const std::string& target_label, const WarpOptions& options = {});

}  // namespace core
