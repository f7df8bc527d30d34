// (internal, for core's .cpp files that read JSON) Untrusted JSON text
// parsed with its nesting capped: nlohmann's parser is iterative, but a copy,
// a dump or tinygltf's conversion to its own values recurse once per level,
// and 20,000 levels (40 KB of brackets) overflow a thread's stack. Numbers
// out of range (1e400) and malformed text are errors naming the file.
#pragma once

#include <string>
#include <string_view>

#include <nlohmann/json.hpp>

#include "core/base/error.h"

namespace core {

// Deepest nesting of arrays and objects accepted in untrusted JSON.
inline constexpr int kMaxJsonDepth = 64;

// Errors read "<label>: <subject> nested deeper than 64 levels" and
// "<label>: not valid <subject> (<the parser's message>)".
inline Result<nlohmann::json> parseJsonText(std::string_view text, const std::string& label,
                                            const std::string& subject = "JSON") {
  struct TooDeep {};
  try {
    return nlohmann::json::parse(text.begin(), text.end(), [](int depth, nlohmann::json::parse_event_t event, nlohmann::json&) {
      if ((event == nlohmann::json::parse_event_t::object_start || event == nlohmann::json::parse_event_t::array_start) &&
          depth >= kMaxJsonDepth) {
        throw TooDeep{};
      }
      return true;
    });
  } catch (const TooDeep&) {
    return makeError(ErrorCode::kParse,
                     label + ": " + subject + " nested deeper than " + std::to_string(kMaxJsonDepth) + " levels");
  } catch (const nlohmann::json::exception& e) {  // malformed, a number out of range (1e400), ...
    return makeError(ErrorCode::kParse, label + ": not valid " + subject + " (" + e.what() + ")");
  }
}

}  // namespace core
