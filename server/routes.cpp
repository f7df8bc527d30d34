#include "server/routes.h"

#include <algorithm>
#include <charconv>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <chrono>
#include <fstream>
#include <set>

#include "api/content_id.h"
#include "api/error_codes.h"
#include "api/json.h"
#include "api/openapi_document.h"
#include "core/base/error.h"
#include "core/io/landmarks.h"
#include "core/io/mesh_io.h"
#include "server/convert.h"
#include "server/retention.h"
#include "server/uploads.h"

namespace server {

namespace {

using httplib::Request;
using httplib::Response;
using nlohmann::json;

void sendProblem(Response& res, const api::Problem& problem, const RouteContext& ctx) {
  res.status = problem.status;
  if ((problem.status == 429 || problem.status == 503) && !res.has_header("Retry-After")) {
    res.set_header("Retry-After", std::to_string(ctx.config.retry_after_s));
  }
  res.set_content(api::dumpJson(api::toJson(problem)), "application/problem+json");
}

void sendJson(Response& res, int status, const json& body) {
  res.status = status;
  res.set_content(api::dumpJson(body), "application/json");
}

// What the access log says of the request being served: set when routing
// starts, on the thread that serves the whole request (server/http_server.h).
struct RequestLogContext {
  std::chrono::steady_clock::time_point start;
  std::string request_id;
  std::string tenant;
  std::string client;  // the client's address (behind a trusted proxy, the one it names)
};
thread_local RequestLogContext t_request;

// The tenant of the request, or a 401 (or, for an address that failed too
// often, 429) problem sent.
std::optional<std::string> authenticate(const Request& req, Response& res, const RouteContext& ctx) {
  if (ctx.keys.enabled()) {
    if (const int wait_s = ctx.auth_failures.blockedFor(t_request.client); wait_s > 0) {
      res.set_header("Retry-After", std::to_string(wait_s));
      sendProblem(res, api::makeProblem(api::WireError::kAuthThrottled,
                                        "too many failed authentications from this address; retry in " +
                                            std::to_string(wait_s) + " s",
                                        req.path), ctx);
      return std::nullopt;
    }
  }
  auto tenant = ctx.keys.tenantFor(req.get_header_value("Authorization"));
  if (!tenant) {
    const bool blocks = ctx.auth_failures.recordFailure(t_request.client);
    ctx.log.warn(blocks ? "auth_blocked" : "auth_failed",
                 {{"client", t_request.client}, {"method", req.method}, {"path", req.path},
                  {"reason", req.has_header("Authorization") ? "unknown key" : "no key"}});
    res.set_header("WWW-Authenticate", "Bearer");
    sendProblem(res,
                api::makeProblem(api::WireError::kUnauthorized,
                                 req.has_header("Authorization") ? "unknown API key"
                                                                 : "missing 'Authorization: Bearer <api key>' header",
                                 req.path),
                ctx);
    return tenant;
  }
  t_request.tenant = *tenant;
  return tenant;
}

api::Problem storageProblem(const Request& req) {
  return api::makeProblem(api::WireError::kStorageUnavailable,
                          "the service's storage does not take writes now; nothing was changed, retry later", req.path);
}

// A write to the store or the blobs failed: readiness turns red and the
// client is told to retry; what failed (with server paths) goes to the log.
void sendStorageFault(const Request& req, Response& res, RouteContext& ctx, const std::string& where,
                      const std::string& detail) {
  ctx.storage.reportFault(where, detail);
  sendProblem(res, storageProblem(req), ctx);
}

// False, with 503 storage-unavailable sent, while storage is faulty: no
// request that writes starts then.
bool storageWritable(const Request& req, Response& res, RouteContext& ctx) {
  if (ctx.storage.ok()) return true;
  sendProblem(res, storageProblem(req), ctx);
  return false;
}

bool isHexId(const std::string& s, std::size_t length) {
  if (s.size() != length) return false;
  for (char c : s) {
    if (!((c >= '0' && c <= '9') || (c >= 'a' && c <= 'f'))) return false;
  }
  return true;
}

// Counts a multipart body being received; over the limit -> 429.
std::string_view asText(const std::vector<std::uint8_t>& bytes) {
  return {reinterpret_cast<const char*>(bytes.data()), bytes.size()};
}

// The spooled parts read into memory (they are parsed before anything is stored).
struct LoadedParts {
  std::map<std::string, std::vector<std::uint8_t>> bytes;
};

// Parts holding a mesh, rig or clip may use the whole body limit; the JSON
// documents (spec, landmarks, markers, options, components) are read into
// memory and parsed whole, so they have a limit of their own, checked on the
// spooled size before any byte is read.
bool isBulkPart(const std::string& field) {
  return field == "rig" || field == "target" || field == "mesh" || field == "mocap";
}

api::Result<LoadedParts> loadParts(const SpooledUpload& upload, const std::set<std::string>& required,
                                                  const std::set<std::string>& optional, const std::string& path,
                                                  std::uint64_t max_document_bytes) {
  for (const auto& name : required) {
    if (!upload.parts.count(name)) {
      return api::makeProblem(api::WireError::kMalformedRequest, "multipart field '" + name + "' is required", path);
    }
  }
  LoadedParts loaded;
  for (const auto& [field, part] : upload.parts) {
    if (!required.count(field) && !optional.count(field)) {
      std::vector<std::string> known(required.begin(), required.end());
      known.insert(known.end(), optional.begin(), optional.end());
      return api::makeProblem(api::WireError::kMalformedRequest, "multipart field '" + field +
                              "' is not known here (expected " + core::joinNames(known) + ")", path);
    }
    if (!isBulkPart(field) && part.size > max_document_bytes) {
      return api::makeProblem(api::WireError::kPayloadTooLarge,
                              "multipart field '" + field + "' is " + std::to_string(part.size) +
                                  " bytes; a JSON part may have at most " + std::to_string(max_document_bytes),
                              path);
    }
    auto bytes = core::readFileBytes(part.path);
    if (!bytes) return api::makeProblem(api::WireError::kInternal, "reading the spooled upload failed", path);
    loaded.bytes[field] = std::move(*bytes);
  }
  return loaded;
}

const std::set<std::string>& knownRoutes() {
  static const std::set<std::string> routes = {
      "/healthz", "/readyz", "/metrics", "/openapi.json", "/v1/rigs", "/v1/rigs/{id}", "/v1/jobs", "/v1/jobs/{id}",
      "/v1/jobs/{id}:cancel", "/v1/jobs/{id}/result", "/v1/jobs/{id}/diagnostics"};
  return routes;
}

// An authenticated multipart body spooled to disk within the upload limits,
// or nullopt with the problem already sent.
struct ReceivedUpload {
  std::string tenant;
  SpooledUpload upload;
};

std::optional<ReceivedUpload> receiveUpload(const Request& req, Response& res, const httplib::ContentReader& reader,
                                            RouteContext& ctx) {
  auto tenant = authenticate(req, res, ctx);
  if (!tenant || !storageWritable(req, res, ctx)) return std::nullopt;
  auto slot = ctx.uploads.acquire(*tenant, t_request.client);
  if (!slot) {
    res.set_header("Connection", "close");  // the body is left unread
    sendProblem(res, api::makeProblem(api::WireError::kTooManyUploads, slot.error() + "; retry later", req.path), ctx);
    return std::nullopt;
  }
  auto spooled = spoolMultipart(req, reader, ctx.config.data_dir / "uploads", ctx.config.max_body_bytes);
  if (!spooled) {
    if (spooled.error().status == 503) ctx.storage.reportFault("upload_spool", spooled.error().detail);
    sendProblem(res, spooled.error(), ctx);
    return std::nullopt;
  }
  return ReceivedUpload{std::move(*tenant), std::move(*spooled)};
}

// ---------------------------------------------------------------- rigs

void postRig(const Request& req, Response& res, const httplib::ContentReader& reader, RouteContext& ctx) {
  auto received = receiveUpload(req, res, reader, ctx);
  if (!received) return;
  const std::string* tenant = &received->tenant;
  const SpooledUpload& upload = received->upload;
  auto loaded = loadParts(upload, {"rig", "landmarks"}, {"components"}, req.path, ctx.config.max_document_part_bytes);
  if (!loaded) return sendProblem(res, loaded.error(), ctx);
  const auto& bytes = loaded->bytes;
  const bool has_components = bytes.count("components") > 0;
  const std::vector<std::uint8_t> no_components;
  const std::string id =
      api::rigContentId(bytes.at("rig"), bytes.at("landmarks"), has_components ? bytes.at("components") : no_components);

  if (auto existing = ctx.store.getRig(*tenant, id)) {  // idempotent: same content, same rig
    res.set_header("Location", "/v1/rigs/" + id);
    return sendJson(res, 200, api::toJson(existing->info));
  }
  const std::string rig_name = upload.parts.at("rig").filename.empty() ? "rig.glb" : upload.parts.at("rig").filename;
  auto checked = checkRigUpload(bytes.at("rig"), rig_name, bytes.at("landmarks"),
                                has_components ? std::optional<Bytes>(bytes.at("components")) : std::nullopt, ctx.config);
  if (!checked) return sendProblem(res, checked.error(), ctx);

  RigRecord record;
  record.tenant = *tenant;
  record.info = *checked;
  record.info.id = id;
  record.info.created_at = formatTimestamp(nowMs());
  std::shared_lock collection(ctx.blob_collection);
  for (const auto& [field, part] : upload.parts) {
    auto hash = ctx.blobs.adopt(part.path);
    if (!hash) return sendStorageFault(req, res, ctx, "rig_upload", hash.error().message);
    (field == "rig" ? record.rig_blob : field == "landmarks" ? record.landmarks_blob : record.components_blob) = *hash;
  }
  auto inserted = ctx.store.insertRig(record);
  collection.unlock();
  if (!inserted) return sendStorageFault(req, res, ctx, "rig_insert", inserted.error().message);
  ctx.log.info("rig_uploaded", {{"tenant", *tenant}, {"rig", id}, {"name", rig_name}, {"vertices", record.info.vertices}});
  res.set_header("Location", "/v1/rigs/" + id);
  sendJson(res, inserted->second ? 201 : 200, api::toJson(inserted->first.info));
}

void getRigs(const Request& req, Response& res, RouteContext& ctx) {
  const auto tenant = authenticate(req, res, ctx);
  if (!tenant) return;
  api::RigPage page;
  for (auto& rig : ctx.store.listRigs(*tenant)) page.items.push_back(std::move(rig.info));
  sendJson(res, 200, api::toJson(page));
}

void getRig(const Request& req, Response& res, RouteContext& ctx) {
  const auto tenant = authenticate(req, res, ctx);
  if (!tenant) return;
  const std::string id = req.matches[1];
  auto rig = ctx.store.getRig(*tenant, id);
  if (!rig) return sendProblem(res, api::makeProblem(api::WireError::kNotFound, "no rig " + id, req.path), ctx);
  sendJson(res, 200, api::toJson(rig->info));
}

void deleteRig(const Request& req, Response& res, RouteContext& ctx) {
  const auto tenant = authenticate(req, res, ctx);
  if (!tenant || !storageWritable(req, res, ctx)) return;
  const std::string id = req.matches[1];
  std::unique_lock collection(ctx.blob_collection);
  if (!ctx.blob_collection.mayCollect()) return sendStorageFault(req, res, ctx, "rig_delete", "rig " + id);
  auto rig = ctx.store.getRig(*tenant, id);
  if (!rig || !ctx.store.deleteRig(*tenant, id)) {
    return sendProblem(res, api::makeProblem(api::WireError::kNotFound, "no rig " + id, req.path), ctx);
  }
  ctx.blob_collection.removeUnreferenced(ctx.blobs, {rig->rig_blob, rig->landmarks_blob, rig->components_blob});
  ctx.caches.rigs.erase(tenantCacheKey(*tenant, id));  // this tenant's next job prepares it again; others keep theirs
  ctx.log.info("rig_deleted", {{"tenant", *tenant}, {"rig", id}});
  res.status = 204;
}

// ---------------------------------------------------------------- jobs

void postJob(const Request& req, Response& res, const httplib::ContentReader& reader, RouteContext& ctx) {
  auto received = receiveUpload(req, res, reader, ctx);
  if (!received) return;
  const std::string* tenant = &received->tenant;
  const SpooledUpload& upload = received->upload;
  if (!upload.parts.count("spec")) {
    return sendProblem(res, api::makeProblem(api::WireError::kMalformedRequest, "multipart field 'spec' is required", req.path), ctx);
  }
  auto spec_bytes = core::readFileBytes(upload.parts.at("spec").path);
  if (!spec_bytes) return sendProblem(res, api::makeProblem(api::WireError::kInternal, "reading the spooled upload failed", req.path), ctx);
  auto spec_json = api::parseJsonText(std::string(asText(*spec_bytes)), "spec");
  if (!spec_json) return sendProblem(res, api::makeProblem(api::WireError::kMalformedRequest, spec_json.error(), req.path), ctx);
  auto parsed_spec = api::jobSpecFromJson(*spec_json);
  if (!parsed_spec) {
    return sendProblem(res, api::makeProblem(api::WireError::kMalformedRequest, parsed_spec.error(), req.path), ctx);
  }
  api::JobSpec& spec = *parsed_spec;
  const api::JobKindInfo& kind = api::jobKindInfo(spec.kind);
  std::optional<core::LandmarkSet> rig_landmarks;
  bool rig_has_components = false;
  if (kind.needs_rig) {
    if (!isHexId(spec.rig, 64)) {
      return sendProblem(res, api::makeProblem(api::WireError::kMalformedRequest,
                                               "spec.rig: expected the 64-hex-digit id of an uploaded rig", req.path), ctx);
    }
    auto rig = ctx.store.getRig(*tenant, spec.rig);
    if (!rig) {
      return sendProblem(res, api::makeProblem(api::WireError::kNotFound, "spec.rig: no rig " + spec.rig, req.path), ctx);
    }
    // The rig's landmark names, so a target that shares too few is a 422 now.
    auto landmark_bytes = ctx.blobs.read(rig->landmarks_blob);
    auto landmarks = landmark_bytes ? core::parseLandmarks(asText(*landmark_bytes), "rig " + spec.rig + " landmarks")
                                    : core::Result<core::LandmarkSet>(landmark_bytes.error());
    if (!landmarks) {
      ctx.log.error("rig_unreadable", {{"rig", spec.rig}, {"tenant", *tenant}, {"detail", landmarks.error().message}});
      return sendProblem(res, api::makeProblem(api::WireError::kInternal, "the stored rig " + spec.rig + " is unreadable", req.path), ctx);
    }
    rig_landmarks = std::move(*landmarks);
    rig_has_components = rig->info.has_components;
  }
  std::set<std::string> required(kind.required_files.begin(), kind.required_files.end());
  required.insert("spec");
  auto loaded = loadParts(upload, required, {kind.optional_files.begin(), kind.optional_files.end()}, req.path,
                          ctx.config.max_document_part_bytes);
  if (!loaded) return sendProblem(res, loaded.error(), ctx);
  const auto& bytes = loaded->bytes;
  std::map<std::string, std::pair<std::string, Bytes>> files;
  for (const auto& [field, data] : bytes) {
    const std::string& filename = upload.parts.at(field).filename;
    files[field] = {filename.empty() ? field : filename, Bytes(data)};
  }
  if (auto p = checkJobInputs(spec, files, rig_landmarks ? &*rig_landmarks : nullptr, rig_has_components, ctx.config)) {
    return sendProblem(res, *p, ctx);
  }

  JobRecord job;
  job.tenant = *tenant;
  auto job_id = secureRandomHex(16);  // unguessable: ids are not secrets, but need not be predictable
  if (!job_id) return sendProblem(res, api::makeProblem(api::WireError::kInternal, "no random job id available", req.path), ctx);
  job.id = *job_id;
  job.kind = spec.kind;
  job.rig = spec.rig;
  job.spec_json = api::dumpJson(api::toJson(spec));
  job.idempotency_key = req.get_header_value("Idempotency-Key");
  job.created_ms = nowMs();
  std::shared_lock collection(ctx.blob_collection);  // held until the job row is committed
  for (const auto& [field, part] : upload.parts) {
    if (field == "spec") continue;
    auto hash = ctx.blobs.adopt(part.path);
    if (!hash) return sendStorageFault(req, res, ctx, "job_upload", hash.error().message);
    job.inputs[field] = *hash;
    job.input_names[field] = files.at(field).first;
  }
  auto submitted = ctx.jobs.submit(job);
  if (!submitted) return sendProblem(res, submitted.error(), ctx);
  const auto& [record, created] = *submitted;
  if (!created && (record.spec_json != job.spec_json || record.inputs != job.inputs)) {
    // The key names another request: a retry must be the same request (as
    // Stripe answers). What this one stored alone is removed, under the
    // exclusive lock a rig delete takes (no other request between adopting
    // the same bytes and committing its row).
    collection.unlock();
    std::unique_lock exclusive(ctx.blob_collection);
    std::set<std::string> stored_alone;
    for (const auto& [field, hash] : job.inputs) stored_alone.insert(hash);
    ctx.blob_collection.removeUnreferenced(ctx.blobs, stored_alone);
    return sendProblem(res,
                       api::makeProblem(api::WireError::kConflict,
                                        "Idempotency-Key '" + job.idempotency_key + "' was used for another request (job " +
                                            record.id + "): a retry must send the same spec and files",
                                        req.path),
                       ctx);
  }
  if (created) {
    ctx.log.info("job_accepted", {{"job", record.id}, {"tenant", *tenant}, {"kind", api::jobKindName(record.kind)}, {"rig", record.rig}});
  }
  res.set_header("Location", "/v1/jobs/" + record.id);
  sendJson(res, created ? 202 : 200, api::toJson(jobInfoOf(record, ctx.jobs.live(record.id))));
}

void getJobs(const Request& req, Response& res, RouteContext& ctx) {
  const auto tenant = authenticate(req, res, ctx);
  if (!tenant) return;
  JobListQuery query;
  query.tenant = *tenant;
  if (req.has_param("status")) {
    query.status = api::parseJobStatus(req.get_param_value("status"));
    if (!query.status) {
      return sendProblem(res, api::makeProblem(api::WireError::kMalformedRequest,
                                               "status: expected queued, running, succeeded, failed or cancelled", req.path), ctx);
    }
  }
  // Whole integers only ("5abc" is no 5).
  auto integer = [&](const char* name, auto& out) {
    const std::string text = req.get_param_value(name);
    const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), out);
    return error == std::errc() && end == text.data() + text.size();
  };
  if ((req.has_param("limit") && !integer("limit", query.limit)) ||
      (req.has_param("after") && !integer("after", query.after_sequence))) {
    return sendProblem(res, api::makeProblem(api::WireError::kMalformedRequest, "limit/after: expected integers", req.path), ctx);
  }
  if (query.limit < 1 || query.limit > 500) {
    return sendProblem(res, api::makeProblem(api::WireError::kMalformedRequest, "limit: expected 1..500", req.path), ctx);
  }
  const auto jobs = ctx.store.listJobs(query);
  api::JobPage page;
  for (const auto& job : jobs) page.items.push_back(jobInfoOf(job, ctx.jobs.live(job.id)));
  if (static_cast<int>(jobs.size()) == query.limit) page.next = std::to_string(jobs.back().sequence);
  sendJson(res, 200, api::toJson(page));
}

