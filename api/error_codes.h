// Wire error codes of the contract and the one table mapping each to its HTTP
// status, problem type URI and title. Client errors come before server errors.
#pragma once

#include <string>

#include "api/types.h"

namespace api {

enum class WireError {
  // 4xx: the caller can fix it
  kMalformedRequest,      // 400 bad multipart/JSON, unknown or missing field
  kMalformedFile,         // 400 an uploaded file is not the format it claims (truncated, garbage)
  kInvalidOption,         // 400 an option out of its documented range
  kUnauthorized,          // 401 missing or unknown API key
  kNotFound,              // 404 unknown route, rig or job (or another tenant's)
  kRequestTimeout,        // 408 the request head did not arrive in time (answered before any thread is taken)
  kConflict,              // 409 e.g. result of a job that has not succeeded
  kLengthRequired,        // 411 a chunked body on a route that takes no upload
  kPayloadTooLarge,       // 413 body, vertex or landmark count over the limit
  kUnsupportedMediaType,  // 415 not multipart/form-data where files are expected
  kInvalidMesh,           // 422 NaN/Inf, bad indices, no faces
  kInvalidLandmarks,      // 422 unknown/duplicate names, too few shared, off the mesh
  kIllConditioned,        // 422 duplicate or coplanar landmarks
  kUnsupportedFeature,    // 422 valid file using a feature rigport does not handle
  kQualityGate,           // 422 (job error) a strict transfer's output failed its quality check
  kQueueFull,             // 429 with Retry-After
  kAuthThrottled,         // 429 with Retry-After: too many failed authentications from the client address
  kTooManyUploads,        // 429 with Retry-After: upload slots of the service, the tenant or the client address taken
  kHeadersTooLarge,       // 431 request head over its limit
  // 5xx and job outcomes
  kJobCancelled,          // 409 (job error) cancelled on request
  kJobTimeout,            // 504 (job error) over the per-job time limit
  kInternal,              // 500
  kNotReady,              // 503 starting up or shutting down
  kStorageUnavailable,    // 503 with Retry-After: the data directory does not take writes (accepted jobs wait)
};

int httpStatus(WireError error);
const char* wireErrorSlug(WireError error);   // "invalid-mesh"
std::string problemType(WireError error);     // "urn:rigport:problem:invalid-mesh"
Problem makeProblem(WireError error, std::string detail, std::string instance);

}  // namespace api
