// Scale-out: several rigport-server processes on one PostgreSQL and one
// shared blob directory, on loopback. Every accepted job is run once to a
// result byte-identical to the in-process CLI, whichever replica accepted
// it, when a replica is killed (kill -9) or stopped past its lease, when all
// are killed and restarted, and when PostgreSQL restarts under load.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdlib>
#include <fstream>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "server/store.h"
#include "tests/server/server_process.h"
#include "tests/server/service_fixture.h"
#include "tests/server/store_fixture.h"
#include "tests/test_support.h"

namespace rigport_test {
namespace {

using Clock = std::chrono::steady_clock;
using store::freshPostgresLocation;
using store::kNoPostgres;
using store::testPostgresUrl;

class Replicas : public ::testing::Test {
 protected:
  void SetUp() override {
    if (testPostgresUrl().empty()) GTEST_SKIP() << kNoPostgres;
    dir_ = makeTempDir("replicas");
    files_ = writeTransferFiles(dir_, 60);
    const std::vector<std::uint8_t> cli = runCliTransfer(files_, dir_);
    expected_.assign(cli.begin(), cli.end());
    store_url_ = freshPostgresLocation(::testing::UnitTest::GetInstance()->current_test_info()->name());
  }

  // Replica i: its own data directory, the shared blob directory and store.
  std::unique_ptr<ServerProcess> startReplica(int i, double lease_s, int workers = 2, const std::string& store = "") {
    auto replica = std::make_unique<ServerProcess>(std::vector<std::string>{
        "--data-dir", (dir_ / ("data" + std::to_string(i))).string(), "--blob-dir", (dir_ / "blobs").string(),
        "--store", store.empty() ? store_url_ : store, "--no-auth", "--workers", std::to_string(workers),
        "--lease-s", std::to_string(lease_s), "--replica-id", "replica-" + std::to_string(i)});
    EXPECT_GT(replica->port(), 0) << "replica " << i << " did not start";
    return replica;
  }

  std::string uploadRigTo(const ServerProcess& replica) {
    Reply rig = uploadRig(*replica.client(), files_);
    EXPECT_EQ(rig.status, 201) << rig.raw;
    return rig.body.value("id", "");
  }

  std::vector<std::string> submitTo(const ServerProcess& replica, const std::string& rig, int jobs) {
    auto client = replica.client();
    std::vector<std::string> ids;
    for (int i = 0; i < jobs; ++i) {
      Reply r = submitTransfer(*client, rig, files_);
      EXPECT_EQ(r.status, 202) << r.raw;
      if (r.status == 202) ids.push_back(r.body["id"]);
    }
    return ids;
  }

  // Every job succeeded, its result the CLI's bytes; returns the attempts per job.
  std::map<std::string, int> expectSucceededWithCliBytes(const ServerProcess& replica, const std::vector<std::string>& ids) {
    auto client = replica.client();
    std::map<std::string, int> attempts;
    for (const std::string& id : ids) {
      const nlohmann::json done = waitForJob(*client, id);
      EXPECT_EQ(done.value("status", ""), "succeeded") << done.dump();
      attempts[id] = done.value("attempts", 0);
      Reply result = get(*client, "/v1/jobs/" + id + "/result");
      EXPECT_EQ(result.status, 200) << id;
      EXPECT_TRUE(result.raw == expected_) << "the result of " << id << " differs from the CLI's";
    }
    return attempts;
  }

  // Nothing left queued or running in the store.
  void expectNoUnfinishedJobs() {
    auto store = server::MetadataStore::open(store_url_);
    ASSERT_TRUE(store.ok()) << store.error().message;
    EXPECT_TRUE((*store)->unfinishedJobs().empty()) << "stuck jobs in the queue";
  }

