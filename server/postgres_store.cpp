// The PostgreSQL metadata store (server/store.h): the same rigs, jobs and
// inputs as the embedded store, in a database every replica shares.
//
// One libpq connection behind a mutex, re-established (PQreset) before a call
// when the server went away, so a restarted PostgreSQL is picked up again
// without restarting the replica; meanwhile calls fail (probeWrite: the
// replica reports not ready). Every value is a bound parameter (text format).
// Commits are durable: PostgreSQL's default synchronous_commit flushes the WAL
// before COMMIT returns. The schema (the embedded store's, store_sql.h, in
// PostgreSQL's dialect) is created or upgraded at start inside one
// transaction holding an advisory lock, so replicas starting together do not
// race.
#include <libpq-fe.h>
#include <poll.h>

#include <cerrno>

#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "server/store_sql.h"

namespace server {

using core::Error;
using core::ErrorCode;
using core::makeError;
using namespace store_sql;

namespace {

// pg_advisory_xact_lock key of schema creation and upgrades ("rigport" in ASCII).
constexpr long long kSchemaLockKey = 0x72696770'6f7274LL;


// The channel a job queued (inserted or requeued) is announced on: a
// wake-up hint for other replicas' idle workers, who also poll.
constexpr const char* kListenSql = "LISTEN rigport_jobs_queued";
constexpr const char* kNotifySql = "SELECT pg_notify('rigport_jobs_queued', '')";

// pg_advisory_xact_lock key of job admission against the queue capacity ("rigqueue").
constexpr long long kQueueAdmissionLockKey = 0x72696771'75657565LL;

// Session advisory lock key of the blob collection ("rigblob").
constexpr long long kBlobCollectionLockKey = 0x72696762'6c6f62LL;

// The database's clock in epoch ms: leases are granted and expired by one
// clock, whatever the replicas' clocks say.
constexpr const char* kDatabaseNowMs = "(EXTRACT(EPOCH FROM clock_timestamp()) * 1000)::BIGINT";

// store_sql.h's ?N placeholders as PostgreSQL's $N.
std::string dollarParams(std::string sql) {
  for (std::size_t i = 0; i + 1 < sql.size(); ++i) {
    if (sql[i] == '?' && std::isdigit(static_cast<unsigned char>(sql[i + 1]))) sql[i] = '$';
  }
  return sql;
}

// SQLSTATE of a unique_violation.
constexpr const char* kUniqueViolation = "23505";

// A query's result, cleared on scope exit.
class PgResult {
 public:
  explicit PgResult(PGresult* result) : result_(result, &PQclear) {}
  int rows() const { return PQntuples(result_.get()); }
  // Rows an INSERT/UPDATE/DELETE changed.
  long long affected() const { return std::atoll(PQcmdTuples(result_.get())); }
  const PGresult* get() const { return result_.get(); }

 private:
  std::unique_ptr<PGresult, void (*)(PGresult*)> result_;
};

// One row of a result, read as store_sql.h's readers expect.
struct PgRow {
  const PGresult* result;
  int row;
  std::string text(int col) const {
    return std::string(PQgetvalue(result, row, col), static_cast<std::size_t>(PQgetlength(result, row, col)));
  }
  std::int64_t int64(int col) const { return std::strtoll(PQgetvalue(result, row, col), nullptr, 10); }
  int int32(int col) const { return static_cast<int>(int64(col)); }
};

// A query parameter: text, or NULL.
using Param = std::optional<std::string>;

// The connection. All access is under PostgresMetadataStore::mutex_.
class PgConnection {
 public:
  PgConnection(std::string url, std::string label) : url_(std::move(url)), label_(std::move(label)) {}
  PgConnection(const PgConnection&) = delete;
  PgConnection& operator=(const PgConnection&) = delete;
  ~PgConnection() {
    if (conn_) PQfinish(conn_);
  }

  // Connected now, connecting again when the server went away.
  core::Status ensure() {
    if (conn_ && PQstatus(conn_) == CONNECTION_OK) return core::Ok{};
    if (conn_) {
      PQreset(conn_);
    } else {
      conn_ = PQconnectdb(url_.c_str());
      // Server notices ("relation ... already exists, skipping" from the
      // schema's IF NOT EXISTS) are not the service's log lines: dropped,
      // not printed raw on stderr. Errors come back with their results.
      if (conn_) PQsetNoticeProcessor(conn_, [](void*, const char*) {}, nullptr);
    }
    if (!conn_ || PQstatus(conn_) != CONNECTION_OK) {
      return makeError(ErrorCode::kIo, "database " + label_ + ": cannot connect: " + message());
    }
    return core::Ok{};
  }

