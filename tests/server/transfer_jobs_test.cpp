// The job lifecycle against the real service on loopback: upload, submit,
// poll, fetch; results byte-identical to the in-process CLI; many concurrent
// jobs on one rig prepare it once.
#include <gtest/gtest.h>

#include <atomic>
#include <thread>

#include "core/io/mesh_io.h"
#include "tests/server/service_fixture.h"
#include "tests/test_support.h"

namespace rigport_test {
namespace {

TEST(TransferJobs, UploadSubmitPollFetchGivesTheCliBytes) {
  const auto dir = makeTempDir("lifecycle");
  const TransferFiles files = writeTransferFiles(dir);
  const std::vector<std::uint8_t> cli = runCliTransfer(files, dir);
  ASSERT_FALSE(cli.empty());
  const std::string expected(cli.begin(), cli.end());

  InProcessService service(testConfig(dir / "data"));
  auto client = service.client();
  Reply rig = uploadRig(*client, files);
  ASSERT_EQ(rig.status, 201) << rig.raw;
  const std::string rig_id = rig.body["id"];
  EXPECT_EQ(rig_id.size(), 64u);
  EXPECT_EQ(get(*client, "/v1/rigs/" + rig_id).body["vertices"], rig.body["vertices"]);

  Reply job = submitTransfer(*client, rig_id, files);
  ASSERT_EQ(job.status, 202) << job.raw;
  EXPECT_TRUE(job.body["status"] == "queued" || job.body["status"] == "running");
  const std::string id = job.body["id"];
  const nlohmann::json done = waitForJob(*client, id);
  ASSERT_EQ(done["status"], "succeeded") << done.dump();
  EXPECT_EQ(done["progress"], 1.0);
  EXPECT_EQ(done["attempts"], 1);
  EXPECT_FALSE(done["cache_hit"].get<bool>());
  EXPECT_GT(done["timings_ms"]["total"].get<double>(), 0.0);
  // The record keeps the names the files were sent under.
  EXPECT_EQ(done["files"]["target"], files.target.filename().string()) << done.dump();
  EXPECT_EQ(done["files"]["target_landmarks"], files.target_landmarks.filename().string()) << done.dump();

  Reply result = get(*client, "/v1/jobs/" + id + "/result");
  ASSERT_EQ(result.status, 200);
  EXPECT_EQ(result.content_type, "model/gltf-binary");
  EXPECT_TRUE(result.raw == expected) << "service result differs from the in-process CLI (" << result.raw.size()
                                      << " vs " << expected.size() << " bytes)";
  const auto glb = dir / "service_out.glb";
  ASSERT_TRUE(core::writeFileBytes(glb, std::span(reinterpret_cast<const std::uint8_t*>(result.raw.data()), result.raw.size())).ok());
  EXPECT_GLTF_VALID(glb);

  Reply diagnostics = get(*client, "/v1/jobs/" + id + "/diagnostics");
  ASSERT_EQ(diagnostics.status, 200);
  EXPECT_FALSE(diagnostics.body["cache"]["hit"].get<bool>()) << diagnostics.raw.substr(0, 400);
  // The target's region labels came through upload, store and job.
  EXPECT_TRUE(diagnostics.body["correspondence"]["region_matching"].get<bool>()) << diagnostics.raw.substr(0, 400);
  // The rig's labels are on record.
  Reply on_record = get(*client, "/v1/rigs/" + rig_id);
  ASSERT_EQ(on_record.status, 200) << on_record.raw;
  ASSERT_TRUE(on_record.body.contains("region_labels")) << on_record.raw;
  EXPECT_FALSE(on_record.body["region_labels"].empty()) << on_record.raw;
  EXPECT_EQ(on_record.body["region_labels"], rig.body["region_labels"]);
  for (const auto& l : on_record.body["region_labels"]) {
    EXPECT_TRUE(l.is_number_integer() && l.get<int>() >= 0 && l.get<int>() < 64) << on_record.raw;
  }

  // A second job on the same rig skips all source-only work.
  Reply second = submitTransfer(*client, rig_id, files);
  ASSERT_EQ(second.status, 202);
  const nlohmann::json second_done = waitForJob(*client, second.body["id"]);
  EXPECT_TRUE(second_done["cache_hit"].get<bool>());
  EXPECT_EQ(second_done["timings_ms"]["prepare"], 0.0);
  EXPECT_TRUE(get(*client, "/v1/jobs/" + second.body["id"].get<std::string>() + "/diagnostics").body["cache"]["hit"].get<bool>());
}

TEST(TransferJobs, SixtyFourJobsFromEightClientsAllSucceedWithOnePreparation) {
  const auto dir = makeTempDir("concurrent");
  const TransferFiles files = writeTransferFiles(dir);
  const std::vector<std::uint8_t> cli = runCliTransfer(files, dir);
  const std::string expected(cli.begin(), cli.end());
  InProcessService service(testConfig(dir / "data"));
  auto setup = service.client();
  Reply rig = uploadRig(*setup, files);
  ASSERT_EQ(rig.status, 201) << rig.raw;
  const std::string rig_id = rig.body["id"];

  constexpr int kClients = 8, kJobsPerClient = 8;
  std::atomic<int> succeeded{0}, identical{0}, other{0};
  std::vector<std::thread> clients;
  for (int c = 0; c < kClients; ++c) {
    clients.emplace_back([&] {
      auto client = service.client();
      for (int j = 0; j < kJobsPerClient; ++j) {
        Reply job = submitTransfer(*client, rig_id, files);
        if (job.status != 202) {
          ++other;
          continue;
        }
        const nlohmann::json done = waitForJob(*client, job.body["id"]);
        if (done.value("status", "") != "succeeded") {
          ++other;
          continue;
        }
        ++succeeded;
        Reply result = get(*client, "/v1/jobs/" + done["id"].get<std::string>() + "/result");
        if (result.raw == expected) ++identical;
      }
    });
  }
  for (auto& t : clients) t.join();
  EXPECT_EQ(succeeded, kClients * kJobsPerClient);
  EXPECT_EQ(identical, kClients * kJobsPerClient);
  EXPECT_EQ(other, 0);
  EXPECT_EQ(metricValue(*setup, "rigport_cache_misses_total{cache=\"rig\"}"), 1.0) << "the rig must be prepared exactly once";
  EXPECT_EQ(metricValue(*setup, "rigport_cache_hits_total{cache=\"rig\"}"), kClients * kJobsPerClient - 1.0);
  EXPECT_EQ(metricValue(*setup, "rigport_queue_depth"), 0.0);
}

}  // namespace
}  // namespace rigport_test
