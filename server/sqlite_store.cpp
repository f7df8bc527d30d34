// The embedded metadata store (server/store.h): rigs, jobs and their inputs
// in SQLite, the default on one machine.
//
// One sqlite3 connection (C API), journal_mode=WAL and synchronous=FULL, so
// every committed transition has been fsynced before the call returns. Every
// value goes through a bound parameter; statements are prepared once and
// cached per connection.
#include "server/store_sql.h"

#include <nlohmann/json.hpp>
#include <sqlite3.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <ctime>
#include <unordered_map>

#include "api/content_id.h"
#include "api/json.h"

namespace server {

using core::Error;
using namespace store_sql;
using core::ErrorCode;
using core::makeError;

namespace {

constexpr int kBusyTimeoutMs = 5000;

}  // namespace

// The one sqlite3 connection and its cached prepared statements. All access is
// under SqliteMetadataStore::mutex_.
namespace {
struct SqliteConnection {
  sqlite3* db = nullptr;
  std::filesystem::path file;
  std::unordered_map<const char*, sqlite3_stmt*> statements;  // keyed by the SQL literal's address

  SqliteConnection() = default;
  SqliteConnection(const SqliteConnection&) = delete;
  SqliteConnection& operator=(const SqliteConnection&) = delete;
  ~SqliteConnection() {
    for (auto& [sql, stmt] : statements) sqlite3_finalize(stmt);
    if (db) sqlite3_close_v2(db);
  }

  Error error(const std::string& what) const {
    return makeError(ErrorCode::kIo, "database " + file.string() + ": " + what + ": " + sqlite3_errmsg(db));
  }

  core::Status exec(const char* sql) {
    char* msg = nullptr;
    if (sqlite3_exec(db, sql, nullptr, nullptr, &msg) != SQLITE_OK) {
      std::string text = msg ? msg : sqlite3_errmsg(db);
      sqlite3_free(msg);
      return makeError(ErrorCode::kIo, "database " + file.string() + ": " + text + " (in: " + sql + ")");
    }
    return core::Ok{};
  }

  // A cached statement for a SQL string literal (static storage, stable address).
  core::Result<sqlite3_stmt*> prepare(const char* sql) {
    if (auto it = statements.find(sql); it != statements.end()) return it->second;
    sqlite3_stmt* stmt = nullptr;
    if (sqlite3_prepare_v3(db, sql, -1, SQLITE_PREPARE_PERSISTENT, &stmt, nullptr) != SQLITE_OK) {
      return error(std::string("cannot prepare '") + sql + "'");
    }
    statements.emplace(sql, stmt);
    return stmt;
  }
};

// Borrowed cached statement: binds by 1-based index; resets on scope exit.
class Stmt {
 public:
  explicit Stmt(sqlite3_stmt* stmt) : stmt_(stmt) {}
  ~Stmt() {
    sqlite3_reset(stmt_);
    sqlite3_clear_bindings(stmt_);
  }
  Stmt(const Stmt&) = delete;
  Stmt& operator=(const Stmt&) = delete;

  Stmt& bind(int i, const std::string& s) {
    sqlite3_bind_text(stmt_, i, s.data(), static_cast<int>(s.size()), SQLITE_TRANSIENT);
    return *this;
  }
  Stmt& bind(int i, const char* s) {
    sqlite3_bind_text(stmt_, i, s, -1, SQLITE_STATIC);
    return *this;
  }
  Stmt& bind(int i, std::int64_t v) {
    sqlite3_bind_int64(stmt_, i, v);
    return *this;
  }
  Stmt& bind(int i, int v) {
    sqlite3_bind_int(stmt_, i, v);
    return *this;
  }
  Stmt& bind(int i, bool v) { return bind(i, v ? 1 : 0); }
  Stmt& bindNull(int i) {
    sqlite3_bind_null(stmt_, i);
    return *this;
  }

  int step() { return sqlite3_step(stmt_); }

  std::string text(int col) const {
    const auto* p = reinterpret_cast<const char*>(sqlite3_column_text(stmt_, col));
    return p ? std::string(p, static_cast<std::size_t>(sqlite3_column_bytes(stmt_, col))) : std::string();
  }
  std::int64_t int64(int col) const { return sqlite3_column_int64(stmt_, col); }
  int int32(int col) const { return sqlite3_column_int(stmt_, col); }

