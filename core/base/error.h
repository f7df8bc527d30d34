// core::Error and core::Result<T>: how core reports bad user data.
// Programmer errors are asserts; bad input (files, landmarks, geometry) is an
// Error with a closed code and a message naming the file, field or element at
// fault. Modelled on cpp-httplib's Result/Error pair; no exceptions cross the
// core API.
#pragma once

#include <cassert>
#include <optional>
#include <string>
#include <utility>
#include <variant>
#include <vector>

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
class Result {
 public:
  Result(T value) : state_(std::move(value)) {}              // NOLINT: implicit by design
  Result(Error error) : state_(std::move(error)) {}          // NOLINT: implicit by design

  bool ok() const { return std::holds_alternative<T>(state_); }
  explicit operator bool() const { return ok(); }

  const T& value() const& { assert(ok()); return std::get<T>(state_); }
  T& value() & { assert(ok()); return std::get<T>(state_); }
  T&& value() && { assert(ok()); return std::get<T>(std::move(state_)); }
  const T& operator*() const& { return value(); }
  T& operator*() & { return value(); }
  T&& operator*() && { return std::move(*this).value(); }
  const T* operator->() const { return &value(); }
  T* operator->() { return &value(); }

  const Error& error() const { assert(!ok()); return std::get<Error>(state_); }

 private:
  std::variant<T, Error> state_;
};

// For operations that return nothing on success.
struct Ok {};
using Status = Result<Ok>;

inline Error makeError(ErrorCode code, std::string message) { return Error{code, std::move(message)}; }

// "a, b, c": names listed in a message or warning.
std::string joinNames(const std::vector<std::string>& names);

// The one of `names` a mistyped `typo` most likely meant (fewest single-letter
// edits, case aside, at most a third of its letters and at least one), or ""
// when none is that close: for "did you mean ...?" in messages.
std::string closestName(const std::string& typo, const std::vector<std::string>& names);

}  // namespace core
