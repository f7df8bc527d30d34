// core::Mesh: the triangle mesh value type every stage passes around.
#pragma once

#include <array>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "core/base/error.h"

namespace core {

// The custom attribute (without its leading '_') that carries region labels.
inline constexpr const char* kRegionAttribute = "REGION";
// Region labels are bits of a 64-bit mask in the closest-point filter.
inline constexpr int kMaxRegionLabel = 63;

using RowMatrixX3d = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;

// A triangle mesh (or a point cloud when `triangles` has no rows).
// Degenerate triangles (repeated index or zero area) are kept so that triangle
// indices stay those of the file (landmarks refer to them); algorithms skip them.
struct Mesh {
  Eigen::MatrixX3d positions;  // #V by 3 vertex positions, model units (glTF: metres)
  Eigen::MatrixX3i triangles;  // #F by 3 vertex indices, counter-clockwise = front face
  Eigen::MatrixX3d normals;    // #V by 3 unit vertex normals, or 0 rows when absent
  Eigen::MatrixX2d uvs;        // #V by 2 texture coordinates (glTF convention, v down), or 0 rows
  // #V region labels in [0, kMaxRegionLabel] (glTF custom attribute _REGION,
  // PLY vertex property "region"), or 0 rows. When source and target both carry them, matching is
  // region-constrained (see core/correspond/correspondence.h).
  Eigen::VectorXi regions;

  Eigen::Index vertexCount() const { return positions.rows(); }
  Eigen::Index triangleCount() const { return triangles.rows(); }
};

// #F by 3 unit face normals (zero rows for degenerate triangles).
Eigen::MatrixX3d computeFaceNormals(const Eigen::MatrixX3d& positions, const Eigen::MatrixX3i& triangles);

// #V by 3 area-weighted unit vertex normals; vertices on no valid triangle get (0,0,0).
Eigen::MatrixX3d computeVertexNormals(const Eigen::MatrixX3d& positions, const Eigen::MatrixX3i& triangles);

// For each vertex, the lowest-indexed vertex at exactly its position (itself
// when unique): copies split at one point (UV seams, hard edges) share one.
// Empty when every position is unique.
std::vector<int> coincidentVertexRepresentatives(const Eigen::MatrixX3d& positions);

// An open boundary of the mesh: edges used by one triangle with three
// distinct vertices (a zero-area sliver still connects its neighbours).
struct BoundaryLoop {
  std::vector<int> vertices;  // in the direction of its triangles' winding; a closed loop starts at its smallest index
  std::vector<int> faces;     // faces[i] owns the edge vertices[i] -> vertices[i + 1] (cyclic when closed)
  std::vector<std::array<int, 2>> corners;  // that edge's two ends as corner slots (0-2) of faces[i]
  bool closed = true;         // false: a chain that cannot be closed (inconsistent winding, non-manifold)
  double length = 0.0;        // geometric length (with the closing edge when closed)
};

// Mean length of the edges around each vertex (an edge counted once per face
// it bounds), 0 on no face. With `representative` (as from
// coincidentVertexRepresentatives) around each point instead, copies split at
// it included: every copy's row holds its point's value.
Eigen::VectorXd meanIncidentEdgeLengths(const Mesh& mesh, const std::vector<int>& representative = {});

// Positions and triangles with every corner re-pointed to its point's
// representative (coincidentVertexRepresentatives; empty: a plain copy):
// split points (UV seams, hard edges) joined for topology.
Mesh weldedTopology(const Mesh& mesh, const std::vector<int>& representative);

// Connected pieces of a mesh with split points welded (`representative` as
// from coincidentVertexRepresentatives: a UV seam does not cut a piece).
struct MeshPieces {
  int count = 0;
  std::vector<int> face_piece;    // #F: piece of each face, numbered in order of first face
  std::vector<int> vertex_piece;  // #V: piece of each vertex, -1 on no face
};
MeshPieces meshPieces(const Mesh& mesh, const std::vector<int>& representative);

// Boundary loops of the mesh, longest first by geometric length (ties: more
// vertices first, then smaller first vertex). On a face: the outer rim (neck
// cut), the mouth, the eyes.
std::vector<BoundaryLoop> boundaryLoops(const Mesh& mesh);

// Whether every connected piece of the mesh (split points welded) is closed:
// no boundary edge. A rig part that is solid (an eyeball, teeth) moves as a
// rigid body; an open one (lashes, gums) deforms with the face.
bool isSolid(const Mesh& mesh);

// computeVertexNormals with the copies of a split point (see
// coincidentVertexRepresentatives) sharing one normal, that of all faces
// around the point: the two sides of a UV seam shade and match as one
// surface. For meshes whose file gives no normals.
Eigen::MatrixX3d computeSeamlessVertexNormals(const Eigen::MatrixX3d& positions, const Eigen::MatrixX3i& triangles);

// For each vertex, the lowest-indexed vertex at exactly its position with
// exactly its row of `values` (#V by k; itself when none). Empty when every
// vertex is its own.
std::vector<int> agreeingVertexRepresentatives(const Eigen::MatrixX3d& positions, const Eigen::MatrixXd& values);

// agreeingVertexRepresentatives by normal: the copies of a point split at a
// UV seam, which shade as one surface, share one; copies split at a hard edge
// (normals that differ) stay apart.
std::vector<int> smoothVertexRepresentatives(const Eigen::MatrixX3d& positions, const Eigen::MatrixX3d& normals);

// computeVertexNormals with the vertices that share a representative (as
// from coincidentVertexRepresentatives or smoothVertexRepresentatives; empty:
// none) sharing one normal, that of all their faces, summed in ascending face
// order.
Eigen::MatrixX3d computeSharedVertexNormals(const Eigen::MatrixX3d& positions, const Eigen::MatrixX3i& triangles,
                                            const std::vector<int>& representative);

// Vertex normals fit for matching: `normals` (#V by 3 unit) where they point
// to the side the faces' winding makes the front (positive dot with the
// area-weighted face normal of computeVertexNormals), that face normal where
// they do not (normals flipped or zeroed by a broken export). Vertices on no
// valid face keep theirs.
struct WindingNormals {
  Eigen::MatrixX3d normals;
  int replaced = 0;  // vertices whose normal pointed against (or across) their faces
};
WindingNormals normalsAgreeingWithWinding(const Eigen::MatrixX3d& normals, const Eigen::MatrixX3d& positions,
                                          const Eigen::MatrixX3i& triangles);

// Vertex adjacency (CSR): the neighbours of v, ascending and unique, are
// indices[offsets[v] .. offsets[v + 1]).
struct VertexAdjacency {
  std::vector<int> offsets;  // #V + 1
  std::vector<int> indices;
};
VertexAdjacency vertexAdjacency(const Eigen::MatrixX3i& triangles, Eigen::Index vertex_count);

// Faces around each point of a mesh (CSR by representative vertex).
struct FacesAroundPoints {
  std::vector<int> point;    // #V: the representative of each vertex
  std::vector<int> offsets;  // #V + 1, by representative
  std::vector<int> faces;

