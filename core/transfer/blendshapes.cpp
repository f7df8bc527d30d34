#include "core/transfer/blendshapes.h"

#include <algorithm>
#include <bit>
#include <cstdint>

#include "core/base/parallel.h"
#include "core/base/vector_clones.h"

namespace core {

namespace {

// Vertex normals of the displaced target minus the rest ones, recomputed only
// at vertices next to a moving one (elsewhere the delta is exactly 0). The
// vertices sharing a representative (`shared`, smoothVertexRepresentatives:
// the copies of a point split at a UV seam) take the normal of all their
// faces, so both sides of a seam shade alike under the shape. Each sums its
// faces in ascending order with the formula of computeVertexNormals, so the
// values are bit-identical to computeSharedVertexNormals of the whole mesh
// (53 shapes did that: most of the shape stage).
Eigen::MatrixX3d normalDeltas(const Mesh& target, const std::vector<int>& shared, const Eigen::MatrixX3d& base_normals,
                              const Eigen::MatrixX3d& deltas) {
  const Eigen::Index nv = target.vertexCount();
  const Eigen::MatrixX3i& tris = target.triangles;
  auto pointOf = [&](Eigen::Index v) -> std::size_t {
    return static_cast<std::size_t>(shared.empty() ? v : shared[static_cast<std::size_t>(v)]);
  };
  std::vector<unsigned char> moving(static_cast<std::size_t>(nv), 0), affected(static_cast<std::size_t>(nv), 0);
  for (Eigen::Index v = 0; v < nv; ++v) moving[static_cast<std::size_t>(v)] = deltas.row(v).isZero(0.0) ? 0 : 1;
  auto touches = [&](const std::vector<unsigned char>& mark, Eigen::Index f, bool by_point) {
    unsigned char any = 0;
    for (int k = 0; k < 3; ++k) any |= mark[by_point ? pointOf(tris(f, k)) : static_cast<std::size_t>(tris(f, k))];
    return any;
  };
  for (Eigen::Index f = 0; f < tris.rows(); ++f) {
    if (!touches(moving, f, false)) continue;
    for (int k = 0; k < 3; ++k) affected[pointOf(tris(f, k))] = 1;
  }
  Eigen::MatrixX3d normals = Eigen::MatrixX3d::Zero(nv, 3);
  for (Eigen::Index f = 0; f < tris.rows(); ++f) {
    if (!touches(affected, f, true)) continue;
    const Eigen::Vector3d a = target.positions.row(tris(f, 0)) + deltas.row(tris(f, 0));
    const Eigen::Vector3d b = target.positions.row(tris(f, 1)) + deltas.row(tris(f, 1));
    const Eigen::Vector3d c = target.positions.row(tris(f, 2)) + deltas.row(tris(f, 2));
    const Eigen::RowVector3d n = (b - a).cross(c - a).transpose();
    for (int k = 0; k < 3; ++k) {
      const std::size_t p = pointOf(tris(f, k));
      if (affected[p]) normals.row(static_cast<Eigen::Index>(p)) += n;
    }
  }
  Eigen::MatrixX3d out = Eigen::MatrixX3d::Zero(nv, 3);
  for (Eigen::Index v = 0; v < nv; ++v) {
    // Representatives come first in index order: normalised before their copies read them.
    const auto p = static_cast<Eigen::Index>(pointOf(v));
    if (!affected[static_cast<std::size_t>(p)]) continue;
    if (p == v) {
      // The same expressions on the same matrix rows as computeVertexNormals
      // (a contiguous vector's norm() may sum in another order).
      const double len = normals.row(v).norm();
      if (len > 0.0) normals.row(v) /= len;
    }
    out.row(v) = normals.row(p) - base_normals.row(v);
  }
  return out;
}

// Each located target vertex's source corners and weights (corner -1: no
// location), read once per shape from this compact table (the SurfacePoints
// are 80 bytes each).
struct Corners {
  int vertex[3];
  double weight[3];
};

std::vector<Corners> cornerTable(const Eigen::MatrixX3i& source_triangles, const TargetLocations& locations) {
  std::vector<Corners> corners(locations.on_source.size(), Corners{{-1, -1, -1}, {0.0, 0.0, 0.0}});
  for (std::size_t v = 0; v < corners.size(); ++v) {
    const SurfacePoint& sp = locations.on_source[v];
    if (!sp.found()) continue;
    for (int c = 0; c < 3; ++c) {
      corners[v].vertex[c] = source_triangles(sp.face, c);
      corners[v].weight[c] = sp.barycentric(c);
    }
  }
  return corners;
}

// mark[i] = 1 where (x, y, z)[i] has a non-zero coordinate. Cloned: the
// baseline build leaves the 64-to-8-bit narrowing scalar, the AVX2 and
// AVX-512F clones vectorise it.
RIGPORT_VECTOR_CLONES
void markMoving(const double* __restrict x, const double* __restrict y, const double* __restrict z, Eigen::Index n,
                unsigned char* __restrict mark) {
  for (Eigen::Index i = 0; i < n; ++i) {
    const std::uint64_t bits =
        std::bit_cast<std::uint64_t>(x[i]) | std::bit_cast<std::uint64_t>(y[i]) | std::bit_cast<std::uint64_t>(z[i]);
    mark[i] = (bits << 1) != 0 ? 1 : 0;
  }
}

// One shape's deltas at the located target vertices: interpolated, adapted,
// scaled by `gain`. `moving` is scratch space.
Eigen::MatrixX3d gatherDeltas(const MorphTarget& s, const std::vector<Corners>& corners,
                              const std::vector<Eigen::Matrix3d>& adaptation, double gain,
                              std::vector<unsigned char>& moving) {
  const auto nt = static_cast<Eigen::Index>(corners.size());
  Eigen::MatrixX3d out = Eigen::MatrixX3d::Zero(nt, 3);
  // Shapes are sparse: one sequential pass marks the source vertices that
  // move, so target vertices located among still ones skip the gather.
  // A delta is non-zero when any coordinate's bits other than the sign are
  // set (as `!= 0.0`, NaN included): integer tests, which vectorise.
  const Eigen::Index ns = s.position_deltas.rows();
  moving.resize(static_cast<std::size_t>(ns));
  markMoving(s.position_deltas.col(0).data(), s.position_deltas.col(1).data(), s.position_deltas.col(2).data(), ns,
             moving.data());
  for (Eigen::Index v = 0; v < nt; ++v) {
    const Corners& at = corners[static_cast<std::size_t>(v)];
    if (at.vertex[0] < 0) continue;  // no location
    if (!(moving[static_cast<std::size_t>(at.vertex[0])] | moving[static_cast<std::size_t>(at.vertex[1])] |
          moving[static_cast<std::size_t>(at.vertex[2])])) {
      continue;
    }
    Eigen::Vector3d d = Eigen::Vector3d::Zero();
    for (int c = 0; c < 3; ++c) d += at.weight[c] * s.position_deltas.row(at.vertex[c]).transpose();
    if (d.isZero(0.0)) continue;  // keeps sparse shapes sparse
    const Eigen::Matrix3d& a = adaptation.size() == 1 ? adaptation[0] : adaptation[static_cast<std::size_t>(v)];
    out.row(v) = gain * (a * d).transpose();
  }
  return out;
}

}  // namespace

std::vector<MorphTarget> transferMorphTargets(const std::vector<MorphTarget>& source,
                                              const Eigen::MatrixX3i& source_triangles,
                                              const TargetLocations& locations,
                                              const std::vector<Eigen::Matrix3d>& adaptation, const Mesh& target,
                                              const HarmonicInpainting* mismatched,
                                              const ShapeTransferOptions& options) {
  const Eigen::Index nt = target.vertexCount();
  std::vector<MorphTarget> out(source.size());
  const std::vector<Corners> corners = cornerTable(source_triangles, locations);
  parallelFor(static_cast<std::ptrdiff_t>(source.size()), [&](std::ptrdiff_t begin, std::ptrdiff_t end) {
    std::vector<unsigned char> moving;
    for (std::ptrdiff_t k = begin; k < end; ++k) {
      const MorphTarget& s = source[static_cast<std::size_t>(k)];
      const double gain = options.exaggeration.of(s.name);
      out[static_cast<std::size_t>(k)].name = s.name;
      out[static_cast<std::size_t>(k)].position_deltas = gatherDeltas(s, corners, adaptation, gain, moving);
    }
  }, 1);
  if (mismatched != nullptr) inpaintShapeDeltas(*mismatched, out);

  // Normal deltas from the final position deltas (the source's are not
  // transferable: they belong to the source's surface).
  for (std::size_t k = 0; k < source.size(); ++k) {
    if (source[k].normal_deltas.rows() > 0) out[k].normal_deltas.resize(nt, 3);
  }
  updateNormalDeltas(target, out);
  return out;
}

// All shapes in one solve, from the boundary rows only (stacking whole shapes
// cost #V x 3 #shapes doubles: 335 MB at 93k vertices, 150 shapes).
void inpaintShapeDeltas(const HarmonicInpainting& inpainting, std::vector<MorphTarget>& shapes) {
  if (shapes.empty()) return;
  const std::vector<int>& boundary = inpainting.boundary();
  Eigen::MatrixXd values(static_cast<Eigen::Index>(boundary.size()), 3 * static_cast<Eigen::Index>(shapes.size()));
  for (std::size_t k = 0; k < shapes.size(); ++k) {
    for (std::size_t i = 0; i < boundary.size(); ++i) {
      values.block<1, 3>(static_cast<Eigen::Index>(i), 3 * static_cast<Eigen::Index>(k)) =
          shapes[k].position_deltas.row(boundary[i]);
    }
  }
  const Eigen::MatrixXd solved = inpainting.solve(values);
  const std::vector<int>& unknown_vertices = inpainting.unknown();
  for (std::size_t k = 0; k < shapes.size(); ++k) {
    for (std::size_t i = 0; i < unknown_vertices.size(); ++i) {
      if (!inpainting.reached(i)) {
        shapes[k].position_deltas.row(unknown_vertices[i]).setZero();
        continue;
      }
      const Eigen::RowVector3d d = solved.row(static_cast<Eigen::Index>(i)).segment<3>(3 * static_cast<Eigen::Index>(k));
      shapes[k].position_deltas.row(unknown_vertices[i]) = d.cwiseAbs().maxCoeff() < 1e-12 ? Eigen::RowVector3d::Zero() : d;
    }
  }
}

void updateNormalDeltas(const Mesh& target, std::vector<MorphTarget>& shapes) {
  const Eigen::Index nt = target.vertexCount();
  const bool any_normal_deltas =
      std::any_of(shapes.begin(), shapes.end(), [](const MorphTarget& s) { return s.normal_deltas.rows() > 0; });
  if (!any_normal_deltas) return;
  const std::vector<int> shared = target.normals.rows() == nt
                                      ? smoothVertexRepresentatives(target.positions, target.normals)
                                      : std::vector<int>();
  const Eigen::MatrixX3d rest_normals = computeSharedVertexNormals(target.positions, target.triangles, shared);
  parallelFor(static_cast<std::ptrdiff_t>(shapes.size()), [&](std::ptrdiff_t begin, std::ptrdiff_t end) {
    for (std::ptrdiff_t k = begin; k < end; ++k) {
      MorphTarget& t = shapes[static_cast<std::size_t>(k)];
      if (t.normal_deltas.rows() == 0) continue;
      t.normal_deltas = normalDeltas(target, shared, rest_normals, t.position_deltas);
      // Exact zeros where the shape does not move, so sparse output stays sparse.
      for (Eigen::Index v = 0; v < nt; ++v) {
        if (t.normal_deltas.row(v).cwiseAbs().maxCoeff() < 1e-12) t.normal_deltas.row(v).setZero();
      }
    }
  }, 1);
}

}  // namespace core
