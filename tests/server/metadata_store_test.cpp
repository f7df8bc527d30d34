// Tests server/metadata_store.cpp: the SQLite metadata store (schema and
// upgrades on open, rigs and jobs per tenant, idempotency keys, paging,
// transitions, persistence across reopen, blob references, expiry,
// concurrent writers).
#include "server/store.h"
#include "server/store_sql.h"

#include <sqlite3.h>

#include <atomic>
#include <chrono>
#include <map>
#include <mutex>
#include <regex>
#include <thread>

#include <gtest/gtest.h>

#include "tests/server/store_fixture.h"
#include "tests/test_support.h"

namespace {

namespace fs = std::filesystem;
using api::JobStatus;
using server::JobListQuery;
using server::JobRecord;
using server::MetadataStore;
using server::RigRecord;
using namespace rigport_test::store;

// What schema 6 added (the queue's leases), dropped to fake an older store.
constexpr const char* kDropSchemaSixSql =
    "DROP INDEX jobs_running_lease; ALTER TABLE jobs DROP COLUMN lease_owner; ALTER TABLE jobs DROP COLUMN "
    "lease_expires_ms; ALTER TABLE jobs DROP COLUMN cancel_requested; ALTER TABLE jobs DROP COLUMN progress_ppm; ";

std::vector<std::string> idsOf(const std::vector<JobRecord>& jobs) {
  std::vector<std::string> ids;
  for (const auto& j : jobs) ids.push_back(j.id);
  return ids;
}

// ---------------------------------------------------------------------------
// Metadata: open

TEST(MetadataStore, OpenCreatesDirectoriesAndUsesWal) {
  const fs::path file = rigport_test::makeTempDir("open") / "nested" / "dir" / "meta.db";
  auto store = openStore(file);
  ASSERT_TRUE(store);
  EXPECT_TRUE(fs::exists(file));
  store.reset();
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open(file.c_str(), &db), SQLITE_OK);
  sqlite3_stmt* stmt = nullptr;
  ASSERT_EQ(sqlite3_prepare_v2(db, "PRAGMA journal_mode", -1, &stmt, nullptr), SQLITE_OK);
  ASSERT_EQ(sqlite3_step(stmt), SQLITE_ROW);
  EXPECT_STREQ(reinterpret_cast<const char*>(sqlite3_column_text(stmt, 0)), "wal");
  sqlite3_finalize(stmt);
  sqlite3_close(db);
}

TEST(MetadataStore, OpenRefusesNewerSchemaNamingTheFile) {
  const fs::path file = rigport_test::makeTempDir("newer") / "meta.db";
  ASSERT_TRUE(openStore(file));
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open(file.c_str(), &db), SQLITE_OK);
  ASSERT_EQ(sqlite3_exec(db, "PRAGMA user_version=99", nullptr, nullptr, nullptr), SQLITE_OK);
  sqlite3_close(db);
  auto store = MetadataStore::open(file);
  ASSERT_FALSE(store.ok());
  EXPECT_NE(store.error().message.find(file.string()), std::string::npos) << store.error().message;
  EXPECT_NE(store.error().message.find("99"), std::string::npos) << store.error().message;
}

// A store written by schema 1 (rigs without region labels) is upgraded in
// place on open: its rigs stay, with their labels unknown rather than "none".
TEST(MetadataStore, SchemaOneIsUpgradedKeepingItsRigs) {
  const fs::path file = rigport_test::makeTempDir("upgrade") / "meta.db";
  {
    auto store = openStore(file);
    ASSERT_TRUE(store);
    RigRecord old_rig = makeRig("acme", "old", "old.glb");
    old_rig.info.region_labels = std::vector<int>{1, 2};
    ASSERT_TRUE(store->insertRig(old_rig).ok());
  }
  // Back to what schema 1 wrote (without what versions 2, 3, 5 and 6 added).
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open(file.c_str(), &db), SQLITE_OK);
  const std::string downgrade = std::string(kDropSchemaSixSql) +
                               "ALTER TABLE rigs DROP COLUMN region_labels; DROP TABLE storage_probe; DROP INDEX "
                               "jobs_components_blob; ALTER TABLE jobs DROP COLUMN components_blob; PRAGMA user_version=1;";
  ASSERT_EQ(sqlite3_exec(db, downgrade.c_str(), nullptr, nullptr, nullptr),
            SQLITE_OK)
      << sqlite3_errmsg(db);
  sqlite3_close(db);

  auto store = openStore(file);
  ASSERT_TRUE(store);
  auto old_rig = store->getRig("acme", "old");
  ASSERT_TRUE(old_rig);
  EXPECT_EQ(old_rig->info.name, "old.glb");
  EXPECT_EQ(old_rig->rig_blob, makeRig("acme", "old", "old.glb").rig_blob);
  EXPECT_FALSE(old_rig->info.region_labels.has_value());
  RigRecord labelled = makeRig("acme", "labelled", "labelled.glb");
  labelled.info.region_labels = std::vector<int>{0, 3, 4};
  RigRecord unlabelled = makeRig("acme", "unlabelled", "unlabelled.glb");
  unlabelled.info.region_labels = std::vector<int>{};
  ASSERT_TRUE(store->insertRig(labelled).ok());
  ASSERT_TRUE(store->insertRig(unlabelled).ok());
  store.reset();

  auto reopened = openStore(file);
  ASSERT_TRUE(reopened);
  EXPECT_EQ(reopened->getRig("acme", "labelled")->info.region_labels, (std::vector<int>{0, 3, 4}));
  EXPECT_EQ(reopened->getRig("acme", "unlabelled")->info.region_labels, std::vector<int>{});
  EXPECT_FALSE(reopened->getRig("acme", "old")->info.region_labels.has_value());
  EXPECT_EQ(reopened->listRigs("acme").size(), 3u);
  EXPECT_TRUE(reopened->probeWrite().ok()) << "version 3's probe table must exist";
  const JobRecord job = makeJob("acme", "after-upgrade");
  ASSERT_TRUE(reopened->insertJob(job).ok());
  ASSERT_TRUE(reopened->markRunning("after-upgrade", 1, false).ok());
  ASSERT_TRUE(reopened->markFinished(finished(job, JobStatus::kSucceeded)).ok());
  EXPECT_EQ(reopened->getJob("acme", "after-upgrade")->components_blob, std::string(64, '3'))
      << "version 5's components column must exist";
  ASSERT_EQ(sqlite3_open(file.c_str(), &db), SQLITE_OK);
  sqlite3_stmt* stmt = nullptr;
  ASSERT_EQ(sqlite3_prepare_v2(db, "PRAGMA user_version", -1, &stmt, nullptr), SQLITE_OK);
  ASSERT_EQ(sqlite3_step(stmt), SQLITE_ROW);
  EXPECT_EQ(sqlite3_column_int(stmt, 0), 6) << "upgraded to the current version (6: the job queue's leases)";
  sqlite3_finalize(stmt);
  sqlite3_close(db);
}

