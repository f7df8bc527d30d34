// glTF 2.0 / GLB reading and writing. This is the only translation unit that
// includes tiny_gltf.h: tinygltf types never leave this file, and tinygltf's
// err/warn strings become core::Error / report warnings right here.
//
// Reference: Khronos glTF 2.0 specification,
// https://registry.khronos.org/glTF/specs/2.0/glTF-2.0.html (sections
// "Accessors" incl. sparse accessors and data alignment, "Transformations",
// "Meshes" / primitive topology, "Skins", and "GLB File Format Specification").
//
// Safety: tinygltf 2.7 parses the JSON and copies buffers but does not check
// accessor or bufferView ranges, and has two unchecked reads of its own (the
// GLB BIN chunk header is bounds-checked without its 8 header bytes, and an
// embedded image's bufferView offset indexes the buffer unchecked). So the GLB
// container and image bufferViews are checked here before tinygltf sees the
// bytes, and every accessor read below is bounds-checked with overflow-safe
// arithmetic. Truncated or corrupt files give kParse, never a bad read.
#include <algorithm>
#include <array>
#include <bit>
#include <cctype>
#include <cmath>
#include <cstring>
#include <fstream>  // tinygltf uses std::ofstream even with TINYGLTF_NO_FS
#include <limits>
#include <map>
#include <optional>
#include <set>
#include <sstream>
#include <string>
#include <string_view>
#include <system_error>
#include <tuple>
#include <utility>
#include <vector>

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <Eigen/SVD>
#include <nlohmann/json.hpp>

#include "core/io/json_text.h"
#include "core/io/mesh_io.h"
#include "core/io/rig_io.h"

// tinygltf 2.7 uses nlohmann::json; TINYGLTF_NO_INCLUDE_JSON makes it use the
// one included above. No image decoding or writing (we never need pixels), no
// external images, and no built-in file system access: the only file access is
// through the callbacks below, which are confined to the glTF's directory.
#define TINYGLTF_IMPLEMENTATION
#define TINYGLTF_NO_STB_IMAGE
#define TINYGLTF_NO_STB_IMAGE_WRITE
#define TINYGLTF_NO_EXTERNAL_IMAGE
#define TINYGLTF_NO_INCLUDE_JSON
#define TINYGLTF_NO_FS
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wshadow"
#pragma GCC diagnostic ignored "-Wpedantic"
#pragma GCC diagnostic ignored "-Wunused-parameter"
#pragma GCC diagnostic ignored "-Wunused-function"
#pragma GCC diagnostic ignored "-Wunused-variable"
#pragma GCC diagnostic ignored "-Wsign-compare"
#pragma GCC diagnostic ignored "-Wmissing-field-initializers"
#pragma GCC diagnostic ignored "-Wimplicit-fallthrough"
#pragma GCC diagnostic ignored "-Wnon-virtual-dtor"
#include <tiny_gltf.h>
#pragma GCC diagnostic pop

