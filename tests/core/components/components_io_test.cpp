#include "core/io/components_io.h"

#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>

#include "tests/core/components/components_fixture.h"

namespace {

using components_test::fullDocument;

constexpr const char* kSmall = R"({
  "format": "rigport.components", "version": 1,
  "locators": [{"name": "mouth", "binding": {"vertex": 3}}],
  "clusters": [{"name": "lip", "pivot": {"face": 0, "barycentric": [0.2, 0.3, 0.5]},
                "members": [{"vertex": 1, "weight": 0.5}], "rotate_euler_deg": [0, 0, 90]}],
  "curves": [{"name": "base", "degree": 1, "knots": [0, 0, 1, 1], "points": [{"vertex": 0}, {"vertex": 1}]},
             {"name": "wire", "degree": 1, "knots": [0, 0, 1, 1], "points": [{"vertex": 0}, {"position": [1, 0, 0.1]}],
              "drivers": [{"point": 0, "cluster": "lip"}]}],
  "wires": [{"name": "upper_lip", "base_curve": "base", "curve": "wire", "dropoff_distance": 0.5}],
  "muscles": [{"name": "zyg", "origin": {"vertex": 0}, "insertion": {"vertex": 2}, "range": [0, 0.4],
               "drives": [{"cluster": "lip"}]}],
  "controls": [{"name": "mouth_smile", "range": [0, 1], "drives": [{"muscle": "zyg", "gain": 0.4},
                {"cluster": "lip", "channel": "translate_y", "gain": 0.01}, {"morph": "smile"},
                {"joint": "jaw", "channel": "rotate_x", "gain": 20}]}],
  "presets": {"smile": {"controls": {"mouth_smile": 1.0}}}
})";

// Parses `text` and expects an error starting with the file's name and containing `fragment`.
void expectError(const std::string& text, const std::string& fragment) {
  auto r = core::parseComponents(text, "components.json");
  ASSERT_FALSE(r) << "no error for: " << fragment;
  EXPECT_NE(r.error().message.find(fragment), std::string::npos) << r.error().message;
  EXPECT_EQ(r.error().message.rfind("components.json: ", 0), 0u) << r.error().message;
}

std::string replaced(std::string text, const std::string& from, const std::string& to) {
  const auto at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  return text.replace(at, from.size(), to);
}

TEST(ComponentsIo, ReadsTheSmallExample) {
  auto r = core::parseComponents(kSmall, "components.json");
  ASSERT_TRUE(r) << r.error().message;
  ASSERT_EQ(r->clusters.size(), 1u);
  EXPECT_EQ(r->clusters[0].pivot.kind, core::BindingKind::kFace);
  EXPECT_LT((r->clusters[0].rotate * Eigen::Vector3d::UnitX() - Eigen::Vector3d::UnitY()).norm(), 1e-12);
  EXPECT_EQ(r->curves[1].drivers[0].kind, core::TargetKind::kCluster);
  EXPECT_EQ(r->wires[0].rotation, 1.0);  // defaults
  EXPECT_EQ(r->wires[0].envelope, 1.0);
  EXPECT_EQ(r->controls[0].drives[1].cluster_channel, core::ClusterChannel::kTranslateY);
  EXPECT_EQ(r->controls[0].drives[2].gain, 1.0);
  EXPECT_EQ(r->presets.at("smile").controls.at("mouth_smile"), 1.0);
  EXPECT_TRUE(core::validate(*r, 4));
  auto small_mesh = core::validate(*r, 3);
  ASSERT_FALSE(small_mesh);
  EXPECT_NE(small_mesh.error().message.find("locators[0] \"mouth\": binding.vertex 3 is out of range (mesh has 3 vertices)"),
            std::string::npos)
      << small_mesh.error().message;
}

TEST(ComponentsIo, WriteThenReadGivesTheSameDocument) {
  const core::ComponentsDocument doc = fullDocument();
  ASSERT_TRUE(core::validate(doc, 121)) << core::validate(doc, 121).error().message;
  const std::string text = core::formatComponents(doc);
  auto back = core::parseComponents(text, "components.json");
  ASSERT_TRUE(back) << back.error().message;
  EXPECT_TRUE(*back == doc);
  EXPECT_EQ(core::formatComponents(*back), text);
  // Every kind survives, not just an empty document.
  EXPECT_EQ(back->lattices[0].points.size(), 12u);
  EXPECT_EQ(back->aim_constraints[0].up_axis, Eigen::Vector3d::UnitZ());
  auto small = core::parseComponents(kSmall, "components.json");
  ASSERT_TRUE(small);
  auto small_back = core::parseComponents(core::formatComponents(*small), "components.json");
  ASSERT_TRUE(small_back) << small_back.error().message;
  EXPECT_TRUE(*small_back == *small);
}

