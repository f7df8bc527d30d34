#include "core/fit/scan.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include <Eigen/Eigenvalues>

#include "core/base/parallel.h"

namespace core {

namespace {

constexpr int kMinScanPoints = 100;
// Pieces under this share of the largest piece's area are not skin: eyeball
// caps, teeth, debris a scanner leaves (docs/FIT.md 2.1: caps are ~2%).
constexpr double kDetachedAreaShare = 0.05;
// A vertex off its 1-ring's plane by more than this many times the ring's
// radius (the ring's mean distance to its own centroid, about an edge) is a
// spike: noise is a small fraction of an edge, and a fold or crease of the
// skin sits within about one. The ring's size must not include the vertex:
// its mean distance to the vertex is never below the offset (triangle
// inequality), so a rule on that could not fire.
constexpr double kSpikeRadiusFactor = 1.0;
// A cloud point is on a border (a crop, a hole) when its 24 nearest
// neighbours leave a gap wider than 120 degrees around it: a crop's edge
// leaves ~180, the rim of a hole four spacings wide over 120; among random
// samples of a surface a gap over 90 degrees in 16 neighbours happens by
// chance to ~21% of points (16 (3/4)^15; measured 24% on a random plane),
// this rule to 0.4%.
constexpr int kCloudBorderNeighbours = 24;
constexpr double kCloudBorderGapDeg = 120.0;
// A closest point with a barycentric weight at most this lies on an edge.
constexpr double kOnEdge = 1e-9;
// Candidates of a match by position and normal (nearestAlike): the nearest
// this many points, about a ring and a half of a mesh's vertices (24 gave the
// same fits, measured, at twice the cost).
constexpr int kAlikeCandidates = 12;

// Pieces of a mesh scan: flags the vertices of small pieces as detached.
int flagDetachedPieces(const Mesh& mesh, const std::vector<int>& representative, std::vector<std::uint8_t>& flags,
                       int& piece_count) {
  const MeshPieces pieces = meshPieces(mesh, representative);
  piece_count = pieces.count;
  if (pieces.count < 2) return 0;
  const Eigen::VectorXd areas = computeDoubleAreas(mesh.positions, mesh.triangles);
  std::vector<double> piece_area(static_cast<std::size_t>(pieces.count), 0.0);
  for (Eigen::Index f = 0; f < mesh.triangleCount(); ++f) {
    piece_area[static_cast<std::size_t>(pieces.face_piece[static_cast<std::size_t>(f)])] += areas(f);
  }
  const double largest = *std::max_element(piece_area.begin(), piece_area.end());
  int detached = 0;
  for (Eigen::Index v = 0; v < mesh.vertexCount(); ++v) {
    const int piece = pieces.vertex_piece[static_cast<std::size_t>(v)];
    if (piece >= 0 && piece_area[static_cast<std::size_t>(piece)] < kDetachedAreaShare * largest) {
      flags[static_cast<std::size_t>(v)] |= kScanDetached;
      ++detached;
    }
  }
  return detached;
}

// Vertices on an open boundary of the skin: a crop or a hole. A match that
// lands on such an edge (ScanSurface::nearest) is a point beyond the scan's
// data, not the surface under the query.
void flagMeshBorders(const Mesh& mesh, const std::vector<int>& representative, std::vector<std::uint8_t>& flags,
                     std::vector<std::vector<int>>& rims, ScanReport& report) {
  for (const BoundaryLoop& loop : boundaryLoops(weldedTopology(mesh, representative))) {
    if (loop.vertices.empty() || (flags[static_cast<std::size_t>(loop.vertices.front())] & kScanDetached)) continue;
    for (const int v : loop.vertices) flags[static_cast<std::size_t>(v)] |= kScanBorder;
    if (loop.closed && loop.vertices.size() >= 3) rims.push_back(loop.vertices);
  }
  report.holes = std::max(0, static_cast<int>(rims.size()) - 1);
}

// Spikes of a mesh scan: a vertex far off the least-squares plane of its
// 1-ring (relative to the ring's size).
void flagMeshSpikes(const Mesh& mesh, const VertexAdjacency& adjacency, std::vector<std::uint8_t>& flags) {
  const Eigen::Index nv = mesh.vertexCount();
  parallelFor(nv, [&](std::ptrdiff_t begin, std::ptrdiff_t end) {
    for (std::ptrdiff_t v = begin; v < end; ++v) {
      const int first = adjacency.offsets[static_cast<std::size_t>(v)];
      const int count = adjacency.offsets[static_cast<std::size_t>(v) + 1] - first;
      if (count < 3) continue;
      Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
      for (int i = 0; i < count; ++i) {
        centroid += mesh.positions.row(adjacency.indices[static_cast<std::size_t>(first + i)]).transpose();
      }
      centroid /= count;
      Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
      double radius = 0.0;
      for (int i = 0; i < count; ++i) {
        const Eigen::Vector3d p = mesh.positions.row(adjacency.indices[static_cast<std::size_t>(first + i)]).transpose();
        covariance += (p - centroid) * (p - centroid).transpose();
        radius += (p - centroid).norm();
      }
      radius /= count;
      const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(covariance);
      const Eigen::Vector3d normal = solver.eigenvectors().col(0);
      const double offset = std::abs(normal.dot(mesh.positions.row(v).transpose() - centroid));
      if (offset > kSpikeRadiusFactor * radius) flags[static_cast<std::size_t>(v)] |= kScanSpike;
    }
  });
}

// The faces matched to: those of detached pieces and around spikes made
// degenerate, which the index skips.
Eigen::MatrixX3i usableTriangles(Eigen::MatrixX3i triangles, const std::vector<std::uint8_t>& flags) {
  for (Eigen::Index f = 0; f < triangles.rows(); ++f) {
    for (int k = 0; k < 3; ++k) {
      if (flags[static_cast<std::size_t>(triangles(f, k))] & (kScanDetached | kScanSpike)) {
        triangles.row(f).setConstant(triangles(f, 0));
        break;
      }
    }
  }
  return triangles;
}

Status prepareMeshScan(ScanSurface& scan) {
  Mesh& mesh = scan.mesh;
  const std::vector<int> representative = coincidentVertexRepresentatives(mesh.positions);
  if (mesh.normals.rows() == mesh.vertexCount()) {
    scan.normals = normalsAgreeingWithWinding(mesh.normals, mesh.positions, mesh.triangles).normals;
  } else {
    scan.normals = computeSeamlessVertexNormals(mesh.positions, mesh.triangles);
  }
  const VertexAdjacency adjacency = vertexAdjacency(weldedTopology(mesh, representative).triangles, mesh.vertexCount());
  scan.report.detached_points = flagDetachedPieces(mesh, representative, scan.flags, scan.report.pieces);
  flagMeshBorders(mesh, representative, scan.flags, scan.rims, scan.report);
  flagMeshSpikes(mesh, adjacency, scan.flags);
  scan.surface_index = ClosestPointIndex(mesh.positions, usableTriangles(mesh.triangles, scan.flags));
  scan.point_index = PointCloudIndex(mesh.positions);
  if (scan.surface_index.faceCount() == 0) {
    return Error{ErrorCode::kInvalidMesh, scan.report.file + ": no usable triangle (all degenerate, detached or spikes)"};
  }
  return Ok{};
}

void prepareCloudScan(ScanSurface& scan) {
  const Mesh& mesh = scan.mesh;
  scan.point_index = PointCloudIndex(mesh.positions);
  if (mesh.normals.rows() == mesh.vertexCount()) {
    scan.normals = mesh.normals;
  } else {
    scan.normals = estimateCloudNormals(mesh.positions, scan.point_index);
    scan.report.normals_computed = true;
  }
  const std::vector<char> border =
      cloudBorderPoints(mesh.positions, scan.normals, scan.point_index, kCloudBorderNeighbours, kCloudBorderGapDeg);
  const std::vector<char> spikes = cloudSpikes(mesh.positions, scan.point_index);
  for (std::size_t v = 0; v < scan.flags.size(); ++v) {
    if (border[v]) scan.flags[v] |= kScanBorder;
    if (spikes[v]) scan.flags[v] |= kScanSpike;
  }
}

}  // namespace

ScanMatch ScanSurface::matchAtPoint(int index, const Eigen::Vector3d& query) const {
  ScanMatch m;
  m.found = true;
  m.point = mesh.positions.row(index).transpose();
  m.normal = normals.row(index).transpose();
  m.distance = (m.point - query).norm();
  m.flags = flags[static_cast<std::size_t>(index)];
  return m;
}

std::vector<ScanMatch> ScanSurface::nearest(const Eigen::MatrixX3d& queries) const {
  std::vector<ScanMatch> out(static_cast<std::size_t>(queries.rows()));
  if (!isCloud()) {
    const std::vector<SurfacePoint> points = surface_index.closestPoints(queries);
    for (std::size_t i = 0; i < out.size(); ++i) {
      const SurfacePoint& sp = points[i];
      if (!sp.found()) continue;
      ScanMatch& m = out[i];
      m.found = true;
      m.point = sp.point;
      m.distance = std::sqrt(sp.sq_distance);
      const Eigen::Vector3d n = interpolateOnFace(normals, mesh.triangles, sp.face, sp.barycentric).transpose();
      m.normal = n.norm() > 0.0 ? Eigen::Vector3d(n.normalized()) : n;
      // Spike and detached flags from any corner; border only when the point
      // lies on the border itself (every corner it weighs is a border vertex,
      // and it is on an edge or a corner): the query is beyond the data.
      bool on_edge = false, weighs_border_only = true;
      for (int k = 0; k < 3; ++k) {
        const std::uint8_t corner = flags[static_cast<std::size_t>(mesh.triangles(sp.face, k))];
        m.flags |= corner & static_cast<std::uint8_t>(~kScanBorder);
        if (sp.barycentric(k) <= kOnEdge) on_edge = true;
        else if (!(corner & kScanBorder)) weighs_border_only = false;
      }
      if (on_edge && weighs_border_only) m.flags |= kScanBorder;
    }
    return out;
  }
  const std::vector<PointCloudIndex::Neighbour> points = point_index.nearest(queries);
  for (std::size_t i = 0; i < out.size(); ++i) {
    if (points[i].index >= 0) out[i] = matchAtPoint(points[i].index, queries.row(static_cast<Eigen::Index>(i)).transpose());
  }
  return out;
}

std::vector<ScanMatch> ScanSurface::nearestAlike(const Eigen::MatrixX3d& queries, const Eigen::MatrixX3d& query_normals,
                                                 double normal_weight) const {
  std::vector<ScanMatch> out(static_cast<std::size_t>(queries.rows()));
  const double w2 = normal_weight * normal_weight;
  const bool unsigned_normals = report.normals_computed;
  parallelFor(queries.rows(), [&](std::ptrdiff_t begin, std::ptrdiff_t end) {
    for (std::ptrdiff_t i = begin; i < end; ++i) {
      const Eigen::Vector3d q = queries.row(i).transpose();
      const Eigen::Vector3d nq = query_normals.row(i).transpose();
      double best = std::numeric_limits<double>::infinity();
      int chosen = -1;
      for (const auto& nb : point_index.nearest(q, kAlikeCandidates)) {
        if (flags[static_cast<std::size_t>(nb.index)] & (kScanDetached | kScanSpike)) continue;
        const Eigen::Vector3d n = normals.row(nb.index).transpose();
        const double turn = unsigned_normals ? std::min((n - nq).squaredNorm(), (n + nq).squaredNorm()) : (n - nq).squaredNorm();
        const double score = nb.sq_distance + w2 * turn;
        if (score < best) {
          best = score;
          chosen = nb.index;
        }
      }
      if (chosen >= 0) out[static_cast<std::size_t>(i)] = matchAtPoint(chosen, q);
    }
  });
  return out;
}

Status checkScan(const Mesh& mesh, const std::string& label) {
  if (auto valid = validateMesh(mesh, label); !valid) return valid.error();
  if (mesh.vertexCount() < kMinScanPoints) {
    return Error{ErrorCode::kInvalidMesh, label + ": " + std::to_string(mesh.vertexCount()) +
                                              " points; a head scan needs at least " + std::to_string(kMinScanPoints)};
  }
  if (!(boundingBoxDiagonal(mesh.positions) > 0.0)) return Error{ErrorCode::kInvalidMesh, label + ": every point at one position"};
  return Ok{};
}

Result<ScanSurface> prepareScan(Mesh mesh, const std::string& label) {
  if (auto valid = checkScan(mesh, label); !valid) return valid.error();
  ScanSurface scan;
  scan.mesh = std::move(mesh);
  scan.report.file = label;
  scan.report.points = static_cast<int>(scan.mesh.vertexCount());
  scan.report.triangles = static_cast<int>(scan.mesh.triangleCount());
  scan.report.point_cloud = scan.isCloud();
  scan.flags.assign(static_cast<std::size_t>(scan.mesh.vertexCount()), 0);
  scan.diagonal = boundingBoxDiagonal(scan.mesh.positions);
  if (scan.isCloud()) {
    prepareCloudScan(scan);
  } else if (auto prepared = prepareMeshScan(scan); !prepared) {
    return prepared.error();
  }
  for (const std::uint8_t f : scan.flags) {
    if (f & kScanBorder) ++scan.report.border_points;
    if (f & kScanSpike) ++scan.report.spikes;
  }
  return scan;
}

}  // namespace core
