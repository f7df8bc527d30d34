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
#include <cmath>
#include <cstring>
#include <fstream>  // tinygltf uses std::ofstream even with TINYGLTF_NO_FS
#include <limits>
#include <map>
#include <optional>
#include <sstream>
#include <string>
#include <string_view>
#include <system_error>
#include <vector>

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <nlohmann/json.hpp>

#include "core/mesh_io.h"

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

// Declared in core/mesh_io.cpp (readMesh passes the .gltf file's directory).
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
  nlohmann::json doc = nlohmann::json::parse(json_text.begin(), json_text.end(), nullptr, /*allow_exceptions=*/false);
  if (doc.is_discarded()) return parseError(label, "the glTF JSON is malformed");
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

void decodeElement(const std::uint8_t* src, const ElementLayout& layout, int component_type, bool normalized,
                   double* dst) {
  for (int c = 0; c < layout.columns; ++c) {
    for (int r = 0; r < layout.rows; ++r) {
      *dst++ = decodeComponent(src + static_cast<std::size_t>(c) * layout.column_stride +
                                   static_cast<std::size_t>(r) * layout.component_size,
                               component_type, normalized);
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

// Applies accessor.sparse: `values` already holds the dense (or zero) data.
Status applySparse(const tinygltf::Model& model, const tinygltf::Accessor& accessor, const ElementLayout& layout,
                   const std::string& what, const std::string& label, AccessorValues& out) {
  const auto& sparse = accessor.sparse;
  if (sparse.count < 0 || static_cast<std::size_t>(sparse.count) > accessor.count) {
    return parseError(label, what + " has a sparse count of " + std::to_string(sparse.count) + " for " +
                                 std::to_string(accessor.count) + " elements");
  }
  if (sparse.indices.byteOffset < 0 || sparse.values.byteOffset < 0) {
    return parseError(label, what + " has a negative sparse byteOffset");
  }
  const auto n = static_cast<std::size_t>(sparse.count);
  const int index_type = sparse.indices.componentType;
  if (index_type != TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE && index_type != TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT &&
      index_type != TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT) {
    return parseError(label, what + " has sparse indices of invalid componentType " + std::to_string(index_type));
  }
  const std::size_t index_size = static_cast<std::size_t>(componentSize(index_type));
  auto indices = viewRange(model, sparse.indices.bufferView, static_cast<std::size_t>(sparse.indices.byteOffset),
                           spanBytes(n, index_size, index_size), what + " sparse indices", label);
  if (!indices) return indices.error();
  auto values = viewRange(model, sparse.values.bufferView, static_cast<std::size_t>(sparse.values.byteOffset),
                          spanBytes(n, layout.size, layout.size), what + " sparse values", label);
  if (!values) return values.error();

  for (std::size_t i = 0; i < n; ++i) {
    const double index = decodeComponent(*indices + i * index_size, index_type, false);
    if (index >= static_cast<double>(accessor.count)) {
      return parseError(label, what + " sparse index " + std::to_string(i) + " is " +
                                   std::to_string(static_cast<std::uint64_t>(index)) + " but the accessor has " +
                                   std::to_string(accessor.count) + " elements");
    }
    decodeElement(*values + i * layout.size, layout, accessor.componentType, accessor.normalized,
                  out.values.data() + static_cast<std::size_t>(index) * static_cast<std::size_t>(out.components));
  }
  return Ok{};
}

// Reads accessor `index` (any type, stride, normalisation, sparse) as doubles.
// `role` says what it is for ("POSITION", "indices") in error messages.
Result<AccessorValues> readAccessor(const tinygltf::Model& model, int index, const std::string& role,
                                    const std::string& label) {
  const std::string what = "accessor " + std::to_string(index) + " (" + role + ")";
  if (index < 0 || static_cast<std::size_t>(index) >= model.accessors.size()) {
    return parseError(label, role + " refers to accessor " + std::to_string(index) + " but the file has " +
                                 std::to_string(model.accessors.size()));
  }
  const tinygltf::Accessor& accessor = model.accessors[static_cast<std::size_t>(index)];
  const ElementLayout layout = elementLayout(accessor.type, accessor.componentType);
  if (layout.rows == 0) return parseError(label, what + " has an invalid type");
  if (layout.component_size == 0) {
    return parseError(label, what + " has unsupported componentType " + std::to_string(accessor.componentType));
  }

  AccessorValues out;
  out.count = accessor.count;
  out.components = layout.rows * layout.columns;
  const std::size_t components = static_cast<std::size_t>(out.components);
  if (accessor.bufferView < 0) {
    if (accessor.count > kMaxImplicitAccessorCount) {
      return parseError(label, what + " has no bufferView and claims " + std::to_string(accessor.count) +
                                   " elements (more than the " + std::to_string(kMaxImplicitAccessorCount) +
                                   " supported)");
    }
    out.values.assign(accessor.count * components, 0.0);  // spec: no bufferView means zeros
  } else {
    const tinygltf::BufferView* view = static_cast<std::size_t>(accessor.bufferView) < model.bufferViews.size()
                                           ? &model.bufferViews[static_cast<std::size_t>(accessor.bufferView)]
                                           : nullptr;
    const std::size_t stride = view && view->byteStride != 0 ? view->byteStride : layout.size;
    if (stride < layout.size) {
      return parseError(label, what + " has elements of " + std::to_string(layout.size) +
                                   " bytes but bufferView byteStride " + std::to_string(stride));
    }
    auto data = viewRange(model, accessor.bufferView, accessor.byteOffset,
                          spanBytes(accessor.count, stride, layout.size), what, label);
    if (!data) return data.error();
    // The range check above bounds count by the buffer size, so this
    // allocation is at most a few times the file size.
    out.values.resize(accessor.count * components);
    for (std::size_t i = 0; i < accessor.count; ++i) {
      decodeElement(*data + i * stride, layout, accessor.componentType, accessor.normalized,
                    out.values.data() + i * components);
    }
  }
  if (accessor.sparse.isSparse) {
    if (auto ok = applySparse(model, accessor, layout, what, label, out); !ok) return ok.error();
  }
  return out;
}

// Reads a per-vertex attribute with the expected component count.
Result<AccessorValues> readAttribute(const tinygltf::Model& model, int index, const std::string& role,
                                     int components, const std::string& label) {
  auto values = readAccessor(model, index, role, label);
  if (!values) return values;
  if (values->components != components) {
    return parseError(label, "accessor " + std::to_string(index) + " (" + role + ") has " +
                                 std::to_string(values->components) + " components per element, expected " +
                                 std::to_string(components));
  }
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
  auto positions = readAttribute(model, position_it->second, "POSITION", 3, label);
  if (!positions) return positions.error();
  const std::size_t nv = positions->count;
  out.positions.resize(static_cast<Eigen::Index>(nv), 3);
  for (std::size_t v = 0; v < nv; ++v) {
    for (int c = 0; c < 3; ++c) out.positions(static_cast<Eigen::Index>(v), c) = positions->at(v, c);
  }

  auto read_optional = [&](const char* name, int components, auto& target) -> Status {
    const auto it = primitive.attributes.find(name);
    if (it == primitive.attributes.end()) return Ok{};
    auto values = readAttribute(model, it->second, name, components, label);
    if (!values) return values.error();
    if (values->count != nv) {
      return parseError(label, what + " " + name + " has " + std::to_string(values->count) +
                                   " elements but POSITION has " + std::to_string(nv));
    }
    target.resize(static_cast<Eigen::Index>(nv), components);
    for (std::size_t v = 0; v < nv; ++v) {
      for (int c = 0; c < components; ++c) target(static_cast<Eigen::Index>(v), c) = values->at(v, c);
    }
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
  const Eigen::MatrixX3d computed = computeVertexNormals(mesh.positions, mesh.triangles);
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

  const double diagonal = boundingBoxDiagonal(mesh.positions);
  for (Eigen::Index f = 0; f < mesh.triangles.rows(); ++f) {
    if (isDegenerateTriangle(mesh.positions, mesh.triangles.row(f).transpose(), diagonal)) ++report.degenerate_triangles;
  }
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

Result<LoadedMesh> readGltfImpl(Bytes bytes, const std::string& label, bool binary,
                                const std::optional<std::filesystem::path>& base_dir) {
  LoadedMesh loaded;
  loaded.report.format = binary ? MeshFormat::kGlb : MeshFormat::kGltf;
  auto model = loadModel(bytes, label, binary, base_dir, loaded.report.warnings);
  if (!model) return model.error();
  if (auto ok = checkRequiredExtensions(*model, label, loaded.report.warnings); !ok) return ok.error();
  loaded.report.meshes_in_file = static_cast<int>(model->meshes.size());
  auto choice = chooseMesh(*model, label);
  if (!choice) return choice.error();
  loaded.report.chosen_mesh = choice->description;
  return buildMesh(*model, *choice, label, std::move(loaded));
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

// Float accessor from `values` (count * components floats, row-major). With
// `bounds`, min/max are set from the float values themselves, as the spec
// requires for POSITION (and the validator checks exactly).
int addFloatAccessor(tinygltf::Model& model, const std::vector<float>& values, int type, int target, bool bounds) {
  const int components = elementShape(type).first * elementShape(type).second;
  const std::size_t count = values.size() / static_cast<std::size_t>(components);
  std::vector<double> min;
  std::vector<double> max;
  if (bounds && count > 0) {
    min.assign(static_cast<std::size_t>(components), std::numeric_limits<double>::infinity());
    max.assign(static_cast<std::size_t>(components), -std::numeric_limits<double>::infinity());
    for (std::size_t i = 0; i < values.size(); ++i) {
      const std::size_t c = i % static_cast<std::size_t>(components);
      min[c] = std::min(min[c], static_cast<double>(values[i]));
      max[c] = std::max(max[c], static_cast<double>(values[i]));
    }
  }
  const int view = addBufferView(model, asBytes(values), target);
  return addAccessor(model, view, TINYGLTF_COMPONENT_TYPE_FLOAT, type, count, std::move(min), std::move(max));
}

template <int Cols>
std::vector<float> toFloats(const Eigen::Matrix<double, Eigen::Dynamic, Cols>& m) {
  std::vector<float> out(static_cast<std::size_t>(m.rows()) * Cols);
  for (Eigen::Index r = 0; r < m.rows(); ++r) {
    for (int c = 0; c < Cols; ++c) out[static_cast<std::size_t>(r) * Cols + c] = static_cast<float>(m(r, c));
  }
  return out;
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

// Serialises `model` as GLB bytes (tinygltf's writer; deterministic since its
// JSON objects are ordered maps).
Result<std::vector<std::uint8_t>> serializeGlb(const tinygltf::Model& model) {
  tinygltf::TinyGLTF writer;
  std::ostringstream stream;
  try {
    if (!writer.WriteGltfSceneToStream(&model, stream, /*prettyPrint=*/false, /*writeBinary=*/true)) {
      return makeError(ErrorCode::kIo, "GLB serialisation failed");
    }
  } catch (const std::exception& e) {
    return makeError(ErrorCode::kIo, std::string("GLB serialisation failed: ") + e.what());
  }
  const std::string text = std::move(stream).str();
  return std::vector<std::uint8_t>(text.begin(), text.end());
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
  if (auto ok = validateMesh(mesh, "mesh to write"); !ok) return ok.error();
  if (mesh.vertexCount() == 0) return makeError(ErrorCode::kInvalidMesh, "mesh to write: it has no vertices");

  tinygltf::Model model;
  model.asset.version = "2.0";
  model.asset.generator = "rigport";

  // glTF stores float32: a finite double can still overflow it.
  const std::vector<float> positions = toFloats<3>(mesh.positions);
  if (const auto bad = std::find_if(positions.begin(), positions.end(), [](float x) { return !std::isfinite(x); });
      bad != positions.end()) {
    return makeError(ErrorCode::kInvalidMesh, "mesh to write: vertex " + std::to_string((bad - positions.begin()) / 3) +
                                                  " position exceeds the float32 range of glTF");
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
        addFloatAccessor(model, toFloats<2>(mesh.uvs), TINYGLTF_TYPE_VEC2, TINYGLTF_TARGET_ARRAY_BUFFER, false);
  }
  if (mesh.triangleCount() > 0) {
    std::vector<std::uint32_t> indices(static_cast<std::size_t>(mesh.triangleCount()) * 3);
    for (Eigen::Index f = 0; f < mesh.triangleCount(); ++f) {
      for (int k = 0; k < 3; ++k) indices[static_cast<std::size_t>(f) * 3 + k] = static_cast<std::uint32_t>(mesh.triangles(f, k));
    }
    const int view = addBufferView(model, asBytes(indices), TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER);
    primitive.indices =
        addAccessor(model, view, TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT, TINYGLTF_TYPE_SCALAR, indices.size());
    primitive.mode = TINYGLTF_MODE_TRIANGLES;
  } else {
    primitive.mode = TINYGLTF_MODE_POINTS;  // point cloud: every vertex drawn once
  }

  tinygltf::Mesh gmesh;
  gmesh.primitives.push_back(std::move(primitive));
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

}  // namespace core
