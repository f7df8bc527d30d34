// PLY reading, by hand (Greg Turk's format as written by most tools: "ascii"
// and "binary_little_endian" 1.0). Vertices keep the file's order; polygons
// are fan-triangulated; elements and properties we do not use are skipped.
//
// Every count in the header is checked against the bytes that follow before
// anything is allocated, so a header claiming 10^12 vertices is an error, not
// an allocation.
#include <algorithm>
#include <bit>
#include <charconv>
#include <cmath>
#include <cstring>
#include <limits>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "core/io/mesh_io.h"

namespace core {
namespace {

enum class PlyType { kInt8, kUint8, kInt16, kUint16, kInt32, kUint32, kFloat32, kFloat64 };

std::optional<PlyType> parseType(std::string_view name) {
  if (name == "char" || name == "int8") return PlyType::kInt8;
  if (name == "uchar" || name == "uint8") return PlyType::kUint8;
  if (name == "short" || name == "int16") return PlyType::kInt16;
  if (name == "ushort" || name == "uint16") return PlyType::kUint16;
  if (name == "int" || name == "int32") return PlyType::kInt32;
  if (name == "uint" || name == "uint32") return PlyType::kUint32;
  if (name == "float" || name == "float32") return PlyType::kFloat32;
  if (name == "double" || name == "float64") return PlyType::kFloat64;
  return std::nullopt;
}

std::size_t typeSize(PlyType type) {
  switch (type) {
    case PlyType::kInt8:
    case PlyType::kUint8: return 1;
    case PlyType::kInt16:
    case PlyType::kUint16: return 2;
    case PlyType::kInt32:
    case PlyType::kUint32:
    case PlyType::kFloat32: return 4;
    case PlyType::kFloat64: return 8;
  }
  return 1;
}

struct PlyProperty {
  std::string name;
  PlyType type = PlyType::kFloat32;        // value type (list entries for a list)
  bool is_list = false;
  PlyType count_type = PlyType::kUint8;    // lists only
};

struct PlyElement {
  std::string name;
  std::uint64_t count = 0;
  std::vector<PlyProperty> properties;

