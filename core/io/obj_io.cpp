// Wavefront OBJ reading (tinyobjloader for faces, normals and texture
// coordinates). Vertices are kept one per `v` line in file order, so vertex
// indices in landmark files stay valid.
//
// Why positions are scanned here rather than taken from tinyobjloader: the
// Debian build used is single precision, and its number parser turns "nan",
// "inf" or garbage into 0 silently. The scan below reads `v` lines in double
// precision and names the vertex and line of any bad coordinate.
#include <algorithm>
#include <charconv>
#include <cmath>
#include <limits>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <tiny_obj_loader.h>

#include "core/io/mesh_io.h"

namespace core {
namespace {

struct ScannedVertices {
  std::vector<double> xyz;  // 3 per vertex
  std::size_t count() const { return xyz.size() / 3; }
};

// Splits like tinyobjloader's safeGetline: "\n", "\r\n" or a lone "\r".
template <typename Fn>
void forEachLine(std::string_view text, Fn&& fn) {
  std::size_t line_number = 0;
  std::size_t begin = 0;
  while (begin < text.size()) {
    std::size_t end = text.find_first_of("\r\n", begin);
    if (end == std::string_view::npos) end = text.size();
    ++line_number;
    fn(text.substr(begin, end - begin), line_number);
    if (end < text.size() && text[end] == '\r' && end + 1 < text.size() && text[end + 1] == '\n') ++end;
    begin = end + 1;
  }
}

bool isBlank(char c) { return c == ' ' || c == '\t'; }

// Next whitespace-separated token of `line` starting at `pos`.
std::string_view nextToken(std::string_view line, std::size_t& pos) {
  while (pos < line.size() && isBlank(line[pos])) ++pos;
  const std::size_t begin = pos;
  while (pos < line.size() && !isBlank(line[pos])) ++pos;
  return line.substr(begin, pos - begin);
}

// Parses a whole token as a double (std::from_chars, which also accepts
// "nan" and "inf" so that they can be reported rather than zeroed).
bool parseNumber(std::string_view token, double& value) {
  if (token.size() > 1 && token.front() == '+' && token[1] != '-') token.remove_prefix(1);
  const auto [end, ec] = std::from_chars(token.data(), token.data() + token.size(), value);
  if (ec == std::errc::result_out_of_range) {
    value = token.front() == '-' ? -HUGE_VAL : HUGE_VAL;  // overflow: report as non-finite
    return end == token.data() + token.size();
  }
  return ec == std::errc() && end == token.data() + token.size();
}

// Reads every `v x y z` line (same recognition rule as tinyobjloader).
Result<ScannedVertices> scanVertices(std::string_view text, const std::string& label) {
  ScannedVertices out;
  std::optional<Error> error;
  forEachLine(text, [&](std::string_view line, std::size_t line_number) {
    if (error) return;
    std::size_t pos = 0;
    while (pos < line.size() && isBlank(line[pos])) ++pos;
    if (pos + 1 >= line.size() || line[pos] != 'v' || !isBlank(line[pos + 1])) return;
    pos += 2;
    const std::size_t vertex = out.count();
    const std::string where = "vertex " + std::to_string(vertex) + " (line " + std::to_string(line_number) + ")";
    double xyz[3];
    for (int c = 0; c < 3; ++c) {
      const std::string_view token = nextToken(line, pos);
      if (token.empty()) {
        error = makeError(ErrorCode::kParse, label + ": " + where + " has fewer than 3 coordinates");
        return;
      }
      if (!parseNumber(token, xyz[c])) {
        error = makeError(ErrorCode::kParse, label + ": " + where + " has a coordinate that is not a number ('" +
                                                 std::string(token.substr(0, 32)) + "')");
        return;
      }
      if (!std::isfinite(xyz[c])) {
        error = makeError(ErrorCode::kInvalidMesh, label + ": " + where + " has a non-finite coordinate (" +
                                                       "xyz"[c] + " = " + std::string(token.substr(0, 32)) + ")");
        return;
      }
    }
    out.xyz.insert(out.xyz.end(), xyz, xyz + 3);
  });
  if (error) return *error;
  return out;
}

std::string tidyMessage(std::string text) {
  while (!text.empty() && (text.back() == '\n' || text.back() == ' ' || text.back() == '.')) text.pop_back();
  std::replace(text.begin(), text.end(), '\n', ' ');
  return text;
}

// Per-vertex attribute gathered from face corners (vn or vt). OBJ indexes
// these per corner; a vertex keeps them only if all its corners agree.
struct CornerAttribute {
  std::vector<int> index_of_vertex;  // -1: no corner seen yet
  bool any = false;                  // some corner has an index
  bool missing = false;              // some corner has none
  long long conflict_vertex = -1;    // first vertex whose corners disagree

