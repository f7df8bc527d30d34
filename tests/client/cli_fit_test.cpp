// `rigport fit` in-process as a studio tool runs it, on inputs the CLI itself
// generates (`demo --inputs-only`: the reference rig; `generate-head`: scans):
// the fitted rig (a valid glTF) and its diagnostics; a scan without landmarks
// found by the search; bad input is a clear error and writes nothing.
#include <filesystem>
#include <fstream>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "tests/server/service_fixture.h"
#include "tests/test_support.h"

namespace rigport_test {
namespace {

std::string quoted(const std::filesystem::path& p) { return "'" + p.string() + "'"; }

nlohmann::json readJson(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  return nlohmann::json::parse(std::string(std::istreambuf_iterator<char>(in), {}), nullptr, false);
}

// The demo's reference rig (source_rig.glb + landmarks) in `dir`, and a scan:
// a head of identity `seed` (0: the reference's own shape) on another grid,
// in millimetres, with its 68 landmarks.
void writeInputs(const std::filesystem::path& dir, int seed) {
  const CliRun demo = runRigportCli("-q demo --inputs-only --out " + quoted(dir));
  ASSERT_EQ(demo.exit_code, 0) << demo.log;
  const CliRun head = runRigportCli("-q generate-head -o " + quoted(dir / "scan.glb") + " --landmarks " +
                                    quoted(dir / "scan.landmarks.json") + " --seed " + std::to_string(seed) +
                                    " --columns 90 --rows 84 --alternate-diagonals --jitter 0.3 --scale 1000");
  ASSERT_EQ(head.exit_code, 0) << head.log;
}

std::string fitArguments(const std::filesystem::path& dir, const std::filesystem::path& scan,
                         const std::string& scan_landmarks) {
  return "fit --reference " + quoted(dir / "source_rig.glb") + " --reference-landmarks " +
         quoted(dir / "source_rig.landmarks.json") + " --scan " + quoted(scan) + scan_landmarks + " -o " +
         quoted(dir / "fitted.glb") + " --diagnostics " + quoted(dir / "fitted.json");
}

TEST(CliFit, WritesAValidRigAndItsDiagnostics) {
  const auto dir = makeTempDir("cli_fit");
  writeInputs(dir, 3);
  const CliRun run = runRigportCli(fitArguments(dir, dir / "scan.glb", " --scan-landmarks " + quoted(dir / "scan.landmarks.json")));
  ASSERT_EQ(run.exit_code, 0) << run.log;
  EXPECT_NE(run.log.find("fit: ok (landmarks alignment, scan in mm"), std::string::npos) << run.log;
  EXPECT_NE(run.log.find("wrote "), std::string::npos) << run.log;
  EXPECT_GLTF_VALID(dir / "fitted.glb");
  const nlohmann::json d = readJson(dir / "fitted.json");
  ASSERT_TRUE(d.is_object()) << run.log;
  EXPECT_EQ(d["verdict"], "ok") << d.dump().substr(0, 600);
  EXPECT_EQ(d["alignment"]["method"], "landmarks");
  EXPECT_EQ(d["scan"]["units"], "mm");
  EXPECT_EQ(d["rebuild"]["shapes"], 6);
  EXPECT_EQ(d["rebuild"]["joints"], 6);
  EXPECT_GT(d["coverage"]["face"].get<double>(), 0.9);
  EXPECT_GT(d["timings_ms"]["total"].get<double>(), 0.0);
}

// The reference's own shape, sampled otherwise and in other units: found by
// the landmark-free search with no other pose near it.
TEST(CliFit, FindsAScanWithoutLandmarksBySearch) {
  const auto dir = makeTempDir("cli_fit_search");
  writeInputs(dir, 0);
  const CliRun run = runRigportCli(fitArguments(dir, dir / "scan.glb", ""));
  ASSERT_EQ(run.exit_code, 0) << run.log;
  EXPECT_GLTF_VALID(dir / "fitted.glb");
  const nlohmann::json d = readJson(dir / "fitted.json");
  EXPECT_EQ(d["verdict"], "ok") << d.dump().substr(0, 600);
  EXPECT_EQ(d["alignment"]["method"], "search");
  EXPECT_GT(d["alignment"]["inlier_fraction"].get<double>(), 0.9);
  EXPECT_NEAR(d["alignment"]["scale"].get<double>(), 1000.0, 10.0);
}

// --reference-components: the document rebuilt by vertex index on the fitted
// mesh (bindings and members as they were, lengths in the scan's units);
// a document that does not fit the reference is refused naming its field.
TEST(CliFit, ComponentsAreRebuiltByVertexIndex) {
  const auto dir = makeTempDir("cli_fit_components");
  writeInputs(dir, 3);
  const nlohmann::json doc = {
      {"format", "rigport.components"},
      {"version", 1},
      {"locators", {{{"name", "nose"}, {"binding", {{"vertex", 120}}}}, {{"name", "free"}, {"binding", {{"position", {0.01, 0.02, 0.03}}}}}}},
      {"clusters", {{{"name", "lip_c"}, {"pivot", {{"face", 10}, {"barycentric", {0.2, 0.3, 0.5}}}},
                     {"members", {{{"vertex", 49}, {"weight", 1.0}}, {{"vertex", 38}, {"weight", 0.5}}}}}}},
      {"curves", {{{"name", "lip_base"}, {"degree", 1}, {"knots", {0, 0, 1, 1}}, {"points", {{{"vertex", 66}}, {{"vertex", 74}}}}},
                  {{"name", "lip"}, {"degree", 1}, {"knots", {0, 0, 1, 1}}, {"points", {{{"vertex", 66}}, {{"vertex", 74}}}}}}},
      {"wires", {{{"name", "upper_lip"}, {"base_curve", "lip_base"}, {"curve", "lip"}, {"dropoff_distance", 0.03}}}}};
  std::ofstream(dir / "rig.components.json") << doc.dump();
  const std::string components = " --reference-components " + quoted(dir / "rig.components.json") +
                                 " --components-out " + quoted(dir / "fitted.components.json");
  const std::string landmarks = " --scan-landmarks " + quoted(dir / "scan.landmarks.json");
  const CliRun run = runRigportCli(fitArguments(dir, dir / "scan.glb", landmarks + components));
  ASSERT_EQ(run.exit_code, 0) << run.log;
  EXPECT_GLTF_VALID(dir / "fitted.glb");
  const nlohmann::json out = readJson(dir / "fitted.components.json");
  ASSERT_TRUE(out.is_object()) << run.log;
  EXPECT_EQ(out["locators"][0]["binding"], doc["locators"][0]["binding"]);
  EXPECT_EQ(out["clusters"][0]["pivot"], doc["clusters"][0]["pivot"]);
  EXPECT_EQ(out["clusters"][0]["members"], doc["clusters"][0]["members"]);
  EXPECT_EQ(out["curves"][1]["points"], doc["curves"][1]["points"]);
  // The scan is in millimetres, the reference in metres: lengths follow.
  const double dropoff = out["wires"][0]["dropoff_distance"].get<double>();
  EXPECT_GT(dropoff, 0.03 * 1000.0 * 0.8) << out["wires"].dump();
  EXPECT_LT(dropoff, 0.03 * 1000.0 * 1.25) << out["wires"].dump();

  // Out of range for the reference: refused before anything runs.
  nlohmann::json bad = doc;
  bad["locators"][0]["binding"]["vertex"] = 99999999;
  std::ofstream(dir / "bad.components.json") << bad.dump();
  std::filesystem::remove(dir / "fitted.glb");
  const CliRun refused = runRigportCli(fitArguments(dir, dir / "scan.glb", landmarks) + " --reference-components " +
                                       quoted(dir / "bad.components.json"));
  EXPECT_EQ(refused.exit_code, 1) << refused.log;
  EXPECT_NE(refused.log.find("bad.components.json"), std::string::npos) << refused.log;
  EXPECT_NE(refused.log.find("nose"), std::string::npos) << refused.log;
  EXPECT_FALSE(std::filesystem::exists(dir / "fitted.glb"));

  // --components-out needs the reference's document.
  const CliRun alone = runRigportCli(fitArguments(dir, dir / "scan.glb", landmarks) + " --components-out " +
                                     quoted(dir / "x.json"));
  EXPECT_NE(alone.exit_code, 0) << alone.log;
  EXPECT_NE(alone.log.find("--reference-components"), std::string::npos) << alone.log;
}

TEST(CliFit, BadInputIsAClearErrorAndWritesNothing) {
  const auto dir = makeTempDir("cli_fit_bad");
  writeInputs(dir, 3);
  const std::string landmarks = " --scan-landmarks " + quoted(dir / "scan.landmarks.json");

  // A landmarks path that does not exist: refused before anything runs.
  const CliRun missing = runRigportCli(fitArguments(dir, dir / "scan.glb", " --scan-landmarks " + quoted(dir / "nowhere.json")));
  EXPECT_NE(missing.exit_code, 0) << missing.log;
  EXPECT_NE(missing.log.find("--scan-landmarks"), std::string::npos) << missing.log;
  EXPECT_NE(missing.log.find("nowhere.json"), std::string::npos) << missing.log;
  EXPECT_FALSE(std::filesystem::exists(dir / "fitted.glb"));
  EXPECT_FALSE(std::filesystem::exists(dir / "fitted.json"));

  // An empty scan file.
  std::ofstream(dir / "empty.ply").close();
  const CliRun empty = runRigportCli(fitArguments(dir, dir / "empty.ply", landmarks));
  EXPECT_EQ(empty.exit_code, 1) << empty.log;
  EXPECT_NE(empty.log.find("empty.ply"), std::string::npos) << empty.log;
  EXPECT_FALSE(std::filesystem::exists(dir / "fitted.glb"));
  EXPECT_FALSE(std::filesystem::exists(dir / "fitted.json"));

  // Landmarks naming a point the reference lacks.
  auto renamed = readJson(dir / "scan.landmarks.json");
  renamed["landmarks"][0]["name"] = "earlobe_left";
  std::ofstream(dir / "renamed.json") << renamed.dump();
  const CliRun unknown = runRigportCli(fitArguments(dir, dir / "scan.glb", " --scan-landmarks " + quoted(dir / "renamed.json")));
  EXPECT_EQ(unknown.exit_code, 1) << unknown.log;
  EXPECT_NE(unknown.log.find("earlobe_left"), std::string::npos) << unknown.log;
  EXPECT_FALSE(std::filesystem::exists(dir / "fitted.glb"));
}

}  // namespace
}  // namespace rigport_test
