#include "server/convert.h"

#include "core/base/timing.h"

#include <algorithm>
#include <chrono>

#include "api/content_id.h"
#include "api/json.h"
#include "core/fit/scan.h"
#include "core/jobs/fit_job.h"
#include "core/jobs/fit_options.h"
#include "core/jobs/retarget_job.h"
#include "core/jobs/transfer_job.h"
#include "core/io/components_io.h"
#include "core/io/landmarks.h"
#include "core/io/mesh_io.h"
#include "core/jobs/retarget_options.h"
#include "core/io/rig_io.h"
#include "core/io/trc_io.h"
#include "core/solve/tps.h"
#include "core/transfer/transfer.h"
#include "core/jobs/transfer_options.h"

namespace server {

namespace {

using core::Clock;
using core::msSince;

std::string_view asText(Bytes bytes) { return {reinterpret_cast<const char*>(bytes.data()), bytes.size()}; }

bool isGlb(Bytes bytes) { return bytes.size() >= 4 && asText(bytes.first(4)) == "glTF"; }

std::optional<api::Problem> checkCounts(const core::Mesh& mesh, std::size_t landmarks, const std::string& label,
                                        const ServerConfig& limits, const std::string& instance) {
  if (mesh.vertexCount() > limits.max_vertices) {
    return api::makeProblem(api::WireError::kPayloadTooLarge, label + ": " + std::to_string(mesh.vertexCount()) +
                                                                  " vertices, over the limit of " +
                                                                  std::to_string(limits.max_vertices),
                            instance);
  }
  if (landmarks > static_cast<std::size_t>(limits.max_landmarks)) {
    return api::makeProblem(api::WireError::kPayloadTooLarge, label + ": " + std::to_string(landmarks) +
                                                                  " landmarks, over the limit of " +
                                                                  std::to_string(limits.max_landmarks),
                            instance);
  }
  return std::nullopt;
}

core::Result<core::LoadedRig> readRigBytes(Bytes bytes, const std::string& label) {
  return core::readRigGltf(bytes, label, isGlb(bytes));
}

// Inputs of a transfer job, read from their blobs.
struct TransferInputs {
  core::LoadedMesh target;
  core::LandmarkSet target_landmarks;
  core::TransferSettings settings;
};

}  // namespace

api::WireError wireErrorOf(core::ErrorCode code) {
  switch (code) {
    case core::ErrorCode::kIo: return api::WireError::kInternal;
    case core::ErrorCode::kParse: return api::WireError::kMalformedFile;
    case core::ErrorCode::kUnsupported: return api::WireError::kUnsupportedFeature;
    case core::ErrorCode::kInvalidMesh: return api::WireError::kInvalidMesh;
    case core::ErrorCode::kInvalidLandmarks: return api::WireError::kInvalidLandmarks;
    case core::ErrorCode::kIllConditioned: return api::WireError::kIllConditioned;
    case core::ErrorCode::kInvalidArgument: return api::WireError::kInvalidOption;
    case core::ErrorCode::kCancelled: return api::WireError::kJobCancelled;
    case core::ErrorCode::kQualityGate: return api::WireError::kQualityGate;
  }
  return api::WireError::kInternal;
}

api::Problem problemFromCoreError(const core::Error& error, const std::string& instance) {
  // In the service, core reads only memory and the service's own files: an I/O
  // error is about server paths, which tenants never see (the log has them).
  if (error.code == core::ErrorCode::kIo) {
    return api::makeProblem(api::WireError::kInternal, "the service could not read or write its storage (see its log)",
                            instance);
  }
  return api::makeProblem(wireErrorOf(error.code), error.message, instance);
}

api::Result<api::RigInfo> checkRigUpload(Bytes rig_bytes, const std::string& rig_name, Bytes landmark_bytes,
                                                        const std::optional<Bytes>& components,
                                                        const ServerConfig& limits) {
  auto rig = readRigBytes(rig_bytes, "rig '" + rig_name + "'");
  if (!rig) return problemFromCoreError(rig.error(), "/v1/rigs");
  auto landmarks = core::parseLandmarks(asText(landmark_bytes), "landmarks");
  if (!landmarks) return problemFromCoreError(landmarks.error(), "/v1/rigs");
  if (auto p = checkCounts(rig->rig.mesh, landmarks->landmarks.size(), "rig '" + rig_name + "'", limits, "/v1/rigs")) return *p;
  if (auto ok = core::validateSurfaceMesh(rig->rig.mesh, "rig '" + rig_name + "'"); !ok) {
    return problemFromCoreError(ok.error(), "/v1/rigs");
  }
  auto positions = core::resolveLandmarks(*landmarks, rig->rig.mesh, "landmarks");
  if (!positions) return problemFromCoreError(positions.error(), "/v1/rigs");
  std::vector<std::string> names;
  for (const auto& l : landmarks->landmarks) names.push_back(l.name);
  if (auto ok = core::checkTpsCentres(*positions, {}, names); !ok) return problemFromCoreError(ok.error(), "/v1/rigs");
  if (components) {  // the document read and checked against the rig's face (docs/COMPONENTS.md)
    auto doc = core::parseRigComponents(asText(*components), "components", rig->rig.mesh);
    if (!doc) return api::makeProblem(api::WireError::kMalformedFile, doc.error().message, "/v1/rigs");
  }
  api::RigInfo info;
  info.name = rig_name;
  info.size_bytes = static_cast<std::int64_t>(rig_bytes.size());
  info.vertices = static_cast<int>(rig->rig.mesh.vertexCount());
  info.joints = rig->rig.skin ? static_cast<int>(rig->rig.skin->joints.size()) : 0;
  info.morph_targets = static_cast<int>(rig->rig.morph_targets.size());
  info.landmarks = static_cast<int>(landmarks->landmarks.size());
  info.has_components = components.has_value();
  std::vector<int> labels(rig->rig.mesh.regions.data(), rig->rig.mesh.regions.data() + rig->rig.mesh.regions.size());
  std::sort(labels.begin(), labels.end());
  labels.erase(std::unique(labels.begin(), labels.end()), labels.end());
  info.region_labels = std::move(labels);
  return info;
}

std::optional<api::Problem> checkJobInputs(api::JobSpec& spec,
                                           const std::map<std::string, std::pair<std::string, Bytes>>& files,
                                           const core::LandmarkSet* rig_landmarks, bool rig_has_components,
                                           const ServerConfig& limits) {
  const std::string instance = "/v1/jobs";
  const auto bakeWithoutComponents = [&](const core::PresetBake& bake) -> std::optional<api::Problem> {
    if (!bake.enabled || rig_has_components) return std::nullopt;
    return api::makeProblem(api::WireError::kInvalidOption,
                            "spec.options: 'bake_presets': rig " + spec.rig +
                                " was uploaded without a components document (POST /v1/rigs, part components)",
                            instance);
  };
  if (spec.kind == api::JobKind::kTransfer) {
    auto settings = core::parseTransferOptions(spec.options.dump(), "spec.options");
    if (!settings) return problemFromCoreError(settings.error(), instance);
    spec.options = nlohmann::json::parse(core::transferOptionsJson(*settings));
    if (auto p = bakeWithoutComponents(settings->bake)) return p;
    const auto& [target_name, target_bytes] = files.at("target");
    auto target = core::readMeshFromMemory(target_bytes, target_name, "target '" + target_name + "'");
    if (!target) return problemFromCoreError(target.error(), instance);
    if (!files.count("target_landmarks")) {  // found by a fit of the rig's face when the job runs
      if (auto p = checkCounts(target->mesh, 0, "target '" + target_name + "'", limits, instance)) return p;
      if (auto ok = core::validateSurfaceMesh(target->mesh, "target '" + target_name + "'"); !ok) {
        return problemFromCoreError(ok.error(), instance);
      }
      if (auto ok = core::checkScan(target->mesh, target_name); !ok) return problemFromCoreError(ok.error(), instance);
      return std::nullopt;
    }
    auto landmarks = core::parseLandmarks(asText(files.at("target_landmarks").second), "target_landmarks");
    if (!landmarks) return problemFromCoreError(landmarks.error(), instance);
    if (auto p = checkCounts(target->mesh, landmarks->landmarks.size(), "target '" + target_name + "'", limits, instance)) return p;
    auto positions = core::resolveLandmarks(*landmarks, target->mesh, "target_landmarks");
    if (!positions) return problemFromCoreError(positions.error(), instance);
    if (rig_landmarks) {
      // The label the job's own errors use (the target's file name).
      if (auto ok = core::checkWarpTarget(*rig_landmarks, target->mesh, *landmarks, *positions, target_name,
                                          settings->transfer.warp.landmark_tps);
          !ok) {
        return problemFromCoreError(ok.error(), instance);
      }
    }
    return std::nullopt;
  }
  if (spec.kind == api::JobKind::kRetarget) {
    auto settings = core::parseRetargetOptions(spec.options.dump(), "spec.options");
    if (!settings) return problemFromCoreError(settings.error(), instance);
    spec.options = nlohmann::json::parse(core::retargetOptionsJson(*settings));
    const auto& [mesh_name, mesh_bytes] = files.at("mesh");
    auto mesh = core::readMeshFromMemory(mesh_bytes, mesh_name, "mesh '" + mesh_name + "'");
    if (!mesh) return problemFromCoreError(mesh.error(), instance);
    auto markers = core::parseLandmarks(asText(files.at("markers").second), "markers");
    if (!markers) return problemFromCoreError(markers.error(), instance);
    if (auto p = checkCounts(mesh->mesh, markers->landmarks.size(), "mesh '" + mesh_name + "'", limits, instance)) return p;
    if (auto ok = core::validateSurfaceMesh(mesh->mesh, mesh_name); !ok) return problemFromCoreError(ok.error(), instance);
    if (markers->landmarks.size() < 4) {
      return api::makeProblem(api::WireError::kInvalidLandmarks,
                              "markers: " + std::to_string(markers->landmarks.size()) + " markers (at least 4 needed)",
                              instance);
    }
    if (auto positions = core::resolveLandmarks(*markers, mesh->mesh, "markers"); !positions) {
      return problemFromCoreError(positions.error(), instance);
    }
    auto clip = core::parseTrc(asText(files.at("mocap").second), files.at("mocap").first, settings->clip);
    if (!clip) return problemFromCoreError(clip.error(), instance);
    if (const auto it = files.find("stiffness"); it != files.end()) {
      auto stiffness = core::parseStiffness(std::string(asText(it->second.second)), "stiffness");
      if (!stiffness) return problemFromCoreError(stiffness.error(), instance);
      for (const auto& [name, value] : *stiffness) {
        if (markers->indexOf(name) < 0) {
          return api::makeProblem(api::WireError::kInvalidOption, "stiffness: '" + name + "' is not a marker of the placement",
                                  instance);
        }
      }
    }
    return std::nullopt;
  }
  if (spec.kind == api::JobKind::kFit) {
    auto settings = core::parseFitOptions(spec.options.dump(), "spec.options");
    if (!settings) return problemFromCoreError(settings.error(), instance);
    spec.options = nlohmann::json::parse(core::fitOptionsJson(*settings));
    if (auto p = bakeWithoutComponents(settings->bake)) return p;
    const auto& [scan_name, scan_bytes] = files.at("scan");
    auto scan = core::readMeshFromMemory(scan_bytes, scan_name, "scan '" + scan_name + "'");
    if (!scan) return problemFromCoreError(scan.error(), instance);
    const auto landmark_file = files.find("scan_landmarks");
    core::LandmarkSet landmarks;
    if (landmark_file != files.end()) {
      auto parsed = core::parseLandmarks(asText(landmark_file->second.second), "scan_landmarks");
      if (!parsed) return problemFromCoreError(parsed.error(), instance);
      landmarks = std::move(*parsed);
    }
    if (auto p = checkCounts(scan->mesh, landmarks.landmarks.size(), "scan '" + scan_name + "'", limits, instance)) return p;
    if (auto ok = core::checkScan(scan->mesh, scan_name); !ok) return problemFromCoreError(ok.error(), instance);
    if (landmark_file != files.end()) {
      if (rig_landmarks) {
        if (auto ok = core::checkSharedLandmarkNames(*rig_landmarks, landmarks, scan_name); !ok) {
          return problemFromCoreError(ok.error(), instance);
        }
      }
      if (auto positions = core::resolveLandmarks(landmarks, scan->mesh, "scan_landmarks"); !positions) {
        return problemFromCoreError(positions.error(), instance);
      }
    } else if (settings->fit.alignment == core::FitAlignmentMode::kLandmarks) {
      return api::makeProblem(api::WireError::kInvalidOption,
                              "spec.options: 'alignment' is \"landmarks\" but no scan_landmarks file was sent", instance);
    }
    return std::nullopt;
  }
  return api::makeProblem(api::WireError::kMalformedRequest,
                          "spec.kind: '" + std::string(api::jobKindName(spec.kind)) + "' is not served yet", instance);
}

namespace {

// A job's stored inputs and spec, as the runners read them.
struct JobFiles {
  const JobRecord& job;
  const BlobStore& blobs;
  core::Result<std::vector<std::uint8_t>> bytes(const std::string& field) const {
    const auto it = job.inputs.find(field);
    if (it == job.inputs.end()) return core::makeError(core::ErrorCode::kInvalidArgument, "job " + job.id + " has no " + field);
    return blobs.read(it->second);
  }
  bool has(const std::string& field) const { return job.inputs.count(field) > 0; }
  std::string name(const std::string& field) const {
    const auto it = job.input_names.find(field);
    return it == job.input_names.end() ? field : it->second;
  }
  core::Result<core::LoadedMesh> mesh(const std::string& field) const {
    auto stored = bytes(field);
    if (!stored) return stored.error();
    return core::readMeshFromMemory(*stored, name(field), name(field));
  }
  core::Result<core::LandmarkSet> landmarks(const std::string& field) const {
    auto stored = bytes(field);
    if (!stored) return stored.error();
    return core::parseLandmarks(asText(*stored), name(field));
  }
  std::string optionsText() const {
    const auto spec = nlohmann::json::parse(job.spec_json, nullptr, false);
    return spec.is_object() && spec.contains("options") ? spec["options"].dump() : "{}";
  }
};

core::Result<core::JobOutput> runRetargetJob(const JobFiles& in, DistanceCache& cache, core::JobRun run) {
  if (!run.stage("read", 0.02)) return run.stoppedBefore("reading inputs");
  core::RetargetJobInput input;
  auto settings = core::parseRetargetOptions(in.optionsText(), "spec.options");
  if (!settings) return settings.error();
  input.settings = std::move(*settings);
  auto mesh = in.mesh("mesh");
  if (!mesh) return mesh.error();
  auto markers = in.landmarks("markers");
  if (!markers) return markers.error();
  auto clip_bytes = in.bytes("mocap");
  if (!clip_bytes) return clip_bytes.error();
  auto clip = core::parseTrc(asText(*clip_bytes), in.name("mocap"), input.settings.clip);
  if (!clip) return clip.error();
  if (in.has("stiffness")) {
    auto stiffness_bytes = in.bytes("stiffness");
    if (!stiffness_bytes) return stiffness_bytes.error();
    auto stiffness = core::parseStiffness(std::string(asText(*stiffness_bytes)), in.name("stiffness"));
    if (!stiffness) return stiffness.error();
    input.settings.retarget.stiffness = std::move(*stiffness);
  }
  input.mesh = std::move(*mesh);
  input.markers = std::move(*markers);
  input.clip = std::move(*clip);
  run.read_ms = msSince(run.started);

  // Cached per tenant and (mesh, markers, distance options).
  const core::MarkerDistanceOptions& d = input.settings.distances;
  const std::string key = api::sha256Hex(
      in.job.inputs.at("mesh") + "|" + in.job.inputs.at("markers") + "|" + core::distanceMethodName(d.method) + "|" +
      std::to_string(d.geodesic.time_factor) + "|" + std::to_string(d.geodesic.average_boundary_conditions) + "|" +
      std::to_string(d.geodesic.clamp_heat_weights) + "|" + std::to_string(d.hybrid.region_factor) + "|" +
      std::to_string(d.hybrid.blend_gamma) + "|" + std::to_string(d.hybrid.regions.size()));
  const core::ComputeMarkerDistances cached = [&]() -> core::Result<core::MarkerDistancesSource> {
    auto distances = cache.get(tenantCacheKey(in.job.tenant, key), [&] {
      return core::computeMarkerDistances(input.mesh.mesh, input.markers, in.name("mesh"), input.settings.distances);
    });
    if (!distances) return distances.error();
    return core::MarkerDistancesSource{distances->value, distances->hit};
  };
  auto out = core::runRetargetJob(cached, input, run);
  if (!out) return out.error();
  return std::move(out->output);
}

// The rig prepared for transfers and fits: cached per tenant and rig content
// id, so a hit skips all source-only work. `read` receives how the rig file
// was read when it was read for this call.
core::Result<RigCache::Lookup> preparedRig(const RigRecord& rig_record, const BlobStore& blobs, RigCache& cache,
                                           core::MeshReadReport& read) {
  return cache.get(tenantCacheKey(rig_record.tenant, rig_record.info.id), [&]() -> core::Result<core::PreparedRig> {
    auto rig_bytes = blobs.read(rig_record.rig_blob);
    if (!rig_bytes) return rig_bytes.error();
    auto rig = readRigBytes(*rig_bytes, rig_record.info.name);
    if (!rig) return rig.error();
    read = rig->report;
    auto source_landmark_bytes = blobs.read(rig_record.landmarks_blob);
    if (!source_landmark_bytes) return source_landmark_bytes.error();
    auto source_landmarks = core::parseLandmarks(asText(*source_landmark_bytes), "landmarks");
    if (!source_landmarks) return source_landmarks.error();
    std::optional<core::ComponentsDocument> components;
    if (!rig_record.components_blob.empty()) {  // checked at upload; read again as any stored input
      auto bytes = blobs.read(rig_record.components_blob);
      if (!bytes) return bytes.error();
      auto doc = core::parseRigComponents(asText(*bytes), rig_record.info.name + " components", rig->rig.mesh);
      if (!doc) return doc.error();
      components = std::move(*doc);
    }
    auto prepared = core::prepareRig(std::move(rig->rig), std::move(*source_landmarks), rig_record.info.name);
    if (!prepared) return prepared.error();
    prepared->components = std::move(components);
    return prepared;
  });
}

// The fit reference (fit jobs, and transfers that fit), cached per tenant and
// rig beside the prepared rig it is built on (a transfer's cache entry serves
// it too). `read` receives how the rig file was read when it was read for it.
core::PrepareFitSource cachedFitReference(const RigRecord& rig_record, const BlobStore& blobs, Caches& caches,
                                          core::MeshReadReport& read) {
  return [&rig_record, &blobs, &caches, &read]() -> core::Result<core::PreparedFitSource> {
    bool read_now = false;
    auto fitted = caches.fits.get(tenantCacheKey(rig_record.tenant, rig_record.info.id),
                                  [&]() -> core::Result<core::FitReference> {
                                    auto rig = preparedRig(rig_record, blobs, caches.rigs, read);
                                    if (!rig) return rig.error();
                                    read_now = !rig->hit;
                                    return core::prepareFitReference(rig->value);
                                  });
    if (!fitted) return fitted.error();
    return core::PreparedFitSource{fitted->value, read_now ? &read : nullptr, fitted->hit};
  };
}

core::Result<core::JobOutput> runFitJob(const JobFiles& in, const RigRecord& rig_record, const BlobStore& blobs,
                                        Caches& caches, core::JobRun run) {
  if (!run.stage("read", 0.02)) return run.stoppedBefore("reading inputs");
  core::FitJobInput input;
  auto settings = core::parseFitOptions(in.optionsText(), "spec.options");
  if (!settings) return settings.error();
  input.settings = std::move(*settings);
  auto scan = in.mesh("scan");
  if (!scan) return scan.error();
  input.scan = std::move(*scan);
  input.scan_label = in.name("scan");
  if (in.has("scan_landmarks")) {
    auto landmarks = in.landmarks("scan_landmarks");
    if (!landmarks) return landmarks.error();
    input.scan_landmarks = std::move(*landmarks);
  }
  run.read_ms = msSince(run.started);

  core::MeshReadReport source_read;
  const core::PrepareFitSource prepare = cachedFitReference(rig_record, blobs, caches, source_read);
  auto out = core::runFitJob(prepare, std::move(input), run);
  if (!out) return out.error();
  return std::move(out->output);  // a refused fit keeps its diagnostics (JobManager stores them)
}

core::Result<core::JobOutput> runTransferJob(const JobFiles& in, const RigRecord& rig_record, const BlobStore& blobs,
                                             Caches& caches, core::JobRun run) {
  if (!run.stage("read", 0.02)) return run.stoppedBefore("reading inputs");
  core::TransferJobInput input;
  auto settings = core::parseTransferOptions(in.optionsText(), "spec.options");
  if (!settings) return settings.error();
  input.settings = std::move(*settings);
  auto target = in.mesh("target");
  if (!target) return target.error();
  input.target = std::move(*target);
  if (in.has("target_landmarks")) {  // else found by a fit of the rig's face
    auto target_landmarks = in.landmarks("target_landmarks");
    if (!target_landmarks) return target_landmarks.error();
    input.target_landmarks = std::move(*target_landmarks);
  }
  input.target_label = in.name("target");
  run.read_ms = msSince(run.started);

  // Cached per tenant and rig content id: a hit skips all source-only work.
  core::MeshReadReport source_read;
  const core::PrepareRigSource prepare = [&]() -> core::Result<core::PreparedRigSource> {
    auto prepared = preparedRig(rig_record, blobs, caches.rigs, source_read);
    if (!prepared) return prepared.error();
    return core::PreparedRigSource{prepared->value, &source_read, prepared->hit};
  };
  auto out = core::runTransferJob(prepare, std::move(input), run, cachedFitReference(rig_record, blobs, caches, source_read));
  if (!out) return out.error();
  return std::move(out->output);
}

}  // namespace

core::Result<core::JobOutput> runJob(const JobRecord& job, const RigRecord* rig, const BlobStore& blobs, Caches& caches,
                                     const core::StageHook& on_stage, int threads) {
  const JobFiles files{job, blobs};
  core::JobRun run;
  run.threads = threads;
  run.on_stage = on_stage;
  run.job_label = "job " + job.id;
  switch (job.kind) {
    case api::JobKind::kTransfer:
      if (rig == nullptr) break;
      return runTransferJob(files, *rig, blobs, caches, std::move(run));
    case api::JobKind::kRetarget: return runRetargetJob(files, caches.distances, std::move(run));
    case api::JobKind::kFit:
      if (rig == nullptr) break;
      return runFitJob(files, *rig, blobs, caches, std::move(run));
  }
  return core::makeError(core::ErrorCode::kInvalidArgument,
                         "job " + job.id + ": a " + api::jobKindName(job.kind) + " job without its rig cannot run");
}

}  // namespace server
