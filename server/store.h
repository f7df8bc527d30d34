// The durable store: metadata in SQLite (WAL, synchronous=FULL; the default)
// or PostgreSQL (replicas), blobs as content-addressed files. A blob is written to a
// temporary name, fsynced, renamed to its sha256 and the directory fsynced, so
// a crash leaves either no blob or a whole one; rows reference blobs only after
// the blob is durable. Thread-safe.
#pragma once

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "api/types.h"
#include "core/base/error.h"

namespace server {

// Content-addressed files under <root>/<2 hex>/<64 hex>.
class BlobStore {
 public:
  explicit BlobStore(std::filesystem::path root);
  // Writes bytes (temp + fsync + rename + dir fsync); returns the sha256 hex.
  // Idempotent: an existing blob is not rewritten.
  core::Result<std::string> put(std::span<const std::uint8_t> bytes);
  // Moves a fully written file (e.g. a streamed upload on the same filesystem)
  // into the store under its hash; the source file is consumed.
  core::Result<std::string> adopt(const std::filesystem::path& file);
  bool contains(const std::string& hash) const;
  std::filesystem::path pathOf(const std::string& hash) const;   // may not exist
  // Reads and verifies the hash (a corrupted blob is an error, never served).
  core::Result<std::vector<std::uint8_t>> read(const std::string& hash) const;
  void remove(const std::string& hash);
  // Writes, fsyncs and removes a 64 KiB file where blobs are written: whether
  // the blob storage takes writes now (StorageHealth).
  core::Status probeWrite();
  // Removes leftover temporary files (from a crash mid-write) last modified
  // at least `older_than` ago. With 0, call it at startup before any
  // put()/adopt(): it also deletes the temporary file of a put() in flight,
  // which would then fail.
  void removeTemporaries(std::chrono::seconds older_than);
  const std::filesystem::path& root() const { return root_; }

 private:
  std::filesystem::path root_;
};

// `bytes` bytes from OpenSSL's CSPRNG as lower-case hex (job ids); nullopt
// when it cannot deliver.
std::optional<std::string> secureRandomHex(std::size_t bytes);

// sha256 of a file, streamed, lower-case hex (bytes in memory: api::sha256Hex).
core::Result<std::string> sha256HexOfFile(const std::filesystem::path& file);

struct RigRecord {
  std::string tenant;
  api::RigInfo info;                 // info.id is the content hash
  std::string rig_blob;              // blob hashes
  std::string landmarks_blob;
  std::string components_blob;       // empty when none
};

struct JobRecord {
  std::string tenant;
  std::string id;                    // random 32 hex, unique over all tenants
  api::JobKind kind = api::JobKind::kTransfer;
  std::string rig;                   // rig id (may be empty for kinds without a rig)
  std::string spec_json;             // the submitted spec, as normalised JSON
  std::map<std::string, std::string> inputs;  // multipart field -> blob hash (target, target_landmarks, ...)
  std::map<std::string, std::string> input_names;  // multipart field -> uploaded file name
  std::string idempotency_key;       // empty when none
  api::JobStatus status = api::JobStatus::kQueued;
  std::string stage = "queued";
  int attempts = 0;
  bool cache_hit = false;
  std::string error_json;            // problem details JSON when failed/cancelled
  std::string result_blob;           // GLB, when succeeded
  std::string diagnostics_blob;      // diagnostics JSON, when succeeded
  std::string components_blob;       // the result's rig components JSON, when succeeded with one
  std::string timings_json;          // {"stage": ms}, when finished
  std::int64_t created_ms = 0, started_ms = 0, finished_ms = 0;  // unix epoch milliseconds
  std::int64_t sequence = 0;         // insertion order (set by the store), the list cursor
  // The queue's lease on a running job (claimNextJob): who runs it, until
  // when (epoch ms, the store's clock), whether a cancel was asked, and its
  // progress at the owner's last heartbeat (what other replicas serve).
  std::string lease_owner;
  std::int64_t lease_expires_ms = 0;
  bool cancel_requested = false;
  double progress = 0.0;
};

// markFinished and requeue without a fence.
inline constexpr int kAnyAttempt = -1;

// A worker's heartbeat for one running job it claimed: the fencing token
// (the attempt it claimed) and where it is.
struct LeaseRenewal {
  std::string id;
  int attempt = 0;
  std::string stage;
  double progress = 0.0;
};
enum class LeaseState { kHeld, kCancelRequested, kLost };

// What admitJob did with a job.
struct JobAdmission {
  JobRecord job;            // as stored, or the job its idempotency key already names
  bool inserted = false;    // false: that existing job, or the queue was full
  bool queue_full = false;  // refused: nothing stored
};

struct JobListQuery {
  std::string tenant;
  std::optional<api::JobStatus> status;
  std::int64_t after_sequence = 0;   // cursor: jobs with a larger sequence
  int limit = 50;
};

// Rigs, jobs and their inputs: the metadata half of the store. Two
// implementations, chosen at start by where the metadata lives (open): the
// embedded SQLite database (one machine, the default) and PostgreSQL
// (replicas sharing one database). Both keep the same contract, below, and
// run the same tests (tests/server/metadata_store_test.cpp). Thread-safe.
class MetadataStore {
 public:
  // `location`: a postgresql:// (or postgres://) connection URL, else a file
  // for the embedded store (created with its directory when absent).
  //
  // SQLite: WAL, synchronous=FULL, foreign keys, schema version checked;
  // errors name the file. PostgreSQL: one connection, re-established after
  // the server went away; errors name the host and database, never the
  // password. Either way a store of an older schema is upgraded in place, in
  // one transaction (PostgreSQL: under an advisory lock, so replicas starting
  // together do not race; schema 1 -> 2: rigs gain their region labels,
  // unknown for the rigs already stored; 2 -> 3: the storage probe's row;
  // 3 -> 4: fit jobs; 4 -> 5: jobs' components results); a newer one is refused.
  static core::Result<std::unique_ptr<MetadataStore>> open(const std::string& location);
  static core::Result<std::unique_ptr<MetadataStore>> open(const std::filesystem::path& file) {
    return open(file.string());
  }
  virtual ~MetadataStore() = default;
  // Where the read functions (which return empty results on a database error)
  // report the error: the server passes its structured log. Default: dropped.
  void setErrorReporter(std::function<void(const std::string&)> report);
  // "sqlite" or "postgresql" (logs, /metrics).
  virtual const char* backend() const = 0;

