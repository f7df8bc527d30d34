// Tests core/jobs/transfer_options.cpp: a mistyped key named with the key
// meant, and the warp's switches read from the options JSON.
#include "core/jobs/transfer_options.h"

#include <string>

#include <gtest/gtest.h>

namespace {

// A warp switch in the options JSON: on by default, off with false, and a
// value of another type is an error that names the key.
void expectWarpSwitch(const std::string& key, bool core::WarpOptions::*member, const std::string& bad_value) {
  auto defaults = core::parseTransferOptions("{}", "opts.json");
  ASSERT_TRUE(defaults) << defaults.error().message;
  EXPECT_TRUE(defaults->transfer.warp.*member) << key;
  auto off = core::parseTransferOptions("{\"" + key + "\": false}", "opts.json");
  ASSERT_TRUE(off) << off.error().message;
  EXPECT_FALSE(off->transfer.warp.*member) << key;
  auto bad = core::parseTransferOptions("{\"" + key + "\": " + bad_value + "}", "opts.json");
  ASSERT_FALSE(bad) << key;
  EXPECT_NE(bad.error().message.find(key), std::string::npos) << bad.error().message;
}

TEST(TransferOptions, AMistypedKeyIsNamedWithTheKeyMeant) {
  auto typo = core::parseTransferOptions(R"({"max_infuences": 4})", "opts.json");
  ASSERT_FALSE(typo);
  EXPECT_EQ(typo.error().message, "opts.json: 'max_infuences' is not a known option (did you mean 'max_influences'?)");
  auto switched = core::parseTransferOptions(R"({"strcit": true})", "opts.json");
  ASSERT_FALSE(switched);
  EXPECT_EQ(switched.error().message, "opts.json: 'strcit' is not a known option (did you mean 'strict'?)");
  auto unknown = core::parseTransferOptions(R"({"colour": 1})", "opts.json");
  ASSERT_FALSE(unknown);
  EXPECT_EQ(unknown.error().message, "opts.json: 'colour' is not a known option");
}

TEST(TransferOptions, SlidingCentresCanBeSwitchedOff) {
  expectWarpSwitch("slide_centres", &core::WarpOptions::slide_centres, "1");
}

TEST(TransferOptions, RimMatchingCanBeSwitchedOff) {
  expectWarpSwitch("rim_matching", &core::WarpOptions::rim_matching, "\"no\"");
}

TEST(TransferOptions, TargetPullsAndTheSmoothedGuideCanBeSwitchedOff) {
  expectWarpSwitch("target_pulls", &core::WarpOptions::target_pulls, "0");
  expectWarpSwitch("smooth_guide", &core::WarpOptions::smooth_guide, "null");
}

TEST(TransferOptions, RimLocationCanBeSwitchedOff) {
  expectWarpSwitch("rim_location", &core::WarpOptions::rim_location, "\"off\"");
}

}  // namespace

namespace {

TEST(TransferOptions, TheCorrespondenceIsTheWarpOrTheFit) {
  auto defaults = core::parseTransferOptions("{}", "opts.json");
  ASSERT_TRUE(defaults) << defaults.error().message;
  EXPECT_EQ(defaults->correspondence, core::CorrespondenceMethod::kWarp);
  auto fit = core::parseTransferOptions(R"({"correspondence": "fit"})", "opts.json");
  ASSERT_TRUE(fit) << fit.error().message;
  EXPECT_EQ(fit->correspondence, core::CorrespondenceMethod::kFit);
  // Normalised, it reads back as it was given.
  auto again = core::parseTransferOptions(core::transferOptionsJson(*fit), "normalised");
  ASSERT_TRUE(again) << again.error().message;
  EXPECT_EQ(again->correspondence, core::CorrespondenceMethod::kFit);
  for (const char* bad : {R"({"correspondence": "icp"})", R"({"correspondence": 1})"}) {
    auto refused = core::parseTransferOptions(bad, "opts.json");
    ASSERT_FALSE(refused) << bad;
    EXPECT_EQ(refused.error().message, "opts.json: 'correspondence' must be \"warp\" or \"fit\"");
  }
}

}  // namespace

namespace {

// "bake_presets": false by default, true (all), or names; anything else names the key.
TEST(TransferOptions, BakePresetsIsAFlagOrNames) {
  auto defaults = core::parseTransferOptions("{}", "opts.json");
  ASSERT_TRUE(defaults) << defaults.error().message;
  EXPECT_FALSE(defaults->bake.enabled);
  auto all = core::parseTransferOptions(R"({"bake_presets": true})", "opts.json");
  ASSERT_TRUE(all) << all.error().message;
  EXPECT_TRUE(all->bake.enabled);
  EXPECT_TRUE(all->bake.presets.empty());
  auto named = core::parseTransferOptions(R"({"bake_presets": ["joy", "anger"]})", "opts.json");
  ASSERT_TRUE(named) << named.error().message;
  EXPECT_EQ(named->bake.presets, (std::vector<std::string>{"joy", "anger"}));
  // Read back as written.
  auto again = core::parseTransferOptions(core::transferOptionsJson(*named), "normalised");
  ASSERT_TRUE(again) << again.error().message;
  EXPECT_EQ(again->bake.presets, named->bake.presets);
  for (const char* bad : {R"({"bake_presets": "joy"})", R"({"bake_presets": []})", R"({"bake_presets": [1]})"}) {
    auto refused = core::parseTransferOptions(bad, "opts.json");
    ASSERT_FALSE(refused) << bad;
    EXPECT_NE(refused.error().message.find("opts.json: 'bake_presets'"), std::string::npos) << refused.error().message;
  }
}

}  // namespace
