#include "core/transfer/skin_weights.h"

#include <algorithm>
#include <cassert>
#include <vector>

#include "core/solve/inpainting.h"

namespace core {

namespace {

// Keeps the `max` largest entries of a row (ties: lower joint), renormalised.
std::vector<std::pair<int, double>> pruneRow(std::vector<std::pair<int, double>> row, int max, double min_weight,
                                             bool* pruned) {
  row.erase(std::remove_if(row.begin(), row.end(), [&](const auto& e) { return !(e.second > min_weight); }), row.end());
  std::sort(row.begin(), row.end(), [](const auto& a, const auto& b) {
    return a.second != b.second ? a.second > b.second : a.first < b.first;
  });
  *pruned = static_cast<int>(row.size()) > max;
  if (*pruned) row.resize(static_cast<std::size_t>(max));
  double sum = 0.0;
  for (const auto& e : row) sum += e.second;
  for (auto& e : row) e.second /= sum;
  std::sort(row.begin(), row.end());
  return row;
}

}  // namespace

Result<TransferredWeights> transferSkinWeights(const SkinWeights& source_weights,
                                               const Eigen::MatrixX3i& source_triangles,
                                               const TargetLocations& locations, Eigen::Index nt,
                                               const Eigen::SparseMatrix<double>& target_laplacian,
                                               const SkinWeightOptions& options) {
  if (options.max_influences < 1 || options.max_influences > 8) {
    return makeError(ErrorCode::kInvalidArgument, "max_influences must be between 1 and 8");
  }
  const Eigen::Index nj = source_weights.cols();
  TransferredWeights out;
  out.inpainted = Eigen::VectorXi::Zero(nt);

  // 1. Interpolate at each target vertex's location (dense per row: few joints).
  Eigen::MatrixXd dense = Eigen::MatrixXd::Zero(nt, nj);
  std::vector<char> known(static_cast<std::size_t>(nt), 0);
  for (Eigen::Index v = 0; v < nt; ++v) {
    const SurfacePoint& sp = locations.on_source[static_cast<std::size_t>(v)];
    if (!sp.found()) continue;
    for (int k = 0; k < 3; ++k) {
      const int s = source_triangles(sp.face, k);
      for (SkinWeights::InnerIterator it(source_weights, s); it; ++it) dense(v, it.col()) += sp.barycentric(k) * it.value();
    }
    known[static_cast<std::size_t>(v)] = locations.confidence(v) > 0.0 && dense.row(v).sum() > 0.0;
  }

  // 1b. Detached pieces (eyeballs, teeth modelled in the face's mesh) move
  // rigidly with the joint that dominates the weights where they sit: lower
  // teeth follow the jaw, an eyeball the head or its eye joint, and nothing
  // bends them.
  if (!locations.detached_piece.empty()) {
    const int pieces = 1 + *std::max_element(locations.detached_piece.begin(), locations.detached_piece.end());
    Eigen::MatrixXd votes = Eigen::MatrixXd::Zero(pieces, nj);
    for (Eigen::Index v = 0; v < nt; ++v) {
      const int piece = locations.detached_piece[static_cast<std::size_t>(v)];
      if (piece >= 0) votes.row(piece) += dense.row(v);
    }
    for (Eigen::Index v = 0; v < nt; ++v) {
      const int piece = locations.detached_piece[static_cast<std::size_t>(v)];
      if (piece < 0 || !(votes.row(piece).maxCoeff() > 0.0)) continue;
      Eigen::Index joint = 0;
      votes.row(piece).maxCoeff(&joint);
      dense.row(v).setZero();
      dense(v, joint) = 1.0;
      known[static_cast<std::size_t>(v)] = 1;
    }
  }

  // 2. Inpaint untrusted vertices from trusted ones (harmonic).
  if (options.inpaint) {
    const std::size_t unknown = static_cast<std::size_t>(std::count(known.begin(), known.end(), 0));
    if (unknown > 0 && unknown < known.size()) {
      assert(target_laplacian.rows() == nt);
      auto solved = inpaintHarmonic(target_laplacian, known, dense);
      if (!solved) return solved.error();
      for (Eigen::Index v = 0; v < nt; ++v) {
        if (known[static_cast<std::size_t>(v)]) continue;
        const Eigen::RowVectorXd row = solved->row(v).cwiseMax(0.0);
        if (row.sum() > 1e-6) {
          dense.row(v) = row;
          out.inpainted(v) = 1;
          ++out.inpainted_vertices;
        }
      }
    }
  }

  // 3. Prune and renormalise. Every target vertex must end with weights.
  std::vector<Eigen::Triplet<double>> triplets;
  for (Eigen::Index v = 0; v < nt; ++v) {
    std::vector<std::pair<int, double>> row;
    for (Eigen::Index j = 0; j < nj; ++j) if (dense(v, j) > 0.0) row.emplace_back(static_cast<int>(j), dense(v, j));
    bool pruned = false;
    row = pruneRow(std::move(row), options.max_influences, options.min_weight, &pruned);
    if (row.empty()) {
      return makeError(ErrorCode::kInvalidMesh, "skin weights: target vertex " + std::to_string(v) +
                                                    " found no source weights (no match and nothing to inpaint from)");
    }
    out.pruned_vertices += pruned ? 1 : 0;
    out.max_influences = std::max(out.max_influences, static_cast<int>(row.size()));
    for (const auto& [j, w] : row) triplets.emplace_back(static_cast<int>(v), j, w);
  }
  out.weights.resize(nt, nj);
  out.weights.setFromTriplets(triplets.begin(), triplets.end());
  out.weights.makeCompressed();
  return out;
}

}  // namespace core