  int find(std::string_view property) const {
    for (std::size_t i = 0; i < properties.size(); ++i) {
      if (properties[i].name == property) return static_cast<int>(i);
    }
    return -1;
  }
};

struct PlyHeader {
  bool ascii = false;
  std::vector<PlyElement> elements;
  std::size_t data_offset = 0;  // first byte after "end_header\n"
};

std::vector<std::string_view> splitWords(std::string_view line) {
  std::vector<std::string_view> words;
  std::size_t pos = 0;
  while (pos < line.size()) {
    while (pos < line.size() && (line[pos] == ' ' || line[pos] == '\t')) ++pos;
    const std::size_t begin = pos;
    while (pos < line.size() && line[pos] != ' ' && line[pos] != '\t') ++pos;
    if (pos > begin) words.push_back(line.substr(begin, pos - begin));
  }
  return words;
}

// Shortest round-trip text of a value ("10", "0.5", "nan").
std::string formatValue(double value) {
  if (std::isnan(value)) return "nan";
  if (std::isinf(value)) return value > 0 ? "inf" : "-inf";
  char buf[32];
  const auto result = std::to_chars(buf, buf + sizeof(buf), value);
  return std::string(buf, result.ptr);
}

Error headerError(const std::string& label, std::size_t line, const std::string& what) {
  return makeError(ErrorCode::kParse, label + ": PLY header line " + std::to_string(line) + ": " + what);
}

Result<PlyHeader> parseHeader(std::string_view text, const std::string& label) {
  PlyHeader header;
  std::size_t pos = 0;
  std::size_t line_number = 0;
  bool have_format = false;
  for (;;) {
    const std::size_t end = text.find('\n', pos);
    if (end == std::string_view::npos) {
      return makeError(ErrorCode::kParse, label + ": PLY header has no end_header line (truncated or not PLY)");
    }
    std::string_view line = text.substr(pos, end - pos);
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    pos = end + 1;
    ++line_number;
    const std::vector<std::string_view> words = splitWords(line);
    if (line_number == 1) {
      if (words.size() != 1 || words[0] != "ply") return makeError(ErrorCode::kParse, label + ": not a PLY file");
      continue;
    }
    if (words.empty() || words[0] == "comment" || words[0] == "obj_info") continue;
    if (words[0] == "end_header") break;
    if (words[0] == "format") {
      if (words.size() != 3) return headerError(label, line_number, "malformed format line");
      if (words[2] != "1.0" && words[2] != "1") {
        return makeError(ErrorCode::kUnsupported, label + ": PLY version " + std::string(words[2]) + " (only 1.0)");
      }
      if (words[1] == "ascii") {
        header.ascii = true;
      } else if (words[1] == "binary_little_endian") {
        header.ascii = false;
      } else if (words[1] == "binary_big_endian") {
        return makeError(ErrorCode::kUnsupported,
                         label + ": binary_big_endian PLY is not supported (convert to binary_little_endian)");
      } else {
        return headerError(label, line_number, "unknown format '" + std::string(words[1]) + "'");
      }
      have_format = true;
    } else if (words[0] == "element") {
      PlyElement element;
      if (words.size() != 3) return headerError(label, line_number, "malformed element line");
      element.name = std::string(words[1]);
      const auto [ptr, ec] = std::from_chars(words[2].data(), words[2].data() + words[2].size(), element.count);
      if (ec != std::errc() || ptr != words[2].data() + words[2].size()) {
        return headerError(label, line_number, "element count '" + std::string(words[2]) + "' is not a number");
      }
      for (const PlyElement& other : header.elements) {
        if (other.name == element.name) return headerError(label, line_number, "element '" + element.name + "' repeated");
      }
      header.elements.push_back(std::move(element));
    } else if (words[0] == "property") {
      if (header.elements.empty()) return headerError(label, line_number, "property before any element");
      PlyProperty property;
      if (words.size() == 5 && words[1] == "list") {
        const auto count_type = parseType(words[2]);
        const auto value_type = parseType(words[3]);
        if (!count_type || !value_type) return headerError(label, line_number, "unknown list property type");
        if (*count_type == PlyType::kFloat32 || *count_type == PlyType::kFloat64) {
          return headerError(label, line_number, "list count type must be an integer type");
        }
        property.is_list = true;
        property.count_type = *count_type;
        property.type = *value_type;
        property.name = std::string(words[4]);
      } else if (words.size() == 3) {
        const auto type = parseType(words[1]);
        if (!type) return headerError(label, line_number, "unknown property type '" + std::string(words[1]) + "'");
        property.type = *type;
        property.name = std::string(words[2]);
      } else {
        return headerError(label, line_number, "malformed property line");
      }
      header.elements.back().properties.push_back(std::move(property));
    } else {
      return headerError(label, line_number, "unknown keyword '" + std::string(words[0].substr(0, 32)) + "'");
    }
  }
  if (!have_format) return makeError(ErrorCode::kParse, label + ": PLY header has no format line");
  header.data_offset = pos;
  return header;
}

// Reads values of the body, ASCII tokens or little-endian binary.
class PlyValueReader {
 public:
  enum class Status { kOk, kEnd, kMalformed };

  PlyValueReader(std::span<const std::uint8_t> data, bool ascii) : data_(data), ascii_(ascii) {}

  Status read(PlyType type, double& value) { return ascii_ ? readAscii(value) : readBinary(type, value); }

  std::size_t remaining() const { return data_.size() - pos_; }
  bool ascii() const { return ascii_; }
  std::string lastToken() const { return std::string(last_token_.substr(0, 32)); }

 private:
  static bool isSpace(std::uint8_t c) { return c == ' ' || c == '\t' || c == '\r' || c == '\n'; }

  Status readAscii(double& value) {
    while (pos_ < data_.size() && isSpace(data_[pos_])) ++pos_;
    if (pos_ == data_.size()) return Status::kEnd;
    const std::size_t begin = pos_;
    while (pos_ < data_.size() && !isSpace(data_[pos_])) ++pos_;
    last_token_ = std::string_view(reinterpret_cast<const char*>(data_.data()) + begin, pos_ - begin);
    std::string_view token = last_token_;
    if (token.size() > 1 && token.front() == '+' && token[1] != '-') token.remove_prefix(1);
    const auto [end, ec] = std::from_chars(token.data(), token.data() + token.size(), value);
    if (end != token.data() + token.size()) return Status::kMalformed;
    if (ec == std::errc::result_out_of_range) {
      value = token.front() == '-' ? -HUGE_VAL : HUGE_VAL;  // reported as non-finite
      return Status::kOk;
    }
    return ec == std::errc() ? Status::kOk : Status::kMalformed;
  }

