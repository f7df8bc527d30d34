// Building glTF/GLB bytes by hand in tests (tests never include tinygltf): the
// GLB container, base64 data URIs and a small document builder over one buffer.
// Shared by the mesh and rig I/O tests in tests/core/io/.
#pragma once

#include <cstdint>
#include <cstring>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

namespace rigport_test::gltf {

using json = nlohmann::json;
using ByteVector = std::vector<std::uint8_t>;

constexpr int kFloat = 5126;
constexpr int kUnsignedByte = 5121;
constexpr int kUnsignedShort = 5123;
constexpr int kUnsignedInt = 5125;

inline ByteVector toBytes(std::string_view text) { return ByteVector(text.begin(), text.end()); }

inline std::string base64(const ByteVector& data) {
  static const char* table = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  for (std::size_t i = 0; i < data.size(); i += 3) {
    const std::uint32_t chunk = std::uint32_t(data[i]) << 16 | (i + 1 < data.size() ? std::uint32_t(data[i + 1]) << 8 : 0) |
                                (i + 2 < data.size() ? std::uint32_t(data[i + 2]) : 0);
    out += table[(chunk >> 18) & 63];
    out += table[(chunk >> 12) & 63];
    out += i + 1 < data.size() ? table[(chunk >> 6) & 63] : '=';
    out += i + 2 < data.size() ? table[chunk & 63] : '=';
  }
  return out;
}

inline void appendLe32(ByteVector& out, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) out.push_back(static_cast<std::uint8_t>(v >> (8 * i)));
}

// GLB container around JSON text and a BIN chunk (both padded to 4).
inline ByteVector makeGlbFromText(std::string text, ByteVector bin) {
  while (text.size() % 4 != 0) text += ' ';
  while (bin.size() % 4 != 0) bin.push_back(0);
  ByteVector out = {'g', 'l', 'T', 'F'};
  appendLe32(out, 2);
  appendLe32(out, static_cast<std::uint32_t>(12 + 8 + text.size() + (bin.empty() ? 0 : 8 + bin.size())));
  appendLe32(out, static_cast<std::uint32_t>(text.size()));
  appendLe32(out, 0x4E4F534A);
  out.insert(out.end(), text.begin(), text.end());
  if (!bin.empty()) {
    appendLe32(out, static_cast<std::uint32_t>(bin.size()));
    appendLe32(out, 0x004E4942);
    out.insert(out.end(), bin.begin(), bin.end());
  }
  return out;
}

// GLB container around a JSON document and a BIN chunk.
inline ByteVector makeGlb(const json& doc, ByteVector bin) { return makeGlbFromText(doc.dump(), std::move(bin)); }

// Splits a GLB into its JSON and BIN chunks (for mutation tests).
inline std::pair<json, ByteVector> splitGlb(const ByteVector& glb) {
  std::uint32_t json_length = 0;
  std::memcpy(&json_length, glb.data() + 12, 4);
  const json doc = json::parse(glb.begin() + 20, glb.begin() + 20 + json_length);
  ByteVector bin;
  if (20 + json_length + 8 <= glb.size()) bin.assign(glb.begin() + 20 + json_length + 8, glb.end());
  return {doc, bin};
}

// Builds small glTF documents by hand: bufferViews over one buffer, accessors,
// meshes and nodes; emitted as GLB or as .gltf text with a data: URI buffer.
class GltfBuilder {
 public:
  GltfBuilder() { doc_ = {{"asset", {{"version", "2.0"}}}}; }

  template <typename T>
  int view(const std::vector<T>& values, int stride = 0) {
    while (bin_.size() % 4 != 0) bin_.push_back(0);
    const auto* p = reinterpret_cast<const std::uint8_t*>(values.data());
    json v = {{"buffer", 0}, {"byteOffset", bin_.size()}, {"byteLength", values.size() * sizeof(T)}};
    if (stride) v["byteStride"] = stride;
    bin_.insert(bin_.end(), p, p + values.size() * sizeof(T));
    doc_["bufferViews"].push_back(v);
    return static_cast<int>(doc_["bufferViews"].size()) - 1;
  }

  int accessor(int view, int component_type, std::size_t count, const std::string& type, json extra = json::object()) {
    json a = {{"componentType", component_type}, {"count", count}, {"type", type}};
    if (view >= 0) a["bufferView"] = view;
    a.update(extra);
    doc_["accessors"].push_back(a);
    return static_cast<int>(doc_["accessors"].size()) - 1;
  }

  int positions(const std::vector<float>& xyz) { return accessor(view(xyz), kFloat, xyz.size() / 3, "VEC3"); }
  int indices(const std::vector<std::uint16_t>& idx) { return accessor(view(idx), kUnsignedShort, idx.size(), "SCALAR"); }

  int mesh(json primitives, const std::string& name = "") {
    json m = {{"primitives", primitives}};
    if (!name.empty()) m["name"] = name;
    doc_["meshes"].push_back(m);
    return static_cast<int>(doc_["meshes"].size()) - 1;
  }

  int node(json n) {
    doc_["nodes"].push_back(n);
    return static_cast<int>(doc_["nodes"].size()) - 1;
  }

  json& doc() { return doc_; }

  ByteVector glb() const {
    json d = doc_;
    if (!bin_.empty()) d["buffers"] = json::array({{{"byteLength", bin_.size()}}});
    return makeGlb(d, bin_);
  }

  ByteVector gltf() const {
    json d = doc_;
    if (!bin_.empty()) {
      d["buffers"] = json::array(
          {{{"byteLength", bin_.size()}, {"uri", "data:application/octet-stream;base64," + base64(bin_)}}});
    }
    return toBytes(d.dump());
  }

  const ByteVector& bin() const { return bin_; }

 private:
  json doc_;
  ByteVector bin_;
};

}  // namespace rigport_test::gltf
