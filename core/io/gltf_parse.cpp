// glTF reading, first steps: the GLB container and JSON checked before
// tinygltf sees them, tinygltf's load (with file access confined to the
// glTF's directory), the scene's mesh chosen. tinygltf's err/warn strings
// become core::Error / report warnings here. Compiles tinygltf itself.
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
// bytes, and every accessor read (gltf_accessors.cpp) is bounds-checked with overflow-safe
// arithmetic. Truncated or corrupt files give kParse, never a bad read.

#define TINYGLTF_IMPLEMENTATION
#include "core/io/gltf_model.h"

namespace core::gltf {

std::string quoted(const std::string& name) { return name.empty() ? std::string() : " '" + name + "'"; }

Error parseError(const std::string& label, const std::string& what) {
  return makeError(ErrorCode::kParse, label + ": " + what);
}

namespace {

// tinygltf messages end with newlines and sometimes hold several lines.
std::string tidyMessage(std::string text) {
  while (!text.empty() && (text.back() == '\n' || text.back() == ' ' || text.back() == '.')) text.pop_back();
  std::replace(text.begin(), text.end(), '\n', ' ');
  return text;
}

}  // namespace

std::uint32_t readLe32(const std::uint8_t* p) {
  return static_cast<std::uint32_t>(p[0]) | static_cast<std::uint32_t>(p[1]) << 8 |
         static_cast<std::uint32_t>(p[2]) << 16 | static_cast<std::uint32_t>(p[3]) << 24;
}

namespace {

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
// Images are never decoded (no pixels are needed): the encoded bytes are kept
// for the rig's materials to write back as they came.
bool keepEncodedImage(tinygltf::Image* image, const int, std::string*, std::string*, int, int,
                      const unsigned char* bytes, int size, void*) {
  if (bytes != nullptr && size > 0) image->image.assign(bytes, bytes + size);
  image->as_is = true;
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
  loader.SetImageLoader(&keepEncodedImage, nullptr);
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

}  // namespace

// ---------------------------------------------------------------------------
// Scene graph: which mesh, which node, which transform

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
static std::size_t primitiveElementCount(const tinygltf::Model& model, const tinygltf::Primitive& primitive) {
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

namespace {

std::size_t meshTriangleCount(const tinygltf::Model& model, const tinygltf::Mesh& mesh) {
  std::size_t total = 0;
  for (const auto& primitive : mesh.primitives) total += primitiveTriangleCount(model, primitive);
  return total;
}

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

}  // namespace

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

}  // namespace core::gltf