TEST(MetadataStore, OpenReportsUnopenableFileWithItsPath) {
  const fs::path dir = rigport_test::makeTempDir("bad");
  fs::create_directories(dir / "meta.db");  // a directory where the file should be
  auto store = MetadataStore::open(dir / "meta.db");
  ASSERT_FALSE(store.ok());
  EXPECT_EQ(store.error().code, core::ErrorCode::kIo);
  EXPECT_NE(store.error().message.find((dir / "meta.db").string()), std::string::npos) << store.error().message;
}

// ---------------------------------------------------------------------------
// The contract both implementations keep (server/store.h), each test on a
// store of its own: a new SQLite file, or a new schema in the test PostgreSQL.

enum class Backend { kSqlite, kPostgres };

class MetadataStoreContract : public ::testing::TestWithParam<Backend> {
 protected:
  void SetUp() override {
    if (GetParam() == Backend::kPostgres && testPostgresUrl().empty()) GTEST_SKIP() << kNoPostgres;
  }
  std::string freshLocation() const {
    const std::string name = ::testing::UnitTest::GetInstance()->current_test_info()->name();
    if (GetParam() == Backend::kPostgres) return freshPostgresLocation(name);
    return (rigport_test::makeTempDir("contract") / "meta.db").string();
  }
  std::unique_ptr<MetadataStore> open() const { return openStore(freshLocation()); }
};

INSTANTIATE_TEST_SUITE_P(Backends, MetadataStoreContract, ::testing::Values(Backend::kSqlite, Backend::kPostgres),
                         [](const auto& backend) { return backend.param == Backend::kSqlite ? "Sqlite" : "Postgres"; });

// ---------------------------------------------------------------------------
// Metadata: rigs

TEST_P(MetadataStoreContract, InsertRigIsIdempotentOnTenantAndId) {
  auto store = open();
  ASSERT_TRUE(store);
  auto first = store->insertRig(makeRig("acme", "rig1", "first.glb"));
  ASSERT_TRUE(first.ok()) << first.error().message;
  EXPECT_TRUE(first->second);
  EXPECT_TRUE(std::regex_match(first->first.info.created_at,
                               std::regex(R"(\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d\.\d{3}Z)")))
      << first->first.info.created_at;

  auto second = store->insertRig(makeRig("acme", "rig1", "second.glb"));
  ASSERT_TRUE(second.ok()) << second.error().message;
  EXPECT_FALSE(second->second);
  EXPECT_EQ(second->first.info.name, "first.glb");
  EXPECT_EQ(second->first.info.created_at, first->first.info.created_at);
  EXPECT_EQ(store->listRigs("acme").size(), 1u);

  auto got = store->getRig("acme", "rig1");
  ASSERT_TRUE(got);
  const RigRecord expected = makeRig("acme", "rig1", "first.glb");
  EXPECT_EQ(got->info.size_bytes, expected.info.size_bytes);
  EXPECT_EQ(got->info.vertices, expected.info.vertices);
  EXPECT_EQ(got->info.joints, expected.info.joints);
  EXPECT_EQ(got->info.morph_targets, expected.info.morph_targets);
  EXPECT_EQ(got->info.landmarks, expected.info.landmarks);
  EXPECT_TRUE(got->info.has_components);
  EXPECT_EQ(got->rig_blob, expected.rig_blob);
  EXPECT_EQ(got->landmarks_blob, expected.landmarks_blob);
  EXPECT_EQ(got->components_blob, expected.components_blob);
}

TEST_P(MetadataStoreContract, RigsAreIsolatedPerTenant) {
  auto store = open();
  ASSERT_TRUE(store);
  ASSERT_TRUE(store->insertRig(makeRig("acme", "rig1", "acme.glb")).ok());
  auto other = store->insertRig(makeRig("globex", "rig1", "globex.glb"));
  ASSERT_TRUE(other.ok());
  EXPECT_TRUE(other->second) << "same id under another tenant must be a separate row";
  ASSERT_TRUE(store->insertRig(makeRig("", "rig2", "anon.glb")).ok());  // "" is an ordinary tenant

  EXPECT_EQ(store->getRig("acme", "rig1")->info.name, "acme.glb");
  EXPECT_EQ(store->getRig("globex", "rig1")->info.name, "globex.glb");
  EXPECT_FALSE(store->getRig("acme", "rig2"));
  EXPECT_TRUE(store->getRig("", "rig2"));
  EXPECT_EQ(store->listRigs("acme").size(), 1u);
  EXPECT_EQ(store->listRigs("").size(), 1u);
  EXPECT_TRUE(store->listRigs("nobody").empty());

  EXPECT_FALSE(store->deleteRig("acme", "rig2")) << "deleted another tenant's rig";
  EXPECT_TRUE(store->getRig("", "rig2"));
  EXPECT_TRUE(store->deleteRig("acme", "rig1"));
  EXPECT_FALSE(store->deleteRig("acme", "rig1"));
  EXPECT_FALSE(store->getRig("acme", "rig1"));
  EXPECT_TRUE(store->getRig("globex", "rig1"));
}

TEST_P(MetadataStoreContract, TenantAndIdValuesAreBoundNotSpliced) {
  auto store = open();
  ASSERT_TRUE(store);
  const std::string evil = "x' OR '1'='1";
  ASSERT_TRUE(store->insertRig(makeRig("acme", "rig1")).ok());
  ASSERT_TRUE(store->insertRig(makeRig(evil, "it's")).ok());
  EXPECT_FALSE(store->getRig(evil, "rig1"));
  EXPECT_TRUE(store->getRig(evil, "it's"));
  EXPECT_FALSE(store->deleteRig(evil, "rig1"));
  EXPECT_TRUE(store->getRig("acme", "rig1"));
}

// ---------------------------------------------------------------------------
// Metadata: jobs

