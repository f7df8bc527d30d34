// (internal to the metadata stores) What the SQLite and PostgreSQL stores
// share: the schema and its upgrades (written once, in SQLite's dialect;
// postgresDialect translates), the column lists, clock and time format, and
// one reading of a row into a record whatever the driver (a Row gives
// text(i), int64(i), int32(i) of the column lists below).
#pragma once

#include <chrono>
#include <cstdint>
#include <cstdio>
#include <ctime>
#include <map>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "api/json.h"
#include "server/store.h"

namespace server::store_sql {

constexpr int kSchemaVersion = 6;

// Schema version 1. Rig created_at is stored as RFC 3339 UTC text (the wire
// form; fixed-width, so it also sorts); job times are epoch milliseconds.
constexpr const char* kSchemaV1 = R"sql(
CREATE TABLE rigs (
  tenant          TEXT    NOT NULL,
  id              TEXT    NOT NULL,
  name            TEXT    NOT NULL,
  size_bytes      INTEGER NOT NULL,
  vertices        INTEGER NOT NULL,
  joints          INTEGER NOT NULL,
  morph_targets   INTEGER NOT NULL,
  landmarks       INTEGER NOT NULL,
  has_components  INTEGER NOT NULL,
  created_at      TEXT    NOT NULL,
  rig_blob        TEXT    NOT NULL,
  landmarks_blob  TEXT    NOT NULL,
  components_blob TEXT    NOT NULL DEFAULT '',
  PRIMARY KEY (tenant, id)
);
CREATE INDEX rigs_rig_blob ON rigs(rig_blob);
CREATE INDEX rigs_landmarks_blob ON rigs(landmarks_blob);
CREATE INDEX rigs_components_blob ON rigs(components_blob) WHERE components_blob <> '';

CREATE TABLE jobs (
  sequence         INTEGER PRIMARY KEY AUTOINCREMENT,
  id               TEXT    NOT NULL UNIQUE,
  tenant           TEXT    NOT NULL,
  kind             TEXT    NOT NULL,
  rig              TEXT    NOT NULL,
  spec_json        TEXT    NOT NULL,
  inputs_json      TEXT    NOT NULL,
  input_names_json TEXT    NOT NULL,
  idempotency_key  TEXT    NOT NULL DEFAULT '',
  status           TEXT    NOT NULL
                   CHECK (status IN ('queued', 'running', 'succeeded', 'failed', 'cancelled')),
  stage            TEXT    NOT NULL,
  attempts         INTEGER NOT NULL DEFAULT 0,
  cache_hit        INTEGER NOT NULL DEFAULT 0,
  error_json       TEXT    NOT NULL DEFAULT '',
  result_blob      TEXT    NOT NULL DEFAULT '',
  diagnostics_blob TEXT    NOT NULL DEFAULT '',
  timings_json     TEXT    NOT NULL DEFAULT '',
  created_ms       INTEGER NOT NULL,
  started_ms       INTEGER NOT NULL DEFAULT 0,
  finished_ms      INTEGER NOT NULL DEFAULT 0
);
CREATE UNIQUE INDEX jobs_idempotency ON jobs(tenant, idempotency_key) WHERE idempotency_key <> '';
CREATE INDEX jobs_tenant_sequence ON jobs(tenant, sequence);
CREATE INDEX jobs_status_sequence ON jobs(status, sequence);
CREATE INDEX jobs_result_blob ON jobs(result_blob) WHERE result_blob <> '';
CREATE INDEX jobs_diagnostics_blob ON jobs(diagnostics_blob) WHERE diagnostics_blob <> '';

-- jobs.inputs_json flattened, so blobReferenced() is an indexed lookup.
CREATE TABLE job_inputs (
  job_id TEXT NOT NULL REFERENCES jobs(id) ON DELETE CASCADE,
  field  TEXT NOT NULL,
  blob   TEXT NOT NULL,
  PRIMARY KEY (job_id, field)
);
CREATE INDEX job_inputs_blob ON job_inputs(blob);
)sql";