// Longest long-poll a client may ask for (`wait_ms`); at most
// config.max_concurrent_waits wait at once (the others answer at once).
constexpr int kMaxWaitMs = 60000;

void getJob(const Request& req, Response& res, RouteContext& ctx) {
  const auto tenant = authenticate(req, res, ctx);
  if (!tenant) return;
  int wait_ms = 0;
  if (req.has_param("wait_ms")) {
    const std::string text = req.get_param_value("wait_ms");
    const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), wait_ms);
    if (ec != std::errc() || end != text.data() + text.size() || wait_ms < 0 || wait_ms > kMaxWaitMs) {
      return sendProblem(res, api::makeProblem(api::WireError::kMalformedRequest,
                                               "wait_ms: expected an integer 0.." + std::to_string(kMaxWaitMs) +
                                                   " (milliseconds to wait for the job to finish)", req.path), ctx);
    }
  }
  const std::string id = req.matches[1];
  auto job = ctx.store.getJob(*tenant, id);
  if (!job) return sendProblem(res, api::makeProblem(api::WireError::kNotFound, "no job " + id, req.path), ctx);
  if (wait_ms > 0 && !api::isFinal(job->status) &&
      ctx.jobs.waitUntilSettled(*tenant, id, std::chrono::milliseconds(wait_ms), ctx.config.max_concurrent_waits)) {
    if (auto again = ctx.store.getJob(*tenant, id)) job = std::move(again);
  }
  sendJson(res, 200, api::toJson(jobInfoOf(*job, ctx.jobs.live(id))));
}

