// The job lifecycle against the real service on loopback: upload, submit,
// poll, fetch; results byte-identical to the in-process CLI; many concurrent
// jobs on one rig prepare it once.
#include <gtest/gtest.h>

#include <atomic>
#include <thread>

#include "core/io/components_io.h"
#include "core/io/mesh_io.h"
#include "core/io/rig_io.h"
#include "tests/server/service_fixture.h"
#include "tests/server/store_fixture.h"
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

// The same service on the PostgreSQL store (--store postgresql://...): rig,
// job, result and the record's history as on the embedded store, and the
// result still the CLI's bytes.
TEST(TransferJobs, OnThePostgresStoreTheResultIsTheCliBytes) {
  if (rigport_test::store::testPostgresUrl().empty()) GTEST_SKIP() << rigport_test::store::kNoPostgres;
  const auto dir = makeTempDir("postgres");
  const TransferFiles files = writeTransferFiles(dir);
  const std::vector<std::uint8_t> cli = runCliTransfer(files, dir);
  ASSERT_FALSE(cli.empty());
  server::ServerConfig config = testConfig(dir / "data");
  config.store = rigport_test::store::freshPostgresLocation("service_transfer");
  std::string job_id;
  {
    InProcessService service(config);
    auto client = service.client();
    Reply rig = uploadRig(*client, files);
    ASSERT_EQ(rig.status, 201) << rig.raw;
    Reply job = submitTransfer(*client, rig.body["id"], files);
    ASSERT_EQ(job.status, 202) << job.raw;
    job_id = job.body["id"];
    const nlohmann::json done = waitForJob(*client, job_id);
    ASSERT_EQ(done["status"], "succeeded") << done.dump();
    Reply result = get(*client, "/v1/jobs/" + job_id + "/result");
    ASSERT_EQ(result.status, 200);
    EXPECT_TRUE(result.raw == std::string(cli.begin(), cli.end())) << "service result differs from the in-process CLI";
  }
  // A new process on the same database and blobs finds the job and its result.
  InProcessService again(config);
  auto client = again.client();
  Reply job = get(*client, "/v1/jobs/" + job_id);
  ASSERT_EQ(job.status, 200) << job.raw;
  EXPECT_EQ(job.body["status"], "succeeded");
  EXPECT_EQ(get(*client, "/v1/jobs/" + job_id + "/result").raw, std::string(cli.begin(), cli.end()));
}