// Version 2: rigs record their region labels (JSON array text; '' for rigs
// stored by version 1, which did not: "unknown", not "none").
constexpr const char* kMigrateV1ToV2 = R"sql(
ALTER TABLE rigs ADD COLUMN region_labels TEXT NOT NULL DEFAULT '';
)sql";

// Version 3: one row rewritten by the storage probe (StorageHealth), so a
// probe is a real write transaction.
constexpr const char* kMigrateV2ToV3 = R"sql(
CREATE TABLE storage_probe (
  id    INTEGER PRIMARY KEY CHECK (id = 1),
  at_ms INTEGER NOT NULL
);
)sql";

// Version 5: a job's result may come with a rig components document
// (transfer and fit of a rig that has one).
constexpr const char* kMigrateV4ToV5 = R"sql(
ALTER TABLE jobs ADD COLUMN components_blob TEXT NOT NULL DEFAULT '';
CREATE INDEX jobs_components_blob ON jobs(components_blob) WHERE components_blob <> '';
)sql";

// Version 6: the job queue lives in the store (server/jobs.h): a running
// job's lease (owner, expiry in epoch ms), a cancel its owner must see, and
// the progress of its last heartbeat (parts per million). Jobs left running by
// version 5 have no lease (expiry 0): expired, so requeued.
constexpr const char* kMigrateV5ToV6 = R"sql(
ALTER TABLE jobs ADD COLUMN lease_owner TEXT NOT NULL DEFAULT '';
ALTER TABLE jobs ADD COLUMN lease_expires_ms INTEGER NOT NULL DEFAULT 0;
ALTER TABLE jobs ADD COLUMN cancel_requested INTEGER NOT NULL DEFAULT 0;
ALTER TABLE jobs ADD COLUMN progress_ppm INTEGER NOT NULL DEFAULT 0;
CREATE INDEX jobs_running_lease ON jobs(lease_expires_ms) WHERE status = 'running';
)sql";

// Creating or upgrading the schema: each step brings it to `version` (sql
// nullptr: no table change). A store at version v runs the steps above v, in
// one transaction.
struct SchemaStep {
  int version;
  const char* sql;
};
inline constexpr SchemaStep kSchemaSteps[] = {
    {1, kSchemaV1},
    {2, kMigrateV1ToV2},
    {3, kMigrateV2ToV3},
    // 3 -> 4: no table changes; jobs of kind "fit" may be stored, which
    // builds of schema 3 could not read (see readJob).
    {4, nullptr},
    {5, kMigrateV4ToV5},
    {6, kMigrateV5ToV6},
};

// The schema's SQL for PostgreSQL: integers are 64-bit (epoch milliseconds,
// byte sizes), the job sequence a BIGSERIAL. Everything else (partial
// indexes, ON DELETE CASCADE, ALTER TABLE ... ADD COLUMN) reads the same.
inline std::string postgresDialect(std::string sql) {
  const auto replaceAll = [&sql](const std::string& from, const std::string& to) {
    for (std::size_t at = sql.find(from); at != std::string::npos; at = sql.find(from, at + to.size())) {
      sql.replace(at, from.size(), to);
    }
  };
  replaceAll("INTEGER PRIMARY KEY AUTOINCREMENT", "BIGSERIAL PRIMARY KEY");
  replaceAll("INTEGER", "BIGINT");
  return sql;
}

constexpr const char* kRigColumns =
    "tenant, id, name, size_bytes, vertices, joints, morph_targets, landmarks, has_components, created_at, "
    "rig_blob, landmarks_blob, components_blob, region_labels";

constexpr const char* kJobColumns =
    "sequence, id, tenant, kind, rig, spec_json, inputs_json, input_names_json, idempotency_key, status, stage, "
    "attempts, cache_hit, error_json, result_blob, diagnostics_blob, timings_json, created_ms, started_ms, "
    "finished_ms, components_blob, lease_owner, lease_expires_ms, cancel_requested, progress_ppm";

