// Helpers the store tests share (tests/server/blob_store_test.cpp,
// metadata_store_test.cpp, store_durability_test.cpp): bytes to store, a
// metadata store opened with the error in the failure, and rig and job
// records as the service writes them.
#pragma once

#include <atomic>
#include <cctype>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>
#include <libpq-fe.h>
#include <unistd.h>

#include "server/store.h"

namespace rigport_test::store {

inline std::vector<std::uint8_t> bytesOf(const std::string& s) { return {s.begin(), s.end()}; }

inline std::vector<std::uint8_t> randomBytes(std::size_t n, std::mt19937& rng) {
  std::vector<std::uint8_t> out(n);
  for (auto& b : out) b = static_cast<std::uint8_t>(rng());
  return out;
}

// `location`: a file (the embedded store) or a postgresql:// URL.
inline std::unique_ptr<server::MetadataStore> openStore(const std::string& location) {
  auto store = server::MetadataStore::open(location);
  EXPECT_TRUE(store.ok()) << (store.ok() ? "" : store.error().message);
  return store.ok() ? std::move(*store) : nullptr;
}
inline std::unique_ptr<server::MetadataStore> openStore(const std::filesystem::path& file) {
  return openStore(file.string());
}

// The PostgreSQL server the tests use (scripts/test.sh starts one and sets
// RIGPORT_TEST_POSTGRES_URL); empty when none was given.
inline std::string testPostgresUrl() {
  const char* url = std::getenv("RIGPORT_TEST_POSTGRES_URL");
  return url ? url : "";
}

inline const char* kNoPostgres =
    "RIGPORT_TEST_POSTGRES_URL is not set: no PostgreSQL to test against (scripts/test.sh starts a temporary "
    "one; by hand: bash scripts/postgres.sh start DIR)";

// A store location of its own in the test PostgreSQL: a new schema, named
// after `name` and made unique, as the connection's search_path. Tests run in
// parallel processes against one server without seeing each other's rows.
inline std::string freshPostgresLocation(const std::string& name) {
  static std::atomic<int> counter{0};
  std::string schema = "t_";
  for (const char c : name) schema += std::isalnum(static_cast<unsigned char>(c)) ? static_cast<char>(std::tolower(c)) : '_';
  schema = schema.substr(0, 40) + "_" + std::to_string(::getpid()) + "_" + std::to_string(counter++);
  const std::string base = testPostgresUrl();
  PGconn* conn = PQconnectdb(base.c_str());
  EXPECT_EQ(PQstatus(conn), CONNECTION_OK) << PQerrorMessage(conn);
  PGresult* r = PQexec(conn, ("CREATE SCHEMA " + schema).c_str());
  EXPECT_EQ(PQresultStatus(r), PGRES_COMMAND_OK) << PQerrorMessage(conn);
  PQclear(r);
  PQfinish(conn);
  return base + (base.find('?') == std::string::npos ? "?" : "&") + "options=-csearch_path%3D" + schema;
}

// Runs one SQL statement on a PostgreSQL location (what a test sets up behind the store's back).
inline void runPostgres(const std::string& location, const std::string& sql) {
  PGconn* conn = PQconnectdb(location.c_str());
  ASSERT_EQ(PQstatus(conn), CONNECTION_OK) << PQerrorMessage(conn);
  PGresult* r = PQexec(conn, sql.c_str());
  const ExecStatusType status = PQresultStatus(r);
  EXPECT_TRUE(status == PGRES_COMMAND_OK || status == PGRES_TUPLES_OK) << sql << ": " << PQerrorMessage(conn);
  PQclear(r);
  PQfinish(conn);
}

inline server::RigRecord makeRig(const std::string& tenant, const std::string& id,
                                 const std::string& name = "head.glb") {
  server::RigRecord rig;
  rig.tenant = tenant;
  rig.info.id = id;
  rig.info.name = name;
  rig.info.size_bytes = 1234;
  rig.info.vertices = 100;
  rig.info.joints = 3;
  rig.info.morph_targets = 52;
  rig.info.landmarks = 68;
  rig.info.has_components = true;
  rig.rig_blob = std::string(64, 'a');
  rig.landmarks_blob = std::string(64, 'b');
  rig.components_blob = std::string(64, 'c');
  return rig;
}

inline server::JobRecord makeJob(const std::string& tenant, const std::string& id, const std::string& key = "") {
  server::JobRecord job;
  job.tenant = tenant;
  job.id = id;
  job.kind = api::JobKind::kTransfer;
  job.rig = "rig1";
  job.spec_json = R"({"kind":"transfer","rig":"rig1"})";
  job.inputs = {{"target", std::string(64, 'd')}, {"target_landmarks", std::string(64, 'e')}};
  job.input_names = {{"target", "target.glb"}, {"target_landmarks", "target.json"}};
  job.idempotency_key = key;
  job.created_ms = 1700000000000;
  return job;
}

inline server::JobRecord finished(server::JobRecord job, api::JobStatus status) {
  job.status = status;
  job.stage = "done";
  job.finished_ms = 1700000005000;
  if (status == api::JobStatus::kSucceeded) {
    job.result_blob = std::string(64, '1');
    job.diagnostics_blob = std::string(64, '2');
    job.components_blob = std::string(64, '3');
    job.timings_json = R"({"warp":12.5})";
  } else {
    job.error_json = R"({"title":"stopped"})";
  }
  return job;
}

}  // namespace rigport_test::store
