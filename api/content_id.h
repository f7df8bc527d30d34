// Content-derived ids, shared by server/ (stores rigs under them) and client/
// (asks GET /v1/rigs/{id} before uploading): sha256 over the uploaded bytes.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <string_view>

namespace api {

// Lower-case hex SHA-256 (64 characters) of `bytes`.
std::string sha256Hex(std::span<const std::uint8_t> bytes);
std::string sha256Hex(std::string_view text);

// The rig id of POST /v1/rigs: sha256 hex of the ASCII text
//   "rigport-rig-v1\n" + sha256Hex(rig) + "\n" + sha256Hex(landmarks) + "\n" + sha256Hex(components) + "\n"
// where an absent components file counts as empty bytes. Any change to any
// input changes the id; the same three files always give the same id.
std::string rigContentId(std::span<const std::uint8_t> rig, std::span<const std::uint8_t> landmarks,
                         std::span<const std::uint8_t> components = {});

}  // namespace api