  // Reads (getRig, listRigs, getJob, listJobs, unfinishedJobs, countJobsByStatus)
  // pass a database failure to the error reporter and answer empty. Tenant "" is an ordinary tenant.

  // Inserts or, when (tenant, id) exists, returns the existing record and false.
  // An empty info.created_at is set to now (RFC 3339 UTC, milliseconds:
  // "2026-01-31T12:34:56.789Z"); listRigs orders by created_at, then id.
  virtual core::Result<std::pair<RigRecord, bool>> insertRig(const RigRecord& rig) = 0;
  virtual std::optional<RigRecord> getRig(const std::string& tenant, const std::string& id) = 0;
  virtual std::vector<RigRecord> listRigs(const std::string& tenant) = 0;
  virtual bool deleteRig(const std::string& tenant, const std::string& id) = 0;  // false when absent

  // Inserts a queued job. When idempotency_key is set and (tenant, key) exists,
  // returns that job, not inserted, instead. With queue_capacity > 0 a new
  // job is refused (queue_full, nothing stored) when that many jobs, of all
  // tenants, are queued: counted and inserted in one transaction that every
  // process on the store serialises (PostgreSQL: an advisory transaction
  // lock), so replicas admitting at once never overshoot it.
  // The record is stored as given, except created_ms 0 = now; the returned
  // record carries the assigned sequence. A duplicate id is kInvalidArgument.
  virtual core::Result<JobAdmission> admitJob(const JobRecord& job, std::int64_t queue_capacity) = 0;
  // admitJob without a capacity: the job and whether it was inserted.
  core::Result<std::pair<JobRecord, bool>> insertJob(const JobRecord& job) {
    auto admitted = admitJob(job, 0);
    if (!admitted) return admitted.error();
    return std::pair{std::move(admitted->job), admitted->inserted};
  }
  virtual std::optional<JobRecord> getJob(const std::string& tenant, const std::string& id) = 0;
  virtual std::vector<JobRecord> listJobs(const JobListQuery& query) = 0;
  // Queued or running jobs, oldest first (recovery after a restart).
  virtual std::vector<JobRecord> unfinishedJobs() = 0;
  // Transitions (durable). markRunning increments attempts.
  // Each is one durable transaction, guarded by the current status; a refused
  // transition (unknown job, or wrong status) is an Error kInvalidArgument and
  // changes nothing:
  //   markRunning:  queued -> running only (a job cancelled while queued is not started).
  //   markFinished: queued|running -> a final status only; a final job is never
  //                 overwritten (a late success cannot replace a cancel). job.status must be
  //                 final; an empty job.stage keeps the stored stage; finished_ms 0 = now.
  //   requeue:      running|queued -> queued (a final job is refused).
  //   With `attempt` >= 0 (not kAnyAttempt), markFinished and requeue are fenced: refused unless
  //   the job is still at that attempt (a worker whose lease expired and whose
  //   job was claimed again cannot overwrite the new owner's result).
  virtual core::Status markRunning(const std::string& id, std::int64_t started_ms, bool cache_hit) = 0;
  // status, stage, error_json, result/diagnostics/components blobs, timings, cache_hit, finished_ms
  virtual core::Status markFinished(const JobRecord& job, int attempt) = 0;
  core::Status markFinished(const JobRecord& job) { return markFinished(job, kAnyAttempt); }
  virtual core::Status requeue(const std::string& id, int attempt) = 0;  // running -> queued (lease clears)
  core::Status requeue(const std::string& id) { return requeue(id, kAnyAttempt); }

