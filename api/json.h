// JSON of the wire types (api/types.h), at this edge only. Readers return
// std::nullopt-free results: a parse failure names the field at fault.
#pragma once

#include <string>
#include <string_view>

#include <nlohmann/json.hpp>

#include "api/types.h"
#include "common/result.h"

namespace api {

// A value or the name of what is wrong ("spec.rig: expected a string").
template <typename T>
using Parsed = rigport::Result<T, std::string>;

nlohmann::json toJson(const Problem& problem);
nlohmann::json toJson(const RigInfo& rig);
nlohmann::json toJson(const JobSpec& spec);
nlohmann::json toJson(const JobInfo& job);
nlohmann::json toJson(const JobPage& page);
nlohmann::json toJson(const RigPage& page);

Parsed<Problem> problemFromJson(const nlohmann::json& json);
Parsed<RigInfo> rigInfoFromJson(const nlohmann::json& json);
// Shape only (kind/rig are strings, options an object); semantic checks in api/validate.h.
Parsed<JobSpec> jobSpecFromJson(const nlohmann::json& json);
Parsed<JobInfo> jobInfoFromJson(const nlohmann::json& json);
Parsed<JobPage> jobPageFromJson(const nlohmann::json& json);
Parsed<RigPage> rigPageFromJson(const nlohmann::json& json);

// Parses text; errors name `label` ("spec: not valid JSON at byte 12").
// True when `text` is well-formed UTF-8 (RFC 3629: no overlong forms,
// surrogates or code points past U+10FFFF).
bool isValidUtf8(std::string_view text);

// The wire's serialisation of a body: file and landmark names are a
// client's bytes, and invalid UTF-8 among them is replaced (U+FFFD), so that
// no stored name can make a response or a listing fail.
std::string dumpJson(const nlohmann::json& json);

// Deepest nesting of arrays and objects accepted in JSON from a client (as
// core's readers accept in files).
inline constexpr int kMaxJsonDepth = 64;

// Parses untrusted JSON text: malformed, nested deeper than kMaxJsonDepth or
// holding a number out of range is an error message starting with `label`.
Parsed<nlohmann::json> parseJsonText(const std::string& text, const std::string& label);

}  // namespace api
