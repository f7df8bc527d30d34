// libFuzzer targets for every parser of untrusted bytes the service and the
// CLI run (scripts/fuzz.sh builds them with clang and runs each; docs/FUZZING.md
// has the long runs). One source, one target per RIGPORT_FUZZ_TARGET value, so
// each reader gets its own corpus and its own executable. A reader may answer
// any input with an error; it must never crash, hang, leak or read out of
// bounds (ASan + UBSan are on).
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <string_view>

#include "api/json.h"
#include "core/io/components_io.h"
#include "core/io/landmarks.h"
#include "core/io/mesh_io.h"
#include "core/jobs/fit_options.h"
#include "core/jobs/retarget_options.h"
#include "core/io/rig_io.h"
#include "core/jobs/transfer_options.h"
#include "core/io/trc_io.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::span<const std::uint8_t> bytes(data, size);
  const std::string text(reinterpret_cast<const char*>(data), size);
#if RIGPORT_FUZZ_TARGET == 1  // fuzz_glb: binary glTF as a target mesh and as a rig
  (void)core::readGltf(bytes, "fuzz.glb", true);
  (void)core::readRigGltf(bytes, "fuzz.glb", true);
#elif RIGPORT_FUZZ_TARGET == 2  // fuzz_gltf: glTF JSON (no external buffers are ever fetched)
  (void)core::readGltf(bytes, "fuzz.gltf", false);
  (void)core::readRigGltf(bytes, "fuzz.gltf", false);
#elif RIGPORT_FUZZ_TARGET == 3  // fuzz_obj
  (void)core::readObj(bytes, "fuzz.obj");
#elif RIGPORT_FUZZ_TARGET == 4  // fuzz_ply: ASCII and binary
  (void)core::readPly(bytes, "fuzz.ply");
#elif RIGPORT_FUZZ_TARGET == 5  // fuzz_trc: mocap clips, gaps filled
  (void)core::parseTrc(text, "fuzz.trc");
#elif RIGPORT_FUZZ_TARGET == 6  // fuzz_landmarks
  (void)core::parseLandmarks(text, "fuzz.landmarks.json");
#elif RIGPORT_FUZZ_TARGET == 7  // fuzz_options: transfer, retarget and fit options, stiffness
  (void)core::parseTransferOptions(text, "fuzz.options.json");
  (void)core::parseRetargetOptions(text, "fuzz.options.json");
  if (auto fit = core::parseFitOptions(text, "fuzz.options.json")) (void)core::fitOptionsJson(*fit);
  (void)core::parseStiffness(text, "fuzz.stiffness.json");
#elif RIGPORT_FUZZ_TARGET == 8  // fuzz_job_spec: the multipart `spec` part of POST /v1/jobs
  auto parsed = api::parseJsonText(text, "spec");
  if (parsed) (void)api::jobSpecFromJson(*parsed);
#elif RIGPORT_FUZZ_TARGET == 9  // fuzz_components: the rig components document, written back and read again
  if (auto doc = core::parseComponents(text, "fuzz.components.json")) {
    // What was accepted must read back: a written document the reader refuses is a bug.
    if (!core::parseComponents(core::formatComponents(*doc), "fuzz.components.json")) __builtin_trap();
  }
#else
#error "RIGPORT_FUZZ_TARGET must name a reader (1-9)"
#endif
  return 0;
}