  // Runs one statement; a result other than `expected` is an error naming `what`.
  core::Result<PgResult> exec(const char* sql, const std::vector<Param>& params, const std::string& what,
                              ExecStatusType expected = PGRES_TUPLES_OK) {
    if (auto ok = ensure(); !ok) return ok.error();
    std::vector<const char*> values;
    values.reserve(params.size());
    for (const Param& p : params) values.push_back(p ? p->c_str() : nullptr);
    PgResult result(PQexecParams(conn_, sql, static_cast<int>(values.size()), nullptr, values.data(), nullptr,
                                 nullptr, /*text results*/ 0));
    if (PQresultStatus(result.get()) != expected) {
      const char* state = PQresultErrorField(result.get(), PG_DIAG_SQLSTATE);
      last_sqlstate_ = state ? state : "";
      return makeError(ErrorCode::kIo, "database " + label_ + ": " + what + ": " + message());
    }
    last_sqlstate_.clear();
    return result;
  }
  core::Result<PgResult> command(const char* sql, const std::vector<Param>& params, const std::string& what) {
    return exec(sql, params, what, PGRES_COMMAND_OK);
  }

  // Several statements without parameters (the schema): the simple protocol.
  core::Status script(const char* sql, const std::string& what) {
    if (auto ok = ensure(); !ok) return ok.error();
    PgResult result(PQexec(conn_, sql));
    if (PQresultStatus(result.get()) != PGRES_COMMAND_OK) {
      return makeError(ErrorCode::kIo, "database " + label_ + ": " + what + ": " + message());
    }
    return core::Ok{};
  }

  const std::string& lastSqlState() const { return last_sqlstate_; }
  const std::string& label() const { return label_; }
  const std::string& url() const { return url_; }
  bool connected() const { return conn_ && PQstatus(conn_) == CONNECTION_OK; }

  // On a LISTENing connection: waits up to `timeout` for notifications;
  // true when at least one came (all pending are consumed).
  core::Result<bool> awaitNotification(std::chrono::milliseconds timeout) {
    const auto drain = [this] {
      bool any = false;
      while (PGnotify* n = PQnotifies(conn_)) {
        any = true;
        PQfreemem(n);
      }
      return any;
    };
    const auto lost = [this] { return makeError(ErrorCode::kIo, "database " + label_ + ": listening: " + message()); };
    if (!connected() || PQconsumeInput(conn_) == 0) return lost();
    if (drain()) return true;
    pollfd fd{PQsocket(conn_), POLLIN, 0};
    const int ready = ::poll(&fd, 1, static_cast<int>(timeout.count()));
    if (ready < 0 && errno != EINTR) return makeError(ErrorCode::kIo, "database " + label_ + ": poll failed");
    if (ready > 0 && PQconsumeInput(conn_) == 0) return lost();
    return drain();
  }

 private:
  std::string message() const {
    std::string text = conn_ ? PQerrorMessage(conn_) : "out of memory";
    while (!text.empty() && (text.back() == '\n' || text.back() == ' ')) text.pop_back();
    return text;
  }

  std::string url_;
  std::string label_;  // host:port/database, never the password
  PGconn* conn_ = nullptr;
  std::string last_sqlstate_;
};

// BEGIN ... COMMIT; rolls back unless commit() succeeded.
class PgTransaction {
 public:
  explicit PgTransaction(PgConnection& c) : c_(c) {}
  ~PgTransaction() {
    if (active_) (void)c_.command("ROLLBACK", {}, "rollback");
  }
  PgTransaction(const PgTransaction&) = delete;
  PgTransaction& operator=(const PgTransaction&) = delete;
  core::Status begin() {
    auto r = c_.command("BEGIN", {}, "begin");
    if (!r) return r.error();
    active_ = true;
    return core::Ok{};
  }
  core::Status commit() {
    auto r = c_.command("COMMIT", {}, "commit");
    if (!r) return r.error();
    active_ = false;
    return core::Ok{};
  }
  void rollback() {
    if (active_) (void)c_.command("ROLLBACK", {}, "rollback");
    active_ = false;
  }

