// `rigport pose` as a studio tool runs it, on a generated rig (with a small
// unskinned part) and a components document raising a cluster of vertices:
// a preset and a morph weight each give a valid static GLB that moves what
// they drive and nothing else; unknown names and presets without
// --components are clear errors that write nothing.
#include <algorithm>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "core/io/rig_io.h"
#include "core/synthetic/synthetic_rig.h"
#include "tests/server/service_fixture.h"
#include "tests/test_support.h"

namespace rigport_test {
namespace {

std::string quoted(const std::filesystem::path& p) { return "'" + p.string() + "'"; }

void writeText(const std::filesystem::path& path, const std::string& text) { std::ofstream(path) << text; }

// The cluster's members and how far the preset raises them (model units).
constexpr int kFirstMember = 100, kMemberCount = 20;
constexpr double kRaise = 0.01;

// A tetrahedron (an unskinned "tooth" on root node `node`) whose jawOpen target moves its apex.
core::RigPart toothPart(int node) {
  core::RigPart tooth;
  tooth.name = "tooth";
  tooth.node = node;
  tooth.mesh.positions.resize(4, 3);
  tooth.mesh.positions << 0, 0, 0.05, 0.01, 0, 0.05, 0, 0.01, 0.05, 0, 0, 0.06;
  tooth.mesh.triangles.resize(4, 3);
  tooth.mesh.triangles << 0, 2, 1, 0, 1, 3, 1, 2, 3, 0, 3, 2;
  core::MorphTarget open;
  open.name = "jawOpen";
  open.position_deltas = Eigen::MatrixX3d::Zero(4, 3);
  open.position_deltas(3, 1) = -0.005;
  tooth.morph_targets = {open};
  tooth.morph_default_weights = Eigen::VectorXd::Zero(1);
  return tooth;
}

// rig.glb (the generated rig and the tooth), components.json (cluster
// "chin" on kMemberCount vertices, control "chin_up", preset "chin_raised"),
// and the rig as read back (float32, what the command reads).
core::Rig writeInputs(const std::filesystem::path& dir) {
  core::Rig rig = core::generateRig().rig;
  core::Node tooth_node;
  tooth_node.name = "tooth";
  rig.nodes.push_back(tooth_node);
  rig.parts.push_back(toothPart(static_cast<int>(rig.nodes.size()) - 1));
  EXPECT_TRUE(core::writeRigGlb(rig, dir / "rig.glb").ok());
  std::string members;
  for (int v = kFirstMember; v < kFirstMember + kMemberCount; ++v) {
    members += (members.empty() ? "" : ", ") + std::string("{\"vertex\": ") + std::to_string(v) + "}";
  }
  writeText(dir / "components.json",
            R"({"format": "rigport.components", "version": 1,
                "clusters": [{"name": "chin", "pivot": {"vertex": )" + std::to_string(kFirstMember) +
                R"(}, "members": [)" + members + R"(]}],
                "controls": [{"name": "chin_up", "drives": [{"cluster": "chin", "channel": "translate_y", "gain": )" +
                std::to_string(kRaise) + R"(}]}],
                "presets": {"chin_raised": {"controls": {"chin_up": 1}}}})");
  auto read = core::readRig(dir / "rig.glb");
  EXPECT_TRUE(read.ok()) << (read ? "" : read.error().message);
  return read ? read->rig : core::Rig{};
}

CliRun runPose(const std::filesystem::path& dir, const std::string& pose_json, bool with_components = true) {
  writeText(dir / "pose.json", pose_json);
  std::filesystem::remove(dir / "posed.glb");
  return runRigportCli("pose --rig " + quoted(dir / "rig.glb") +
                       (with_components ? " --components " + quoted(dir / "components.json") : "") + " --pose " +
                       quoted(dir / "pose.json") + " -o " + quoted(dir / "posed.glb"));
}

// The written GLB read back: static (no skin, shapes or clips), the face and the tooth.
core::Rig readPosed(const std::filesystem::path& file) {
  auto read = core::readRig(file);
  EXPECT_TRUE(read.ok()) << (read ? "" : read.error().message);
  if (!read) return {};
  EXPECT_FALSE(read->rig.skin.has_value());
  EXPECT_TRUE(read->rig.morph_targets.empty());
  EXPECT_TRUE(read->rig.animations.empty());
  EXPECT_EQ(read->rig.parts.size(), 1u);
  return std::move(read->rig);
}

TEST(CliPose, PresetMovesTheClusterMembersOnly) {
  const auto dir = makeTempDir("cli_pose_preset");
  const core::Rig rest = writeInputs(dir);
  const CliRun run = runPose(dir, R"({"preset": "chin_raised"})");
  ASSERT_EQ(run.exit_code, 0) << run.log;
  EXPECT_NE(run.log.find("pose 'chin_raised'"), std::string::npos) << run.log;
  EXPECT_NE(run.log.find(std::to_string(kMemberCount) + " of " + std::to_string(rest.mesh.vertexCount()) +
                         " face vertices moved"),
            std::string::npos)
      << run.log;
  EXPECT_GLTF_VALID(dir / "posed.glb");
  const core::Rig posed = readPosed(dir / "posed.glb");
  ASSERT_EQ(posed.mesh.vertexCount(), rest.mesh.vertexCount());
  const Eigen::MatrixX3d moved = posed.mesh.positions - rest.mesh.positions;
  for (Eigen::Index v = 0; v < moved.rows(); ++v) {
    const bool member = v >= kFirstMember && v < kFirstMember + kMemberCount;
    const Eigen::RowVector3d expected = member ? Eigen::RowVector3d(0, kRaise, 0) : Eigen::RowVector3d::Zero();
    ASSERT_LT((moved.row(v) - expected).norm(), 1e-6) << "vertex " << v << (member ? " (member)" : "");
  }
  ASSERT_EQ(posed.parts.size(), 1u);
  EXPECT_LT((posed.parts[0].mesh.positions - rest.parts[0].mesh.positions).norm(), 1e-6);  // components move no part
}

TEST(CliPose, MorphWeightMovesWhereTheShapeMovesWithoutComponents) {
  const auto dir = makeTempDir("cli_pose_morph");
  const core::Rig rest = writeInputs(dir);
  const CliRun run = runPose(dir, R"({"morph_weights": {"jawOpen": 1}})", false);
  ASSERT_EQ(run.exit_code, 0) << run.log;
  EXPECT_GLTF_VALID(dir / "posed.glb");
  const core::Rig posed = readPosed(dir / "posed.glb");
  ASSERT_EQ(posed.mesh.vertexCount(), rest.mesh.vertexCount());
  const auto jaw = std::find_if(rest.morph_targets.begin(), rest.morph_targets.end(),
                                [](const core::MorphTarget& t) { return t.name == "jawOpen"; });
  ASSERT_NE(jaw, rest.morph_targets.end());
  const Eigen::MatrixX3d moved = posed.mesh.positions - rest.mesh.positions;
  int shape_vertices = 0;
  for (Eigen::Index v = 0; v < moved.rows(); ++v) {
    const Eigen::RowVector3d delta = jaw->position_deltas.row(v);
    if (delta.isZero(0.0)) {
      ASSERT_LT(moved.row(v).norm(), 1e-6) << "vertex " << v << " is not in jawOpen";
    } else if (delta.norm() > 1e-4) {
      ++shape_vertices;
      ASSERT_LT((moved.row(v) - delta).norm(), 1e-5) << "vertex " << v;
    }
  }
  EXPECT_GT(shape_vertices, 0);
  // The part's own jawOpen target takes the same weight.
  ASSERT_EQ(posed.parts.size(), 1u);
  Eigen::MatrixX3d tooth = rest.parts[0].mesh.positions;
  tooth(3, 1) -= 0.005;
  EXPECT_LT((posed.parts[0].mesh.positions - tooth).norm(), 1e-6);
}

TEST(CliPose, UnknownNamesAndPresetsWithoutComponentsAreClearErrors) {
  const auto dir = makeTempDir("cli_pose_bad");
  writeInputs(dir);

  const CliRun preset = runPose(dir, R"({"preset": "chin_riased"})");
  EXPECT_EQ(preset.exit_code, 1) << preset.log;
  EXPECT_NE(preset.log.find("pose.json: preset: unknown preset \"chin_riased\" in components.json"), std::string::npos)
      << preset.log;
  EXPECT_NE(preset.log.find("did you mean \"chin_raised\""), std::string::npos) << preset.log;
  EXPECT_FALSE(std::filesystem::exists(dir / "posed.glb"));

  const CliRun target = runPose(dir, R"({"morph_weights": {"jawOpne": 1}})");
  EXPECT_EQ(target.exit_code, 1) << target.log;
  EXPECT_NE(target.log.find("pose.json: morph_weights.jawOpne"), std::string::npos) << target.log;
  EXPECT_NE(target.log.find("did you mean \"jawOpen\""), std::string::npos) << target.log;

  const CliRun key = runPose(dir, R"({"joint": {"jaw": [10, 0, 0]}})");
  EXPECT_EQ(key.exit_code, 1) << key.log;
  EXPECT_NE(key.log.find("pose.json: joint: unknown key (did you mean \"joints\"?)"), std::string::npos) << key.log;

  const CliRun no_components = runPose(dir, R"({"preset": "chin_raised"})", false);
  EXPECT_EQ(no_components.exit_code, 1) << no_components.log;
  EXPECT_NE(no_components.log.find("pose.json: preset:"), std::string::npos) << no_components.log;
  EXPECT_NE(no_components.log.find("--components"), std::string::npos) << no_components.log;
  EXPECT_FALSE(std::filesystem::exists(dir / "posed.glb"));
}

// `rigport bake`: the preset becomes a morph target of the face (valid
// glTF, recorded as a baked preset) whose delta is the preset's raise on
// its members only; baking again replaces it; an unknown preset is an error
// naming the file and the preset, and writes nothing.
TEST(CliBake, PresetsBecomeMorphTargetsOfTheFace) {
  const auto dir = makeTempDir("cli_bake");
  const core::Rig rig = writeInputs(dir);
  const std::string inputs = "bake --rig " + quoted(dir / "rig.glb") + " --components " + quoted(dir / "components.json");
  const CliRun run = runRigportCli(inputs + " -o " + quoted(dir / "baked.glb"));
  ASSERT_EQ(run.exit_code, 0) << run.log;
  EXPECT_NE(run.log.find("baked 1 preset as morph targets"), std::string::npos) << run.log;
  EXPECT_GLTF_VALID(dir / "baked.glb");
  auto baked = core::readRig(dir / "baked.glb");
  ASSERT_TRUE(baked) << baked.error().message;
  ASSERT_EQ(baked->rig.morph_targets.size(), rig.morph_targets.size() + 1);
  const core::MorphTarget& preset = baked->rig.morph_targets.back();
  EXPECT_EQ(preset.name, "chin_raised");
  EXPECT_EQ(baked->rig.baked_presets, std::vector<std::string>{"chin_raised"});
  for (Eigen::Index v = 0; v < preset.position_deltas.rows(); ++v) {
    const bool member = v >= kFirstMember && v < kFirstMember + kMemberCount;
    EXPECT_NEAR(preset.position_deltas(v, 1), member ? kRaise : 0.0, 1e-6) << "vertex " << v;
  }
  EXPECT_EQ(baked->rig.parts.size(), rig.parts.size()) << "the rig's other meshes are kept";

  // Baked again (from the baked rig): replaced, not added.
  const CliRun again = runRigportCli("bake --rig " + quoted(dir / "baked.glb") + " --components " +
                                     quoted(dir / "components.json") + " --presets chin_raised -o " +
                                     quoted(dir / "again.glb"));
  ASSERT_EQ(again.exit_code, 0) << again.log;
  auto twice = core::readRig(dir / "again.glb");
  ASSERT_TRUE(twice) << twice.error().message;
  EXPECT_EQ(twice->rig.morph_targets.size(), baked->rig.morph_targets.size());

  const CliRun unknown = runRigportCli(inputs + " --presets chin_riased -o " + quoted(dir / "bad.glb"));
  EXPECT_EQ(unknown.exit_code, 1) << unknown.log;
  EXPECT_NE(unknown.log.find("components.json"), std::string::npos) << unknown.log;
  EXPECT_NE(unknown.log.find("did you mean \"chin_raised\""), std::string::npos) << unknown.log;
  EXPECT_FALSE(std::filesystem::exists(dir / "bad.glb"));
}

}  // namespace
}  // namespace rigport_test