TEST_P(MetadataStoreContract, InsertJobHonoursIdempotencyKeyPerTenant) {
  auto store = open();
  ASSERT_TRUE(store);
  auto first = store->insertJob(makeJob("acme", "job1", "key-1"));
  ASSERT_TRUE(first.ok()) << first.error().message;
  EXPECT_TRUE(first->second);
  EXPECT_GT(first->first.sequence, 0);

  auto repeat = store->insertJob(makeJob("acme", "job2", "key-1"));
  ASSERT_TRUE(repeat.ok()) << repeat.error().message;
  EXPECT_FALSE(repeat->second);
  EXPECT_EQ(repeat->first.id, "job1");
  EXPECT_EQ(repeat->first.sequence, first->first.sequence);
  EXPECT_FALSE(store->getJob("acme", "job2"));

  auto other_tenant = store->insertJob(makeJob("globex", "job3", "key-1"));
  ASSERT_TRUE(other_tenant.ok());
  EXPECT_TRUE(other_tenant->second);
  EXPECT_EQ(other_tenant->first.id, "job3");

  // Without a key every insert is a new job.
  ASSERT_TRUE(store->insertJob(makeJob("acme", "job4")).ok());
  auto job5 = store->insertJob(makeJob("acme", "job5"));
  ASSERT_TRUE(job5.ok());
  EXPECT_TRUE(job5->second);

  // A duplicate id is refused, not silently merged.
  auto dup = store->insertJob(makeJob("globex", "job1"));
  ASSERT_FALSE(dup.ok());
  EXPECT_EQ(dup.error().code, core::ErrorCode::kInvalidArgument);

  auto got = store->getJob("acme", "job1");
  ASSERT_TRUE(got);
  const JobRecord expected = makeJob("acme", "job1", "key-1");
  EXPECT_EQ(got->inputs, expected.inputs);
  EXPECT_EQ(got->input_names, expected.input_names);
  EXPECT_EQ(got->spec_json, expected.spec_json);
  EXPECT_EQ(got->kind, api::JobKind::kTransfer);
  EXPECT_EQ(got->rig, "rig1");
  EXPECT_EQ(got->status, JobStatus::kQueued);
  EXPECT_EQ(got->stage, "queued");
  EXPECT_EQ(got->attempts, 0);
  EXPECT_EQ(got->created_ms, expected.created_ms);
  EXPECT_FALSE(store->getJob("globex", "job1")) << "another tenant's job was visible";
}

TEST_P(MetadataStoreContract, ListJobsPagesBySequenceAndFiltersByStatus) {
  auto store = open();
  ASSERT_TRUE(store);
  for (int i = 0; i < 5; ++i) {
    ASSERT_TRUE(store->insertJob(makeJob("acme", "a" + std::to_string(i))).ok());
    ASSERT_TRUE(store->insertJob(makeJob("globex", "g" + std::to_string(i))).ok());
  }
  ASSERT_TRUE(store->markRunning("a1", 1, false).ok());
  ASSERT_TRUE(store->markRunning("a3", 1, false).ok());
  ASSERT_TRUE(store->markFinished(finished(makeJob("acme", "a3"), JobStatus::kSucceeded)).ok());

  JobListQuery q;
  q.tenant = "acme";
  q.limit = 2;
  std::vector<std::string> all;
  for (int page = 0; page < 10; ++page) {
    auto items = store->listJobs(q);
    if (items.empty()) break;
    EXPECT_LE(items.size(), 2u);
    for (const auto& j : items) {
      EXPECT_EQ(j.tenant, "acme");
      all.push_back(j.id);
    }
    q.after_sequence = items.back().sequence;
  }
  EXPECT_EQ(all, (std::vector<std::string>{"a0", "a1", "a2", "a3", "a4"}));

  JobListQuery queued;
  queued.tenant = "acme";
  queued.status = JobStatus::kQueued;
  EXPECT_EQ(idsOf(store->listJobs(queued)), (std::vector<std::string>{"a0", "a2", "a4"}));
  queued.after_sequence = store->getJob("acme", "a0")->sequence;
  queued.limit = 1;
  EXPECT_EQ(idsOf(store->listJobs(queued)), (std::vector<std::string>{"a2"}));

  JobListQuery succeeded;
  succeeded.tenant = "acme";
  succeeded.status = JobStatus::kSucceeded;
  EXPECT_EQ(idsOf(store->listJobs(succeeded)), (std::vector<std::string>{"a3"}));
  succeeded.tenant = "globex";
  EXPECT_TRUE(store->listJobs(succeeded).empty());
}