  FacesAroundPoints() = default;
  // representative: as from coincidentVertexRepresentatives (empty: none joined)
  FacesAroundPoints(const Mesh& mesh, std::vector<int> representative);
  // fn(face) for each face at the point of `vertex`, in ascending order.
  template <class Fn>
  void forEachFaceAround(int vertex, Fn&& fn) const {
    const auto p = static_cast<std::size_t>(point[static_cast<std::size_t>(vertex)]);
    for (int i = offsets[p]; i < offsets[p + 1]; ++i) fn(faces[static_cast<std::size_t>(i)]);
  }
};

// A maximal independent set of the adjacency, greedy in index order
// (deterministic): every vertex is in it or next to one that is. weight[k]:
// how many vertices vertices[k] stands for (itself and the neighbours it was
// the first to cover).
struct VertexSample {
  std::vector<int> vertices;
  std::vector<int> weight;
};
VertexSample independentVertexSample(const VertexAdjacency& adjacency);

// A per-vertex quantity (positions, normals, attributes: #V rows) at a point
// of face `face` given by its barycentric weights: sum over the corners k of
// barycentric(k) * values.row(triangles(face, k)), in corner order.
template <class Values>
Eigen::Matrix<double, 1, Values::ColsAtCompileTime> interpolateOnFace(const Eigen::MatrixBase<Values>& values,
                                                                      const Eigen::MatrixX3i& triangles, int face,
                                                                      const Eigen::Vector3d& barycentric) {
  Eigen::Matrix<double, 1, Values::ColsAtCompileTime> out =
      Eigen::Matrix<double, 1, Values::ColsAtCompileTime>::Zero(values.cols());
  for (int k = 0; k < 3; ++k) out += barycentric(k) * values.row(triangles(face, k));
  return out;
}

// #F twice-areas (|cross product|); 0 for degenerate triangles.
Eigen::VectorXd computeDoubleAreas(const Eigen::MatrixX3d& positions, const Eigen::MatrixX3i& triangles);

// Length of the axis-aligned bounding box diagonal (0 for an empty mesh).
double boundingBoxDiagonal(const Eigen::MatrixX3d& positions);

// True when triangle f repeats a vertex or has (numerically) zero area relative
// to the mesh scale `diagonal`.
bool isDegenerateTriangle(const Eigen::MatrixX3d& positions, const Eigen::Vector3i& triangle, double diagonal);
// How many of the mesh's triangles are degenerate (isDegenerateTriangle at the
// mesh's own diagonal): kept by the readers, skipped by the algorithms.
int countDegenerateTriangles(const Mesh& mesh);

// Index of the first label outside [0, kMaxRegionLabel], or -1 when all are usable.
Eigen::Index firstInvalidRegionLabel(const Eigen::VectorXi& labels);

// Checks finiteness of positions/normals/uvs, index ranges, region label
// range and array shapes.
// `label` names the mesh in messages (usually its file name); the message names
// the first offending vertex or triangle.
Status validateMesh(const Mesh& mesh, const std::string& label);
// validateMesh, and a surface to work on: at least one triangle, not all of
// them degenerate (a mesh flattened to a line or a point).
Status validateSurfaceMesh(const Mesh& mesh, const std::string& label);

}  // namespace core