 private:
  PgConnection& c_;
  bool active_ = false;
};

// "host:port/database" of a connection URL, for messages (no user, no password).
std::string describeUrl(const std::string& url) {
  char* error = nullptr;
  PQconninfoOption* options = PQconninfoParse(url.c_str(), &error);
  if (!options) {
    std::string why = error ? error : "cannot parse";
    if (error) PQfreemem(error);
    while (!why.empty() && why.back() == '\n') why.pop_back();
    return "(unparsable URL: " + why + ")";
  }
  std::string host = "localhost", port = "5432", db;
  for (PQconninfoOption* o = options; o->keyword; ++o) {
    if (!o->val) continue;
    const std::string key = o->keyword;
    if (key == "host" || key == "hostaddr") host = o->val;
    if (key == "port") port = o->val;
    if (key == "dbname") db = o->val;
  }
  PQconninfoFree(options);
  return host + ":" + port + "/" + db;
}

template <typename Row, typename Read>
std::vector<Row> readRows(const PgResult& result, Read read) {
  std::vector<Row> out;
  out.reserve(static_cast<std::size_t>(result.rows()));
  for (int r = 0; r < result.rows(); ++r) out.push_back(read(PgRow{result.get(), r}));
  return out;
}

std::string p(std::int64_t v) { return std::to_string(v); }

class PostgresMetadataStore final : public MetadataStore {
 public:
  explicit PostgresMetadataStore(std::unique_ptr<PgConnection> connection)
      : c_(std::move(connection)), listener_(std::make_unique<PgConnection>(c_->url(), c_->label())) {}
  const char* backend() const override { return "postgresql"; }

  core::Result<std::pair<RigRecord, bool>> insertRig(const RigRecord& rig) override {
    std::lock_guard lock(mutex_);
    if (rig.info.id.empty()) return makeError(ErrorCode::kInvalidArgument, "rig id is empty");
    RigRecord stored = rig;
    if (stored.info.created_at.empty()) stored.info.created_at = formatRfc3339Ms(nowMs());
    const auto& i = stored.info;
    auto inserted = c_->command(
        "INSERT INTO rigs (tenant, id, name, size_bytes, vertices, joints, morph_targets, landmarks, has_components, "
        "created_at, rig_blob, landmarks_blob, components_blob, region_labels) VALUES ($1, $2, $3, $4, $5, $6, $7, $8, "
        "$9, $10, $11, $12, $13, $14) ON CONFLICT (tenant, id) DO NOTHING",
        {stored.tenant, i.id, i.name, p(i.size_bytes), p(i.vertices), p(i.joints), p(i.morph_targets), p(i.landmarks),
         p(i.has_components ? 1 : 0), i.created_at, stored.rig_blob, stored.landmarks_blob, stored.components_blob,
         regionLabelsText(stored)},
        "cannot insert rig " + i.id);
    if (!inserted) return inserted.error();
    if (inserted->affected() > 0) return std::pair{std::move(stored), true};
    auto existing = selectRig(rig.tenant, rig.info.id);
    if (!existing) return existing.error();
    if (!*existing) return makeError(ErrorCode::kIo, "database " + c_->label() + ": rig " + rig.info.id + " vanished");
    return std::pair{std::move(**existing), false};
  }

  std::optional<RigRecord> getRig(const std::string& tenant, const std::string& id) override {
    std::lock_guard lock(mutex_);
    return valueOr(selectRig(tenant, id), std::optional<RigRecord>{});
  }

  std::vector<RigRecord> listRigs(const std::string& tenant) override {
    std::lock_guard lock(mutex_);
    static const std::string kSelect =
        std::string("SELECT ") + kRigColumns + " FROM rigs WHERE tenant = $1 ORDER BY created_at, id";
    auto rows = c_->exec(kSelect.c_str(), {tenant}, "cannot list rigs");
    if (!rows) return valueOr<std::vector<RigRecord>>(rows.error(), {});
    return readRows<RigRecord>(*rows, [](const PgRow& r) { return readRig(r); });
  }

  bool deleteRig(const std::string& tenant, const std::string& id) override {
    std::lock_guard lock(mutex_);
    auto r = c_->command("DELETE FROM rigs WHERE tenant = $1 AND id = $2", {tenant, id}, "cannot delete rig " + id);
    if (!r) return valueOr<bool>(r.error(), false);
    return r->affected() > 0;
  }