TEST_P(MetadataStoreContract, TransitionsCountAttemptsAndRefuseToOverwriteFinalJobs) {
  auto store = open();
  ASSERT_TRUE(store);
  ASSERT_TRUE(store->insertJob(makeJob("acme", "job1")).ok());

  ASSERT_TRUE(store->markRunning("job1", 111, true).ok());
  auto running = store->getJob("acme", "job1");
  ASSERT_TRUE(running);
  EXPECT_EQ(running->status, JobStatus::kRunning);
  EXPECT_EQ(running->attempts, 1);
  EXPECT_EQ(running->started_ms, 111);
  EXPECT_TRUE(running->cache_hit);
  EXPECT_FALSE(store->markRunning("job1", 112, false).ok()) << "started a running job twice";

  ASSERT_TRUE(store->requeue("job1").ok());
  EXPECT_EQ(store->getJob("acme", "job1")->status, JobStatus::kQueued);
  ASSERT_TRUE(store->markRunning("job1", 222, false).ok());
  EXPECT_EQ(store->getJob("acme", "job1")->attempts, 2);
  EXPECT_EQ(store->getJob("acme", "job1")->started_ms, 222);

  auto not_final = store->markFinished(makeJob("acme", "job1"));  // status queued
  ASSERT_FALSE(not_final.ok());
  EXPECT_EQ(not_final.error().code, core::ErrorCode::kInvalidArgument);

  ASSERT_TRUE(store->markFinished(finished(makeJob("acme", "job1"), JobStatus::kSucceeded)).ok());
  auto done = store->getJob("acme", "job1");
  ASSERT_TRUE(done);
  EXPECT_EQ(done->status, JobStatus::kSucceeded);
  EXPECT_EQ(done->stage, "done");
  EXPECT_EQ(done->result_blob, std::string(64, '1'));
  EXPECT_EQ(done->diagnostics_blob, std::string(64, '2'));
  EXPECT_EQ(done->timings_json, R"({"warp":12.5})");
  EXPECT_EQ(done->finished_ms, 1700000005000);

  // A late cancel (or a late success after a cancel) must not overwrite it.
  auto late = store->markFinished(finished(makeJob("acme", "job1"), JobStatus::kCancelled));
  ASSERT_FALSE(late.ok());
  EXPECT_EQ(late.error().code, core::ErrorCode::kInvalidArgument);
  EXPECT_NE(late.error().message.find("succeeded"), std::string::npos) << late.error().message;
  EXPECT_EQ(store->getJob("acme", "job1")->status, JobStatus::kSucceeded);
  EXPECT_EQ(store->getJob("acme", "job1")->result_blob, std::string(64, '1'));
  EXPECT_FALSE(store->requeue("job1").ok());
  EXPECT_FALSE(store->markRunning("job1", 333, false).ok());

  // Cancelled while queued: the worker may not start it, a late success is refused.
  ASSERT_TRUE(store->insertJob(makeJob("acme", "job2")).ok());
  JobRecord cancel = finished(makeJob("acme", "job2"), JobStatus::kCancelled);
  cancel.stage = "";  // keeps the stored stage
  ASSERT_TRUE(store->markFinished(cancel).ok());
  EXPECT_EQ(store->getJob("acme", "job2")->stage, "queued");
  EXPECT_FALSE(store->markRunning("job2", 1, false).ok());
  EXPECT_FALSE(store->markFinished(finished(makeJob("acme", "job2"), JobStatus::kSucceeded)).ok());
  EXPECT_EQ(store->getJob("acme", "job2")->status, JobStatus::kCancelled);
  EXPECT_EQ(store->getJob("acme", "job2")->error_json, R"({"title":"stopped"})");

  auto unknown = store->markRunning("nope", 1, false);
  ASSERT_FALSE(unknown.ok());
  EXPECT_NE(unknown.error().message.find("nope"), std::string::npos);
  EXPECT_FALSE(store->requeue("nope").ok());
}

TEST_P(MetadataStoreContract, DataSurvivesReopenAndUnfinishedJobsAreRecovered) {
  const std::string location = freshLocation();
  {
    auto store = openStore(location);
    ASSERT_TRUE(store);
    ASSERT_TRUE(store->insertRig(makeRig("acme", "rig1")).ok());
    for (const char* id : {"j1", "j2", "j3", "j4"}) ASSERT_TRUE(store->insertJob(makeJob("acme", id, id)).ok());
    ASSERT_TRUE(store->markRunning("j2", 5, false).ok());
    ASSERT_TRUE(store->markRunning("j3", 5, false).ok());
    ASSERT_TRUE(store->markFinished(finished(makeJob("acme", "j3"), JobStatus::kFailed)).ok());
  }
  auto store = openStore(location);
  ASSERT_TRUE(store);
  EXPECT_TRUE(store->getRig("acme", "rig1"));
  auto unfinished = store->unfinishedJobs();
  EXPECT_EQ(idsOf(unfinished), (std::vector<std::string>{"j1", "j2", "j4"}));
  ASSERT_EQ(unfinished.size(), 3u);
  EXPECT_EQ(unfinished[1].status, JobStatus::kRunning);
  EXPECT_EQ(store->getJob("acme", "j3")->status, JobStatus::kFailed);
  EXPECT_EQ(store->getJob("acme", "j3")->error_json, R"({"title":"stopped"})");

  for (const auto& job : unfinished) {
    if (job.status == JobStatus::kRunning) {
      ASSERT_TRUE(store->requeue(job.id).ok());
    }
  }
  EXPECT_EQ(store->getJob("acme", "j2")->status, JobStatus::kQueued);
  ASSERT_TRUE(store->markRunning("j2", 6, false).ok());
  EXPECT_EQ(store->getJob("acme", "j2")->attempts, 2);

  // The idempotency index survived too.
  auto repeat = store->insertJob(makeJob("acme", "j9", "j1"));
  ASSERT_TRUE(repeat.ok());
  EXPECT_FALSE(repeat->second);
  // Sequences keep growing after a reopen (AUTOINCREMENT), so cursors stay valid.
  auto fresh = store->insertJob(makeJob("acme", "j5"));
  ASSERT_TRUE(fresh.ok());
  EXPECT_GT(fresh->first.sequence, store->getJob("acme", "j4")->sequence);
}

TEST_P(MetadataStoreContract, CountJobsByStatusCoversAllStatuses) {
  auto store = open();
  ASSERT_TRUE(store);
  auto empty = store->countJobsByStatus();
  EXPECT_EQ(empty.size(), 5u);
  for (const auto& [status, n] : empty) EXPECT_EQ(n, 0) << api::jobStatusName(status);

  for (int i = 0; i < 6; ++i) ASSERT_TRUE(store->insertJob(makeJob(i % 2 ? "a" : "b", "j" + std::to_string(i))).ok());
  ASSERT_TRUE(store->markRunning("j0", 1, false).ok());
  ASSERT_TRUE(store->markRunning("j1", 1, false).ok());
  ASSERT_TRUE(store->markFinished(finished(makeJob("b", "j1"), JobStatus::kSucceeded)).ok());
  ASSERT_TRUE(store->markFinished(finished(makeJob("a", "j2"), JobStatus::kCancelled)).ok());
  ASSERT_TRUE(store->markRunning("j3", 1, false).ok());
  ASSERT_TRUE(store->markFinished(finished(makeJob("a", "j3"), JobStatus::kFailed)).ok());
  auto counts = store->countJobsByStatus();
  EXPECT_EQ(counts[JobStatus::kQueued], 2);
  EXPECT_EQ(counts[JobStatus::kRunning], 1);
  EXPECT_EQ(counts[JobStatus::kSucceeded], 1);
  EXPECT_EQ(counts[JobStatus::kFailed], 1);
  EXPECT_EQ(counts[JobStatus::kCancelled], 1);
}