void cancelJob(const Request& req, Response& res, RouteContext& ctx) {
  const auto tenant = authenticate(req, res, ctx);
  if (!tenant || !storageWritable(req, res, ctx)) return;
  const std::string id = req.matches[1];
  auto cancelled = ctx.jobs.cancel(*tenant, id);
  if (!cancelled) return sendProblem(res, cancelled.error(), ctx);
  sendJson(res, 202, api::toJson(jobInfoOf(*cancelled, ctx.jobs.live(id))));
}

enum class JobBlob { kResult, kDiagnostics, kComponents };

// GET result / diagnostics / components: the stored blob, verified against its hash.
void getJobBlob(const Request& req, Response& res, RouteContext& ctx, JobBlob which) {
  const auto tenant = authenticate(req, res, ctx);
  if (!tenant) return;
  const std::string id = req.matches[1];
  std::shared_lock collection(ctx.blob_collection);  // a concurrent DELETE of this job waits for the read
  auto job = ctx.store.getJob(*tenant, id);
  if (!job) return sendProblem(res, api::makeProblem(api::WireError::kNotFound, "no job " + id, req.path), ctx);
  const bool diagnostics = which == JobBlob::kDiagnostics;
  // A failed fit its gate refused keeps its diagnostics (why it failed, in full).
  const bool served = job->status == api::JobStatus::kSucceeded || (diagnostics && !job->diagnostics_blob.empty());
  if (!served) {
    return sendProblem(res, api::makeProblem(api::WireError::kConflict,
                                             "job " + id + " is " + api::jobStatusName(job->status) +
                                                 (diagnostics ? "; diagnostics exist once it has succeeded, or failed its "
                                                                "quality gate (other failures carry their error)"
                                                              : "; the result exists once it has succeeded"),
                                             req.path), ctx);
  }
  if (which == JobBlob::kComponents && job->components_blob.empty()) {
    return sendProblem(res, api::makeProblem(api::WireError::kNotFound,
                                             "job " + id + " has no components document: its rig was uploaded without "
                                                           "one (POST /v1/rigs, part components)",
                                             req.path), ctx);
  }
  const std::string& hash = which == JobBlob::kResult        ? job->result_blob
                            : which == JobBlob::kDiagnostics ? job->diagnostics_blob
                                                             : job->components_blob;
  auto blob = ctx.blobs.read(hash);
  collection.unlock();
  if (!blob) {
    ctx.storage.reportFault("job_result_read", "job " + id + ": " + blob.error().message);
    return sendProblem(res, api::makeProblem(api::WireError::kInternal, "the stored result of job " + id + " is unreadable", req.path), ctx);
  }
  res.status = 200;
  res.set_content(std::string(asText(*blob)), which == JobBlob::kResult ? "model/gltf-binary" : "application/json");
}