  core::Result<JobAdmission> admitJob(const JobRecord& job, std::int64_t queue_capacity) override {
    std::lock_guard lock(mutex_);
    if (job.id.empty()) return makeError(ErrorCode::kInvalidArgument, "job id is empty");
    if (!job.idempotency_key.empty()) {
      auto existing = jobByIdempotencyKey(job.tenant, job.idempotency_key);
      if (!existing) return existing.error();
      if (*existing) return JobAdmission{std::move(**existing), false, false};
    }
    JobRecord stored = job;
    if (stored.created_ms == 0) stored.created_ms = nowMs();
    PgTransaction tx(*c_);
    if (auto ok = tx.begin(); !ok) return ok.error();
    if (queue_capacity > 0) {
      // Admissions of every replica one at a time until commit: the count
      // cannot grow between this look and the insert (claims only shrink it).
      if (auto r = c_->exec("SELECT pg_advisory_xact_lock($1)", {p(kQueueAdmissionLockKey)}, "cannot lock job admission");
          !r) {
        return r.error();
      }
      auto queued = c_->exec(kQueuedJobsSql, {}, "cannot count queued jobs");
      if (!queued) return queued.error();
      if (PgRow{queued->get(), 0}.int64(0) >= queue_capacity) {
        tx.rollback();
        return JobAdmission{job, false, true};
      }
    }
    auto inserted = c_->exec(
        "INSERT INTO jobs (id, tenant, kind, rig, spec_json, inputs_json, input_names_json, idempotency_key, status, "
        "stage, attempts, cache_hit, error_json, result_blob, diagnostics_blob, timings_json, created_ms, started_ms, "
        "finished_ms, components_blob) VALUES ($1, $2, $3, $4, $5, $6, $7, $8, $9, $10, $11, $12, $13, $14, $15, $16, "
        "$17, $18, $19, $20) RETURNING sequence",
        {stored.id, stored.tenant, std::string(api::jobKindName(stored.kind)), stored.rig, stored.spec_json,
         mapToJson(stored.inputs), mapToJson(stored.input_names), stored.idempotency_key,
         std::string(api::jobStatusName(stored.status)), stored.stage, p(stored.attempts), p(stored.cache_hit ? 1 : 0),
         stored.error_json, stored.result_blob, stored.diagnostics_blob, stored.timings_json, p(stored.created_ms),
         p(stored.started_ms), p(stored.finished_ms), stored.components_blob},
        "cannot insert job " + stored.id);
    if (!inserted) {
      const bool duplicate = c_->lastSqlState() == kUniqueViolation;
      tx.rollback();
      if (duplicate && !job.idempotency_key.empty()) {
        // Another replica stored the same key between our look-up and insert.
        auto existing = jobByIdempotencyKey(job.tenant, job.idempotency_key);
        if (!existing) return existing.error();
        if (*existing) return JobAdmission{std::move(**existing), false, false};
      }
      if (duplicate) {
        return makeError(ErrorCode::kInvalidArgument,
                         "database " + c_->label() + ": job id " + stored.id + " already exists: " + inserted.error().message);
      }
      return inserted.error();
    }
    stored.sequence = PgRow{inserted->get(), 0}.int64(0);
    for (const auto& [field, blob] : stored.inputs) {
      auto r = c_->command("INSERT INTO job_inputs (job_id, field, blob) VALUES ($1, $2, $3)", {stored.id, field, blob},
                           "cannot insert input " + field + " of job " + stored.id);
      if (!r) return r.error();
    }
    // Delivered at commit, to every replica LISTENing.
    if (auto r = c_->exec(kNotifySql, {}, "cannot announce job " + stored.id); !r) return r.error();
    if (auto ok = tx.commit(); !ok) return ok.error();
    return JobAdmission{std::move(stored), true, false};
  }

  std::optional<JobRecord> getJob(const std::string& tenant, const std::string& id) override {
    std::lock_guard lock(mutex_);
    auto job = valueOr(loadJob(id), std::optional<JobRecord>{});
    if (job && job->tenant != tenant) return std::nullopt;  // another tenant's job does not exist for this one
    return job;
  }

