// Tests core/jobs/fit_options.cpp: unknown keys named with the key meant,
// schedule values out of range named by stage and field, every option read
// back by fitOptionsJson as parseFitOptions reads it, and the components
// switches reaching the rebuild's options.
#include "core/jobs/fit_options.h"

#include <string>
#include <vector>

#include <gtest/gtest.h>

namespace {

core::FitSettings parsed(const std::string& json) {
  auto settings = core::parseFitOptions(json, "fit.json");
  EXPECT_TRUE(settings) << json << ": " << settings.error().message;
  return settings ? *settings : core::FitSettings{};
}

void expectRefused(const std::string& json, const std::string& message_part) {
  auto settings = core::parseFitOptions(json, "fit.json");
  ASSERT_FALSE(settings) << json << " was accepted";
  EXPECT_EQ(settings.error().code, core::ErrorCode::kInvalidArgument) << json;
  EXPECT_EQ(settings.error().message.rfind("fit.json: ", 0), 0u) << settings.error().message;
  EXPECT_NE(settings.error().message.find(message_part), std::string::npos)
      << json << ": " << settings.error().message << " (expected to contain: " << message_part << ")";
}

TEST(FitOptions, AnUnknownKeyIsNamedWithTheKeyMeant) {
  auto typo = core::parseFitOptions(R"({"binding_wieght": 5})", "fit.json");
  ASSERT_FALSE(typo);
  EXPECT_EQ(typo.error().message, "fit.json: 'binding_wieght' is not a known option (did you mean 'binding_weight'?)");
  auto schedule = core::parseFitOptions(R"({"schedul": []})", "fit.json");
  ASSERT_FALSE(schedule);
  EXPECT_EQ(schedule.error().message, "fit.json: 'schedul' is not a known option (did you mean 'schedule'?)");
  auto unknown = core::parseFitOptions(R"({"colour": 1})", "fit.json");
  ASSERT_FALSE(unknown);
  EXPECT_EQ(unknown.error().message, "fit.json: 'colour' is not a known option");
}

TEST(FitOptions, EmptyObjectGivesTheDefaults) {
  const core::FitSettings s = parsed("{}");
  const core::FitOptions defaults;
  EXPECT_EQ(s.fit.alignment, defaults.alignment);
  EXPECT_EQ(s.fit.units, "auto");
  ASSERT_EQ(s.fit.schedule.size(), defaults.schedule.size());
  for (std::size_t i = 0; i < defaults.schedule.size(); ++i) {
    EXPECT_EQ(s.fit.schedule[i].stiffness, defaults.schedule[i].stiffness) << i;
    EXPECT_EQ(s.fit.schedule[i].iterations, defaults.schedule[i].iterations) << i;
  }
  EXPECT_EQ(s.fit.binding_weight, defaults.binding_weight);
  EXPECT_EQ(s.fit.rebuild.weight_options.max_influences, s.write.max_influences);
}

TEST(FitOptions, ScheduleValuesOutOfRangeAreNamedByStageAndField) {
  const std::string ok = R"("iterations": 3)";
  const auto with = [&](const std::string& stage1) { return R"({"schedule": [{)" + ok + "}, {" + stage1 + "}]}"; };
  expectRefused(with(R"("stiffness": 0)"), "'schedule'[1].stiffness must be a number in");
  expectRefused(with(R"("stiffness": -5)"), "'schedule'[1].stiffness");
  expectRefused(with(R"("iterations": 0)"), "'schedule'[1].iterations must be a number in");
  expectRefused(with(R"("iterations": 51)"), "'schedule'[1].iterations");
  expectRefused(with(R"("max_distance": 0)"), "'schedule'[1].max_distance");
  expectRefused(with(R"("max_distance": 1.5)"), "'schedule'[1].max_distance");
  expectRefused(with(R"("max_normal_angle_deg": 0.5)"), "'schedule'[1].max_normal_angle_deg");
  expectRefused(with(R"("max_normal_angle_deg": 181)"), "'schedule'[1].max_normal_angle_deg");
  expectRefused(with(R"("landmark_weight": -1)"), "'schedule'[1].landmark_weight");
  expectRefused(with(R"("point_share": 1.5)"), "'schedule'[1].point_share");
  expectRefused(with(R"("point_share": "half")"), "'schedule'[1].point_share");
  expectRefused(with(R"("stifness": 3)"), "'schedule'[1].stifness is not a stage setting");
  expectRefused(R"({"schedule": []})", "must be an array of 1 to 20 stages");
  expectRefused(R"({"schedule": {"stiffness": 3}})", "must be an array of 1 to 20 stages");
  std::string many = R"({"schedule": [)";
  for (int i = 0; i < 21; ++i) many += std::string(i ? "," : "") + "{}";
  expectRefused(many + "]}", "must be an array of 1 to 20 stages");
  expectRefused(R"({"schedule": [3]})", "'schedule'[0] must be an object");
  // The bounds themselves are accepted.
  const core::FitSettings edge = parsed(
      R"({"schedule": [{"stiffness": 0.001, "iterations": 50, "max_distance": 1, "max_normal_angle_deg": 180,
                         "landmark_weight": 0, "point_share": 0}]})");
  ASSERT_EQ(edge.fit.schedule.size(), 1u);
  EXPECT_EQ(edge.fit.schedule[0].iterations, 50);
  EXPECT_EQ(edge.fit.schedule[0].max_normal_angle_deg, 180.0);
}

