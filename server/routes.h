// HTTP routes under /v1 plus /healthz, /readyz, /metrics, /openapi.json.
// Handlers are thin: authenticate -> parse -> validate (before anything is
// queued) -> store/enqueue -> respond. Every error is problem+json.
#pragma once

#include <atomic>
#include <shared_mutex>

#include "server/blob_collection.h"

#include "api/http.h"

#include "server/auth.h"
#include "server/client_address.h"
#include "server/config.h"
#include "server/jobs.h"
#include "server/json_log.h"
#include "server/metrics.h"
#include "server/prepared_cache.h"
#include "server/storage_health.h"
#include "server/store.h"
#include "server/uploads.h"

namespace server {

struct RouteContext {
  const ServerConfig& config;
  const ApiKeys& keys;
  MetadataStore& store;
  BlobStore& blobs;
  Caches& caches;
  JobManager& jobs;
  Metrics& metrics;
  JsonLog log;
  std::atomic<bool>& ready;                 // /readyz, and 503 on /v1 while false
  const TrustedProxies& proxies;            // whose X-Forwarded-For names the client address
  AuthFailureLimit& auth_failures;          // per client address
  UploadSlots& uploads;                     // per service, tenant and client address
  // Uploads hold it shared from adopting blobs until their row is committed;
  // a rig or job delete holds it exclusively while it collects unreferenced blobs,
  // so it never removes a blob a concurrent upload is about to reference.
  BlobCollection& blob_collection;
  // Red: /readyz and every request that would write answer 503
  // storage-unavailable; a failed write reports here.
  StorageHealth& storage;
};

// Registers every route and the error/exception/logger hooks. `context` must
// outlive the server.
void registerRoutes(httplib::Server& http, RouteContext& context);

}  // namespace server
