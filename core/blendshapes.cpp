#include "core/blendshapes.h"

#include <cassert>

#include "core/inpainting.h"
#include "core/parallel.h"

namespace core {

std::vector<MorphTarget> transferMorphTargets(const std::vector<MorphTarget>& source,
                                              const Eigen::MatrixX3i& source_triangles,
                                              const TargetLocations& locations,
                                              const std::vector<Eigen::Matrix3d>& adaptation, const Mesh& target,
                                              const Eigen::SparseMatrix<double>& target_laplacian,
                                              const ShapeTransferOptions& options) {
  const Eigen::Index nt = target.vertexCount();
  std::vector<MorphTarget> out(source.size());
  const Eigen::MatrixX3d base_normals = computeVertexNormals(target.positions, target.triangles);
  parallelFor(static_cast<std::ptrdiff_t>(source.size()), options.threads, [&](std::ptrdiff_t begin, std::ptrdiff_t end) {
    std::vector<unsigned char> moving;
    for (std::ptrdiff_t k = begin; k < end; ++k) {
      const MorphTarget& s = source[static_cast<std::size_t>(k)];
      MorphTarget& t = out[static_cast<std::size_t>(k)];
      t.name = s.name;
      const auto found = options.per_shape.find(s.name);
      const double gain = found != options.per_shape.end() ? found->second : options.exaggeration;
      t.position_deltas = Eigen::MatrixX3d::Zero(nt, 3);
      // Shapes are sparse: one sequential pass marks the source vertices that
      // move, so target vertices located among still ones skip the gather.
      const Eigen::Index ns = s.position_deltas.rows();
      moving.assign(static_cast<std::size_t>(ns), 0);
      for (int c = 0; c < 3; ++c) {
        const double* col = s.position_deltas.col(c).data();
        for (Eigen::Index i = 0; i < ns; ++i) moving[static_cast<std::size_t>(i)] |= col[i] != 0.0 ? 1 : 0;
      }
      for (Eigen::Index v = 0; v < nt; ++v) {
        const SurfacePoint& sp = locations.on_source[static_cast<std::size_t>(v)];
        if (!sp.found()) continue;
        if (!(moving[static_cast<std::size_t>(source_triangles(sp.face, 0))] |
              moving[static_cast<std::size_t>(source_triangles(sp.face, 1))] |
              moving[static_cast<std::size_t>(source_triangles(sp.face, 2))])) {
          continue;
        }
        Eigen::Vector3d d = Eigen::Vector3d::Zero();
        for (int c = 0; c < 3; ++c) d += sp.barycentric(c) * s.position_deltas.row(source_triangles(sp.face, c)).transpose();
        if (d.isZero(0.0)) continue;  // keeps sparse shapes sparse
        const Eigen::Matrix3d& a = adaptation.size() == 1 ? adaptation[0] : adaptation[static_cast<std::size_t>(v)];
        t.position_deltas.row(v) = gain * (a * d).transpose();
      }
    }
  }, 1);

  // Mismatched vertices (no location, or matched across a thin gap) take
  // deltas blended from their surroundings, never a copy from the wrong lip or
  // lid. All shapes in one solve.
  std::vector<char> known(static_cast<std::size_t>(nt));
  std::size_t unknown = 0;
  for (Eigen::Index v = 0; v < nt; ++v) {
    known[static_cast<std::size_t>(v)] = locations.mismatched(v) == 0;
    unknown += known[static_cast<std::size_t>(v)] ? 0 : 1;
  }
  if (options.inpaint_untrusted && unknown > 0 && unknown < static_cast<std::size_t>(nt) && !out.empty()) {
    Eigen::MatrixXd stacked(nt, 3 * static_cast<Eigen::Index>(out.size()));
    for (std::size_t k = 0; k < out.size(); ++k) stacked.middleCols<3>(3 * static_cast<Eigen::Index>(k)) = out[k].position_deltas;
    assert(target_laplacian.rows() == nt);
    auto solved = inpaintHarmonic(target_laplacian, known, stacked);
    if (solved) {
      for (std::size_t k = 0; k < out.size(); ++k) {
        MorphTarget& t = out[k];
        for (Eigen::Index v = 0; v < nt; ++v) {
          if (known[static_cast<std::size_t>(v)]) continue;
          const Eigen::RowVector3d d = solved->row(v).segment<3>(3 * static_cast<Eigen::Index>(k));
          t.position_deltas.row(v) = d.cwiseAbs().maxCoeff() < 1e-12 ? Eigen::RowVector3d::Zero() : d;
        }
      }
    }
  }

  // Normal deltas from the final position deltas (the source's are not
  // transferable: they belong to the source's surface).
  parallelFor(static_cast<std::ptrdiff_t>(source.size()), options.threads, [&](std::ptrdiff_t begin, std::ptrdiff_t end) {
    for (std::ptrdiff_t k = begin; k < end; ++k) {
      if (source[static_cast<std::size_t>(k)].normal_deltas.rows() == 0) continue;
      MorphTarget& t = out[static_cast<std::size_t>(k)];
      t.normal_deltas = computeVertexNormals(target.positions + t.position_deltas, target.triangles) - base_normals;
      // Exact zeros where the shape does not move, so sparse output stays sparse.
      for (Eigen::Index v = 0; v < nt; ++v) {
        if (t.normal_deltas.row(v).cwiseAbs().maxCoeff() < 1e-12) t.normal_deltas.row(v).setZero();
      }
    }
  }, 1);
  return out;
}

}  // namespace core
