// The CLI's service commands end to end against the real service on
// loopback: `rigs upload|list|get|delete` and `jobs
// submit|get|wait|list|result|delete`, with the JSON each prints and the
// errors a TD sees (a job that is gone, an unfinished job deleted).
#include <filesystem>
#include <span>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "core/io/mesh_io.h"
#include "tests/server/service_fixture.h"
#include "tests/test_support.h"

namespace rigport_test {
namespace {

std::string quoted(const std::filesystem::path& path) { return "'" + path.string() + "'"; }

nlohmann::json printed(const CliRun& run) {
  auto json = nlohmann::json::parse(run.out, nullptr, false);
  EXPECT_FALSE(json.is_discarded()) << run.log;
  return json;
}

TEST(CliRemote, RigsAndJobsCommandsRunAJobAndDeleteIt) {
  const auto dir = makeTempDir("cli_remote");
  const TransferFiles files = writeTransferFiles(dir);
  InProcessService service(testConfig(dir / "data"));
  const std::string server = " --server http://127.0.0.1:" + std::to_string(service.port());

  const CliRun upload = runRigportCli("-q rigs upload" + server + " --rig " + quoted(files.rig) + " --landmarks " +
                                      quoted(files.landmarks));
  ASSERT_EQ(upload.exit_code, 0) << upload.log;
  const std::string rig_id = printed(upload)["id"];
  EXPECT_EQ(printed(runRigportCli("-q rigs list" + server))["items"].size(), 1u);

  const std::string spec = nlohmann::json{{"kind", "transfer"}, {"rig", rig_id}}.dump();
  ASSERT_TRUE(core::writeFileBytes(dir / "spec.json", std::span(reinterpret_cast<const std::uint8_t*>(spec.data()), spec.size())).ok());
  const CliRun submit = runRigportCli("-q jobs submit" + server + " --spec " + quoted(dir / "spec.json") +
                                      " --file target=" + quoted(files.target) + " --file target_landmarks=" +
                                      quoted(files.target_landmarks));
  ASSERT_EQ(submit.exit_code, 0) << submit.log;
  const std::string job_id = printed(submit)["id"];
  const CliRun wait = runRigportCli("-q jobs wait" + server + " " + job_id);
  ASSERT_EQ(wait.exit_code, 0) << wait.log;
  EXPECT_EQ(printed(wait)["status"], "succeeded");
  const CliRun result = runRigportCli("-q jobs result" + server + " " + job_id + " -o " + quoted(dir / "out.glb"));
  ASSERT_EQ(result.exit_code, 0) << result.log;
  auto downloaded = core::readFileBytes(dir / "out.glb");
  ASSERT_TRUE(downloaded.ok()) << result.log;
  EXPECT_EQ(*downloaded, runCliTransfer(files, dir)) << "the service's result differs from the in-process CLI's";

  const CliRun deleted = runRigportCli("-q jobs delete" + server + " " + job_id);
  ASSERT_EQ(deleted.exit_code, 0) << deleted.log;
  EXPECT_EQ(printed(deleted), (nlohmann::json{{"id", job_id}, {"deleted", true}}));
  const CliRun gone = runRigportCli("-q jobs get" + server + " " + job_id);
  EXPECT_EQ(gone.exit_code, 1) << gone.log;
  EXPECT_NE(gone.log.find("no job " + job_id), std::string::npos) << gone.log;
  EXPECT_TRUE(printed(runRigportCli("-q jobs list" + server))["items"].empty());

  EXPECT_EQ(runRigportCli("-q rigs delete" + server + " " + rig_id).exit_code, 0);
  EXPECT_EQ(runRigportCli("-q rigs get" + server + " " + rig_id).exit_code, 1);
}

}  // namespace
// rigport bench over two services (replicas without a balancer): the rig goes
// to each, the clients are spread over both, every job succeeds, and each
// service ran its clients' share (4 clients of 2 jobs each, 2 per service).
TEST(CliRemote, BenchSpreadsItsClientsOverSeveralServices) {
  const auto dir = makeTempDir("bench_two");
  const TransferFiles files = writeTransferFiles(dir);
  InProcessService first(testConfig(dir / "data1"));
  InProcessService second(testConfig(dir / "data2"));
  const std::string url1 = "http://127.0.0.1:" + std::to_string(first.port());
  const std::string url2 = "http://127.0.0.1:" + std::to_string(second.port());
  const CliRun bench = runRigportCli("-q bench --server " + url1 + "," + url2 + " --concurrency 4 --jobs 8 --source " +
                                     quoted(files.rig) + " --source-landmarks " + quoted(files.landmarks) +
                                     " --target " + quoted(files.target) + " --target-landmarks " +
                                     quoted(files.target_landmarks));
  ASSERT_EQ(bench.exit_code, 0) << bench.log;
  std::string out = bench.out;
  while (!out.empty() && out.back() == '\n') out.pop_back();
  const std::string last_line = out.substr(out.rfind('\n') == std::string::npos ? 0 : out.rfind('\n') + 1);
  const auto summary = nlohmann::json::parse(last_line, nullptr, false);
  ASSERT_FALSE(summary.is_discarded()) << bench.out;
  EXPECT_EQ(summary["succeeded"], 8) << bench.out;
  for (const std::string& url : {url1, url2}) {
    const CliRun listed = runRigportCli("-q jobs list --server " + url);
    ASSERT_EQ(listed.exit_code, 0) << listed.log;
    EXPECT_EQ(printed(listed)["items"].size(), 4u) << url << " ran other than its clients' share of the jobs";
  }
}

}  // namespace rigport_test
