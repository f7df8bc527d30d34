#include "core/geometry/mesh.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <numeric>
#include <string>
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
  // One pass through an open-addressing table of first occurrences (a sort
  // of the positions cost 6x as much, and this runs once per job). Vertices
  // are visited in index order, so the first at a position is its lowest.
  const Eigen::Index nv = positions.rows();
  std::size_t size = 16;
  while (size < 2 * static_cast<std::size_t>(nv)) size *= 2;
  std::vector<int> first(size, -1);
  auto bits = [](double d) {
    if (d == 0.0) d = 0.0;  // -0 and +0 are one position
    std::uint64_t b = 0;
    std::memcpy(&b, &d, sizeof b);
    return b;
  };
  std::vector<int> representative;
  for (Eigen::Index v = 0; v < nv; ++v) {
    const double x = positions(v, 0), y = positions(v, 1), z = positions(v, 2);
    std::uint64_t h = bits(x) * 0x9E3779B97F4A7C15ull;
    h ^= bits(y) + 0x7F4A7C159E3779B9ull + (h << 6) + (h >> 2);
    h ^= bits(z) + 0x94D049BB133111EBull + (h << 6) + (h >> 2);
    h ^= h >> 31;
    for (std::size_t i = static_cast<std::size_t>(h) & (size - 1);; i = (i + 1) & (size - 1)) {
      const int u = first[i];
      if (u < 0) {
        first[i] = static_cast<int>(v);
        break;
      }
      if (positions(u, 0) == x && positions(u, 1) == y && positions(u, 2) == z) {
        if (representative.empty()) {
          representative.resize(static_cast<std::size_t>(nv));
          std::iota(representative.begin(), representative.end(), 0);
        }
        representative[static_cast<std::size_t>(v)] = u;
        break;
      }
    }
  }
  return representative;
}