// The queue's SQL, one dialect for both stores (?N placeholders; the
// PostgreSQL store rewrites them to $N). `now` is an expression of the
// store's clock in epoch ms, so replicas on machines with skewed clocks agree
// on when a lease ends.
inline std::string claimJobSql(const std::string& now, bool skip_locked) {
  return std::string("UPDATE jobs SET status = 'running', attempts = attempts + 1, started_ms = ") + now +
         ", cache_hit = 0, lease_owner = ?1, lease_expires_ms = " + now +
         " + ?2, cancel_requested = 0, progress_ppm = 0 WHERE sequence = (SELECT sequence FROM jobs WHERE status = "
         "'queued' ORDER BY sequence LIMIT 1" + (skip_locked ? " FOR UPDATE SKIP LOCKED" : "") + ") RETURNING " +
         kJobColumns;
}
inline std::string renewLeaseSql(const std::string& now) {
  return "UPDATE jobs SET lease_expires_ms = " + now +
         " + ?3, stage = ?4, progress_ppm = ?5 WHERE id = ?1 AND attempts = ?2 AND lease_owner = ?6 AND status = "
         "'running' RETURNING cancel_requested";
}
inline std::string requeueExpiredSql(const std::string& now) {
  return "UPDATE jobs SET status = 'queued', stage = 'queued', lease_owner = '', lease_expires_ms = 0, "
         "cancel_requested = 0, progress_ppm = 0 WHERE status = 'running' AND lease_expires_ms < " + now +
         " RETURNING id";
}
constexpr const char* kFinishJobSql =
    "UPDATE jobs SET status = ?2, stage = COALESCE(NULLIF(?3, ''), stage), error_json = ?4, result_blob = ?5, "
    "diagnostics_blob = ?6, timings_json = ?7, finished_ms = ?8, cache_hit = ?9, components_blob = ?10, "
    "lease_owner = '', lease_expires_ms = 0, cancel_requested = 0 "
    "WHERE id = ?1 AND status IN ('queued', 'running') AND (?11 < 0 OR attempts = ?11)";
constexpr const char* kRequeueJobSql =
    "UPDATE jobs SET status = 'queued', stage = 'queued', lease_owner = '', lease_expires_ms = 0, "
    "cancel_requested = 0, progress_ppm = 0 WHERE id = ?1 AND status IN ('queued', 'running') AND (?2 < 0 OR "
    "attempts = ?2)";
constexpr const char* kRequestCancelSql = "UPDATE jobs SET cancel_requested = 1 WHERE id = ?1 AND status = 'running'";
constexpr const char* kQueuedJobsSql = "SELECT COUNT(*) FROM jobs WHERE status = 'queued'";

inline std::int64_t nowMs() {
  return std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::system_clock::now().time_since_epoch())
      .count();
}

// "2026-01-31T12:34:56.789Z"
inline std::string formatRfc3339Ms(std::int64_t epoch_ms) {
  const std::time_t secs = static_cast<std::time_t>(epoch_ms / 1000);
  std::tm tm{};
  gmtime_r(&secs, &tm);
  char buf[40];
  const std::size_t n = std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%S", &tm);
  std::snprintf(buf + n, sizeof buf - n, ".%03dZ", static_cast<int>(epoch_ms % 1000));
  return buf;
}

inline std::string mapToJson(const std::map<std::string, std::string>& m) { return api::dumpJson(nlohmann::json(m)); }

inline std::map<std::string, std::string> jsonToMap(const std::string& text) {
  std::map<std::string, std::string> out;
  const auto j = nlohmann::json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (!j.is_object()) return out;
  for (const auto& [key, value] : j.items()) {
    if (value.is_string()) out[key] = value.get<std::string>();
  }
  return out;
}

// rigs.region_labels: a JSON array, '' when unknown.
inline std::string regionLabelsText(const RigRecord& rig) {
  return rig.info.region_labels ? api::dumpJson(nlohmann::json(*rig.info.region_labels)) : std::string();
}

