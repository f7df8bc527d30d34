#include "core/attributes.h"

#include <cassert>
#include <map>

namespace core {

namespace {

Eigen::MatrixXd interpolate(const Eigen::MatrixXd& values, const Eigen::MatrixX3i& triangles,
                            const TargetLocations& locations, Eigen::Index nt) {
  Eigen::MatrixXd out = Eigen::MatrixXd::Zero(nt, values.cols());
  for (Eigen::Index v = 0; v < nt; ++v) {
    const SurfacePoint& sp = locations.on_source[static_cast<std::size_t>(v)];
    if (!sp.found()) continue;
    out.row(v) = interpolateOnFace(values, triangles, sp.face, sp.barycentric);
  }
  return out;
}

// Labels of untrusted vertices: majority of already-labelled neighbours,
// growing outward from the trusted ones (ties: lower label).
void fillUntrustedLabels(Eigen::VectorXi& labels, std::vector<char> assigned, const Eigen::SparseMatrix<double>& laplacian) {
  for (bool changed = true; changed;) {
    changed = false;
    std::vector<std::pair<int, int>> updates;
    for (int v = 0; v < laplacian.outerSize(); ++v) {
      if (assigned[static_cast<std::size_t>(v)]) continue;
      std::map<int, int> votes;
      for (Eigen::SparseMatrix<double>::InnerIterator it(laplacian, v); it; ++it) {
        if (it.row() != v && assigned[static_cast<std::size_t>(it.row())]) ++votes[labels(it.row())];
      }
      if (votes.empty()) continue;
      const auto best = std::max_element(votes.begin(), votes.end(), [](const auto& a, const auto& b) { return a.second < b.second; });
      updates.emplace_back(v, best->first);
    }
    for (const auto& [v, label] : updates) {
      labels(v) = label;
      assigned[static_cast<std::size_t>(v)] = 1;
      changed = true;
    }
  }
}

}  // namespace

TransferredAttributes transferAttributes(const Mesh& source_mesh, const VertexAttributes& source,
                                         const TargetLocations& locations, const Eigen::SparseMatrix<double>& target_laplacian,
                                         const HarmonicInpainting* mismatched, const AttributeTransferOptions& options) {
  TransferredAttributes out;
  const Eigen::Index nt = locations.confidence.size();
  std::vector<char> trusted(static_cast<std::size_t>(nt));
  bool any_untrusted = false;
  for (Eigen::Index v = 0; v < nt; ++v) {
    trusted[static_cast<std::size_t>(v)] = locations.mismatched(v) == 0;
    any_untrusted = any_untrusted || !trusted[static_cast<std::size_t>(v)];
  }
  assert(!any_untrusted || (target_laplacian.rows() == nt && mismatched != nullptr));
  auto inpaint = [&](const Eigen::MatrixXd& values) -> Eigen::MatrixXd {
    return mismatched != nullptr ? mismatched->apply(values) : values;
  };
  const Eigen::MatrixX3i& tris = source_mesh.triangles;
  if (options.uvs) {
    // Triangle-local interpolation: a split (seam) vertex belongs to one chart,
    // and every source triangle references its own chart's copies.
    if (source_mesh.uvs.rows() > 0) out.uvs = inpaint(interpolate(source_mesh.uvs, tris, locations, nt));
    for (const auto& set : source.extra_uv_sets) out.attributes.extra_uv_sets.push_back(inpaint(interpolate(set, tris, locations, nt)));
  }
  if (source.colors.rows() > 0) out.attributes.colors = inpaint(interpolate(source.colors, tris, locations, nt));
  for (const auto& [name, field] : source.fields) out.attributes.fields[name] = inpaint(interpolate(field, tris, locations, nt));
  for (const auto& [name, labels] : source.labels) {
    Eigen::VectorXi result = Eigen::VectorXi::Zero(nt);
    for (Eigen::Index v = 0; v < nt; ++v) {
      const SurfacePoint& sp = locations.on_source[static_cast<std::size_t>(v)];
      if (!sp.found()) continue;
      // Majority by barycentric weight; ties go to the lower label.
      int best = labels(tris(sp.face, 0));
      double best_weight = -1.0;
      for (int k = 0; k < 3; ++k) {
        const int label = labels(tris(sp.face, k));
        double w = 0.0;
        for (int m = 0; m < 3; ++m) if (labels(tris(sp.face, m)) == label) w += sp.barycentric(m);
        if (w > best_weight || (w == best_weight && label < best)) {
          best_weight = w;
          best = label;
        }
      }
      result(v) = best;
    }
    if (any_untrusted) fillUntrustedLabels(result, trusted, target_laplacian);
    out.attributes.labels[name] = result;
  }
  return out;
}

}  // namespace core
