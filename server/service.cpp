#include "server/service.h"

#include <sys/stat.h>

#include <algorithm>
#include <chrono>
#include <system_error>
#include <thread>

namespace server {

core::Result<std::unique_ptr<Service>> Service::create(const ServerConfig& config, ApiKeys keys,
                                                       std::shared_ptr<spdlog::logger> logger) {
  // The service's files (store, blobs, spooled uploads) are readable by its
  // own user only: studio assets on a shared machine. umask covers what
  // SQLite and the spool create; the data dir of an older install is closed too.
  ::umask(077);
  std::error_code ec;
  std::filesystem::create_directories(config.data_dir / "uploads", ec);
  if (ec) return core::makeError(core::ErrorCode::kIo, config.data_dir.string() + ": cannot create: " + ec.message());
  std::filesystem::permissions(config.data_dir, std::filesystem::perms::owner_all, ec);
  if (ec) return core::makeError(core::ErrorCode::kIo, config.data_dir.string() + ": cannot make it private: " + ec.message());
  // Spooled parts of requests that were cut off by a crash: never accepted.
  for (const auto& entry : std::filesystem::directory_iterator(config.data_dir / "uploads", ec)) {
    std::filesystem::remove(entry.path(), ec);
  }
  // Threads kept for probes and small reads whatever uploads and long-polls do.
  constexpr int kReservedHttpThreads = 4;
  if (config.max_concurrent_uploads + config.max_concurrent_waits > config.http_threads - kReservedHttpThreads) {
    return core::makeError(core::ErrorCode::kInvalidArgument,
                           "max_concurrent_uploads (" + std::to_string(config.max_concurrent_uploads) +
                               ") + max_concurrent_waits (" + std::to_string(config.max_concurrent_waits) +
                               ") must leave " + std::to_string(kReservedHttpThreads) + " of the " +
                               std::to_string(config.http_threads) + " HTTP threads free");
  }
  auto proxies = TrustedProxies::parse(config.trusted_proxies);
  if (!proxies) return proxies.error();
  std::shared_ptr<const TlsContext> tls;
  if (config.tls_certificate_file.empty() != config.tls_private_key_file.empty()) {
    return core::makeError(core::ErrorCode::kInvalidArgument,
                           "TLS needs both a certificate (--tls-cert) and its private key (--tls-key)");
  }
  if (!config.tls_certificate_file.empty()) {
    auto loaded = TlsContext::load(config.tls_certificate_file, config.tls_private_key_file);
    if (!loaded) return loaded.error();
    tls = std::move(*loaded);
  }
  auto store = MetadataStore::open(config.store.empty() ? (config.data_dir / "rigport.sqlite").string() : config.store);
  if (!store) return store.error();
  return std::unique_ptr<Service>(
      new Service(config, std::move(keys), std::move(*proxies), std::move(*store), std::move(tls), JsonLog(std::move(logger))));
}

namespace {

HttpLimits httpLimits(const ServerConfig& config) {
  HttpLimits limits;
  limits.threads = config.http_threads;
  limits.keep_alive_max_count = config.keep_alive_max_count;
  limits.read_timeout_s = config.read_timeout_s;
  limits.write_timeout_s = config.write_timeout_s;
  limits.request_time_s = config.request_time_limit_s;
  limits.upload_time_s = config.upload_time_limit_s;
  limits.gate.head_timeout_s = config.head_timeout_s;
  limits.gate.keep_alive_idle_s = config.keep_alive_timeout_s;
  limits.gate.max_waiting = config.max_waiting_connections;
  limits.gate.max_waiting_per_client = config.max_waiting_per_client;
  return limits;
}

}  // namespace

Service::Service(const ServerConfig& config, ApiKeys keys, TrustedProxies proxies, std::unique_ptr<MetadataStore> store,
                 std::shared_ptr<const TlsContext> tls, JsonLog log)
    : config_(config),
      keys_(std::move(keys)),
      proxies_(std::move(proxies)),
      log_(std::move(log)),
      store_(std::move(store)),
      blobs_(config.blob_dir.empty() ? config.data_dir / "blobs" : config.blob_dir),
      caches_(config.cache_bytes),
      storage_(*store_, blobs_, config_, log_),
      jobs_(*store_, blobs_, blob_collection_, storage_, caches_, metrics_, config_, log_),
      retention_(*store_, blobs_, blob_collection_, metrics_, config_, log_),
      auth_failures_(config.max_auth_failures_per_minute),
      uploads_(config.max_concurrent_uploads, config.max_uploads_per_tenant, config.max_uploads_per_client),
      routes_{config_, keys_, *store_, blobs_, caches_, jobs_, metrics_, log_, ready_, proxies_, auth_failures_, uploads_, blob_collection_, storage_},
      http_(httpLimits(config), std::move(tls),
            [this](const std::string& event, const std::string& client, const std::string& detail) {
              log_.info(event, {{"client", client}, {"detail", detail}});
            }) {
  // Other replicas may be writing into a shared blob directory: only their
  // leftovers (no write takes an hour) are removed then.
  blobs_.removeTemporaries(store_->shared() ? std::chrono::hours(1) : std::chrono::seconds(0));
  store_->setErrorReporter([this](const std::string& message) { log_.error("store_error", {{"detail", message}}); });
  http_.set_payload_max_length(config_.max_body_bytes);
  registerRoutes(http_, routes_);
}

Service::~Service() { stop(0.0); }

core::Result<int> Service::start() {
  storage_.probe();  // a read-only or full data dir is red from the start: no job runs
  jobs_.start();
  port_ = std::max(0, http_.bindListener(config_.host, config_.port, config_.listen_backlog));
  if (port_ <= 0) {
    return core::makeError(core::ErrorCode::kIo, "cannot listen on " + config_.host + ":" + std::to_string(config_.port));
  }
  ready_ = true;
  storage_.start();
  retention_.start();
  log_.info("listening", {{"host", config_.host}, {"port", port_}, {"tls", !config_.tls_certificate_file.empty()},
                          {"auth", keys_.enabled()},
                          {"data_dir", config_.data_dir.string()}, {"keep_jobs_days", config_.keep_jobs_days}});
  return port_;
}

void Service::serve() {
  serving_ = true;
  if (!stopped_) http_.listen_after_bind();  // a stop() that came first would not reach a listener not yet running
  serving_ = false;
}

void Service::stop(double grace_s) {
  if (stopped_.exchange(true)) return;
  ready_ = false;
  // httplib's stop() only reaches a listener already running: repeated until
  // serve() has returned (or, entered after this, sees stopped_ and returns).
  http_.stop();
  while (serving_) {
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
    http_.stop();
  }
  retention_.stop();
  storage_.stop();
  const bool finished = jobs_.stop(grace_s);  // also wakes long-polls
  http_.drain();  // waiting connections closed, requests in service finished
  log_.info("stopped", {{"running_jobs_finished", finished}});
}

}  // namespace server
