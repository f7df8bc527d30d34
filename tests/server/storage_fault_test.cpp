// Storage faults fail loudly and lose nothing: with real write errors (the
// process's file-size limit lowered, so every write past 1 KiB fails with
// EFBIG, as on a full disk), readiness turns red, writes answer 503 with
// Retry-After and no server path, accepted jobs stay queued instead of
// failing, and they all finish with the right bytes once storage recovers.
#include <gtest/gtest.h>

#include <sys/resource.h>

#include <chrono>
#include <csignal>
#include <thread>

#include "tests/server/service_fixture.h"
#include "tests/test_support.h"

namespace rigport_test {
namespace {

// Writes past `bytes` fail with EFBIG for the whole process while it lives.
class FileSizeLimit {
 public:
  explicit FileSizeLimit(rlim_t bytes) {
    std::signal(SIGXFSZ, SIG_IGN);  // a failed write, not a killed process
    getrlimit(RLIMIT_FSIZE, &saved_);
    rlimit limit = saved_;
    limit.rlim_cur = bytes;
    EXPECT_EQ(setrlimit(RLIMIT_FSIZE, &limit), 0);
  }
  ~FileSizeLimit() { lift(); }
  void lift() {
    if (lifted_) return;
    lifted_ = true;
    EXPECT_EQ(setrlimit(RLIMIT_FSIZE, &saved_), 0);
  }

 private:
  rlimit saved_{};
  bool lifted_ = false;
};

// Polls /readyz until it answers `status` (fails after 60 s).
Reply waitForReadiness(httplib::Client& client, int status) {
  const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  Reply reply;
  while (std::chrono::steady_clock::now() < give_up) {
    reply = get(client, "/readyz");
    if (reply.status == status) return reply;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  ADD_FAILURE() << "/readyz never answered " << status << "; last: " << reply.status << " " << reply.raw;
  return reply;
}

TEST(StorageFaults, ReadinessTurnsRedWritesAnswer503AndAcceptedJobsFinishAfterRecovery) {
  const auto dir = makeTempDir("storage_fault");
  const TransferFiles slow = writeTransferFiles(dir / "slow", 200);
  const TransferFiles fast = writeTransferFiles(dir / "fast");
  const std::vector<std::uint8_t> slow_cli = runCliTransfer(slow, dir / "slow");
  const std::vector<std::uint8_t> fast_cli = runCliTransfer(fast, dir / "fast");
  ASSERT_FALSE(slow_cli.empty());
  ASSERT_FALSE(fast_cli.empty());

  server::ServerConfig config = testConfig(dir / "data");
  config.workers = 1;
  config.retry_after_s = 4;
  config.storage_probe_s = 0.05;
  config.storage_retry_s = 0.05;
  InProcessService service(config);
  auto client = service.client();
  const std::string data_dir = std::filesystem::absolute(config.data_dir).string();
  const std::string slow_rig = uploadRig(*client, slow).body["id"];
  const std::string fast_rig = uploadRig(*client, fast).body["id"];
  ASSERT_EQ(get(*client, "/readyz").status, 200);

  // One job holds the worker, two wait behind it; then the disk fails.
  Reply running = submitTransfer(*client, slow_rig, slow);
  ASSERT_EQ(running.status, 202) << running.raw;
  std::vector<std::string> queued;
  for (int i = 0; i < 2; ++i) {
    Reply reply = submitTransfer(*client, fast_rig, fast);
    ASSERT_EQ(reply.status, 202) << reply.raw;
    queued.push_back(reply.body["id"]);
  }
  FileSizeLimit full_disk(1024);

  const Reply red = waitForReadiness(*client, 503);
  EXPECT_EQ(red.body["type"], "urn:rigport:problem:storage-unavailable") << red.raw;
  EXPECT_EQ(red.retry_after, "4");
  const Reply refused_job = submitTransfer(*client, fast_rig, fast);
  EXPECT_EQ(refused_job.status, 503) << refused_job.raw;
  EXPECT_EQ(refused_job.body["type"], "urn:rigport:problem:storage-unavailable");
  EXPECT_EQ(refused_job.retry_after, "4");
  EXPECT_EQ(refused_job.body["instance"], "/v1/jobs");
  const Reply refused_rig = uploadRig(*client, fast);
  EXPECT_EQ(refused_rig.status, 503) << refused_rig.raw;
  const Reply refused_delete = del(*client, "/v1/jobs/" + queued[0]);
  EXPECT_EQ(refused_delete.status, 503) << refused_delete.raw;
  for (const Reply* reply : {&red, &refused_job, &refused_rig, &refused_delete}) {
    EXPECT_EQ(reply->raw.find(data_dir), std::string::npos) << "a server path reached the client: " << reply->raw;
  }

  // While it lasts, reads still answer and no accepted job fails or is lost.
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  const Reply listing = get(*client, "/v1/jobs");
  ASSERT_EQ(listing.status, 200) << listing.raw;
  EXPECT_EQ(listing.body["items"].size(), 3u) << "the refused submission must not be stored";
  for (const auto& job : listing.body["items"]) {
    EXPECT_TRUE(job["status"] == "queued" || job["status"] == "running") << job.dump();
  }
  EXPECT_GE(metricValue(*client, "rigport_storage_faults_total"), 1.0);
  EXPECT_EQ(metricValue(*client, "rigport_storage_ok"), 0.0);

  full_disk.lift();
  waitForReadiness(*client, 200);
  const nlohmann::json slow_done = waitForJob(*client, running.body["id"]);
  EXPECT_EQ(slow_done["status"], "succeeded") << slow_done.dump();
  EXPECT_EQ(get(*client, "/v1/jobs/" + running.body["id"].get<std::string>() + "/result").raw,
            std::string(slow_cli.begin(), slow_cli.end()));
  for (const std::string& id : queued) {
    const nlohmann::json done = waitForJob(*client, id);
    EXPECT_EQ(done["status"], "succeeded") << done.dump();
    EXPECT_EQ(get(*client, "/v1/jobs/" + id + "/result").raw, std::string(fast_cli.begin(), fast_cli.end()));
  }
  EXPECT_EQ(metricValue(*client, "rigport_storage_ok"), 1.0);

  // Recovered: new work is accepted and runs.
  Reply after = submitTransfer(*client, fast_rig, fast);
  ASSERT_EQ(after.status, 202) << after.raw;
  EXPECT_EQ(waitForJob(*client, after.body["id"])["status"], "succeeded");
}

// Faulty from the start (the disk already full): the service does not come up
// half-working; it refuses to start, naming the file it could not write.
TEST(StorageFaults, AServiceStartedOnAFullDiskRefusesToStartSayingWhy) {
  const auto dir = makeTempDir("storage_fault_start");
  const server::ServerConfig config = testConfig(dir / "data");
  {
    InProcessService prepare(config);  // the data dir and the store exist
  }
  FileSizeLimit full_disk(1024);
  auto service = server::Service::create(config, server::ApiKeys::disabled(), nullptr);
  ASSERT_FALSE(service);
  EXPECT_NE(service.error().message.find("rigport.sqlite"), std::string::npos) << service.error().message;
  full_disk.lift();
  auto recovered = server::Service::create(config, server::ApiKeys::disabled(), nullptr);
  EXPECT_TRUE(recovered) << recovered.error().message;
}

}  // namespace
}  // namespace rigport_test