  std::vector<JobRecord> listJobs(const JobListQuery& query) override {
    std::lock_guard lock(mutex_);
    static const std::string kSelect = std::string("SELECT ") + kJobColumns +
                                       " FROM jobs WHERE tenant = $1 AND sequence > $2 AND ($3::text IS NULL OR "
                                       "status = $3) ORDER BY sequence LIMIT $4";
    const Param status = query.status ? Param(api::jobStatusName(*query.status)) : std::nullopt;
    auto rows = c_->exec(kSelect.c_str(), {query.tenant, p(query.after_sequence), status, p(std::max(query.limit, 0))},
                         "cannot list jobs");
    if (!rows) return valueOr<std::vector<JobRecord>>(rows.error(), {});
    return readRows<JobRecord>(*rows, [](const PgRow& r) { return readJob(r); });
  }

  std::vector<JobRecord> unfinishedJobs() override {
    std::lock_guard lock(mutex_);
    static const std::string kSelect =
        std::string("SELECT ") + kJobColumns + " FROM jobs WHERE status IN ('queued', 'running') ORDER BY sequence";
    auto rows = c_->exec(kSelect.c_str(), {}, "cannot list unfinished jobs");
    if (!rows) return valueOr<std::vector<JobRecord>>(rows.error(), {});
    return readRows<JobRecord>(*rows, [](const PgRow& r) { return readJob(r); });
  }

  core::Status markRunning(const std::string& id, std::int64_t started_ms, bool cache_hit) override {
    std::lock_guard lock(mutex_);
    auto r = c_->command(
        "UPDATE jobs SET status = 'running', attempts = attempts + 1, started_ms = $2, cache_hit = $3 "
        "WHERE id = $1 AND status = 'queued'",
        {id, p(started_ms), p(cache_hit ? 1 : 0)}, "cannot mark job " + id + " running");
    if (!r) return r.error();
    if (r->affected() == 0) return transitionRefused(id, "start");
    return core::Ok{};
  }

  core::Status markFinished(const JobRecord& job, int attempt) override {
    std::lock_guard lock(mutex_);
    if (!api::isFinal(job.status)) {
      return makeError(ErrorCode::kInvalidArgument, "cannot finish job " + job.id + " with non-final status " +
                                                        api::jobStatusName(job.status));
    }
    static const std::string kFinish = dollarParams(kFinishJobSql);
    auto r = c_->command(kFinish.c_str(),
                         {job.id, std::string(api::jobStatusName(job.status)), job.stage, job.error_json,
                          job.result_blob, job.diagnostics_blob, job.timings_json,
                          p(job.finished_ms != 0 ? job.finished_ms : nowMs()), p(job.cache_hit ? 1 : 0),
                          job.components_blob, p(attempt)},
                         "cannot mark job " + job.id + " finished");
    if (!r) return r.error();
    if (r->affected() == 0) return transitionRefused(job.id, "finish", attempt);
    return core::Ok{};
  }

  core::Status requeue(const std::string& id, int attempt) override {
    std::lock_guard lock(mutex_);
    static const std::string kRequeue = dollarParams(kRequeueJobSql);
    auto r = c_->command(kRequeue.c_str(), {id, p(attempt)}, "cannot requeue job " + id);
    if (!r) return r.error();
    if (r->affected() == 0) return transitionRefused(id, "requeue", attempt);
    (void)c_->exec(kNotifySql, {}, "cannot announce job " + id);  // a hint: polling finds it anyway
    return core::Ok{};
  }

  core::Result<std::optional<JobRecord>> claimNextJob(const std::string& owner, std::int64_t lease_ms) override {
    std::lock_guard lock(mutex_);
    static const std::string kClaim = dollarParams(claimJobSql(kDatabaseNowMs, /*skip_locked=*/true));
    auto rows = c_->exec(kClaim.c_str(), {owner, p(lease_ms)}, "cannot claim a job");
    if (!rows) return rows.error();
    if (rows->rows() == 0) return std::optional<JobRecord>();
    return std::optional<JobRecord>(readJob(PgRow{rows->get(), 0}));
  }

  core::Result<std::vector<LeaseState>> renewLeases(const std::string& owner, const std::vector<LeaseRenewal>& renewals,
                                                    std::int64_t lease_ms) override {
    std::lock_guard lock(mutex_);
    static const std::string kRenew = dollarParams(renewLeaseSql(kDatabaseNowMs));
    std::vector<LeaseState> out;
    for (const LeaseRenewal& r : renewals) {
      auto rows = c_->exec(kRenew.c_str(),
                           {r.id, p(r.attempt), p(lease_ms), r.stage,
                            p(static_cast<std::int64_t>(std::lround(r.progress * 1e6))), owner},
                           "cannot renew the lease of job " + r.id);
      if (!rows) return rows.error();
      out.push_back(rows->rows() == 0                         ? LeaseState::kLost
                    : PgRow{rows->get(), 0}.int32(0) != 0 ? LeaseState::kCancelRequested
                                                              : LeaseState::kHeld);
    }
    return out;
  }

