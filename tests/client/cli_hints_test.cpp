// What `rigport` says to a wrong command line: the command, flag or option
// key a typo meant; output paths it cannot write refused before any work;
// its version; only commands that exist in its help.
#include "client/cli_hints.h"

#include <filesystem>
#include <string>

#include <gtest/gtest.h>

#include "core/base/error.h"
#include "tests/server/service_fixture.h"
#include "tests/test_support.h"

namespace {

using rigport_test::CliRun;

CliRun rigport(const std::string& arguments) { return rigport_test::runRigportCli(arguments); }

TEST(ClosestName, FindsTheNameATypoMeant) {
  const std::vector<std::string> commands = {"warp", "transfer", "retarget", "generate-head", "rigs", "jobs", "bench"};
  EXPECT_EQ(core::closestName("tranfser", commands), "transfer");
  EXPECT_EQ(core::closestName("Retarget", commands), "retarget");
  EXPECT_EQ(core::closestName("wrap", commands), "warp");
  EXPECT_EQ(core::closestName("sculpt", commands), "");
  EXPECT_EQ(core::closestName("x", {}), "");
}

TEST(CliHints, TyposAreAnsweredWithWhatTheyMeant) {
  const CliRun command = rigport("tranfser");
  EXPECT_NE(command.exit_code, 0);
  EXPECT_NE(command.log.find("'tranfser' is not a command; did you mean 'transfer'?"), std::string::npos)
      << command.log;
  const CliRun nested = rigport("rigs lst");
  EXPECT_NE(nested.log.find("did you mean 'list'?"), std::string::npos) << nested.log;
  const CliRun flag = rigport("transfer --outptu x.glb");
  EXPECT_NE(flag.exit_code, 0);
  EXPECT_NE(flag.log.find("'--outptu' is not a flag of transfer; did you mean '--output'?"), std::string::npos)
      << flag.log;
}

TEST(CliHints, AnOutputItCannotWriteIsRefusedBeforeAnyWork) {
  const auto dir = rigport_test::makeTempDir("cli_fbx");
  const CliRun fbx = rigport("generate-head -o '" + (dir / "head.fbx").string() + "' --landmarks '" +
                          (dir / "head.json").string() + "'");
  EXPECT_NE(fbx.exit_code, 0);
  EXPECT_NE(fbx.log.find("rigport writes binary glTF; name the output .glb"), std::string::npos) << fbx.log;
  EXPECT_FALSE(std::filesystem::exists(dir / "head.fbx"));
  const CliRun glb = rigport("-q generate-head -o '" + (dir / "head.GLB").string() + "' --landmarks '" +
                          (dir / "head.json").string() + "'");
  EXPECT_EQ(glb.exit_code, 0) << glb.log;
  EXPECT_TRUE(std::filesystem::exists(dir / "head.GLB"));
}

TEST(CliHints, VersionAndHelpSayWhatIsThere) {
  const CliRun version = rigport("--version");
  EXPECT_EQ(version.exit_code, 0);
  EXPECT_EQ(version.log.rfind("rigport ", 0), 0u) << version.log;
  const CliRun help = rigport("--help");
  EXPECT_EQ(help.exit_code, 0);
  EXPECT_NE(help.log.find("  fit "), std::string::npos) << help.log;
}

}  // namespace
