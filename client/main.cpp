// rigport CLI: wiring only. Subcommands run in-process (core); the service
// client (rigs, jobs, bench, transfer|fit --server) is in client/remote_commands.h.
#include <malloc.h>

#include <cstdio>
#include <string>

#include <CLI/CLI.hpp>
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include "client/cli_hints.h"
#include "client/local_jobs.h"
#include "client/muscle_rig_job.h"
#include "client/remote_commands.h"

int main(int argc, char** argv) {
  // A run allocates and frees buffers of hundreds of kB to a few MB (decoded
  // accessors, per-shape deltas, indices). By default glibc maps each afresh
  // and every page of it faults in again; kept in the heap they are reused.
  // A CLI run is short, so memory not handed back is no loss
  // (docs/journal/BENCHMARKS_HISTORY.md, 2026-11-23: one transfer 101.6 -> 93.7 ms).
  mallopt(M_MMAP_THRESHOLD, 32 << 20);
  mallopt(M_TRIM_THRESHOLD, 1 << 30);
  CLI::App app{"rigport: facial rig transfer (warp, transfer, fit, retarget, pose, bake, muscle-rig; rigs, jobs and bench on the service)"};
  app.set_version_flag("--version", std::string("rigport ") + RIGPORT_VERSION);
  app.require_subcommand(1);
  bool verbose = false, quiet = false;
  app.add_flag("-v,--verbose", verbose, "More log output");
  app.add_flag("-q,--quiet", quiet, "Only errors on stderr");

  client::WarpArgs warp;
  auto* warp_cmd = app.add_subcommand("warp", "Landmark TPS warp + dense correspondence: writes the guide model");
  warp_cmd->add_option("--source", warp.source, "Source mesh (GLB/glTF/OBJ/PLY)")->required()->check(CLI::ExistingFile);
  warp_cmd->add_option("--source-landmarks", warp.source_landmarks, "Source landmarks JSON")->required()->check(CLI::ExistingFile);
  warp_cmd->add_option("--target", warp.target, "Target mesh (GLB/glTF/OBJ/PLY)")->required()->check(CLI::ExistingFile);
  warp_cmd->add_option("--target-landmarks", warp.target_landmarks, "Target landmarks JSON")->required()->check(CLI::ExistingFile);
  warp_cmd->add_option("-o,--output", warp.output, "Guide model GLB (source topology on the target)")->required()->check(client::kGlbPath);
  warp_cmd->add_option("--diagnostics", warp.diagnostics, "Diagnostics JSON");
  auto* refine = warp_cmd->add_option("--refine", warp.refine_iterations, "Dense-map refinement rounds (0 = none)")
                     ->check(CLI::Range(0, 20))->capture_default_str();
  auto* local_rounds = warp_cmd->add_option("--local-rounds", warp.local_rounds,
                                            "Local rounds after the dense map (projection of a sample, smoothed)")
                           ->check(CLI::Range(0, 20))->capture_default_str();
  auto* plain = warp_cmd->add_flag("--plain", warp.plain,
                                   "The papers' method as written: landmark TPS, projection, location (no dense-map "
                                   "refinement, local rounds or rim matching)")
                    ->excludes(refine)->excludes(local_rounds);
  warp_cmd->add_flag("--light", warp.light,
                     "The fast pipeline: one local round with rims matched (no dense-map refinement, target pulls "
                     "or smoothed guide)")
      ->excludes(refine)->excludes(local_rounds)->excludes(plain);
  warp_cmd->add_option("--landmark-regularization", warp.landmark_regularization,
                       "Approximating TPS: kernel diagonal (model units), 0 = exact")
      ->check(CLI::NonNegativeNumber)->capture_default_str();
  warp_cmd->add_option("--threads", warp.threads, "Worker threads (0 = all cores)")->check(CLI::NonNegativeNumber);
  warp_cmd->add_flag("--print-diagnostics", warp.print_diagnostics, "Also print the diagnostics JSON on stdout");

  client::TransferArgs transfer;
  auto* transfer_cmd = app.add_subcommand("transfer", "Transfer a rig (skin, joints, shapes, animations, attributes) to a target mesh");
  transfer_cmd->add_option("--source", transfer.source, "Source rig (GLB/glTF)")->required()->check(CLI::ExistingFile);
  transfer_cmd->add_option("--source-landmarks", transfer.source_landmarks, "Source landmarks JSON")->required()->check(CLI::ExistingFile);
  transfer_cmd->add_option("--target", transfer.target, "Target mesh (GLB/glTF/OBJ/PLY)")->required()->check(CLI::ExistingFile);
  transfer_cmd->add_option("--target-landmarks", transfer.target_landmarks,
                           "Target landmarks JSON (without: found by a fit of the rig's face)")
      ->check(CLI::ExistingFile);
  transfer_cmd->add_option("-o,--output", transfer.output, "Rigged target GLB")->required()->check(client::kGlbPath);
  auto* source_components =
      transfer_cmd->add_option("--source-components", transfer.source_components,
                               "The rig's components document (rigport.components JSON, docs/COMPONENTS.md): carried "
                               "to the target")
          ->check(CLI::ExistingFile);
  transfer_cmd->add_option("--components-out", transfer.components_out,
                           "The target's components document to write (bound to the target's mesh)")
      ->needs(source_components);
  transfer_cmd->add_option("--diagnostics", transfer.diagnostics, "Diagnostics JSON");
  transfer_cmd->add_option("--options", transfer.options, "Transfer options JSON (see core/jobs/transfer_options.h)")->check(CLI::ExistingFile);
  transfer_cmd->add_option("--threads", transfer.threads, "Worker threads (0 = all cores)")->check(CLI::NonNegativeNumber);
  transfer_cmd->add_flag("--print-diagnostics", transfer.print_diagnostics, "Also print the diagnostics JSON on stdout");
  transfer_cmd->add_flag("--strict", transfer.strict,
                         "Fail when the output fails its quality check (a vertex moving as none of its ring does, or "
                         "located across the mouth or an eye), instead of warning");

  client::FitArgs fit;
  auto* fit_cmd = app.add_subcommand("fit", "Fit the reference face to a head scan and rebuild its rig on the fitted mesh");
  fit_cmd->add_option("--reference", fit.reference, "Reference rig (GLB/glTF)")->required()->check(CLI::ExistingFile);
  fit_cmd->add_option("--reference-landmarks", fit.reference_landmarks, "Reference landmarks JSON")->required()->check(CLI::ExistingFile);
  fit_cmd->add_option("--scan", fit.scan, "Head scan: mesh or point cloud (PLY/OBJ/GLB)")->required()->check(CLI::ExistingFile);
  fit_cmd->add_option("--scan-landmarks", fit.scan_landmarks, "Scan landmarks JSON (>= 4 of the reference's names); "
                      "without them the alignment is searched (head roughly upright)")->check(CLI::ExistingFile);
  fit_cmd->add_option("-o,--output", fit.output, "Rigged fitted GLB")->required()->check(client::kGlbPath);
  auto* reference_components =
      fit_cmd->add_option("--reference-components", fit.reference_components,
                          "The reference's components document (rigport.components JSON): rebuilt by vertex index "
                          "on the fitted mesh")
          ->check(CLI::ExistingFile);
  fit_cmd->add_option("--components-out", fit.components_out, "The fitted rig's components document to write")
      ->needs(reference_components);
  fit_cmd->add_option("--diagnostics", fit.diagnostics, "Diagnostics JSON (written also when the gate refuses the fit)");
  fit_cmd->add_option("--options", fit.options, "Fit options JSON (see core/jobs/fit_options.h)")->check(CLI::ExistingFile);
  fit_cmd->add_option("--threads", fit.threads, "Worker threads (0 = all cores)")->check(CLI::NonNegativeNumber);
  fit_cmd->add_flag("--print-diagnostics", fit.print_diagnostics, "Also print the diagnostics JSON on stdout");
  fit_cmd->add_flag("--strict", fit.strict, "Fail when the fit's gate warns, not only when it fails");

  client::GenerateHeadArgs head;
  auto* head_cmd = app.add_subcommand("generate-head", "Write a procedural head mesh with 68 landmarks");
  head_cmd->add_option("-o,--output", head.output, "GLB to write")->required()->check(client::kGlbPath);
  head_cmd->add_option("--landmarks", head.landmarks, "Landmarks JSON to write")->required();
  head_cmd->add_option("--seed", head.seed, "Identity seed (0 = the mean head)")->capture_default_str();
  head_cmd->add_option("--variation", head.variation, "Relative variation of proportions")->capture_default_str();
  head_cmd->add_option("--columns", head.columns, "Grid cells around")->check(CLI::Range(8, 4000))->capture_default_str();
  head_cmd->add_option("--rows", head.rows, "Grid cells up")->check(CLI::Range(8, 4000))->capture_default_str();
  head_cmd->add_flag("--alternate-diagonals", head.alternate_diagonals, "Other triangulation");
  head_cmd->add_option("--jitter", head.jitter, "Random vertex offset (fraction of a cell)")->check(CLI::Range(0.0, 0.45));
  head_cmd->add_option("--mouth-open", head.mouth_open, "Mouth slit half-height (radians of latitude; 0 = closed)");
  head_cmd->add_option("--scale", head.scale, "Uniform scale (1 = metres)")->check(CLI::PositiveNumber);

  client::RetargetArgs retarget;
  auto* retarget_cmd = app.add_subcommand("retarget", "Drive a mesh with facial mocap markers (RBF): writes morph targets + animation");
  retarget_cmd->add_option("--mesh", retarget.mesh, "Mesh to animate (GLB/glTF/OBJ/PLY)")->required()->check(CLI::ExistingFile);
  retarget_cmd->add_option("--markers", retarget.markers, "Markers on the mesh (landmarks JSON, names as in the clip)")->required()->check(CLI::ExistingFile);
  retarget_cmd->add_option("--mocap", retarget.mocap, "Marker trajectories (TRC)")->required()->check(CLI::ExistingFile);
  retarget_cmd->add_option("-o,--output", retarget.output, "Animated GLB")->required()->check(client::kGlbPath);
  retarget_cmd->add_option("--diagnostics", retarget.diagnostics, "Diagnostics JSON");
  retarget_cmd->add_option("--method", retarget.method, "Marker-to-vertex distance: euclidean|geodesic|hybrid")
      ->check(CLI::IsMember({"euclidean", "geodesic", "hybrid"}))->capture_default_str();
  retarget_cmd->add_option("--kernel", retarget.kernel, "RBF kernel: gaussian|multiquadric|thin-plate|linear")
      ->check(CLI::IsMember({"gaussian", "multiquadric", "thin-plate", "linear"}))->capture_default_str();
  retarget_cmd->add_option("--gamma", retarget.gamma, "Kernel shape parameter, mesh units (0 = 0.1 x bounding-box diagonal)")
      ->check(CLI::NonNegativeNumber);
  retarget_cmd->add_option("--stiffness", retarget.stiffness, "Per-marker stiffness JSON {\"marker\": 1-9}")->check(CLI::ExistingFile);
  retarget_cmd->add_option("--rest-frame", retarget.rest_frame, "0-based neutral frame")->check(CLI::NonNegativeNumber)->capture_default_str();
  retarget_cmd->add_option("--tolerance", retarget.tolerance, "Bake: relative Frobenius error of the morph-target compression")
      ->check(CLI::Range(0.0, 1.0))->capture_default_str();
  retarget_cmd->add_flag("--exact", retarget.exact, "One morph target per frame (short clips)");
  retarget_cmd->add_flag("--keep-head-motion", retarget.keep_head_motion, "Do not remove rigid head motion");
  retarget_cmd->add_option("--max-gap-frames", retarget.max_gap_frames, "Gaps up to this many frames: interpolated in time")
      ->check(CLI::NonNegativeNumber)->capture_default_str();
  retarget_cmd->add_flag("!--no-fill-long-gaps", retarget.fill_long_gaps,
                         "Longer gaps are an error (by default they follow the neighbouring markers)");
  retarget_cmd->add_option("--threads", retarget.threads, "Worker threads (0 = all cores)")->check(CLI::NonNegativeNumber);
  retarget_cmd->add_flag("--print-diagnostics", retarget.print_diagnostics, "Also print the diagnostics JSON on stdout");

  client::PoseArgs pose;
  auto* pose_cmd = app.add_subcommand("pose", "Pose a rig (components preset or controls, morph weights, joint rotations): "
                                              "writes the posed meshes as a static GLB");
  pose_cmd->add_option("--rig", pose.rig, "Rig (GLB/glTF)")->required()->check(CLI::ExistingFile);
  pose_cmd->add_option("--components", pose.components,
                       "The rig's components document (rigport.components JSON; needed for presets and controls)")
      ->check(CLI::ExistingFile);
  pose_cmd->add_option("--pose", pose.pose, "Pose JSON: preset, controls, morph_weights, joints (docs/COMPONENTS.md)")
      ->required()->check(CLI::ExistingFile);
  pose_cmd->add_option("-o,--output", pose.output, "Posed static GLB (no skin, morph targets or animations)")
      ->required()->check(client::kGlbPath);

  client::MuscleRigArgs muscle_rig;
  auto* muscle_rig_cmd = app.add_subcommand("muscle-rig", "Build the reference muscle rig (26 muscles, 16 wires, controls, "
                                                          "15 expression presets) on a face with the 68 iBUG landmarks; "
                                                          "writes the rig GLB with the presets baked and its components JSON");
  muscle_rig_cmd->add_option("--mesh", muscle_rig.mesh, "Face (GLB/glTF)")->required()->check(CLI::ExistingFile);
  muscle_rig_cmd->add_option("--landmarks", muscle_rig.landmarks, "Landmarks JSON (the 68 iBUG names)")
      ->required()->check(CLI::ExistingFile);
  muscle_rig_cmd->add_option("-o,--output", muscle_rig.output, "Rig GLB with every preset baked as a morph target")
      ->required()->check(client::kGlbPath);
  muscle_rig_cmd->add_option("--components", muscle_rig.components, "Components JSON of the rig (rigport.components)")
      ->required();
  muscle_rig_cmd->add_option("--wire-dropoff", muscle_rig.wire_dropoff, "Scale of every wire's dropoff distance (1 = default)")
      ->check(CLI::PositiveNumber);
  muscle_rig_cmd->add_option("--expression-gain", muscle_rig.expression_gain, "Scale of every muscle's travel (1 = default)")
      ->check(CLI::PositiveNumber);

  client::BakeArgs bake;
  auto* bake_cmd = app.add_subcommand("bake", "Bake a rig's component presets into morph targets of its face, so any glTF "
                                              "consumer plays them (the GLB records which targets are baked presets)");
  bake_cmd->add_option("--rig", bake.rig, "Rig (GLB/glTF)")->required()->check(CLI::ExistingFile);
  bake_cmd->add_option("--components", bake.components, "The rig's components document (rigport.components JSON)")
      ->required()->check(CLI::ExistingFile);
  bake_cmd->add_option("--presets", bake.presets, "Presets to bake, comma-separated (default: every preset)")
      ->delimiter(',');
  bake_cmd->add_option("-o,--output", bake.output, "The rig with the presets as morph targets (baked again: replaced)")
      ->required()->check(client::kGlbPath);

  std::string demo_dir = "demo-out";
  int demo_threads = 0;
  bool demo_inputs_only = false;
  auto* demo_cmd = app.add_subcommand("demo", "Generate a rig and a target head, transfer the rig, print diagnostics");
  demo_cmd->add_option("--out", demo_dir, "Output directory")->capture_default_str();
  demo_cmd->add_option("--threads", demo_threads, "Worker threads (0 = all cores)");
  demo_cmd->add_flag("--inputs-only", demo_inputs_only, "Only write the generated rig and target (scripts/demo.sh sends them to the service)");

  // rigs, jobs, bench, and --server/--api-key on transfer and fit (client/remote_commands.h).
  const client::RemoteCommands remote(app, *transfer_cmd, *fit_cmd);

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return client::exitWithHints(app, e, argc, argv);
  }

  auto logger = spdlog::stderr_color_mt("rigport");
  spdlog::set_default_logger(logger);
  spdlog::set_pattern("%^[%l]%$ %v");
  spdlog::set_level(quiet ? spdlog::level::err : verbose ? spdlog::level::debug : spdlog::level::info);

  if (auto rc = remote.run(transfer, fit)) return *rc;  // remote commands, transfer|fit --server
  if (*warp_cmd) return client::runWarp(warp);
  if (*transfer_cmd) return client::runTransfer(transfer);
  if (*fit_cmd) return client::runFit(fit);
  if (*head_cmd) return client::runGenerateHead(head);
  if (*retarget_cmd) return client::runRetarget(retarget);
  if (*pose_cmd) return client::runPose(pose);
  if (*bake_cmd) return client::runBake(bake);
  if (*muscle_rig_cmd) return client::runMuscleRig(muscle_rig);
  if (*demo_cmd) return client::runDemo(demo_dir, demo_threads, demo_inputs_only);
  return 2;
}