  explicit CornerAttribute(std::size_t vertices) : index_of_vertex(vertices, -1) {}

  // `same(a, b)`: true when attribute entries a and b hold equal values
  // (exporters often repeat a value under a new index).
  template <typename Same>
  void add(int vertex, int index, Same&& same) {
    if (index < 0) {
      missing = true;
      return;
    }
    any = true;
    int& current = index_of_vertex[static_cast<std::size_t>(vertex)];
    if (current < 0) {
      current = index;
    } else if (current != index && !same(current, index) && conflict_vertex < 0) {
      conflict_vertex = vertex;
    }
  }

  bool usable() const { return any && !missing && conflict_vertex < 0; }

  std::string problem() const {
    return conflict_vertex >= 0 ? "vertex " + std::to_string(conflict_vertex) + " has several"
                                : std::string("some face corners have none");
  }
};

// Checks a face corner's index into an attribute array of `size` entries.
Status checkAttributeIndex(int index, std::size_t size, const char* what, std::size_t face, const std::string& label) {
  if (index == -1 || (index >= 0 && static_cast<std::size_t>(index) < size)) return Ok{};
  return makeError(ErrorCode::kParse, label + ": face " + std::to_string(face) + " refers to " + what + " " +
                                          (index < 0 ? std::string("before the first one")
                                                     : std::to_string(index + 1) + " (OBJ numbers from 1)") +
                                          " but the file has " + std::to_string(size));
}

// Attribute entry `index` of a flat array with `width` values per entry.
bool sameEntry(const std::vector<tinyobj::real_t>& values, int width, int a, int b) {
  const auto first = values.begin() + static_cast<std::ptrdiff_t>(a) * width;
  return std::equal(first, first + width, values.begin() + static_cast<std::ptrdiff_t>(b) * width);
}

struct ObjFaces {
  std::vector<Eigen::Vector3i> triangles;
  CornerAttribute normals;    // vn per vertex
  CornerAttribute texcoords;  // vt per vertex
};

// Fan-triangulates every face of every shape (file order), checking vertex,
// normal and texture-coordinate indices and gathering vn/vt per vertex.
Result<ObjFaces> collectFaces(const tinyobj::ObjReader& reader, std::size_t nv, const std::string& label,
                              MeshReadReport& report) {
  const tinyobj::attrib_t& attrib = reader.GetAttrib();
  const std::size_t n_normals = attrib.normals.size() / 3;
  const std::size_t n_texcoords = attrib.texcoords.size() / 2;
  auto same_normal = [&](int a, int b) { return sameEntry(attrib.normals, 3, a, b); };
  auto same_texcoord = [&](int a, int b) { return sameEntry(attrib.texcoords, 2, a, b); };

  ObjFaces out{{}, CornerAttribute(nv), CornerAttribute(nv)};
  std::size_t face = 0;
  std::size_t ignored_lines = 0;
  std::size_t ignored_points = 0;
  for (const tinyobj::shape_t& shape : reader.GetShapes()) {
    ignored_lines += shape.lines.num_line_vertices.size();
    ignored_points += shape.points.indices.size();
    const auto& indices = shape.mesh.indices;
    std::size_t corner = 0;
    for (const unsigned char corners : shape.mesh.num_face_vertices) {
      // num_face_vertices is 8-bit in tinyobjloader: larger faces wrap around
      // (tinyobjloader itself drops faces with fewer than 3 corners).
      if (corners < 3 || corner + corners > indices.size()) {
        return makeError(ErrorCode::kUnsupported, label + ": face " + std::to_string(face) + " has more than 255 corners");
      }
      const std::size_t first_triangle = out.triangles.size();
      for (std::size_t k = 0; k < corners; ++k) {
        const tinyobj::index_t& idx = indices[corner + k];
        const int v = idx.vertex_index;
        if (v < 0 || static_cast<std::size_t>(v) >= nv) {
          const std::size_t triangle = first_triangle + (k >= 2 ? k - 2 : 0);  // first triangle using corner k
          return makeError(ErrorCode::kInvalidMesh,
                           label + ": triangle " + std::to_string(triangle) + " (face " + std::to_string(face) +
                               ") refers to " +
                               (v < 0 ? std::string("a vertex before the first one")
                                      : "vertex " + std::to_string(v + 1) + " (OBJ numbers from 1)") +
                               " but the file has " + std::to_string(nv) + " vertices");
        }
        if (auto ok = checkAttributeIndex(idx.normal_index, n_normals, "normal", face, label); !ok) return ok.error();
        if (auto ok = checkAttributeIndex(idx.texcoord_index, n_texcoords, "texture coordinate", face, label); !ok) {
          return ok.error();
        }
        out.normals.add(v, idx.normal_index, same_normal);
        out.texcoords.add(v, idx.texcoord_index, same_texcoord);
      }
      // Fan from the first corner: (0, k, k+1), the convention of the ICT data.
      for (std::size_t k = 1; k + 1 < corners; ++k) {
        out.triangles.emplace_back(indices[corner].vertex_index, indices[corner + k].vertex_index,
                                   indices[corner + k + 1].vertex_index);
      }
      if (corners > 3) ++report.polygons_triangulated;
      corner += corners;
      ++face;
    }
    if (corner != indices.size()) {
      return makeError(ErrorCode::kUnsupported, label + ": a face has more than 255 corners");
    }
  }
  if (ignored_lines > 0) report.warnings.push_back(std::to_string(ignored_lines) + " line elements ('l') ignored");
  if (ignored_points > 0) report.warnings.push_back(std::to_string(ignored_points) + " point elements ('p') ignored");
  return out;
}

// #V by 3 unit normals from vn (vertices on no face get zero).
Eigen::MatrixX3d fileNormals(const tinyobj::attrib_t& attrib, const CornerAttribute& normals) {
  const auto nv = static_cast<Eigen::Index>(normals.index_of_vertex.size());
  Eigen::MatrixX3d out = Eigen::MatrixX3d::Zero(nv, 3);
  for (Eigen::Index v = 0; v < nv; ++v) {
    const int n = normals.index_of_vertex[static_cast<std::size_t>(v)];
    if (n < 0) continue;
    const std::size_t i = 3 * static_cast<std::size_t>(n);
    const Eigen::RowVector3d normal(attrib.normals[i], attrib.normals[i + 1], attrib.normals[i + 2]);
    const double len = normal.norm();
    if (len > 0.0 && std::isfinite(len)) out.row(v) = normal / len;
  }
  return out;
}

// #V by 2 UVs from vt, v flipped to glTF's downward axis (vertices on no face get 0).
Eigen::MatrixX2d fileUvs(const tinyobj::attrib_t& attrib, const CornerAttribute& texcoords) {
  const auto nv = static_cast<Eigen::Index>(texcoords.index_of_vertex.size());
  Eigen::MatrixX2d out = Eigen::MatrixX2d::Zero(nv, 2);
  for (Eigen::Index v = 0; v < nv; ++v) {
    const int t = texcoords.index_of_vertex[static_cast<std::size_t>(v)];
    if (t < 0) continue;
    const std::size_t i = 2 * static_cast<std::size_t>(t);
    out.row(v) << attrib.texcoords[i], 1.0 - attrib.texcoords[i + 1];
  }
  return out;
}

}  // namespace

Result<LoadedMesh> readObj(std::span<const std::uint8_t> bytes, const std::string& label) {
  const std::string_view text(reinterpret_cast<const char*>(bytes.data()), bytes.size());
  if (text.find('\0') != std::string_view::npos) {
    return makeError(ErrorCode::kParse, label + ": contains binary data (NUL bytes); not an OBJ text file");
  }
  auto scanned = scanVertices(text, label);
  if (!scanned) return scanned.error();
  const std::size_t nv = scanned->count();
  if (nv == 0) return makeError(ErrorCode::kParse, label + ": no vertices ('v' lines); not an OBJ mesh");
  if (nv > static_cast<std::size_t>(std::numeric_limits<int>::max())) {
    return makeError(ErrorCode::kUnsupported, label + ": too many vertices");
  }

  // Faces, normals and UVs from tinyobjloader; no material files are read.
  tinyobj::ObjReaderConfig config;
  config.triangulate = false;  // fan-triangulated here, so polygons can be counted
  config.vertex_color = false;
  tinyobj::ObjReader reader;
  if (!reader.ParseFromString(std::string(text), /*mtl_text=*/"", config) || !reader.Valid()) {
    return makeError(ErrorCode::kParse,
                     label + ": " + (reader.Error().empty() ? "invalid OBJ" : tidyMessage(reader.Error())));
  }
  const tinyobj::attrib_t& attrib = reader.GetAttrib();
  if (attrib.vertices.size() / 3 != nv) {
    return makeError(ErrorCode::kParse, label + ": inconsistent vertex lines (" + std::to_string(nv) + " read, " +
                                            std::to_string(attrib.vertices.size() / 3) + " parsed)");
  }

  LoadedMesh loaded;
  MeshReadReport& report = loaded.report;
  report.format = MeshFormat::kObj;
  auto faces = collectFaces(reader, nv, label, report);
  if (!faces) return faces.error();

  Mesh& mesh = loaded.mesh;
  mesh.positions = Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>>(
      scanned->xyz.data(), static_cast<Eigen::Index>(nv), 3);
  mesh.triangles.resize(static_cast<Eigen::Index>(faces->triangles.size()), 3);
  for (std::size_t t = 0; t < faces->triangles.size(); ++t) {
    mesh.triangles.row(static_cast<Eigen::Index>(t)) = faces->triangles[t].transpose();
  }
  report.point_cloud = faces->triangles.empty();

  if (!report.point_cloud) {
    // Normals: the file's when one per vertex, else computed.
    if (faces->normals.usable()) {
      mesh.normals = fileNormals(attrib, faces->normals);
    } else {
      if (faces->normals.any) {
        report.warnings.push_back("vn normals are not one per vertex (" + faces->normals.problem() +
                                  "); normals were recomputed");
      }
      mesh.normals = computeSeamlessVertexNormals(mesh.positions, mesh.triangles);
      report.normals_computed = true;
    }
    // UVs: only when one per vertex (a UV seam would need split vertices,
    // which would renumber the vertices).
    if (faces->texcoords.usable()) {
      mesh.uvs = fileUvs(attrib, faces->texcoords);
    } else if (faces->texcoords.any) {
      report.warnings.push_back("vt texture coordinates are not one per vertex (" + faces->texcoords.problem() +
                                "; a UV seam needs split vertices, e.g. a GLB); UVs dropped");
    }
  }

  if (auto ok = validateMesh(mesh, label); !ok) return ok.error();
  report.degenerate_triangles = countDegenerateTriangles(mesh);
  return loaded;
}

}  // namespace core