  Status readBinary(PlyType type, double& value) {
    const std::size_t size = typeSize(type);
    if (remaining() < size) return Status::kEnd;
    std::uint64_t bits = 0;
    for (std::size_t i = 0; i < size; ++i) bits |= static_cast<std::uint64_t>(data_[pos_ + i]) << (8 * i);
    pos_ += size;
    switch (type) {
      case PlyType::kInt8: value = static_cast<std::int8_t>(bits); break;
      case PlyType::kUint8: value = static_cast<std::uint8_t>(bits); break;
      case PlyType::kInt16: value = static_cast<std::int16_t>(bits); break;
      case PlyType::kUint16: value = static_cast<std::uint16_t>(bits); break;
      case PlyType::kInt32: value = static_cast<std::int32_t>(bits); break;
      case PlyType::kUint32: value = static_cast<std::uint32_t>(bits); break;
      case PlyType::kFloat32: value = std::bit_cast<float>(static_cast<std::uint32_t>(bits)); break;
      case PlyType::kFloat64: value = std::bit_cast<double>(bits); break;
    }
    return Status::kOk;
  }

  std::span<const std::uint8_t> data_;
  bool ascii_;
  std::size_t pos_ = 0;
  std::string_view last_token_;
};

// Smallest number of bytes one element can occupy: lets a count be rejected
// before allocating. Binary: fixed sizes plus list counts (empty lists).
// ASCII: each value needs at least one character and one separator.
std::size_t minElementBytes(const PlyElement& element, bool ascii) {
  std::size_t bytes = 0;
  for (const PlyProperty& p : element.properties) {
    bytes += ascii ? 2 : typeSize(p.is_list ? p.count_type : p.type);
  }
  return bytes;
}

Status checkCountFits(const PlyElement& element, const PlyValueReader& reader, const std::string& label) {
  if (element.count == 0) return Ok{};
  if (element.properties.empty()) {
    return makeError(ErrorCode::kParse, label + ": PLY element '" + element.name + "' has no properties");
  }
  const std::size_t per_element = minElementBytes(element, reader.ascii());
  // ASCII: the last value in the file needs no separator after it.
  const std::size_t available = reader.remaining() + (reader.ascii() ? 1 : 0);
  if (element.count > available / per_element) {
    return makeError(ErrorCode::kParse, label + ": PLY header claims " + std::to_string(element.count) + " '" +
                                            element.name + "' elements (at least " + std::to_string(per_element) +
                                            " bytes each) but only " + std::to_string(reader.remaining()) +
                                            " bytes of data follow (truncated?)");
  }
  return Ok{};
}

// Reads one value, turning end-of-data and bad tokens into errors naming the
// element and its index.
class ElementCursor {
 public:
  ElementCursor(PlyValueReader& reader, const PlyElement& element, const std::string& label)
      : reader_(reader), element_(element), label_(label) {}

  Status value(PlyType type, std::uint64_t index, double& out) {
    switch (reader_.read(type, out)) {
      case PlyValueReader::Status::kOk: return Ok{};
      case PlyValueReader::Status::kEnd:
        return makeError(ErrorCode::kParse, label_ + ": PLY data ends inside " + element_.name + " " +
                                                std::to_string(index) + " (truncated file)");
      case PlyValueReader::Status::kMalformed: break;
    }
    return makeError(ErrorCode::kParse, label_ + ": " + element_.name + " " + std::to_string(index) + ": '" +
                                            reader_.lastToken() + "' is not a number");
  }

