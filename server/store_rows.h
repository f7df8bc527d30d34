// (internal to the metadata stores) What the SQLite and PostgreSQL stores
// share: the schema's column lists, clock and time format, and one reading of
// a row into a record whatever the driver (a Row gives text(i), int64(i),
// int32(i) of the column lists below).
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

namespace server::store_rows {

constexpr int kSchemaVersion = 5;

constexpr const char* kRigColumns =
    "tenant, id, name, size_bytes, vertices, joints, morph_targets, landmarks, has_components, created_at, "
    "rig_blob, landmarks_blob, components_blob, region_labels";

constexpr const char* kJobColumns =
    "sequence, id, tenant, kind, rig, spec_json, inputs_json, input_names_json, idempotency_key, status, stage, "
    "attempts, cache_hit, error_json, result_blob, diagnostics_blob, timings_json, created_ms, started_ms, "
    "finished_ms, components_blob";

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
  return j;
}

}  // namespace server::store_rows

namespace server {

// Whether a store location is a PostgreSQL connection URL.
bool isPostgresUrl(const std::string& location);

// The two implementations (sqlite_store.cpp, postgres_store.cpp).
core::Result<std::unique_ptr<MetadataStore>> openSqliteStore(const std::filesystem::path& file);
core::Result<std::unique_ptr<MetadataStore>> openPostgresStore(const std::string& url);

}  // namespace server
