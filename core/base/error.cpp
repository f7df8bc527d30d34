#include "core/base/error.h"

#include <algorithm>
#include <cctype>

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

std::string closestName(const std::string& typo, const std::vector<std::string>& names) {
  auto same = [](char a, char b) {
    return std::tolower(static_cast<unsigned char>(a)) == std::tolower(static_cast<unsigned char>(b));
  };
  const std::size_t allowed = std::max<std::size_t>(1, typo.size() / 3);
  std::string best;
  std::size_t best_distance = allowed + 1;
  std::vector<std::size_t> before, previous, current;
  for (const std::string& name : names) {
    // Edit distance with adjacent swaps ("tranfser", "wrap"), a row at a time.
    before.assign(name.size() + 1, 0);
    previous.resize(name.size() + 1);
    current.resize(name.size() + 1);
    for (std::size_t j = 0; j <= name.size(); ++j) previous[j] = j;
    for (std::size_t i = 1; i <= typo.size(); ++i) {
      current[0] = i;
      for (std::size_t j = 1; j <= name.size(); ++j) {
        current[j] = std::min({previous[j] + 1, current[j - 1] + 1, previous[j - 1] + (same(typo[i - 1], name[j - 1]) ? 0 : 1)});
        if (i > 1 && j > 1 && same(typo[i - 1], name[j - 2]) && same(typo[i - 2], name[j - 1])) {
          current[j] = std::min(current[j], before[j - 2] + 1);
        }
      }
      before.swap(previous);
      previous.swap(current);
    }
    if (previous[name.size()] < best_distance) {
      best_distance = previous[name.size()];
      best = name;
    }
  }
  return best;
}

std::string didYouMean(const std::string& typo, const std::vector<std::string>& names, char quote) {
  const std::string guess = closestName(typo, names);
  return guess.empty() ? std::string() : " (did you mean " + (quote + guess + quote) + "?)";
}

}  // namespace core