namespace core {

// Declared in core/io/mesh_io.cpp (readMesh passes the .gltf file's directory).
Result<LoadedMesh> readGltfWithBaseDir(std::span<const std::uint8_t> bytes, const std::string& label, bool binary,
                                       const std::filesystem::path& base_dir);

namespace {

using Bytes = std::span<const std::uint8_t>;

// An accessor without a bufferView is all zeros (plus sparse overrides), so its
// count is not bounded by the file size; cap it so a crafted file cannot ask
// for an arbitrarily large allocation. 16M elements is far above any face rig.
constexpr std::size_t kMaxImplicitAccessorCount = std::size_t{1} << 24;

std::string quoted(const std::string& name) { return name.empty() ? std::string() : " '" + name + "'"; }

Error parseError(const std::string& label, const std::string& what) {
  return makeError(ErrorCode::kParse, label + ": " + what);
}

// tinygltf messages end with newlines and sometimes hold several lines.
std::string tidyMessage(std::string text) {
  while (!text.empty() && (text.back() == '\n' || text.back() == ' ' || text.back() == '.')) text.pop_back();
  std::replace(text.begin(), text.end(), '\n', ' ');
  return text;
}

std::uint32_t readLe32(const std::uint8_t* p) {
  return static_cast<std::uint32_t>(p[0]) | static_cast<std::uint32_t>(p[1]) << 8 |
         static_cast<std::uint32_t>(p[2]) << 16 | static_cast<std::uint32_t>(p[3]) << 24;
}

// ---------------------------------------------------------------------------
// Before tinygltf: GLB container and JSON checks

struct GlbLayout {
  std::size_t length = 0;      // total GLB length from the header (<= file size)
  std::string_view json_text;  // the JSON chunk
};

// Checks the 12-byte header and the chunk headers so that every range tinygltf
// will read lies inside the file (see the note at the top of this file).
Result<GlbLayout> checkGlbContainer(Bytes bytes, const std::string& label, std::vector<std::string>& warnings) {
  if (bytes.size() < 12) {
    return parseError(label, "truncated GLB: " + std::to_string(bytes.size()) + " bytes, the header alone needs 12");
  }
  if (std::memcmp(bytes.data(), "glTF", 4) != 0) return parseError(label, "not a binary glTF (no 'glTF' magic)");
  const std::uint32_t version = readLe32(bytes.data() + 4);
  if (version != 2) {
    return makeError(ErrorCode::kUnsupported,
                     label + ": GLB container version " + std::to_string(version) + " (only version 2 is supported)");
  }
  const std::size_t length = readLe32(bytes.data() + 8);
  if (length > bytes.size()) {
    return parseError(label, "truncated GLB: header declares " + std::to_string(length) + " bytes, file has " +
                                 std::to_string(bytes.size()));
  }
  if (length < bytes.size()) {
    warnings.push_back(std::to_string(bytes.size() - length) + " bytes after the end of the GLB were ignored");
  }
  if (length < 20) return parseError(label, "truncated GLB: no JSON chunk");
  const std::size_t json_length = readLe32(bytes.data() + 12);
  if (readLe32(bytes.data() + 16) != 0x4E4F534Au) return parseError(label, "GLB first chunk is not JSON");
  if (json_length == 0 || json_length > length - 20) {
    return parseError(label, "GLB JSON chunk of " + std::to_string(json_length) + " bytes does not fit in the " +
                                 std::to_string(length) + "-byte file");
  }
  const std::size_t bin_header = 20 + json_length;
  if (bin_header < length) {
    if (length - bin_header < 8) return parseError(label, "truncated GLB: incomplete BIN chunk header");
    const std::size_t bin_length = readLe32(bytes.data() + bin_header);
    if (bin_length > length - bin_header - 8) {
      return parseError(label, "GLB BIN chunk of " + std::to_string(bin_length) + " bytes does not fit in the " +
                                   std::to_string(length) + "-byte file (truncated?)");
    }
  }
  return GlbLayout{length, std::string_view(reinterpret_cast<const char*>(bytes.data()) + 20, json_length)};
}

std::size_t jsonUnsigned(const nlohmann::json& object, const char* key, std::size_t fallback) {
  const auto it = object.find(key);
  return it != object.end() && it->is_number_unsigned() ? it->get<std::size_t>() : fallback;
}

// Buffer URIs: only data: URIs (or, with a base directory, relative file names
// inside it) are accepted, so a glTF cannot make the service read arbitrary
// files. Embedded images: tinygltf indexes the buffer with their bufferView
// offset unchecked, so the range is checked here against the declared
// byteLength (tinygltf sizes every buffer to exactly its byteLength).
Status checkJsonBeforeTinygltf(std::string_view json_text, const std::string& label, bool allow_external) {
  auto parsed = parseJsonText(json_text, label, "glTF JSON");
  if (!parsed) return parsed.error();
  const nlohmann::json& doc = *parsed;
  if (!doc.is_object()) return parseError(label, "the glTF JSON is not an object");

  std::vector<std::size_t> buffer_lengths;
  if (const auto buffers = doc.find("buffers"); buffers != doc.end() && buffers->is_array()) {
    for (std::size_t i = 0; i < buffers->size(); ++i) {
      const nlohmann::json& buffer = (*buffers)[i];
      if (!buffer.is_object()) return parseError(label, "buffer " + std::to_string(i) + " is not an object");
      buffer_lengths.push_back(jsonUnsigned(buffer, "byteLength", 0));
      const auto uri = buffer.find("uri");
      if (uri == buffer.end() || !uri->is_string()) continue;
      const std::string text = uri->get<std::string>();
      if (text.rfind("data:", 0) == 0) continue;
      if (!allow_external) {
        return makeError(ErrorCode::kUnsupported,
                         label + ": buffer " + std::to_string(i) + " refers to the external file '" + text +
                             "'; only embedded buffers (GLB or data: URIs) can be read here");
      }
      if (text.empty() || text.front() == '/' || text.find("..") != std::string::npos ||
          text.find(':') != std::string::npos) {
        return makeError(ErrorCode::kUnsupported, label + ": buffer " + std::to_string(i) + " URI '" + text +
                                                      "' is not a relative file name inside the glTF's directory");
      }
    }
  }

  const auto views = doc.find("bufferViews");
  const auto images = doc.find("images");
  if (images == doc.end() || !images->is_array()) return Ok{};
  for (std::size_t i = 0; i < images->size(); ++i) {
    const nlohmann::json& image = (*images)[i];
    if (!image.is_object()) continue;  // tinygltf rejects it with its own message
    const auto view_it = image.find("bufferView");
    if (view_it == image.end() || !view_it->is_number_unsigned()) continue;
    const std::string what = "image " + std::to_string(i) + " ";
    const std::size_t view_index = view_it->get<std::size_t>();
    if (views == doc.end() || !views->is_array() || view_index >= views->size() || !(*views)[view_index].is_object()) {
      return parseError(label, what + "refers to a missing bufferView " + std::to_string(view_index));
    }
    const nlohmann::json& view = (*views)[view_index];
    const std::size_t buffer_index = jsonUnsigned(view, "buffer", std::numeric_limits<std::size_t>::max());
    if (buffer_index >= buffer_lengths.size()) {
      return parseError(label, what + "uses bufferView " + std::to_string(view_index) + " with a missing buffer");
    }
    const std::size_t offset = jsonUnsigned(view, "byteOffset", 0);
    const std::size_t length = jsonUnsigned(view, "byteLength", 0);
    const std::size_t buffer_length = buffer_lengths[buffer_index];
    if (buffer_length == 0 || offset > buffer_length || length > buffer_length - offset) {
      return parseError(label, what + "reads past the end of buffer " + std::to_string(buffer_index) + " (needs " +
                                   std::to_string(length) + " bytes at offset " + std::to_string(offset) +
                                   ", buffer has " + std::to_string(buffer_length) + ")");
    }
  }
  return Ok{};
}

// ---------------------------------------------------------------------------
// tinygltf callbacks

// We never decode pixels: accept every image as is.
bool skipImageDecoding(tinygltf::Image*, const int, std::string*, std::string*, int, int, const unsigned char*, int,
                       void*) {
  return true;
}

// File access for external buffers, confined to one directory. With no
// directory (reading from memory) nothing can be opened.
struct ConfinedFs {
  std::optional<std::filesystem::path> root;  // canonical directory, or nullopt
};

bool insideRoot(const ConfinedFs& fs, const std::string& file) {
  if (!fs.root) return false;
  std::error_code ec;
  const std::filesystem::path p = std::filesystem::weakly_canonical(file, ec);
  if (ec) return false;
  const auto [root_end, p_it] = std::mismatch(fs.root->begin(), fs.root->end(), p.begin(), p.end());
  return root_end == fs.root->end() && p_it != p.end();
}

bool confinedFileExists(const std::string& file, void* user) {
  const auto& fs = *static_cast<const ConfinedFs*>(user);
  std::error_code ec;
  return insideRoot(fs, file) && std::filesystem::is_regular_file(file, ec);
}

std::string confinedExpandPath(const std::string& file, void*) { return file; }

bool confinedReadFile(std::vector<unsigned char>* out, std::string* err, const std::string& file, void* user) {
  const auto& fs = *static_cast<const ConfinedFs*>(user);
  if (!insideRoot(fs, file)) {
    if (err) *err += "'" + file + "' is outside the glTF's directory";
    return false;
  }
  auto bytes = readFileBytes(file);
  if (!bytes) {
    if (err) *err += bytes.error().message;
    return false;
  }
  *out = std::move(*bytes);
  return true;
}

bool refuseWriteFile(std::string* err, const std::string&, const std::vector<unsigned char>&, void*) {
  if (err) *err += "rigport never writes through tinygltf's file callbacks";
  return false;
}

// Parses `bytes` into a tinygltf model. `base_dir` enables external buffers.
Result<tinygltf::Model> loadModel(Bytes bytes, const std::string& label, bool binary,
                                  const std::optional<std::filesystem::path>& base_dir,
                                  std::vector<std::string>& warnings) {
  if (bytes.size() > std::numeric_limits<std::uint32_t>::max()) {
    return makeError(ErrorCode::kUnsupported, label + ": glTF files of 4 GiB or more are not supported");
  }
  Bytes input = bytes;
  std::string_view json_text(reinterpret_cast<const char*>(bytes.data()), bytes.size());
  if (binary) {
    auto layout = checkGlbContainer(bytes, label, warnings);
    if (!layout) return layout.error();
    input = bytes.first(layout->length);
    json_text = layout->json_text;
  }
  if (auto ok = checkJsonBeforeTinygltf(json_text, label, base_dir.has_value()); !ok) return ok.error();

  ConfinedFs fs;
  std::string base;
  if (base_dir) {
    std::error_code ec;
    fs.root = std::filesystem::weakly_canonical(base_dir->empty() ? std::filesystem::path(".") : *base_dir, ec);
    if (ec) fs.root.reset();
    if (fs.root) base = fs.root->string();
  }
  tinygltf::TinyGLTF loader;
  loader.SetImageLoader(&skipImageDecoding, nullptr);
  loader.SetFsCallbacks(
      tinygltf::FsCallbacks{&confinedFileExists, &confinedExpandPath, &confinedReadFile, &refuseWriteFile, &fs});

  tinygltf::Model model;
  std::string err;
  std::string warn;
  bool ok = false;
  try {
    const auto size = static_cast<unsigned int>(input.size());
    ok = binary ? loader.LoadBinaryFromMemory(&model, &err, &warn, input.data(), size, base)
                : loader.LoadASCIIFromString(&model, &err, &warn, reinterpret_cast<const char*>(input.data()), size,
                                             base);
  } catch (const std::exception& e) {
    // tinygltf 2.7 can throw (e.g. std::out_of_range for an empty GLB buffer).
    return parseError(label, std::string("invalid glTF: ") + e.what());
  }
  if (!ok) return parseError(label, err.empty() ? "invalid glTF" : tidyMessage(err));
  if (!err.empty()) warnings.push_back("glTF: " + tidyMessage(err));
  if (!warn.empty()) warnings.push_back("glTF: " + tidyMessage(warn));
  return model;
}

// ---------------------------------------------------------------------------
// Accessor reading (bounds-checked; also for skins, morphs and animations)

int componentSize(int component_type) {
  switch (component_type) {
    case TINYGLTF_COMPONENT_TYPE_BYTE:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return 1;
    case TINYGLTF_COMPONENT_TYPE_SHORT:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: return 2;
    case TINYGLTF_COMPONENT_TYPE_INT:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT:
    case TINYGLTF_COMPONENT_TYPE_FLOAT: return 4;
    default: return 0;
  }
}

// Rows and columns of one element (vectors are one column).
std::pair<int, int> elementShape(int type) {
  switch (type) {
    case TINYGLTF_TYPE_SCALAR: return {1, 1};
    case TINYGLTF_TYPE_VEC2: return {2, 1};
    case TINYGLTF_TYPE_VEC3: return {3, 1};
    case TINYGLTF_TYPE_VEC4: return {4, 1};
    case TINYGLTF_TYPE_MAT2: return {2, 2};
    case TINYGLTF_TYPE_MAT3: return {3, 3};
    case TINYGLTF_TYPE_MAT4: return {4, 4};
    default: return {0, 0};
  }
}

// Components of one element (16 for MAT4).
int typeComponents(int type) { return elementShape(type).first * elementShape(type).second; }

// Byte layout of one element: matrix columns start on 4-byte boundaries (spec,
// "Data Alignment"), which only matters for 1- and 2-byte matrix components.
struct ElementLayout {
  int rows = 0;
  int columns = 0;
  std::size_t component_size = 0;
  std::size_t column_stride = 0;
  std::size_t size = 0;  // bytes per element, tightly packed
};

ElementLayout elementLayout(int type, int component_type) {
  const auto [rows, columns] = elementShape(type);
  ElementLayout layout;
  layout.rows = rows;
  layout.columns = columns;
  layout.component_size = static_cast<std::size_t>(componentSize(component_type));
  layout.column_stride = layout.component_size * static_cast<std::size_t>(rows);
  if (columns > 1) layout.column_stride = (layout.column_stride + 3) / 4 * 4;
  layout.size = layout.column_stride * static_cast<std::size_t>(columns);
  return layout;
}

double decodeComponent(const std::uint8_t* p, int component_type, bool normalized) {
  switch (component_type) {
    case TINYGLTF_COMPONENT_TYPE_BYTE: {
      const auto v = static_cast<std::int8_t>(p[0]);
      return normalized ? std::max(v / 127.0, -1.0) : v;
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return normalized ? p[0] / 255.0 : p[0];
    case TINYGLTF_COMPONENT_TYPE_SHORT: {
      const auto v = static_cast<std::int16_t>(static_cast<std::uint16_t>(p[0] | p[1] << 8));
      return normalized ? std::max(v / 32767.0, -1.0) : v;
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: {
      const auto v = static_cast<std::uint16_t>(p[0] | p[1] << 8);
      return normalized ? v / 65535.0 : v;
    }
    case TINYGLTF_COMPONENT_TYPE_INT: return static_cast<std::int32_t>(readLe32(p));
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: return readLe32(p);
    case TINYGLTF_COMPONENT_TYPE_FLOAT: return std::bit_cast<float>(readLe32(p));
    default: return 0.0;
  }
}

// Decoded accessor: `count` elements of `components` doubles, row-major
// (matrices column-major within the element, as in the file).
struct AccessorValues {
  std::size_t count = 0;
  int components = 0;
  std::vector<double> values;

  double at(std::size_t element, int component) const {
    return values[element * static_cast<std::size_t>(components) + static_cast<std::size_t>(component)];
  }
};

// Where decoded values go: component c of element i at
// data[i * element_stride + c * component_stride] (row-major values, or a
// block of rows of a column-major matrix).
struct DecodeDestination {
  double* data = nullptr;
  std::size_t element_stride = 0;
  std::size_t component_stride = 1;
};

void decodeElement(const std::uint8_t* src, const ElementLayout& layout, int component_type, bool normalized,
                   double* dst, std::size_t component_stride) {
  for (int c = 0; c < layout.columns; ++c) {
    for (int r = 0; r < layout.rows; ++r) {
      *dst = decodeComponent(src + static_cast<std::size_t>(c) * layout.column_stride +
                                 static_cast<std::size_t>(r) * layout.component_size,
                             component_type, normalized);
      dst += component_stride;
    }
  }
}

// Bytes needed by `count` elements of `element_size` at `stride`, or nullopt
// on overflow.
std::optional<std::size_t> spanBytes(std::size_t count, std::size_t stride, std::size_t element_size) {
  if (count == 0) return std::size_t{0};
  std::size_t bytes = 0;
  if (__builtin_mul_overflow(count - 1, stride, &bytes) || __builtin_add_overflow(bytes, element_size, &bytes)) {
    return std::nullopt;
  }
  return bytes;
}

// Returns the data of `view_index` after checking that [offset, offset+needed)
// lies inside the bufferView and the bufferView inside its buffer. `what`
// names the reader in messages ("accessor 3 (POSITION)").
Result<const std::uint8_t*> viewRange(const tinygltf::Model& model, int view_index, std::size_t offset,
                                      std::optional<std::size_t> needed, const std::string& what,
                                      const std::string& label) {
  if (view_index < 0 || static_cast<std::size_t>(view_index) >= model.bufferViews.size()) {
    return parseError(label, what + " refers to bufferView " + std::to_string(view_index) + " but the file has " +
                                 std::to_string(model.bufferViews.size()));
  }
  const tinygltf::BufferView& view = model.bufferViews[static_cast<std::size_t>(view_index)];
  if (view.buffer < 0 || static_cast<std::size_t>(view.buffer) >= model.buffers.size()) {
    return parseError(label, "bufferView " + std::to_string(view_index) + " (used by " + what +
                                 ") refers to buffer " + std::to_string(view.buffer) + " but the file has " +
                                 std::to_string(model.buffers.size()));
  }
  const std::vector<unsigned char>& data = model.buffers[static_cast<std::size_t>(view.buffer)].data;
  const std::string view_name = "bufferView " + std::to_string(view_index);
  if (!needed || offset > view.byteLength || *needed > view.byteLength - offset) {
    return parseError(label, what + " reads past the end of " + view_name + " (needs " +
                                 (needed ? std::to_string(*needed) : std::string("more than 2^64")) +
                                 " bytes at offset " + std::to_string(offset) + ", " + view_name + " has " +
                                 std::to_string(view.byteLength) + ")");
  }
  if (view.byteOffset > data.size() || view.byteLength > data.size() - view.byteOffset) {
    return parseError(label, what + " reads past the end of buffer " + std::to_string(view.buffer) + " (needs " +
                                 std::to_string(view.byteLength) + " bytes at offset " +
                                 std::to_string(view.byteOffset) + ", buffer has " + std::to_string(data.size()) +
                                 ")");
  }
  return data.data() + view.byteOffset + offset;
}

// An accessor checked against its bufferViews and buffers, ready to decode:
// every byte it will read is known to be inside the file, so a caller may
// size its destination by `count` before decoding.
struct CheckedAccessor {
  std::string what;  // "accessor 3 (POSITION)", for messages
  std::size_t count = 0;
  int components = 0;
  ElementLayout layout;
  int component_type = 0;
  bool normalized = false;
  const std::uint8_t* data = nullptr;  // nullptr: no bufferView, all zeros
  std::size_t stride = 0;
  // accessor.sparse, when present
  std::size_t sparse_count = 0;
  int sparse_index_type = 0;
  const std::uint8_t* sparse_indices = nullptr;
  const std::uint8_t* sparse_values = nullptr;
};

// Checks accessor `index` (any type, stride, normalisation, sparse). `role`
// says what it is for ("POSITION", "indices") in error messages.
Result<CheckedAccessor> checkAccessor(const tinygltf::Model& model, int index, const std::string& role,
                                      const std::string& label) {
  CheckedAccessor out;
  out.what = "accessor " + std::to_string(index) + " (" + role + ")";
  const std::string& what = out.what;
  if (index < 0 || static_cast<std::size_t>(index) >= model.accessors.size()) {
    return parseError(label, role + " refers to accessor " + std::to_string(index) + " but the file has " +
                                 std::to_string(model.accessors.size()));
  }
  const tinygltf::Accessor& accessor = model.accessors[static_cast<std::size_t>(index)];
  out.layout = elementLayout(accessor.type, accessor.componentType);
  if (out.layout.rows == 0) return parseError(label, what + " has an invalid type");
  if (out.layout.component_size == 0) {
    return parseError(label, what + " has unsupported componentType " + std::to_string(accessor.componentType));
  }
  out.count = accessor.count;
  out.components = out.layout.rows * out.layout.columns;
  out.component_type = accessor.componentType;
  out.normalized = accessor.normalized;
  if (accessor.bufferView < 0) {
    if (accessor.count > kMaxImplicitAccessorCount) {
      return parseError(label, what + " has no bufferView and claims " + std::to_string(accessor.count) +
                                   " elements (more than the " + std::to_string(kMaxImplicitAccessorCount) +
                                   " supported)");
    }
  } else {
    const tinygltf::BufferView* view = static_cast<std::size_t>(accessor.bufferView) < model.bufferViews.size()
                                           ? &model.bufferViews[static_cast<std::size_t>(accessor.bufferView)]
                                           : nullptr;
    out.stride = view && view->byteStride != 0 ? view->byteStride : out.layout.size;
    if (out.stride < out.layout.size) {
      return parseError(label, what + " has elements of " + std::to_string(out.layout.size) +
                                   " bytes but bufferView byteStride " + std::to_string(out.stride));
    }
    // This bounds count by the buffer size, so a destination sized by it is
    // at most a few times the file size.
    auto data = viewRange(model, accessor.bufferView, accessor.byteOffset,
                          spanBytes(accessor.count, out.stride, out.layout.size), what, label);
    if (!data) return data.error();
    out.data = *data;
  }
  if (!accessor.sparse.isSparse) return out;

  const auto& sparse = accessor.sparse;
  if (sparse.count < 0 || static_cast<std::size_t>(sparse.count) > accessor.count) {
    return parseError(label, what + " has a sparse count of " + std::to_string(sparse.count) + " for " +
                                 std::to_string(accessor.count) + " elements");
  }
  if (sparse.indices.byteOffset < 0 || sparse.values.byteOffset < 0) {
    return parseError(label, what + " has a negative sparse byteOffset");
  }
  out.sparse_count = static_cast<std::size_t>(sparse.count);
  out.sparse_index_type = sparse.indices.componentType;
  if (out.sparse_index_type != TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE &&
      out.sparse_index_type != TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT &&
      out.sparse_index_type != TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT) {
    return parseError(label, what + " has sparse indices of invalid componentType " +
                                 std::to_string(out.sparse_index_type));
  }
  const std::size_t index_size = static_cast<std::size_t>(componentSize(out.sparse_index_type));
  auto indices = viewRange(model, sparse.indices.bufferView, static_cast<std::size_t>(sparse.indices.byteOffset),
                           spanBytes(out.sparse_count, index_size, index_size), what + " sparse indices", label);
  if (!indices) return indices.error();
  auto values = viewRange(model, sparse.values.bufferView, static_cast<std::size_t>(sparse.values.byteOffset),
                          spanBytes(out.sparse_count, out.layout.size, out.layout.size), what + " sparse values",
                          label);
  if (!values) return values.error();
  out.sparse_indices = *indices;
  out.sparse_values = *values;
  return out;
}

// Decodes a checked accessor into `dst`, which has room for its count
// elements: the dense data (or zeros), then the sparse overrides.
Status decodeAccessor(const CheckedAccessor& a, DecodeDestination dst, const std::string& label) {
  const std::size_t components = static_cast<std::size_t>(a.components);
  if (a.data == nullptr) {
    for (std::size_t i = 0; i < a.count; ++i) {
      for (std::size_t c = 0; c < components; ++c) dst.data[i * dst.element_stride + c * dst.component_stride] = 0.0;
    }
  } else if (a.component_type == TINYGLTF_COMPONENT_TYPE_FLOAT) {
    // The common case (positions, normals, morph deltas, weights, keys),
    // without a component-type switch per value. Float components are 4-byte
    // aligned, so a matrix's columns follow each other without padding.
    for (std::size_t i = 0; i < a.count; ++i) {
      const std::uint8_t* src = a.data + i * a.stride;
      double* out = dst.data + i * dst.element_stride;
      for (std::size_t c = 0; c < components; ++c) {
        out[c * dst.component_stride] = std::bit_cast<float>(readLe32(src + 4 * c));
      }
    }
  } else {
    for (std::size_t i = 0; i < a.count; ++i) {
      decodeElement(a.data + i * a.stride, a.layout, a.component_type, a.normalized,
                    dst.data + i * dst.element_stride, dst.component_stride);
    }
  }
  const std::size_t index_size = static_cast<std::size_t>(componentSize(a.sparse_index_type));
  for (std::size_t i = 0; i < a.sparse_count; ++i) {
    const double index = decodeComponent(a.sparse_indices + i * index_size, a.sparse_index_type, false);
    if (index >= static_cast<double>(a.count)) {
      return parseError(label, a.what + " sparse index " + std::to_string(i) + " is " +
                                   std::to_string(static_cast<std::uint64_t>(index)) + " but the accessor has " +
                                   std::to_string(a.count) + " elements");
    }
    decodeElement(a.sparse_values + i * a.layout.size, a.layout, a.component_type, a.normalized,
                  dst.data + static_cast<std::size_t>(index) * dst.element_stride, dst.component_stride);
  }
  return Ok{};
}

// Reads accessor `index` (any type, stride, normalisation, sparse) as doubles.
// `role` says what it is for ("POSITION", "indices") in error messages.
Result<AccessorValues> readAccessor(const tinygltf::Model& model, int index, const std::string& role,
                                    const std::string& label) {
  auto checked = checkAccessor(model, index, role, label);
  if (!checked) return checked.error();
  AccessorValues out;
  out.count = checked->count;
  out.components = checked->components;
  out.values.resize(out.count * static_cast<std::size_t>(out.components));
  if (auto ok = decodeAccessor(*checked, {out.values.data(), static_cast<std::size_t>(out.components), 1}, label);
      !ok) {
    return ok.error();
  }
  return out;
}

// Reads a per-vertex attribute with the expected component count, decoded
// straight into a #count by `components` matrix.
template <typename Matrix>
Result<Matrix> readAttribute(const tinygltf::Model& model, int index, const std::string& role, int components,
                             const std::string& label) {
  auto checked = checkAccessor(model, index, role, label);
  if (!checked) return checked.error();
  if (checked->components != components) {
    return parseError(label, checked->what + " has " + std::to_string(checked->components) +
                                 " components per element, expected " + std::to_string(components));
  }
  Matrix values(static_cast<Eigen::Index>(checked->count), components);
  if (auto ok = decodeAccessor(*checked, {values.data(), 1, checked->count}, label); !ok) return ok.error();
  return values;
}

// ---------------------------------------------------------------------------
// Scene graph: which mesh, which node, which transform

// Node-local transform: `matrix` (column-major) or T * R * S.
Result<Eigen::Matrix4d> localTransform(const tinygltf::Node& node, int index, const std::string& label) {
  const std::string what = "node " + std::to_string(index);
  auto finite = [](const std::vector<double>& v) {
    return std::all_of(v.begin(), v.end(), [](double x) { return std::isfinite(x); });
  };
  if (!finite(node.matrix) || !finite(node.translation) || !finite(node.rotation) || !finite(node.scale)) {
    return parseError(label, what + " has a non-finite transform value");
  }
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  if (!node.matrix.empty()) {
    if (node.matrix.size() != 16) {
      return parseError(label, what + " matrix has " + std::to_string(node.matrix.size()) + " values, expected 16");
    }
    for (int i = 0; i < 16; ++i) m(i % 4, i / 4) = node.matrix[static_cast<std::size_t>(i)];
    return m;
  }
  if (!node.translation.empty() && node.translation.size() != 3) {
    return parseError(label, what + " translation has " + std::to_string(node.translation.size()) + " values");
  }
  if (!node.rotation.empty() && node.rotation.size() != 4) {
    return parseError(label, what + " rotation has " + std::to_string(node.rotation.size()) + " values");
  }
  if (!node.scale.empty() && node.scale.size() != 3) {
    return parseError(label, what + " scale has " + std::to_string(node.scale.size()) + " values");
  }
  Eigen::Affine3d t = Eigen::Affine3d::Identity();
  if (!node.translation.empty()) t.translate(Eigen::Vector3d(node.translation[0], node.translation[1], node.translation[2]));
  if (!node.rotation.empty()) {
    // glTF stores (x, y, z, w); Eigen's constructor takes (w, x, y, z).
    Eigen::Quaterniond q(node.rotation[3], node.rotation[0], node.rotation[1], node.rotation[2]);
    if (!(q.norm() > 0.0)) return parseError(label, what + " rotation is a zero quaternion");
    t.rotate(q.normalized());
  }
  if (!node.scale.empty()) t.scale(Eigen::Vector3d(node.scale[0], node.scale[1], node.scale[2]));
  return t.matrix();
}

// Parent of every node (-1 for roots), rejecting out-of-range children and
// nodes with two parents.
Result<std::vector<int>> nodeParents(const tinygltf::Model& model, const std::string& label) {
  const int n = static_cast<int>(model.nodes.size());
  std::vector<int> parents(model.nodes.size(), -1);
  for (int i = 0; i < n; ++i) {
    for (const int child : model.nodes[static_cast<std::size_t>(i)].children) {
      if (child < 0 || child >= n) {
        return parseError(label, "node " + std::to_string(i) + " lists child " + std::to_string(child) +
                                     " but the file has " + std::to_string(n) + " nodes");
      }
      if (child == i || parents[static_cast<std::size_t>(child)] != -1) {
        return parseError(label, "node " + std::to_string(child) + " has more than one parent");
      }
      parents[static_cast<std::size_t>(child)] = i;
    }
  }
  return parents;
}

// World transform of `node`: product of local transforms up to the root.
Result<Eigen::Matrix4d> worldTransform(const tinygltf::Model& model, int node, const std::string& label) {
  auto parents = nodeParents(model, label);
  if (!parents) return parents.error();
  Eigen::Matrix4d world = Eigen::Matrix4d::Identity();
  std::size_t steps = 0;
  for (int current = node; current != -1; current = (*parents)[static_cast<std::size_t>(current)]) {
    if (++steps > model.nodes.size()) return parseError(label, "the node hierarchy has a cycle");
    auto local = localTransform(model.nodes[static_cast<std::size_t>(current)], current, label);
    if (!local) return local.error();
    world = *local * world;
  }
  return world;
}

// Number of elements a primitive draws: its index count, else its vertex count
// (0 when the accessors are unusable; the real read reports those).
std::size_t primitiveElementCount(const tinygltf::Model& model, const tinygltf::Primitive& primitive) {
  auto count_of = [&](int accessor) -> std::size_t {
    return accessor >= 0 && static_cast<std::size_t>(accessor) < model.accessors.size()
               ? model.accessors[static_cast<std::size_t>(accessor)].count
               : 0;
  };
  if (primitive.indices >= 0) return count_of(primitive.indices);
  const auto position = primitive.attributes.find("POSITION");
  return position == primitive.attributes.end() ? 0 : count_of(position->second);
}

std::size_t primitiveTriangleCount(const tinygltf::Model& model, const tinygltf::Primitive& primitive) {
  const std::size_t n = primitiveElementCount(model, primitive);
  switch (primitive.mode) {
    case TINYGLTF_MODE_TRIANGLES: return n / 3;
    case TINYGLTF_MODE_TRIANGLE_STRIP:
    case TINYGLTF_MODE_TRIANGLE_FAN: return n >= 3 ? n - 2 : 0;
    default: return 0;
  }
}

std::size_t meshTriangleCount(const tinygltf::Model& model, const tinygltf::Mesh& mesh) {
  std::size_t total = 0;
  for (const auto& primitive : mesh.primitives) total += primitiveTriangleCount(model, primitive);
  return total;
}

struct MeshChoice {
  int mesh = -1;
  int node = -1;  // first node instancing it, -1 if none
  bool skinned = false;
  std::string description;  // for MeshReadReport::chosen_mesh
};

// First mesh used by a skinned node (the rig), else the mesh with most
// triangles (ties: lowest index).
Result<MeshChoice> chooseMesh(const tinygltf::Model& model, const std::string& label) {
  if (model.meshes.empty()) return makeError(ErrorCode::kInvalidMesh, label + ": the file contains no mesh");
  for (std::size_t i = 0; i < model.nodes.size(); ++i) {
    const int mesh = model.nodes[i].mesh;
    if (mesh >= 0 && static_cast<std::size_t>(mesh) >= model.meshes.size()) {
      return parseError(label, "node " + std::to_string(i) + " refers to mesh " + std::to_string(mesh) +
                                   " but the file has " + std::to_string(model.meshes.size()));
    }
  }
  MeshChoice choice;
  std::string reason;
  for (std::size_t i = 0; i < model.nodes.size() && choice.mesh < 0; ++i) {
    if (model.nodes[i].mesh >= 0 && model.nodes[i].skin >= 0) {
      choice.mesh = model.nodes[i].mesh;
      choice.node = static_cast<int>(i);
      choice.skinned = true;
      reason = "first skinned mesh";
    }
  }
  if (choice.mesh < 0) {
    std::size_t best = 0;
    choice.mesh = 0;
    for (std::size_t m = 0; m < model.meshes.size(); ++m) {
      const std::size_t triangles = meshTriangleCount(model, model.meshes[m]);
      if (triangles > best) {
        best = triangles;
        choice.mesh = static_cast<int>(m);
      }
    }
    if (model.meshes.size() == 1) {
      reason = "the only mesh";
    } else if (best == 0) {
      reason = "no mesh has triangles; first of " + std::to_string(model.meshes.size()) + " meshes";
    } else {
      reason = "most triangles (" + std::to_string(best) + ") of " + std::to_string(model.meshes.size()) + " meshes";
    }
    for (std::size_t i = 0; i < model.nodes.size() && choice.node < 0; ++i) {
      if (model.nodes[i].mesh == choice.mesh) choice.node = static_cast<int>(i);
    }
  }
  const tinygltf::Mesh& mesh = model.meshes[static_cast<std::size_t>(choice.mesh)];
  choice.description = "mesh " + std::to_string(choice.mesh) + quoted(mesh.name);
  if (choice.node >= 0) {
    choice.description += " on node " + std::to_string(choice.node) +
                          quoted(model.nodes[static_cast<std::size_t>(choice.node)].name);
  } else {
    choice.description += " (used by no node)";
  }
  choice.description += " (" + reason + ")";
  return choice;
}

// ---------------------------------------------------------------------------
// Primitive -> core::Mesh

const char* modeName(int mode) {
  switch (mode) {
    case TINYGLTF_MODE_POINTS: return "POINTS";
    case TINYGLTF_MODE_LINE: return "LINES";
    case TINYGLTF_MODE_LINE_LOOP: return "LINE_LOOP";
    case TINYGLTF_MODE_LINE_STRIP: return "LINE_STRIP";
    case TINYGLTF_MODE_TRIANGLES: return "TRIANGLES";
    case TINYGLTF_MODE_TRIANGLE_STRIP: return "TRIANGLE_STRIP";
    case TINYGLTF_MODE_TRIANGLE_FAN: return "TRIANGLE_FAN";
    default: return "unknown";
  }
}

bool isTriangleMode(int mode) {
  return mode == TINYGLTF_MODE_TRIANGLES || mode == TINYGLTF_MODE_TRIANGLE_STRIP ||
         mode == TINYGLTF_MODE_TRIANGLE_FAN;
}

// One primitive's vertex data, before merging.
struct PrimitiveData {
  Eigen::MatrixX3d positions;
  Eigen::MatrixX3d normals;  // 0 rows when the primitive has none
  Eigen::MatrixX2d uvs;      // 0 rows when the primitive has none
  std::vector<std::array<std::int64_t, 3>> triangles;  // primitive-local vertex indices
};

// Expands TRIANGLES / TRIANGLE_STRIP / TRIANGLE_FAN element lists (spec,
// "Primitive Topology") into triangles. `elements` are vertex indices in drawing order.
Result<std::vector<std::array<std::int64_t, 3>>> assembleTriangles(const std::vector<std::int64_t>& elements, int mode,
                                                                   const std::string& what,
                                                                   const std::string& label) {
  std::vector<std::array<std::int64_t, 3>> triangles;
  const std::size_t n = elements.size();
  if (mode == TINYGLTF_MODE_TRIANGLES) {
    if (n % 3 != 0) {
      return parseError(label, what + " draws TRIANGLES from " + std::to_string(n) +
                                   " elements, which is not a multiple of 3");
    }
    triangles.reserve(n / 3);
    for (std::size_t i = 0; i + 2 < n; i += 3) triangles.push_back({elements[i], elements[i + 1], elements[i + 2]});
  } else if (mode == TINYGLTF_MODE_TRIANGLE_STRIP) {
    // Odd triangles swap their last two vertices to keep a consistent winding.
    for (std::size_t i = 0; i + 2 < n; ++i) {
      if (i % 2 == 0) {
        triangles.push_back({elements[i], elements[i + 1], elements[i + 2]});
      } else {
        triangles.push_back({elements[i], elements[i + 2], elements[i + 1]});
      }
    }
  } else {  // TRIANGLE_FAN
    for (std::size_t i = 0; i + 2 < n; ++i) triangles.push_back({elements[i + 1], elements[i + 2], elements[0]});
  }
  return triangles;
}

Result<PrimitiveData> readPrimitive(const tinygltf::Model& model, const tinygltf::Primitive& primitive,
                                    const std::string& what, bool want_triangles, const std::string& label) {
  PrimitiveData out;
  const auto position_it = primitive.attributes.find("POSITION");
  if (position_it == primitive.attributes.end()) return parseError(label, what + " has no POSITION attribute");
  auto positions = readAttribute<Eigen::MatrixX3d>(model, position_it->second, "POSITION", 3, label);
  if (!positions) return positions.error();
  out.positions = std::move(*positions);
  const auto nv = static_cast<std::size_t>(out.positions.rows());

  auto read_optional = [&]<typename Matrix>(const char* name, int components, Matrix& target) -> Status {
    const auto it = primitive.attributes.find(name);
    if (it == primitive.attributes.end()) return Ok{};
    auto values = readAttribute<Matrix>(model, it->second, name, components, label);
    if (!values) return values.error();
    if (static_cast<std::size_t>(values->rows()) != nv) {
      return parseError(label, what + " " + name + " has " + std::to_string(values->rows()) +
                                   " elements but POSITION has " + std::to_string(nv));
    }
    target = std::move(*values);
    return Ok{};
  };
  if (auto ok = read_optional("NORMAL", 3, out.normals); !ok) return ok.error();
  if (auto ok = read_optional("TEXCOORD_0", 2, out.uvs); !ok) return ok.error();
  if (!want_triangles) return out;

  // Element list: the indices, or consecutive vertices for a non-indexed primitive.
  std::vector<std::int64_t> elements;
  if (primitive.indices >= 0) {
    auto indices = readAccessor(model, primitive.indices, "indices", label);
    if (!indices) return indices.error();
    if (indices->components != 1) return parseError(label, what + " indices accessor is not SCALAR");
    elements.resize(indices->count);
    for (std::size_t i = 0; i < indices->count; ++i) {
      const double index = indices->values[i];
      // Anything outside [0, nv) is caught per triangle below; clamp to keep
      // the conversion defined.
      elements[i] = index >= 0.0 && index < 9.0e15 ? static_cast<std::int64_t>(index) : -1;
    }
  } else {
    elements.resize(nv);
    for (std::size_t i = 0; i < nv; ++i) elements[i] = static_cast<std::int64_t>(i);
  }
  auto triangles = assembleTriangles(elements, primitive.mode, what, label);
  if (!triangles) return triangles.error();
  out.triangles = std::move(*triangles);
  return out;
}

// Positions by the affine part of `world`, normals by its inverse transpose
// (not renormalised here); a mirroring transform flips the winding to keep faces front.
Status applyTransform(const Eigen::Matrix4d& world, const std::string& label, Mesh& mesh,
                      std::vector<std::string>& warnings) {
  if (world.isIdentity(0.0)) return Ok{};
  const Eigen::Matrix3d linear = world.topLeftCorner<3, 3>();
  const Eigen::Vector3d translation = world.topRightCorner<3, 1>();
  const double det = linear.determinant();
  if (!(std::abs(det) > 0.0) || !std::isfinite(det)) {
    return makeError(ErrorCode::kInvalidMesh, label + ": the node transform of the mesh is singular (zero scale)");
  }
  if (world.row(3) != Eigen::RowVector4d(0, 0, 0, 1)) {
    warnings.push_back("the node transform has a projective row; it was ignored");
  }
  mesh.positions = ((mesh.positions * linear.transpose()).rowwise() + translation.transpose()).eval();
  if (mesh.normals.rows() > 0) {
    const Eigen::Matrix3d normal_matrix = linear.inverse().transpose();
    mesh.normals = (mesh.normals * normal_matrix.transpose()).eval();  // renormalised by the caller
  }
  if (det < 0.0) mesh.triangles.col(1).swap(mesh.triangles.col(2));
  return Ok{};
}

// Triangles when any primitive has them; a POINTS-only mesh is a point cloud.
// Returns whether the mesh has triangles.
Result<bool> checkPrimitiveModes(const tinygltf::Mesh& gmesh, const std::string& mesh_name, const std::string& label) {
  if (gmesh.primitives.empty()) return makeError(ErrorCode::kInvalidMesh, label + ": " + mesh_name + " has no primitives");
  const bool has_triangles =
      std::any_of(gmesh.primitives.begin(), gmesh.primitives.end(), [](const auto& p) { return isTriangleMode(p.mode); });
  for (std::size_t p = 0; p < gmesh.primitives.size(); ++p) {
    const int mode = gmesh.primitives[p].mode;
    const std::string what = mesh_name + " primitive " + std::to_string(p);
    if (mode < TINYGLTF_MODE_POINTS || mode > TINYGLTF_MODE_TRIANGLE_FAN) {
      return parseError(label, what + " has invalid mode " + std::to_string(mode));
    }
    if (isTriangleMode(mode) || (!has_triangles && mode == TINYGLTF_MODE_POINTS)) continue;
    return makeError(ErrorCode::kUnsupported, label + ": " + what + " uses mode " + modeName(mode) +
                                                  (has_triangles ? " beside triangles" : "") +
                                                  "; only triangle meshes and point clouds are supported");
  }
  return has_triangles;
}

// Reads every primitive and checks its indices; an out-of-range index names
// the triangle by its index in the merged mesh.
Result<std::vector<PrimitiveData>> readPrimitives(const tinygltf::Model& model, const tinygltf::Mesh& gmesh,
                                                  const std::string& mesh_name, bool has_triangles,
                                                  const std::string& label) {
  std::vector<PrimitiveData> parts;
  std::size_t total_vertices = 0;
  std::size_t total_triangles = 0;
  for (std::size_t p = 0; p < gmesh.primitives.size(); ++p) {
    const std::string what = mesh_name + " primitive " + std::to_string(p);
    auto part = readPrimitive(model, gmesh.primitives[p], what, has_triangles, label);
    if (!part) return part.error();
    const auto nv = static_cast<std::int64_t>(part->positions.rows());
    for (std::size_t t = 0; t < part->triangles.size(); ++t) {
      for (const std::int64_t index : part->triangles[t]) {
        if (index < 0 || index >= nv) {
          return makeError(ErrorCode::kInvalidMesh,
                           label + ": triangle " + std::to_string(total_triangles + t) + " (" + what +
                               ") refers to vertex " + (index < 0 ? std::string("<invalid>") : std::to_string(index)) +
                               " but the primitive has " + std::to_string(nv) + " vertices");
        }
      }
    }
    total_vertices += static_cast<std::size_t>(nv);
    total_triangles += part->triangles.size();
    if (total_vertices > static_cast<std::size_t>(std::numeric_limits<int>::max()) ||
        total_triangles > static_cast<std::size_t>(std::numeric_limits<int>::max())) {
      return makeError(ErrorCode::kUnsupported, label + ": " + mesh_name + " is too large for 32-bit indices");
    }
    parts.push_back(std::move(*part));
  }
  return parts;
}

bool hasNormals(const PrimitiveData& p) { return p.normals.rows() > 0; }
bool hasUvs(const PrimitiveData& p) { return p.uvs.rows() > 0; }

// Concatenates the primitives (vertex offsets added to their triangles).
// Normals missing on some primitives are left zero (filled later); UVs are
// kept only when every primitive has them.
Mesh mergePrimitives(const std::vector<PrimitiveData>& parts, const std::string& mesh_name, MeshReadReport& report) {
  const bool any_normals = std::any_of(parts.begin(), parts.end(), hasNormals);
  const bool all_uvs = std::all_of(parts.begin(), parts.end(), hasUvs);
  if (!all_uvs && std::any_of(parts.begin(), parts.end(), hasUvs)) {
    report.warnings.push_back("TEXCOORD_0 is missing on some primitives of " + mesh_name + "; UVs dropped");
  }
  Eigen::Index nv_total = 0;
  Eigen::Index nf_total = 0;
  for (const PrimitiveData& part : parts) {
    nv_total += part.positions.rows();
    nf_total += static_cast<Eigen::Index>(part.triangles.size());
  }
  Mesh mesh;
  mesh.positions.resize(nv_total, 3);
  mesh.triangles.resize(nf_total, 3);
  if (any_normals) mesh.normals = Eigen::MatrixX3d::Zero(nv_total, 3);
  if (all_uvs) mesh.uvs.resize(nv_total, 2);
  Eigen::Index v0 = 0;
  Eigen::Index t0 = 0;
  for (const PrimitiveData& part : parts) {
    const Eigen::Index nv = part.positions.rows();
    mesh.positions.middleRows(v0, nv) = part.positions;
    if (hasNormals(part)) mesh.normals.middleRows(v0, nv) = part.normals;
    if (all_uvs) mesh.uvs.middleRows(v0, nv) = part.uvs;
    for (const auto& tri : part.triangles) {
      for (int k = 0; k < 3; ++k) mesh.triangles(t0, k) = static_cast<int>(tri[static_cast<std::size_t>(k)] + v0);
      ++t0;
    }
    v0 += nv;
  }
  return mesh;
}

// Moves the mesh into world space with the node that instances it. glTF spec
// ("Skins"): a skinned mesh's node transform is ignored (its joints place it),
// so a skinned mesh stays in the bind-pose space its inverse bind matrices use.
Status placeMesh(const tinygltf::Model& model, const MeshChoice& choice, const std::string& label, Mesh& mesh,
                 MeshReadReport& report) {
  if (choice.node < 0) return Ok{};
  auto world = worldTransform(model, choice.node, label);
  if (!world) return world.error();
  if (!choice.skinned) return applyTransform(*world, label, mesh, report.warnings);
  if (!world->isIdentity(1e-12)) {
    report.warnings.push_back("node " + std::to_string(choice.node) +
                              " transform ignored: glTF places skinned meshes by their joints");
  }
  return Ok{};
}

// Unit normals whatever the file or the transform did to their length, and
// area-weighted ones (computed in world space) where the file has none.
void finishNormals(const std::vector<PrimitiveData>& parts, const std::string& mesh_name, Mesh& mesh,
                   MeshReadReport& report) {
  for (Eigen::Index v = 0; v < mesh.normals.rows(); ++v) {
    const double len = mesh.normals.row(v).norm();
    if (len > 0.0) mesh.normals.row(v) /= len;
  }
  if (report.point_cloud || std::all_of(parts.begin(), parts.end(), hasNormals)) return;
  const Eigen::MatrixX3d computed = computeSeamlessVertexNormals(mesh.positions, mesh.triangles);
  report.normals_computed = true;
  if (mesh.normals.rows() == 0) {
    mesh.normals = computed;
    return;
  }
  Eigen::Index v0 = 0;
  for (const PrimitiveData& part : parts) {
    const Eigen::Index nv = part.positions.rows();
    if (!hasNormals(part)) mesh.normals.middleRows(v0, nv) = computed.middleRows(v0, nv);
    v0 += nv;
  }
  report.warnings.push_back("NORMAL is missing on some primitives of " + mesh_name + "; computed there");
}

// The chosen glTF mesh as one core::Mesh: all its primitives merged, placed
// by its node, validated.
Result<LoadedMesh> buildMesh(const tinygltf::Model& model, const MeshChoice& choice, const std::string& label,
                             LoadedMesh loaded) {
  MeshReadReport& report = loaded.report;
  const tinygltf::Mesh& gmesh = model.meshes[static_cast<std::size_t>(choice.mesh)];
  const std::string mesh_name = "mesh " + std::to_string(choice.mesh);

  auto has_triangles = checkPrimitiveModes(gmesh, mesh_name, label);
  if (!has_triangles) return has_triangles.error();
  auto parts = readPrimitives(model, gmesh, mesh_name, *has_triangles, label);
  if (!parts) return parts.error();
  loaded.mesh = mergePrimitives(*parts, mesh_name, report);
  Mesh& mesh = loaded.mesh;
  if (auto ok = placeMesh(model, choice, label, mesh, report); !ok) return ok.error();
  if (auto ok = validateMesh(mesh, label); !ok) return ok.error();
  report.point_cloud = mesh.triangleCount() == 0;
  finishNormals(*parts, mesh_name, mesh, report);

  report.degenerate_triangles = countDegenerateTriangles(mesh);
  return loaded;
}

// Required extensions that change how geometry is stored cannot be ignored.
Status checkRequiredExtensions(const tinygltf::Model& model, const std::string& label,
                               std::vector<std::string>& warnings) {
  for (const std::string& ext : model.extensionsRequired) {
    if (ext == "KHR_mesh_quantization") continue;  // plain accessors: handled by readAccessor
    if (ext == "KHR_draco_mesh_compression" || ext == "EXT_meshopt_compression") {
      return makeError(ErrorCode::kUnsupported, label + ": requires the " + ext +
                                                    " extension (compressed geometry), which is not supported");
    }
    warnings.push_back("required extension " + ext + " is not supported; geometry was read without it");
  }
  return Ok{};
}

// The parsed file and the mesh chosen from it: the common start of readGltf
// and readRig.
struct ParsedGltf {
  tinygltf::Model model;
  MeshChoice choice;
};

Result<ParsedGltf> parseGltf(Bytes bytes, const std::string& label, bool binary,
                             const std::optional<std::filesystem::path>& base_dir, MeshReadReport& report) {
  report.format = binary ? MeshFormat::kGlb : MeshFormat::kGltf;
  auto model = loadModel(bytes, label, binary, base_dir, report.warnings);
  if (!model) return model.error();
  if (auto ok = checkRequiredExtensions(*model, label, report.warnings); !ok) return ok.error();
  report.meshes_in_file = static_cast<int>(model->meshes.size());
  auto choice = chooseMesh(*model, label);
  if (!choice) return choice.error();
  report.chosen_mesh = choice->description;
  return ParsedGltf{std::move(*model), std::move(*choice)};
}

// ---------------------------------------------------------------------------
// Rig reading: nodes, skin and weights, morph targets, animations and vertex
// attributes of the mesh chosen above (after buildMesh has read and checked
// its primitives).

// Weight rows further than this from a sum of 1 are reported as renormalised
// (every non-empty row is divided by its sum anyway).
constexpr double kWeightSumTolerance = 1e-5;

// Closest translation * rotation * scale to a node matrix (spec,
// "Transformations"). `exact` is false when the matrix has shear or a
// projective row, which TRS cannot hold.
struct Trs {
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
  Eigen::Vector3d scale = Eigen::Vector3d::Ones();
  bool exact = true;
};

Trs decomposeTrs(const Eigen::Matrix4d& m) {
  Trs trs;
  trs.translation = m.topRightCorner<3, 1>();
  const Eigen::Matrix3d linear = m.topLeftCorner<3, 3>();
  for (int i = 0; i < 3; ++i) trs.scale(i) = linear.col(i).norm();
  if (linear.determinant() < 0.0) trs.scale(0) = -trs.scale(0);  // a mirror is one negative scale
  Eigen::Matrix3d unscaled = Eigen::Matrix3d::Zero();
  for (int i = 0; i < 3; ++i) {
    if (trs.scale(i) != 0.0) unscaled.col(i) = linear.col(i) / trs.scale(i);
  }
  // Closest rotation to the unscaled columns (polar decomposition by SVD).
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(unscaled, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d u = svd.matrixU();
  Eigen::Matrix3d rotation = u * svd.matrixV().transpose();
  if (rotation.determinant() < 0.0) {
    u.col(2) = -u.col(2);
    rotation = u * svd.matrixV().transpose();
  }
  trs.rotation = Eigen::Quaterniond(rotation).normalized();
  const double tolerance = 1e-6 * std::max(1.0, linear.cwiseAbs().maxCoeff());
  trs.exact = (rotation * trs.scale.asDiagonal() - linear).cwiseAbs().maxCoeff() <= tolerance &&
              (m.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).cwiseAbs().maxCoeff() <= 1e-12;
  return trs;
}

// Every node with its parent and local TRS (a `matrix` is decomposed).
Result<std::vector<Node>> readNodes(const tinygltf::Model& model, const std::string& label,
                                    std::vector<std::string>& warnings) {
  auto parents = nodeParents(model, label);
  if (!parents) return parents.error();
  const std::size_t n = model.nodes.size();
  std::vector<Node> nodes(n);
  for (std::size_t i = 0; i < n; ++i) {
    std::size_t steps = 0;
    for (int p = (*parents)[i]; p != -1; p = (*parents)[static_cast<std::size_t>(p)]) {
      if (++steps > n) return parseError(label, "the node hierarchy has a cycle through node " + std::to_string(i));
    }
    const tinygltf::Node& gnode = model.nodes[i];
    auto local = localTransform(gnode, static_cast<int>(i), label);  // checks sizes and finiteness
    if (!local) return local.error();
    Node& node = nodes[i];
    node.name = gnode.name;
    node.parent = (*parents)[i];
    if (!gnode.matrix.empty()) {
      const Trs trs = decomposeTrs(*local);
      node.translation = trs.translation;
      node.rotation = trs.rotation;
      node.scale = trs.scale;
      if (!trs.exact) {
        warnings.push_back("node " + std::to_string(i) + quoted(gnode.name) +
                           " matrix has shear or a projective row; the closest translation/rotation/scale was kept");
      }
      continue;
    }
    const auto& t = gnode.translation;
    const auto& r = gnode.rotation;
    const auto& s = gnode.scale;
    if (!t.empty()) node.translation = Eigen::Vector3d(t[0], t[1], t[2]);
    if (!r.empty()) node.rotation = Eigen::Quaterniond(r[3], r[0], r[1], r[2]).normalized();
    if (!s.empty()) node.scale = Eigen::Vector3d(s[0], s[1], s[2]);
  }
  return nodes;
}

std::string jointName(const tinygltf::Model& model, const std::vector<int>& joints, std::size_t j) {
  const int node = joints[j];
  return "joint " + std::to_string(j) + " (node " + std::to_string(node) +
         quoted(model.nodes[static_cast<std::size_t>(node)].name) + ")";
}

Status readInverseBinds(const tinygltf::Model& model, const tinygltf::Skin& gskin, const std::string& what,
                        const std::string& label, std::vector<std::string>& warnings, Skin& skin) {
  const std::size_t count = skin.joints.size();
  skin.inverse_bind.assign(count, Eigen::Matrix4d::Identity());  // spec: identity when absent
  if (gskin.inverseBindMatrices < 0) return Ok{};
  auto ibm = readAccessor(model, gskin.inverseBindMatrices, what + " inverseBindMatrices", label);
  if (!ibm) return ibm.error();
  if (ibm->components != 16) return parseError(label, what + " inverseBindMatrices accessor is not MAT4");
  if (ibm->count < count) {
    return parseError(label, what + " has " + std::to_string(count) + " joints but " + std::to_string(ibm->count) +
                                 " inverse bind matrices");
  }
  if (ibm->count > count) {
    warnings.push_back(what + " has " + std::to_string(ibm->count - count) +
                       " inverse bind matrices beyond its joints");
  }
  for (std::size_t j = 0; j < count; ++j) {
    Eigen::Matrix4d& m = skin.inverse_bind[j];
    for (int c = 0; c < 4; ++c) {
      for (int r = 0; r < 4; ++r) m(r, c) = ibm->at(j, c * 4 + r);  // column-major in the file
    }
    const std::string joint = what + " " + jointName(model, skin.joints, j);
    if (!m.allFinite()) {
      return makeError(ErrorCode::kInvalidMesh, label + ": " + joint + " inverse bind matrix is not finite");
    }
    if ((m.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).cwiseAbs().maxCoeff() > 1e-6) {
      return makeError(ErrorCode::kInvalidMesh,
                       label + ": " + joint + " inverse bind matrix bottom row is not 0 0 0 1 (not affine)");
    }
    m.row(3) = Eigen::RowVector4d(0, 0, 0, 1);
  }
  return Ok{};
}

Result<Skin> readSkin(const tinygltf::Model& model, int index, const std::string& label,
                      std::vector<std::string>& warnings) {
  if (index < 0 || static_cast<std::size_t>(index) >= model.skins.size()) {
    return parseError(label, "the mesh node uses skin " + std::to_string(index) + " but the file has " +
                                 std::to_string(model.skins.size()));
  }
  const tinygltf::Skin& gskin = model.skins[static_cast<std::size_t>(index)];
  const std::string what = "skin " + std::to_string(index) + quoted(gskin.name);
  if (gskin.joints.empty()) return parseError(label, what + " has no joints");
  const std::size_t node_count = model.nodes.size();
  std::vector<char> used(node_count, 0);
  for (std::size_t j = 0; j < gskin.joints.size(); ++j) {
    const int node = gskin.joints[j];
    if (node < 0 || static_cast<std::size_t>(node) >= node_count) {
      return parseError(label, what + " joint " + std::to_string(j) + " refers to node " + std::to_string(node) +
                                   " but the file has " + std::to_string(node_count) + " nodes");
    }
    if (used[static_cast<std::size_t>(node)]) {
      return parseError(label, what + " joint " + std::to_string(j) + " repeats node " + std::to_string(node));
    }
    used[static_cast<std::size_t>(node)] = 1;
  }
  if (gskin.skeleton >= 0 && static_cast<std::size_t>(gskin.skeleton) >= node_count) {
    return parseError(label, what + " skeleton refers to node " + std::to_string(gskin.skeleton) +
                                 " but the file has " + std::to_string(node_count) + " nodes");
  }
  Skin skin;
  skin.name = gskin.name;
  skin.joints = gskin.joints;
  skin.skeleton = gskin.skeleton >= 0 ? gskin.skeleton : -1;
  if (auto ok = readInverseBinds(model, gskin, what, label, warnings, skin); !ok) return ok.error();
  return skin;
}

// Rows of the merged mesh that come from each primitive (mergePrimitives order).
struct PrimitiveRange {
  Eigen::Index offset = 0;
  Eigen::Index count = 0;
};

std::vector<PrimitiveRange> primitiveRanges(const tinygltf::Model& model, const tinygltf::Mesh& gmesh) {
  std::vector<PrimitiveRange> ranges;
  Eigen::Index offset = 0;
  for (const tinygltf::Primitive& primitive : gmesh.primitives) {
    const int position = primitive.attributes.at("POSITION");  // buildMesh has read it
    const auto count = static_cast<Eigen::Index>(model.accessors[static_cast<std::size_t>(position)].count);
    ranges.push_back({offset, count});
    offset += count;
  }
  return ranges;
}

Eigen::Index vertexTotal(const std::vector<PrimitiveRange>& ranges) {
  return ranges.empty() ? 0 : ranges.back().offset + ranges.back().count;
}

// Accessor of attribute `name` in each primitive, or in its morph target
// `target` (-1: the primitive's own attributes); -1 where absent.
std::vector<int> attributeAccessors(const tinygltf::Mesh& gmesh, const std::string& name, int target = -1) {
  std::vector<int> accessors;
  for (const tinygltf::Primitive& primitive : gmesh.primitives) {
    const std::map<std::string, int>& attributes =
        target < 0 ? primitive.attributes : primitive.targets[static_cast<std::size_t>(target)];
    const auto it = attributes.find(name);
    accessors.push_back(it == attributes.end() ? -1 : it->second);
  }
  return accessors;
}

bool presentInAll(const std::vector<int>& accessors) {
  return std::all_of(accessors.begin(), accessors.end(), [](int a) { return a >= 0; });
}
bool presentInAny(const std::vector<int>& accessors) {
  return std::any_of(accessors.begin(), accessors.end(), [](int a) { return a >= 0; });
}

// One attribute of every primitive merged into a #V by `components` matrix
// (rows of primitives without it stay zero; no rows when no primitive has it),
// decoded straight into place. `components` 0 takes the count from the first
// accessor. Values must be finite.
template <typename Matrix = Eigen::MatrixXd>
Result<Matrix> readMergedAttribute(const tinygltf::Model& model, const std::vector<int>& accessors,
                                   const std::vector<PrimitiveRange>& ranges, int components, const std::string& role,
                                   const std::string& mesh_name, const std::string& label) {
  Matrix merged;
  for (std::size_t p = 0; p < accessors.size(); ++p) {
    if (accessors[p] < 0) continue;
    const std::string what = mesh_name + " primitive " + std::to_string(p) + " " + role;
    auto checked = checkAccessor(model, accessors[p], role, label);
    if (!checked) return checked.error();
    if (components == 0) components = checked->components;
    if (checked->components != components) {
      return parseError(label, what + " has " + std::to_string(checked->components) +
                                   " components per element, expected " + std::to_string(components));
    }
    const PrimitiveRange range = ranges[p];
    if (checked->count != static_cast<std::size_t>(range.count)) {
      return parseError(label, what + " has " + std::to_string(checked->count) + " elements but POSITION has " +
                                   std::to_string(range.count));
    }
    if (merged.rows() == 0) {
      merged.resize(vertexTotal(ranges), components);
      if (!presentInAll(accessors)) merged.setZero();
    }
    if (auto ok = decodeAccessor(*checked,
                                 {merged.data() + range.offset, 1, static_cast<std::size_t>(merged.rows())}, label);
        !ok) {
      return ok.error();
    }
    for (Eigen::Index v = range.offset; v < range.offset + range.count; ++v) {
      if (!merged.row(v).allFinite()) {
        return makeError(ErrorCode::kInvalidMesh, label + ": " + role + " of vertex " + std::to_string(v) +
                                                      " is not finite");
      }
    }
  }
  return merged;
}

bool isUnsignedSmallInt(int component_type) {
  return component_type == TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE ||
         component_type == TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT;
}

// Spec ("Skins"): JOINTS_n unsigned byte/short integers, WEIGHTS_n float or
// normalized unsigned byte/short. Call after the accessors have been read.
Status checkInfluenceFormat(const tinygltf::Model& model, const std::vector<int>& accessors, bool joints,
                            const std::string& role, const std::string& label) {
  for (const int index : accessors) {
    if (index < 0) continue;
    const tinygltf::Accessor& a = model.accessors[static_cast<std::size_t>(index)];
    const bool ok = joints ? isUnsignedSmallInt(a.componentType) && !a.normalized
                           : a.componentType == TINYGLTF_COMPONENT_TYPE_FLOAT ||
                                 (isUnsignedSmallInt(a.componentType) && a.normalized);
    if (!ok) {
      return parseError(
          label, "accessor " + std::to_string(index) + " (" + role + ") must be " +
                     (joints ? "unsigned byte or short integers" : "float or normalized unsigned byte or short"));
    }
  }
  return Ok{};
}

// JOINTS_n and WEIGHTS_n of all primitives, #V by 4 each.
struct InfluenceSet {
  std::string suffix;  // "0", "1", ...
  Eigen::MatrixXd joints;
  Eigen::MatrixXd weights;
};

Result<std::vector<InfluenceSet>> readInfluenceSets(const tinygltf::Model& model, const tinygltf::Mesh& gmesh,
                                                    const std::vector<PrimitiveRange>& ranges,
                                                    const std::string& mesh_name, const std::string& label) {
  std::vector<InfluenceSet> sets;
  for (int n = 0;; ++n) {
    InfluenceSet set{std::to_string(n), {}, {}};
    const std::string joints_name = "JOINTS_" + set.suffix;
    const std::string weights_name = "WEIGHTS_" + set.suffix;
    const std::vector<int> joints = attributeAccessors(gmesh, joints_name);
    const std::vector<int> weights = attributeAccessors(gmesh, weights_name);
    if (!presentInAny(joints) && !presentInAny(weights)) break;
    for (std::size_t p = 0; p < joints.size(); ++p) {
      if ((joints[p] < 0) != (weights[p] < 0)) {
        return parseError(label, mesh_name + " primitive " + std::to_string(p) + " has only one of " + joints_name +
                                     " and " + weights_name);
      }
    }
    auto j = readMergedAttribute(model, joints, ranges, 4, joints_name, mesh_name, label);
    if (!j) return j.error();
    auto w = readMergedAttribute(model, weights, ranges, 4, weights_name, mesh_name, label);
    if (!w) return w.error();
    if (auto ok = checkInfluenceFormat(model, joints, true, joints_name, label); !ok) return ok.error();
    if (auto ok = checkInfluenceFormat(model, weights, false, weights_name, label); !ok) return ok.error();
    set.joints = std::move(*j);
    set.weights = std::move(*w);
    sets.push_back(std::move(set));
  }
  return sets;
}

// Skin weights (#V by #joints) from every JOINTS_n/WEIGHTS_n set: zero weights
// dropped, a joint repeated within a vertex summed, rows normalised.
Result<SkinWeights> readSkinWeights(const tinygltf::Model& model, const tinygltf::Mesh& gmesh,
                                    const std::vector<PrimitiveRange>& ranges, std::size_t joint_count,
                                    const std::string& mesh_name, const std::string& label,
                                    std::vector<std::string>& warnings) {
  auto sets = readInfluenceSets(model, gmesh, ranges, mesh_name, label);
  if (!sets) return sets.error();
  const Eigen::Index nv = vertexTotal(ranges);
  std::vector<Eigen::Triplet<double>> triplets;
  std::vector<std::pair<int, double>> row;
  int renormalised = 0;
  int empty = 0;
  auto vertexError = [&](Eigen::Index v, const std::string& what) {
    return makeError(ErrorCode::kInvalidMesh, label + ": vertex " + std::to_string(v) + " " + what);
  };
  for (Eigen::Index v = 0; v < nv; ++v) {
    row.clear();
    for (const InfluenceSet& set : *sets) {
      for (int c = 0; c < 4; ++c) {
        const double w = set.weights(v, c);
        const double joint = set.joints(v, c);
        if (w < 0.0) return vertexError(v, "has the negative weight " + std::to_string(w) + " in WEIGHTS_" + set.suffix);
        if (w == 0.0) continue;
        if (joint >= static_cast<double>(joint_count)) {
          return vertexError(v, "uses joint " + std::to_string(static_cast<long long>(joint)) + " in JOINTS_" +
                                    set.suffix + " but the skin has " + std::to_string(joint_count) + " joints");
        }
        row.emplace_back(static_cast<int>(joint), w);
      }
    }
    std::sort(row.begin(), row.end());
    double sum = 0.0;
    for (const auto& entry : row) sum += entry.second;
    if (row.empty()) {
      ++empty;
      continue;
    }
    if (std::abs(sum - 1.0) > kWeightSumTolerance) ++renormalised;
    for (std::size_t i = 0; i < row.size(); ++i) {
      double w = row[i].second;
      while (i + 1 < row.size() && row[i + 1].first == row[i].first) w += row[++i].second;  // repeated joint
      triplets.emplace_back(static_cast<int>(v), row[i].first, w / sum);
    }
  }
  if (renormalised > 0) {
    warnings.push_back(std::to_string(renormalised) + " vertices had skin weights not summing to 1; renormalised");
  }
  if (empty > 0) {
    warnings.push_back(std::to_string(empty) + " vertices of the skinned mesh have no skin weight (left empty)");
  }
  SkinWeights weights(nv, static_cast<Eigen::Index>(joint_count));
  weights.setFromTriplets(triplets.begin(), triplets.end());
  weights.makeCompressed();
  return weights;
}

// mesh.extras.targetNames when it is a list of `count` strings, else target_<i>.
std::vector<std::string> targetNames(const tinygltf::Mesh& gmesh, std::size_t count, const std::string& mesh_name,
                                     std::vector<std::string>& warnings) {
  std::vector<std::string> names(count);
  for (std::size_t i = 0; i < count; ++i) names[i] = "target_" + std::to_string(i);
  if (!gmesh.extras.IsObject() || !gmesh.extras.Has("targetNames")) return names;
  const tinygltf::Value& list = gmesh.extras.Get("targetNames");
  bool usable = list.IsArray() && list.ArrayLen() == count;
  for (std::size_t i = 0; usable && i < count; ++i) usable = list.Get(static_cast<int>(i)).IsString();
  if (!usable) {
    warnings.push_back(mesh_name + " extras.targetNames is not a list of " + std::to_string(count) +
                       " strings; targets named target_<i>");
    return names;
  }
  for (std::size_t i = 0; i < count; ++i) names[i] = list.Get(static_cast<int>(i)).Get<std::string>();
  return names;
}

// Morph targets merged across primitives (POSITION and NORMAL deltas).
Result<std::vector<MorphTarget>> readMorphTargets(const tinygltf::Model& model, const tinygltf::Mesh& gmesh,
                                                  const std::vector<PrimitiveRange>& ranges,
                                                  const std::string& mesh_name, const std::string& label,
                                                  std::vector<std::string>& warnings) {
  const std::size_t count = gmesh.primitives.front().targets.size();
  for (std::size_t p = 1; p < gmesh.primitives.size(); ++p) {
    if (gmesh.primitives[p].targets.size() != count) {
      return makeError(ErrorCode::kUnsupported, label + ": " + mesh_name + " primitive " + std::to_string(p) + " has " +
                                                    std::to_string(gmesh.primitives[p].targets.size()) +
                                                    " morph targets but primitive 0 has " + std::to_string(count));
    }
  }
  const std::vector<std::string> names = targetNames(gmesh, count, mesh_name, warnings);
  std::set<std::string> ignored;
  std::vector<MorphTarget> targets(count);
  for (std::size_t t = 0; t < count; ++t) {
    const int ti = static_cast<int>(t);
    const std::string role = "morph target " + std::to_string(t);
    auto positions = readMergedAttribute<Eigen::MatrixX3d>(model, attributeAccessors(gmesh, "POSITION", ti), ranges,
                                                           3, role + " POSITION", mesh_name, label);
    if (!positions) return positions.error();
    auto normals = readMergedAttribute<Eigen::MatrixX3d>(model, attributeAccessors(gmesh, "NORMAL", ti), ranges, 3,
                                                         role + " NORMAL", mesh_name, label);
    if (!normals) return normals.error();
    MorphTarget& target = targets[t];
    target.name = names[t];
    if (positions->rows() > 0) {
      target.position_deltas = std::move(*positions);
    } else {
      target.position_deltas = Eigen::MatrixX3d::Zero(vertexTotal(ranges), 3);  // NORMAL-only target
    }
    if (normals->rows() > 0) target.normal_deltas = std::move(*normals);  // else 0 rows: no NORMAL deltas
    for (const tinygltf::Primitive& primitive : gmesh.primitives) {
      for (const auto& [name, accessor] : primitive.targets[t]) {
        if (name != "POSITION" && name != "NORMAL") ignored.insert(name);
      }
    }
  }
  for (const std::string& name : ignored) warnings.push_back("morph target " + name + " deltas ignored");
  return targets;
}

// An unskinned mesh is read in world space (placeMesh), so are its deltas:
// positions by the linear part, normals by its inverse transpose.
void transformMorphTargets(const Eigen::Matrix4d& world, std::vector<MorphTarget>& targets) {
  if (world.isIdentity(0.0)) return;
  const Eigen::Matrix3d linear = world.topLeftCorner<3, 3>();
  const Eigen::Matrix3d normal_matrix = linear.inverse().transpose();
  for (MorphTarget& target : targets) {
    target.position_deltas = (target.position_deltas * linear.transpose()).eval();
    if (target.normal_deltas.rows() > 0) {
      target.normal_deltas = (target.normal_deltas * normal_matrix.transpose()).eval();
    }
  }
}

// node.weights (which override mesh.weights, spec "Morph Targets"), else
// mesh.weights, else zeros.
Eigen::VectorXd defaultMorphWeights(const tinygltf::Mesh& gmesh, const tinygltf::Node* node, std::size_t count,
                                    const std::string& mesh_name, std::vector<std::string>& warnings) {
  Eigen::VectorXd weights = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(count));
  const std::vector<double>& source = node && !node->weights.empty() ? node->weights : gmesh.weights;
  if (source.empty()) return weights;
  const bool finite = std::all_of(source.begin(), source.end(), [](double w) { return std::isfinite(w); });
  if (source.size() != count || !finite) {
    warnings.push_back(mesh_name + " default morph weights are not " + std::to_string(count) +
                       " finite numbers; zeros used");
    return weights;
  }
  for (std::size_t i = 0; i < count; ++i) weights(static_cast<Eigen::Index>(i)) = source[i];
  return weights;
}

std::optional<AnimationPath> animationPath(const std::string& path) {
  if (path == "translation") return AnimationPath::kTranslation;
  if (path == "rotation") return AnimationPath::kRotation;
  if (path == "scale") return AnimationPath::kScale;
  if (path == "weights") return AnimationPath::kWeights;
  return std::nullopt;
}

std::optional<Interpolation> interpolation(const std::string& name) {
  if (name == "LINEAR" || name.empty()) return Interpolation::kLinear;
  if (name == "STEP") return Interpolation::kStep;
  if (name == "CUBICSPLINE") return Interpolation::kCubicSpline;
  return std::nullopt;
}

Result<Eigen::VectorXd> readKeyTimes(const tinygltf::Model& model, int accessor, const std::string& what,
                                     const std::string& label) {
  auto input = readAccessor(model, accessor, what + " input", label);
  if (!input) return input.error();
  if (input->components != 1 || input->count == 0) {
    return parseError(label, what + " input must be a non-empty SCALAR accessor");
  }
  Eigen::VectorXd times(static_cast<Eigen::Index>(input->count));
  for (std::size_t k = 0; k < input->count; ++k) {
    const double t = input->values[k];
    if (!std::isfinite(t)) return parseError(label, what + " key time " + std::to_string(k) + " is not finite");
    if (k > 0 && !(t > input->values[k - 1])) {
      return parseError(label, what + " key times do not increase at key " + std::to_string(k));
    }
    times(static_cast<Eigen::Index>(k)) = t;
  }
  return times;
}

// Rotation keys as unit quaternions, like node rotations (cubic spline
// tangents stay as they are).
Result<AnimationChannel> normalizeRotationKeys(AnimationChannel channel, const std::string& what,
                                               const std::string& label) {
  const bool cubic = channel.interpolation == Interpolation::kCubicSpline;
  for (Eigen::Index r = cubic ? 1 : 0; r < channel.values.rows(); r += cubic ? 3 : 1) {
    const double norm = channel.values.row(r).norm();
    if (!(norm > 0.0)) return parseError(label, what + " rotation key " + std::to_string(r) + " is a zero quaternion");
    channel.values.row(r) /= norm;
  }
  return channel;
}

// One channel: key times and #K (x3 for cubic spline) by `columns` values.
Result<AnimationChannel> readChannel(const tinygltf::Model& model, const tinygltf::Animation& ganim,
                                     const tinygltf::AnimationChannel& gchannel, AnimationPath path, int columns,
                                     const std::string& what, const std::string& label) {
  if (gchannel.sampler < 0 || static_cast<std::size_t>(gchannel.sampler) >= ganim.samplers.size()) {
    return parseError(label, what + " refers to sampler " + std::to_string(gchannel.sampler) +
                                 " but the animation has " + std::to_string(ganim.samplers.size()));
  }
  const tinygltf::AnimationSampler& sampler = ganim.samplers[static_cast<std::size_t>(gchannel.sampler)];
  const auto mode = interpolation(sampler.interpolation);
  if (!mode) return parseError(label, what + " has unknown interpolation '" + sampler.interpolation + "'");
  AnimationChannel channel;
  channel.node = gchannel.target_node;
  channel.path = path;
  channel.interpolation = *mode;
  auto times = readKeyTimes(model, sampler.input, what, label);
  if (!times) return times.error();
  channel.times = std::move(*times);

  auto output = readAccessor(model, sampler.output, what + " output", label);
  if (!output) return output.error();
  const auto rows = static_cast<std::size_t>(channel.times.size()) * (*mode == Interpolation::kCubicSpline ? 3 : 1);
  const int element_components = path == AnimationPath::kWeights ? 1 : columns;
  const std::size_t expected = path == AnimationPath::kWeights ? rows * static_cast<std::size_t>(columns) : rows;
  if (output->components != element_components || output->count != expected) {
    return parseError(label, what + " output has " + std::to_string(output->count) + " elements of " +
                                 std::to_string(output->components) + " components; expected " +
                                 std::to_string(expected) + " of " + std::to_string(element_components));
  }
  channel.values.resize(static_cast<Eigen::Index>(rows), columns);
  for (std::size_t r = 0; r < rows; ++r) {
    for (int c = 0; c < columns; ++c) {
      // Row-major either way: element r of `columns` components, or `columns` scalars per row.
      const double x = output->values[r * static_cast<std::size_t>(columns) + static_cast<std::size_t>(c)];
      if (!std::isfinite(x)) return parseError(label, what + " output value " + std::to_string(r) + " is not finite");
      channel.values(static_cast<Eigen::Index>(r), c) = x;
    }
  }
  if (path == AnimationPath::kRotation) return normalizeRotationKeys(std::move(channel), what, label);
  return channel;
}

// Every usable channel of every animation. Weight channels must target the
// mesh node (columns = its morph targets); others are skipped with a warning.
Result<std::vector<Animation>> readAnimations(const tinygltf::Model& model, int mesh_node, int target_count,
                                              const std::string& label, std::vector<std::string>& warnings) {
  std::vector<Animation> animations;
  for (std::size_t a = 0; a < model.animations.size(); ++a) {
    const tinygltf::Animation& ganim = model.animations[a];
    const std::string name = "animation " + std::to_string(a) + quoted(ganim.name);
    Animation animation;
    animation.name = ganim.name;
    for (std::size_t c = 0; c < ganim.channels.size(); ++c) {
      const tinygltf::AnimationChannel& gchannel = ganim.channels[c];
      const std::string what = name + " channel " + std::to_string(c);
      const int node = gchannel.target_node;
      if (node < 0) {
        warnings.push_back(what + " has no target node; skipped");
        continue;
      }
      if (static_cast<std::size_t>(node) >= model.nodes.size()) {
        return parseError(label, what + " targets node " + std::to_string(node) + " but the file has " +
                                     std::to_string(model.nodes.size()) + " nodes");
      }
      const auto path = animationPath(gchannel.target_path);
      if (!path) {
        warnings.push_back(what + " animates '" + gchannel.target_path + "', which a rig does not carry; skipped");
        continue;
      }
      if (*path == AnimationPath::kWeights && node != mesh_node) {
        warnings.push_back(what + " animates the morph weights of node " + std::to_string(node) +
                           ", not of the rig's mesh; skipped");
        continue;
      }
      if (*path == AnimationPath::kWeights && target_count == 0) {
        return parseError(label, what + " animates morph weights but the mesh has no morph targets");
      }
      const int columns = *path == AnimationPath::kRotation ? 4 : *path == AnimationPath::kWeights ? target_count : 3;
      auto channel = readChannel(model, ganim, gchannel, *path, columns, what, label);
      if (!channel) return channel.error();
      animation.channels.push_back(std::move(*channel));
    }
    if (animation.channels.empty()) {
      warnings.push_back(name + " has no usable channel; dropped");
      continue;
    }
    animations.push_back(std::move(animation));
  }
  return animations;
}

// TEXCOORD_1.. as far as every primitive has them.
Result<std::vector<Eigen::MatrixX2d>> readExtraUvSets(const tinygltf::Model& model, const tinygltf::Mesh& gmesh,
                                                      const std::vector<PrimitiveRange>& ranges,
                                                      const std::string& mesh_name, const std::string& label,
                                                      std::vector<std::string>& warnings) {
  std::vector<Eigen::MatrixX2d> sets;
  for (int k = 1;; ++k) {
    const std::string name = "TEXCOORD_" + std::to_string(k);
    const std::vector<int> accessors = attributeAccessors(gmesh, name);
    if (!presentInAny(accessors)) break;
    if (!presentInAll(accessors)) {
      warnings.push_back(name + " is missing on some primitives of " + mesh_name + "; it and later sets dropped");
      break;
    }
    auto uvs = readMergedAttribute(model, accessors, ranges, 2, name, mesh_name, label);
    if (!uvs) return uvs.error();
    sets.emplace_back(std::move(*uvs));
  }
  return sets;
}

// COLOR_0 as RGBA (VEC3 gets alpha 1); 0 rows when absent.
Result<Eigen::MatrixX4d> readColors(const tinygltf::Model& model, const tinygltf::Mesh& gmesh,
                                    const std::vector<PrimitiveRange>& ranges, const std::string& mesh_name,
                                    const std::string& label, std::vector<std::string>& warnings) {
  const std::vector<int> accessors = attributeAccessors(gmesh, "COLOR_0");
  if (!presentInAny(accessors)) return Eigen::MatrixX4d();
  if (!presentInAll(accessors)) {
    warnings.push_back("COLOR_0 is missing on some primitives of " + mesh_name + "; colours dropped");
    return Eigen::MatrixX4d();
  }
  auto colors = readMergedAttribute(model, accessors, ranges, 0, "COLOR_0", mesh_name, label);
  if (!colors) return colors.error();
  if (colors->cols() != 3 && colors->cols() != 4) return parseError(label, "COLOR_0 must be VEC3 or VEC4");
  Eigen::MatrixX4d rgba = Eigen::MatrixX4d::Ones(colors->rows(), 4);
  rgba.leftCols(colors->cols()) = *colors;
  return rgba;
}

// Custom attribute "_NAME": unnormalised integer SCALAR -> labels["NAME"],
// float or normalized SCALAR..VEC4 -> fields["NAME"]; anything else warned.
Status readCustomAttribute(const tinygltf::Model& model, const tinygltf::Mesh& gmesh,
                           const std::vector<PrimitiveRange>& ranges, const std::string& name,
                           const std::string& mesh_name, const std::string& label, VertexAttributes& out,
                           std::vector<std::string>& warnings) {
  const std::vector<int> accessors = attributeAccessors(gmesh, name);
  if (!presentInAll(accessors)) {
    warnings.push_back(name + " is missing on some primitives of " + mesh_name + "; dropped");
    return Ok{};
  }
  auto values = readMergedAttribute(model, accessors, ranges, 0, name, mesh_name, label);
  if (!values) return values.error();
  // 1: label (unnormalised integer SCALAR), 2: field (float or normalized SCALAR..VEC4), 0: neither.
  auto kind = [&](int index) {
    const tinygltf::Accessor& a = model.accessors[static_cast<std::size_t>(index)];
    const bool is_float = a.componentType == TINYGLTF_COMPONENT_TYPE_FLOAT || a.normalized;
    const bool is_vector =
        a.type == TINYGLTF_TYPE_SCALAR || (a.type >= TINYGLTF_TYPE_VEC2 && a.type <= TINYGLTF_TYPE_VEC4);
    if (!is_float) return a.type == TINYGLTF_TYPE_SCALAR ? 1 : 0;
    return is_vector ? 2 : 0;
  };
  const int first = kind(accessors.front());
  const bool same = std::all_of(accessors.begin(), accessors.end(), [&](int a) { return kind(a) == first; });
  const std::string key = name.substr(1);
  if (first == 0 || !same) {
    warnings.push_back(name + " is neither an integer SCALAR nor a float SCALAR..VEC4 on every primitive; dropped");
    return Ok{};
  }
  if (first == 2) {
    out.fields[key] = std::move(*values);
    return Ok{};
  }
  const bool fits_int = values->rows() == 0 || (values->maxCoeff() <= std::numeric_limits<int>::max() &&
                                                 values->minCoeff() >= std::numeric_limits<int>::min());
  if (!fits_int) {
    warnings.push_back(name + " has values beyond the int range; dropped");
    return Ok{};
  }
  out.labels[key] = values->col(0).cast<int>();
  return Ok{};
}

bool isInfluenceOrBaseAttribute(const std::string& name) {
  return name == "POSITION" || name == "NORMAL" || name.rfind("TEXCOORD_", 0) == 0 || name.rfind("JOINTS_", 0) == 0 ||
         name.rfind("WEIGHTS_", 0) == 0 || name == "COLOR_0";
}

Result<VertexAttributes> readVertexAttributes(const tinygltf::Model& model, const tinygltf::Mesh& gmesh,
                                              const std::vector<PrimitiveRange>& ranges, const std::string& mesh_name,
                                              const std::string& label, std::vector<std::string>& warnings) {
  VertexAttributes out;
  auto uv_sets = readExtraUvSets(model, gmesh, ranges, mesh_name, label, warnings);
  if (!uv_sets) return uv_sets.error();
  out.extra_uv_sets = std::move(*uv_sets);
  auto colors = readColors(model, gmesh, ranges, mesh_name, label, warnings);
  if (!colors) return colors.error();
  out.colors = std::move(*colors);
  std::set<std::string> names;
  for (const tinygltf::Primitive& primitive : gmesh.primitives) {
    for (const auto& [name, accessor] : primitive.attributes) names.insert(name);
  }
  for (const std::string& name : names) {
    if (isInfluenceOrBaseAttribute(name)) continue;
    if (name.size() > 1 && name.front() == '_') {
      if (auto ok = readCustomAttribute(model, gmesh, ranges, name, mesh_name, label, out, warnings); !ok) {
        return ok.error();
      }
      continue;
    }
    warnings.push_back("attribute " + name + " of " + mesh_name + " is not carried by rigs; ignored");
  }
  return out;
}

// Region labels for region-constrained matching: the _REGION custom attribute
// when it is an integer SCALAR in 0..kMaxRegionLabel (anything else is warned
// and left out of the matching; a rig still carries it as a label).
Status readMeshRegions(const tinygltf::Model& model, const MeshChoice& choice, const std::string& label, Mesh& mesh,
                       std::vector<std::string>& warnings) {
  const tinygltf::Mesh& gmesh = model.meshes[static_cast<std::size_t>(choice.mesh)];
  const std::string name = std::string("_") + kRegionAttribute;
  if (!presentInAny(attributeAccessors(gmesh, name))) return Ok{};
  const std::string mesh_name = "mesh " + std::to_string(choice.mesh);
  VertexAttributes read;
  std::vector<std::string> dropped;
  if (auto ok = readCustomAttribute(model, gmesh, primitiveRanges(model, gmesh), name, mesh_name, label, read, dropped);
      !ok) {
    return ok.error();
  }
  const auto labels = read.labels.find(kRegionAttribute);
  if (labels == read.labels.end()) {
    warnings.push_back(name + " of " + mesh_name + " is not an integer SCALAR on every primitive; not used for region matching");
    return Ok{};
  }
  if (const Eigen::Index v = firstInvalidRegionLabel(labels->second); v >= 0) {
    warnings.push_back(name + " of vertex " + std::to_string(v) + " is " + std::to_string(labels->second(v)) +
                       " (region labels are 0.." + std::to_string(kMaxRegionLabel) + "); not used for region matching");
    return Ok{};
  }
  mesh.regions = labels->second;
  return Ok{};
}

// Skin and weights of a skinned mesh node (JOINTS/WEIGHTS of an unskinned
// mesh are ignored with a warning).
Status readSkinning(const tinygltf::Model& model, const MeshChoice& choice, const std::vector<PrimitiveRange>& ranges,
                    const std::string& mesh_name, const std::string& label, Rig& rig,
                    std::vector<std::string>& warnings) {
  const tinygltf::Mesh& gmesh = model.meshes[static_cast<std::size_t>(choice.mesh)];
  if (!choice.skinned) {
    if (presentInAny(attributeAccessors(gmesh, "JOINTS_0"))) {
      warnings.push_back("JOINTS/WEIGHTS of " + mesh_name + " ignored: no node uses it with a skin");
    }
    return Ok{};
  }
  auto skin = readSkin(model, model.nodes[static_cast<std::size_t>(choice.node)].skin, label, warnings);
  if (!skin) return skin.error();
  auto weights = readSkinWeights(model, gmesh, ranges, skin->joints.size(), mesh_name, label, warnings);
  if (!weights) return weights.error();
  rig.skin = std::move(*skin);
  rig.weights = std::move(*weights);
  return Ok{};
}

Status readMorphing(const tinygltf::Model& model, const MeshChoice& choice, const std::vector<PrimitiveRange>& ranges,
                    const std::string& mesh_name, const std::string& label, Rig& rig,
                    std::vector<std::string>& warnings) {
  const tinygltf::Mesh& gmesh = model.meshes[static_cast<std::size_t>(choice.mesh)];
  auto targets = readMorphTargets(model, gmesh, ranges, mesh_name, label, warnings);
  if (!targets) return targets.error();
  rig.morph_targets = std::move(*targets);
  if (!choice.skinned && choice.node >= 0) {
    auto world = worldTransform(model, choice.node, label);
    if (!world) return world.error();
    transformMorphTargets(*world, rig.morph_targets);
  }
  const tinygltf::Node* node = choice.node >= 0 ? &model.nodes[static_cast<std::size_t>(choice.node)] : nullptr;
  rig.morph_default_weights = defaultMorphWeights(gmesh, node, rig.morph_targets.size(), mesh_name, warnings);
  return Ok{};
}

// A rig is dense in memory (#targets x #V x 3 morph deltas, all key values),
// and accessors without a bufferView are zeros that cost no file bytes, so a
// small file could claim far more than any face rig. Checked before reading.
constexpr std::size_t kMaxRigValues = std::size_t{1} << 27;  // 1 GiB of doubles

std::size_t accessorValueCount(const tinygltf::Model& model, int index) {
  if (index < 0 || static_cast<std::size_t>(index) >= model.accessors.size()) return 0;  // reported when read
  const tinygltf::Accessor& a = model.accessors[static_cast<std::size_t>(index)];
  const auto components = static_cast<std::size_t>(typeComponents(a.type));
  return a.count > kMaxRigValues ? kMaxRigValues + 1 : a.count * components;
}

Status checkRigSize(const tinygltf::Model& model, const tinygltf::Mesh& gmesh, Eigen::Index vertex_count,
                    const std::string& label) {
  std::size_t total = 0;
  auto add = [&](std::size_t n) { total = std::min(total + std::min(n, kMaxRigValues + 1), kMaxRigValues + 1); };
  const std::size_t targets = gmesh.primitives.front().targets.size();
  for (std::size_t t = 0; t < targets; ++t) add(static_cast<std::size_t>(vertex_count) * 6);  // positions, normals
  for (const tinygltf::Animation& animation : model.animations) {
    for (const tinygltf::AnimationChannel& channel : animation.channels) {
      if (channel.sampler < 0 || static_cast<std::size_t>(channel.sampler) >= animation.samplers.size()) continue;
      const tinygltf::AnimationSampler& sampler = animation.samplers[static_cast<std::size_t>(channel.sampler)];
      add(accessorValueCount(model, sampler.input));
      add(accessorValueCount(model, sampler.output));
    }
  }
  if (total > kMaxRigValues) {
    return makeError(ErrorCode::kUnsupported, label + ": the morph targets and animations would need more than " +
                                                  std::to_string(kMaxRigValues) + " values in memory");
  }
  return Ok{};
}

// Everything beyond the mesh itself (buildMesh has read and placed that).
Status readRigParts(const tinygltf::Model& model, const MeshChoice& choice, const std::string& label, Rig& rig,
                    std::vector<std::string>& warnings) {
  const tinygltf::Mesh& gmesh = model.meshes[static_cast<std::size_t>(choice.mesh)];
  const std::string mesh_name = "mesh " + std::to_string(choice.mesh);
  const std::vector<PrimitiveRange> ranges = primitiveRanges(model, gmesh);
  if (auto ok = checkRigSize(model, gmesh, vertexTotal(ranges), label); !ok) return ok.error();
  rig.mesh_name = gmesh.name;
  rig.mesh_node = choice.node;
  auto nodes = readNodes(model, label, warnings);
  if (!nodes) return nodes.error();
  rig.nodes = std::move(*nodes);
  if (auto ok = readSkinning(model, choice, ranges, mesh_name, label, rig, warnings); !ok) return ok.error();
  if (auto ok = readMorphing(model, choice, ranges, mesh_name, label, rig, warnings); !ok) return ok.error();
  auto animations = readAnimations(model, choice.node, static_cast<int>(rig.morph_targets.size()), label, warnings);
  if (!animations) return animations.error();
  rig.animations = std::move(*animations);
  auto attributes = readVertexAttributes(model, gmesh, ranges, mesh_name, label, warnings);
  if (!attributes) return attributes.error();
  rig.attributes = std::move(*attributes);
  return Ok{};
}

// The chosen mesh of a parsed file (buildMesh) with its region labels.
Result<LoadedMesh> chosenMesh(const ParsedGltf& parsed, const std::string& label, LoadedMesh loaded) {
  auto mesh = buildMesh(parsed.model, parsed.choice, label, std::move(loaded));
  if (!mesh) return mesh.error();
  if (auto ok = readMeshRegions(parsed.model, parsed.choice, label, mesh->mesh, mesh->report.warnings); !ok) {
    return ok.error();
  }
  return mesh;
}

Result<LoadedMesh> readGltfImpl(Bytes bytes, const std::string& label, bool binary,
                                const std::optional<std::filesystem::path>& base_dir) {
  LoadedMesh loaded;
  auto parsed = parseGltf(bytes, label, binary, base_dir, loaded.report);
  if (!parsed) return parsed.error();
  return chosenMesh(*parsed, label, std::move(loaded));
}

Result<LoadedRig> readRigImpl(Bytes bytes, const std::string& label, bool binary,
                              const std::optional<std::filesystem::path>& base_dir) {
  LoadedMesh loaded_mesh;
  auto parsed = parseGltf(bytes, label, binary, base_dir, loaded_mesh.report);
  if (!parsed) return parsed.error();
  auto mesh = chosenMesh(*parsed, label, std::move(loaded_mesh));
  if (!mesh) return mesh.error();
  LoadedRig loaded;
  loaded.rig.mesh = std::move(mesh->mesh);
  loaded.report = std::move(mesh->report);
  if (auto ok = readRigParts(parsed->model, parsed->choice, label, loaded.rig, loaded.report.warnings); !ok) {
    return ok.error();
  }
  return loaded;
}

// ---------------------------------------------------------------------------
// Writing: small helpers that append to buffer 0 (reused for skins, morph
// targets and animations).

static_assert(std::endian::native == std::endian::little, "GLB data is little-endian; writer copies host floats");

template <typename T>
Bytes asBytes(const std::vector<T>& values) {
  return Bytes(reinterpret_cast<const std::uint8_t*>(values.data()), values.size() * sizeof(T));
}

// Appends `bytes` to buffer 0 at a 4-byte aligned offset and returns the new
// bufferView. `target` is TINYGLTF_TARGET_ARRAY_BUFFER, ..._ELEMENT_ARRAY_BUFFER
// or 0 (animation / inverse-bind data has no target).
int addBufferView(tinygltf::Model& model, Bytes bytes, int target) {
  if (model.buffers.empty()) model.buffers.emplace_back();
  std::vector<unsigned char>& data = model.buffers[0].data;
  data.resize((data.size() + 3) / 4 * 4, 0);
  tinygltf::BufferView view;
  view.buffer = 0;
  view.byteOffset = data.size();
  view.byteLength = bytes.size();
  view.target = target;
  data.insert(data.end(), bytes.begin(), bytes.end());
  model.bufferViews.push_back(std::move(view));
  return static_cast<int>(model.bufferViews.size()) - 1;
}

// Adds an accessor over a whole bufferView and returns its index.
int addAccessor(tinygltf::Model& model, int buffer_view, int component_type, int type, std::size_t count,
                std::vector<double> min = {}, std::vector<double> max = {}) {
  tinygltf::Accessor accessor;
  accessor.bufferView = buffer_view;
  accessor.byteOffset = 0;
  accessor.componentType = component_type;
  accessor.type = type;
  accessor.count = count;
  accessor.minValues = std::move(min);
  accessor.maxValues = std::move(max);
  model.accessors.push_back(std::move(accessor));
  return static_cast<int>(model.accessors.size()) - 1;
}

// Per-component min and max of `values` (count * components floats).
std::pair<std::vector<double>, std::vector<double>> floatBounds(const std::vector<float>& values, int components) {
  const auto n = static_cast<std::size_t>(components);
  std::vector<double> min(n, std::numeric_limits<double>::infinity());
  std::vector<double> max(n, -std::numeric_limits<double>::infinity());
  for (std::size_t row = 0; row + n <= values.size(); row += n) {
    for (std::size_t c = 0; c < n; ++c) {
      min[c] = std::min(min[c], static_cast<double>(values[row + c]));
      max[c] = std::max(max[c], static_cast<double>(values[row + c]));
    }
  }
  return {min, max};
}

// Float accessor from `values` (count * components floats, row-major). With
// `bounds`, min/max are set from the float values themselves, as the spec
// requires for POSITION (and the validator checks exactly).
int addFloatAccessor(tinygltf::Model& model, const std::vector<float>& values, int type, int target, bool bounds) {
  const int components = typeComponents(type);
  const std::size_t count = values.size() / static_cast<std::size_t>(components);
  std::vector<double> min;
  std::vector<double> max;
  if (bounds && count > 0) std::tie(min, max) = floatBounds(values, components);
  const int view = addBufferView(model, asBytes(values), target);
  return addAccessor(model, view, TINYGLTF_COMPONENT_TYPE_FLOAT, type, count, std::move(min), std::move(max));
}

// Row-major float copy of a matrix.
template <typename Derived>
std::vector<float> toFloats(const Eigen::MatrixBase<Derived>& m) {
  std::vector<float> out(static_cast<std::size_t>(m.rows() * m.cols()));
  for (Eigen::Index r = 0; r < m.rows(); ++r) {
    for (Eigen::Index c = 0; c < m.cols(); ++c) {
      out[static_cast<std::size_t>(r * m.cols() + c)] = static_cast<float>(m(r, c));
    }
  }
  return out;
}

// Index of the first value that is not finite (a finite double can still
// overflow float32), or nullopt.
std::optional<std::size_t> firstNonFinite(const std::vector<float>& values) {
  const auto bad = std::find_if(values.begin(), values.end(), [](float x) { return !std::isfinite(x); });
  if (bad == values.end()) return std::nullopt;
  return static_cast<std::size_t>(bad - values.begin());
}

// The validator requires unit NORMALs: renormalise in float, and give zero or
// unusable normals +Y (they carry no direction anyway).
std::vector<float> unitNormals(const Eigen::MatrixX3d& normals) {
  std::vector<float> out(static_cast<std::size_t>(normals.rows()) * 3);
  for (Eigen::Index v = 0; v < normals.rows(); ++v) {
    Eigen::Vector3d n = normals.row(v).transpose();
    const double len = n.norm();
    n = len > 1e-12 && std::isfinite(len) ? Eigen::Vector3d(n / len) : Eigen::Vector3d::UnitY();
    for (int c = 0; c < 3; ++c) out[static_cast<std::size_t>(v) * 3 + c] = static_cast<float>(n(c));
  }
  return out;
}

// POSITION (with min/max), unit NORMAL, TEXCOORD_0 and uint32 indices of a
// validated `mesh` as one primitive, mode TRIANGLES (POINTS for a point cloud).
Result<tinygltf::Primitive> addMeshPrimitive(tinygltf::Model& model, const Mesh& mesh, const std::string& label) {
  const std::vector<float> positions = toFloats(mesh.positions);
  if (const auto bad = firstNonFinite(positions)) {
    return makeError(ErrorCode::kInvalidMesh,
                     label + ": vertex " + std::to_string(*bad / 3) + " position exceeds the float32 range of glTF");
  }
  tinygltf::Primitive primitive;
  primitive.attributes["POSITION"] =
      addFloatAccessor(model, positions, TINYGLTF_TYPE_VEC3, TINYGLTF_TARGET_ARRAY_BUFFER, /*bounds=*/true);
  if (mesh.normals.rows() > 0) {
    primitive.attributes["NORMAL"] =
        addFloatAccessor(model, unitNormals(mesh.normals), TINYGLTF_TYPE_VEC3, TINYGLTF_TARGET_ARRAY_BUFFER, false);
  }
  if (mesh.uvs.rows() > 0) {
    primitive.attributes["TEXCOORD_0"] =
        addFloatAccessor(model, toFloats(mesh.uvs), TINYGLTF_TYPE_VEC2, TINYGLTF_TARGET_ARRAY_BUFFER, false);
  }
  if (mesh.triangleCount() == 0) {
    primitive.mode = TINYGLTF_MODE_POINTS;  // point cloud: every vertex drawn once
    return primitive;
  }
  std::vector<std::uint32_t> indices(static_cast<std::size_t>(mesh.triangleCount()) * 3);
  for (Eigen::Index f = 0; f < mesh.triangleCount(); ++f) {
    for (int k = 0; k < 3; ++k) {
      indices[static_cast<std::size_t>(f) * 3 + k] = static_cast<std::uint32_t>(mesh.triangles(f, k));
    }
  }
  const int view = addBufferView(model, asBytes(indices), TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER);
  primitive.indices =
      addAccessor(model, view, TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT, TINYGLTF_TYPE_SCALAR, indices.size());
  primitive.mode = TINYGLTF_MODE_TRIANGLES;  // explicit: tinygltf's default (-1) is invalid
  return primitive;
}

// An output stream appending to a byte vector reserved up front: the GLB of a
// large rig (hundreds of MB of morph targets) is written once, not grown in
// an ostringstream and copied out of it.
class ByteSink : public std::streambuf {
 public:
  explicit ByteSink(std::size_t reserve) { bytes_.reserve(reserve); }
  std::vector<std::uint8_t> take() { return std::move(bytes_); }

 protected:
  int_type overflow(int_type c) override {
    if (!traits_type::eq_int_type(c, traits_type::eof())) bytes_.push_back(static_cast<std::uint8_t>(c));
    return traits_type::not_eof(c);
  }
  std::streamsize xsputn(const char* s, std::streamsize n) override {
    bytes_.insert(bytes_.end(), reinterpret_cast<const std::uint8_t*>(s), reinterpret_cast<const std::uint8_t*>(s) + n);
    return n;
  }

 private:
  std::vector<std::uint8_t> bytes_;
};

// Serialises `model` as GLB bytes (tinygltf's writer; deterministic since its
// JSON objects are ordered maps).
Result<std::vector<std::uint8_t>> serializeGlb(const tinygltf::Model& model) {
  tinygltf::TinyGLTF writer;
  std::size_t binary = 0;
  for (const auto& buffer : model.buffers) binary += buffer.data.size();
  // JSON: a few hundred bytes per accessor and buffer view, plus headroom.
  ByteSink sink(binary + 256 * (model.accessors.size() + model.bufferViews.size()) + (64 << 10));
  std::ostream stream(&sink);
  try {
    if (!writer.WriteGltfSceneToStream(&model, stream, /*prettyPrint=*/false, /*writeBinary=*/true)) {
      return makeError(ErrorCode::kIo, "GLB serialisation failed");
    }
  } catch (const std::exception& e) {
    return makeError(ErrorCode::kIo, std::string("GLB serialisation failed: ") + e.what());
  }
  if (!stream) return makeError(ErrorCode::kIo, "GLB serialisation failed (stream error)");
  return sink.take();
}

// ---------------------------------------------------------------------------
// Rig writing: checks first (every rule the validator enforces that the Rig
// type does not), then nodes, the mesh primitive, skin, morph targets and
// animations appended to one model.

const std::string kRigLabel = "rig to write";

Error invalidRig(const std::string& what) { return makeError(ErrorCode::kInvalidArgument, kRigLabel + ": " + what); }

std::string nodeName(const Rig& rig, int node) {
  return "node " + std::to_string(node) + quoted(rig.nodes[static_cast<std::size_t>(node)].name);
}

Status checkRigNodes(const Rig& rig) {
  const int n = static_cast<int>(rig.nodes.size());
  for (int i = 0; i < n; ++i) {
    const Node& node = rig.nodes[static_cast<std::size_t>(i)];
    if (node.parent < -1 || node.parent >= n || node.parent == i) {
      return invalidRig(nodeName(rig, i) + " has parent " + std::to_string(node.parent) + ", not another node");
    }
    if (!node.translation.allFinite() || !node.rotation.coeffs().allFinite() || !node.scale.allFinite()) {
      return invalidRig(nodeName(rig, i) + " has a non-finite transform");
    }
    if (!(node.rotation.norm() > 0.0)) return invalidRig(nodeName(rig, i) + " has a zero rotation quaternion");
  }
  for (int i = 0; i < n; ++i) {  // every parent is a node index now
    int steps = 0;
    for (int p = rig.nodes[static_cast<std::size_t>(i)].parent; p >= 0;
         p = rig.nodes[static_cast<std::size_t>(p)].parent) {
      if (++steps > n) return invalidRig(nodeName(rig, i) + " is in a cycle of parents");
    }
  }
  if (rig.mesh_node < -1 || rig.mesh_node >= n) {
    return invalidRig("mesh_node " + std::to_string(rig.mesh_node) + " is not a node index (or -1)");
  }
  return Ok{};
}

Status checkRigSkin(const Rig& rig) {
  const Eigen::Index nv = rig.mesh.vertexCount();
  if (!rig.skin) {
    if (rig.weights.nonZeros() > 0) return invalidRig("it has skin weights but no skin");
    return Ok{};
  }
  const Skin& skin = *rig.skin;
  const std::size_t count = skin.joints.size();
  if (count == 0 || count > 65536) return invalidRig("the skin has " + std::to_string(count) + " joints (1..65536)");
  std::vector<char> used(rig.nodes.size(), 0);
  for (std::size_t j = 0; j < count; ++j) {
    const int node = skin.joints[j];
    if (node < 0 || static_cast<std::size_t>(node) >= rig.nodes.size()) {
      return invalidRig("skin joint " + std::to_string(j) + " is node " + std::to_string(node) + " but the rig has " +
                        std::to_string(rig.nodes.size()) + " nodes");
    }
    if (used[static_cast<std::size_t>(node)]) {
      return invalidRig("skin joint " + std::to_string(j) + " repeats " + nodeName(rig, node));
    }
    used[static_cast<std::size_t>(node)] = 1;
  }
  if (skin.inverse_bind.size() != count) {
    return invalidRig("the skin has " + std::to_string(count) + " joints but " +
                      std::to_string(skin.inverse_bind.size()) + " inverse bind matrices");
  }
  for (std::size_t j = 0; j < count; ++j) {
    const Eigen::Matrix4d& m = skin.inverse_bind[j];
    const std::string joint = "skin joint " + std::to_string(j) + " (" + nodeName(rig, skin.joints[j]) + ")";
    if (!m.allFinite() || !m.cast<float>().allFinite()) {
      return invalidRig(joint + " inverse bind matrix is not finite in float32");
    }
    if ((m.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).cwiseAbs().maxCoeff() > 1e-9) {
      return invalidRig(joint + " inverse bind matrix bottom row is not 0 0 0 1");
    }
  }
  if (skin.skeleton < -1 || skin.skeleton >= static_cast<int>(rig.nodes.size())) {
    return invalidRig("skin skeleton " + std::to_string(skin.skeleton) + " is not a node index (or -1)");
  }
  if (rig.weights.rows() != nv || rig.weights.cols() != static_cast<Eigen::Index>(count)) {
    return invalidRig("skin weights are " + std::to_string(rig.weights.rows()) + " by " +
                      std::to_string(rig.weights.cols()) + ", expected #V " + std::to_string(nv) + " by #joints " +
                      std::to_string(count));
  }
  return Ok{};
}

Status checkRigMorphTargets(const Rig& rig) {
  const Eigen::Index nv = rig.mesh.vertexCount();
  const std::size_t count = rig.morph_targets.size();
  for (std::size_t t = 0; t < count; ++t) {
    const MorphTarget& target = rig.morph_targets[t];
    const std::string what = "morph target " + std::to_string(t) + quoted(target.name);
    if (target.position_deltas.rows() != nv) {
      return invalidRig(what + " has " + std::to_string(target.position_deltas.rows()) + " position deltas for " +
                        std::to_string(nv) + " vertices");
    }
    if (target.normal_deltas.rows() != 0 && target.normal_deltas.rows() != nv) {
      return invalidRig(what + " has " + std::to_string(target.normal_deltas.rows()) + " normal deltas for " +
                        std::to_string(nv) + " vertices");
    }
    if (target.normal_deltas.rows() > 0 && rig.mesh.normals.rows() == 0) {
      return invalidRig(what + " has normal deltas but the mesh has no normals");
    }
  }
  const Eigen::Index defaults = rig.morph_default_weights.size();
  if ((defaults != 0 && defaults != static_cast<Eigen::Index>(count)) || !rig.morph_default_weights.allFinite()) {
    return invalidRig("morph_default_weights has " + std::to_string(defaults) + " values for " + std::to_string(count) +
                      " morph targets (or is not finite)");
  }
  return Ok{};
}

Status checkRig(const Rig& rig, const RigWriteOptions& options) {
  if (options.max_influences < 1 || options.max_influences > 8) {
    return invalidRig("max_influences is " + std::to_string(options.max_influences) + " (1..8)");
  }
  if (auto ok = validateMesh(rig.mesh, kRigLabel); !ok) return ok.error();
  if (rig.mesh.vertexCount() == 0) return makeError(ErrorCode::kInvalidMesh, kRigLabel + ": the mesh has no vertices");
  if (auto ok = checkRigNodes(rig); !ok) return ok.error();
  if (auto ok = checkRigSkin(rig); !ok) return ok.error();
  return checkRigMorphTargets(rig);
}

// Which output node carries the mesh. A skinned mesh's node must be an
// identity root whose TRS is not animated (glTF ignores it; the validator
// warns): the rig's node is used when it is one, reset when nothing depends
// on its transform, else a new root node is appended for the mesh.
struct MeshNodePlan {
  int node = -1;          // output node index carrying the mesh (and skin)
  bool appended = false;  // a new root node (index rig.nodes.size())
  bool reset = false;     // rig.mesh_node written as an identity root
};

bool hasTransform(const Node& node) {
  return node.translation != Eigen::Vector3d::Zero() || !node.rotation.normalized().vec().isZero(0.0) ||
         node.scale != Eigen::Vector3d::Ones();
}

bool animatesTransformOf(const Rig& rig, int node) {
  for (const Animation& animation : rig.animations) {
    for (const AnimationChannel& channel : animation.channels) {
      if (channel.node == node && channel.path != AnimationPath::kWeights) return true;
    }
  }
  return false;
}

MeshNodePlan planMeshNode(const Rig& rig) {
  const int appended_index = static_cast<int>(rig.nodes.size());
  const int mesh_node = rig.mesh_node;
  if (mesh_node < 0) return {appended_index, true, false};
  if (!rig.skin) return {mesh_node, false, false};
  const Node& node = rig.nodes[static_cast<std::size_t>(mesh_node)];
  const bool animated = animatesTransformOf(rig, mesh_node);
  if (node.parent < 0 && !hasTransform(node) && !animated) return {mesh_node, false, false};
  const bool has_children =
      std::any_of(rig.nodes.begin(), rig.nodes.end(), [&](const Node& n) { return n.parent == mesh_node; });
  const bool is_joint =
      std::find(rig.skin->joints.begin(), rig.skin->joints.end(), mesh_node) != rig.skin->joints.end();
  if (!has_children && !is_joint && !animated) return {mesh_node, false, true};
  return {appended_index, true, false};
}

// TRS with identity components omitted.
tinygltf::Node toGltfNode(const Node& node) {
  tinygltf::Node out;
  out.name = node.name;
  const Eigen::Vector3d& t = node.translation;
  const Eigen::Quaterniond q = node.rotation.normalized();
  const Eigen::Vector3d& s = node.scale;
  if (t != Eigen::Vector3d::Zero()) out.translation = {t.x(), t.y(), t.z()};
  if (!q.vec().isZero(0.0)) out.rotation = {q.x(), q.y(), q.z(), q.w()};
  if (s != Eigen::Vector3d::Ones()) out.scale = {s.x(), s.y(), s.z()};
  return out;
}

// All rig nodes (children lists from the parents), the mesh node, one scene
// of the roots in index order.
void addRigNodes(tinygltf::Model& model, const Rig& rig, const MeshNodePlan& plan) {
  const int n = static_cast<int>(rig.nodes.size());
  for (const Node& node : rig.nodes) model.nodes.push_back(toGltfNode(node));
  if (plan.appended) {
    tinygltf::Node mesh_node;
    mesh_node.name = rig.mesh_name.empty() ? "mesh" : rig.mesh_name;
    model.nodes.push_back(std::move(mesh_node));
  }
  tinygltf::Node& mesh_node = model.nodes[static_cast<std::size_t>(plan.node)];
  if (plan.reset) {
    mesh_node.translation.clear();
    mesh_node.rotation.clear();
    mesh_node.scale.clear();
  }
  mesh_node.mesh = 0;
  if (rig.skin) mesh_node.skin = 0;
  tinygltf::Scene scene;
  for (int i = 0; i < n; ++i) {
    const int parent = plan.reset && i == plan.node ? -1 : rig.nodes[static_cast<std::size_t>(i)].parent;
    if (parent < 0) {
      scene.nodes.push_back(i);
    } else {
      model.nodes[static_cast<std::size_t>(parent)].children.push_back(i);
    }
  }
  if (plan.appended) scene.nodes.push_back(n);
  model.scenes.push_back(std::move(scene));
  // tinygltf writes a node with no property as null, which no reader accepts.
  for (tinygltf::Node& node : model.nodes) {
    const bool empty = node.name.empty() && node.translation.empty() && node.rotation.empty() && node.scale.empty() &&
                       node.children.empty() && node.mesh < 0;
    if (empty) node.translation = {0.0, 0.0, 0.0};
  }
  model.defaultScene = 0;
}

// World space -> the mesh node's space. The reader moves an unskinned mesh
// into world space by its node (placeMesh), so the writer moves it back;
// skinned meshes and meshes on a new root node need nothing.
struct NodeSpace {
  bool identity = true;
  Eigen::Matrix3d linear = Eigen::Matrix3d::Identity();          // node -> world
  Eigen::Matrix3d inverse_linear = Eigen::Matrix3d::Identity();  // world -> node
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();

  Eigen::MatrixX3d points(const Eigen::MatrixX3d& p) const {
    return identity ? p : Eigen::MatrixX3d((p.rowwise() - translation.transpose()) * inverse_linear.transpose());
  }
  Eigen::MatrixX3d vectors(const Eigen::MatrixX3d& d) const {
    return identity ? d : Eigen::MatrixX3d(d * inverse_linear.transpose());
  }
  Eigen::MatrixX3d normals(const Eigen::MatrixX3d& n) const { return identity ? n : Eigen::MatrixX3d(n * linear); }
};

Result<NodeSpace> meshNodeSpace(const Rig& rig, const MeshNodePlan& plan) {
  NodeSpace space;
  if (rig.skin || plan.appended) return space;
  const Eigen::Matrix4d world = nodeWorldTransforms(rig.nodes)[static_cast<std::size_t>(plan.node)];
  if (world.isIdentity(0.0)) return space;
  space.identity = false;
  space.linear = world.topLeftCorner<3, 3>();
  space.translation = world.topRightCorner<3, 1>();
  const double det = space.linear.determinant();
  if (!(std::abs(det) > 0.0) || !std::isfinite(det)) {
    return invalidRig("the world transform of mesh " + nodeName(rig, plan.node) + " is singular");
  }
  space.inverse_linear = space.linear.inverse();
  return space;
}

Mesh meshInNodeSpace(const Mesh& mesh, const NodeSpace& space) {
  Mesh local = mesh;
  local.positions = space.points(mesh.positions);
  if (mesh.normals.rows() > 0) local.normals = space.normals(mesh.normals);
  if (space.linear.determinant() < 0.0) local.triangles.col(1).swap(local.triangles.col(2));  // as the reader flips
  return local;
}

// Accessor over a 1- or 2-byte per-vertex SCALAR padded to a 4-byte stride
// (spec: vertex attribute elements are 4-byte aligned).
int addPaddedScalarAccessor(tinygltf::Model& model, const Eigen::VectorXi& values, bool two_bytes) {
  std::vector<std::uint8_t> bytes(static_cast<std::size_t>(values.size()) * 4, 0);
  for (Eigen::Index v = 0; v < values.size(); ++v) {
    const auto value = static_cast<std::uint32_t>(values(v));
    bytes[static_cast<std::size_t>(v) * 4] = static_cast<std::uint8_t>(value & 0xFF);
    bytes[static_cast<std::size_t>(v) * 4 + 1] = static_cast<std::uint8_t>(value >> 8);
  }
  const int view = addBufferView(model, Bytes(bytes), TINYGLTF_TARGET_ARRAY_BUFFER);
  model.bufferViews[static_cast<std::size_t>(view)].byteStride = 4;
  const int type = two_bytes ? TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT : TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE;
  return addAccessor(model, view, type, TINYGLTF_TYPE_SCALAR, static_cast<std::size_t>(values.size()));
}

Status addLabels(tinygltf::Model& model, const VertexAttributes& attributes, Eigen::Index nv,
                 tinygltf::Primitive& primitive) {
  for (const auto& [key, values] : attributes.labels) {
    const std::string name = "_" + key;
    if (key.empty() || attributes.fields.count(key) > 0) {
      return invalidRig("custom attribute name '" + name + "' is empty or used twice");
    }
    if (values.size() != nv) {
      return invalidRig("label " + key + " has " + std::to_string(values.size()) + " values for " + std::to_string(nv) +
                        " vertices");
    }
    for (Eigen::Index v = 0; v < nv; ++v) {
      if (values(v) < 0 || values(v) > 65535) {
        return invalidRig("label " + key + " of vertex " + std::to_string(v) + " is " + std::to_string(values(v)) +
                          " (0..65535)");
      }
    }
    primitive.attributes[name] = addPaddedScalarAccessor(model, values, values.maxCoeff() > 255);
  }
  return Ok{};
}

Status addFields(tinygltf::Model& model, const VertexAttributes& attributes, Eigen::Index nv,
                 tinygltf::Primitive& primitive) {
  static constexpr std::array<int, 4> kTypes = {TINYGLTF_TYPE_SCALAR, TINYGLTF_TYPE_VEC2, TINYGLTF_TYPE_VEC3,
                                                TINYGLTF_TYPE_VEC4};
  for (const auto& [key, values] : attributes.fields) {
    if (key.empty()) return invalidRig("custom attribute name '_' is empty");
    if (values.rows() != nv || values.cols() < 1 || values.cols() > 4) {
      return invalidRig("field " + key + " is " + std::to_string(values.rows()) + " by " +
                        std::to_string(values.cols()) + ", expected #V " + std::to_string(nv) + " by 1..4");
    }
    const std::vector<float> floats = toFloats(values);
    if (const auto bad = firstNonFinite(floats)) {
      return invalidRig("field " + key + " of vertex " +
                        std::to_string(*bad / static_cast<std::size_t>(values.cols())) + " is not finite in float32");
    }
    const int type = kTypes[static_cast<std::size_t>(values.cols() - 1)];
    primitive.attributes["_" + key] = addFloatAccessor(model, floats, type, TINYGLTF_TARGET_ARRAY_BUFFER, false);
  }
  return Ok{};
}

// TEXCOORD_1.., COLOR_0 and the custom attributes.
Status addVertexAttributes(tinygltf::Model& model, const Rig& rig, tinygltf::Primitive& primitive) {
  const VertexAttributes& attributes = rig.attributes;
  const Eigen::Index nv = rig.mesh.vertexCount();
  if (!attributes.extra_uv_sets.empty() && rig.mesh.uvs.rows() == 0) {
    return invalidRig("extra UV sets need mesh.uvs (TEXCOORD_0)");
  }
  for (std::size_t k = 0; k < attributes.extra_uv_sets.size(); ++k) {
    const std::string name = "TEXCOORD_" + std::to_string(k + 1);
    const std::vector<float> uvs = toFloats(attributes.extra_uv_sets[k]);
    if (attributes.extra_uv_sets[k].rows() != nv || firstNonFinite(uvs)) {
      return invalidRig(name + " must have " + std::to_string(nv) + " finite rows");
    }
    primitive.attributes[name] = addFloatAccessor(model, uvs, TINYGLTF_TYPE_VEC2, TINYGLTF_TARGET_ARRAY_BUFFER, false);
  }
  if (attributes.colors.rows() > 0) {
    if (attributes.colors.rows() != nv) return invalidRig("colors must have " + std::to_string(nv) + " rows");
    for (Eigen::Index v = 0; v < nv; ++v) {
      const auto row = attributes.colors.row(v);
      if (!(row.minCoeff() >= 0.0 && row.maxCoeff() <= 1.0)) {
        return invalidRig("color of vertex " + std::to_string(v) + " is outside [0, 1]");
      }
    }
    primitive.attributes["COLOR_0"] =
        addFloatAccessor(model, toFloats(attributes.colors), TINYGLTF_TYPE_VEC4, TINYGLTF_TARGET_ARRAY_BUFFER, false);
  }
  if (auto ok = addLabels(model, attributes, nv, primitive); !ok) return ok.error();
  return addFields(model, attributes, nv, primitive);
}

// Per vertex, the kept influences: `slots` (4 or 8) (joint, weight) pairs,
// largest weight first (ties: lower joint), summing to 1; unused slots are
// joint 0 weight 0.
struct InfluenceTable {
  int slots = 4;
  std::vector<int> joints;      // #V * slots
  std::vector<double> weights;  // #V * slots
};

Result<InfluenceTable> selectInfluences(const SkinWeights& weights, int max_influences) {
  const auto nv = static_cast<std::size_t>(weights.rows());
  std::vector<std::vector<std::pair<int, double>>> kept(nv);
  int widest = 0;
  std::vector<std::pair<int, double>> row;
  for (std::size_t v = 0; v < nv; ++v) {
    row.clear();
    for (SkinWeights::InnerIterator it(weights, static_cast<Eigen::Index>(v)); it; ++it) {
      const double w = it.value();
      if (!std::isfinite(w) || w < 0.0) {
        return invalidRig("vertex " + std::to_string(v) + " has weight " + std::to_string(w) + " on joint " +
                          std::to_string(it.col()) + " (weights must be finite and >= 0)");
      }
      if (w > 0.0) row.emplace_back(static_cast<int>(it.col()), w);
    }
    if (row.empty()) return invalidRig("vertex " + std::to_string(v) + " of the skinned mesh has no skin weight");
    std::sort(row.begin(), row.end(), [](const auto& a, const auto& b) {
      return a.second != b.second ? a.second > b.second : a.first < b.first;
    });
    if (row.size() > static_cast<std::size_t>(max_influences)) row.resize(static_cast<std::size_t>(max_influences));
    double sum = 0.0;
    for (const auto& entry : row) sum += entry.second;
    for (auto& entry : row) entry.second /= sum;
    widest = std::max(widest, static_cast<int>(row.size()));
    kept[v] = row;
  }
  InfluenceTable table;
  table.slots = widest > 4 ? 8 : 4;
  const auto slots = static_cast<std::size_t>(table.slots);
  table.joints.assign(nv * slots, 0);
  table.weights.assign(nv * slots, 0.0);
  for (std::size_t v = 0; v < nv; ++v) {
    for (std::size_t s = 0; s < kept[v].size(); ++s) {
      table.joints[v * slots + s] = kept[v][s].first;
      table.weights[v * slots + s] = kept[v][s].second;
    }
  }
  return table;
}

// The validator's sum of one vertex's weights: float32, component-major
// across the JOINTS_n/WEIGHTS_n sets (gltf-validator's eX.dY).
float validatorWeightSum(const float* w, int slots) {
  float sum = 0.0f;
  for (int c = 0; c < 4; ++c) {
    for (int set = 0; set < slots / 4; ++set) sum += w[set * 4 + c];
  }
  return sum;
}

// Float weights whose float32 sum is 1 (the largest absorbs the rounding).
std::vector<float> encodeFloatWeights(const InfluenceTable& table, std::vector<int>& joints) {
  std::vector<float> out(table.weights.size());
  const auto slots = static_cast<std::size_t>(table.slots);
  for (std::size_t base = 0; base < out.size(); base += slots) {
    for (std::size_t s = 0; s < slots; ++s) out[base + s] = static_cast<float>(table.weights[base + s]);
    for (int pass = 0; pass < 4 && validatorWeightSum(&out[base], table.slots) != 1.0f; ++pass) {
      double sum = 0.0;
      for (std::size_t s = 0; s < slots; ++s) sum += out[base + s];
      out[base] = static_cast<float>(out[base] + (1.0 - sum));
    }
    for (std::size_t s = 0; s < slots; ++s) {
      if (out[base + s] == 0.0f) joints[base + s] = 0;  // underflowed: an unused slot
    }
  }
  return out;
}

// Normalized integer weights summing exactly to `scale` per vertex
// (largest-remainder rounding; ties: earlier slot, i.e. larger weight).
template <typename T>
std::vector<T> quantizeWeights(const InfluenceTable& table, std::uint32_t scale, std::vector<int>& joints) {
  std::vector<T> out(table.weights.size(), 0);
  const auto slots = static_cast<std::size_t>(table.slots);
  std::vector<std::pair<double, std::size_t>> remainders;
  for (std::size_t base = 0; base < out.size(); base += slots) {
    std::uint32_t total = 0;
    remainders.clear();
    for (std::size_t s = 0; s < slots; ++s) {
      const double exact = table.weights[base + s] * scale;
      const double floor = std::min(std::floor(exact), static_cast<double>(scale));
      out[base + s] = static_cast<T>(floor);
      total += static_cast<std::uint32_t>(floor);
      if (table.weights[base + s] > 0.0) remainders.emplace_back(exact - floor, s);
    }
    std::stable_sort(remainders.begin(), remainders.end(),
                     [](const auto& a, const auto& b) { return a.first > b.first; });
    for (std::size_t i = 0; total < scale && !remainders.empty(); i = (i + 1) % remainders.size(), ++total) {
      ++out[base + remainders[i].second];
    }
    for (std::size_t s = 0; s < slots; ++s) {
      if (out[base + s] == 0) joints[base + s] = 0;  // rounded away: an unused slot
    }
  }
  return out;
}

// Elements [4 * set, 4 * set + 4) of every vertex's `slots` values.
template <typename T, typename U>
std::vector<T> influenceSet(const std::vector<U>& values, int slots, int set) {
  std::vector<T> out;
  out.reserve(values.size() / static_cast<std::size_t>(slots) * 4);
  for (std::size_t base = 0; base < values.size(); base += static_cast<std::size_t>(slots)) {
    for (int c = 0; c < 4; ++c) out.push_back(static_cast<T>(values[base + static_cast<std::size_t>(set * 4 + c)]));
  }
  return out;
}

// JOINTS_n (unsigned byte below 256 joints, else short) for each set.
void addJointSets(tinygltf::Model& model, const std::vector<int>& joints, int slots, std::size_t joint_count,
                  tinygltf::Primitive& primitive) {
  const std::size_t nv = joints.size() / static_cast<std::size_t>(slots);
  for (int set = 0; set < slots / 4; ++set) {
    int view = 0;
    int type = TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE;
    if (joint_count <= 256) {
      view =
          addBufferView(model, asBytes(influenceSet<std::uint8_t>(joints, slots, set)), TINYGLTF_TARGET_ARRAY_BUFFER);
    } else {
      view =
          addBufferView(model, asBytes(influenceSet<std::uint16_t>(joints, slots, set)), TINYGLTF_TARGET_ARRAY_BUFFER);
      type = TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT;
    }
    primitive.attributes["JOINTS_" + std::to_string(set)] = addAccessor(model, view, type, TINYGLTF_TYPE_VEC4, nv);
  }
}

// WEIGHTS_n in the chosen encoding; zeroes the joints of slots left empty.
void addWeightSets(tinygltf::Model& model, const InfluenceTable& table, WeightEncoding encoding,
                   std::vector<int>& joints, tinygltf::Primitive& primitive) {
  const std::size_t nv = joints.size() / static_cast<std::size_t>(table.slots);
  std::vector<float> floats;
  std::vector<std::uint16_t> shorts;
  std::vector<std::uint8_t> bytes;
  if (encoding == WeightEncoding::kFloat) floats = encodeFloatWeights(table, joints);
  if (encoding == WeightEncoding::kUnorm16) shorts = quantizeWeights<std::uint16_t>(table, 65535, joints);
  if (encoding == WeightEncoding::kUnorm8) bytes = quantizeWeights<std::uint8_t>(table, 255, joints);
  for (int set = 0; set < table.slots / 4; ++set) {
    int view = 0;
    int type = TINYGLTF_COMPONENT_TYPE_FLOAT;
    if (encoding == WeightEncoding::kFloat) {
      view = addBufferView(model, asBytes(influenceSet<float>(floats, table.slots, set)), TINYGLTF_TARGET_ARRAY_BUFFER);
    } else if (encoding == WeightEncoding::kUnorm16) {
      view = addBufferView(model, asBytes(influenceSet<std::uint16_t>(shorts, table.slots, set)),
                           TINYGLTF_TARGET_ARRAY_BUFFER);
      type = TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT;
    } else {
      view = addBufferView(model, asBytes(influenceSet<std::uint8_t>(bytes, table.slots, set)),
                           TINYGLTF_TARGET_ARRAY_BUFFER);
      type = TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE;
    }
    const int accessor = addAccessor(model, view, type, TINYGLTF_TYPE_VEC4, nv);
    model.accessors[static_cast<std::size_t>(accessor)].normalized = encoding != WeightEncoding::kFloat;
    primitive.attributes["WEIGHTS_" + std::to_string(set)] = accessor;
  }
}

// Inverse bind matrices as a MAT4 float accessor, bottom rows exactly 0 0 0 1.
int addInverseBinds(tinygltf::Model& model, const Skin& skin) {
  std::vector<float> values;
  values.reserve(skin.inverse_bind.size() * 16);
  for (const Eigen::Matrix4d& m : skin.inverse_bind) {
    for (int c = 0; c < 4; ++c) {
      for (int r = 0; r < 3; ++r) values.push_back(static_cast<float>(m(r, c)));
      values.push_back(c == 3 ? 1.0f : 0.0f);
    }
  }
  return addFloatAccessor(model, values, TINYGLTF_TYPE_MAT4, /*target=*/0, false);
}

Status addSkin(tinygltf::Model& model, const Rig& rig, const RigWriteOptions& options, tinygltf::Primitive& primitive) {
  auto table = selectInfluences(rig.weights, options.max_influences);
  if (!table) return table.error();
  std::vector<int> joints = table->joints;
  addWeightSets(model, *table, options.weight_encoding, joints, primitive);  // before the joints: may zero some
  addJointSets(model, joints, table->slots, rig.skin->joints.size(), primitive);
  tinygltf::Skin skin;
  skin.name = rig.skin->name;
  skin.joints = rig.skin->joints;
  skin.skeleton = rig.skin->skeleton;
  skin.inverseBindMatrices = addInverseBinds(model, *rig.skin);
  model.skins.push_back(std::move(skin));
  return Ok{};
}

// A morph delta accessor (#V VEC3 floats): sparse (the rows with a non-zero
// component) when `sparse` and smaller than dense, with no data at all when
// every row is zero. `bounds` sets min/max over all rows, the implicit zeros
// included (the validator requires them for POSITION deltas).
int addDeltaAccessor(tinygltf::Model& model, const std::vector<float>& deltas, bool sparse, bool bounds) {
  const std::size_t count = deltas.size() / 3;
  if (!sparse) return addFloatAccessor(model, deltas, TINYGLTF_TYPE_VEC3, TINYGLTF_TARGET_ARRAY_BUFFER, bounds);
  // Which rows move, without a branch per row (moving and still rows
  // alternate unpredictably; mispredicted compares were most of the GLB
  // encode): a row moves when a component other than +-0 is in it.
  std::vector<std::uint32_t> moves(count);
  std::size_t moving = 0;
  for (std::size_t r = 0; r < count; ++r) {
    const std::uint32_t any = (std::bit_cast<std::uint32_t>(deltas[3 * r]) | std::bit_cast<std::uint32_t>(deltas[3 * r + 1]) |
                               std::bit_cast<std::uint32_t>(deltas[3 * r + 2])) &
                              0x7fffffffu;
    moves[r] = any != 0 ? 1u : 0u;
    moving += moves[r];
  }
  const bool short_indices = count <= 65536;
  const std::size_t index_size = short_indices ? 2 : 4;
  if (moving * (index_size + 12) >= count * 12) {
    return addFloatAccessor(model, deltas, TINYGLTF_TYPE_VEC3, TINYGLTF_TARGET_ARRAY_BUFFER, bounds);
  }
  // Compacted the same way: every row is written at the next free slot, which
  // only a moving row keeps (one spare slot for the last still rows).
  std::vector<std::uint32_t> rows(moving + 1);
  std::vector<float> values(3 * (moving + 1));
  for (std::size_t r = 0, k = 0; r < count; ++r) {
    rows[k] = static_cast<std::uint32_t>(r);
    std::copy_n(deltas.begin() + static_cast<std::ptrdiff_t>(3 * r), 3, values.begin() + static_cast<std::ptrdiff_t>(3 * k));
    k += moves[r];
    if (k == moving) break;  // the rest are still (and there is no slot past the spare)
  }
  rows.resize(moving);
  values.resize(3 * moving);
  std::vector<double> min;
  std::vector<double> max;
  if (bounds) std::tie(min, max) = floatBounds(deltas, 3);
  const int accessor = addAccessor(model, -1, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC3, count, min, max);
  if (rows.empty()) return accessor;  // no bufferView, no sparse: all zeros
  const int index_view = short_indices
                             ? addBufferView(model, asBytes(std::vector<std::uint16_t>(rows.begin(), rows.end())), 0)
                             : addBufferView(model, asBytes(rows), 0);
  const int value_view = addBufferView(model, asBytes(values), 0);
  auto& s = model.accessors[static_cast<std::size_t>(accessor)].sparse;
  s.isSparse = true;
  s.count = static_cast<int>(rows.size());
  s.indices.bufferView = index_view;
  s.indices.byteOffset = 0;
  s.indices.componentType =
      short_indices ? TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT : TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT;
  s.values.bufferView = value_view;
  s.values.byteOffset = 0;
  return accessor;
}

// Morph targets, their names (mesh.extras.targetNames) and default weights.
Status addMorphTargets(tinygltf::Model& model, const Rig& rig, const NodeSpace& space, bool sparse,
                       tinygltf::Primitive& primitive, tinygltf::Mesh& gmesh) {
  if (rig.morph_targets.empty()) return Ok{};
  tinygltf::Value::Array names;
  for (std::size_t t = 0; t < rig.morph_targets.size(); ++t) {
    const MorphTarget& target = rig.morph_targets[t];
    const std::string what = "morph target " + std::to_string(t) + quoted(target.name);
    const std::vector<float> positions = toFloats(space.vectors(target.position_deltas));
    if (const auto bad = firstNonFinite(positions)) {
      return invalidRig(what + " position delta of vertex " + std::to_string(*bad / 3) + " is not finite in float32");
    }
    std::map<std::string, int> attributes;
    attributes["POSITION"] = addDeltaAccessor(model, positions, sparse, /*bounds=*/true);
    if (target.normal_deltas.rows() > 0) {
      const std::vector<float> normals = toFloats(space.normals(target.normal_deltas));
      if (const auto bad = firstNonFinite(normals)) {
        return invalidRig(what + " normal delta of vertex " + std::to_string(*bad / 3) + " is not finite in float32");
      }
      attributes["NORMAL"] = addDeltaAccessor(model, normals, sparse, /*bounds=*/false);
    }
    primitive.targets.push_back(std::move(attributes));
    names.emplace_back(target.name);
  }
  const Eigen::VectorXd& defaults = rig.morph_default_weights;
  gmesh.weights.assign(rig.morph_targets.size(), 0.0);
  for (Eigen::Index t = 0; t < defaults.size(); ++t) gmesh.weights[static_cast<std::size_t>(t)] = defaults(t);
  tinygltf::Value::Object extras;
  extras["targetNames"] = tinygltf::Value(std::move(names));
  gmesh.extras = tinygltf::Value(std::move(extras));
  return Ok{};
}

const char* pathName(AnimationPath path) {
  switch (path) {
    case AnimationPath::kTranslation: return "translation";
    case AnimationPath::kRotation: return "rotation";
    case AnimationPath::kScale: return "scale";
    case AnimationPath::kWeights: return "weights";
  }
  return "translation";
}

const char* interpolationName(Interpolation interpolation) {
  switch (interpolation) {
    case Interpolation::kLinear: return "LINEAR";
    case Interpolation::kStep: return "STEP";
    case Interpolation::kCubicSpline: return "CUBICSPLINE";
  }
  return "LINEAR";
}

// Key times as a float SCALAR accessor with min/max (spec), shared between
// channels with the same times.
Result<int> addKeyTimes(tinygltf::Model& model, const Eigen::VectorXd& times, const std::string& what,
                        std::map<std::vector<float>, int>& shared) {
  if (times.size() == 0) return invalidRig(what + " has no keys");
  std::vector<float> t = toFloats(times);
  for (std::size_t k = 0; k < t.size(); ++k) {
    if (!std::isfinite(t[k]) || t[k] < 0.0f) {
      return invalidRig(what + " key time " + std::to_string(k) + " is negative or not finite");
    }
    if (k > 0 && !(t[k] > t[k - 1])) {
      return invalidRig(what + " key times do not increase (in float32) at key " + std::to_string(k));
    }
  }
  const auto it = shared.find(t);
  if (it != shared.end()) return it->second;
  const int accessor = addFloatAccessor(model, t, TINYGLTF_TYPE_SCALAR, /*target=*/0, /*bounds=*/true);
  shared.emplace(std::move(t), accessor);
  return accessor;
}

// Output values: VEC3 (translation, scale), unit VEC4 (rotation; cubic
// tangents as they are) or #targets scalars per key (weights).
Result<int> addKeyValues(tinygltf::Model& model, const AnimationChannel& channel, int columns,
                         const std::string& what) {
  const bool cubic = channel.interpolation == Interpolation::kCubicSpline;
  const Eigen::Index rows = channel.times.size() * (cubic ? 3 : 1);
  if (channel.values.rows() != rows || channel.values.cols() != columns) {
    return invalidRig(what + " values are " + std::to_string(channel.values.rows()) + " by " +
                      std::to_string(channel.values.cols()) + ", expected " + std::to_string(rows) + " by " +
                      std::to_string(columns));
  }
  std::vector<float> values = toFloats(channel.values);
  if (const auto bad = firstNonFinite(values)) {
    return invalidRig(what + " value " + std::to_string(*bad / static_cast<std::size_t>(columns)) +
                      " is not finite in float32");
  }
  if (channel.path == AnimationPath::kRotation) {
    for (Eigen::Index r = cubic ? 1 : 0; r < rows; r += cubic ? 3 : 1) {
      const Eigen::Vector4d q = channel.values.row(r).transpose();
      if (!(q.norm() > 0.0)) return invalidRig(what + " rotation key " + std::to_string(r) + " is a zero quaternion");
      for (int c = 0; c < 4; ++c) values[static_cast<std::size_t>(r * 4 + c)] = static_cast<float>(q(c) / q.norm());
    }
  }
  const int type = channel.path == AnimationPath::kWeights    ? TINYGLTF_TYPE_SCALAR
                   : channel.path == AnimationPath::kRotation ? TINYGLTF_TYPE_VEC4
                                                              : TINYGLTF_TYPE_VEC3;
  return addFloatAccessor(model, values, type, /*target=*/0, false);
}

// Output node of a channel: weights go to the node carrying the mesh.
Result<int> channelNode(const Rig& rig, const AnimationChannel& channel, const MeshNodePlan& plan,
                        const std::string& what) {
  if (channel.node < 0 || static_cast<std::size_t>(channel.node) >= rig.nodes.size()) {
    return invalidRig(what + " targets node " + std::to_string(channel.node) + " but the rig has " +
                      std::to_string(rig.nodes.size()) + " nodes");
  }
  if (channel.path != AnimationPath::kWeights) return channel.node;
  if (rig.morph_targets.empty() || channel.node != rig.mesh_node) {
    return invalidRig(what + " animates morph weights of " + nodeName(rig, channel.node) +
                      ", which does not carry the rig's morphed mesh");
  }
  return plan.node;
}

Status addAnimation(tinygltf::Model& model, const Rig& rig, const Animation& animation, const std::string& name,
                    const MeshNodePlan& plan, std::map<std::vector<float>, int>& shared_times) {
  tinygltf::Animation ganim;
  ganim.name = animation.name;
  std::set<std::pair<int, AnimationPath>> targets;
  for (std::size_t c = 0; c < animation.channels.size(); ++c) {
    const AnimationChannel& channel = animation.channels[c];
    const std::string what = name + " channel " + std::to_string(c);
    auto node = channelNode(rig, channel, plan, what);
    if (!node) return node.error();
    if (!targets.emplace(*node, channel.path).second) {
      return invalidRig(what + " animates the same node and path as an earlier channel");
    }
    const int columns = channel.path == AnimationPath::kRotation  ? 4
                        : channel.path == AnimationPath::kWeights ? static_cast<int>(rig.morph_targets.size())
                                                                  : 3;
    auto input = addKeyTimes(model, channel.times, what, shared_times);
    if (!input) return input.error();
    auto output = addKeyValues(model, channel, columns, what);
    if (!output) return output.error();
    tinygltf::AnimationSampler sampler;
    sampler.input = *input;
    sampler.output = *output;
    sampler.interpolation = interpolationName(channel.interpolation);
    ganim.samplers.push_back(std::move(sampler));
    tinygltf::AnimationChannel gchannel;
    gchannel.sampler = static_cast<int>(ganim.samplers.size()) - 1;
    gchannel.target_node = *node;
    gchannel.target_path = pathName(channel.path);
    ganim.channels.push_back(std::move(gchannel));
  }
  model.animations.push_back(std::move(ganim));
  return Ok{};
}

// Animations with channels (tinygltf drops empty ones; so do we).
Status addAnimations(tinygltf::Model& model, const Rig& rig, const MeshNodePlan& plan) {
  std::map<std::vector<float>, int> shared_times;
  for (std::size_t a = 0; a < rig.animations.size(); ++a) {
    const Animation& animation = rig.animations[a];
    if (animation.channels.empty()) continue;
    const std::string name = "animation " + std::to_string(a) + quoted(animation.name);
    if (auto ok = addAnimation(model, rig, animation, name, plan, shared_times); !ok) return ok.error();
  }
  return Ok{};
}

// Bytes the rig's buffer takes at most for usual rigs (morph targets dense,
// every attribute written, fields of up to 4 components): reserved once so
// appending does not re-copy the buffer. Only a capacity hint: a rig beyond
// it costs one reallocation; untouched reserve costs address space, not memory.
std::size_t rigBufferBound(const Rig& rig) {
  const auto nv = static_cast<std::size_t>(rig.mesh.vertexCount());
  std::size_t per_vertex = 3 * 12 + 2 * 8 + 2 * 16 * 4;  // position, normal, UVs, joints/weights (up to 2 sets)
  per_vertex += 16 * (rig.attributes.extra_uv_sets.size() + rig.attributes.fields.size() + rig.attributes.labels.size() + 1);
  std::size_t bytes = nv * per_vertex + static_cast<std::size_t>(rig.mesh.triangleCount()) * 12;
  for (const auto& t : rig.morph_targets) bytes += nv * 12 * (t.normal_deltas.rows() > 0 ? 2 : 1) + 64;
  for (const auto& a : rig.animations) {
    for (const auto& c : a.channels) bytes += static_cast<std::size_t>(c.values.size() + c.times.size()) * 4 + 64;
  }
  return bytes + 64 * (rig.nodes.size() + 1);
}

Result<tinygltf::Model> buildRigModel(const Rig& rig, const RigWriteOptions& options) {
  tinygltf::Model model;
  model.asset.version = "2.0";
  model.asset.generator = "rigport";
  model.buffers.emplace_back();
  model.buffers[0].data.reserve(rigBufferBound(rig));
  const MeshNodePlan plan = planMeshNode(rig);
  auto space = meshNodeSpace(rig, plan);
  if (!space) return space.error();
  std::optional<Mesh> local;
  if (!space->identity) local = meshInNodeSpace(rig.mesh, *space);
  auto primitive = addMeshPrimitive(model, local ? *local : rig.mesh, kRigLabel);
  if (!primitive) return primitive.error();
  if (auto ok = addVertexAttributes(model, rig, *primitive); !ok) return ok.error();
  if (rig.skin) {
    if (auto ok = addSkin(model, rig, options, *primitive); !ok) return ok.error();
  }
  tinygltf::Mesh gmesh;
  gmesh.name = rig.mesh_name;
  if (auto ok = addMorphTargets(model, rig, *space, options.sparse_morph_targets, *primitive, gmesh); !ok) {
    return ok.error();
  }
  gmesh.primitives.push_back(std::move(*primitive));
  model.meshes.push_back(std::move(gmesh));
  addRigNodes(model, rig, plan);
  if (auto ok = addAnimations(model, rig, plan); !ok) return ok.error();
  return model;
}

}  // namespace

Result<LoadedMesh> readGltf(std::span<const std::uint8_t> bytes, const std::string& label, bool binary) {
  return readGltfImpl(bytes, label, binary, std::nullopt);
}

Result<LoadedMesh> readGltfWithBaseDir(std::span<const std::uint8_t> bytes, const std::string& label, bool binary,
                                       const std::filesystem::path& base_dir) {
  return readGltfImpl(bytes, label, binary, base_dir);
}

Result<std::vector<std::uint8_t>> encodeMeshGlb(const Mesh& mesh) {
  const std::string label = "mesh to write";
  if (auto ok = validateMesh(mesh, label); !ok) return ok.error();
  if (mesh.vertexCount() == 0) return makeError(ErrorCode::kInvalidMesh, label + ": it has no vertices");

  tinygltf::Model model;
  model.asset.version = "2.0";
  model.asset.generator = "rigport";
  auto primitive = addMeshPrimitive(model, mesh, label);
  if (!primitive) return primitive.error();
  if (mesh.regions.size() > 0) {
    primitive->attributes[std::string("_") + kRegionAttribute] = addPaddedScalarAccessor(model, mesh.regions, false);
  }
  tinygltf::Mesh gmesh;
  gmesh.primitives.push_back(std::move(*primitive));
  model.meshes.push_back(std::move(gmesh));
  tinygltf::Node node;
  node.mesh = 0;
  model.nodes.push_back(std::move(node));
  tinygltf::Scene scene;
  scene.nodes.push_back(0);
  model.scenes.push_back(std::move(scene));
  model.defaultScene = 0;
  return serializeGlb(model);
}

Status writeMeshGlb(const Mesh& mesh, const std::filesystem::path& path) {
  auto bytes = encodeMeshGlb(mesh);
  if (!bytes) return makeError(bytes.error().code, path.filename().string() + ": " + bytes.error().message);
  return writeFileBytes(path, *bytes);
}

Result<LoadedRig> readRigGltf(std::span<const std::uint8_t> bytes, const std::string& label, bool binary) {
  return readRigImpl(bytes, label, binary, std::nullopt);
}

// Like readMesh: .glb / .gltf by extension, else by the GLB magic; a .gltf may
// use buffer files in its own directory.
Result<LoadedRig> readRig(const std::filesystem::path& path) {
  auto file = MappedFile::open(path);
  if (!file) return file.error();
  const std::span<const std::uint8_t> bytes = file->bytes();
  std::string ext = path.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  const bool magic = bytes.size() >= 4 && std::memcmp(bytes.data(), "glTF", 4) == 0;
  const bool binary = ext == ".glb" || (ext != ".gltf" && magic);
  return readRigImpl(bytes, path.filename().string(), binary, path.parent_path());
}

Result<std::vector<std::uint8_t>> encodeRigGlb(const Rig& rig, const RigWriteOptions& options) {
  if (auto ok = checkRig(rig, options); !ok) return ok.error();
  auto model = buildRigModel(rig, options);
  if (!model) return model.error();
  return serializeGlb(*model);
}

Status writeRigGlb(const Rig& rig, const std::filesystem::path& path, const RigWriteOptions& options) {
  auto bytes = encodeRigGlb(rig, options);
  if (!bytes) return makeError(bytes.error().code, path.filename().string() + ": " + bytes.error().message);
  return writeFileBytes(path, *bytes);
}

}  // namespace core
