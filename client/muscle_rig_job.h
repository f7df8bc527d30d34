// `rigport muscle-rig`: the reference muscle rig (core/muscle_rig) built on a
// face with the 68 iBUG landmarks; writes the rig GLB with every preset baked
// as a morph target (core/components/bake.h) and the components JSON.
#pragma once

#include <filesystem>

namespace client {

struct MuscleRigArgs {
  std::filesystem::path mesh;        // the face (GLB/glTF; a skeleton it has is kept)
  std::filesystem::path landmarks;   // landmarks JSON with the 68 iBUG names
  std::filesystem::path output;      // rig GLB: the face, its own shapes and the baked presets
  std::filesystem::path components;  // rigport.components JSON of the rig
  double wire_dropoff = 1.0;         // core::MuscleRigOptions::wire_dropoff
  double expression_gain = 1.0;      // core::MuscleRigOptions::expression_gain
};

// Returns the process exit code (0 ok, 1 failed).
int runMuscleRig(const MuscleRigArgs& args);

}  // namespace client