Eigen::MatrixX3d computeSharedVertexNormals(const Eigen::MatrixX3d& positions, const Eigen::MatrixX3i& triangles,
                                            const std::vector<int>& representative) {
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

Eigen::MatrixX3d computeSeamlessVertexNormals(const Eigen::MatrixX3d& positions, const Eigen::MatrixX3i& triangles) {
  return computeSharedVertexNormals(positions, triangles, coincidentVertexRepresentatives(positions));
}

std::vector<int> agreeingVertexRepresentatives(const Eigen::MatrixX3d& positions, const Eigen::MatrixXd& values) {
  assert(values.rows() == positions.rows());
  std::vector<int> representative = coincidentVertexRepresentatives(positions);
  if (representative.empty()) return representative;
  // The copies of each point so far, in index order; a copy joins the first
  // one with its values.
  std::vector<std::vector<int>> copies(representative.size());
  bool shared = false;
  for (std::size_t v = 0; v < representative.size(); ++v) {
    std::vector<int>& point = copies[static_cast<std::size_t>(representative[v])];
    const auto same = std::find_if(point.begin(), point.end(), [&](int u) {
      return values.row(u) == values.row(static_cast<Eigen::Index>(v));
    });
    if (same != point.end()) {
      representative[v] = *same;
      shared = true;
    } else {
      representative[v] = static_cast<int>(v);
      point.push_back(static_cast<int>(v));
    }
  }
  if (!shared) representative.clear();
  return representative;
}

std::vector<int> smoothVertexRepresentatives(const Eigen::MatrixX3d& positions, const Eigen::MatrixX3d& normals) {
  return agreeingVertexRepresentatives(positions, normals);
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

VertexAdjacency vertexAdjacency(const Eigen::MatrixX3i& triangles, Eigen::Index vertex_count) {
  // Directed edges bucketed twice (a counting sort by the neighbour, then
  // stably by the vertex), so each vertex's neighbours come out ascending
  // and de-duplicate in one pass.
  using Index = std::size_t;
  const auto n = static_cast<Index>(vertex_count);
  auto bucketStarts = [n](const std::vector<int>& keys) {
    std::vector<int> start(n + 1, 0);
    for (int k : keys) ++start[static_cast<Index>(k) + 1];
    for (Index v = 0; v < n; ++v) start[v + 1] += start[v];
    return start;
  };
  std::vector<int> from, to;
  from.reserve(static_cast<Index>(triangles.size()) * 2);
  to.reserve(from.capacity());
  for (Eigen::Index f = 0; f < triangles.rows(); ++f) {
    for (int k = 0; k < 3; ++k) {
      const int a = triangles(f, k), b = triangles(f, (k + 1) % 3);
      if (a == b) continue;
      from.push_back(a), to.push_back(b);
      from.push_back(b), to.push_back(a);
    }
  }
  std::vector<Index> by_neighbour(from.size());
  std::vector<int> fill = bucketStarts(to);
  for (Index e = 0; e < to.size(); ++e) by_neighbour[static_cast<Index>(fill[static_cast<Index>(to[e])]++)] = e;
  const std::vector<int> start = bucketStarts(from);
  fill.assign(start.begin(), start.end() - 1);
  std::vector<int> sorted(from.size());
  for (Index e : by_neighbour) sorted[static_cast<Index>(fill[static_cast<Index>(from[e])]++)] = to[e];
  VertexAdjacency out;
  out.offsets.assign(n + 1, 0);
  out.indices.reserve(sorted.size() / 2);
  for (Index v = 0; v < n; ++v) {
    const auto first = sorted.begin() + start[v], last = sorted.begin() + start[v + 1];
    out.indices.insert(out.indices.end(), first, std::unique(first, last));
    out.offsets[v + 1] = static_cast<int>(out.indices.size());
  }
  return out;
}

FacesAroundPoints::FacesAroundPoints(const Mesh& mesh, std::vector<int> representative) : point(std::move(representative)) {
  const Eigen::Index nv = mesh.vertexCount(), nf = mesh.triangleCount();
  if (point.empty()) {
    point.resize(static_cast<std::size_t>(nv));
    std::iota(point.begin(), point.end(), 0);
  }
  auto cornerPoint = [&](Eigen::Index f, int k) {
    return static_cast<std::size_t>(point[static_cast<std::size_t>(mesh.triangles(f, k))]);
  };
  offsets.assign(static_cast<std::size_t>(nv) + 1, 0);
  for (Eigen::Index f = 0; f < nf; ++f) {
    for (int k = 0; k < 3; ++k) ++offsets[cornerPoint(f, k) + 1];
  }
  for (std::size_t v = 0; v + 1 < offsets.size(); ++v) offsets[v + 1] += offsets[v];
  faces.resize(static_cast<std::size_t>(offsets.back()));
  std::vector<int> fill(offsets.begin(), offsets.end() - 1);
  for (Eigen::Index f = 0; f < nf; ++f) {
    for (int k = 0; k < 3; ++k) faces[static_cast<std::size_t>(fill[cornerPoint(f, k)]++)] = static_cast<int>(f);
  }
}

VertexSample independentVertexSample(const VertexAdjacency& adjacency) {
  const std::size_t n = adjacency.offsets.empty() ? 0 : adjacency.offsets.size() - 1;
  VertexSample out;
  std::vector<char> covered(n, 0);
  for (std::size_t v = 0; v < n; ++v) {
    if (covered[v]) continue;
    int weight = 1;
    for (int k = adjacency.offsets[v]; k < adjacency.offsets[v + 1]; ++k) {
      const auto u = static_cast<std::size_t>(adjacency.indices[static_cast<std::size_t>(k)]);
      // Neighbours before v are sampled or covered already.
      if (u > v && !covered[u]) {
        covered[u] = 1;
        ++weight;
      }
    }
    out.vertices.push_back(static_cast<int>(v));
    out.weight.push_back(weight);
  }
  return out;
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

int countDegenerateTriangles(const Mesh& mesh) {
  const double diagonal = boundingBoxDiagonal(mesh.positions);
  int count = 0;
  for (Eigen::Index f = 0; f < mesh.triangles.rows(); ++f) {
    if (isDegenerateTriangle(mesh.positions, mesh.triangles.row(f).transpose(), diagonal)) ++count;
  }
  return count;
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

Eigen::VectorXd meanIncidentEdgeLengths(const Mesh& mesh, const std::vector<int>& representative) {
  const Eigen::Index n = mesh.vertexCount();
  auto pointOf = [&](Eigen::Index v) -> Eigen::Index {
    return representative.empty() ? v : representative[static_cast<std::size_t>(v)];
  };
  Eigen::VectorXd sum = Eigen::VectorXd::Zero(n), count = Eigen::VectorXd::Zero(n);
  for (Eigen::Index f = 0; f < mesh.triangles.rows(); ++f) {
    for (int k = 0; k < 3; ++k) {
      const Eigen::Index a = pointOf(mesh.triangles(f, k)), b = pointOf(mesh.triangles(f, (k + 1) % 3));
      const double length = (mesh.positions.row(a) - mesh.positions.row(b)).norm();
      sum(a) += length;
      sum(b) += length;
      count(a) += 1;
      count(b) += 1;
    }
  }
  Eigen::VectorXd mean = Eigen::VectorXd::Zero(n);
  for (Eigen::Index v = 0; v < n; ++v) {
    const Eigen::Index p = pointOf(v);
    if (count(p) > 0) mean(v) = sum(p) / count(p);
  }
  return mean;
}

Mesh weldedTopology(const Mesh& mesh, const std::vector<int>& representative) {
  Mesh welded;
  welded.positions = mesh.positions;
  welded.triangles = mesh.triangles;
  if (!representative.empty()) {
    for (Eigen::Index i = 0; i < welded.triangles.size(); ++i) {
      welded.triangles.data()[i] = representative[static_cast<std::size_t>(welded.triangles.data()[i])];
    }
  }
  return welded;
}

MeshPieces meshPieces(const Mesh& mesh, const std::vector<int>& representative) {
  const Eigen::Index nv = mesh.vertexCount(), nf = mesh.triangleCount();
  auto weld = [&](int v) { return representative.empty() ? v : representative[static_cast<std::size_t>(v)]; };
  std::vector<int> parent(static_cast<std::size_t>(nv));
  std::iota(parent.begin(), parent.end(), 0);
  auto root = [&](int v) {
    while (parent[static_cast<std::size_t>(v)] != v) {
      parent[static_cast<std::size_t>(v)] = parent[static_cast<std::size_t>(parent[static_cast<std::size_t>(v)])];
      v = parent[static_cast<std::size_t>(v)];
    }
    return v;
  };
  for (Eigen::Index f = 0; f < nf; ++f) {
    const int a = root(weld(mesh.triangles(f, 0)));
    for (int k = 1; k < 3; ++k) {
      const int b = root(weld(mesh.triangles(f, k)));
      if (a != b) parent[static_cast<std::size_t>(b)] = a;
    }
  }
  MeshPieces pieces;
  pieces.face_piece.resize(static_cast<std::size_t>(nf));
  pieces.vertex_piece.assign(static_cast<std::size_t>(nv), -1);
  std::vector<int> number(static_cast<std::size_t>(nv), -1);  // by root
  for (Eigen::Index f = 0; f < nf; ++f) {
    int& n = number[static_cast<std::size_t>(root(weld(mesh.triangles(f, 0))))];
    if (n < 0) n = pieces.count++;
    pieces.face_piece[static_cast<std::size_t>(f)] = n;
    for (int k = 0; k < 3; ++k) pieces.vertex_piece[static_cast<std::size_t>(mesh.triangles(f, k))] = n;
  }
  return pieces;
}

std::vector<BoundaryLoop> boundaryLoops(const Mesh& mesh) {
  const Eigen::MatrixX3i& tris = mesh.triangles;
  const auto nv = static_cast<std::size_t>(mesh.vertexCount());
  const auto nf = static_cast<std::size_t>(tris.rows());
  auto distinct = [&](std::size_t f) {
    const auto t = tris.row(static_cast<Eigen::Index>(f));
    return t(0) != t(1) && t(1) != t(2) && t(0) != t(2);
  };
  auto corner = [&](std::size_t h) { return tris(static_cast<Eigen::Index>(h / 3), static_cast<Eigen::Index>(h % 3)); };
  auto next = [&](std::size_t h) { return tris(static_cast<Eigen::Index>(h / 3), static_cast<Eigen::Index>((h + 1) % 3)); };
  // Half-edges h = 3f + c (corner c -> c + 1) bucketed by their smaller end
  // (counting sort, face order within a bucket): an edge's uses share a
  // bucket of a few entries, so counting them needs no hashing.
  std::vector<int> start(nv + 1, 0);
  for (std::size_t f = 0; f < nf; ++f) {
    if (!distinct(f)) continue;
    for (std::size_t c = 0; c < 3; ++c) ++start[static_cast<std::size_t>(std::min(corner(3 * f + c), next(3 * f + c))) + 1];
  }
  for (std::size_t v = 0; v < nv; ++v) start[v + 1] += start[v];
  std::vector<int> bucket(static_cast<std::size_t>(start.back()));  // half-edge
  std::vector<int> other(bucket.size());                             // its larger end
  {
    std::vector<int> fill(start.begin(), start.end() - 1);
    for (std::size_t f = 0; f < nf; ++f) {
      if (!distinct(f)) continue;
      for (std::size_t c = 0; c < 3; ++c) {
        const int a = corner(3 * f + c), b = next(3 * f + c);
        const auto slot = static_cast<std::size_t>(fill[static_cast<std::size_t>(std::min(a, b))]++);
        bucket[slot] = static_cast<int>(3 * f + c);
        other[slot] = std::max(a, b);
      }
    }
  }
  std::vector<char> is_boundary(3 * nf, 0);
  for (std::size_t v = 0; v < nv; ++v) {
    for (int i = start[v]; i < start[v + 1]; ++i) {
      int uses = 0;
      for (int j = start[v]; j < start[v + 1]; ++j) uses += other[static_cast<std::size_t>(j)] == other[static_cast<std::size_t>(i)] ? 1 : 0;
      is_boundary[static_cast<std::size_t>(bucket[static_cast<std::size_t>(i)])] = uses == 1 ? 1 : 0;
    }
  }
  // Boundary half-edges in face order, and grouped by start vertex.
  std::vector<std::size_t> half_edges;
  std::vector<int> out_start(nv + 1, 0);
  for (std::size_t h = 0; h < 3 * nf; ++h) {
    if (!is_boundary[h]) continue;
    half_edges.push_back(h);
    ++out_start[static_cast<std::size_t>(corner(h)) + 1];
  }
  for (std::size_t v = 0; v < nv; ++v) out_start[v + 1] += out_start[v];
  std::vector<std::size_t> outgoing(half_edges.size());
  {
    std::vector<int> fill(out_start.begin(), out_start.end() - 1);
    for (std::size_t h : half_edges) outgoing[static_cast<std::size_t>(fill[static_cast<std::size_t>(corner(h))]++)] = h;
  }
  std::vector<char> used(3 * nf, 0);
  std::vector<BoundaryLoop> loops;
  for (const std::size_t h0 : half_edges) {
    if (used[h0]) continue;
    BoundaryLoop loop;
    const int a0 = corner(h0);
    std::size_t h = h0;
    // Follow unused boundary half-edges until the loop closes (or, on an
    // inconsistently oriented mesh, the chain ends).
    for (;;) {
      used[h] = 1;
      loop.vertices.push_back(corner(h));
      loop.faces.push_back(static_cast<int>(h / 3));
      loop.corners.push_back({static_cast<int>(h % 3), static_cast<int>((h + 1) % 3)});
      const int current = next(h);
      if (current == a0) break;
      std::size_t taken = 3 * nf;
      for (int k = out_start[static_cast<std::size_t>(current)]; k < out_start[static_cast<std::size_t>(current) + 1]; ++k) {
        if (!used[outgoing[static_cast<std::size_t>(k)]]) {
          taken = outgoing[static_cast<std::size_t>(k)];
          break;
        }
      }
      if (taken == 3 * nf) {
        loop.vertices.push_back(current);
        loop.closed = false;
        break;
      }
      h = taken;
    }
    if (loop.closed) {
      // Start each closed loop at its smallest vertex index (stable output).
      const auto first = std::min_element(loop.vertices.begin(), loop.vertices.end()) - loop.vertices.begin();
      std::rotate(loop.vertices.begin(), loop.vertices.begin() + first, loop.vertices.end());
      std::rotate(loop.faces.begin(), loop.faces.begin() + first, loop.faces.end());
      std::rotate(loop.corners.begin(), loop.corners.begin() + first, loop.corners.end());
    }
    const std::size_t n = loop.vertices.size();
    for (std::size_t i = 0; i + (loop.closed ? 0 : 1) < n; ++i) {
      loop.length += (mesh.positions.row(loop.vertices[i]) - mesh.positions.row(loop.vertices[(i + 1) % n])).norm();
    }
    loops.push_back(std::move(loop));
  }
  // Longest first by geometric length (the rim before the mouth before the
  // eyes, whatever the resolution); ties by vertex count, then first vertex.
  std::stable_sort(loops.begin(), loops.end(), [](const BoundaryLoop& x, const BoundaryLoop& y) {
    if (x.length != y.length) return x.length > y.length;
    if (x.vertices.size() != y.vertices.size()) return x.vertices.size() > y.vertices.size();
    return x.vertices.front() < y.vertices.front();
  });
  return loops;
}

Status validateSurfaceMesh(const Mesh& mesh, const std::string& label) {
  if (auto ok = validateMesh(mesh, label); !ok) return ok;
  if (mesh.triangleCount() == 0) {
    return makeError(ErrorCode::kInvalidMesh, label + ": not a triangle mesh (it has no faces)");
  }
  if (countDegenerateTriangles(mesh) == static_cast<int>(mesh.triangleCount())) {
    return makeError(ErrorCode::kInvalidMesh, label + ": all " + std::to_string(mesh.triangleCount()) +
                                                  " triangles have zero area (the mesh has no surface)");
  }
  return Ok{};
}

bool isSolid(const Mesh& mesh) {
  if (mesh.triangleCount() == 0) return false;
  return boundaryLoops(weldedTopology(mesh, coincidentVertexRepresentatives(mesh.positions))).empty();
}

}  // namespace core
