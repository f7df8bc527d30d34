#include "core/error.h"

namespace core {

const char* errorCodeName(ErrorCode code) {
  switch (code) {
    case ErrorCode::kIo: return "io";
    case ErrorCode::kParse: return "parse";
    case ErrorCode::kUnsupported: return "unsupported";
    case ErrorCode::kInvalidMesh: return "invalid_mesh";
    case ErrorCode::kInvalidLandmarks: return "invalid_landmarks";
    case ErrorCode::kIllConditioned: return "ill_conditioned";
    case ErrorCode::kInvalidArgument: return "invalid_argument";
    case ErrorCode::kCancelled: return "cancelled";
    case ErrorCode::kQualityGate: return "quality_gate";
  }
  return "unknown";
}

std::string joinNames(const std::vector<std::string>& names) {
  std::string out;
  for (const std::string& name : names) out += (out.empty() ? "" : ", ") + name;
  return out;
}

}  // namespace core
