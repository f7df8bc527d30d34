// Tests core/geometry/mesh.cpp: normals, areas, degenerate triangles, validateMesh.
#include "core/geometry/mesh.h"

#include <cmath>
#include <limits>
#include <numbers>
#include <numeric>
#include <random>
#include <vector>

#include <Eigen/Geometry>

#include <gtest/gtest.h>

#include "tests/test_support.h"

namespace {

// Regular tetrahedron centred at the origin, counter-clockwise seen from outside.
core::Mesh makeTetrahedron() {
  core::Mesh mesh;
  mesh.positions.resize(4, 3);
  mesh.positions << 1, 1, 1,  //
      1, -1, -1,              //
      -1, 1, -1,              //
      -1, -1, 1;
  mesh.triangles.resize(4, 3);
  mesh.triangles << 0, 1, 2,  //
      0, 3, 1,                //
      0, 2, 3,                //
      1, 3, 2;
  return mesh;
}

TEST(Mesh, TetrahedronFaceNormalsAreUnitAndPointOutward) {
  const core::Mesh mesh = makeTetrahedron();
  const Eigen::MatrixX3d normals = core::computeFaceNormals(mesh.positions, mesh.triangles);
  ASSERT_EQ(normals.rows(), 4);
  for (Eigen::Index f = 0; f < 4; ++f) {
    EXPECT_NEAR(normals.row(f).norm(), 1.0, 1e-12) << "face " << f;
    Eigen::RowVector3d centroid = Eigen::RowVector3d::Zero();
    for (int k = 0; k < 3; ++k) centroid += mesh.positions.row(mesh.triangles(f, k)) / 3.0;
    // Regular tetrahedron: the outward face normal is the direction of the face centroid.
    EXPECT_TRUE(rigport_test::matricesNear(normals.row(f), centroid.normalized(), 1e-12)) << "face " << f;
  }
}

TEST(Mesh, TetrahedronVertexNormalsPointAwayFromCentre) {
  const core::Mesh mesh = makeTetrahedron();
  const Eigen::MatrixX3d normals = core::computeVertexNormals(mesh.positions, mesh.triangles);
  for (Eigen::Index v = 0; v < 4; ++v) {
    // By symmetry the area-weighted normal is the vertex direction.
    EXPECT_TRUE(rigport_test::matricesNear(normals.row(v), mesh.positions.row(v).normalized(), 1e-12)) << "vertex " << v;
  }
}

TEST(Mesh, VertexOnNoTriangleGetsZeroNormal) {
  core::Mesh mesh = makeTetrahedron();
  mesh.positions.conservativeResize(5, 3);
  mesh.positions.row(4) << 5, 5, 5;
  const Eigen::MatrixX3d normals = core::computeVertexNormals(mesh.positions, mesh.triangles);
  EXPECT_EQ(normals.row(4).norm(), 0.0);
  EXPECT_NEAR(normals.row(0).norm(), 1.0, 1e-12);
}

// Vertex 0 of the tetrahedron split in two at one position, as a UV seam
// splits it: face 2 uses the copy (vertex 4).
core::Mesh makeSplitTetrahedron() {
  core::Mesh mesh = makeTetrahedron();
  mesh.positions.conservativeResize(5, 3);
  mesh.positions.row(4) = mesh.positions.row(0);
  for (int k = 0; k < 3; ++k) {
    if (mesh.triangles(2, k) == 0) mesh.triangles(2, k) = 4;
  }
  return mesh;
}

TEST(Mesh, CopiesOfASplitPointShareTheNormalOfAllItsFaces) {
  const core::Mesh whole = makeTetrahedron();
  const core::Mesh split = makeSplitTetrahedron();
  const std::vector<int> representative = core::coincidentVertexRepresentatives(split.positions);
  EXPECT_EQ(representative, (std::vector<int>{0, 1, 2, 3, 0}));
  EXPECT_TRUE(core::coincidentVertexRepresentatives(whole.positions).empty());
  const Eigen::MatrixX3d expected = core::computeVertexNormals(whole.positions, whole.triangles);
  const Eigen::MatrixX3d seamless = core::computeSeamlessVertexNormals(split.positions, split.triangles);
  EXPECT_TRUE(seamless.topRows(4) == expected);
  EXPECT_TRUE(seamless.row(4) == expected.row(0));
  // Per vertex, each copy only sees its own faces.
  const Eigen::MatrixX3d per_vertex = core::computeVertexNormals(split.positions, split.triangles);
  EXPECT_GT((per_vertex.row(0) - per_vertex.row(4)).norm(), 0.5);
}

// A point split three ways: two copies with one normal (a UV seam) share the
// lower index, the third with its own normal (a hard edge) stays apart.
TEST(Mesh, SmoothRepresentativesJoinCopiesWithOneNormalOnly) {
  core::Mesh mesh = makeSplitTetrahedron();  // vertex 4: a copy of 0 on face 2
  mesh.positions.conservativeResize(6, 3);
  mesh.positions.row(5) = mesh.positions.row(0);
  for (int k = 0; k < 3; ++k) {
    if (mesh.triangles(1, k) == 0) mesh.triangles(1, k) = 5;
  }
  Eigen::MatrixX3d normals = core::computeSeamlessVertexNormals(mesh.positions, mesh.triangles);
  normals.row(5) << 0.0, 0.0, 1.0;
  EXPECT_EQ(core::smoothVertexRepresentatives(mesh.positions, normals), (std::vector<int>{0, 1, 2, 3, 0, 5}));
  // Shared normals sum the faces of 0 and 4 only; 5 keeps its face.
  const std::vector<int> shared = core::smoothVertexRepresentatives(mesh.positions, normals);
  const Eigen::MatrixX3d n = core::computeSharedVertexNormals(mesh.positions, mesh.triangles, shared);
  const Eigen::MatrixX3d apart = core::computeVertexNormals(mesh.positions, mesh.triangles);
  EXPECT_TRUE(n.row(4) == n.row(0));
  EXPECT_TRUE(n.row(5) == apart.row(5));
  EXPECT_GT((n.row(0) - apart.row(0)).norm(), 0.1);
  // No copies with one normal: nothing shared.
  normals.row(4) << 0.0, 1.0, 0.0;
  EXPECT_TRUE(core::smoothVertexRepresentatives(mesh.positions, normals).empty());
}

// Against a brute-force search: points on a coarse grid (so many coincide,
// some three or more times), -0 and +0 as one coordinate.
TEST(Mesh, CoincidentVerticesShareTheirLowestIndex) {
  std::mt19937 rng(11);
  std::uniform_int_distribution<int> cell(-3, 3);
  Eigen::MatrixX3d positions(3000, 3);
  for (Eigen::Index v = 0; v < positions.rows(); ++v) {
    for (int c = 0; c < 3; ++c) positions(v, c) = 0.25 * cell(rng);
  }
  positions.row(2998) << -0.0, 0.5, 0.25;
  positions.row(2999) << 0.0, 0.5, 0.25;
  const std::vector<int> representative = core::coincidentVertexRepresentatives(positions);
  ASSERT_EQ(representative.size(), 3000u);
  int shared = 0;
  for (Eigen::Index v = 0; v < positions.rows(); ++v) {
    Eigen::Index lowest = v;
    for (Eigen::Index u = 0; u < v; ++u) {
      if (positions.row(u) == positions.row(v)) {
        lowest = u;
        break;
      }
    }
    ASSERT_EQ(representative[static_cast<std::size_t>(v)], lowest) << "vertex " << v;
    shared += lowest != v ? 1 : 0;
  }
  EXPECT_GT(shared, 2000);  // 343 grid cells for 3000 points
  EXPECT_EQ(representative[2999], representative[2998]);
}

// Authored normals may lean off the face normal (hard edges, smoothing
// groups): only those pointing to the back of their faces, or zero, are
// replaced; a vertex on no face keeps its normal.
TEST(Mesh, NormalsPointingAgainstTheirFacesAreReplacedByTheFaceNormal) {
  core::Mesh mesh = makeTetrahedron();
  mesh.positions.conservativeResize(5, 3);
  mesh.positions.row(4) << 5, 5, 5;
  const Eigen::MatrixX3d faces = core::computeVertexNormals(mesh.positions, mesh.triangles);
  Eigen::MatrixX3d authored = faces;
  // Vertex 0 leans 80 degrees off its face normal: kept.
  const Eigen::Vector3d axis = faces.row(0).transpose().unitOrthogonal();
  authored.row(0) = (Eigen::AngleAxisd(80.0 * std::numbers::pi / 180.0, axis) * faces.row(0).transpose()).transpose();
  authored.row(1) = -faces.row(1);                      // flipped
  authored.row(2) = Eigen::RowVector3d::Zero();          // zeroed
  authored.row(4) << 0, 0, -1;                           // on no face
  const core::WindingNormals checked = core::normalsAgreeingWithWinding(authored, mesh.positions, mesh.triangles);
  EXPECT_EQ(checked.replaced, 2);
  EXPECT_TRUE(checked.normals.row(0) == authored.row(0));
  EXPECT_TRUE(checked.normals.row(1) == faces.row(1));
  EXPECT_TRUE(checked.normals.row(2) == faces.row(2));
  EXPECT_TRUE(checked.normals.row(3) == authored.row(3));
  EXPECT_TRUE(checked.normals.row(4) == authored.row(4));
  // With the winding reversed, every outward normal points against it.
  core::Mesh reversed = mesh;
  reversed.triangles.col(1).swap(reversed.triangles.col(2));
  EXPECT_EQ(core::normalsAgreeingWithWinding(faces, reversed.positions, reversed.triangles).replaced, 4);
}

// Two triangles sharing an edge (0-1-2, 2-1-3), a repeated-corner sliver
// (3, 3, 4) and a vertex on no face (5).
TEST(Mesh, VertexAdjacencyIsSortedUniqueAndSkipsRepeatedCorners) {
  Eigen::MatrixX3i tris(3, 3);
  tris << 0, 1, 2, 2, 1, 3, 3, 3, 4;
  const core::VertexAdjacency a = core::vertexAdjacency(tris, 6);
  ASSERT_EQ(a.offsets.size(), 7u);
  auto neighbours = [&](int v) {
    return std::vector<int>(a.indices.begin() + a.offsets[v], a.indices.begin() + a.offsets[v + 1]);
  };
  EXPECT_EQ(neighbours(0), (std::vector<int>{1, 2}));
  EXPECT_EQ(neighbours(1), (std::vector<int>{0, 2, 3}));
  EXPECT_EQ(neighbours(2), (std::vector<int>{0, 1, 3}));
  EXPECT_EQ(neighbours(3), (std::vector<int>{1, 2, 4}));
  EXPECT_EQ(neighbours(4), (std::vector<int>{3}));
  EXPECT_TRUE(neighbours(5).empty());
}

// On a grid: no two sampled vertices are neighbours, every other vertex has a
// sampled neighbour, and the weights count every vertex once.
TEST(Mesh, IndependentVertexSampleCoversEveryVertexOnce) {
  constexpr int kSide = 9;
  Eigen::MatrixX3i tris(2 * (kSide - 1) * (kSide - 1), 3);
  int f = 0;
  for (int r = 0; r + 1 < kSide; ++r) {
    for (int c = 0; c + 1 < kSide; ++c) {
      const int v = r * kSide + c;
      tris.row(f++) << v, v + 1, v + kSide + 1;
      tris.row(f++) << v, v + kSide + 1, v + kSide;
    }
  }
  const core::VertexAdjacency a = core::vertexAdjacency(tris, kSide * kSide);
  const core::VertexSample sample = core::independentVertexSample(a);
  ASSERT_EQ(sample.vertices.size(), sample.weight.size());
  std::vector<char> in(kSide * kSide, 0);
  for (int v : sample.vertices) in[static_cast<std::size_t>(v)] = 1;
  for (int v = 0; v < kSide * kSide; ++v) {
    bool sampled_neighbour = false;
    for (int k = a.offsets[v]; k < a.offsets[v + 1]; ++k) sampled_neighbour |= in[static_cast<std::size_t>(a.indices[k])] != 0;
    if (in[static_cast<std::size_t>(v)]) {
      EXPECT_FALSE(sampled_neighbour) << "vertex " << v;
    } else {
      EXPECT_TRUE(sampled_neighbour) << "vertex " << v;
    }
  }
  EXPECT_EQ(std::accumulate(sample.weight.begin(), sample.weight.end(), 0), kSide * kSide);
  EXPECT_LT(sample.vertices.size(), static_cast<std::size_t>(kSide * kSide / 2));
  EXPECT_EQ(sample.vertices.front(), 0);  // greedy in index order
}

TEST(Mesh, DoubleAreasAndBoundingBoxDiagonal) {
  core::Mesh mesh;
  mesh.positions.resize(4, 3);
  mesh.positions << 0, 0, 0,  //
      2, 0, 0,                //
      0, 3, 0,                //
      4, 0, 0;
  mesh.triangles.resize(2, 3);
  mesh.triangles << 0, 1, 2,  //
      0, 1, 3;                // collinear
  const Eigen::VectorXd areas = core::computeDoubleAreas(mesh.positions, mesh.triangles);
  EXPECT_DOUBLE_EQ(areas(0), 6.0);
  EXPECT_DOUBLE_EQ(areas(1), 0.0);
  EXPECT_DOUBLE_EQ(core::boundingBoxDiagonal(mesh.positions), 5.0);
  EXPECT_EQ(core::boundingBoxDiagonal(Eigen::MatrixX3d(0, 3)), 0.0);
  const Eigen::MatrixX3d face_normals = core::computeFaceNormals(mesh.positions, mesh.triangles);
  EXPECT_EQ(face_normals.row(1).norm(), 0.0) << "degenerate triangle must get a zero normal";
}

TEST(Mesh, DetectsDegenerateTriangles) {
  Eigen::MatrixX3d positions(5, 3);
  positions << 0, 0, 0,  //
      1, 0, 0,           //
      0, 1, 0,           //
      2, 0, 0,           //
      0.5, 1e-21, 0;     // twice-area 1e-21, below (1e-10 * diagonal)^2
  const double diagonal = core::boundingBoxDiagonal(positions);
  EXPECT_FALSE(core::isDegenerateTriangle(positions, Eigen::Vector3i(0, 1, 2), diagonal));
  EXPECT_TRUE(core::isDegenerateTriangle(positions, Eigen::Vector3i(0, 0, 2), diagonal)) << "repeated index";
  EXPECT_TRUE(core::isDegenerateTriangle(positions, Eigen::Vector3i(0, 2, 2), diagonal)) << "repeated index";
  EXPECT_TRUE(core::isDegenerateTriangle(positions, Eigen::Vector3i(0, 1, 3), diagonal)) << "collinear";
  EXPECT_TRUE(core::isDegenerateTriangle(positions, Eigen::Vector3i(0, 1, 4), diagonal)) << "zero area at mesh scale";
}

TEST(Mesh, ValidMeshPasses) {
  core::Mesh mesh = makeTetrahedron();
  mesh.normals = core::computeVertexNormals(mesh.positions, mesh.triangles);
  mesh.uvs = Eigen::MatrixX2d::Zero(4, 2);
  EXPECT_TRUE(core::validateMesh(mesh, "tet.glb").ok());
}

TEST(Mesh, ValidateMeshNamesFirstNonFiniteVertex) {
  core::Mesh mesh = makeTetrahedron();
  mesh.positions(2, 1) = std::numeric_limits<double>::quiet_NaN();
  mesh.positions(3, 0) = std::numeric_limits<double>::infinity();
  const auto status = core::validateMesh(mesh, "tet.glb");
  ASSERT_FALSE(status.ok());
  EXPECT_EQ(status.error().code, core::ErrorCode::kInvalidMesh);
  EXPECT_EQ(status.error().message, "tet.glb: vertex 2 has a non-finite position");
}

TEST(Mesh, ValidateMeshChecksNormalsAndUvs) {
  core::Mesh mesh = makeTetrahedron();
  mesh.normals = Eigen::MatrixX3d::Zero(3, 3);
  auto status = core::validateMesh(mesh, "a.obj");
  ASSERT_FALSE(status.ok());
  EXPECT_EQ(status.error().message, "a.obj: normal count 3 differs from vertex count 4");

  mesh.normals = Eigen::MatrixX3d::Zero(4, 3);
  mesh.normals(1, 2) = std::numeric_limits<double>::infinity();
  status = core::validateMesh(mesh, "a.obj");
  ASSERT_FALSE(status.ok());
  EXPECT_EQ(status.error().message, "a.obj: vertex 1 has a non-finite normal");

  mesh.normals.resize(0, 3);
  mesh.uvs = Eigen::MatrixX2d::Zero(4, 2);
  mesh.uvs(3, 0) = std::numeric_limits<double>::quiet_NaN();
  status = core::validateMesh(mesh, "a.obj");
  ASSERT_FALSE(status.ok());
  EXPECT_EQ(status.error().message, "a.obj: vertex 3 has a non-finite UV");

  mesh.uvs = Eigen::MatrixX2d::Zero(5, 2);
  status = core::validateMesh(mesh, "a.obj");
  ASSERT_FALSE(status.ok());
  EXPECT_EQ(status.error().message, "a.obj: UV count 5 differs from vertex count 4");
}

TEST(Mesh, ValidateMeshNamesTriangleWithOutOfRangeIndex) {
  core::Mesh mesh = makeTetrahedron();
  mesh.triangles(1, 2) = 7;
  auto status = core::validateMesh(mesh, "t.ply");
  ASSERT_FALSE(status.ok());
  EXPECT_EQ(status.error().code, core::ErrorCode::kInvalidMesh);
  EXPECT_EQ(status.error().message, "t.ply: triangle 1 refers to vertex 7 but the mesh has 4 vertices");

  mesh = makeTetrahedron();
  mesh.triangles(3, 0) = -1;
  status = core::validateMesh(mesh, "t.ply");
  ASSERT_FALSE(status.ok());
  EXPECT_EQ(status.error().message, "t.ply: triangle 3 refers to vertex -1 but the mesh has 4 vertices");
}

}  // namespace
