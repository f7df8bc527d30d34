// `rigport warp` as a studio tool runs it: the pipeline flags (--light,
// --plain, --refine, --local-rounds) reach the warp, shown by the diagnostics
// it writes, and contradictory flags are refused.
#include <cstdlib>
#include <fstream>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "core/io/mesh_io.h"
#include "tests/server/service_fixture.h"
#include "tests/test_support.h"

namespace {

struct WarpRun {
  int exit_code = -1;
  nlohmann::json diagnostics;
};

WarpRun runWarp(const rigport_test::TransferFiles& files, const std::filesystem::path& dir, const std::string& flags) {
  const std::filesystem::path guide = dir / "guide.glb", diagnostics = dir / "d.json";
  std::filesystem::remove(diagnostics);
  const std::string cmd = std::string("'") + RIGPORT_CLI_PATH + "' -q warp --source '" + files.rig.string() +
                          "' --source-landmarks '" + files.landmarks.string() + "' --target '" +
                          files.target.string() + "' --target-landmarks '" + files.target_landmarks.string() +
                          "' -o '" + guide.string() + "' --diagnostics '" + diagnostics.string() + "' " + flags +
                          " 2>/dev/null";
  WarpRun run;
  const int status = std::system(cmd.c_str());
  run.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  if (run.exit_code == 0) {
    auto bytes = core::readFileBytes(diagnostics);
    EXPECT_TRUE(bytes.ok()) << cmd;
    if (bytes) run.diagnostics = nlohmann::json::parse(bytes->begin(), bytes->end(), nullptr, false);
  }
  return run;
}

TEST(CliWarp, PipelineFlagsReachTheWarp) {
  const auto dir = rigport_test::makeTempDir("cli_warp");
  const rigport_test::TransferFiles files = rigport_test::writeTransferFiles(dir, 40);

  // A count of the run's correspondence diagnostics.
  auto count = [](const WarpRun& run, const char* key) { return run.diagnostics["correspondence"][key].get<int>(); };

  const WarpRun standard = runWarp(files, dir, "");
  ASSERT_EQ(standard.exit_code, 0);
  EXPECT_EQ(count(standard, "refine_iterations"), 2);
  EXPECT_GT(count(standard, "target_pulls"), 0);
  EXPECT_GT(count(standard, "matched_rims"), 0);
  EXPECT_GT(count(standard, "rim_located_vertices"), 0);
  // A warp job returns the guide: every source vertex is projected.
  EXPECT_EQ(count(standard, "projected_source_vertices"), standard.diagnostics["mesh"]["source_vertices"].get<int>());

  const WarpRun light = runWarp(files, dir, "--light");
  ASSERT_EQ(light.exit_code, 0);
  EXPECT_EQ(count(light, "refine_iterations"), 0);
  EXPECT_EQ(count(light, "target_pulls"), 0);
  EXPECT_GT(count(light, "matched_rims"), 0);
  EXPECT_EQ(count(light, "rim_located_vertices"), 0);

  const WarpRun plain = runWarp(files, dir, "--plain");
  ASSERT_EQ(plain.exit_code, 0);
  EXPECT_EQ(count(plain, "refine_iterations"), 0);
  EXPECT_EQ(count(plain, "target_pulls"), 0);
  EXPECT_EQ(count(plain, "matched_rims"), 0);
  EXPECT_EQ(count(plain, "rim_located_vertices"), 0);

  const WarpRun one_round = runWarp(files, dir, "--refine 1 --local-rounds 0");
  ASSERT_EQ(one_round.exit_code, 0);
  EXPECT_EQ(count(one_round, "refine_iterations"), 1);
  EXPECT_EQ(count(one_round, "target_pulls"), 0);  // pulls act in local rounds

  EXPECT_NE(runWarp(files, dir, "--light --plain").exit_code, 0);
  EXPECT_NE(runWarp(files, dir, "--light --refine 1").exit_code, 0);
  EXPECT_NE(runWarp(files, dir, "--plain --local-rounds 2").exit_code, 0);
}

// Untrusted JSON the CLI reads (an options file with a number out of range,
// or nested past any use): a clear error and exit 1, not an abort.
TEST(CliTransfer, HostileOptionsFilesAreErrorsNotAborts) {
  const auto dir = rigport_test::makeTempDir("cli_hostile");
  const rigport_test::TransferFiles files = rigport_test::writeTransferFiles(dir);
  const std::filesystem::path options = dir / "opts.json", log = dir / "log.txt";
  for (const std::string& text : {std::string(R"({"exaggeration": 1e400})"), std::string(100000, '[') + std::string(100000, ']')}) {
    std::ofstream(options, std::ios::binary) << text;
    const std::string cmd = std::string("'") + RIGPORT_CLI_PATH + "' transfer --source '" + files.rig.string() +
                            "' --source-landmarks '" + files.landmarks.string() + "' --target '" +
                            files.target.string() + "' --target-landmarks '" + files.target_landmarks.string() +
                            "' -o '" + (dir / "out.glb").string() + "' --options '" + options.string() + "' > '" +
                            log.string() + "' 2>&1";
    const int status = std::system(cmd.c_str());
    ASSERT_TRUE(WIFEXITED(status)) << cmd;
    EXPECT_EQ(WEXITSTATUS(status), 1);
    std::ifstream in(log);
    const std::string output((std::istreambuf_iterator<char>(in)), {});
    EXPECT_NE(output.find("opts.json: "), std::string::npos) << output;
  }
}

}  // namespace