  // List length: a non-negative integer that the remaining data can hold.
  Status listCount(const PlyProperty& property, std::uint64_t index, std::size_t& count) {
    double n = 0;
    if (auto ok = value(property.count_type, index, n); !ok) return ok;
    const std::size_t min_bytes = reader_.ascii() ? 2 : typeSize(property.type);
    if (!(n >= 0) || n != std::floor(n) || n > static_cast<double>(reader_.remaining() / min_bytes + 1)) {
      return makeError(ErrorCode::kParse, label_ + ": " + element_.name + " " + std::to_string(index) +
                                              " has an invalid list length for '" + property.name + "'");
    }
    count = static_cast<std::size_t>(n);
    return Ok{};
  }

  // Reads (and drops) one property of any kind.
  Status skip(const PlyProperty& property, std::uint64_t index) {
    double unused = 0;
    if (!property.is_list) return value(property.type, index, unused);
    std::size_t count = 0;
    if (auto ok = listCount(property, index, count); !ok) return ok;
    for (std::size_t i = 0; i < count; ++i) {
      if (auto ok = value(property.type, index, unused); !ok) return ok;
    }
    return Ok{};
  }

 private:
  PlyValueReader& reader_;
  const PlyElement& element_;
  const std::string& label_;
};

// Property roles of the vertex element (-1: absent).
struct VertexLayout {
  int xyz[3] = {-1, -1, -1};
  int normal[3] = {-1, -1, -1};
  int uv[2] = {-1, -1};
  int region = -1;  // "region": integer region labels (Mesh::regions)
};

VertexLayout vertexLayout(const PlyElement& element) {
  VertexLayout layout;
  const char* xyz[3] = {"x", "y", "z"};
  const char* normal[3] = {"nx", "ny", "nz"};
  for (int c = 0; c < 3; ++c) {
    layout.xyz[c] = element.find(xyz[c]);
    layout.normal[c] = element.find(normal[c]);
  }
  const char* uv_names[4][2] = {{"u", "v"}, {"s", "t"}, {"texture_u", "texture_v"}, {"texture_s", "texture_t"}};
  for (const auto& names : uv_names) {
    if (element.find(names[0]) >= 0 && element.find(names[1]) >= 0) {
      layout.uv[0] = element.find(names[0]);
      layout.uv[1] = element.find(names[1]);
      break;
    }
  }
  layout.region = element.find("region");
  return layout;
}

struct VertexData {
  Eigen::MatrixX3d positions;
  Eigen::MatrixX3d normals;
  Eigen::MatrixX2d uvs;
  Eigen::VectorXi regions;
};

Result<VertexData> readVertices(PlyValueReader& reader, const PlyElement& element, const std::string& label,
                                MeshReadReport& report) {
  VertexLayout layout = vertexLayout(element);
  for (int c = 0; c < 3; ++c) {
    const int p = layout.xyz[c];
    if (p < 0 || element.properties[static_cast<std::size_t>(p)].is_list) {
      return makeError(ErrorCode::kParse, label + ": PLY vertex element has no scalar '" + "xyz"[c] + "' property");
    }
  }
  const bool has_normals = std::all_of(std::begin(layout.normal), std::end(layout.normal), [&](int p) {
    return p >= 0 && !element.properties[static_cast<std::size_t>(p)].is_list;
  });
  const bool has_uvs = layout.uv[0] >= 0 && !element.properties[static_cast<std::size_t>(layout.uv[0])].is_list &&
                       !element.properties[static_cast<std::size_t>(layout.uv[1])].is_list;
  if (!has_normals && std::any_of(std::begin(layout.normal), std::end(layout.normal), [](int p) { return p >= 0; })) {
    report.warnings.push_back("PLY vertex normals incomplete (need nx, ny and nz); ignored");
  }
  // Region labels (as glTF _REGION): an integer scalar 0..kMaxRegionLabel,
  // else warned and left out of the matching.
  bool has_regions = layout.region >= 0;
  if (has_regions) {
    const PlyProperty& property = element.properties[static_cast<std::size_t>(layout.region)];
    if (property.is_list || property.type == PlyType::kFloat32 || property.type == PlyType::kFloat64) {
      report.warnings.push_back("PLY vertex property 'region' is not an integer scalar; not used for region matching");
      has_regions = false;
    }
  }
  // Which role each property fills: 0..2 position, 3..5 normal, 6..7 uv, 8
  // region, -1 none.
  std::vector<int> role(element.properties.size(), -1);
  for (int c = 0; c < 3; ++c) {
    role[static_cast<std::size_t>(layout.xyz[c])] = c;
    if (has_normals) role[static_cast<std::size_t>(layout.normal[c])] = 3 + c;
  }
  if (has_uvs) {
    role[static_cast<std::size_t>(layout.uv[0])] = 6;
    role[static_cast<std::size_t>(layout.uv[1])] = 7;
  }
  if (has_regions) role[static_cast<std::size_t>(layout.region)] = 8;

  if (auto ok = checkCountFits(element, reader, label); !ok) return ok.error();
  const auto nv = static_cast<Eigen::Index>(element.count);
  VertexData out;
  out.positions.resize(nv, 3);
  if (has_normals) out.normals.resize(nv, 3);
  if (has_uvs) out.uvs.resize(nv, 2);
  if (has_regions) out.regions.resize(nv);
  std::string region_problem;
  ElementCursor cursor(reader, element, label);
  for (Eigen::Index v = 0; v < nv; ++v) {
    const auto index = static_cast<std::uint64_t>(v);
    for (std::size_t p = 0; p < element.properties.size(); ++p) {
      const PlyProperty& property = element.properties[p];
      if (role[p] < 0) {
        if (auto ok = cursor.skip(property, index); !ok) return ok.error();
        continue;
      }
      double value = 0;
      if (auto ok = cursor.value(property.type, index, value); !ok) return ok.error();
      if (role[p] < 3) {
        if (!std::isfinite(value)) {
          return makeError(ErrorCode::kInvalidMesh, label + ": vertex " + std::to_string(v) +
                                                        " has a non-finite coordinate (" + "xyz"[role[p]] + " = " +
                                                        formatValue(value) + ")");
        }
        out.positions(v, role[p]) = value;
      } else if (role[p] < 6) {
        out.normals(v, role[p] - 3) = value;
      } else if (role[p] == 8) {
        const bool in_range = value >= 0 && value <= kMaxRegionLabel;
        if (!in_range && region_problem.empty()) {
          region_problem = "PLY vertex property 'region' of vertex " + std::to_string(v) + " is " + formatValue(value) +
                           " (region labels are 0.." + std::to_string(kMaxRegionLabel) + "); not used for region matching";
        }
        out.regions(v) = in_range ? static_cast<int>(value) : 0;
      } else {
        // PLY texture coordinates follow OpenGL (v up); glTF's v points down.
        out.uvs(v, role[p] - 6) = role[p] == 7 ? 1.0 - value : value;
      }
    }
  }
  if (!region_problem.empty()) {
    report.warnings.push_back(region_problem);
    out.regions.resize(0);
  }
  for (Eigen::Index v = 0; v < out.normals.rows(); ++v) {
    const double len = out.normals.row(v).norm();
    if (len > 0.0 && std::isfinite(len)) out.normals.row(v) /= len;
  }
  return out;
}

// Reads the face element, fan-triangulating polygons. `nv` is the vertex count
// declared in the header (indices are checked against it).
Result<std::vector<Eigen::Vector3i>> readFaces(PlyValueReader& reader, const PlyElement& element, std::uint64_t nv,
                                               const std::string& label, MeshReadReport& report) {
  int list = element.find("vertex_indices");
  if (list < 0) list = element.find("vertex_index");
  if (list < 0 || !element.properties[static_cast<std::size_t>(list)].is_list) {
    return makeError(ErrorCode::kParse, label + ": PLY face element has no 'vertex_indices' list property");
  }
  if (auto ok = checkCountFits(element, reader, label); !ok) return ok.error();

  std::vector<Eigen::Vector3i> triangles;
  triangles.reserve(static_cast<std::size_t>(element.count));
  std::vector<int> polygon;
  std::size_t skipped = 0;
  ElementCursor cursor(reader, element, label);
  for (std::uint64_t f = 0; f < element.count; ++f) {
    for (std::size_t p = 0; p < element.properties.size(); ++p) {
      const PlyProperty& property = element.properties[p];
      if (static_cast<int>(p) != list) {
        if (auto ok = cursor.skip(property, f); !ok) return ok.error();
        continue;
      }
      std::size_t corners = 0;
      if (auto ok = cursor.listCount(property, f, corners); !ok) return ok.error();
      polygon.clear();
      for (std::size_t k = 0; k < corners; ++k) {
        double value = 0;
        if (auto ok = cursor.value(property.type, f, value); !ok) return ok.error();
        if (!(value >= 0) || value != std::floor(value) || value >= static_cast<double>(nv)) {
          const std::size_t triangle = triangles.size() + (k >= 2 ? k - 2 : 0);
          return makeError(ErrorCode::kInvalidMesh,
                           label + ": triangle " + std::to_string(triangle) + " (face " + std::to_string(f) +
                               ") refers to vertex " + formatValue(value) + " but the file has " +
                               std::to_string(nv) + " vertices");
        }
        polygon.push_back(static_cast<int>(value));
      }
      if (corners < 3) {
        ++skipped;
        continue;
      }
      for (std::size_t k = 1; k + 1 < corners; ++k) triangles.emplace_back(polygon[0], polygon[k], polygon[k + 1]);
      if (corners > 3) ++report.polygons_triangulated;
    }
  }
  if (skipped > 0) report.warnings.push_back(std::to_string(skipped) + " PLY faces with fewer than 3 corners ignored");
  return triangles;
}

}  // namespace

Result<LoadedMesh> readPly(std::span<const std::uint8_t> bytes, const std::string& label) {
  auto header = parseHeader(std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()), label);
  if (!header) return header.error();

