// `rigport muscle-rig` as a studio runs it: on a generated head it writes a
// valid GLB whose morph targets include every preset, and the components JSON
// of the 26-muscle rig; a landmarks file missing a landmark fails naming the
// file and the landmark, and writes nothing.
#include <filesystem>
#include <fstream>
#include <string>

#include <gtest/gtest.h>

#include "core/io/components_io.h"
#include "core/io/landmarks.h"
#include "core/io/rig_io.h"
#include "tests/server/service_fixture.h"
#include "tests/test_support.h"

namespace rigport_test {
namespace {

std::string quoted(const std::filesystem::path& p) { return "'" + p.string() + "'"; }

// Skips until client/main.cpp wires the subcommand (client/muscle_rig_job.h).
#define REQUIRE_MUSCLE_RIG_COMMAND()                                                               \
  if (runRigportCli("--help").log.find("muscle-rig") == std::string::npos)                          \
  GTEST_SKIP() << "rigport has no muscle-rig subcommand yet (client/main.cpp): skipped"

std::filesystem::path writeHead(const std::filesystem::path& dir) {
  const CliRun run = runRigportCli("generate-head -o " + quoted(dir / "head.glb") + " --landmarks " +
                                   quoted(dir / "head.landmarks.json") + " --mouth-open 0.012");
  EXPECT_EQ(run.exit_code, 0) << run.log;
  return dir / "head.glb";
}

TEST(CliMuscleRig, WritesAValidRigWithEveryPresetBakedAndItsComponents) {
  REQUIRE_MUSCLE_RIG_COMMAND();
  const auto dir = makeTempDir("cli_muscle_rig");
  writeHead(dir);
  const CliRun run = runRigportCli("muscle-rig --mesh " + quoted(dir / "head.glb") + " --landmarks " +
                                   quoted(dir / "head.landmarks.json") + " -o " + quoted(dir / "rig.glb") +
                                   " --components " + quoted(dir / "rig.components.json"));
  ASSERT_EQ(run.exit_code, 0) << run.log;
  EXPECT_GLTF_VALID(dir / "rig.glb");
  auto components = core::readComponents(dir / "rig.components.json");
  ASSERT_TRUE(components.ok()) << components.error().message;
  EXPECT_EQ(components->muscles.size(), 26u);
  EXPECT_EQ(components->wires.size(), 16u);
  auto rig = core::readRig(dir / "rig.glb");
  ASSERT_TRUE(rig.ok()) << rig.error().message;
  EXPECT_EQ(rig->rig.baked_presets.size(), components->presets.size());
  for (const auto& [name, preset] : components->presets) {
    bool found = false;
    for (const core::MorphTarget& target : rig->rig.morph_targets) {
      if (target.name != name) continue;
      found = true;
      EXPECT_GT(target.position_deltas.rowwise().norm().maxCoeff(), 0.0) << name << " is baked as an empty target";
    }
    EXPECT_TRUE(found) << name << " is not a morph target of the rig";
  }
}

TEST(CliMuscleRig, MissingLandmarkNamesTheFileAndTheLandmark) {
  REQUIRE_MUSCLE_RIG_COMMAND();
  const auto dir = makeTempDir("cli_muscle_rig_missing");
  writeHead(dir);
  auto landmarks = core::readLandmarks(dir / "head.landmarks.json");
  ASSERT_TRUE(landmarks.ok());
  auto& list = landmarks->landmarks;
  std::erase_if(list, [](const core::Landmark& l) { return l.name == "brow_left_2"; });
  std::ofstream(dir / "partial.landmarks.json") << core::formatLandmarks(*landmarks);
  const CliRun run = runRigportCli("muscle-rig --mesh " + quoted(dir / "head.glb") + " --landmarks " +
                                   quoted(dir / "partial.landmarks.json") + " -o " + quoted(dir / "rig.glb") +
                                   " --components " + quoted(dir / "rig.components.json"));
  EXPECT_EQ(run.exit_code, 1) << run.log;
  EXPECT_NE(run.log.find("partial.landmarks.json"), std::string::npos) << run.log;
  EXPECT_NE(run.log.find("brow_left_2"), std::string::npos) << run.log;
  EXPECT_FALSE(std::filesystem::exists(dir / "rig.glb"));
  EXPECT_FALSE(std::filesystem::exists(dir / "rig.components.json"));
}

}  // namespace
}  // namespace rigport_test
