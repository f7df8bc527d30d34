#include "core/mesh.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <numeric>
#include <string>
#include <tuple>
#include <vector>

namespace core {

Eigen::MatrixX3d computeFaceNormals(const Eigen::MatrixX3d& positions, const Eigen::MatrixX3i& triangles) {
  Eigen::MatrixX3d normals(triangles.rows(), 3);
  for (Eigen::Index f = 0; f < triangles.rows(); ++f) {
    const Eigen::Vector3d a = positions.row(triangles(f, 0));
    const Eigen::Vector3d b = positions.row(triangles(f, 1));
    const Eigen::Vector3d c = positions.row(triangles(f, 2));
    Eigen::Vector3d n = (b - a).cross(c - a);
    const double len = n.norm();
    normals.row(f) = len > 0.0 ? Eigen::RowVector3d(n.transpose() / len) : Eigen::RowVector3d::Zero();
  }
  return normals;
}

Eigen::MatrixX3d computeVertexNormals(const Eigen::MatrixX3d& positions, const Eigen::MatrixX3i& triangles) {
  Eigen::MatrixX3d normals = Eigen::MatrixX3d::Zero(positions.rows(), 3);
  for (Eigen::Index f = 0; f < triangles.rows(); ++f) {
    const Eigen::Vector3d a = positions.row(triangles(f, 0));
    const Eigen::Vector3d b = positions.row(triangles(f, 1));
    const Eigen::Vector3d c = positions.row(triangles(f, 2));
    const Eigen::RowVector3d n = (b - a).cross(c - a).transpose();  // length = 2 * area: area weighting
    for (int k = 0; k < 3; ++k) normals.row(triangles(f, k)) += n;
  }
  for (Eigen::Index v = 0; v < normals.rows(); ++v) {
    const double len = normals.row(v).norm();
    if (len > 0.0) normals.row(v) /= len;
  }
  return normals;
}

std::vector<int> coincidentVertexRepresentatives(const Eigen::MatrixX3d& positions) {
  const Eigen::Index nv = positions.rows();
  std::vector<int> order(static_cast<std::size_t>(nv));
  std::iota(order.begin(), order.end(), 0);
  auto key = [&](int v) { return std::make_tuple(positions(v, 0), positions(v, 1), positions(v, 2), v); };
  std::sort(order.begin(), order.end(), [&](int a, int b) { return key(a) < key(b); });
  std::vector<int> representative;
  for (std::size_t i = 1; i < order.size(); ++i) {
    const int a = order[i - 1], b = order[i];
    if (positions.row(a) != positions.row(b)) continue;
    if (representative.empty()) {
      representative.resize(static_cast<std::size_t>(nv));
      std::iota(representative.begin(), representative.end(), 0);
    }
    representative[static_cast<std::size_t>(b)] = representative[static_cast<std::size_t>(a)];  // ascending within a run
  }
  return representative;
}

Eigen::MatrixX3d computeSeamlessVertexNormals(const Eigen::MatrixX3d& positions, const Eigen::MatrixX3i& triangles) {
  const std::vector<int> representative = coincidentVertexRepresentatives(positions);
  if (representative.empty()) return computeVertexNormals(positions, triangles);
  // Faces through each point's representative (at the same position, so the
  // face normals are the same): its normal sums every face around the point,
  // and the other copies take it.
  Eigen::MatrixX3i welded = triangles;
  for (Eigen::Index i = 0; i < welded.size(); ++i) welded.data()[i] = representative[static_cast<std::size_t>(welded.data()[i])];
  Eigen::MatrixX3d normals = computeVertexNormals(positions, welded);
  for (Eigen::Index v = 0; v < normals.rows(); ++v) normals.row(v) = normals.row(representative[static_cast<std::size_t>(v)]);
  return normals;
}

WindingNormals normalsAgreeingWithWinding(const Eigen::MatrixX3d& normals, const Eigen::MatrixX3d& positions,
                                          const Eigen::MatrixX3i& triangles) {
  assert(normals.rows() == positions.rows());
  WindingNormals out{normals, 0};
  const Eigen::MatrixX3d faces = computeVertexNormals(positions, triangles);
  for (Eigen::Index v = 0; v < normals.rows(); ++v) {
    if (faces.row(v).isZero()) continue;  // on no valid face: nothing to compare with
    if (!(normals.row(v).dot(faces.row(v)) > 0.0)) {
      out.normals.row(v) = faces.row(v);
      ++out.replaced;
    }
  }
  return out;
}

Eigen::VectorXd computeDoubleAreas(const Eigen::MatrixX3d& positions, const Eigen::MatrixX3i& triangles) {
  Eigen::VectorXd areas(triangles.rows());
  for (Eigen::Index f = 0; f < triangles.rows(); ++f) {
    const Eigen::Vector3d a = positions.row(triangles(f, 0));
    const Eigen::Vector3d b = positions.row(triangles(f, 1));
    const Eigen::Vector3d c = positions.row(triangles(f, 2));
    areas(f) = (b - a).cross(c - a).norm();
  }
  return areas;
}

double boundingBoxDiagonal(const Eigen::MatrixX3d& positions) {
  if (positions.rows() == 0) return 0.0;
  return (positions.colwise().maxCoeff() - positions.colwise().minCoeff()).norm();
}

bool isDegenerateTriangle(const Eigen::MatrixX3d& positions, const Eigen::Vector3i& t, double diagonal) {
  if (t(0) == t(1) || t(1) == t(2) || t(0) == t(2)) return true;
  const Eigen::Vector3d a = positions.row(t(0));
  const Eigen::Vector3d b = positions.row(t(1));
  const Eigen::Vector3d c = positions.row(t(2));
  // Twice-area below (1e-10 * diagonal)^2: no usable normal or barycentrics.
  const double eps = 1e-10 * diagonal;
  return (b - a).cross(c - a).norm() <= eps * eps;
}

Eigen::Index firstInvalidRegionLabel(const Eigen::VectorXi& labels) {
  for (Eigen::Index v = 0; v < labels.size(); ++v) {
    if (labels(v) < 0 || labels(v) > kMaxRegionLabel) return v;
  }
  return -1;
}

Status validateMesh(const Mesh& mesh, const std::string& label) {
  const Eigen::Index nv = mesh.positions.rows();
  for (Eigen::Index v = 0; v < nv; ++v) {
    if (!mesh.positions.row(v).allFinite()) {
      return makeError(ErrorCode::kInvalidMesh, label + ": vertex " + std::to_string(v) + " has a non-finite position");
    }
  }
  if (mesh.normals.rows() != 0 && mesh.normals.rows() != nv) {
    return makeError(ErrorCode::kInvalidMesh, label + ": normal count " + std::to_string(mesh.normals.rows()) +
                                                  " differs from vertex count " + std::to_string(nv));
  }
  for (Eigen::Index v = 0; v < mesh.normals.rows(); ++v) {
    if (!mesh.normals.row(v).allFinite()) {
      return makeError(ErrorCode::kInvalidMesh, label + ": vertex " + std::to_string(v) + " has a non-finite normal");
    }
  }
  if (mesh.uvs.rows() != 0 && mesh.uvs.rows() != nv) {
    return makeError(ErrorCode::kInvalidMesh, label + ": UV count " + std::to_string(mesh.uvs.rows()) +
                                                  " differs from vertex count " + std::to_string(nv));
  }
  for (Eigen::Index v = 0; v < mesh.uvs.rows(); ++v) {
    if (!mesh.uvs.row(v).allFinite()) {
      return makeError(ErrorCode::kInvalidMesh, label + ": vertex " + std::to_string(v) + " has a non-finite UV");
    }
  }
  if (mesh.regions.size() != 0 && mesh.regions.size() != nv) {
    return makeError(ErrorCode::kInvalidMesh, label + ": region label count " + std::to_string(mesh.regions.size()) +
                                                  " differs from vertex count " + std::to_string(nv));
  }
  if (const Eigen::Index v = firstInvalidRegionLabel(mesh.regions); v >= 0) {
    return makeError(ErrorCode::kInvalidMesh, label + ": vertex " + std::to_string(v) + " has region label " +
                                                  std::to_string(mesh.regions(v)) + " (labels are 0.." +
                                                  std::to_string(kMaxRegionLabel) + ")");
  }
  for (Eigen::Index f = 0; f < mesh.triangles.rows(); ++f) {
    for (int k = 0; k < 3; ++k) {
      const int i = mesh.triangles(f, k);
      if (i < 0 || i >= nv) {
        return makeError(ErrorCode::kInvalidMesh, label + ": triangle " + std::to_string(f) + " refers to vertex " +
                                                      std::to_string(i) + " but the mesh has " + std::to_string(nv) +
                                                      " vertices");
      }
    }
  }
  return Ok{};
}

}  // namespace core
