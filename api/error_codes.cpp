#include "api/error_codes.h"

namespace api {

namespace {

struct Row {
  WireError error;
  int status;
  const char* slug;
  const char* title;
};

// The single table: wire code -> HTTP status, slug, title.
constexpr Row kTable[] = {
    {WireError::kMalformedRequest, 400, "malformed-request", "Malformed request"},
    {WireError::kMalformedFile, 400, "malformed-file", "Uploaded file is not a valid file of its format"},
    {WireError::kInvalidOption, 400, "invalid-option", "Option out of range"},
    {WireError::kUnauthorized, 401, "unauthorized", "Missing or unknown API key"},
    {WireError::kNotFound, 404, "not-found", "Not found"},
    {WireError::kRequestTimeout, 408, "request-timeout", "Request not received in time"},
    {WireError::kConflict, 409, "conflict", "Conflict with the resource's state"},
    {WireError::kLengthRequired, 411, "length-required", "Content-Length required"},
    {WireError::kPayloadTooLarge, 413, "payload-too-large", "Request over a size limit"},
    {WireError::kUnsupportedMediaType, 415, "unsupported-media-type", "Unsupported media type"},
    {WireError::kInvalidMesh, 422, "invalid-mesh", "Mesh unusable"},
    {WireError::kInvalidLandmarks, 422, "invalid-landmarks", "Landmarks unusable"},
    {WireError::kIllConditioned, 422, "ill-conditioned", "Landmarks make an ill-conditioned warp"},
    {WireError::kUnsupportedFeature, 422, "unsupported-feature", "File uses an unsupported feature"},
    {WireError::kQualityGate, 422, "quality-gate", "Job output failed its quality check"},
    {WireError::kQueueFull, 429, "queue-full", "Job queue full; retry later"},
    {WireError::kAuthThrottled, 429, "auth-throttled", "Too many failed authentications; retry later"},
    {WireError::kTooManyUploads, 429, "too-many-uploads", "Too many uploads in progress; retry later"},
    {WireError::kHeadersTooLarge, 431, "headers-too-large", "Request head too large"},
    {WireError::kJobCancelled, 409, "job-cancelled", "Job cancelled"},
    {WireError::kJobTimeout, 504, "job-timeout", "Job exceeded its time limit"},
    {WireError::kInternal, 500, "internal", "Internal error"},
    {WireError::kNotReady, 503, "not-ready", "Service not ready"},
    {WireError::kStorageUnavailable, 503, "storage-unavailable", "Storage unavailable; retry later"},
};

const Row& row(WireError error) {
  for (const Row& r : kTable) {
    if (r.error == error) return r;
  }
  return error == WireError::kInternal ? kTable[0] : row(WireError::kInternal);  // every code is in the table
}

}  // namespace

int httpStatus(WireError error) { return row(error).status; }
const char* wireErrorSlug(WireError error) { return row(error).slug; }
std::string problemType(WireError error) { return std::string("urn:rigport:problem:") + row(error).slug; }

Problem makeProblem(WireError error, std::string detail, std::string instance) {
  const Row& r = row(error);
  return Problem{problemType(error), r.title, r.status, std::move(detail), std::move(instance)};
}

}  // namespace api
