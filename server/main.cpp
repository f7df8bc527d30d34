// rigport-server: wiring only. Configuration from the command line, logger,
// service, signals.
#include <sys/resource.h>

#include <algorithm>
#include <csignal>
#include <cstdlib>
#include <thread>

#include <CLI/CLI.hpp>

#include "server/service.h"

namespace {

volatile std::sig_atomic_t g_stop_signal = 0;
void onSignal(int signal) { g_stop_signal = signal; }

}  // namespace

int main(int argc, char** argv) {
  server::ServerConfig config;
  CLI::App app{"rigport-server: the rig transfer service (REST under /v1)"};
  std::string listen = "127.0.0.1:8080";
  double cache_mb = static_cast<double>(config.cache_bytes >> 20);
  double max_body_mb = static_cast<double>(config.max_body_bytes >> 20);
  bool no_auth = false;
  app.add_option("--listen", listen, "host:port to listen on (port 0 = any free port)")->capture_default_str();
  app.add_option("--data-dir", config.data_dir, "Store directory (SQLite + blobs)")->required();
  app.add_option("--store", config.store,
                 "Metadata store: a postgresql://user@host:port/db URL (replicas sharing one database); "
                 "default: the embedded SQLite file in --data-dir");
  app.add_option("--blob-dir", config.blob_dir,
                 "Blob directory (default <data-dir>/blobs); replicas on one --store share one, on a volume all mount");
  app.add_option("--tls-cert", config.tls_certificate_file, "Serve HTTPS: certificate chain (PEM), with --tls-key")
      ->check(CLI::ExistingFile);
  app.add_option("--tls-key", config.tls_private_key_file, "Private key (PEM) of --tls-cert")->check(CLI::ExistingFile);
  app.add_flag("--public-metrics", config.public_metrics, "Serve /metrics without an API key");
  app.add_option("--max-auth-failures-per-minute", config.max_auth_failures_per_minute,
                 "Failed authentications a client address may make per minute before it is refused for a minute (0 = no limit)")
      ->check(CLI::NonNegativeNumber)->capture_default_str();
  app.add_option("--trusted-proxy", config.trusted_proxies,
                 "A load balancer (address or CIDR block) whose X-Forwarded-For names the client address for the "
                 "per-client limits and the log; repeat it or separate by commas")
      ->delimiter(',');
  app.add_option("--max-uploads-per-tenant", config.max_uploads_per_tenant, "Uploads one tenant may send at once")
      ->check(CLI::PositiveNumber)->capture_default_str();
  app.add_option("--max-uploads-per-client", config.max_uploads_per_client, "Uploads one client address may send at once")
      ->check(CLI::PositiveNumber)->capture_default_str();
  app.add_option("--workers", config.workers, "Job worker threads (0 = hardware threads)")->check(CLI::NonNegativeNumber);
  app.add_option("--cache-mb", cache_mb, "Prepared-rig cache bound, MiB")->check(CLI::PositiveNumber)->capture_default_str();
  app.add_option("--api-keys", config.api_keys_file, "API key file: '<key> <tenant>' per line (also RIGPORT_API_KEYS)")
      ->check(CLI::ExistingFile);
  app.add_flag("--no-auth", no_auth, "No API keys: every request is one local tenant");
  app.add_option("--queue-capacity", config.queue_capacity, "Queued jobs before 429")->check(CLI::PositiveNumber)->capture_default_str();
  app.add_option("--lease-s", config.lease_s,
                 "Seconds a worker's claim on a job lasts unrenewed: a replica that dies leaves its jobs to be requeued "
                 "this long after its last heartbeat")
      ->check(CLI::Range(0.1, 3600.0))
      ->capture_default_str();
  app.add_option("--replica-id", config.replica_id, "Name of this replica's leases (default host:pid:random)");
  app.add_option("--job-time-limit", config.job_time_limit_s, "Seconds a job may run")->check(CLI::PositiveNumber)->capture_default_str();
  app.add_option("--listen-backlog", config.listen_backlog, "New connections the kernel queues until accepted")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--http-threads", config.http_threads, "HTTP connection threads")->check(CLI::PositiveNumber)->capture_default_str();
  app.add_option("--max-body-mb", max_body_mb, "Largest request body, MiB")->check(CLI::PositiveNumber)->capture_default_str();
  app.add_option("--max-vertices", config.max_vertices, "Largest mesh, vertices")->check(CLI::PositiveNumber)->capture_default_str();
  app.add_option("--keep-jobs-days", config.keep_jobs_days,
                 "Finished jobs (results, inputs) are deleted this many days after they finished (0 = keep until deleted)")
      ->check(CLI::NonNegativeNumber)->capture_default_str();
  app.add_option("--shutdown-grace", config.shutdown_grace_s, "SIGTERM: seconds running jobs get to finish")->capture_default_str();
  CLI11_PARSE(app, argc, argv);

  const auto colon = listen.rfind(':');
  if (colon == std::string::npos) {
    std::fprintf(stderr, "--listen: expected host:port, got '%s'\n", listen.c_str());
    return 2;
  }
  config.host = listen.substr(0, colon);
  config.port = std::atoi(listen.c_str() + colon + 1);
  config.cache_bytes = static_cast<std::size_t>(cache_mb * 1024 * 1024);
  config.max_body_bytes = static_cast<std::size_t>(max_body_mb * 1024 * 1024);

  auto logger = server::makeJsonStderrLogger("rigport-server");
  server::JsonLog log(logger);
  const char* env_keys = std::getenv("RIGPORT_API_KEYS");
  server::ApiKeys keys = server::ApiKeys::disabled();
  if (!no_auth) {
    auto loaded = server::ApiKeys::load(config.api_keys_file, env_keys ? env_keys : "");
    if (!loaded) {
      log.error("config_error", {{"detail", loaded.error().message}});
      return 2;
    }
    keys = std::move(*loaded);
  }

  // Connections waiting at the gate hold a descriptor each; the usual soft
  // limit (1024) is below what the gate is sized for.
  if (rlimit files{}; getrlimit(RLIMIT_NOFILE, &files) == 0 && files.rlim_cur < files.rlim_max) {
    files.rlim_cur = std::min<rlim_t>(files.rlim_max, 65536);
    setrlimit(RLIMIT_NOFILE, &files);
  }
  auto service = server::Service::create(config, std::move(keys), logger);
  if (!service) {
    log.error("startup_failed", {{"detail", service.error().message}});
    return 1;
  }
  auto port = (*service)->start();
  if (!port) {
    log.error("startup_failed", {{"detail", port.error().message}});
    return 1;
  }
  // The first stdout line tells scripts and tests the bound port.
  std::printf("listening on %s://%s:%d\n", config.tls_certificate_file.empty() ? "http" : "https", config.host.c_str(),
              *port);
  std::fflush(stdout);

  std::signal(SIGTERM, onSignal);
  std::signal(SIGINT, onSignal);
  std::thread http([&] { (*service)->serve(); });
  while (g_stop_signal == 0) std::this_thread::sleep_for(std::chrono::milliseconds(50));
  log.info("shutdown_requested", {{"signal", static_cast<int>(g_stop_signal)}, {"grace_s", config.shutdown_grace_s}});
  (*service)->stop(config.shutdown_grace_s);
  http.join();
  return 0;
}
