// core::Error and core::Result<T>: how core reports bad user data.
// Programmer errors are asserts; bad input (files, landmarks, geometry) is an
// Error with a closed code and a message naming the file, field or element at
// fault (common/result.h, the one value-or-error of every layer); no
// exceptions cross the core API.
#pragma once

#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "common/result.h"

namespace core {

enum class ErrorCode {
  kIo,               // a file could not be opened, read or written
  kParse,            // bytes are not the format they claim to be (truncated, garbage)
  kUnsupported,      // valid file using a feature core does not handle
  kInvalidMesh,      // mesh content unusable: NaN/Inf, out-of-range indices, no faces
  kInvalidLandmarks, // unknown/duplicate names, bad indices, too few shared landmarks
  kIllConditioned,   // duplicate or (near-)coplanar landmarks: the TPS system is singular
  kInvalidArgument,  // an option or argument out of its documented range
  kCancelled,        // work stopped on request
  kQualityGate,      // the output failed its own quality check (strict transfers)
};

// Stable lower_snake name of a code, used in diagnostics and on the wire.
const char* errorCodeName(ErrorCode code);

struct Error {
  ErrorCode code;
  std::string message;
};

template <typename T>
using Result = rigport::Result<T, Error>;

// For operations that return nothing on success.
using Ok = rigport::Ok;
using Status = Result<Ok>;

inline Error makeError(ErrorCode code, std::string message) { return Error{code, std::move(message)}; }

// "a, b, c": names listed in a message or warning.
std::string joinNames(const std::vector<std::string>& names);

// The one of `names` a mistyped `typo` most likely meant (fewest single-letter
// edits, case aside, at most a third of its letters and at least one), or ""
// when none is that close: for "did you mean ...?" in messages.
std::string closestName(const std::string& typo, const std::vector<std::string>& names);

// ` (did you mean "name"?)` with closestName's pick quoted by `quote`, or ""
// when none is close: appended to an "unknown ..." message.
std::string didYouMean(const std::string& typo, const std::vector<std::string>& names, char quote = '"');

}  // namespace core