// A rig uploaded with its components document: transfer jobs carry it to
// the target, GET /v1/jobs/{id}/components gives the same bytes as the CLI's
// --components-out, bound to the result's mesh. A rig without one: 404.
TEST(TransferJobs, ComponentsUploadedWithTheRigComeBackWithTheResult) {
  const auto dir = makeTempDir("components_jobs");
  TransferFiles files = writeTransferFiles(dir);
  files.components = dir / "rig.components.json";
  const nlohmann::json doc = {
      {"format", "rigport.components"},
      {"version", 1},
      {"locators", {{{"name", "nose"}, {"binding", {{"vertex", 120}}}}}},
      {"clusters", {{{"name", "lip_c"},
                     {"pivot", {{"face", 10}, {"barycentric", {0.2, 0.3, 0.5}}}},
                     {"members", {{{"vertex", 49}, {"weight", 1.0}}, {{"vertex", 38}, {"weight", 0.5}}}}}}},
      {"curves", {{{"name", "lip_base"}, {"degree", 1}, {"knots", {0, 0, 1, 1}}, {"points", {{{"vertex", 66}}, {{"vertex", 74}}}}},
                  {{"name", "lip"}, {"degree", 1}, {"knots", {0, 0, 1, 1}}, {"points", {{{"vertex", 66}}, {{"vertex", 74}}}},
                   {"drivers", {{{"point", 1}, {"cluster", "lip_c"}}}}}}},
      {"wires", {{{"name", "upper_lip"}, {"base_curve", "lip_base"}, {"curve", "lip"}, {"dropoff_distance", 0.03}}}},
      {"muscles", {{{"name", "zygomatic"}, {"origin", {{"position", {0.05, 0.1, 0.02}}}}, {"insertion", {{"vertex", 60}}},
                    {"range", {0, 0.5}}, {"drives", {{{"cluster", "lip_c"}, {"mode", "translate"}}}}}}},
      {"controls", {{{"name", "smile"}, {"range", {0, 1}}, {"default", 0}, {"drives", {{{"muscle", "zygomatic"}, {"gain", 0.4}}}}}}},
      {"presets", {{"smile", {{"controls", {{"smile", 1.0}}}}}}}};
  ASSERT_TRUE(core::writeFileBytes(files.components, std::span(reinterpret_cast<const std::uint8_t*>(doc.dump().data()),
                                                               doc.dump().size()))
                  .ok());
  ASSERT_FALSE(runCliTransfer(files, dir).empty());
  auto cli_components = core::readFileBytes(dir / "cli_components.json");
  ASSERT_TRUE(cli_components.ok()) << "the CLI wrote no --components-out";

  InProcessService service(testConfig(dir / "data"));
  auto client = service.client();
  Reply rig = uploadRig(*client, files);
  ASSERT_EQ(rig.status, 201) << rig.raw;
  EXPECT_TRUE(rig.body["has_components"].get<bool>());
  Reply job = submitTransfer(*client, rig.body["id"], files);
  ASSERT_EQ(job.status, 202) << job.raw;
  const std::string id = job.body["id"];
  const nlohmann::json done = waitForJob(*client, id);
  ASSERT_EQ(done["status"], "succeeded") << done.dump();
  EXPECT_TRUE(done["has_components"].get<bool>()) << done.dump();
  Reply components = get(*client, "/v1/jobs/" + id + "/components");
  ASSERT_EQ(components.status, 200) << components.raw;
  EXPECT_EQ(components.content_type, "application/json");
  EXPECT_TRUE(components.raw == std::string(cli_components->begin(), cli_components->end()))
      << "service components differ from the CLI's --components-out";
  // Bound to the result's mesh (the target's vertices), not the rig's.
  Reply result = get(*client, "/v1/jobs/" + id + "/result");
  ASSERT_EQ(result.status, 200);
  const auto glb = dir / "with_components.glb";
  ASSERT_TRUE(core::writeFileBytes(glb, std::span(reinterpret_cast<const std::uint8_t*>(result.raw.data()), result.raw.size())).ok());
  auto target_rig = core::readRig(glb);
  ASSERT_TRUE(target_rig.ok()) << target_rig.error().message;
  auto carried = core::parseRigComponents(components.raw, "job components", target_rig->rig.mesh);
  ASSERT_TRUE(carried.ok()) << carried.error().message;
  EXPECT_EQ(carried->clusters.size(), 1u);
  EXPECT_FALSE(carried->clusters[0].members.empty());
  ASSERT_EQ(carried->muscles.size(), 1u);
  EXPECT_GT((carried->muscles[0].origin.position - Eigen::Vector3d(0.05, 0.1, 0.02)).norm(), 0.0)
      << "a free point goes through the dense map";

  // "bake_presets": the carried document's presets as morph targets of the result.
  Reply baking = submitTransfer(*client, rig.body["id"], files, "", {{"bake_presets", true}});
  ASSERT_EQ(baking.status, 202) << baking.raw;
  const nlohmann::json baked_done = waitForJob(*client, baking.body["id"]);
  ASSERT_EQ(baked_done["status"], "succeeded") << baked_done.dump();
  Reply baked_result = get(*client, "/v1/jobs/" + baking.body["id"].get<std::string>() + "/result");
  ASSERT_EQ(baked_result.status, 200);
  const auto baked_glb = dir / "baked.glb";
  ASSERT_TRUE(core::writeFileBytes(baked_glb, std::span(reinterpret_cast<const std::uint8_t*>(baked_result.raw.data()),
                                                        baked_result.raw.size()))
                  .ok());
  EXPECT_GLTF_VALID(baked_glb);
  auto baked_rig = core::readRig(baked_glb);
  ASSERT_TRUE(baked_rig.ok()) << baked_rig.error().message;
  EXPECT_EQ(baked_rig->rig.baked_presets, std::vector<std::string>{"smile"});
  ASSERT_EQ(baked_rig->rig.morph_targets.size(), target_rig->rig.morph_targets.size() + 1);
  EXPECT_GT(baked_rig->rig.morph_targets.back().position_deltas.rowwise().norm().maxCoeff(), 0.0)
      << "the smile moves the target's face";

  // The same rig without its document: no components.
  TransferFiles bare = files;
  bare.components.clear();
  Reply bare_rig = uploadRig(*client, bare);
  ASSERT_EQ(bare_rig.status, 201) << bare_rig.raw;
  EXPECT_NE(bare_rig.body["id"], rig.body["id"]) << "the document is part of the rig's content id";
  Reply bare_job = submitTransfer(*client, bare_rig.body["id"], bare);
  ASSERT_EQ(bare_job.status, 202) << bare_job.raw;
  const nlohmann::json bare_done = waitForJob(*client, bare_job.body["id"]);
  ASSERT_EQ(bare_done["status"], "succeeded") << bare_done.dump();
  EXPECT_FALSE(bare_done["has_components"].get<bool>());
  Reply none = get(*client, "/v1/jobs/" + bare_job.body["id"].get<std::string>() + "/components");
  EXPECT_EQ(none.status, 404) << none.raw;
  EXPECT_NE(none.raw.find("no components document"), std::string::npos) << none.raw;
  // Baking presets needs the document: refused at submission, saying so.
  Reply cannot_bake = submitTransfer(*client, bare_rig.body["id"], bare, "", {{"bake_presets", {"smile"}}});
  EXPECT_EQ(cannot_bake.status, 400) << cannot_bake.raw;
  EXPECT_EQ(cannot_bake.body.value("type", ""), "urn:rigport:problem:invalid-option") << cannot_bake.raw;
  EXPECT_NE(cannot_bake.raw.find("bake_presets"), std::string::npos) << cannot_bake.raw;
  EXPECT_NE(cannot_bake.raw.find("without a components document"), std::string::npos) << cannot_bake.raw;
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
