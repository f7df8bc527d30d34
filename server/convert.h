// The only server file that sees both api:: and core:: types: core errors as
// wire problems, upload checks before anything is stored or queued, and the
// worker's run of a job (inputs from the store -> core -> GLB + diagnostics).
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "api/error_codes.h"
#include "api/types.h"
#include "core/base/error.h"
#include "core/io/landmarks.h"
#include "core/jobs/job.h"
#include "server/config.h"
#include "server/prepared_cache.h"
#include "server/store.h"

namespace server {

// The one mapping of core error codes to wire errors.
api::WireError wireErrorOf(core::ErrorCode code);
api::Problem problemFromCoreError(const core::Error& error, const std::string& instance);

using Bytes = std::span<const std::uint8_t>;

// An uploaded rig: the GLB reads as a rig, the landmarks parse, lie on its
// mesh and make a well-conditioned TPS; counts within the limits. On success
// the rig's summary (id and created_at left to the caller).
api::Result<api::RigInfo> checkRigUpload(Bytes rig, const std::string& rig_name, Bytes landmarks,
                                                        const std::optional<Bytes>& components,
                                                        const ServerConfig& limits);

// A job's inputs before it is queued, so that what the job would refuse is
// answered at submission (422), not accepted and failed later: the kind's
// options parse, its files read, lie within the limits and are usable (a
// surface mesh; landmarks sharing >= 4 names with the rig's `rig_landmarks`
// and spanning 3D; markers on the mesh; stiffness 1-9 of known markers).
// `files` maps multipart field -> (file name, bytes); `rig_landmarks` is null
// for kinds without a rig; `rig_has_components`: the rig was uploaded with a
// components document (options that bake its presets need one). On success
// `spec.options` holds the options normalised (every option with its value):
// what is stored and what the job runs with, whatever defaults a later build has.
std::optional<api::Problem> checkJobInputs(api::JobSpec& spec,
                                           const std::map<std::string, std::pair<std::string, Bytes>>& files,
                                           const core::LandmarkSet* rig_landmarks, bool rig_has_components,
                                           const ServerConfig& limits);

// Runs a queued job on the calling (worker) thread. `rig` is the job's rig
// record (nullptr for kinds without one).
core::Result<core::JobOutput> runJob(const JobRecord& job, const RigRecord* rig, const BlobStore& blobs, Caches& caches,
                                     const core::StageHook& on_stage, int threads);

}  // namespace server
