// Controls and expression presets of the reference muscle rig (paper 001,
// chapter 6): one descriptive control per muscle parameter (Table 6.2; the
// paper's "Orbicularis Oris Inner/Outer" rows are the orbicularis oculi
// portions, the muscles this rig has), ranging 0..1 over the muscle's
// contraction range, and the expression library (section 6.2.3: fifteen
// expressions as collections of control values; the six universal ones
// first).
#include <utility>

#include "core/muscle_rig/muscle_rig_parts.h"

namespace core::muscle_rig_detail {

namespace {

// Descriptive name (Table 6.2) -> muscle, for the sided muscles.
const std::vector<std::pair<std::string, std::string>>& sidedControls() {
  static const std::vector<std::pair<std::string, std::string>> table = {
      {"lift_inner_brow", "frontalis_inner"},
      {"lift_outer_brow", "frontalis_outer"},
      {"squeeze_brow", "corrugator"},
      {"sneer_intensity", "orbicularis_oculi_inner"},
      {"squint", "orbicularis_oculi_outer"},
      {"sneer", "levator_labii_nasal"},
      {"sneer_width", "levator_labii_mid"},
      {"smile_wide", "zygomatic_major"},
      {"stretch_lower_lip", "risorius"},
      {"mouth_narrow", "orbicularis_oris_incisivis"},
      {"lower_mouth_corner", "triangularis"},
      {"lower_lip_down", "depressor_labii"},
  };
  return table;
}

Control muscleControl(const std::string& name, const std::string& muscle, double max_contraction) {
  Control c{name, 0.0, 1.0, 0.0, {}};
  c.drives.push_back({DriveTargetKind::kMuscle, muscle, ClusterChannel::kTranslateX, JointChannel::kRotateX, max_contraction});
  return c;
}

// Both sides of a sided control at one value.
void both(std::map<std::string, double>& controls, const std::string& name, double value) {
  controls[name + "_L"] = value;
  controls[name + "_R"] = value;
}

}  // namespace

void addExpressionControls(ComponentsDocument& doc) {
  auto max_of = [&](const std::string& muscle) { return doc.muscles[static_cast<std::size_t>(indexByName(doc.muscles, muscle))].max_contraction; };
  for (const auto& [name, muscle] : sidedControls()) {
    for (const int s : {+1, -1}) {
      const std::string m = muscle + sideSuffix(s);
      doc.controls.push_back(muscleControl(name + sideSuffix(s), m, max_of(m)));
    }
  }
  doc.controls.push_back(muscleControl("lower_brows", "procerus", max_of("procerus")));
  doc.controls.push_back(muscleControl("lower_lip_up", "mentalis", max_of("mentalis")));
}

void addExpressionPresets(ComponentsDocument& doc) {
  auto preset = [&](const std::string& name, const std::map<std::string, double>& sided,
                    const std::map<std::string, double>& single) {
    Preset p;
    for (const auto& [control, value] : sided) both(p.controls, control, value);
    for (const auto& [control, value] : single) {
      if (indexByName(doc.controls, control) >= 0) p.controls[control] = value;
    }
    doc.presets[name] = p;
  };
  // The six universal expressions (Ekman), by their usual action units.
  preset("joy", {{"smile_wide", 1.0}, {"squint", 0.6}, {"sneer_width", 0.15}, {"stretch_lower_lip", 0.2}}, {{"jaw_open", 0.08}});
  preset("sadness", {{"lift_inner_brow", 0.9}, {"squeeze_brow", 0.5}, {"lower_mouth_corner", 0.9}, {"sneer_intensity", 0.2}},
         {{"lower_lip_up", 0.5}});
  preset("anger", {{"squeeze_brow", 1.0}, {"squint", 0.5}, {"sneer", 0.3}, {"mouth_narrow", 0.4}},
         {{"lower_brows", 0.5}, {"lower_lip_up", 0.5}});
  preset("fear", {{"lift_inner_brow", 1.0}, {"lift_outer_brow", 0.5}, {"squeeze_brow", 0.5}, {"stretch_lower_lip", 0.9},
                  {"lower_lip_down", 0.3}},
         {{"jaw_open", 0.25}});
  preset("surprise", {{"lift_inner_brow", 1.0}, {"lift_outer_brow", 1.0}}, {{"jaw_open", 0.6}});
  preset("disgust", {{"sneer", 1.0}, {"sneer_intensity", 0.6}, {"sneer_width", 0.4}, {"squint", 0.3}},
         {{"lower_brows", 0.5}, {"lower_lip_up", 0.6}});
  // More of the library: single actions and asymmetric ones.
  preset("smile_closed", {{"smile_wide", 0.7}, {"squint", 0.3}}, {});
  preset("smile_left", {}, {{"smile_wide_L", 1.0}, {"squint_L", 0.4}});
  preset("smile_right", {}, {{"smile_wide_R", 1.0}, {"squint_R", 0.4}});
  preset("brows_up", {{"lift_inner_brow", 1.0}, {"lift_outer_brow", 1.0}}, {});
  preset("frown", {{"squeeze_brow", 1.0}, {"lower_mouth_corner", 0.6}}, {{"lower_brows", 0.4}});
  preset("sneer_left", {}, {{"sneer_L", 1.0}, {"sneer_width_L", 0.5}, {"sneer_intensity_L", 0.4}});
  preset("pucker", {{"mouth_narrow", 1.0}}, {{"lower_lip_up", 0.4}});
  preset("mouth_stretch", {{"stretch_lower_lip", 1.0}, {"lower_lip_down", 0.6}}, {{"jaw_open", 0.15}});
  preset("blink", {}, {{"blink_L", 1.0}, {"blink_R", 1.0}});
}

}  // namespace core::muscle_rig_detail
