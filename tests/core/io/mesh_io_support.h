// Helpers the mesh reader and writer tests share (tests/core/io/gltf_write_test.cpp,
// gltf_mesh_read_test.cpp, obj_io_test.cpp, ply_io_test.cpp, mesh_io_test.cpp):
// the read-error check, small meshes, matrices written out row by row, an
// ASCII PLY and bytes to a file.
#pragma once

#include <cmath>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <string>

#include <Eigen/Core>
#include <gtest/gtest.h>

#include "core/geometry/mesh.h"
#include "tests/gltf_builder.h"

namespace rigport_test::mesh_io {

inline std::string startOf(const std::string& message, std::size_t n) { return message.substr(0, n); }

// Expects a failed read whose message starts with `label` and contains `part`.
#define EXPECT_READ_ERROR(result, error_code, label, part)                                    \
  do {                                                                                        \
    const auto& r_ = (result);                                                                \
    ASSERT_FALSE(r_.ok()) << "expected an error containing: " << (part);                      \
    EXPECT_EQ(r_.error().code, (error_code)) << r_.error().message;                           \
    EXPECT_EQ(::rigport_test::mesh_io::startOf(r_.error().message, std::string(label).size() + 2), \
              std::string(label) + ": ")                                                      \
        << r_.error().message;                                                                \
    EXPECT_NE(r_.error().message.find(part), std::string::npos) << r_.error().message;        \
  } while (0)

// A unit tetrahedron with unit vertex normals and UVs.
inline core::Mesh makeTetrahedron(bool normals = true, bool uvs = true) {
  core::Mesh mesh;
  mesh.positions.resize(4, 3);
  mesh.positions << 0, 0, 0,  //
      1, 0, 0,                //
      0, 1, 0,                //
      0, 0, 1;
  mesh.triangles.resize(4, 3);
  mesh.triangles << 0, 2, 1,  //
      0, 1, 3,                //
      0, 3, 2,                //
      1, 2, 3;
  if (normals) mesh.normals = core::computeVertexNormals(mesh.positions, mesh.triangles);
  if (uvs) {
    mesh.uvs.resize(4, 2);
    mesh.uvs << 0, 0, 1, 0, 0, 1, 0.5, 0.5;
  }
  return mesh;
}

// An n x n vertex grid on a wavy surface, with normals and UVs.
inline core::Mesh makeGrid(int n) {
  core::Mesh mesh;
  mesh.positions.resize(n * n, 3);
  mesh.uvs.resize(n * n, 2);
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      const double x = i / double(n - 1);
      const double y = j / double(n - 1);
      mesh.positions.row(j * n + i) << x, y, 0.1 * std::sin(6 * x) * std::cos(4 * y);
      mesh.uvs.row(j * n + i) << x, 1 - y;
    }
  }
  mesh.triangles.resize(2 * (n - 1) * (n - 1), 3);
  int t = 0;
  for (int j = 0; j + 1 < n; ++j) {
    for (int i = 0; i + 1 < n; ++i) {
      const int a = j * n + i;
      mesh.triangles.row(t++) << a, a + 1, a + n + 1;
      mesh.triangles.row(t++) << a, a + n + 1, a + n;
    }
  }
  mesh.normals = core::computeVertexNormals(mesh.positions, mesh.triangles);
  return mesh;
}

inline Eigen::MatrixX3d rows3(std::initializer_list<std::initializer_list<double>> rows) {
  Eigen::MatrixX3d m(static_cast<Eigen::Index>(rows.size()), 3);
  Eigen::Index r = 0;
  for (const auto& row : rows) {
    Eigen::Index c = 0;
    for (const double v : row) m(r, c++) = v;
    ++r;
  }
  return m;
}

inline Eigen::MatrixX3i tris(std::initializer_list<std::initializer_list<int>> rows) {
  Eigen::MatrixX3i m(static_cast<Eigen::Index>(rows.size()), 3);
  Eigen::Index r = 0;
  for (const auto& row : rows) {
    Eigen::Index c = 0;
    for (const int v : row) m(r, c++) = v;
    ++r;
  }
  return m;
}

inline void writeBytes(const std::filesystem::path& path, const gltf::ByteVector& bytes) {
  std::ofstream out(path, std::ios::binary);
  out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
}

inline const char* const kAsciiPly =
    "ply\n"
    "format ascii 1.0\n"
    "comment made by hand\n"
    "element vertex 5\n"
    "property float x\n"
    "property float y\n"
    "property float z\n"
    "property uchar confidence\n"
    "property float s\n"
    "property float t\n"
    "element face 2\n"
    "property list uchar int vertex_indices\n"
    "property list uchar float texcoord\n"
    "element edge 1\n"
    "property int vertex1\n"
    "property int vertex2\n"
    "end_header\n"
    "0 0 0 9 0 0\n"
    "1 0 0 9 1 0\n"
    "1 1 0 9 1 1\n"
    "0 1 0 9 0 1\n"
    "2 2 2 9 0.5 0.25\n"
    "4 0 1 2 3 2 0.5 0.5\n"
    "3 0 1 4 0\n"
    "0 1\n";

}  // namespace rigport_test::mesh_io