void deleteJobRoute(const Request& req, Response& res, RouteContext& ctx) {
  const auto tenant = authenticate(req, res, ctx);
  if (!tenant || !storageWritable(req, res, ctx)) return;
  const std::string id = req.matches[1];
  switch (deleteJob(ctx.store, ctx.blobs, ctx.blob_collection, ctx.metrics, ctx.log, *tenant, id, "request")) {
    case JobDeletion::kDeleted: res.status = 204; return;
    case JobDeletion::kAbsent:
      return sendProblem(res, api::makeProblem(api::WireError::kNotFound, "no job " + id, req.path), ctx);
    case JobDeletion::kUnfinished:
      return sendProblem(res, api::makeProblem(api::WireError::kConflict,
                                               "job " + id + " is queued or running: cancel it first (POST /v1/jobs/" + id +
                                                   ":cancel), then delete it once it is cancelled",
                                               req.path), ctx);
    case JobDeletion::kStoreError:
      return sendStorageFault(req, res, ctx, "job_delete", "job " + id);
  }
}

}  // namespace

void registerRoutes(httplib::Server& http, RouteContext& ctx) {
  http.Get("/healthz", [](const Request&, Response& res) {
    res.set_content("ok rigport " RIGPORT_VERSION "\n", "text/plain");
  });
  http.Get("/readyz", [&ctx](const Request& req, Response& res) {
    if (ctx.ready && ctx.storage.ok()) return res.set_content("ready\n", "text/plain");
    if (ctx.ready) {
      return sendProblem(res, api::makeProblem(api::WireError::kStorageUnavailable,
                                               "the service's storage does not take writes now", req.path), ctx);
    }
    sendProblem(res, api::makeProblem(api::WireError::kNotReady, "starting up or shutting down", req.path), ctx);
  });
  http.Get("/metrics", [&ctx](const Request& req, Response& res) {
    // Queue depths and job counts are the service's business: a key (any
    // tenant's) unless the operator made them public.
    if (!ctx.config.public_metrics && !authenticate(req, res, ctx)) return;
    GaugeSnapshot g;
    for (const auto& [status, n] : ctx.store.countJobsByStatus()) g.jobs_by_state[api::jobStatusName(status)] = n;
    g.queue_depth = ctx.jobs.queueDepth();
    g.running_jobs = ctx.jobs.runningJobs();
    g.storage_ok = ctx.storage.ok();
    g.storage_faults = ctx.storage.faults();
    g.caches = {{"rig", ctx.caches.rigs.stats()}, {"fit", ctx.caches.fits.stats()}, {"distances", ctx.caches.distances.stats()}};
    res.set_content(ctx.metrics.render(g), "text/plain; version=0.0.4");
  });
  http.Get("/openapi.json", [](const Request&, Response& res) {
    res.set_content(std::string(api::openApiDocument()), "application/json");
  });

  http.Post("/v1/rigs", [&ctx](const Request& req, Response& res, const httplib::ContentReader& reader) {
    postRig(req, res, reader, ctx);
  });
  http.Get("/v1/rigs", [&ctx](const Request& req, Response& res) { getRigs(req, res, ctx); });
  http.Get(R"(/v1/rigs/([0-9a-f]{64}))", [&ctx](const Request& req, Response& res) { getRig(req, res, ctx); });
  http.Delete(R"(/v1/rigs/([0-9a-f]{64}))", [&ctx](const Request& req, Response& res) { deleteRig(req, res, ctx); });

  http.Post("/v1/jobs", [&ctx](const Request& req, Response& res, const httplib::ContentReader& reader) {
    postJob(req, res, reader, ctx);
  });
  http.Get("/v1/jobs", [&ctx](const Request& req, Response& res) { getJobs(req, res, ctx); });
  http.Get(R"(/v1/jobs/([0-9a-f]{32}))", [&ctx](const Request& req, Response& res) { getJob(req, res, ctx); });
  http.Delete(R"(/v1/jobs/([0-9a-f]{32}))", [&ctx](const Request& req, Response& res) { deleteJobRoute(req, res, ctx); });
  http.Post(R"(/v1/jobs/([0-9a-f]{32}):cancel)", [&ctx](const Request& req, Response& res) { cancelJob(req, res, ctx); });
  http.Get(R"(/v1/jobs/([0-9a-f]{32})/result)", [&ctx](const Request& req, Response& res) { getJobBlob(req, res, ctx, JobBlob::kResult); });
  http.Get(R"(/v1/jobs/([0-9a-f]{32})/diagnostics)",
           [&ctx](const Request& req, Response& res) { getJobBlob(req, res, ctx, JobBlob::kDiagnostics); });
  http.Get(R"(/v1/jobs/([0-9a-f]{32})/components)",
           [&ctx](const Request& req, Response& res) { getJobBlob(req, res, ctx, JobBlob::kComponents); });

  // Every other 4xx/5xx without a body (unknown route, 413 from the payload
  // limit, a method not served) becomes problem+json too.
  http.set_error_handler(httplib::Server::HandlerWithResponse([&ctx](const Request& req, Response& res) {
    if (!res.body.empty()) return httplib::Server::HandlerResponse::Unhandled;
    api::WireError kind = api::WireError::kInternal;
    std::string detail = "error";
    switch (res.status) {
      case 404: kind = api::WireError::kNotFound; detail = "no route " + req.method + " " + req.path; break;
      case 413: kind = api::WireError::kPayloadTooLarge;
        detail = "request body over the limit of " + std::to_string(ctx.config.max_body_bytes) + " bytes"; break;
      case 400: kind = api::WireError::kMalformedRequest; detail = "malformed HTTP request (a POST without a body must send Content-Length: 0)"; break;
      case 415: kind = api::WireError::kUnsupportedMediaType; detail = "unsupported media type"; break;
      default: detail = "HTTP " + std::to_string(res.status); break;
    }
    api::Problem problem = api::makeProblem(kind, detail, req.path);
    problem.status = res.status;
    res.set_content(api::dumpJson(api::toJson(problem)), "application/problem+json");
    return httplib::Server::HandlerResponse::Handled;
  }));
  http.set_exception_handler([&ctx](const Request& req, Response& res, std::exception_ptr ep) {
    std::string what = "unknown exception";
    try {
      std::rethrow_exception(ep);
    } catch (const std::exception& e) {
      what = e.what();
    } catch (...) {
    }
    ctx.log.error("unhandled_exception", {{"path", req.path}, {"detail", what}});
    sendProblem(res, api::makeProblem(api::WireError::kInternal, "internal error while serving " + req.path, req.path), ctx);
  });
  http.set_pre_routing_handler([&ctx](const Request& req, Response& res) {
    // A proxy's request id is kept (so its log and ours match) when it is a
    // plain token; otherwise the service makes one.
    std::string id = req.get_header_value("X-Request-Id");
    const bool plain = !id.empty() && id.size() <= 64 && std::all_of(id.begin(), id.end(), [](unsigned char c) {
      return std::isalnum(c) || c == '-' || c == '_' || c == '.';
    });
    if (!plain) id = secureRandomHex(8).value_or("");
    std::string forwarded_for;
    for (std::size_t i = 0; i < req.get_header_value_count("X-Forwarded-For"); ++i) {
      forwarded_for += (i > 0 ? "," : "") + req.get_header_value("X-Forwarded-For", i);
    }
    t_request = {std::chrono::steady_clock::now(), std::move(id), "", ctx.proxies.clientOf(req.remote_addr, forwarded_for)};
    res.set_header("X-Request-Id", t_request.request_id);
    return httplib::Server::HandlerResponse::Unhandled;
  });
  // One access-log line per request that reached routing (what the gate
  // answers by itself it logs itself, server/connection_gate.h).
  http.set_logger([&ctx](const Request& req, const Response& res) {
    std::string route = routePattern(req.path);
    if (!knownRoutes().count(route)) route = "unmatched";
    ctx.metrics.countRequest(req.method, route, res.status);
    const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t_request.start).count();
    const nlohmann::json line = {{"request_id", t_request.request_id}, {"method", req.method}, {"route", route},
                                 {"status", res.status}, {"tenant", t_request.tenant}, {"client", t_request.client},
                                 {"bytes_in", std::strtoull(req.get_header_value("Content-Length").c_str(), nullptr, 10)}, {"bytes_out", res.body.size()},
                                 {"ms", std::round(ms * 10) / 10}};
    if (res.status >= 500) {
      ctx.log.error("request", line);
    } else {
      ctx.log.info("request", line);
    }
  });
}

}  // namespace server
