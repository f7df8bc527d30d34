// The transfer's quality check end to end: a transfer whose lips cross (a
// head with touching lips and a sagging mouth, 10 landmarks, matched without
// the openings' sides and without repair) warns by default and, strict,
// fails with a clear error naming the shapes, through the CLI in-process,
// the CLI against the service, and the service's REST API.
#include <cstdlib>
#include <fstream>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "core/io/landmarks.h"
#include "core/io/mesh_io.h"
#include "core/io/rig_io.h"
#include "core/synthetic/synthetic_rig.h"
#include "tests/server/service_fixture.h"
#include "tests/test_support.h"

namespace {

using namespace rigport_test;

void writeFile(const std::filesystem::path& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  out << text;
}


TransferFiles writeCrossingFiles(const std::filesystem::path& dir) {
  std::filesystem::create_directories(dir);
  TransferFiles f{dir / "touching_rig.glb", dir / "touching_rig.landmarks.json", dir / "sagging.glb",
                  dir / "sagging.landmarks.json", {}};
  const core::SyntheticRig& rig = touchingLipsSource();
  EXPECT_TRUE(core::writeRigGlb(rig.rig, f.rig).ok());
  writeFile(f.landmarks, core::formatLandmarks(rig.landmarks));
  const core::SyntheticRig& target = saggingMouthTarget();
  core::Mesh scan = target.rig.mesh;
  scan.regions.resize(0);
  EXPECT_TRUE(core::writeMeshGlb(scan, f.target).ok());
  writeFile(f.target_landmarks, core::formatLandmarks(tenLandmarks(target)));
  return f;
}

CliRun runCli(const TransferFiles& f, const std::filesystem::path& dir, const std::string& flags) {
  const std::filesystem::path out = dir / "out.glb";
  std::filesystem::remove(out);
  return runRigportCli("transfer --source '" + f.rig.string() + "' --source-landmarks '" + f.landmarks.string() +
                       "' --target '" + f.target.string() + "' --target-landmarks '" + f.target_landmarks.string() +
                       "' -o '" + out.string() + "' " + flags);
}

const nlohmann::json kCrossing = {{"side_matching", false}, {"repair_unsure", false}};

TEST(QualityGate, StrictFailsACrossingTransferInTheCli) {
  const auto dir = makeTempDir("gate_cli");
  const TransferFiles f = writeCrossingFiles(dir);
  writeFile(dir / "crossing.json", kCrossing.dump());
  const std::string crossing = "--options '" + (dir / "crossing.json").string() + "'";

  const CliRun warned = runCli(f, dir, crossing);
  EXPECT_EQ(warned.exit_code, 0) << warned.log;
  EXPECT_NE(warned.log.find("sagging.glb: unsure vertices, check them before use:"), std::string::npos) << warned.log;
  EXPECT_NE(warned.log.find("located across an opening (the other lip or lid), moving in jawOpen"), std::string::npos)
      << warned.log;

  const CliRun failed = runCli(f, dir, crossing + " --strict");
  EXPECT_EQ(failed.exit_code, 1) << failed.log;
  EXPECT_NE(failed.log.find("sagging.glb: the transfer failed its quality check (strict):"), std::string::npos)
      << failed.log;
  EXPECT_NE(failed.log.find("jawOpen"), std::string::npos) << failed.log;
  EXPECT_FALSE(std::filesystem::exists(dir / "out.glb"));

  // Matched with the openings' sides (the default), the same target passes strict.
  const CliRun passed = runCli(f, dir, "--strict");
  EXPECT_EQ(passed.exit_code, 0) << passed.log;
  EXPECT_TRUE(std::filesystem::exists(dir / "out.glb"));
}

TEST(QualityGate, StrictFailsACrossingTransferOnTheService) {
  const auto dir = makeTempDir("gate_service");
  const TransferFiles f = writeCrossingFiles(dir / "files");
  InProcessService service(testConfig(dir / "data"));
  auto client = service.client();
  const Reply rig = uploadRig(*client, f);
  ASSERT_EQ(rig.status, 201) << rig.raw;
  const std::string rig_id = rig.body["id"];

  nlohmann::json strict = kCrossing;
  strict["strict"] = true;
  const Reply submitted = submitTransfer(*client, rig_id, f, "", strict);
  ASSERT_EQ(submitted.status, 202) << submitted.raw;
  const nlohmann::json job = waitForJob(*client, submitted.body["id"]);
  EXPECT_EQ(job["status"], "failed") << job.dump();
  EXPECT_EQ(job["error"]["type"], "urn:rigport:problem:quality-gate") << job.dump();
  EXPECT_EQ(job["error"]["status"], 422) << job.dump();
  const std::string detail = job["error"]["detail"];
  EXPECT_NE(detail.find("the transfer failed its quality check (strict)"), std::string::npos) << detail;
  EXPECT_NE(detail.find("vertices located across an opening (the other lip or lid), moving in jawOpen ("),
            std::string::npos)
      << detail;

  // Not strict: the job succeeds and its diagnostics say what the check found.
  const Reply lenient = submitTransfer(*client, rig_id, f, "", kCrossing);
  ASSERT_EQ(lenient.status, 202) << lenient.raw;
  const std::string id = lenient.body["id"];
  EXPECT_EQ(waitForJob(*client, id)["status"], "succeeded");
  const Reply diagnostics = get(*client, "/v1/jobs/" + id + "/diagnostics");
  ASSERT_EQ(diagnostics.status, 200) << diagnostics.raw;
  EXPECT_EQ(diagnostics.body["quality"]["clean"], false) << diagnostics.raw;
  EXPECT_GT(diagnostics.body["quality"]["crossed_vertices"].get<int>(), 0) << diagnostics.raw;

  // The CLI against the service: the same error, and a failed exit.
  const std::string url = "--server http://127.0.0.1:" + std::to_string(service.port());
  writeFile(dir / "crossing.json", kCrossing.dump());
  const CliRun remote = runCli(f, dir, url + " --options '" + (dir / "crossing.json").string() + "' --strict");
  EXPECT_EQ(remote.exit_code, 1) << remote.log;
  EXPECT_NE(remote.log.find("Job output failed its quality check (HTTP 422)"), std::string::npos) << remote.log;
  EXPECT_NE(remote.log.find("jawOpen"), std::string::npos) << remote.log;
  service.stop();
}

}  // namespace
