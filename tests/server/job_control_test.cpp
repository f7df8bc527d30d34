// Cancellation (queued: at once; running: at the next stage boundary), the
// bounded queue (429 with Retry-After), and graceful stop keeping queued jobs.
#include <gtest/gtest.h>

#include <chrono>
#include <thread>

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

}  // namespace
}  // namespace rigport_test