  // Pauses `paused` (SIGSTOP) at a moment the store says one of them runs a
  // job under its lease; resumes and looks again until then, submitting more
  // jobs (to the first, added to `ids`) whenever the queue ran dry.
  bool catchRunning(const std::vector<ServerProcess*>& paused, const std::string& rig, std::vector<std::string>& ids) {
    for (int tries = 0; tries < 5000; ++tries) {
      for (ServerProcess* p : paused) p->signal(SIGSTOP);
      auto store = server::MetadataStore::open(store_url_);
      if (!store.ok()) return false;
      const auto unfinished = (*store)->unfinishedJobs();
      for (const auto& job : unfinished) {
        if (job.status == api::JobStatus::kRunning && job.lease_owner.rfind("replica-", 0) == 0) return true;
      }
      for (ServerProcess* p : paused) p->signal(SIGCONT);
      if (unfinished.empty()) {
        auto more = submitTo(*paused.front(), rig, 3);
        ids.insert(ids.end(), more.begin(), more.end());
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    return false;
  }

  // Polls until `ready` or `limit` passes.
  template <typename Ready>
  static bool waitFor(Ready ready, std::chrono::seconds limit = std::chrono::seconds(120)) {
    const auto give_up = Clock::now() + limit;
    while (Clock::now() < give_up) {
      if (ready()) return true;
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    return ready();
  }

  static double metric(const ServerProcess& replica, const std::string& prefix) {
    return metricValue(*replica.client(), prefix);
  }

  std::filesystem::path dir_;
  TransferFiles files_;
  std::string expected_;
  std::string store_url_;
};

TEST_F(Replicas, ThreeReplicasRunTwoHundredJobsFromSixteenClientsWithTheCliBytes) {
  std::vector<std::unique_ptr<ServerProcess>> replicas;
  for (int i = 0; i < 3; ++i) replicas.push_back(startReplica(i, 30.0));
  const std::string rig = uploadRigTo(*replicas[0]);
  ASSERT_FALSE(rig.empty());

  constexpr int kClients = 16, kJobs = 200;
  std::mutex mutex;
  std::vector<std::vector<std::string>> ids(kClients);
  std::vector<std::thread> clients;
  for (int c = 0; c < kClients; ++c) {
    clients.emplace_back([&, c] {
      const ServerProcess& replica = *replicas[c % 3];  // the rig was uploaded to one; every replica sees it
      const int jobs = kJobs / kClients + (c < kJobs % kClients ? 1 : 0);
      auto submitted = submitTo(replica, rig, jobs);
      std::lock_guard lock(mutex);
      ids[c] = std::move(submitted);
    });
  }
  for (auto& t : clients) t.join();
  std::size_t accepted = 0;
  for (const auto& client_ids : ids) accepted += client_ids.size();
  ASSERT_EQ(accepted, static_cast<std::size_t>(kJobs));
  for (int c = 0; c < kClients; ++c) expectSucceededWithCliBytes(*replicas[(c + 1) % 3], ids[c]);

  double succeeded = 0;
  for (const auto& replica : replicas) {
    const double ran = metric(*replica, "rigport_job_outcomes_total{status=\"succeeded\"}");
    EXPECT_GT(ran, 0) << "a replica ran no job";
    succeeded += ran;
    EXPECT_EQ(metric(*replica, "rigport_fencing_rejections_total"), 0);
  }
  EXPECT_EQ(succeeded, kJobs) << "a job ran to success more than once";
  expectNoUnfinishedJobs();
}

TEST_F(Replicas, KillNineOfOneReplicaLeavesItsJobsToTheOthers) {
  constexpr double kLease = 2.0;
  std::vector<std::unique_ptr<ServerProcess>> replicas;
  replicas.push_back(startReplica(0, kLease, 1));
  const std::string rig = uploadRigTo(*replicas[0]);
  std::vector<std::string> ids = submitTo(*replicas[0], rig, 12);
  ASSERT_EQ(ids.size(), 12u);
  // Caught holding a job (paused, so the job cannot finish between the look
  // and the kill); the others start meanwhile, then replica 0 is killed.
  ASSERT_TRUE(catchRunning({replicas[0].get()}, rig, ids));
  for (int i = 1; i < 3; ++i) replicas.push_back(startReplica(i, kLease, 1));
  replicas[0]->kill(SIGKILL);
  const auto killed = Clock::now();

  const auto attempts = expectSucceededWithCliBytes(*replicas[1], ids);
  const double rescue_s = std::chrono::duration<double>(Clock::now() - killed).count();
  int rerun = 0;
  for (const auto& [id, n] : attempts) rerun += n > 1 ? 1 : 0;
  EXPECT_GE(rerun, 1) << "the job replica 0 was running was not run again";
  double rescued = 0, expired = 0;
  for (int i = 1; i < 3; ++i) {
    rescued += metric(*replicas[i], "rigport_jobs_rescued_total");
    expired += metric(*replicas[i], "rigport_lease_expiries_total");
    EXPECT_EQ(metric(*replicas[i], "rigport_fencing_rejections_total"), 0);
  }
  EXPECT_EQ(rescued, rerun);
  EXPECT_GE(expired, 1);
  expectNoUnfinishedJobs();
  // Measured, not asserted (docs/SCALE_OUT.md): all done this long after the kill.
  RecordProperty("all_succeeded_after_kill_s", std::to_string(rescue_s));
}

TEST_F(Replicas, AReplicaPausedPastItsLeaseCannotOverwriteTheNewOwnersResult) {
  constexpr double kLease = 1.0;
  auto paused = startReplica(0, kLease, 1);
  auto other = startReplica(1, kLease, 1);
  const std::string rig = uploadRigTo(*paused);
  // The pause must land while replica 0 runs the job: try until it does.
  for (int round = 0; round < 10; ++round) {
    const double rejected_before = metric(*paused, "rigport_fencing_rejections_total");
    other->signal(SIGSTOP);  // so that replica 0 claims the job
    const std::vector<std::string> ids = submitTo(*paused, rig, 1);
    ASSERT_EQ(ids.size(), 1u);
    const bool running = waitFor([&] { return metric(*paused, "rigport_running_jobs") >= 1; }, std::chrono::seconds(30));
    paused->signal(SIGSTOP);
    other->signal(SIGCONT);
    if (!running) {
      paused->signal(SIGCONT);
      continue;
    }
    auto on_other = other->client();
    const nlohmann::json done = waitForJob(*on_other, ids[0]);
    if (done.value("attempts", 0) < 2) {  // replica 0 finished before the pause
      paused->signal(SIGCONT);
      continue;
    }
    ASSERT_EQ(done.value("status", ""), "succeeded") << done.dump();
    paused->signal(SIGCONT);
    // Replica 0 wakes with a stale lease: its heartbeat or its result write is refused.
    EXPECT_TRUE(waitFor([&] { return metric(*paused, "rigport_fencing_rejections_total") > rejected_before; }))
        << "the paused replica's stale attempt was not fenced";
    const nlohmann::json after = get(*on_other, "/v1/jobs/" + ids[0]).body;
    EXPECT_EQ(after.value("status", ""), "succeeded");
    EXPECT_EQ(after.value("attempts", 0), 2);
    EXPECT_TRUE(get(*on_other, "/v1/jobs/" + ids[0] + "/result").raw == expected_);
    expectNoUnfinishedJobs();
    return;
  }
  FAIL() << "the pause never landed while replica 0 ran a job";
}

TEST_F(Replicas, KillNineOfEveryReplicaThenARestartLosesNoAcceptedJob) {
  constexpr double kLease = 2.0;
  std::vector<std::unique_ptr<ServerProcess>> replicas;
  for (int i = 0; i < 3; ++i) replicas.push_back(startReplica(i, kLease, 1));
  const std::string rig = uploadRigTo(*replicas[0]);
  std::vector<std::string> ids;
  for (int i = 0; i < 3; ++i) {
    auto more = submitTo(*replicas[i], rig, 5);
    ids.insert(ids.end(), more.begin(), more.end());
  }
  ASSERT_EQ(ids.size(), 15u);
  ASSERT_TRUE(catchRunning({replicas[0].get(), replicas[1].get(), replicas[2].get()}, rig, ids));
  for (auto& replica : replicas) replica->kill(SIGKILL);
  replicas.clear();
  for (int i = 0; i < 3; ++i) replicas.push_back(startReplica(i, kLease, 1));
  expectSucceededWithCliBytes(*replicas[2], ids);
  expectNoUnfinishedJobs();
}

TEST_F(Replicas, PostgresRestartedUnderLoadMakesThemNotReadyThenTheyCarryOn) {
  // A cluster of this test's own, to stop and start.
  char pattern[] = "/tmp/rigport-pgrestart.XXXXXX";
  ASSERT_NE(mkdtemp(pattern), nullptr);
  const std::string cluster = pattern;
  const std::string script = std::string("bash ") + RIGPORT_SOURCE_DIR + "/scripts/postgres.sh ";
  ASSERT_EQ(std::system(("chmod 755 " + cluster + " && " + script + "start " + cluster + " > " + cluster + "/url").c_str()), 0);
  std::string url;
  {
    std::ifstream in(cluster + "/url");
    std::getline(in, url);
  }
  ASSERT_FALSE(url.empty());
  struct StopCluster {
    std::string command;
    ~StopCluster() { (void)std::system(command.c_str()); }
  } stop_at_end{script + "stop " + cluster + " > /dev/null 2>&1; rm -rf " + cluster};

  auto a = startReplica(0, 5.0, 1, url);
  auto b = startReplica(1, 5.0, 1, url);
  const std::string rig = uploadRigTo(*a);
  std::vector<std::string> ids = submitTo(*a, rig, 6);
  auto more = submitTo(*b, rig, 6);
  ids.insert(ids.end(), more.begin(), more.end());
  ASSERT_EQ(ids.size(), 12u);

  ASSERT_EQ(std::system((script + "stop " + cluster + " > /dev/null").c_str()), 0);
  EXPECT_TRUE(waitFor([&] { return get(*a->client(), "/readyz").status == 503; })) << "replica a stayed ready";
  EXPECT_TRUE(waitFor([&] { return get(*b->client(), "/readyz").status == 503; })) << "replica b stayed ready";
  Reply refused = submitTransfer(*a->client(), rig, files_);
  EXPECT_EQ(refused.status, 503) << "a job was taken while the store was away: " << refused.raw;

  ASSERT_EQ(std::system((script + "start " + cluster + " > /dev/null").c_str()), 0);
  EXPECT_TRUE(waitFor([&] { return get(*a->client(), "/readyz").status == 200; })) << "replica a stayed not ready";
  EXPECT_TRUE(waitFor([&] { return get(*b->client(), "/readyz").status == 200; })) << "replica b stayed not ready";
  expectSucceededWithCliBytes(*b, ids);
  store_url_ = url;
  expectNoUnfinishedJobs();
}

}  // namespace
}  // namespace rigport_test
