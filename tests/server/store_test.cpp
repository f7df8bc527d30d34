// Tests server/blob_store.cpp and server/metadata_store.cpp: content-addressed blobs (round trip, idempotence,
// hash verification, adopt, temp cleanup), the SQLite metadata store (rigs and
// jobs per tenant, idempotency keys, paging, transitions, persistence across
// reopen, blob references) and durability under SIGKILL of a writer process.
#include "api/content_id.h"
#include "server/store.h"

#include <signal.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <sqlite3.h>

#include <atomic>
#include <chrono>
#include <fstream>
#include <random>
#include <regex>
#include <set>
#include <sstream>
#include <thread>

#include <gtest/gtest.h>

#include "tests/test_support.h"

namespace {

namespace fs = std::filesystem;
using api::JobStatus;
using server::BlobStore;
using server::JobListQuery;
using server::JobRecord;
using server::MetadataStore;
using server::RigRecord;

std::vector<std::uint8_t> bytesOf(const std::string& s) { return {s.begin(), s.end()}; }

std::vector<std::uint8_t> randomBytes(std::size_t n, std::mt19937& rng) {
  std::vector<std::uint8_t> out(n);
  for (auto& b : out) b = static_cast<std::uint8_t>(rng());
  return out;
}

std::unique_ptr<MetadataStore> openStore(const fs::path& file) {
  auto store = MetadataStore::open(file);
  EXPECT_TRUE(store.ok()) << (store.ok() ? "" : store.error().message);
  return store.ok() ? std::move(*store) : nullptr;
}

RigRecord makeRig(const std::string& tenant, const std::string& id, const std::string& name = "head.glb") {
  RigRecord rig;
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

JobRecord makeJob(const std::string& tenant, const std::string& id, const std::string& key = "") {
  JobRecord job;
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

JobRecord finished(JobRecord job, JobStatus status) {
  job.status = status;
  job.stage = "done";
  job.finished_ms = 1700000005000;
  if (status == JobStatus::kSucceeded) {
    job.result_blob = std::string(64, '1');
    job.diagnostics_blob = std::string(64, '2');
    job.timings_json = R"({"warp":12.5})";
  } else {
    job.error_json = R"({"title":"stopped"})";
  }
  return job;
}

std::vector<std::string> idsOf(const std::vector<JobRecord>& jobs) {
  std::vector<std::string> ids;
  for (const auto& j : jobs) ids.push_back(j.id);
  return ids;
}

// ---------------------------------------------------------------------------
// Blobs

TEST(Sha256, MatchesKnownVectors) {
  EXPECT_EQ(api::sha256Hex(bytesOf("abc")), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
  EXPECT_EQ(api::sha256Hex(std::span<const std::uint8_t>{}), "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
  const fs::path dir = rigport_test::makeTempDir("sha");
  std::mt19937 rng(1);
  const auto bytes = randomBytes(300000, rng);  // several read chunks
  std::ofstream(dir / "f", std::ios::binary).write(reinterpret_cast<const char*>(bytes.data()), bytes.size());
  auto file_hash = server::sha256HexOfFile(dir / "f");
  ASSERT_TRUE(file_hash.ok()) << file_hash.error().message;
  EXPECT_EQ(*file_hash, api::sha256Hex(bytes));
  auto missing = server::sha256HexOfFile(dir / "missing");
  ASSERT_FALSE(missing.ok());
  EXPECT_NE(missing.error().message.find((dir / "missing").string()), std::string::npos) << missing.error().message;
}

TEST(SecureRandomHex, GivesDistinctLowerCaseHexOfTheAskedLength) {
  std::set<std::string> seen;
  for (int i = 0; i < 64; ++i) {
    auto hex = server::secureRandomHex(16);
    ASSERT_TRUE(hex);
    EXPECT_TRUE(std::regex_match(*hex, std::regex("[0-9a-f]{32}"))) << *hex;
    seen.insert(*hex);
  }
  EXPECT_EQ(seen.size(), 64u);
}

TEST(BlobStore, PutThenReadReturnsTheBytesUnderTheirHash) {
  BlobStore blobs(rigport_test::makeTempDir("blobs") / "store");
  const auto bytes = bytesOf("abc");
  auto hash = blobs.put(bytes);
  ASSERT_TRUE(hash.ok()) << hash.error().message;
  EXPECT_EQ(*hash, "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
  EXPECT_EQ(blobs.pathOf(*hash), blobs.root() / "ba" / *hash);
  EXPECT_TRUE(fs::is_regular_file(blobs.pathOf(*hash)));
  EXPECT_TRUE(blobs.contains(*hash));
  auto read = blobs.read(*hash);
  ASSERT_TRUE(read.ok()) << read.error().message;
  EXPECT_EQ(*read, bytes);

  auto empty = blobs.put({});
  ASSERT_TRUE(empty.ok());
  auto read_empty = blobs.read(*empty);
  ASSERT_TRUE(read_empty.ok()) << read_empty.error().message;
  EXPECT_TRUE(read_empty->empty());
}

TEST(BlobStore, PutOfExistingBlobDoesNotRewriteIt) {
  BlobStore blobs(rigport_test::makeTempDir("blobs"));
  auto first = blobs.put(bytesOf("same content"));
  ASSERT_TRUE(first.ok());
  struct stat before{};
  ASSERT_EQ(::stat(blobs.pathOf(*first).c_str(), &before), 0);
  auto second = blobs.put(bytesOf("same content"));
  ASSERT_TRUE(second.ok());
  EXPECT_EQ(*first, *second);
  struct stat after{};
  ASSERT_EQ(::stat(blobs.pathOf(*first).c_str(), &after), 0);
  EXPECT_EQ(before.st_ino, after.st_ino) << "an existing blob was replaced";
  EXPECT_TRUE(fs::is_empty(blobs.root() / "tmp")) << "temporary file left behind";
}

TEST(BlobStore, ReadRejectsCorruptedOrTruncatedBlob) {
  BlobStore blobs(rigport_test::makeTempDir("blobs"));
  auto hash = blobs.put(bytesOf("a rig file that will be damaged on disk"));
  ASSERT_TRUE(hash.ok());
  const fs::path path = blobs.pathOf(*hash);
  {
    std::fstream f(path, std::ios::in | std::ios::out | std::ios::binary);
    f.seekg(5);
    char c = 0;
    f.read(&c, 1);
    c = static_cast<char>(c ^ 0x01);
    f.seekp(5);
    f.write(&c, 1);
  }
  auto corrupted = blobs.read(*hash);
  ASSERT_FALSE(corrupted.ok()) << "a corrupted blob was served";
  EXPECT_EQ(corrupted.error().code, core::ErrorCode::kIo);
  EXPECT_NE(corrupted.error().message.find(path.string()), std::string::npos) << corrupted.error().message;

  fs::resize_file(path, 3);
  auto truncated = blobs.read(*hash);
  ASSERT_FALSE(truncated.ok()) << "a truncated blob was served";
  EXPECT_EQ(truncated.error().code, core::ErrorCode::kIo);

  // Putting the same bytes again repairs a blob whose size is wrong.
  ASSERT_TRUE(blobs.put(bytesOf("a rig file that will be damaged on disk")).ok());
  EXPECT_TRUE(blobs.read(*hash).ok());
}

TEST(BlobStore, ReadRejectsMissingBlobAndMalformedHash) {
  BlobStore blobs(rigport_test::makeTempDir("blobs"));
  auto missing = blobs.read(std::string(64, 'f'));
  ASSERT_FALSE(missing.ok());
  EXPECT_EQ(missing.error().code, core::ErrorCode::kIo);
  EXPECT_NE(missing.error().message.find(blobs.pathOf(std::string(64, 'f')).string()), std::string::npos);
  auto traversal = blobs.read("../../etc/passwd");
  ASSERT_FALSE(traversal.ok());
  EXPECT_EQ(traversal.error().code, core::ErrorCode::kInvalidArgument);
  EXPECT_FALSE(blobs.contains("../../etc/passwd"));
  EXPECT_FALSE(blobs.contains(std::string(64, 'A')));
}

TEST(BlobStore, AdoptMovesFileUnderItsHashAndConsumesDuplicates) {
  const fs::path dir = rigport_test::makeTempDir("adopt");
  BlobStore blobs(dir / "blobs");
  std::mt19937 rng(7);
  const auto bytes = randomBytes(200000, rng);
  const fs::path upload = dir / "upload.part";
  std::ofstream(upload, std::ios::binary).write(reinterpret_cast<const char*>(bytes.data()), bytes.size());

  auto hash = blobs.adopt(upload);
  ASSERT_TRUE(hash.ok()) << hash.error().message;
  EXPECT_EQ(*hash, api::sha256Hex(bytes));
  EXPECT_FALSE(fs::exists(upload));
  auto read = blobs.read(*hash);
  ASSERT_TRUE(read.ok()) << read.error().message;
  EXPECT_EQ(*read, bytes);

  // The same content again: the store keeps its copy and deletes the source.
  std::ofstream(upload, std::ios::binary).write(reinterpret_cast<const char*>(bytes.data()), bytes.size());
  auto again = blobs.adopt(upload);
  ASSERT_TRUE(again.ok()) << again.error().message;
  EXPECT_EQ(*again, *hash);
  EXPECT_FALSE(fs::exists(upload));

  auto missing = blobs.adopt(dir / "nope");
  ASSERT_FALSE(missing.ok());
  EXPECT_NE(missing.error().message.find((dir / "nope").string()), std::string::npos);
}

TEST(BlobStore, BlobIsNeverVisibleHalfWritten) {
  // A reader polling the final path while a large blob is written must see
  // either nothing or the whole, verified blob (the rename publishes it).
  BlobStore blobs(rigport_test::makeTempDir("visible"));
  std::mt19937 rng(3);
  const auto bytes = randomBytes(16u << 20, rng);
  const std::string hash = api::sha256Hex(bytes);
  std::atomic<bool> done{false};
  std::atomic<int> polls{0}, bad{0};
  std::string first_error;
  std::thread reader([&] {
    while (!done.load()) {
      ++polls;
      struct stat st{};
      if (::stat(blobs.pathOf(hash).c_str(), &st) == 0 && static_cast<std::size_t>(st.st_size) != bytes.size()) {
        if (bad++ == 0) first_error = "final path has " + std::to_string(st.st_size) + " bytes";
      }
    }
  });
  auto put = blobs.put(bytes);
  done = true;
  reader.join();
  ASSERT_TRUE(put.ok()) << put.error().message;
  EXPECT_EQ(*put, hash);
  EXPECT_GT(polls.load(), 0);
  EXPECT_EQ(bad.load(), 0) << first_error;
  EXPECT_TRUE(blobs.read(hash).ok());
}

TEST(BlobStore, RemoveTemporariesDeletesLeftoversButNotBlobs) {
  BlobStore blobs(rigport_test::makeTempDir("blobs"));
  auto hash = blobs.put(bytesOf("keep me"));
  ASSERT_TRUE(hash.ok());
  std::ofstream(blobs.root() / "tmp" / "0123.part") << "half a blob";
  std::ofstream(blobs.root() / "tmp" / "4567.part") << "another half";
  blobs.removeTemporaries();
  EXPECT_TRUE(fs::is_empty(blobs.root() / "tmp"));
  EXPECT_TRUE(blobs.read(*hash).ok());

  blobs.remove(*hash);
  EXPECT_FALSE(blobs.contains(*hash));
  BlobStore fresh(rigport_test::makeTempDir("fresh"));
  fresh.removeTemporaries();  // no tmp directory yet: a no-op
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
  // Back to what schema 1 wrote (without what versions 2 and 3 added).
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open(file.c_str(), &db), SQLITE_OK);
  ASSERT_EQ(sqlite3_exec(db, "ALTER TABLE rigs DROP COLUMN region_labels; DROP TABLE storage_probe; PRAGMA user_version=1;", nullptr, nullptr,
                         nullptr),
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
  ASSERT_EQ(sqlite3_open(file.c_str(), &db), SQLITE_OK);
  sqlite3_stmt* stmt = nullptr;
  ASSERT_EQ(sqlite3_prepare_v2(db, "PRAGMA user_version", -1, &stmt, nullptr), SQLITE_OK);
  ASSERT_EQ(sqlite3_step(stmt), SQLITE_ROW);
  EXPECT_EQ(sqlite3_column_int(stmt, 0), 3);
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
// Metadata: rigs

TEST(MetadataStore, InsertRigIsIdempotentOnTenantAndId) {
  auto store = openStore(rigport_test::makeTempDir("rigs") / "meta.db");
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

TEST(MetadataStore, RigsAreIsolatedPerTenant) {
  auto store = openStore(rigport_test::makeTempDir("rigs") / "meta.db");
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

TEST(MetadataStore, TenantAndIdValuesAreBoundNotSpliced) {
  auto store = openStore(rigport_test::makeTempDir("inject") / "meta.db");
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

TEST(MetadataStore, InsertJobHonoursIdempotencyKeyPerTenant) {
  auto store = openStore(rigport_test::makeTempDir("jobs") / "meta.db");
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

TEST(MetadataStore, ListJobsPagesBySequenceAndFiltersByStatus) {
  auto store = openStore(rigport_test::makeTempDir("list") / "meta.db");
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

TEST(MetadataStore, TransitionsCountAttemptsAndRefuseToOverwriteFinalJobs) {
  auto store = openStore(rigport_test::makeTempDir("transitions") / "meta.db");
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

TEST(MetadataStore, DataSurvivesReopenAndUnfinishedJobsAreRecovered) {
  const fs::path file = rigport_test::makeTempDir("reopen") / "meta.db";
  {
    auto store = openStore(file);
    ASSERT_TRUE(store);
    ASSERT_TRUE(store->insertRig(makeRig("acme", "rig1")).ok());
    for (const char* id : {"j1", "j2", "j3", "j4"}) ASSERT_TRUE(store->insertJob(makeJob("acme", id, id)).ok());
    ASSERT_TRUE(store->markRunning("j2", 5, false).ok());
    ASSERT_TRUE(store->markRunning("j3", 5, false).ok());
    ASSERT_TRUE(store->markFinished(finished(makeJob("acme", "j3"), JobStatus::kFailed)).ok());
  }
  auto store = openStore(file);
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

TEST(MetadataStore, CountJobsByStatusCoversAllStatuses) {
  auto store = openStore(rigport_test::makeTempDir("count") / "meta.db");
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

TEST(MetadataStore, BlobReferencedSeesEveryReferencingColumn) {
  auto store = openStore(rigport_test::makeTempDir("refs") / "meta.db");
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
  ASSERT_TRUE(store->markFinished(finished(job, JobStatus::kSucceeded)).ok());  // 1, 2

  for (char c : {'a', 'b', 'c', 'd', 'e', '1', '2'}) EXPECT_TRUE(store->blobReferenced(h(c))) << c;
  EXPECT_FALSE(store->blobReferenced(h('9')));
  EXPECT_FALSE(store->blobReferenced(""));

  ASSERT_TRUE(store->deleteRig("acme", "rig1"));
  EXPECT_FALSE(store->blobReferenced(h('c')));
  EXPECT_TRUE(store->blobReferenced(h('a'))) << "still referenced by rig2";
}

TEST(MetadataStore, DeleteFinishedJobTakesOnlyTheTenantsFinalJobAndItsInputRows) {
  auto store = openStore(rigport_test::makeTempDir("delete_job") / "meta.db");
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

TEST(MetadataStore, FinishedJobsBeforeListsExpiredFinalJobsOldestFirst) {
  auto store = openStore(rigport_test::makeTempDir("expired") / "meta.db");
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

TEST(MetadataStore, ConcurrentWritersAllLand) {
  auto store = openStore(rigport_test::makeTempDir("threads") / "meta.db");
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
// Crash durability: a child process writes and acknowledges, then is SIGKILLed.

void writeLine(int fd, const std::string& line) {
  const std::string text = line + "\n";  // < PIPE_BUF: one atomic write
  const char* p = text.data();
  std::size_t n = text.size();
  while (n > 0) {
    const ssize_t w = ::write(fd, p, n);
    if (w < 0) {
      if (errno == EINTR) continue;
      ::_exit(3);
    }
    p += w;
    n -= static_cast<std::size_t>(w);
  }
}

// Runs in the forked child until killed. Acknowledges only after each call returned ok.
[[noreturn]] void runCrashWriter(const fs::path& dir, int fd, unsigned seed) {
  auto opened = MetadataStore::open(dir / "meta.db");
  if (!opened) ::_exit(2);
  auto store = std::move(*opened);
  BlobStore blobs(dir / "blobs");
  std::mt19937 rng(seed);
  for (int i = 0;; ++i) {
    const std::string n = std::to_string(seed) + "-" + std::to_string(i);
    auto rig_blob = blobs.put(randomBytes(1000 + rng() % 300000, rng));
    if (!rig_blob) ::_exit(4);
    RigRecord rig = makeRig("t" + std::to_string(i % 2), "rig-" + n);
    rig.rig_blob = rig.landmarks_blob = *rig_blob;
    rig.components_blob = "";
    if (!store->insertRig(rig).ok()) ::_exit(5);
    writeLine(fd, "R " + rig.tenant + " " + rig.info.id + " " + *rig_blob);

    JobRecord job = makeJob(rig.tenant, "job-" + n, "key-" + n);
    job.inputs = {{"target", *rig_blob}};
    if (!store->insertJob(job).ok()) ::_exit(6);
    writeLine(fd, "J " + job.tenant + " " + job.id);
    if (!store->markRunning(job.id, 1, false).ok()) ::_exit(7);
    if (i % 3 == 2) continue;  // leave some running for recovery
    auto result = blobs.put(randomBytes(1000 + rng() % 300000, rng));
    if (!result) ::_exit(8);
    JobRecord done = finished(job, JobStatus::kSucceeded);
    done.result_blob = *result;
    done.diagnostics_blob = *result;
    if (!store->markFinished(done).ok()) ::_exit(9);
    writeLine(fd, "F " + job.tenant + " " + job.id + " " + *result);
  }
}

TEST(StoreDurability, AcknowledgedWritesSurviveSigkill) {
  std::mt19937 rng(20261121);
  int total_acks = 0;
  for (int round = 0; round < 4; ++round) {
    const fs::path dir = rigport_test::makeTempDir("crash" + std::to_string(round));
    // The same directory is written by two children in turn, so the second
    // one starts on a store that already went through one crash.
    for (int life = 0; life < 2; ++life) {
      int fds[2];
      ASSERT_EQ(::pipe(fds), 0);
      const unsigned seed = static_cast<unsigned>(round * 10 + life);
      const pid_t pid = ::fork();
      ASSERT_GE(pid, 0);
      if (pid == 0) {
        ::close(fds[0]);
        runCrashWriter(dir, fds[1], seed);
      }
      ::close(fds[1]);
      const int delay_ms = 40 + static_cast<int>(rng() % 260);
      std::this_thread::sleep_for(std::chrono::milliseconds(delay_ms));
      ::kill(pid, SIGKILL);
      int wstatus = 0;
      ASSERT_EQ(::waitpid(pid, &wstatus, 0), pid);
      ASSERT_TRUE(WIFSIGNALED(wstatus) && WTERMSIG(wstatus) == SIGKILL)
          << "writer exited early with status " << (WIFEXITED(wstatus) ? WEXITSTATUS(wstatus) : -1);
      std::string acks;
      char buf[4096];
      ssize_t r;
      while ((r = ::read(fds[0], buf, sizeof buf)) > 0) acks.append(buf, static_cast<std::size_t>(r));
      ::close(fds[0]);

      auto store = openStore(dir / "meta.db");
      ASSERT_TRUE(store) << "store does not reopen after SIGKILL";
      BlobStore blobs(dir / "blobs");
      blobs.removeTemporaries();
      std::istringstream lines(acks);
      std::string line;
      std::set<std::string> finished_ids;
      while (std::getline(lines, line)) {
        if (lines.eof()) break;  // an unterminated last line was never acknowledged
        std::istringstream in(line);
        std::string kind, tenant, id, hash;
        in >> kind >> tenant >> id >> hash;
        ++total_acks;
        if (kind == "R") {
          auto rig = store->getRig(tenant, id);
          ASSERT_TRUE(rig) << "acknowledged rig lost: " << id << " (delay " << delay_ms << " ms)";
          EXPECT_EQ(rig->rig_blob, hash);
          auto bytes = blobs.read(hash);
          EXPECT_TRUE(bytes.ok()) << (bytes.ok() ? "" : bytes.error().message);
        } else if (kind == "J") {
          EXPECT_TRUE(store->getJob(tenant, id)) << "acknowledged job lost: " << id;
        } else if (kind == "F") {
          auto job = store->getJob(tenant, id);
          ASSERT_TRUE(job) << "finished job lost: " << id;
          EXPECT_EQ(job->status, JobStatus::kSucceeded) << id;
          EXPECT_EQ(job->result_blob, hash) << id;
          auto bytes = blobs.read(hash);
          EXPECT_TRUE(bytes.ok()) << (bytes.ok() ? "" : bytes.error().message);
          finished_ids.insert(id);
        } else {
          ADD_FAILURE() << "unexpected ack line: " << line;
        }
      }
      // Every blob file on disk is whole: nothing half-written is servable.
      std::error_code ec;
      for (const auto& entry : fs::recursive_directory_iterator(blobs.root(), ec)) {
        if (!entry.is_regular_file() || entry.path().parent_path().filename() == "tmp") continue;
        auto bytes = blobs.read(entry.path().filename().string());
        EXPECT_TRUE(bytes.ok()) << (bytes.ok() ? "" : bytes.error().message);
      }
      EXPECT_TRUE(!fs::exists(blobs.root() / "tmp") || fs::is_empty(blobs.root() / "tmp"));

      // Recovery as the server does it: requeue running jobs, then finish every one.
      for (const auto& job : store->unfinishedJobs()) {
        EXPECT_EQ(finished_ids.count(job.id), 0u) << "acknowledged finish was lost: " << job.id;
        if (job.status == JobStatus::kRunning) {
      ASSERT_TRUE(store->requeue(job.id).ok());
    }
        ASSERT_TRUE(store->markRunning(job.id, 2, false).ok());
        auto result = blobs.put(bytesOf("recovered " + job.id));
        ASSERT_TRUE(result.ok());
        JobRecord done = finished(job, JobStatus::kSucceeded);
        done.result_blob = *result;
        ASSERT_TRUE(store->markFinished(done).ok());
      }
      EXPECT_TRUE(store->unfinishedJobs().empty());
      const auto counts = store->countJobsByStatus();
      EXPECT_EQ(counts.at(JobStatus::kQueued) + counts.at(JobStatus::kRunning), 0);
    }
  }
  EXPECT_GT(total_acks, 0) << "the writer never acknowledged anything: the test proved nothing";
}

}  // namespace