  core::Result<std::vector<std::string>> requeueExpiredLeases() override {
    std::lock_guard lock(mutex_);
    static const std::string kRequeue = dollarParams(requeueExpiredSql(kDatabaseNowMs));
    auto rows = c_->exec(kRequeue.c_str(), {}, "cannot requeue jobs with expired leases");
    if (!rows) return rows.error();
    if (rows->rows() > 0) (void)c_->exec(kNotifySql, {}, "cannot announce requeued jobs");
    return readRows<std::string>(*rows, [](const PgRow& r) { return r.text(0); });
  }

  core::Status requestCancel(const std::string& id) override {
    std::lock_guard lock(mutex_);
    static const std::string kCancel = dollarParams(kRequestCancelSql);
    auto r = c_->command(kCancel.c_str(), {id}, "cannot request the cancel of job " + id);
    if (!r) return r.error();
    if (r->affected() == 0) return transitionRefused(id, "request the cancel of");
    return core::Ok{};
  }

  core::Result<std::int64_t> queuedJobs() override {
    std::lock_guard lock(mutex_);
    auto rows = c_->exec(kQueuedJobsSql, {}, "cannot count queued jobs");
    if (!rows) return rows.error();
    return PgRow{rows->get(), 0}.int64(0);
  }

  bool shared() const override { return true; }

  core::Result<bool> waitForQueuedJobs(std::chrono::milliseconds timeout) override {
    std::lock_guard lock(listen_mutex_);
    if (!listening_ || !listener_->connected()) {
      listening_ = false;  // a new session (after a reconnect) listens again
      if (auto ok = listener_->script(kListenSql, "cannot listen for queued jobs"); !ok) return ok.error();
      listening_ = true;
    }
    auto notified = listener_->awaitNotification(timeout);
    if (!notified) listening_ = false;
    return notified;
  }

  // One session lock for all of this replica's writers (they count here), so
  // a writer costs a round trip only when it is the first.
  core::Status lockBlobCollection(bool exclusive) override {
    std::unique_lock lock(mutex_);
    if (!exclusive && shared_holders_++ > 0 && shared_held_) return core::Ok{};
    const char* sql = exclusive ? "SELECT pg_try_advisory_lock($1)" : "SELECT pg_try_advisory_lock_shared($1)";
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
    for (;;) {
      auto rows = c_->exec(sql, {p(kBlobCollectionLockKey)}, "cannot take the blob-collection lock");
      if (!rows) return rows.error();
      if (rows->rows() == 1 && PgRow{rows->get(), 0}.text(0) == "t") break;
      if (std::chrono::steady_clock::now() > deadline) {
        return makeError(ErrorCode::kIo, "database " + c_->label() + ": the blob-collection lock stayed taken for 10 s");
      }
      // The other side holds it for one blob write or one reference check:
      // wait without holding this replica's connection.
      lock.unlock();
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
      lock.lock();
    }
    if (!exclusive) shared_held_ = true;
    return core::Ok{};
  }

  void unlockBlobCollection(bool exclusive) override {
    std::lock_guard lock(mutex_);
    if (!exclusive && (--shared_holders_ > 0 || !shared_held_)) return;
    if (!exclusive) shared_held_ = false;
    // A connection lost meanwhile lost the lock with it: nothing to release.
    (void)c_->exec(exclusive ? "SELECT pg_advisory_unlock($1)" : "SELECT pg_advisory_unlock_shared($1)",
                   {p(kBlobCollectionLockKey)}, "cannot release the blob-collection lock");
  }

  core::Result<bool> deleteFinishedJob(const std::string& tenant, const std::string& id) override {
    std::lock_guard lock(mutex_);
    auto r = c_->command(
        "DELETE FROM jobs WHERE id = $1 AND tenant = $2 AND status IN ('succeeded', 'failed', 'cancelled')",
        {id, tenant}, "cannot delete job " + id);
    if (!r) return r.error();
    return r->affected() > 0;
  }