TEST(ComponentsIo, ErrorsNameTheComponentAndField) {
  const std::string text = kSmall;
  expectError(replaced(text, "\"dropoff_distance\": 0.5", "\"dropoff_distance\": -1"),
              "wires[0] \"upper_lip\": dropoff_distance must be > 0");
  expectError(replaced(text, "{\"muscle\": \"zyg\"", "{\"muscle\": \"zgy\""),
              "controls[0] \"mouth_smile\": drives[0].muscle: unknown muscle \"zgy\" (did you mean \"zyg\"?)");
  expectError(replaced(text, "\"curve\": \"wire\"", "\"curve\": \"wir\""),
              "wires[0] \"upper_lip\": curve: unknown curve \"wir\" (did you mean \"wire\"?)");
  expectError(replaced(text, "\"dropoff_distance\"", "\"dropof_distance\""),
              "wires[0] \"upper_lip\": unknown key \"dropof_distance\" (did you mean \"dropoff_distance\"?)");
  expectError(replaced(text, "\"knots\": [0, 0, 1, 1], \"points\": [{\"vertex\": 0}, {\"vertex\": 1}]",
                       "\"knots\": [0, 1, 1], \"points\": [{\"vertex\": 0}, {\"vertex\": 1}]"),
              "curves[0] \"base\": knots must hold points + degree + 1 = 4 values, got 3");
  expectError(replaced(text, "\"range\": [0, 0.4]", "\"range\": [0, 1.5]"), "muscles[0] \"zyg\": range: max must be < 1");
  expectError(replaced(text, "\"mouth_smile\": 1.0", "\"mouth_smile\": 2.0"),
              "presets \"smile\": controls.\"mouth_smile\": 2 is outside the control's range [0, 1]");
  expectError(replaced(text, "\"channel\": \"translate_y\"", "\"channel\": \"translate_w\""),
              "controls[0] \"mouth_smile\": drives[1].channel: unknown value \"translate_w\"");
  expectError(replaced(text, "\"weight\": 0.5", "\"weight\": 1e400"), "not valid JSON");
  expectError(replaced(text, "\"barycentric\": [0.2, 0.3, 0.5]", "\"barycentric\": [0.2, 0.3, 0.6]"),
              "clusters[0] \"lip\": pivot.barycentric must be finite, non-negative and sum to 1");
  expectError(replaced(text, "\"rigport.components\"", "\"rigport.landmarks\""), "format: must be \"rigport.components\"");
  expectError(replaced(text, "\"presets\": {", "\"presets\": [{"), "not valid JSON");  // malformed
  expectError(replaced(text, "\"presets\": {\"smile\": {\"controls\": {\"mouth_smile\": 1.0}}}",
                       "\"presets\": [{\"smile\": {}}]"),
              "presets: must be an object keyed by preset name");
  auto version = core::parseComponents(replaced(text, "\"version\": 1", "\"version\": 2"), "components.json");
  ASSERT_FALSE(version);
  EXPECT_EQ(version.error().code, core::ErrorCode::kUnsupported);
}

// The eye rig's pieces: a control moving a locator, a joint aimed at it, a
// sculptor pushing along rays from a point.
constexpr const char* kEyeRig = R"({"format": "rigport.components", "version": 1,
  "locators": [{"name": "aim", "binding": {"position": [0, 1, 5]}}],
  "clusters": [{"name": "chin", "pivot": {"position": [0, 1, 0]}, "members": [{"vertex": 2}], "joint": "jaw"}],
  "aim_constraints": [{"name": "eye_aim", "constrained_joint": "eye", "targets": [{"locator": "aim"}]}],
  "push_to_surfaces": [{"name": "sculptor", "surface": {"sphere": {"center": {"position": [0, 1, 0]}, "radius": 0.5}},
                        "direction": {"from": {"position": [0, 1, -0.1]}}, "members": [2, 3]}],
  "controls": [{"name": "look_left", "drives": [{"locator": "aim", "channel": "translate_x", "gain": 5}]}]})";

TEST(ComponentsIo, EyeRigPiecesReadWriteAndNameTheirErrors) {
  auto doc = core::parseComponents(kEyeRig, "eyes.json");
  ASSERT_TRUE(doc) << doc.error().message;
  ASSERT_EQ(doc->aim_constraints.size(), 1u);
  EXPECT_TRUE(doc->aim_constraints[0].joint);
  EXPECT_EQ(doc->aim_constraints[0].constrained, "eye");
  EXPECT_EQ(doc->push_to_surfaces[0].direction, core::PushDirection::kFromPoint);
  EXPECT_EQ(doc->push_to_surfaces[0].from.position, Eigen::Vector3d(0, 1, -0.1));
  EXPECT_EQ(doc->controls[0].drives[0].kind, core::DriveTargetKind::kLocator);
  EXPECT_EQ(doc->clusters[0].joint, "jaw");
  auto back = core::parseComponents(core::formatComponents(*doc), "eyes.json");
  ASSERT_TRUE(back) << back.error().message;
  EXPECT_TRUE(*back == *doc);
  const std::string text = kEyeRig;
  expectError(replaced(text, "\"translate_x\"", "\"rotate_x\""),
              "controls[0] \"look_left\": drives[0].channel: a locator takes translate_x, translate_y or translate_z only");
  expectError(replaced(text, "{\"locator\": \"aim\", \"channel\"", "{\"locator\": \"aimm\", \"channel\""),
              "drives[0].locator: unknown locator \"aimm\" (did you mean \"aim\"?)");
  expectError(replaced(text, "\"constrained_joint\": \"eye\"", "\"constrained_joint\": \"eye\", \"constrained\": \"aim\""),
              "aim_constraints[0] \"eye_aim\": needs exactly one of \"constrained\" (a locator or cluster) or \"constrained_joint\"");
  expectError(replaced(text, "{\"from\": {\"position\": [0, 1, -0.1]}}", "{\"from\": {\"vertex\": -4}}"),
              "push_to_surfaces[0] \"sculptor\"");
  expectError(replaced(text, "\"joint\": \"jaw\"", "\"joint\": \"\""),
              "clusters[0] \"chin\": joint must be a non-empty name");
  expectError(replaced(text, "\"joint\": \"jaw\"}", "\"joint\": \"jaw\"}, {\"name\": \"chin2\", \"pivot\": {\"vertex\": 0}, "
                              "\"members\": [], \"joint\": \"jaw\"}"),
              "clusters[1] \"chin2\": joint: \"jaw\" is already carried by clusters[0] \"chin\"");
  expectError(replaced(text, "\"constrained_joint\": \"eye\"", "\"constrained_joint\": \"jaw\""),
              "aim_constraints[0] \"eye_aim\": constrained_joint: \"jaw\" is carried by clusters[0] \"chin\"");
}