  const PlyElement* vertex_element = nullptr;
  for (const PlyElement& e : header->elements) {
    if (e.name == "vertex") vertex_element = &e;
  }
  if (!vertex_element) return makeError(ErrorCode::kParse, label + ": PLY file has no 'vertex' element");
  if (vertex_element->count > static_cast<std::uint64_t>(std::numeric_limits<int>::max())) {
    return makeError(ErrorCode::kUnsupported,
                     label + ": PLY header claims " + std::to_string(vertex_element->count) + " vertices (too many)");
  }

  LoadedMesh loaded;
  MeshReadReport& report = loaded.report;
  report.format = MeshFormat::kPly;
  PlyValueReader reader(bytes.subspan(header->data_offset), header->ascii);
  std::vector<Eigen::Vector3i> triangles;
  for (const PlyElement& element : header->elements) {
    if (&element == vertex_element) {
      auto vertices = readVertices(reader, element, label, report);
      if (!vertices) return vertices.error();
      loaded.mesh.positions = std::move(vertices->positions);
      loaded.mesh.normals = std::move(vertices->normals);
      loaded.mesh.uvs = std::move(vertices->uvs);
      loaded.mesh.regions = std::move(vertices->regions);
    } else if (element.name == "face") {
      auto faces = readFaces(reader, element, vertex_element->count, label, report);
      if (!faces) return faces.error();
      triangles = std::move(*faces);
    } else {
      // Unused element (edges, materials...): read past it.
      if (auto ok = checkCountFits(element, reader, label); !ok) return ok.error();
      ElementCursor cursor(reader, element, label);
      for (std::uint64_t i = 0; i < element.count; ++i) {
        for (const PlyProperty& property : element.properties) {
          if (auto ok = cursor.skip(property, i); !ok) return ok.error();
        }
      }
    }
  }

  Mesh& mesh = loaded.mesh;
  if (mesh.vertexCount() == 0) return makeError(ErrorCode::kInvalidMesh, label + ": PLY file has no vertices");
  mesh.triangles.resize(static_cast<Eigen::Index>(triangles.size()), 3);
  for (std::size_t t = 0; t < triangles.size(); ++t) mesh.triangles.row(static_cast<Eigen::Index>(t)) = triangles[t].transpose();
  report.point_cloud = triangles.empty();
  if (mesh.normals.rows() == 0 && !report.point_cloud) {
    mesh.normals = computeSeamlessVertexNormals(mesh.positions, mesh.triangles);
    report.normals_computed = true;
  }
  if (auto ok = validateMesh(mesh, label); !ok) return ok.error();
  report.degenerate_triangles = countDegenerateTriangles(mesh);
  return loaded;
}

}  // namespace core