  std::vector<std::pair<std::string, std::string>> finishedJobsBefore(std::int64_t finished_before_ms,
                                                                      int limit) override {
    std::lock_guard lock(mutex_);
    using Key = std::pair<std::string, std::string>;
    auto rows = c_->exec(
        "SELECT tenant, id FROM jobs WHERE status IN ('succeeded', 'failed', 'cancelled') AND finished_ms < $1 "
        "ORDER BY finished_ms LIMIT $2",
        {p(finished_before_ms), p(limit)}, "cannot list expired jobs");
    if (!rows) return valueOr<std::vector<Key>>(rows.error(), {});
    return readRows<Key>(*rows, [](const PgRow& r) { return Key{r.text(0), r.text(1)}; });
  }

  std::map<api::JobStatus, std::int64_t> countJobsByStatus() override {
    std::lock_guard lock(mutex_);
    std::map<api::JobStatus, std::int64_t> out;
    for (auto status : {api::JobStatus::kQueued, api::JobStatus::kRunning, api::JobStatus::kSucceeded,
                        api::JobStatus::kFailed, api::JobStatus::kCancelled}) {
      out[status] = 0;
    }
    auto rows = c_->exec("SELECT status, COUNT(*) FROM jobs GROUP BY status", {}, "cannot count jobs");
    if (!rows) return valueOr<std::map<api::JobStatus, std::int64_t>>(rows.error(), out);
    for (int r = 0; r < rows->rows(); ++r) {
      const PgRow row{rows->get(), r};
      if (auto status = api::parseJobStatus(row.text(0))) out[*status] = row.int64(1);
    }
    return out;
  }

  core::Status probeWrite() override {
    std::lock_guard lock(mutex_);
    auto r = c_->command(
        "INSERT INTO storage_probe (id, at_ms) VALUES (1, $1) ON CONFLICT (id) DO UPDATE SET at_ms = EXCLUDED.at_ms",
        {p(nowMs())}, "storage probe write failed");
    if (!r) return r.error();
    return core::Ok{};
  }

  bool blobReferenced(const std::string& hash) override {
    std::lock_guard lock(mutex_);
    if (hash.empty()) return false;
    // One EXISTS per indexed column, so each is an index probe.
    auto r = c_->exec(
        "SELECT EXISTS (SELECT 1 FROM rigs WHERE rig_blob = $1)"
        " OR EXISTS (SELECT 1 FROM rigs WHERE landmarks_blob = $1)"
        " OR EXISTS (SELECT 1 FROM rigs WHERE components_blob = $1 AND components_blob <> '')"
        " OR EXISTS (SELECT 1 FROM jobs WHERE result_blob = $1 AND result_blob <> '')"
        " OR EXISTS (SELECT 1 FROM jobs WHERE diagnostics_blob = $1 AND diagnostics_blob <> '')"
        " OR EXISTS (SELECT 1 FROM jobs WHERE components_blob = $1 AND components_blob <> '')"
        " OR EXISTS (SELECT 1 FROM job_inputs WHERE blob = $1)",
        {hash}, "cannot check references to blob " + hash);
    // Fail safe: a garbage collector must not delete what it cannot check.
    if (!r) return valueOr<bool>(r.error(), true);
    if (r->rows() != 1) return true;
    return PgRow{r->get(), 0}.text(0) == "t";
  }

 private:
  core::Result<std::optional<RigRecord>> selectRig(const std::string& tenant, const std::string& id) {
    static const std::string kSelect = std::string("SELECT ") + kRigColumns + " FROM rigs WHERE tenant = $1 AND id = $2";
    auto rows = c_->exec(kSelect.c_str(), {tenant, id}, "cannot read rig " + id);
    if (!rows) return rows.error();
    if (rows->rows() == 0) return std::optional<RigRecord>();
    return std::optional<RigRecord>(readRig(PgRow{rows->get(), 0}));
  }

  core::Result<std::optional<JobRecord>> loadJob(const std::string& id) {
    static const std::string kSelect = std::string("SELECT ") + kJobColumns + " FROM jobs WHERE id = $1";
    auto rows = c_->exec(kSelect.c_str(), {id}, "cannot read job " + id);
    if (!rows) return rows.error();
    if (rows->rows() == 0) return std::optional<JobRecord>();
    return std::optional<JobRecord>(readJob(PgRow{rows->get(), 0}));
  }

