#include "core/jobs/diagnostics_json.h"

#include <algorithm>
#include <cmath>

#include <nlohmann/json.hpp>

namespace core {

namespace {

using Json = nlohmann::ordered_json;

// Names from files (meshes, joints, shapes, markers) are bytes: invalid UTF-8
// is replaced (U+FFFD) rather than failing the whole document.
std::string dumpDocument(const Json& doc) { return doc.dump(2, ' ', false, Json::error_handler_t::replace) + "\n"; }

const char* formatName(MeshFormat f) {
  switch (f) {
    case MeshFormat::kGlb: return "glb";
    case MeshFormat::kGltf: return "gltf";
    case MeshFormat::kObj: return "obj";
    case MeshFormat::kPly: return "ply";
  }
  return "unknown";
}

Json readReportJson(const MeshReadReport& r) {
  Json j;
  j["format"] = formatName(r.format);
  j["chosen_mesh"] = r.chosen_mesh;
  j["meshes_in_file"] = r.meshes_in_file;
  j["polygons_triangulated"] = r.polygons_triangulated;
  j["degenerate_triangles"] = r.degenerate_triangles;
  j["normals_computed"] = r.normals_computed;
  j["warnings"] = r.warnings;
  return j;
}

Json warpJson(const WarpReport& r, const DiagnosticsContext& context) {
  Json doc;
  Json& lm = doc["landmarks"];
  lm["count"] = r.landmark_count;
  lm["rms_residual"] = r.landmark_rms_residual;
  lm["max_residual"] = r.landmark_max_residual;
  lm["suspicious"] = r.suspicious_landmarks;
  lm["bending_energy"] = r.bending_energy;
  lm["misfit_deg"] = r.landmark_misfit_deg;
  lm["misfit"] = r.landmarks_misfit;
  lm["residuals"] = Json::array();
  for (const auto& res : r.landmark_residuals) {
    lm["residuals"].push_back({{"name", res.name}, {"fit", res.fit}, {"leave_one_out", res.leave_one_out}});
  }

  Json& c = doc["correspondence"];
  c["method"] = r.guide_from;
  c["mean_distance"] = r.mean_distance;
  c["p95_distance"] = r.p95_distance;
  c["max_distance"] = r.max_distance;
  c["flipped_triangles"] = r.flipped_triangles;
  c["collapsed_triangles"] = r.collapsed_triangles;
  c["unmatched_source_vertices"] = r.unmatched_source_vertices;
  c["projected_source_vertices"] = r.projected_source_vertices;
  c["low_confidence_vertices"] = r.low_confidence_vertices;
  c["detached_pieces"] = r.detached_pieces;
  c["detached_vertices"] = r.detached_vertices;
  c["refine_iterations"] = r.refine_iterations;
  c["target_pulls"] = r.target_pulls;
  c["rim_located_vertices"] = r.rim_located_vertices;
  c["slid_centres"] = r.slid_centres;
  c["mean_slide"] = r.mean_slide;
  c["region_matching"] = r.region_matching;
  c["sided_openings"] = r.sided_openings;
  c["sided_target_vertices"] = r.sided_target_vertices;
  c["matched_rims"] = r.matched_rims;
  c["rims_in_warp"] = r.rims_in_warp;
  c["orientation_agreement"] = r.orientation_agreement;
  c["target_turned"] = r.target_turned;
  c["source_normals_against_winding"] = r.source_normals_against_winding;
  c["target_normals_against_winding"] = r.target_normals_against_winding;
  c["warnings"] = r.warnings;

  Json& m = doc["mesh"];
  m["bbox_diagonal"] = r.target_diagonal;
  m["source_vertices"] = r.source_vertices;
  m["source_triangles"] = r.source_triangles;
  m["target_vertices"] = r.target_vertices;
  m["target_triangles"] = r.target_triangles;
  if (context.source_read) m["source_file"] = readReportJson(*context.source_read);
  if (context.target_read) m["target_file"] = readReportJson(*context.target_read);

  doc["cache"] = {{"hit", context.cache_hit}};
  return doc;
}

Json distanceJson(const DistanceStats& d) { return {{"median", d.median}, {"p95", d.p95}, {"max", d.max}}; }

Json vectorJson(const Eigen::Vector3d& v) { return Json::array({v(0), v(1), v(2)}); }

// The rig's other meshes as carried: how (rigid body or deformed), the
// body's scale and how far the dense map strays from it.
Json partsJson(const std::vector<CarriedPart>& parts) {
  Json out = Json::array();
  for (const CarriedPart& p : parts) {
    // -1: not checked (the landmarks gave no forward axis).
    auto count = [](int n) { return n >= 0 ? Json(n) : Json(nullptr); };
    out.push_back({{"name", p.name},
                   {"carried", p.rigid ? "rigid" : "deformed"},
                   {"scale", p.scale},
                   {"fit_residual", p.fit_residual},
                   {"vertices_in_front", count(p.vertices_in_front)},
                   {"source_vertices_in_front", count(p.source_vertices_in_front)}});
  }
  return out;
}

Json fitJson(const FitReport& r, const DiagnosticsContext& context) {
  Json doc;
  doc["verdict"] = r.verdict;
  doc["reasons"] = r.reasons;
  doc["warnings"] = r.warnings;
  const ScanReport& s = r.scan;
  Json& scan = doc["scan"];
  scan["file"] = s.file;
  scan["points"] = s.points;
  scan["triangles"] = s.triangles;
  scan["point_cloud"] = s.point_cloud;
  scan["normals_computed"] = s.normals_computed;
  scan["pieces"] = s.pieces;
  scan["detached_points"] = s.detached_points;
  scan["border_points"] = s.border_points;
  scan["spikes"] = s.spikes;
  scan["holes"] = s.holes;
  scan["units"] = s.units;
  scan["unit_scale"] = s.unit_scale;
  scan["size_ratio"] = s.size_ratio;
  if (context.target_read) scan["read"] = readReportJson(*context.target_read);
  const AlignmentReport& a = r.alignment;
  doc["alignment"] = {{"method", a.method},           {"rotation_deg", a.rotation_deg},
                      {"yaw_deg", a.yaw_deg},         {"pitch_deg", a.pitch_deg},
                      {"roll_deg", a.roll_deg},       {"scale", a.scale},
                      {"translation", vectorJson(a.translation)}, {"rms_residual", a.rms_residual},
                      {"inlier_fraction", a.inlier_fraction}, {"hypotheses", a.hypotheses},
                      {"runner_up_ratio", a.runner_up_ratio}, {"landmarks_dropped", a.landmarks_dropped}};
  Json& lm = doc["landmarks"];
  lm["count"] = r.landmarks.size();
  double rms = 0.0, worst = 0.0;
  lm["residuals"] = Json::array();
  for (const FitLandmarkResidual& l : r.landmarks) {
    rms += l.fitted * l.fitted;
    worst = std::max(worst, l.fitted);
    lm["residuals"].push_back({{"name", l.name}, {"aligned", l.aligned}, {"fitted", l.fitted}});
  }
  lm["rms_residual"] = r.landmarks.empty() ? 0.0 : std::sqrt(rms / static_cast<double>(r.landmarks.size()));
  lm["max_residual"] = worst;
  lm["found"] = Json::array();
  for (const FoundLandmark& f : r.found_landmarks) lm["found"].push_back({{"name", f.name}, {"position", vectorJson(f.position)}});
  Json stages = Json::array();
  for (const FitStageReport& st : r.stages) {
    stages.push_back({{"stiffness", st.stiffness},
                      {"iterations", st.iterations},
                      {"accepted", st.accepted},
                      {"rim_matches", st.rim_matches},
                      {"rejected", {{"distance", st.rejected_distance}, {"normal", st.rejected_normal},
                                    {"border", st.rejected_border}, {"spike", st.rejected_spike}}},
                      {"energy", {{"data", st.energy_data}, {"smooth", st.energy_smooth}, {"landmarks", st.energy_landmarks}}},
                      {"max_step", st.max_step}});
  }
  doc["fit"] = {{"stages", stages}};
  doc["distance"] = {{"face", distanceJson(r.face_distance)}, {"skin", distanceJson(r.skin_distance)}};
  doc["coverage"] = {{"face", r.face_coverage}, {"skin", r.skin_coverage}, {"uncovered_vertices", r.uncovered_vertices}};
  doc["folds"] = {{"flipped", r.flipped_triangles}, {"collapsed", r.collapsed_triangles}};
  doc["rebuild"] = {{"shapes", r.shapes}, {"joints", r.joints}, {"animations", r.animations}};
  doc["parts"] = partsJson(r.parts);
  return doc;
}

}  // namespace

std::string formatWarpDiagnostics(const WarpReport& r, const DiagnosticsContext& context) {
  Json doc = warpJson(r, context);
  Json& t = doc["timings_ms"];
  t["prepare"] = r.prepare_ms;
  t["warp"] = r.warp_ms;
  t["correspond"] = r.correspond_ms;
  for (const auto& [name, ms] : context.extra_timings_ms) t[name] = ms;
  t["total"] = context.total_ms >= 0.0 ? context.total_ms : r.total_ms;
  return dumpDocument(doc);
}

std::string formatTransferDiagnostics(const TransferReport& r, const DiagnosticsContext& context) {
  Json doc = warpJson(r.warp, context);
  doc["weights"] = {{"inpainted_vertices", r.inpainted_vertices},
                    {"pruned_vertices", r.pruned_vertices},
                    {"max_influences", r.max_influences}};
  doc["shapes"] = {{"count", r.shapes}};
  doc["joints"] = {{"count", r.joints}};
  doc["animations"] = {{"count", r.animations}};
  doc["parts"] = partsJson(r.parts);
  doc["transfer"] = {{"unlocated_vertices", r.unlocated_vertices},
                     {"uv_seam_vertices", r.uv_seam_vertices},
                     {"uv_extended_vertices", r.uv_extended_vertices},
                     {"adaptation", r.adaptation},
                     {"adaptation_reason", r.adaptation_reason},
                     {"global_scale", r.global_scale},
                     {"global_rotation_deg", r.global_rotation_deg},
                     {"rotation_threshold_deg", r.rotation_threshold_deg},
                     {"rotation_applied", r.rotation_applied},
                     {"scale_applied", r.scale_applied},
                     {"delta_scale", r.delta_scale},
                     {"stretch_ratio", r.stretch_ratio},
                     {"stretch_threshold", r.stretch_threshold},
                     {"stretch_applied", r.stretch_applied},
                     {"warnings", r.warnings}};
  doc["landmarks"]["found_by_fit"] = context.landmarks_found;
  if (context.fit) doc["fit"] = fitJson(*context.fit, {});
  Json& q = doc["quality"];
  q["clean"] = r.quality.clean();
  q["shape_outliers"] = r.quality.shape_outliers;
  q["shapes"] = Json::array();
  for (const ShapeOutliers& s : r.quality.shapes) {
    q["shapes"].push_back({{"shape", s.shape}, {"vertices", s.vertices}, {"worst", s.worst}});
  }
  q["crossed_vertices"] = r.quality.crossed_vertices;
  q["crossed_shapes"] = Json::array();
  for (const ShapeOutliers& s : r.quality.crossed_shapes) {
    q["crossed_shapes"].push_back({{"shape", s.shape}, {"vertices", s.vertices}, {"worst", s.worst}});
  }
  q["repaired_vertices"] = r.quality.repaired_vertices;
  q["worst"] = Json::array();
  for (const QualityVertex& w : r.quality.worst) {
    q["worst"].push_back({{"vertex", w.vertex}, {"shape", w.shape}, {"score", w.score}});
  }
  Json& t = doc["timings_ms"];
  t["prepare"] = r.prepare_ms;
  t["warp"] = r.warp.warp_ms;
  t["correspond"] = r.warp.correspond_ms;
  t["dense_map"] = r.dense_map_ms;
  t["weights"] = r.weights_ms;
  t["joints"] = r.joints_ms;
  t["shapes"] = r.shapes_ms;
  t["parts"] = r.parts_ms;
  t["components"] = r.components_ms;
  t["animations"] = r.animations_ms;
  t["attributes"] = r.attributes_ms;
  t["quality"] = r.quality_ms;
  for (const auto& [name, ms] : context.extra_timings_ms) t[name] = ms;
  t["total"] = context.total_ms >= 0.0 ? context.total_ms : r.total_ms;
  return dumpDocument(doc);
}

std::string formatFitDiagnostics(const FitReport& r, const DiagnosticsContext& context) {
  Json doc = fitJson(r, context);
  doc["cache"] = {{"hit", context.cache_hit}};
  Json& t = doc["timings_ms"];
  t["scan"] = r.scan_ms;
  t["align"] = r.align_ms;
  t["fit"] = r.fit_ms;
  t["gate"] = r.gate_ms;
  t["rebuild"] = r.rebuild_ms;
  for (const auto& [name, ms] : context.extra_timings_ms) t[name] = ms;
  t["total"] = context.total_ms >= 0.0 ? context.total_ms : r.total_ms;
  return dumpDocument(doc);
}

}  // namespace core