TEST(ComponentsIo, ValidationCatchesCyclesNonFiniteValuesAndDuplicates) {
  core::ComponentsDocument doc = fullDocument();
  doc.point_constraints.push_back({"nose_follow", "nose", {{core::TargetKind::kLocator, "brow", -1, 1.0}}, true});
  auto cycle = core::validate(doc, 121);
  ASSERT_FALSE(cycle);
  EXPECT_NE(cycle.error().message.find("constraint cycle: "), std::string::npos) << cycle.error().message;
  EXPECT_NE(cycle.error().message.find("nose -> brow -> nose"), std::string::npos) << cycle.error().message;

  doc = fullDocument();
  doc.lattices[0].points[3].x() = std::nan("");
  auto nan = core::validate(doc, 121);
  ASSERT_FALSE(nan);
  EXPECT_NE(nan.error().message.find("lattices[0] \"jaw\": points[3] is not finite"), std::string::npos) << nan.error().message;

  doc = fullDocument();
  doc.clusters[0].members[2].weight = std::numeric_limits<double>::infinity();
  auto inf = core::validate(doc, 121);
  ASSERT_FALSE(inf);
  EXPECT_NE(inf.error().message.find("clusters[0] \"lip_c\": members[2].weight is not finite"), std::string::npos)
      << inf.error().message;

  doc = fullDocument();
  doc.muscles.push_back(doc.muscles[0]);
  auto duplicate = core::validate(doc, 121);
  ASSERT_FALSE(duplicate);
  EXPECT_NE(duplicate.error().message.find("muscles[1] \"zygomatic\": duplicate name"), std::string::npos)
      << duplicate.error().message;

  doc = fullDocument();
  doc.point_constraints[0].targets[1].vertex = 500;
  auto range = core::validate(doc, 121);
  ASSERT_FALSE(range);
  EXPECT_NE(range.error().message.find("point_constraints[0] \"lip_follow\": targets[1].vertex 500 is out of range (mesh has 121 vertices)"),
            std::string::npos)
      << range.error().message;

  doc = fullDocument();
  doc.wires[0].members = {3, 121};
  auto members = core::validate(doc, 121);
  ASSERT_FALSE(members);
  EXPECT_NE(members.error().message.find("wires[0] \"upper_lip\": members[1] 121 is out of range"), std::string::npos)
      << members.error().message;

  doc = fullDocument();
  doc.aim_constraints[0].up_axis = {2.0, 0.0, 0.0};
  auto parallel = core::validate(doc, 121);
  ASSERT_FALSE(parallel);
  EXPECT_NE(parallel.error().message.find("aim_constraints[0] \"aim_nose\": up_axis must not be parallel to aim_axis"),
            std::string::npos)
      << parallel.error().message;
}

}  // namespace

namespace {

// The example in docs/COMPONENTS.md reads as documented.
TEST(ComponentsIo, DocumentedExampleParses) {
  auto doc = core::readComponents(std::filesystem::path(RIGPORT_SOURCE_DIR) / "docs" / "COMPONENTS.md");
  ASSERT_FALSE(doc);  // the markdown itself is not JSON
  std::ifstream in(std::filesystem::path(RIGPORT_SOURCE_DIR) / "docs" / "COMPONENTS.md");
  const std::string markdown((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const auto begin = markdown.find("```json\n");
  ASSERT_NE(begin, std::string::npos);
  const auto end = markdown.find("```", begin + 8);
  auto example = core::parseComponents(markdown.substr(begin + 8, end - begin - 8), "COMPONENTS.md");
  ASSERT_TRUE(example) << example.error().message;
  EXPECT_EQ(example->wires.size(), 1u);
  EXPECT_TRUE(core::validate(*example, 121));
  EXPECT_EQ(example->presets.at("smile").controls.at("smile"), 1.0);
}

}  // namespace