// A row of kRigColumns.
template <typename Row>
RigRecord readRig(const Row& s) {
  RigRecord r;
  r.tenant = s.text(0);
  r.info.id = s.text(1);
  r.info.name = s.text(2);
  r.info.size_bytes = s.int64(3);
  r.info.vertices = s.int32(4);
  r.info.joints = s.int32(5);
  r.info.morph_targets = s.int32(6);
  r.info.landmarks = s.int32(7);
  r.info.has_components = s.int32(8) != 0;
  r.info.created_at = s.text(9);
  r.rig_blob = s.text(10);
  r.landmarks_blob = s.text(11);
  r.components_blob = s.text(12);
  if (const std::string labels = s.text(13); !labels.empty()) {
    const auto parsed = nlohmann::json::parse(labels, nullptr, /*allow_exceptions=*/false);
    if (parsed.is_array()) {
      std::vector<int> values;
      for (const auto& l : parsed) {
        if (l.is_number_integer()) values.push_back(l.get<int>());
      }
      r.info.region_labels = std::move(values);
    }
  }
  return r;
}

// A row of kJobColumns.
template <typename Row>
JobRecord readJob(const Row& s) {
  JobRecord j;
  j.sequence = s.int64(0);
  j.id = s.text(1);
  j.tenant = s.text(2);
  // Written from jobKindName only; a new kind comes with a new schema version,
  // which older builds refuse to open, so every stored kind parses.
  j.kind = api::parseJobKind(s.text(3)).value_or(api::JobKind::kTransfer);
  j.rig = s.text(4);
  j.spec_json = s.text(5);
  j.inputs = jsonToMap(s.text(6));
  j.input_names = jsonToMap(s.text(7));
  j.idempotency_key = s.text(8);
  j.status = api::parseJobStatus(s.text(9)).value_or(api::JobStatus::kFailed);  // CHECK constraint: always parses
  j.stage = s.text(10);
  j.attempts = s.int32(11);
  j.cache_hit = s.int32(12) != 0;
  j.error_json = s.text(13);
  j.result_blob = s.text(14);
  j.diagnostics_blob = s.text(15);
  j.timings_json = s.text(16);
  j.created_ms = s.int64(17);
  j.started_ms = s.int64(18);
  j.finished_ms = s.int64(19);
  j.components_blob = s.text(20);
  j.lease_owner = s.text(21);
  j.lease_expires_ms = s.int64(22);
  j.cancel_requested = s.int32(23) != 0;
  j.progress = static_cast<double>(s.int64(24)) / 1e6;
  return j;
}

// Why a guarded transition changed no row: the job is absent (nullptr), in
// the wrong state, or at another attempt than the fenced one.
inline core::Error transitionRefusal(const std::string& id, const char* transition, const JobRecord* job, int attempt) {
  using core::ErrorCode;
  if (!job) return core::makeError(ErrorCode::kInvalidArgument, "cannot " + std::string(transition) + ": no job " + id);
  if (attempt >= 0 && job->attempts != attempt && !api::isFinal(job->status)) {
    return core::makeError(ErrorCode::kInvalidArgument,
                           "cannot " + std::string(transition) + " job " + id + ": attempt " + std::to_string(attempt) +
                               " lost its lease (the job is at attempt " + std::to_string(job->attempts) + ")");
  }
  return core::makeError(ErrorCode::kInvalidArgument, "cannot " + std::string(transition) + " job " + id + ": it is " +
                                                          api::jobStatusName(job->status));
}

}  // namespace server::store_sql

namespace server {

// Whether a store location is a PostgreSQL connection URL.
bool isPostgresUrl(const std::string& location);

// The two implementations (sqlite_store.cpp, postgres_store.cpp).
core::Result<std::unique_ptr<MetadataStore>> openSqliteStore(const std::filesystem::path& file);
core::Result<std::unique_ptr<MetadataStore>> openPostgresStore(const std::string& url);

}  // namespace server
