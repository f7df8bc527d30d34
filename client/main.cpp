// rigport CLI: wiring only. Subcommands run in-process (core); the service
// client (--server) arrives with the REST API.
#include <cstdio>
#include <string>

#include <CLI/CLI.hpp>
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include "client/local_jobs.h"

int main(int argc, char** argv) {
  CLI::App app{"rigport: facial rig transfer (warp, transfer, retarget, fit)"};
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
  warp_cmd->add_option("-o,--output", warp.output, "Guide model GLB (source topology on the target)")->required();
  warp_cmd->add_option("--diagnostics", warp.diagnostics, "Diagnostics JSON");
  warp_cmd->add_option("--refine", warp.refine_iterations, "Non-rigid refinement rounds (0 = plain projection)")
      ->check(CLI::Range(0, 20))->capture_default_str();
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
  transfer_cmd->add_option("--target-landmarks", transfer.target_landmarks, "Target landmarks JSON")->required()->check(CLI::ExistingFile);
  transfer_cmd->add_option("-o,--output", transfer.output, "Rigged target GLB")->required();
  transfer_cmd->add_option("--diagnostics", transfer.diagnostics, "Diagnostics JSON");
  transfer_cmd->add_option("--options", transfer.options, "Transfer options JSON (see client/transfer_options.h)")->check(CLI::ExistingFile);
  transfer_cmd->add_option("--threads", transfer.threads, "Worker threads (0 = all cores)")->check(CLI::NonNegativeNumber);
  transfer_cmd->add_flag("--print-diagnostics", transfer.print_diagnostics, "Also print the diagnostics JSON on stdout");

  client::GenerateHeadArgs head;
  auto* head_cmd = app.add_subcommand("generate-head", "Write a procedural head mesh with 68 landmarks");
  head_cmd->add_option("-o,--output", head.output, "GLB to write")->required();
  head_cmd->add_option("--landmarks", head.landmarks, "Landmarks JSON to write")->required();
  head_cmd->add_option("--seed", head.seed, "Identity seed (0 = the mean head)")->capture_default_str();
  head_cmd->add_option("--variation", head.variation, "Relative variation of proportions")->capture_default_str();
  head_cmd->add_option("--columns", head.columns, "Grid cells around")->check(CLI::Range(8, 4000))->capture_default_str();
  head_cmd->add_option("--rows", head.rows, "Grid cells up")->check(CLI::Range(8, 4000))->capture_default_str();
  head_cmd->add_flag("--alternate-diagonals", head.alternate_diagonals, "Other triangulation");
  head_cmd->add_option("--jitter", head.jitter, "Random vertex offset (fraction of a cell)")->check(CLI::Range(0.0, 0.45));
  head_cmd->add_option("--mouth-open", head.mouth_open, "Mouth slit half-height (radians of latitude; 0 = closed)");
  head_cmd->add_option("--scale", head.scale, "Uniform scale (1 = metres)")->check(CLI::PositiveNumber);

  std::string demo_dir = "demo-out";
  int demo_threads = 0;
  auto* demo_cmd = app.add_subcommand("demo", "Generate a rig and a target head, transfer the rig, print diagnostics");
  demo_cmd->add_option("--out", demo_dir, "Output directory")->capture_default_str();
  demo_cmd->add_option("--threads", demo_threads, "Worker threads (0 = all cores)");

  CLI11_PARSE(app, argc, argv);

  auto logger = spdlog::stderr_color_mt("rigport");
  spdlog::set_default_logger(logger);
  spdlog::set_pattern("%^[%l]%$ %v");
  spdlog::set_level(quiet ? spdlog::level::err : verbose ? spdlog::level::debug : spdlog::level::info);

  if (*warp_cmd) return client::runWarp(warp);
  if (*transfer_cmd) return client::runTransfer(transfer);
  if (*head_cmd) return client::runGenerateHead(head);
  if (*demo_cmd) return client::runDemo(demo_dir, demo_threads);
  return 2;
}
