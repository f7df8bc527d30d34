// In-process job runners behind the CLI subcommands: read files, call core,
// write outputs. Each returns the process exit code (0 ok, 1 failed job).
#pragma once

#include <filesystem>
#include <string>
#include <vector>

namespace client {

struct WarpArgs {
  std::filesystem::path source, source_landmarks, target, target_landmarks;
  std::filesystem::path output;       // guide GLB (source topology on the target)
  std::filesystem::path diagnostics;  // JSON; empty = none
  int refine_iterations = 2;         // core::WarpOptions default
  int local_rounds = 2;               // core::WarpOptions default
  bool plain = false;                 // no refinement, local rounds or rims (the papers' pipeline)
  bool light = false;                 // one local round; no refinement, target pulls or smoothed guide
  double landmark_regularization = 0.0;
  int threads = 0;
  bool print_diagnostics = false;     // also print the diagnostics JSON on stdout
};
int runWarp(const WarpArgs& args);

struct TransferArgs {
  std::filesystem::path source, source_landmarks, target, target_landmarks;
  std::filesystem::path source_components;  // the rig's components JSON; empty = none
  std::filesystem::path output;       // rigged target GLB
  std::filesystem::path components_out;     // the target's components JSON (needs source_components)
  std::filesystem::path diagnostics;  // JSON; empty = none
  std::filesystem::path options;      // transfer options JSON; empty = defaults
  int threads = 0;
  bool print_diagnostics = false;
  bool strict = false;                // a transfer that fails its quality check fails (options "strict": true)
};
int runTransfer(const TransferArgs& args);

struct FitArgs {
  std::filesystem::path reference, reference_landmarks, scan, scan_landmarks;  // scan_landmarks empty: searched
  std::filesystem::path reference_components;  // the reference's components JSON; empty = none
  std::filesystem::path output;       // rigged fitted GLB
  std::filesystem::path components_out;        // the fitted rig's components JSON (needs reference_components)
  std::filesystem::path diagnostics;  // JSON; empty = none
  std::filesystem::path options;      // fit options JSON; empty = defaults
  int threads = 0;
  bool print_diagnostics = false;
  bool strict = false;                // a fit the gate warns about fails (options "strict": true)
};
int runFit(const FitArgs& args);

struct GenerateHeadArgs {
  std::filesystem::path output;       // GLB
  std::filesystem::path landmarks;    // landmarks JSON
  unsigned seed = 0;                  // 0 = the mean head
  double variation = 0.15;
  int columns = 128, rows = 112;
  bool alternate_diagonals = false;
  double jitter = 0.0;
  double mouth_open = 0.0;
  double scale = 1.0;                 // uniform scale (e.g. 100 for centimetres)
};
int runGenerateHead(const GenerateHeadArgs& args);

struct RetargetArgs {
  std::filesystem::path mesh;          // GLB/glTF/OBJ/PLY to animate
  std::filesystem::path markers;       // marker landmarks JSON (names as in the TRC)
  std::filesystem::path mocap;         // TRC clip
  std::filesystem::path output;        // animated GLB (morph targets + weights animation)
  std::filesystem::path diagnostics;   // JSON; empty = none
  std::filesystem::path stiffness;     // JSON {"marker": 1-9}; empty = all 1
  // Names, checked by the CLI (this header stays free of core: the remote
  // client library includes it and links api only).
  std::string method = "hybrid";       // euclidean | geodesic | hybrid
  std::string kernel = "gaussian";     // gaussian | multiquadric | thin-plate | linear
  double gamma = 0.0;                  // model units; 0 = default (core/retarget/retarget.h)
  int rest_frame = 0;
  double tolerance = 0.05;             // relative Frobenius error of the bake
  bool exact = false;                  // one morph target per frame (short clips)
  bool keep_head_motion = false;       // do not remove rigid head motion
  int max_gap_frames = 10;             // longest gap filled by interpolation in time
  bool fill_long_gaps = true;          // longer ones from neighbouring markers (else an error)
  int threads = 0;
  bool print_diagnostics = false;
};
int runRetarget(const RetargetArgs& args);

struct PoseArgs {
  std::filesystem::path rig;          // GLB/glTF
  std::filesystem::path components;   // rigport.components JSON; empty = none (no presets or controls)
  std::filesystem::path pose;         // pose JSON (core/components/pose_spec.h)
  std::filesystem::path output;       // static posed GLB
};
int runPose(const PoseArgs& args);

struct BakeArgs {
  std::filesystem::path rig;          // GLB/glTF
  std::filesystem::path components;   // the rig's rigport.components JSON
  std::vector<std::string> presets;   // names to bake; empty = every preset of the document
  std::filesystem::path output;       // the rig with the presets as morph targets
};
int runBake(const BakeArgs& args);

// Generates a source rig and a target head of other proportions and topology
// in `dir`, transfers the rig (out.glb) and prints the diagnostics; with
// `inputs_only` it stops after writing the inputs.
int runDemo(const std::filesystem::path& dir, int threads, bool inputs_only = false);

}  // namespace client
