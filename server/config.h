// Server configuration: every limit in one place, with its default and unit.
// Filled by server/main.cpp from the command line; tests build it directly.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace server {

struct ServerConfig {
  std::string host = "127.0.0.1";
  int port = 8080;                       // 0 = any free port (tests)
  std::filesystem::path data_dir = "rigport-data";  // SQLite file, blobs, upload spool
  // Where the metadata lives: empty = the embedded SQLite file in data_dir; a
  // postgresql:// URL = a database replicas share (server/store.h).
  std::string store;
  // Blobs (rigs, inputs, results): empty = data_dir/blobs. Replicas share one
  // directory on a volume every replica mounts (docs/SCALE_OUT.md says what
  // the volume must guarantee).
  std::filesystem::path blob_dir;
  int workers = 0;                       // job worker threads; 0 = hardware threads
  int threads_per_job = 1;               // core threads inside one job (parallelism is across jobs)
  std::size_t cache_bytes = 512ull << 20;  // prepared rigs (3/4) + marker distances (1/4), bytes
  std::filesystem::path api_keys_file;   // "key tenant" per line; empty + no env = auth off
  bool auth = true;                      // false: every request is tenant "" (local use, demo)
  bool public_metrics = false;           // /metrics without a key (with auth on, it needs one)
  // HTTPS: both PEM files given (certificate chain, then its private key),
  // or neither (plain HTTP, for loopback or behind a TLS proxy).
  std::filesystem::path tls_certificate_file;
  std::filesystem::path tls_private_key_file;

  // HTTP (server/http_server.h, server/connection_gate.h): a connection
  // takes a thread only once its request head is in; a request's time on a
  // thread is bounded as a whole. Threads are kept in reserve for probes and
  // small reads: uploads and long-polls together may hold at most
  // http_threads - 4 of them (checked at start).
  int http_threads = 32;
  int keep_alive_max_count = 100;        // requests per connection
  int keep_alive_timeout_s = 2;          // idle keep-alive connection closed after this
  int read_timeout_s = 30;               // one stalled read or write
  int write_timeout_s = 30;
  double head_timeout_s = 10.0;          // a request head must arrive whole within this (else 408)
  double request_time_limit_s = 120.0;   // a request on a thread: body, handler and response
  double upload_time_limit_s = 600.0;    // the same for uploads (POST /v1/rigs, /v1/jobs)
  int listen_backlog = 1024;             // new connections the kernel holds until accepted
  int max_waiting_connections = 4096;    // connections waiting for their request head
  int max_waiting_per_client = 64;       // ... from one client address (its oldest is closed beyond)

  // Limits
  std::size_t max_body_bytes = 256ull << 20;   // one request body
  std::uint64_t max_document_part_bytes = 16ull << 20;  // one JSON part (spec, landmarks, markers, options, components)
  std::int64_t max_vertices = 2'000'000;       // per mesh
  int max_landmarks = 10'000;
  int max_concurrent_uploads = 12;             // multipart bodies being received (and checked) at once
  int max_uploads_per_tenant = 8;              // ... of one tenant (a busy pipeline overlaps its uploads)
  int max_uploads_per_client = 10;             // ... from one client address
  int max_auth_failures_per_minute = 120;      // per client address, then 429 for a minute (0 = no limit)
  // Load balancers whose X-Forwarded-For names the client (addresses or CIDR
  // blocks; server/client_address.h): the per-client limits and the access
  // log then see the client behind them.
  std::vector<std::string> trusted_proxies;
  int max_concurrent_waits = 8;                // long-polls (GET /v1/jobs/{id}?wait_ms) waiting at once
  int queue_capacity = 256;                    // queued jobs; beyond -> 429
  int retry_after_s = 1;                       // Retry-After of a 429
  double job_time_limit_s = 300.0;             // a running job is stopped at its next stage after this
  // The job queue (server/jobs.h): a worker's claim on a job is a lease this
  // long, renewed by a heartbeat (a third of it, at most every second); a
  // replica that dies leaves its jobs to be requeued when their leases end.
  // Idle workers look for queued jobs every poll_s (jobs submitted here, or
  // requeued, wake them at once).
  double lease_s = 30.0;
  double poll_s = 0.5;
  std::string replica_id;                      // names this process's leases; empty = host:pid:random
  double shutdown_grace_s = 30.0;              // SIGTERM: running jobs get this long to finish

  // Retention: finished jobs (and the blobs only they used) are deleted this
  // long after they finished; 0 keeps them until DELETE /v1/jobs/{id}.
  double keep_jobs_days = 30.0;
  double retention_sweep_s = 600.0;            // how often expired jobs are looked for

  // Storage health (server/storage_health.h): how often the data directory is
  // probed for writes while it takes them, and while it does not.
  double storage_probe_s = 10.0;
  double storage_retry_s = 1.0;
  int storage_retries_per_job = 5;             // a job whose own data keeps failing (a corrupted blob) then fails
};

}  // namespace server
