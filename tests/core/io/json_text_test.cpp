// Untrusted JSON (core/io/json_text.h): nesting that would crash a recursive
// copy or conversion, and numbers out of range, are errors naming the file
// for every reader of JSON in core, not an abort.
#include "core/io/json_text.h"

#include <string>

#include <gtest/gtest.h>

#include "core/io/mesh_io.h"
#include "core/jobs/retarget_options.h"
#include "core/io/rig_io.h"
#include "core/jobs/transfer_options.h"
#include "tests/gltf_builder.h"

namespace {

TEST(JsonText, NestingIsCappedAndHugeNumbersAreErrors) {
  EXPECT_TRUE(core::parseJsonText(std::string(64, '[') + std::string(64, ']'), "ok.json"));
  auto deep = core::parseJsonText(std::string(65, '[') + std::string(65, ']'), "deep.json");
  ASSERT_FALSE(deep);
  EXPECT_EQ(deep.error().code, core::ErrorCode::kParse);
  EXPECT_EQ(deep.error().message, "deep.json: JSON nested deeper than 64 levels");
  auto huge = core::parseJsonText("[1e400]", "huge.json");
  ASSERT_FALSE(huge);
  EXPECT_EQ(huge.error().message.rfind("huge.json: not valid JSON (", 0), 0u) << huge.error().message;
  EXPECT_FALSE(core::parseJsonText("{not json", "bad.json"));
}

// The same rule for every JSON core reads: transfer and retarget options,
// stiffness.
TEST(JsonText, EveryReaderRefusesDeepNestingAndHugeNumbers) {
  const std::string deep = "{\"a\":" + std::string(20000, '[') + std::string(20000, ']') + "}";
  for (const std::string& text : {deep, std::string(R"({"exaggeration": 1e400})")}) {
    auto transfer = core::parseTransferOptions(text, "opts.json");
    ASSERT_FALSE(transfer);
    EXPECT_EQ(transfer.error().code, core::ErrorCode::kParse);
    EXPECT_EQ(transfer.error().message.rfind("opts.json: ", 0), 0u) << transfer.error().message;
    auto retarget = core::parseRetargetOptions(text, "spec.options");
    ASSERT_FALSE(retarget);
    EXPECT_EQ(retarget.error().message.rfind("spec.options: ", 0), 0u) << retarget.error().message;
    auto stiffness = core::parseStiffness(text, "stiffness.json");
    ASSERT_FALSE(stiffness);
    EXPECT_EQ(stiffness.error().message.rfind("stiffness.json: ", 0), 0u) << stiffness.error().message;
  }
}

// A glTF whose JSON nests 20,000 deep: tinygltf never sees it.
TEST(JsonText, AGltfNestedTooDeepIsRefusedBeforeTinygltf) {
  const std::string text = R"({"asset":{"version":"2.0"},"extras":)" + std::string(20000, '[') + std::string(20000, ']') + "}";
  const auto glb = rigport_test::gltf::makeGlbFromText(text, {});
  auto mesh = core::readGltf(glb, "deep.glb", /*binary=*/true);
  ASSERT_FALSE(mesh);
  EXPECT_EQ(mesh.error().code, core::ErrorCode::kParse);
  EXPECT_EQ(mesh.error().message, "deep.glb: glTF JSON nested deeper than 64 levels");
  auto rig = core::readRigGltf(rigport_test::gltf::toBytes(text), "deep.gltf", /*binary=*/false);
  ASSERT_FALSE(rig);
  EXPECT_EQ(rig.error().message, "deep.gltf: glTF JSON nested deeper than 64 levels");
}

}  // namespace
