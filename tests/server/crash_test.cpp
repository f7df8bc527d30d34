// Durability: the rigport-server process is killed with SIGKILL while jobs are
// queued and running, then restarted on the same data directory. Every
// accepted rig is still there; every accepted job reaches a final state with
// its result intact (byte-identical to the in-process CLI); nothing is lost.
#include <gtest/gtest.h>

#include <chrono>
#include <thread>

#include "tests/server/server_process.h"
#include "tests/server/service_fixture.h"
#include "tests/test_support.h"

namespace rigport_test {
namespace {

ServerProcess startServer(const std::filesystem::path& data_dir) {
  return ServerProcess({"--data-dir", data_dir.string(), "--no-auth", "--workers", "1"});
}

TEST(Crash, KillNineLosesNoAcceptedRigOrJob) {
  const auto dir = makeTempDir("crash");
  const TransferFiles files = writeTransferFiles(dir, 90);
  const std::vector<std::uint8_t> cli = runCliTransfer(files, dir);
  const std::string expected(cli.begin(), cli.end());
  const auto data = dir / "data";

  std::string rig_id;
  std::vector<std::string> accepted;
  for (int round = 0; round < 2; ++round) {
    ServerProcess server = startServer(data);
    ASSERT_GT(server.port(), 0) << "rigport-server did not start";
    auto client = server.client();
    if (rig_id.empty()) {
      Reply rig = uploadRig(*client, files);
      ASSERT_EQ(rig.status, 201) << rig.raw;
      rig_id = rig.body["id"];
    }
    for (int i = 0; i < 6; ++i) {
      Reply r = submitTransfer(*client, rig_id, files);
      ASSERT_EQ(r.status, 202) << r.raw;
      accepted.push_back(r.body["id"]);
    }
    // Kill while the worker is mid-job and others wait in the queue.
    const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(120);
    while (std::chrono::steady_clock::now() < give_up &&
           get(*client, "/v1/jobs/" + accepted.back()).body.value("status", "") == "queued" &&
           get(*client, "/v1/jobs?status=running").body["items"].empty()) {
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
    server.kill(SIGKILL);
  }

  ServerProcess server = startServer(data);
  ASSERT_GT(server.port(), 0);
  auto client = server.client();
  EXPECT_EQ(get(*client, "/v1/rigs/" + rig_id).status, 200) << "an accepted rig was lost";
  int requeued = 0;
  for (const auto& id : accepted) {
    const nlohmann::json done = waitForJob(*client, id);
    ASSERT_EQ(done.value("status", ""), "succeeded") << done.dump();
    requeued += done["attempts"].get<int>() > 1 ? 1 : 0;
    Reply result = get(*client, "/v1/jobs/" + id + "/result");
    ASSERT_EQ(result.status, 200);
    EXPECT_TRUE(result.raw == expected) << "result of " << id << " differs from the CLI's";
  }
  EXPECT_EQ(get(*client, "/v1/jobs?limit=100").body["items"].size(), accepted.size());
  // Informational: how many jobs were interrupted mid-run and run again.
  RecordProperty("requeued_jobs", requeued);
}

}  // namespace
}  // namespace rigport_test