TEST_P(MetadataStoreContract, BlobReferencedSeesEveryReferencingColumn) {
  auto store = open();
  ASSERT_TRUE(store);
  const auto h = [](char c) { return std::string(64, c); };
  RigRecord rig = makeRig("acme", "rig1");  // a, b, c
  ASSERT_TRUE(store->insertRig(rig).ok());
  RigRecord bare = makeRig("acme", "rig2");
  bare.rig_blob = h('a');
  bare.landmarks_blob = h('b');
  bare.components_blob = "";
  ASSERT_TRUE(store->insertRig(bare).ok());
  JobRecord job = makeJob("acme", "job1");  // inputs d, e
  ASSERT_TRUE(store->insertJob(job).ok());
  ASSERT_TRUE(store->markRunning("job1", 1, false).ok());
  ASSERT_TRUE(store->markFinished(finished(job, JobStatus::kSucceeded)).ok());  // 1, 2, 3
  EXPECT_EQ(store->getJob("acme", "job1")->components_blob, h('3'));

  for (char c : {'a', 'b', 'c', 'd', 'e', '1', '2', '3'}) EXPECT_TRUE(store->blobReferenced(h(c))) << c;
  EXPECT_FALSE(store->blobReferenced(h('9')));
  EXPECT_FALSE(store->blobReferenced(""));

  ASSERT_TRUE(store->deleteRig("acme", "rig1"));
  EXPECT_FALSE(store->blobReferenced(h('c')));
  EXPECT_TRUE(store->blobReferenced(h('a'))) << "still referenced by rig2";
}

TEST_P(MetadataStoreContract, DeleteFinishedJobTakesOnlyTheTenantsFinalJobAndItsInputRows) {
  auto store = open();
  ASSERT_TRUE(store);
  const auto h = [](char c) { return std::string(64, c); };
  JobRecord job = makeJob("acme", "job1");  // inputs d, e
  ASSERT_TRUE(store->insertJob(job).ok());
  JobRecord sharing = makeJob("acme", "job2");  // the same input bytes, still queued
  ASSERT_TRUE(store->insertJob(sharing).ok());

  auto queued = store->deleteFinishedJob("acme", "job1");
  ASSERT_TRUE(queued.ok());
  EXPECT_FALSE(*queued) << "a queued job was deleted";
  ASSERT_TRUE(store->markRunning("job1", 1, false).ok());
  EXPECT_FALSE(*store->deleteFinishedJob("acme", "job1")) << "a running job was deleted";
  ASSERT_TRUE(store->markFinished(finished(job, JobStatus::kSucceeded)).ok());
  EXPECT_FALSE(*store->deleteFinishedJob("globex", "job1")) << "another tenant deleted it";
  EXPECT_TRUE(store->getJob("acme", "job1"));

  auto deleted = store->deleteFinishedJob("acme", "job1");
  ASSERT_TRUE(deleted.ok());
  EXPECT_TRUE(*deleted);
  EXPECT_FALSE(store->getJob("acme", "job1"));
  EXPECT_FALSE(*store->deleteFinishedJob("acme", "job1")) << "deleted twice";
  EXPECT_FALSE(store->blobReferenced(h('1')));
  EXPECT_FALSE(store->blobReferenced(h('2')));
  EXPECT_TRUE(store->blobReferenced(h('d'))) << "job2 still uses the target";

  ASSERT_TRUE(store->markFinished(finished(sharing, JobStatus::kCancelled)).ok());
  ASSERT_TRUE(*store->deleteFinishedJob("acme", "job2"));
  EXPECT_FALSE(store->blobReferenced(h('d'))) << "input rows outlived their job";
  EXPECT_FALSE(store->blobReferenced(h('e')));
  EXPECT_TRUE(idsOf(store->listJobs(JobListQuery{"acme", {}, 0, 50})).empty());
}

TEST_P(MetadataStoreContract, FinishedJobsBeforeListsExpiredFinalJobsOldestFirst) {
  auto store = open();
  ASSERT_TRUE(store);
  const std::vector<std::pair<std::string, std::int64_t>> finishing = {{"late", 3000}, {"early", 1000}, {"middle", 2000}};
  for (const auto& [id, at] : finishing) {
    JobRecord job = makeJob(id == "middle" ? "globex" : "acme", id);
    ASSERT_TRUE(store->insertJob(job).ok());
    JobRecord done = finished(job, JobStatus::kFailed);
    done.finished_ms = at;
    ASSERT_TRUE(store->markFinished(done).ok());
  }
  ASSERT_TRUE(store->insertJob(makeJob("acme", "waiting")).ok());  // unfinished: never expires

  using Key = std::pair<std::string, std::string>;
  EXPECT_EQ(store->finishedJobsBefore(2500, 10), (std::vector<Key>{{"acme", "early"}, {"globex", "middle"}}));
  EXPECT_EQ(store->finishedJobsBefore(1000, 10), std::vector<Key>{});
  EXPECT_EQ(store->finishedJobsBefore(1'000'000, 1), (std::vector<Key>{{"acme", "early"}}));
  EXPECT_EQ(store->finishedJobsBefore(1'000'000, 10).size(), 3u);
}

TEST_P(MetadataStoreContract, ConcurrentWritersAllLand) {
  auto store = open();
  ASSERT_TRUE(store);
  constexpr int kThreads = 4, kPerThread = 10;
  std::vector<std::thread> threads;
  std::atomic<int> failures{0};
  for (int t = 0; t < kThreads; ++t) {
    threads.emplace_back([&, t] {
      for (int i = 0; i < kPerThread; ++i) {
        const std::string id = "t" + std::to_string(t) + "-" + std::to_string(i);
        if (!store->insertJob(makeJob("acme", id, "k" + std::to_string(i))).ok()) ++failures;
        if (!store->insertRig(makeRig("acme", id)).ok()) ++failures;
        store->listJobs(JobListQuery{"acme", std::nullopt, 0, 5});
      }
    });
  }
  for (auto& th : threads) th.join();
  EXPECT_EQ(failures.load(), 0);
  // Ten distinct idempotency keys: exactly ten jobs, whichever thread won each key.
  EXPECT_EQ(store->countJobsByStatus()[JobStatus::kQueued], kPerThread);
  EXPECT_EQ(store->listRigs("acme").size(), static_cast<std::size_t>(kThreads * kPerThread));
}


// ---------------------------------------------------------------------------
// The job queue: claims, leases, fencing

