// The service assembled: store, blob files, prepared-rig cache, job manager,
// metrics and the HTTP server with its routes. Used by server/main.cpp and by
// the integration tests (in-process on an ephemeral loopback port).
#pragma once

#include <atomic>
#include <memory>
#include <shared_mutex>

#include "server/blob_collection.h"

#include "api/http.h"

#include "core/base/error.h"
#include "server/auth.h"
#include "server/config.h"
#include "server/http_server.h"
#include "server/jobs.h"
#include "server/json_log.h"
#include "server/metrics.h"
#include "server/prepared_cache.h"
#include "server/retention.h"
#include "server/storage_health.h"
#include "server/routes.h"
#include "server/store.h"

namespace server {

class Service {
 public:
  // Opens (or creates) the data directory: <dir>/rigport.sqlite, <dir>/blobs,
  // <dir>/uploads. `logger` may be null (no logs).
  static core::Result<std::unique_ptr<Service>> create(const ServerConfig& config, ApiKeys keys,
                                                       std::shared_ptr<spdlog::logger> logger);
  ~Service();

  // Recovers unfinished jobs, starts the workers, binds the listener (port 0:
  // any free port) and marks the service ready. Returns the bound port.
  core::Result<int> start();
  // Accept loop; returns after stop().
  void serve();
  // Graceful stop: not ready, no new connections, running jobs get `grace_s`
  // to finish; queued jobs stay in the store for the next start.
  void stop(double grace_s);
  int port() const { return port_; }

 private:
  Service(const ServerConfig& config, ApiKeys keys, TrustedProxies proxies, std::unique_ptr<MetadataStore> store,
          std::shared_ptr<const TlsContext> tls, JsonLog log);

  ServerConfig config_;
  ApiKeys keys_;
  TrustedProxies proxies_;
  JsonLog log_;
  std::unique_ptr<MetadataStore> store_;
  BlobStore blobs_;
  Caches caches_;
  Metrics metrics_;
  BlobCollection blob_collection_{*store_};
  StorageHealth storage_;
  JobManager jobs_;
  RetentionSweeper retention_;
  std::atomic<bool> ready_{false};
  AuthFailureLimit auth_failures_;
  UploadSlots uploads_;
  RouteContext routes_;
  GatedHttpServer http_;
  int port_ = 0;
  std::atomic<bool> stopped_{false};
  std::atomic<bool> serving_{false};  // serve() entered and not returned
};

}  // namespace server
