#include "api/content_id.h"

#include <cassert>

#include <openssl/evp.h>

namespace api {

std::string sha256Hex(std::span<const std::uint8_t> bytes) {
  unsigned char digest[EVP_MAX_MD_SIZE];
  unsigned int length = 0;
  // One-shot EVP digest; it only fails on allocation failure inside OpenSSL.
  const int ok = EVP_Digest(bytes.data(), bytes.size(), digest, &length, EVP_sha256(), nullptr);
  assert(ok == 1 && length == 32);
  (void)ok;
  static constexpr char kHex[] = "0123456789abcdef";
  std::string hex;
  hex.reserve(2 * length);
  for (unsigned int i = 0; i < length; ++i) {
    hex.push_back(kHex[digest[i] >> 4]);
    hex.push_back(kHex[digest[i] & 0x0f]);
  }
  return hex;
}

std::string sha256Hex(std::string_view text) {
  return sha256Hex(std::span<const std::uint8_t>(reinterpret_cast<const std::uint8_t*>(text.data()), text.size()));
}

std::string rigContentId(std::span<const std::uint8_t> rig, std::span<const std::uint8_t> landmarks,
                         std::span<const std::uint8_t> components) {
  const std::string text = "rigport-rig-v1\n" + sha256Hex(rig) + "\n" + sha256Hex(landmarks) + "\n" +
                           sha256Hex(components) + "\n";
  return sha256Hex(std::string_view(text));
}

}  // namespace api
