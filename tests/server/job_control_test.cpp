// Cancellation (queued: at once; running: at the next stage boundary), the
// bounded queue (429 with Retry-After), graceful stop keeping queued jobs, and
// deleting jobs (on request and by retention) with the files only they used.
#include <gtest/gtest.h>

#include <chrono>
#include <fstream>
#include <set>
#include <thread>

#include "api/content_id.h"

#include "tests/server/service_fixture.h"
#include "tests/test_support.h"

namespace rigport_test {
namespace {

// Polls until the job reports `status` (fails after 120 s).
void waitForStatus(httplib::Client& client, const std::string& id, const std::string& status) {
  const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(120);
  while (std::chrono::steady_clock::now() < give_up) {
    if (get(client, "/v1/jobs/" + id).body.value("status", "") == status) return;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  ADD_FAILURE() << "job " << id << " never reached " << status;
}

TEST(JobControl, FullQueueAnswers429AndCancelStopsQueuedAndRunningJobs) {
  const auto dir = makeTempDir("queue");
  const TransferFiles slow = writeTransferFiles(dir, 200);  // a target large enough to keep the worker busy
  const TransferFiles fast = writeTransferFiles(dir / "fast");
  server::ServerConfig config = testConfig(dir / "data");
  config.workers = 1;
  config.queue_capacity = 1;
  config.retry_after_s = 3;
  InProcessService service(config);
  auto client = service.client();
  const std::string rig_id = uploadRig(*client, slow).body["id"];
  const std::string fast_rig = uploadRig(*client, fast).body["id"];

  // Everything up to the second cancel must happen while the slow job holds
  // the worker: the jobs that only queue or bounce carry the small target,
  // so their uploads keep that window short even on a loaded machine.
  Reply running = submitTransfer(*client, rig_id, slow);
  ASSERT_EQ(running.status, 202) << running.raw;
  waitForStatus(*client, running.body["id"], "running");
  Reply queued = submitTransfer(*client, fast_rig, fast);
  ASSERT_EQ(queued.status, 202) << queued.raw;
  EXPECT_EQ(queued.body["status"], "queued");

  Reply rejected = submitTransfer(*client, fast_rig, fast);
  EXPECT_EQ(rejected.status, 429) << rejected.raw;
  EXPECT_EQ(rejected.retry_after, "3");
  EXPECT_EQ(rejected.body["type"], "urn:rigport:problem:queue-full");
  EXPECT_EQ(get(*client, "/v1/jobs").body["items"].size(), 2u) << "a rejected job must not be stored";

  Reply cancel_queued = post(*client, "/v1/jobs/" + queued.body["id"].get<std::string>() + ":cancel");
  ASSERT_EQ(cancel_queued.status, 202) << cancel_queued.raw;
  EXPECT_EQ(cancel_queued.body["status"], "cancelled");
  Reply cancel_running = post(*client, "/v1/jobs/" + running.body["id"].get<std::string>() + ":cancel");
  ASSERT_EQ(cancel_running.status, 202) << cancel_running.raw;
  const nlohmann::json stopped = waitForJob(*client, running.body["id"]);
  EXPECT_EQ(stopped["status"], "cancelled") << stopped.dump();
  EXPECT_EQ(stopped["error"]["type"], "urn:rigport:problem:job-cancelled");
  EXPECT_EQ(get(*client, "/v1/jobs/" + running.body["id"].get<std::string>() + "/result").status, 409);

  // The queue has room again and the worker is free.
  Reply next = submitTransfer(*client, fast_rig, fast);
  ASSERT_EQ(next.status, 202) << next.raw;
  EXPECT_EQ(waitForJob(*client, next.body["id"])["status"], "succeeded");
  EXPECT_EQ(get(*client, "/v1/jobs?status=cancelled").body["items"].size(), 2u);
}

// GET with wait_ms answers when the job finishes: one request sees the final
// state of a job that was queued behind another.
TEST(JobControl, LongPollAnswersWhenTheJobFinishes) {
  const auto dir = makeTempDir("longpoll");
  const TransferFiles files = writeTransferFiles(dir, 200);  // slow enough that a plain GET sees it unfinished
  server::ServerConfig config = testConfig(dir / "data");
  config.workers = 1;
  InProcessService service(config);
  auto client = service.client();
  client->set_read_timeout(std::chrono::seconds(120));
  const std::string rig_id = uploadRig(*client, files).body["id"];
  const std::string first = submitTransfer(*client, rig_id, files).body["id"];
  Reply second = submitTransfer(*client, rig_id, files);
  ASSERT_EQ(second.status, 202) << second.raw;
  ASSERT_NE(second.body["status"], "succeeded");
  Reply settled = get(*client, "/v1/jobs/" + second.body["id"].get<std::string>() + "?wait_ms=60000");
  ASSERT_EQ(settled.status, 200) << settled.raw;
  EXPECT_EQ(settled.body["status"], "succeeded") << settled.raw;
  EXPECT_EQ(get(*client, "/v1/jobs/" + first).body["status"], "succeeded");

  for (const char* bad : {"-1", "60001", "abc", "5x"}) {
    Reply r = get(*client, "/v1/jobs/" + first + "?wait_ms=" + bad);
    EXPECT_EQ(r.status, 400) << bad;
    EXPECT_NE(r.body.value("detail", "").find("wait_ms"), std::string::npos) << r.raw;
  }
}

TEST(JobControl, ListsArePaginatedInSubmissionOrder) {
  const auto dir = makeTempDir("pages");
  const TransferFiles files = writeTransferFiles(dir);
  InProcessService service(testConfig(dir / "data"));
  auto client = service.client();
  const std::string rig_id = uploadRig(*client, files).body["id"];
  std::vector<std::string> ids;
  for (int i = 0; i < 5; ++i) ids.push_back(submitTransfer(*client, rig_id, files).body["id"]);
  std::vector<std::string> listed;
  std::string next;
  for (int page = 0; page < 10; ++page) {
    Reply r = get(*client, "/v1/jobs?limit=2" + (next.empty() ? "" : "&after=" + next));
    ASSERT_EQ(r.status, 200) << r.raw;
    for (const auto& item : r.body["items"]) listed.push_back(item["id"]);
    if (r.body["next"].is_null()) break;
    next = r.body["next"];
  }
  EXPECT_EQ(listed, ids);
  for (const auto& id : ids) waitForJob(*client, id);
}

TEST(JobControl, GracefulStopKeepsQueuedJobsForTheNextStart) {
  const auto dir = makeTempDir("graceful");
  const TransferFiles files = writeTransferFiles(dir);
  server::ServerConfig config = testConfig(dir / "data");
  config.workers = 1;
  std::vector<std::string> ids;
  {
    InProcessService service(config);
    auto client = service.client();
    const std::string rig_id = uploadRig(*client, files).body["id"];
    for (int i = 0; i < 6; ++i) {
      Reply r = submitTransfer(*client, rig_id, files);
      ASSERT_EQ(r.status, 202) << r.raw;
      ids.push_back(r.body["id"]);
    }
    service.stop(30.0);  // running job finishes; queued ones stay queued in the store
  }
  InProcessService restarted(config);
  auto client = restarted.client();
  for (const auto& id : ids) EXPECT_EQ(waitForJob(*client, id)["status"], "succeeded") << id;
}

// The blob files under a data directory, by hash.
std::set<std::string> blobHashes(const std::filesystem::path& data_dir) {
  std::set<std::string> out;
  for (const auto& entry : std::filesystem::recursive_directory_iterator(data_dir / "blobs")) {
    if (entry.is_regular_file()) out.insert(entry.path().filename().string());
  }
  return out;
}

std::string fileHash(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  return api::sha256Hex(std::string_view(bytes));
}

TEST(JobControl, DeletingAFinishedJobRemovesTheFilesOnlyItUsed) {
  const auto dir = makeTempDir("delete_job");
  const TransferFiles slow = writeTransferFiles(dir, 200);
  const TransferFiles files = writeTransferFiles(dir / "small");
  server::ServerConfig config = testConfig(dir / "data");
  config.workers = 1;
  InProcessService service(config);
  auto client = service.client();
  const std::string rig_id = uploadRig(*client, files).body["id"];
  const std::string slow_rig = uploadRig(*client, slow).body["id"];

  // Unfinished jobs are refused with a way out.
  Reply running = submitTransfer(*client, slow_rig, slow);
  ASSERT_EQ(running.status, 202) << running.raw;
  const std::string running_id = running.body["id"];
  waitForStatus(*client, running_id, "running");
  Reply refused = del(*client, "/v1/jobs/" + running_id);
  EXPECT_EQ(refused.status, 409) << refused.raw;
  EXPECT_EQ(refused.body.value("type", ""), "urn:rigport:problem:conflict");
  EXPECT_NE(refused.body.value("detail", "").find(":cancel"), std::string::npos) << refused.raw;
  ASSERT_EQ(post(*client, "/v1/jobs/" + running_id + ":cancel").status, 202);
  EXPECT_EQ(waitForJob(*client, running_id)["status"], "cancelled");
  EXPECT_EQ(del(*client, "/v1/jobs/" + running_id).status, 204);

  // Two jobs on the same files share their input and result blobs: deleting
  // one keeps what the other still uses.
  const std::string first = submitTransfer(*client, rig_id, files).body["id"];
  const std::string second = submitTransfer(*client, rig_id, files).body["id"];
  ASSERT_EQ(waitForJob(*client, first)["status"], "succeeded");
  ASSERT_EQ(waitForJob(*client, second)["status"], "succeeded");
  const std::string result = get(*client, "/v1/jobs/" + second + "/result").raw;
  ASSERT_FALSE(result.empty());
  EXPECT_EQ(del(*client, "/v1/jobs/" + first).status, 204);
  EXPECT_EQ(get(*client, "/v1/jobs/" + first).status, 404);
  EXPECT_EQ(get(*client, "/v1/jobs/" + first + "/result").status, 404);
  EXPECT_EQ(del(*client, "/v1/jobs/" + first).status, 404) << "deleted twice";
  EXPECT_EQ(get(*client, "/v1/jobs/" + second + "/result").raw, result) << "a shared blob went with the first job";
  EXPECT_EQ(del(*client, "/v1/jobs/" + second).status, 204);

  // What is left on disk is the two rigs' files, nothing of the jobs.
  const std::set<std::string> rig_files = {fileHash(files.rig), fileHash(files.landmarks), fileHash(slow.rig),
                                           fileHash(slow.landmarks)};
  EXPECT_EQ(blobHashes(dir / "data"), rig_files);
  EXPECT_TRUE(get(*client, "/v1/jobs").body["items"].empty());
  EXPECT_EQ(metricValue(*client, "rigport_jobs_deleted_total{reason=\"request\"}"), 3.0);
  // The service still works after its deletes.
  const std::string third = submitTransfer(*client, rig_id, files).body["id"];
  EXPECT_EQ(waitForJob(*client, third)["status"], "succeeded");
  EXPECT_EQ(get(*client, "/v1/jobs/" + third + "/result").raw, result);
}

TEST(JobControl, RetentionDeletesJobsFinishedLongerAgoThanItKeepsThem) {
  const auto dir = makeTempDir("retention");
  const TransferFiles files = writeTransferFiles(dir);
  server::ServerConfig config = testConfig(dir / "data");
  config.keep_jobs_days = 1e-9;    // ~0.1 ms: every finished job has expired by the next sweep
  config.retention_sweep_s = 0.02;
  InProcessService service(config);
  auto client = service.client();
  const std::string rig_id = uploadRig(*client, files).body["id"];
  const std::string id = submitTransfer(*client, rig_id, files).body["id"];
  const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(120);
  // The count goes up once the job's row and its blobs are gone.
  const std::string deleted_metric = "rigport_jobs_deleted_total{reason=\"retention\"}";
  while (metricValue(*client, deleted_metric) < 1.0 && std::chrono::steady_clock::now() < give_up) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  EXPECT_EQ(metricValue(*client, deleted_metric), 1.0) << "the sweep never deleted the finished job";
  EXPECT_EQ(get(*client, "/v1/jobs/" + id).status, 404);
  EXPECT_EQ(blobHashes(dir / "data"), (std::set<std::string>{fileHash(files.rig), fileHash(files.landmarks)}));
  EXPECT_EQ(get(*client, "/v1/rigs/" + rig_id).status, 200) << "retention is for jobs, not rigs";
}

}  // namespace
}  // namespace rigport_test
