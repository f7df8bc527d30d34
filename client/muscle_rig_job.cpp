// runMuscleRig: read the face and its landmarks -> buildMuscleRig -> bake the
// presets -> write the GLB and the components JSON. Errors name the file.
#include "client/muscle_rig_job.h"

#include <chrono>
#include <span>
#include <string>

#include <spdlog/spdlog.h>

#include "core/components/bake.h"
#include "core/io/components_io.h"
#include "core/io/landmarks.h"
#include "core/io/mesh_io.h"
#include "core/io/rig_io.h"
#include "core/muscle_rig/muscle_rig.h"

namespace client {

namespace {

int failWith(const core::Error& error) {
  spdlog::error("{} ({})", error.message, core::errorCodeName(error.code));
  return 1;
}

}  // namespace

int runMuscleRig(const MuscleRigArgs& args) {
  const auto start = std::chrono::steady_clock::now();
  auto loaded = core::readRig(args.mesh);
  if (!loaded) return failWith(loaded.error());
  core::Rig& rig = loaded->rig;
  auto landmarks = core::readLandmarks(args.landmarks);
  if (!landmarks) return failWith(landmarks.error());
  spdlog::info("read face {} ({} vertices, {} shapes)", args.mesh.filename().string(), rig.mesh.vertexCount(),
               rig.morph_targets.size());

  core::MuscleRigOptions options;
  options.wire_dropoff = args.wire_dropoff;
  options.expression_gain = args.expression_gain;
  options.label = args.landmarks.filename().string();  // landmark errors name the landmarks file
  options.joints = core::namedNodeTransforms(rig);  // eye joints among them are aimed, a jaw joint is the hinge
  options.joint_weights = core::faceJointWeights(rig);
  auto built = core::buildMuscleRig(rig.mesh, *landmarks, options);
  if (!built) return failWith(built.error());
  const core::ComponentsDocument& doc = built->components;
  spdlog::info("muscle rig: {} muscles, {} wires, {} clusters, {} controls, {} presets", doc.muscles.size(),
               doc.wires.size(), doc.clusters.size(), doc.controls.size(), doc.presets.size());

  auto baked = core::bakePresets(rig, doc);
  if (!baked) return failWith(core::makeError(baked.error().code, args.mesh.filename().string() + ": " + baked.error().message));
  for (const std::string& warning : baked->warnings) spdlog::warn("{}", warning);
  if (auto ok = core::writeRigGlb(rig, args.output); !ok) return failWith(ok.error());
  const std::string text = core::formatComponents(doc);
  const std::span<const std::uint8_t> bytes(reinterpret_cast<const std::uint8_t*>(text.data()), text.size());
  if (auto ok = core::writeFileBytes(args.components, bytes); !ok) return failWith(ok.error());
  const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  spdlog::info("baked {} presets as morph targets; {:.1f} ms", baked->baked.size(), ms);
  spdlog::info("wrote {} and {}", args.output.string(), args.components.string());
  return 0;
}

}  // namespace client