  // The job queue (server/jobs.h), shared by every process on the store.
  // claimNextJob: the oldest queued job becomes running for `owner` (attempts
  // + 1: its fencing token; started_ms now) under a lease of `lease_ms` by
  // the store's clock; nullopt when none is queued. Claims never collide
  // (PostgreSQL: FOR UPDATE SKIP LOCKED).
  virtual core::Result<std::optional<JobRecord>> claimNextJob(const std::string& owner, std::int64_t lease_ms) = 0;
  // The owner's heartbeat: extends each lease it still holds and records the
  // job's stage and progress; answers per renewal, in order, held (and
  // whether a cancel was asked) or lost (expired and requeued, claimed again,
  // or finished by a cancel).
  virtual core::Result<std::vector<LeaseState>> renewLeases(const std::string& owner,
                                                            const std::vector<LeaseRenewal>& renewals,
                                                            std::int64_t lease_ms) = 0;
  // Running jobs whose lease has ended go back to queued (their owner died or
  // lost the store); returns their ids.
  virtual core::Result<std::vector<std::string>> requeueExpiredLeases() = 0;
  // Asks a running job's owner to stop it (it sees the flag at its next
  // heartbeat); refused (kInvalidArgument) unless the job is running.
  virtual core::Status requestCancel(const std::string& id) = 0;
  // Queued jobs, all tenants (admission and /metrics).
  virtual core::Result<std::int64_t> queuedJobs() = 0;
  // The store's half of the blob-collection lock (server/blob_collection.h),
  // across processes sharing the store: held shared by writers, exclusive by
  // the collector, waiting up to seconds for the other side. The embedded
  // store has one process: nothing to do.
  virtual core::Status lockBlobCollection(bool exclusive) = 0;
  virtual void unlockBlobCollection(bool exclusive) = 0;
  // Waits up to `timeout` for a job queued by any process on the store
  // (PostgreSQL: LISTEN/NOTIFY on a session of its own); true when one was
  // announced. Only a hint to wake idle workers sooner: workers poll anyway.
  // The embedded store announces nothing (its one process wakes its own
  // workers): false at once.
  virtual core::Result<bool> waitForQueuedJobs(std::chrono::milliseconds timeout) = 0;
  // Whether other processes may share this store (PostgreSQL). The embedded
  // store has one process, which at start requeues every running job at
  // once; on a shared store running jobs are left to their leases.
  virtual bool shared() const = 0;
  // Deletes a final job of the tenant (its input rows go with it); false when
  // the tenant has no such job or it is still queued or running. Its blobs are
  // the caller's to collect (blobReferenced), under the collection lock.
  virtual core::Result<bool> deleteFinishedJob(const std::string& tenant, const std::string& id) = 0;
  // (tenant, id) of final jobs that finished before `finished_before_ms`,
  // oldest first, at most `limit` (the retention sweep).
  virtual std::vector<std::pair<std::string, std::string>> finishedJobsBefore(std::int64_t finished_before_ms,
                                                                              int limit) = 0;
  virtual std::map<api::JobStatus, std::int64_t> countJobsByStatus() = 0;
  // One durable write transaction: whether the database takes writes now
  // (StorageHealth).
  virtual core::Status probeWrite() = 0;
  // Blob hashes referenced by any rig or job row (for garbage collection).
  // Answers true when the database cannot be read (never lets GC delete blindly).
  virtual bool blobReferenced(const std::string& hash) = 0;

 protected:
  // The value of a read, or `fallback` with the error passed to the reporter.
  template <typename T>
  T valueOr(core::Result<T> result, T fallback) {
    if (result) return std::move(*result);
    std::function<void(const std::string&)> report;
    {
      std::lock_guard lock(reporter_mutex_);
      report = report_error_;
    }
    if (report) report(result.error().message);
    return fallback;
  }

 private:
  std::mutex reporter_mutex_;
  std::function<void(const std::string&)> report_error_;
};

}  // namespace server