TEST_P(MetadataStoreContract, ClaimsTakeTheOldestQueuedJobUnderALease) {
  auto store = open();
  ASSERT_TRUE(store);
  for (const char* id : {"j1", "j2", "j3"}) ASSERT_TRUE(store->insertJob(makeJob("acme", id)).ok());
  ASSERT_TRUE(store->markFinished(finished(makeJob("acme", "j2"), JobStatus::kCancelled)).ok());
  const std::int64_t before = server::store_sql::nowMs();
  auto first = store->claimNextJob("replica-a", 30'000);
  ASSERT_TRUE(first.ok()) << first.error().message;
  ASSERT_TRUE(first->has_value());
  EXPECT_EQ((*first)->id, "j1");
  EXPECT_EQ((*first)->status, JobStatus::kRunning);
  EXPECT_EQ((*first)->attempts, 1);
  EXPECT_EQ((*first)->lease_owner, "replica-a");
  // The store's clock (PostgreSQL: the server's) grants it; same machine here.
  EXPECT_GE((*first)->lease_expires_ms, before + 30'000 - 1000);
  EXPECT_LE((*first)->lease_expires_ms, server::store_sql::nowMs() + 30'000 + 1000);
  EXPECT_EQ(store->getJob("acme", "j1")->lease_owner, "replica-a");
  auto second = store->claimNextJob("replica-b", 30'000);
  ASSERT_TRUE(second.ok() && second->has_value());
  EXPECT_EQ((*second)->id, "j3") << "a cancelled job is never claimed";
  auto none = store->claimNextJob("replica-a", 30'000);
  ASSERT_TRUE(none.ok());
  EXPECT_FALSE(none->has_value());
  EXPECT_EQ(*store->queuedJobs(), 0);
  EXPECT_TRUE(store->requeueExpiredLeases()->empty()) << "live leases are not expired";
}

TEST_P(MetadataStoreContract, AnExpiredLeaseIsRequeuedAndItsOldAttemptFenced) {
  auto store = open();
  ASSERT_TRUE(store);
  ASSERT_TRUE(store->insertJob(makeJob("acme", "j1")).ok());
  auto a = store->claimNextJob("replica-a", 1);  // a lease of 1 ms: replica a "dies"
  ASSERT_TRUE(a.ok() && a->has_value());
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  auto expired = store->requeueExpiredLeases();
  ASSERT_TRUE(expired.ok()) << expired.error().message;
  EXPECT_EQ(*expired, std::vector<std::string>{"j1"});
  EXPECT_EQ(store->getJob("acme", "j1")->status, JobStatus::kQueued);
  EXPECT_EQ(store->getJob("acme", "j1")->lease_owner, "");

  auto b = store->claimNextJob("replica-b", 30'000);
  ASSERT_TRUE(b.ok() && b->has_value());
  EXPECT_EQ((*b)->attempts, 2);
  // Replica a wakes up: its heartbeat finds the lease gone, its writes are refused.
  auto renewed = store->renewLeases("replica-a", {{"j1", 1, "warp", 0.5}}, 30'000);
  ASSERT_TRUE(renewed.ok());
  EXPECT_EQ(*renewed, std::vector<server::LeaseState>{server::LeaseState::kLost});
  JobRecord stale = finished(makeJob("acme", "j1"), JobStatus::kSucceeded);
  stale.result_blob = std::string(64, 'a');
  auto refused = store->markFinished(stale, 1);
  ASSERT_FALSE(refused.ok());
  EXPECT_EQ(refused.error().code, core::ErrorCode::kInvalidArgument);
  EXPECT_NE(refused.error().message.find("lost its lease"), std::string::npos) << refused.error().message;
  EXPECT_FALSE(store->requeue("j1", 1).ok());
  EXPECT_EQ(store->getJob("acme", "j1")->status, JobStatus::kRunning);

  JobRecord fresh = finished(makeJob("acme", "j1"), JobStatus::kSucceeded);
  fresh.result_blob = std::string(64, 'b');
  ASSERT_TRUE(store->markFinished(fresh, 2).ok());
  EXPECT_EQ(store->getJob("acme", "j1")->result_blob, std::string(64, 'b'));
  EXPECT_FALSE(store->markFinished(stale, 1).ok()) << "a final job is never overwritten";
  EXPECT_EQ(store->getJob("acme", "j1")->lease_owner, "") << "a finished job holds no lease";
}

TEST_P(MetadataStoreContract, HeartbeatsRecordProgressAndCarryCancelRequests) {
  auto store = open();
  ASSERT_TRUE(store);
  ASSERT_TRUE(store->insertJob(makeJob("acme", "j1")).ok());
  ASSERT_TRUE(store->insertJob(makeJob("acme", "j2")).ok());
  EXPECT_FALSE(store->requestCancel("j1").ok()) << "a queued job is cancelled directly, not asked";
  ASSERT_TRUE(store->claimNextJob("replica-a", 1000)->has_value());
  auto renewed = store->renewLeases("replica-a", {{"j1", 1, "correspond", 0.25}}, 60'000);
  ASSERT_TRUE(renewed.ok()) << renewed.error().message;
  EXPECT_EQ(*renewed, std::vector<server::LeaseState>{server::LeaseState::kHeld});
  auto seen = store->getJob("acme", "j1");
  EXPECT_EQ(seen->stage, "correspond");
  EXPECT_DOUBLE_EQ(seen->progress, 0.25);
  EXPECT_GT(seen->lease_expires_ms, server::store_sql::nowMs() + 50'000) << "renewed for the new lease length";
  EXPECT_FALSE(seen->cancel_requested);

  ASSERT_TRUE(store->requestCancel("j1").ok());
  EXPECT_TRUE(store->getJob("acme", "j1")->cancel_requested);
  // Another replica's name does not renew it; the owner's heartbeat sees the request.
  EXPECT_EQ(*store->renewLeases("replica-b", {{"j1", 1, "x", 0.0}}, 60'000),
            std::vector<server::LeaseState>{server::LeaseState::kLost});
  EXPECT_EQ(*store->renewLeases("replica-a", {{"j1", 1, "transfer", 0.5}}, 60'000),
            std::vector<server::LeaseState>{server::LeaseState::kCancelRequested});
  EXPECT_EQ(*store->queuedJobs(), 1);
}

TEST_P(MetadataStoreContract, ConcurrentClaimersNeverClaimOneJobTwice) {
  const std::string location = freshLocation();
  constexpr int kStores = 4, kThreadsPerStore = 2, kJobs = 120;
  std::vector<std::unique_ptr<MetadataStore>> stores;
  for (int i = 0; i < kStores; ++i) {
    stores.push_back(openStore(location));
    ASSERT_TRUE(stores.back());
  }
  for (int i = 0; i < kJobs; ++i) ASSERT_TRUE(stores[0]->insertJob(makeJob("acme", "j" + std::to_string(i))).ok());
  std::mutex mutex;
  std::map<std::string, int> claims;
  std::atomic<int> failures{0};
  std::vector<std::thread> threads;
  for (int t = 0; t < kStores * kThreadsPerStore; ++t) {
    threads.emplace_back([&, t] {
      MetadataStore& store = *stores[t % kStores];
      for (;;) {
        auto claimed = store.claimNextJob("worker-" + std::to_string(t), 30'000);
        if (!claimed) {
          ++failures;
          continue;
        }
        if (!*claimed) return;
        std::lock_guard lock(mutex);
        ++claims[(*claimed)->id];
      }
    });
  }
  for (auto& th : threads) th.join();
  EXPECT_EQ(failures.load(), 0);
  EXPECT_EQ(claims.size(), static_cast<std::size_t>(kJobs));
  for (const auto& [id, n] : claims) EXPECT_EQ(n, 1) << id << " claimed " << n << " times";
  EXPECT_EQ(stores[0]->countJobsByStatus()[JobStatus::kRunning], kJobs);
}

// Admission against the queue capacity: a job past it is refused and nothing
// is stored; a replay of an idempotency key is answered even when full; and
// processes admitting at once (stores of their own) never overshoot it.
TEST_P(MetadataStoreContract, AdmissionNeverOvershootsTheQueueCapacity) {
  const std::string location = freshLocation();
  {
    auto store = openStore(location);
    ASSERT_TRUE(store);
    ASSERT_TRUE(store->admitJob(makeJob("acme", "a1", "key-a1"), 2)->inserted);
    ASSERT_TRUE(store->admitJob(makeJob("globex", "g1"), 2)->inserted);
    auto full = store->admitJob(makeJob("acme", "a2"), 2);
    ASSERT_TRUE(full.ok()) << full.error().message;
    EXPECT_TRUE(full->queue_full);
    EXPECT_FALSE(full->inserted);
    EXPECT_FALSE(store->getJob("acme", "a2").has_value()) << "a refused job is not stored";
    auto replay = store->admitJob(makeJob("acme", "a3", "key-a1"), 2);
    ASSERT_TRUE(replay.ok()) << replay.error().message;
    EXPECT_FALSE(replay->queue_full) << "a replay is answered whatever the queue holds";
    EXPECT_EQ(replay->job.id, "a1");
    ASSERT_TRUE(store->claimNextJob("worker", 30'000)->has_value());  // a claim frees a place
    EXPECT_TRUE(store->admitJob(makeJob("acme", "a4"), 2)->inserted);
    EXPECT_TRUE(store->admitJob(makeJob("acme", "a5"), 2)->queue_full);
    EXPECT_TRUE(store->admitJob(makeJob("acme", "a6"), 0)->inserted) << "0: no capacity";
  }
  // Rounds of eight stores admitting at the same instant into a queue with
  // room for three: each round admits exactly three.
  const std::string shared = freshLocation();
  constexpr int kStores = 8, kRounds = 25, kCapacity = 3;
  std::vector<std::unique_ptr<MetadataStore>> stores;
  for (int i = 0; i < kStores; ++i) {
    stores.push_back(openStore(shared));
    ASSERT_TRUE(stores.back());
  }
  for (int round = 0; round < kRounds; ++round) {
    std::atomic<int> admitted{0}, refused{0}, failures{0}, ready{0};
    std::vector<std::thread> threads;
    for (int t = 0; t < kStores; ++t) {
      threads.emplace_back([&, t] {
        ++ready;
        while (ready.load() < kStores) std::this_thread::yield();
        auto r = stores[static_cast<std::size_t>(t)]->admitJob(
            makeJob("acme", "r" + std::to_string(round) + "-" + std::to_string(t)), kCapacity);
        if (!r) {
          ++failures;
        } else if (r->queue_full) {
          ++refused;
        } else {
          ++admitted;
        }
      });
    }
    for (auto& th : threads) th.join();
    ASSERT_EQ(failures.load(), 0) << "round " << round;
    ASSERT_EQ(admitted.load(), kCapacity) << "round " << round;
    ASSERT_EQ(refused.load(), kStores - kCapacity) << "round " << round;
    for (int k = 0; k < kCapacity; ++k) ASSERT_TRUE(stores[0]->claimNextJob("worker", 30'000)->has_value());
  }
}

}  // namespace

// ---------------------------------------------------------------------------
// PostgreSQL only: schema under the advisory lock, replicas sharing one
// database, a connection lost and found, errors that name the server.

namespace {

class PostgresStore : public ::testing::Test {
 protected:
  void SetUp() override {
    if (testPostgresUrl().empty()) GTEST_SKIP() << kNoPostgres;
  }
  std::string freshLocation() const {
    return freshPostgresLocation(::testing::UnitTest::GetInstance()->current_test_info()->name());
  }
};

TEST_F(PostgresStore, ReplicasStartingTogetherCreateTheSchemaOnce) {
  const std::string location = freshLocation();
  constexpr int kReplicas = 8;
  std::vector<std::unique_ptr<MetadataStore>> stores(kReplicas);
  std::vector<std::string> errors(kReplicas);
  std::vector<std::thread> threads;
  for (int r = 0; r < kReplicas; ++r) {
    threads.emplace_back([&, r] {
      auto opened = MetadataStore::open(location);
      if (opened) {
        stores[static_cast<std::size_t>(r)] = std::move(*opened);
      } else {
        errors[static_cast<std::size_t>(r)] = opened.error().message;
      }
    });
  }
  for (auto& t : threads) t.join();
  for (int r = 0; r < kReplicas; ++r) {
    ASSERT_TRUE(stores[static_cast<std::size_t>(r)]) << "replica " << r << ": " << errors[static_cast<std::size_t>(r)];
    EXPECT_STREQ(stores[static_cast<std::size_t>(r)]->backend(), "postgresql");
  }
  ASSERT_TRUE(stores[0]->insertRig(makeRig("acme", "rig1")).ok());
  EXPECT_TRUE(stores[kReplicas - 1]->getRig("acme", "rig1")) << "the replicas do not share one database";
}

// LISTEN/NOTIFY: a job queued through one replica's store wakes a replica
// waiting on another (the hint its idle workers get; they also poll).
TEST_F(PostgresStore, AJobQueuedOnOneReplicaIsAnnouncedToTheOthers) {
  const std::string location = freshLocation();
  auto waiting = openStore(location);
  auto submitting = openStore(location);
  ASSERT_TRUE(waiting && submitting);
  // Listening from here on; what other tests on this database announced is drained.
  for (int i = 0; i < 100; ++i) {
    auto pending = waiting->waitForQueuedJobs(std::chrono::milliseconds(0));
    ASSERT_TRUE(pending.ok()) << pending.error().message;
    if (!*pending) break;
  }
  std::thread submit([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    EXPECT_TRUE(submitting->insertJob(makeJob("acme", "announced")).ok());
  });
  auto announced = waiting->waitForQueuedJobs(std::chrono::seconds(30));
  submit.join();
  ASSERT_TRUE(announced.ok()) << announced.error().message;
  EXPECT_TRUE(*announced);
}

TEST_F(PostgresStore, ReplicasShareJobsAndOneIdempotencyKeyMakesOneJob) {
  const std::string location = freshLocation();
  auto a = openStore(location);
  auto b = openStore(location);
  ASSERT_TRUE(a && b);
  // The same key submitted through both replicas at once, many times.
  constexpr int kKeys = 20;
  std::atomic<int> failures{0};
  std::vector<std::thread> threads;
  for (MetadataStore* store : {a.get(), b.get()}) {
    threads.emplace_back([&, store] {
      for (int k = 0; k < kKeys; ++k) {
        const std::string id = std::string(store == a.get() ? "a" : "b") + std::to_string(k);
        if (!store->insertJob(makeJob("acme", id, "key-" + std::to_string(k))).ok()) ++failures;
      }
    });
  }
  for (auto& t : threads) t.join();
  EXPECT_EQ(failures.load(), 0);
  EXPECT_EQ(a->countJobsByStatus()[JobStatus::kQueued], kKeys);
  // A job one replica stored, the other runs and finishes; a late finish from
  // the first is refused.
  const auto listed = a->listJobs(JobListQuery{"acme", std::nullopt, 0, 1});
  ASSERT_EQ(listed.size(), 1u);
  const std::string id = listed.front().id;
  ASSERT_TRUE(b->markRunning(id, 1, false).ok());
  ASSERT_TRUE(b->markFinished(finished(listed.front(), JobStatus::kSucceeded)).ok());
  auto late = a->markFinished(finished(listed.front(), JobStatus::kFailed));
  ASSERT_FALSE(late.ok());
  EXPECT_NE(late.error().message.find("succeeded"), std::string::npos) << late.error().message;
  EXPECT_EQ(a->getJob("acme", id)->status, JobStatus::kSucceeded);
}

TEST_F(PostgresStore, AConnectionTheServerDroppedIsMadeAgain) {
  const std::string schema_location = freshLocation();
  const std::string application = "rigport_drop_" + std::to_string(::getpid());
  const std::string location = schema_location + "&application_name=" + application;
  auto store = openStore(location);
  ASSERT_TRUE(store);
  ASSERT_TRUE(store->insertRig(makeRig("acme", "rig1")).ok());
  runPostgres(testPostgresUrl(),
              "SELECT pg_terminate_backend(pid) FROM pg_stat_activity WHERE application_name = '" + application + "'");
  // The call that finds the connection gone fails (whether it wrote is not
  // known to it, so it is not retried blindly); the next one reconnects.
  int failed = 0;
  while (!store->probeWrite().ok() && failed < 3) ++failed;
  EXPECT_LE(failed, 1);
  EXPECT_TRUE(store->getRig("acme", "rig1"));
}

// A store written at schema 4 (before jobs had components results and
// leases) is upgraded in place on open, keeping its rows; a job it left
// running has no lease, so the first scan for expired leases requeues it.
TEST_F(PostgresStore, AnOlderSchemaIsUpgradedInPlace) {
  const std::string location = freshLocation();
  {
    auto store = openStore(location);
    ASSERT_TRUE(store);
    ASSERT_TRUE(store->insertRig(makeRig("acme", "old")).ok());
    ASSERT_TRUE(store->insertJob(makeJob("acme", "left-running")).ok());
    ASSERT_TRUE(store->markRunning("left-running", 1, false).ok());
  }
  runPostgres(location, std::string(kDropSchemaSixSql) +
                            "DROP INDEX jobs_components_blob; ALTER TABLE jobs DROP COLUMN components_blob; "
                            "UPDATE rigport_schema SET version = 4");
  auto store = openStore(location);
  ASSERT_TRUE(store);
  EXPECT_TRUE(store->getRig("acme", "old"));
  const JobRecord job = makeJob("acme", "after-upgrade");
  ASSERT_TRUE(store->insertJob(job).ok());
  ASSERT_TRUE(store->markFinished(finished(job, JobStatus::kSucceeded)).ok());
  EXPECT_EQ(store->getJob("acme", "after-upgrade")->components_blob, std::string(64, '3'))
      << "version 5's components column must exist";
  auto expired = store->requeueExpiredLeases();
  ASSERT_TRUE(expired.ok()) << expired.error().message;
  EXPECT_EQ(*expired, std::vector<std::string>{"left-running"});
}

TEST_F(PostgresStore, ANewerSchemaIsRefusedNamingTheDatabase) {
  const std::string location = freshLocation();
  ASSERT_TRUE(openStore(location));
  runPostgres(location, "UPDATE rigport_schema SET version = 99");
  auto store = MetadataStore::open(location);
  ASSERT_FALSE(store.ok());
  EXPECT_EQ(store.error().code, core::ErrorCode::kUnsupported);
  EXPECT_NE(store.error().message.find("99"), std::string::npos) << store.error().message;
  EXPECT_NE(store.error().message.find("/rigport_test"), std::string::npos) << store.error().message;
}

TEST(PostgresStoreOpen, AnUnreachableServerIsAnErrorNamingItButNotThePassword) {
  // Port 1 on loopback: nothing listens there.
  auto store = MetadataStore::open(std::string("postgresql://rigport:s3cret@127.0.0.1:1/studio?connect_timeout=2"));
  ASSERT_FALSE(store.ok());
  EXPECT_EQ(store.error().code, core::ErrorCode::kIo);
  EXPECT_NE(store.error().message.find("127.0.0.1:1/studio"), std::string::npos) << store.error().message;
  EXPECT_EQ(store.error().message.find("s3cret"), std::string::npos) << store.error().message;
}

}  // namespace