TEST(FitOptions, OtherValuesOutOfRangeAreRefused) {
  expectRefused(R"({"binding_weight": -1})", "'binding_weight' must be a number in");
  expectRefused(R"({"rim_stiffness": 0.5})", "'rim_stiffness' must be a number in");
  expectRefused(R"({"normal_matching": 2})", "'normal_matching' must be a number in");
  expectRefused(R"({"max_yaw_deg": 200})", "'max_yaw_deg'");
  expectRefused(R"({"max_influences": 9})", "'max_influences'");
  expectRefused(R"({"units": "furlong"})", "'units' must be");
  expectRefused(R"({"alignment": "manual"})", "'alignment' must be one of");
  expectRefused(R"({"frame": "world"})", "'frame' must be one of");
  expectRefused(R"({"adaptation": "stretch"})", "'adaptation' must be one of");
  expectRefused(R"({"strict": "yes"})", "'strict' must be true or false");
  expectRefused("[]", "expected a JSON object");
}

// Every option set away from its default survives fitOptionsJson and back.
TEST(FitOptions, JsonRoundTripGivesTheSameSettings) {
  const std::string text = R"({
    "alignment": "search", "units": "in", "frame": "reference", "adaptation": "similarity",
    "weight_encoding": "unorm16", "max_influences": 6, "max_yaw_deg": 40.5, "max_tilt_deg": 12.25,
    "schedule": [{"stiffness": 50, "iterations": 2, "max_distance": 0.04, "max_normal_angle_deg": 80,
                  "landmark_weight": 120, "point_share": 0.75},
                 {"stiffness": 0.2, "iterations": 7, "max_distance": 0.005, "max_normal_angle_deg": 30,
                  "landmark_weight": 0.5, "point_share": 0}],
    "binding_weight": 2.5, "rim_stiffness": 4, "normal_matching": 0.07, "reject_borders": false, "reject_spikes": false,
    "diagnostic_attributes": true, "strict": true,
    "components": {"weights": false, "joints": true, "shapes": false, "animations": true, "attributes": false}})";
  const core::FitSettings first = parsed(text);
  const std::string json = core::fitOptionsJson(first);
  const core::FitSettings second = parsed(json);
  EXPECT_EQ(core::fitOptionsJson(second), json);

  for (const core::FitSettings* s : {&first, &second}) {
    const core::FitOptions& f = s->fit;
    EXPECT_EQ(f.alignment, core::FitAlignmentMode::kSearch);
    EXPECT_EQ(f.units, "in");
    EXPECT_EQ(f.frame, core::FitFrame::kReference);
    EXPECT_EQ(f.rebuild.adaptation, core::ShapeAdaptation::kSimilarity);
    EXPECT_EQ(s->write.weight_encoding, core::WeightEncoding::kUnorm16);
    EXPECT_EQ(s->write.max_influences, 6);
    EXPECT_EQ(f.rebuild.weight_options.max_influences, 6);
    EXPECT_EQ(f.search.max_yaw_deg, 40.5);
    EXPECT_EQ(f.normal_matching, 0.07);
    EXPECT_EQ(f.search.max_tilt_deg, 12.25);
    ASSERT_EQ(f.schedule.size(), 2u);
    EXPECT_EQ(f.schedule[0].stiffness, 50.0);
    EXPECT_EQ(f.schedule[0].iterations, 2);
    EXPECT_EQ(f.schedule[0].max_distance, 0.04);
    EXPECT_EQ(f.schedule[0].max_normal_angle_deg, 80.0);
    EXPECT_EQ(f.schedule[0].landmark_weight, 120.0);
    EXPECT_EQ(f.schedule[0].point_share, 0.75);
    EXPECT_EQ(f.schedule[1].stiffness, 0.2);
    EXPECT_EQ(f.schedule[1].iterations, 7);
    EXPECT_EQ(f.schedule[1].max_distance, 0.005);
    EXPECT_EQ(f.schedule[1].point_share, 0.0);
    EXPECT_EQ(f.binding_weight, 2.5);
    EXPECT_EQ(f.rim_stiffness, 4.0);
    EXPECT_FALSE(f.reject_borders);
    EXPECT_FALSE(f.reject_spikes);
    EXPECT_TRUE(f.diagnostic_attributes);
    EXPECT_TRUE(f.strict);
    EXPECT_FALSE(f.rebuild.weights);
    EXPECT_TRUE(f.rebuild.joints);
    EXPECT_FALSE(f.rebuild.shapes);
    EXPECT_TRUE(f.rebuild.animations);
    EXPECT_FALSE(f.rebuild.attributes);
  }
  // The defaults too.
  const std::string defaults = core::fitOptionsJson(core::FitSettings{});
  EXPECT_EQ(core::fitOptionsJson(parsed(defaults)), defaults);
}

// Each component switch reaches FitOptions::rebuild, alone.
TEST(FitOptions, ComponentsSwitchesReachTheRebuild) {
  const std::vector<std::pair<std::string, bool core::TransferOptions::*>> components = {
      {"weights", &core::TransferOptions::weights},
      {"joints", &core::TransferOptions::joints},
      {"shapes", &core::TransferOptions::shapes},
      {"animations", &core::TransferOptions::animations},
      {"attributes", &core::TransferOptions::attributes}};
  for (const auto& [name, member] : components) {
    const core::FitSettings s = parsed(R"({"components": {")" + name + R"(": false}})");
    for (const auto& [other, other_member] : components) {
      EXPECT_EQ(s.fit.rebuild.*other_member, other != name) << name << " off: " << other;
    }
  }
  expectRefused(R"({"components": {"uvs": false}})", "unknown component 'uvs'");
  expectRefused(R"({"components": {"shapes": 0}})", "shapes must be true or false");
  expectRefused(R"({"components": ["shapes"]})", "'components' must be an object");
}

}  // namespace
