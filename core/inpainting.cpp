#include "core/inpainting.h"

#include <Eigen/SparseCholesky>
#include <algorithm>

namespace core {

Eigen::SparseMatrix<double> uniformLaplacian(Eigen::Index vertex_count, const Eigen::MatrixX3i& triangles) {
  // Unique undirected edges first (an interior edge appears in two faces):
  // bucketed by their lower vertex, each short bucket sorted on its own (a
  // global sort of all half-edges cost more than the rest of the function).
  std::vector<int> offsets(static_cast<std::size_t>(vertex_count) + 1, 0);
  auto forEachEdge = [&](auto&& fn) {
    for (Eigen::Index f = 0; f < triangles.rows(); ++f) {
      for (int k = 0; k < 3; ++k) {
        const int a = triangles(f, k), b = triangles(f, (k + 1) % 3);
        if (a != b) fn(std::min(a, b), std::max(a, b));
      }
    }
  };
  forEachEdge([&](int a, int) { ++offsets[static_cast<std::size_t>(a) + 1]; });
  for (std::size_t v = 0; v + 1 < offsets.size(); ++v) offsets[v + 1] += offsets[v];
  std::vector<int> upper(static_cast<std::size_t>(offsets.back()));
  {
    std::vector<int> fill(offsets.begin(), offsets.end() - 1);
    forEachEdge([&](int a, int b) { upper[static_cast<std::size_t>(fill[static_cast<std::size_t>(a)]++)] = b; });
  }
  std::vector<std::pair<int, int>> edges;
  edges.reserve(upper.size());
  for (std::size_t a = 0; a + 1 < offsets.size(); ++a) {
    const auto first = upper.begin() + offsets[a], last = upper.begin() + offsets[a + 1];
    std::sort(first, last);
    for (auto it = first; it != last; ++it) {
      if (it == first || *it != *(it - 1)) edges.emplace_back(static_cast<int>(a), *it);
    }
  }
  // One triplet pass, diagonal included: inserting into a compressed matrix
  // afterwards costs O(nnz) per entry.
  std::vector<Eigen::Triplet<double>> triplets;
  triplets.reserve(edges.size() * 2 + static_cast<std::size_t>(vertex_count));
  Eigen::VectorXd degree = Eigen::VectorXd::Zero(vertex_count);
  for (const auto& [a, b] : edges) {
    triplets.emplace_back(a, b, -1.0);
    triplets.emplace_back(b, a, -1.0);
    degree(a) += 1.0;
    degree(b) += 1.0;
  }
  for (Eigen::Index v = 0; v < vertex_count; ++v) triplets.emplace_back(static_cast<int>(v), static_cast<int>(v), degree(v));
  Eigen::SparseMatrix<double> laplacian(vertex_count, vertex_count);
  laplacian.setFromTriplets(triplets.begin(), triplets.end());
  return laplacian;
}

Result<Eigen::MatrixXd> inpaintHarmonic(const Eigen::SparseMatrix<double>& laplacian, const std::vector<char>& known,
                                        const Eigen::MatrixXd& values) {
  const Eigen::Index n = values.rows();
  std::vector<int> unknown;
  for (Eigen::Index v = 0; v < n; ++v) if (!known[static_cast<std::size_t>(v)]) unknown.push_back(static_cast<int>(v));
  Eigen::MatrixXd out = values;
  if (unknown.empty() || unknown.size() == static_cast<std::size_t>(n)) return out;
  std::vector<int> slot(static_cast<std::size_t>(n), -1);
  for (std::size_t i = 0; i < unknown.size(); ++i) slot[static_cast<std::size_t>(unknown[i])] = static_cast<int>(i);
  const Eigen::Index nu = static_cast<Eigen::Index>(unknown.size());
  std::vector<Eigen::Triplet<double>> luu;
  Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(nu, values.cols());
  Eigen::VectorXd touches_known = Eigen::VectorXd::Zero(nu);
  for (int k = 0; k < laplacian.outerSize(); ++k) {
    for (Eigen::SparseMatrix<double>::InnerIterator it(laplacian, k); it; ++it) {
      const int r = slot[static_cast<std::size_t>(it.row())];
      if (r < 0) continue;
      const int c = slot[static_cast<std::size_t>(it.col())];
      if (c >= 0) {
        luu.emplace_back(r, c, it.value());
      } else {
        rhs.row(r) -= it.value() * values.row(it.col());
        touches_known(r) = 1.0;
      }
    }
  }
  // A tiny diagonal keeps components with no known vertex solvable (they
  // come out ~0 and are restored below).
  for (Eigen::Index i = 0; i < nu; ++i) luu.emplace_back(i, i, 1e-9);
  Eigen::SparseMatrix<double> a(nu, nu);
  a.setFromTriplets(luu.begin(), luu.end());
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(a);
  if (solver.info() != Eigen::Success) {
    return makeError(ErrorCode::kInvalidMesh, "inpainting: the target Laplacian could not be factorised");
  }
  const Eigen::MatrixXd x = solver.solve(rhs);
  // Components that touch no known vertex: find them by propagating from the
  // unknowns adjacent to known ones.
  std::vector<char> reached(static_cast<std::size_t>(nu), 0);
  std::vector<int> stack;
  for (Eigen::Index i = 0; i < nu; ++i) if (touches_known(i) > 0) { reached[static_cast<std::size_t>(i)] = 1; stack.push_back(static_cast<int>(i)); }
  while (!stack.empty()) {
    const int r = stack.back();
    stack.pop_back();
    const int v = unknown[static_cast<std::size_t>(r)];
    for (Eigen::SparseMatrix<double>::InnerIterator it(laplacian, v); it; ++it) {
      const int c = slot[static_cast<std::size_t>(it.row())];
      if (c >= 0 && !reached[static_cast<std::size_t>(c)]) {
        reached[static_cast<std::size_t>(c)] = 1;
        stack.push_back(c);
      }
    }
  }
  for (Eigen::Index i = 0; i < nu; ++i) {
    if (reached[static_cast<std::size_t>(i)]) out.row(unknown[static_cast<std::size_t>(i)]) = x.row(i);
  }
  return out;
}

}  // namespace core