 private:
  sqlite3_stmt* stmt_;
};

// BEGIN IMMEDIATE ... COMMIT; rolls back unless commit() succeeded.
class Transaction {
 public:
  Transaction(SqliteConnection& c, core::Status& begun) : c_(c) {
    begun = c_.exec("BEGIN IMMEDIATE");
    active_ = begun.ok();
  }
  ~Transaction() {
    if (active_) (void)c_.exec("ROLLBACK");
  }
  Transaction(const Transaction&) = delete;
  Transaction& operator=(const Transaction&) = delete;
  core::Status commit() {
    auto st = c_.exec("COMMIT");
    if (st) active_ = false;
    return st;
  }

 private:
  SqliteConnection& c_;
  bool active_ = false;
};

}  // namespace

namespace {

// Runs a SELECT: `bind` binds its parameters, `read` turns each row into a Row.
template <typename Row, typename Bind, typename Read>
core::Result<std::vector<Row>> selectRows(SqliteConnection& c, const std::string& sql, Bind bind, Read read,
                                          const std::string& what) {
  auto stmt = c.prepare(sql.c_str());
  if (!stmt) return stmt.error();
  Stmt s(*stmt);
  bind(s);
  std::vector<Row> out;
  int rc;
  while ((rc = s.step()) == SQLITE_ROW) out.push_back(read(s));
  if (rc != SQLITE_DONE) return c.error(what);
  return out;
}

}  // namespace

namespace {

// One connection behind a mutex (SQLite serialises writers anyway).
class SqliteMetadataStore final : public MetadataStore {
 public:
  using Connection = SqliteConnection;
  explicit SqliteMetadataStore(std::unique_ptr<Connection> connection) : connection_(std::move(connection)) {}
  const char* backend() const override { return "sqlite"; }
  core::Result<std::pair<RigRecord, bool>> insertRig(const RigRecord& rig) override;
  std::optional<RigRecord> getRig(const std::string& tenant, const std::string& id) override;
  std::vector<RigRecord> listRigs(const std::string& tenant) override;
  bool deleteRig(const std::string& tenant, const std::string& id) override;
  core::Result<JobAdmission> admitJob(const JobRecord& job, std::int64_t queue_capacity) override;
  std::optional<JobRecord> getJob(const std::string& tenant, const std::string& id) override;
  std::vector<JobRecord> listJobs(const JobListQuery& query) override;
  std::vector<JobRecord> unfinishedJobs() override;
  core::Status markRunning(const std::string& id, std::int64_t started_ms, bool cache_hit) override;
  core::Status markFinished(const JobRecord& job, int attempt) override;
  core::Status requeue(const std::string& id, int attempt) override;
  core::Result<std::optional<JobRecord>> claimNextJob(const std::string& owner, std::int64_t lease_ms) override;
  core::Result<std::vector<LeaseState>> renewLeases(const std::string& owner, const std::vector<LeaseRenewal>& renewals,
                                                    std::int64_t lease_ms) override;
  core::Result<std::vector<std::string>> requeueExpiredLeases() override;
  core::Status requestCancel(const std::string& id) override;
  core::Result<std::int64_t> queuedJobs() override;
  bool shared() const override { return false; }
  core::Result<bool> waitForQueuedJobs(std::chrono::milliseconds) override { return false; }
  core::Status lockBlobCollection(bool) override { return core::Ok{}; }
  void unlockBlobCollection(bool) override {}
  core::Result<bool> deleteFinishedJob(const std::string& tenant, const std::string& id) override;
  std::vector<std::pair<std::string, std::string>> finishedJobsBefore(std::int64_t finished_before_ms,
                                                                      int limit) override;
  std::map<api::JobStatus, std::int64_t> countJobsByStatus() override;
  core::Status probeWrite() override;
  bool blobReferenced(const std::string& hash) override;