  core::Result<std::optional<JobRecord>> jobByIdempotencyKey(const std::string& tenant, const std::string& key) {
    static const std::string kSelect =
        std::string("SELECT ") + kJobColumns + " FROM jobs WHERE tenant = $1 AND idempotency_key = $2";
    auto rows = c_->exec(kSelect.c_str(), {tenant, key}, "cannot look up idempotency key");
    if (!rows) return rows.error();
    if (rows->rows() == 0) return std::optional<JobRecord>();
    return std::optional<JobRecord>(readJob(PgRow{rows->get(), 0}));
  }

  // Explains why a guarded UPDATE changed no row: the job is absent or in the wrong state.
  Error transitionRefused(const std::string& id, const char* transition, int attempt = kAnyAttempt) {
    auto job = loadJob(id);
    if (!job) return job.error();
    return transitionRefusal(id, transition, *job ? &**job : nullptr, attempt);
  }

  std::unique_ptr<PgConnection> c_;
  std::mutex mutex_;
  // A second session, only LISTENing for kQueuedChannel (connected on first use).
  std::unique_ptr<PgConnection> listener_;
  std::mutex listen_mutex_;
  bool listening_ = false;
  int shared_holders_ = 0;   // writers holding the blob-collection lock shared
  bool shared_held_ = false; // ... and the session holds it in the database
};

// Creates the schema, or checks it, under the advisory lock.
core::Status prepareSchema(PgConnection& c) {
  PgTransaction tx(c);
  if (auto ok = tx.begin(); !ok) return ok;
  if (auto r = c.exec("SELECT pg_advisory_xact_lock($1)", {std::to_string(kSchemaLockKey)}, "cannot take the schema lock");
      !r) {
    return r.error();
  }
  if (auto r = c.command("CREATE TABLE IF NOT EXISTS rigport_schema (version INTEGER NOT NULL)", {},
                         "cannot create the schema version table");
      !r) {
    return r.error();
  }
  auto version = c.exec("SELECT version FROM rigport_schema", {}, "cannot read the schema version");
  if (!version) return version.error();
  const std::int64_t stored = version->rows() == 0 ? 0 : PgRow{version->get(), 0}.int64(0);
  if (stored > kSchemaVersion) {
    return makeError(ErrorCode::kUnsupported, "database " + c.label() + " has schema version " + std::to_string(stored) +
                                                  ", newer than this build knows (" + std::to_string(kSchemaVersion) +
                                                  "): upgrade rigport");
  }
  std::int64_t now_version = stored;
  for (const SchemaStep& step : kSchemaSteps) {
    if (now_version >= step.version) continue;
    if (step.sql) {
      const std::string what = now_version == 0 ? std::string("cannot create the schema")
                                                : "cannot upgrade schema " + std::to_string(now_version) + " to " +
                                                      std::to_string(step.version);
      if (auto ok = c.script(postgresDialect(step.sql).c_str(), what); !ok) return ok;
    }
    now_version = step.version;
  }
  if (stored != kSchemaVersion) {
    if (auto r = c.command("DELETE FROM rigport_schema", {}, "cannot record the schema version"); !r) return r.error();
    if (auto r = c.command("INSERT INTO rigport_schema (version) VALUES ($1)", {std::to_string(kSchemaVersion)},
                           "cannot record the schema version");
        !r) {
      return r.error();
    }
  }
  return tx.commit();
}

// The URL with bounds on waiting for a server that does not answer (unless
// the URL sets them): every store call holds the store's one connection, so
// an unreachable or silent server must fail calls in seconds, not hang the
// replica's HTTP threads behind them for the kernel's TCP timeouts.
std::string withTimeouts(const std::string& url) {
  std::string out = url;
  for (const char* setting : {"connect_timeout=5", "keepalives_idle=10", "keepalives_interval=5", "keepalives_count=3",
                              "tcp_user_timeout=30000"}) {
    const std::string key = std::string(setting).substr(0, std::string(setting).find('=') + 1);
    if (url.find(key) != std::string::npos) continue;
    out += (out.find('?') == std::string::npos ? "?" : "&");
    out += setting;
  }
  return out;
}

}  // namespace

core::Result<std::unique_ptr<MetadataStore>> openPostgresStore(const std::string& url) {
  auto c = std::make_unique<PgConnection>(withTimeouts(url), describeUrl(url));
  if (auto ok = c->ensure(); !ok) return ok.error();
  if (auto ok = prepareSchema(*c); !ok) return ok.error();
  return std::unique_ptr<MetadataStore>(new PostgresMetadataStore(std::move(c)));
}

}  // namespace server