 private:
  std::unique_ptr<Connection> connection_;
  std::mutex mutex_;
};

}  // namespace

core::Result<std::unique_ptr<MetadataStore>> openSqliteStore(const std::filesystem::path& file) {
  using Connection = SqliteConnection;
  if (file.has_parent_path()) {
    std::error_code ec;
    std::filesystem::create_directories(file.parent_path(), ec);
    if (ec) {
      return makeError(ErrorCode::kIo,
                       "cannot create directory " + file.parent_path().string() + " for database: " + ec.message());
    }
  }
  auto c = std::make_unique<Connection>();
  c->file = file;
  const int rc = sqlite3_open_v2(file.c_str(), &c->db, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE | SQLITE_OPEN_FULLMUTEX,
                                 nullptr);
  if (rc != SQLITE_OK) {
    std::string msg = c->db ? sqlite3_errmsg(c->db) : sqlite3_errstr(rc);
    return makeError(ErrorCode::kIo, "cannot open database " + file.string() + ": " + msg);
  }
  sqlite3_extended_result_codes(c->db, 1);
  sqlite3_busy_timeout(c->db, kBusyTimeoutMs);

  // journal_mode answers with the mode in effect; anything but "wal" (e.g. a
  // filesystem without shared memory) would silently weaken the guarantees.
  {
    auto stmt = c->prepare("PRAGMA journal_mode=WAL");
    if (!stmt) return stmt.error();
    Stmt s(*stmt);
    if (s.step() != SQLITE_ROW) return c->error("cannot set journal_mode=WAL");
    if (const std::string mode = s.text(0); mode != "wal") {
      return makeError(ErrorCode::kIo, "database " + file.string() + ": journal_mode is '" + mode + "', not 'wal'");
    }
  }
  if (auto st = c->exec("PRAGMA synchronous=FULL; PRAGMA foreign_keys=ON;"); !st) return st.error();

  int version = 0;
  {
    auto stmt = c->prepare("PRAGMA user_version");
    if (!stmt) return stmt.error();
    Stmt s(*stmt);
    if (s.step() != SQLITE_ROW) return c->error("cannot read user_version");
    version = s.int32(0);
  }
  if (version > kSchemaVersion) {
    return makeError(ErrorCode::kUnsupported, "database " + file.string() + " has schema version " +
                                                  std::to_string(version) + ", newer than this build knows (" +
                                                  std::to_string(kSchemaVersion) + "): upgrade rigport");
  }
  if (version < kSchemaVersion) {
    // Create or upgrade in one transaction: a crash leaves the old version
    // whole, and the next open does it again.
    core::Status begun = core::Ok{};
    Transaction tx(*c, begun);
    if (!begun) return begun.error();
    // Re-check under the write lock: another process may have done it.
    int now_version = 0;
    {
      auto stmt = c->prepare("PRAGMA user_version");
      if (!stmt) return stmt.error();
      Stmt s(*stmt);
      if (s.step() == SQLITE_ROW) now_version = s.int32(0);
    }
    for (const SchemaStep& step : kSchemaSteps) {
      if (now_version >= step.version) continue;
      if (step.sql) {
        if (auto st = c->exec(step.sql); !st) {
          return Error{st.error().code, "database " + file.string() + ": " +
                                            (now_version == 0 ? std::string("creating the schema")
                                                              : "upgrading schema " + std::to_string(now_version) +
                                                                    " to " + std::to_string(step.version)) +
                                            ": " + st.error().message};
        }
      }
      now_version = step.version;
    }
    if (auto st = c->exec(("PRAGMA user_version=" + std::to_string(now_version)).c_str()); !st) return st.error();
    if (auto st = tx.commit(); !st) return st.error();
  }
  return std::unique_ptr<MetadataStore>(new SqliteMetadataStore(std::move(c)));
}

// ----- rigs

core::Result<std::pair<RigRecord, bool>> SqliteMetadataStore::insertRig(const RigRecord& rig) {
  std::lock_guard lock(mutex_);
  Connection& c = *connection_;
  if (rig.info.id.empty()) return makeError(ErrorCode::kInvalidArgument, "rig id is empty");

  RigRecord stored = rig;
  if (stored.info.created_at.empty()) stored.info.created_at = formatRfc3339Ms(nowMs());

  core::Status begun = core::Ok{};
  Transaction tx(c, begun);
  if (!begun) return begun.error();
  static const char* kInsert =
      "INSERT INTO rigs (tenant, id, name, size_bytes, vertices, joints, morph_targets, landmarks, has_components, "
      "created_at, rig_blob, landmarks_blob, components_blob, region_labels) VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, "
      "?9, ?10, ?11, ?12, ?13, ?14) ON CONFLICT (tenant, id) DO NOTHING";
  auto stmt = c.prepare(kInsert);
  if (!stmt) return stmt.error();
  {
    Stmt s(*stmt);
    s.bind(1, stored.tenant).bind(2, stored.info.id).bind(3, stored.info.name).bind(4, stored.info.size_bytes);
    s.bind(5, stored.info.vertices).bind(6, stored.info.joints).bind(7, stored.info.morph_targets);
    s.bind(8, stored.info.landmarks).bind(9, stored.info.has_components).bind(10, stored.info.created_at);
    s.bind(11, stored.rig_blob).bind(12, stored.landmarks_blob).bind(13, stored.components_blob);
    s.bind(14, stored.info.region_labels ? api::dumpJson(nlohmann::json(*stored.info.region_labels)) : std::string());
    if (s.step() != SQLITE_DONE) return c.error("cannot insert rig " + stored.info.id);
  }
  if (sqlite3_changes(c.db) == 0) {
    static const std::string kSelect = std::string("SELECT ") + kRigColumns + " FROM rigs WHERE tenant = ?1 AND id = ?2";
    auto sel = c.prepare(kSelect.c_str());
    if (!sel) return sel.error();
    Stmt s(*sel);
    s.bind(1, rig.tenant).bind(2, rig.info.id);
    if (s.step() != SQLITE_ROW) return c.error("cannot read existing rig " + rig.info.id);
    RigRecord existing = readRig(s);
    return std::pair{std::move(existing), false};
  }
  if (auto st = tx.commit(); !st) return st.error();
  return std::pair{std::move(stored), true};
}

std::optional<RigRecord> SqliteMetadataStore::getRig(const std::string& tenant, const std::string& id) {
  std::lock_guard lock(mutex_);
  static const std::string kSelect = std::string("SELECT ") + kRigColumns + " FROM rigs WHERE tenant = ?1 AND id = ?2";
  auto rows = valueOr(selectRows<RigRecord>(
                          *connection_, kSelect, [&](Stmt& s) { s.bind(1, tenant).bind(2, id); }, readRig<Stmt>,
                          "cannot read rig " + id),
                      std::vector<RigRecord>{});
  if (rows.empty()) return std::nullopt;
  return std::move(rows.front());
}

std::vector<RigRecord> SqliteMetadataStore::listRigs(const std::string& tenant) {
  std::lock_guard lock(mutex_);
  static const std::string kSelect =
      std::string("SELECT ") + kRigColumns + " FROM rigs WHERE tenant = ?1 ORDER BY created_at, id";
  return valueOr(selectRows<RigRecord>(
                     *connection_, kSelect, [&](Stmt& s) { s.bind(1, tenant); }, readRig<Stmt>, "cannot list rigs"),
                 std::vector<RigRecord>{});
}

bool SqliteMetadataStore::deleteRig(const std::string& tenant, const std::string& id) {
  std::lock_guard lock(mutex_);
  Connection& c = *connection_;
  auto stmt = c.prepare("DELETE FROM rigs WHERE tenant = ?1 AND id = ?2");
  if (!stmt) return valueOr<bool>(stmt.error(), false);
  Stmt s(*stmt);
  s.bind(1, tenant).bind(2, id);
  if (s.step() != SQLITE_DONE) return valueOr<bool>(c.error("cannot delete rig " + id), false);
  return sqlite3_changes(c.db) > 0;
}

// ----- jobs

namespace {

const std::string& selectJobByIdSql() {
  static const std::string sql = std::string("SELECT ") + kJobColumns + " FROM jobs WHERE id = ?1";
  return sql;
}

// Reads one job by id (no tenant filter); nullopt when absent.
core::Result<std::optional<JobRecord>> loadJob(SqliteConnection& c, const std::string& id) {
  auto stmt = c.prepare(selectJobByIdSql().c_str());
  if (!stmt) return stmt.error();
  Stmt s(*stmt);
  s.bind(1, id);
  const int rc = s.step();
  if (rc == SQLITE_ROW) return std::optional<JobRecord>(readJob(s));
  if (rc != SQLITE_DONE) return c.error("cannot read job " + id);
  return std::optional<JobRecord>();
}

}  // namespace

core::Result<JobAdmission> SqliteMetadataStore::admitJob(const JobRecord& job, std::int64_t queue_capacity) {
  std::lock_guard lock(mutex_);
  Connection& c = *connection_;
  if (job.id.empty()) return makeError(ErrorCode::kInvalidArgument, "job id is empty");

  core::Status begun = core::Ok{};
  Transaction tx(c, begun);
  if (!begun) return begun.error();

  if (!job.idempotency_key.empty()) {
    static const std::string kSelect =
        std::string("SELECT ") + kJobColumns + " FROM jobs WHERE tenant = ?1 AND idempotency_key = ?2";
    auto stmt = c.prepare(kSelect.c_str());
    if (!stmt) return stmt.error();
    Stmt s(*stmt);
    s.bind(1, job.tenant).bind(2, job.idempotency_key);
    const int rc = s.step();
    if (rc == SQLITE_ROW) return JobAdmission{readJob(s), false, false};
    if (rc != SQLITE_DONE) return c.error("cannot look up idempotency key");
  }
  if (queue_capacity > 0) {  // in the write transaction: no other insert in between
    auto queued = selectRows<std::int64_t>(
        c, kQueuedJobsSql, [](Stmt&) {}, [](const Stmt& s) { return s.int64(0); }, "cannot count queued jobs");
    if (!queued) return queued.error();
    if (!queued->empty() && queued->front() >= queue_capacity) return JobAdmission{job, false, true};
  }

  JobRecord stored = job;
  if (stored.created_ms == 0) stored.created_ms = nowMs();
  static const char* kInsert =
      "INSERT INTO jobs (id, tenant, kind, rig, spec_json, inputs_json, input_names_json, idempotency_key, status, "
      "stage, attempts, cache_hit, error_json, result_blob, diagnostics_blob, timings_json, created_ms, started_ms, "
      "finished_ms, components_blob) VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12, ?13, ?14, ?15, ?16, ?17, "
      "?18, ?19, ?20)";
  {
    auto stmt = c.prepare(kInsert);
    if (!stmt) return stmt.error();
    Stmt s(*stmt);
    s.bind(1, stored.id).bind(2, stored.tenant).bind(3, std::string(api::jobKindName(stored.kind))).bind(4, stored.rig).bind(5, stored.spec_json);
    s.bind(6, mapToJson(stored.inputs)).bind(7, mapToJson(stored.input_names)).bind(8, stored.idempotency_key);
    s.bind(9, api::jobStatusName(stored.status)).bind(10, stored.stage).bind(11, stored.attempts);
    s.bind(12, stored.cache_hit).bind(13, stored.error_json).bind(14, stored.result_blob);
    s.bind(15, stored.diagnostics_blob).bind(16, stored.timings_json).bind(17, stored.created_ms);
    s.bind(18, stored.started_ms).bind(19, stored.finished_ms).bind(20, stored.components_blob);
    if (s.step() != SQLITE_DONE) {
      if (sqlite3_extended_errcode(c.db) == SQLITE_CONSTRAINT_UNIQUE) {
        return makeError(ErrorCode::kInvalidArgument, "database " + c.file.string() + ": job id " + stored.id +
                                                          " already exists: " + sqlite3_errmsg(c.db));
      }
      return c.error("cannot insert job " + stored.id);
    }
  }
  stored.sequence = sqlite3_last_insert_rowid(c.db);
  for (const auto& [field, blob] : stored.inputs) {
    auto stmt = c.prepare("INSERT INTO job_inputs (job_id, field, blob) VALUES (?1, ?2, ?3)");
    if (!stmt) return stmt.error();
    Stmt s(*stmt);
    s.bind(1, stored.id).bind(2, field).bind(3, blob);
    if (s.step() != SQLITE_DONE) return c.error("cannot insert input " + field + " of job " + stored.id);
  }
  if (auto st = tx.commit(); !st) return st.error();
  return JobAdmission{std::move(stored), true, false};
}

std::optional<JobRecord> SqliteMetadataStore::getJob(const std::string& tenant, const std::string& id) {
  std::lock_guard lock(mutex_);
  auto job = valueOr(loadJob(*connection_, id), std::optional<JobRecord>{});
  if (job && job->tenant != tenant) return std::nullopt;  // another tenant's job does not exist for this one
  return job;
}

std::vector<JobRecord> SqliteMetadataStore::listJobs(const JobListQuery& query) {
  std::lock_guard lock(mutex_);
  static const std::string kSelect = std::string("SELECT ") + kJobColumns +
                                     " FROM jobs WHERE tenant = ?1 AND sequence > ?2 AND (?3 IS NULL OR status = ?3)"
                                     " ORDER BY sequence LIMIT ?4";
  auto bind = [&](Stmt& s) {
    s.bind(1, query.tenant).bind(2, query.after_sequence);
    if (query.status) {
      s.bind(3, api::jobStatusName(*query.status));
    } else {
      s.bindNull(3);
    }
    s.bind(4, std::max(query.limit, 0));
  };
  return valueOr(selectRows<JobRecord>(*connection_, kSelect, bind, readJob<Stmt>, "cannot list jobs"), std::vector<JobRecord>{});
}

std::vector<JobRecord> SqliteMetadataStore::unfinishedJobs() {
  std::lock_guard lock(mutex_);
  static const std::string kSelect =
      std::string("SELECT ") + kJobColumns + " FROM jobs WHERE status IN ('queued', 'running') ORDER BY sequence";
  return valueOr(selectRows<JobRecord>(
                     *connection_, kSelect, [](Stmt&) {}, readJob<Stmt>, "cannot list unfinished jobs"),
                 std::vector<JobRecord>{});
}

namespace {

// Explains why a guarded UPDATE changed no row: the job is absent or in the wrong state.
Error transitionRefused(SqliteConnection& c, const std::string& id, const char* transition, int attempt = kAnyAttempt) {
  auto job = loadJob(c, id);
  if (!job) return job.error();
  return transitionRefusal(id, transition, *job ? &**job : nullptr, attempt);
}

}  // namespace

core::Status SqliteMetadataStore::markRunning(const std::string& id, std::int64_t started_ms, bool cache_hit) {
  std::lock_guard lock(mutex_);
  Connection& c = *connection_;
  auto stmt = c.prepare(
      "UPDATE jobs SET status = 'running', attempts = attempts + 1, started_ms = ?2, cache_hit = ?3 "
      "WHERE id = ?1 AND status = 'queued'");
  if (!stmt) return stmt.error();
  {
    Stmt s(*stmt);
    s.bind(1, id).bind(2, started_ms).bind(3, cache_hit);
    if (s.step() != SQLITE_DONE) return c.error("cannot mark job " + id + " running");
  }
  if (sqlite3_changes(c.db) == 0) return transitionRefused(c, id, "start");
  return core::Ok{};
}

core::Status SqliteMetadataStore::markFinished(const JobRecord& job, int attempt) {
  std::lock_guard lock(mutex_);
  Connection& c = *connection_;
  if (!api::isFinal(job.status)) {
    return makeError(ErrorCode::kInvalidArgument, "cannot finish job " + job.id + " with non-final status " +
                                                      api::jobStatusName(job.status));
  }
  auto stmt = c.prepare(kFinishJobSql);
  if (!stmt) return stmt.error();
  {
    Stmt s(*stmt);
    s.bind(1, job.id).bind(2, api::jobStatusName(job.status)).bind(3, job.stage).bind(4, job.error_json);
    s.bind(5, job.result_blob).bind(6, job.diagnostics_blob).bind(7, job.timings_json);
    s.bind(8, job.finished_ms != 0 ? job.finished_ms : nowMs());
    s.bind(9, job.cache_hit).bind(10, job.components_blob).bind(11, attempt);
    if (s.step() != SQLITE_DONE) return c.error("cannot mark job " + job.id + " finished");
  }
  if (sqlite3_changes(c.db) == 0) return transitionRefused(c, job.id, "finish", attempt);
  return core::Ok{};
}

core::Status SqliteMetadataStore::requeue(const std::string& id, int attempt) {
  std::lock_guard lock(mutex_);
  Connection& c = *connection_;
  auto stmt = c.prepare(kRequeueJobSql);
  if (!stmt) return stmt.error();
  {
    Stmt s(*stmt);
    s.bind(1, id).bind(2, attempt);
    if (s.step() != SQLITE_DONE) return c.error("cannot requeue job " + id);
  }
  if (sqlite3_changes(c.db) == 0) return transitionRefused(c, id, "requeue", attempt);
  return core::Ok{};
}

core::Result<std::optional<JobRecord>> SqliteMetadataStore::claimNextJob(const std::string& owner, std::int64_t lease_ms) {
  std::lock_guard lock(mutex_);
  Connection& c = *connection_;
  static const std::string kClaim = claimJobSql("?3", /*skip_locked=*/false);
  auto claimed = selectRows<JobRecord>(
      c, kClaim, [&](Stmt& s) { s.bind(1, owner).bind(2, lease_ms).bind(3, nowMs()); }, readJob<Stmt>,
      "cannot claim a job");
  if (!claimed) return claimed.error();
  if (claimed->empty()) return std::optional<JobRecord>();
  return std::optional<JobRecord>(std::move(claimed->front()));
}

core::Result<std::vector<LeaseState>> SqliteMetadataStore::renewLeases(const std::string& owner,
                                                                       const std::vector<LeaseRenewal>& renewals,
                                                                       std::int64_t lease_ms) {
  std::lock_guard lock(mutex_);
  Connection& c = *connection_;
  static const std::string kRenew = renewLeaseSql("?7");
  std::vector<LeaseState> out;
  for (const LeaseRenewal& r : renewals) {
    auto rows = selectRows<int>(
        c, kRenew,
        [&](Stmt& s) {
          s.bind(1, r.id).bind(2, r.attempt).bind(3, lease_ms).bind(4, r.stage);
          s.bind(5, static_cast<std::int64_t>(std::lround(r.progress * 1e6))).bind(6, owner).bind(7, nowMs());
        },
        [](const Stmt& s) { return s.int32(0); }, "cannot renew the lease of job " + r.id);
    if (!rows) return rows.error();
    out.push_back(rows->empty() ? LeaseState::kLost : rows->front() != 0 ? LeaseState::kCancelRequested : LeaseState::kHeld);
  }
  return out;
}

core::Result<std::vector<std::string>> SqliteMetadataStore::requeueExpiredLeases() {
  std::lock_guard lock(mutex_);
  static const std::string kRequeue = requeueExpiredSql("?1");
  return selectRows<std::string>(
      *connection_, kRequeue, [&](Stmt& s) { s.bind(1, nowMs()); }, [](const Stmt& s) { return s.text(0); },
      "cannot requeue jobs with expired leases");
}

core::Status SqliteMetadataStore::requestCancel(const std::string& id) {
  std::lock_guard lock(mutex_);
  Connection& c = *connection_;
  auto stmt = c.prepare(kRequestCancelSql);
  if (!stmt) return stmt.error();
  {
    Stmt s(*stmt);
    s.bind(1, id);
    if (s.step() != SQLITE_DONE) return c.error("cannot request the cancel of job " + id);
  }
  if (sqlite3_changes(c.db) == 0) return transitionRefused(c, id, "request the cancel of");
  return core::Ok{};
}

core::Result<std::int64_t> SqliteMetadataStore::queuedJobs() {
  std::lock_guard lock(mutex_);
  auto rows = selectRows<std::int64_t>(
      *connection_, kQueuedJobsSql, [](Stmt&) {}, [](const Stmt& s) { return s.int64(0); }, "cannot count queued jobs");
  if (!rows) return rows.error();
  return rows->empty() ? 0 : rows->front();
}

core::Status SqliteMetadataStore::probeWrite() {
  std::lock_guard lock(mutex_);
  Connection& c = *connection_;
  auto stmt = c.prepare("INSERT INTO storage_probe (id, at_ms) VALUES (1, ?1) ON CONFLICT (id) DO UPDATE SET at_ms = ?1");
  if (!stmt) return stmt.error();
  Stmt s(*stmt);
  s.bind(1, nowMs());
  if (s.step() != SQLITE_DONE) return c.error("storage probe write failed");
  return core::Ok{};
}

core::Result<bool> SqliteMetadataStore::deleteFinishedJob(const std::string& tenant, const std::string& id) {
  std::lock_guard lock(mutex_);
  Connection& c = *connection_;
  auto stmt = c.prepare(
      "DELETE FROM jobs WHERE id = ?1 AND tenant = ?2 AND status IN ('succeeded', 'failed', 'cancelled')");
  if (!stmt) return stmt.error();
  Stmt s(*stmt);
  s.bind(1, id).bind(2, tenant);
  if (s.step() != SQLITE_DONE) return c.error("cannot delete job " + id);
  return sqlite3_changes(c.db) > 0;
}

std::vector<std::pair<std::string, std::string>> SqliteMetadataStore::finishedJobsBefore(std::int64_t finished_before_ms,
                                                                                   int limit) {
  std::lock_guard lock(mutex_);
  using Key = std::pair<std::string, std::string>;
  return valueOr(selectRows<Key>(
                     *connection_,
                     "SELECT tenant, id FROM jobs WHERE status IN ('succeeded', 'failed', 'cancelled') AND finished_ms < ?1 "
                     "ORDER BY finished_ms LIMIT ?2",
                     [&](Stmt& s) { s.bind(1, finished_before_ms).bind(2, static_cast<std::int64_t>(limit)); },
                     [](const Stmt& s) { return Key{s.text(0), s.text(1)}; }, "cannot list expired jobs"),
                 std::vector<Key>{});
}

std::map<api::JobStatus, std::int64_t> SqliteMetadataStore::countJobsByStatus() {
  std::lock_guard lock(mutex_);
  Connection& c = *connection_;
  std::map<api::JobStatus, std::int64_t> out;
  for (auto status : {api::JobStatus::kQueued, api::JobStatus::kRunning, api::JobStatus::kSucceeded,
                      api::JobStatus::kFailed, api::JobStatus::kCancelled}) {
    out[status] = 0;
  }
  using Count = std::pair<std::string, std::int64_t>;
  const auto counts = valueOr(selectRows<Count>(
                                  c, "SELECT status, COUNT(*) FROM jobs GROUP BY status", [](Stmt&) {},
                                  [](const Stmt& s) { return Count{s.text(0), s.int64(1)}; }, "cannot count jobs"),
                              std::vector<Count>{});
  for (const auto& [name, n] : counts) {
    if (auto status = api::parseJobStatus(name)) out[*status] = n;
  }
  return out;
}

bool SqliteMetadataStore::blobReferenced(const std::string& hash) {
  std::lock_guard lock(mutex_);
  Connection& c = *connection_;
  if (hash.empty()) return false;
  // One EXISTS per indexed column, so each is an index probe.
  auto stmt = c.prepare(
      "SELECT EXISTS (SELECT 1 FROM rigs WHERE rig_blob = ?1)"
      " OR EXISTS (SELECT 1 FROM rigs WHERE landmarks_blob = ?1)"
      " OR EXISTS (SELECT 1 FROM rigs WHERE components_blob = ?1 AND components_blob <> '')"
      " OR EXISTS (SELECT 1 FROM jobs WHERE result_blob = ?1 AND result_blob <> '')"
      " OR EXISTS (SELECT 1 FROM jobs WHERE diagnostics_blob = ?1 AND diagnostics_blob <> '')"
      " OR EXISTS (SELECT 1 FROM jobs WHERE components_blob = ?1 AND components_blob <> '')"
      " OR EXISTS (SELECT 1 FROM job_inputs WHERE blob = ?1)");
  // Fail safe: a garbage collector must not delete what it cannot check.
  if (!stmt) return valueOr<bool>(stmt.error(), true);
  Stmt s(*stmt);
  s.bind(1, hash);
  if (s.step() != SQLITE_ROW) return valueOr<bool>(c.error("cannot check references to blob " + hash), true);
  return s.int32(0) != 0;
}

}  // namespace server
