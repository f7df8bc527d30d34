#include "core/solve/inpainting.h"

#include <Eigen/SparseCholesky>
#include <algorithm>
#include <vector>

#include "core/geometry/mesh.h"

namespace core {

Eigen::SparseMatrix<double> uniformLaplacian(const Eigen::MatrixX3d& positions, const Eigen::MatrixX3i& triangles) {
  // Vertices split at one position (UV seams, hard edges) are one point of
  // the surface. Without joining them, the two sides of a seam were solved
  // apart and could part when the mesh moves.
  return uniformLaplacian(triangles, positions.rows(), coincidentVertexRepresentatives(positions));
}

Eigen::SparseMatrix<double> uniformLaplacian(const Eigen::MatrixX3i& triangles, Eigen::Index vertex_count,
                                             const std::vector<int>& representative) {
  // Faces use the lowest-indexed copy, and every other copy hangs on it by a
  // single edge, so an unknown copy takes its value and a known one joins its
  // neighbourhood.
  auto corner = [&](Eigen::Index f, int k) {
    const int v = triangles(f, k);
    return representative.empty() ? v : representative[static_cast<std::size_t>(v)];
  };
  // Unique undirected edges first (an interior edge appears in two faces):
  // bucketed by their lower vertex, each short bucket sorted on its own (a
  // global sort of all half-edges cost more than the rest of the function).
  std::vector<int> offsets(static_cast<std::size_t>(vertex_count) + 1, 0);
  auto forEachEdge = [&](auto&& fn) {
    for (Eigen::Index f = 0; f < triangles.rows(); ++f) {
      for (int k = 0; k < 3; ++k) {
        const int a = corner(f, k), b = corner(f, (k + 1) % 3);
        if (a != b) fn(std::min(a, b), std::max(a, b));
      }
    }
    for (std::size_t v = 0; v < representative.size(); ++v) {
      if (representative[v] != static_cast<int>(v)) fn(representative[v], static_cast<int>(v));
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

struct HarmonicInpainting::Solver {
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt;
};

Result<HarmonicInpainting> HarmonicInpainting::create(const Eigen::SparseMatrix<double>& laplacian,
                                                      const std::vector<char>& known) {
  const auto n = static_cast<Eigen::Index>(known.size());
  HarmonicInpainting h;
  std::vector<int> slot(known.size(), -1), boundary_slot(known.size(), -1);
  for (Eigen::Index v = 0; v < n; ++v) {
    if (!known[static_cast<std::size_t>(v)]) {
      slot[static_cast<std::size_t>(v)] = static_cast<int>(h.unknown_.size());
      h.unknown_.push_back(static_cast<int>(v));
    }
  }
  const auto nu = static_cast<Eigen::Index>(h.unknown_.size());
  std::vector<Eigen::Triplet<double>> luu;
  std::vector<char> touches_known(h.unknown_.size(), 0);
  for (int k = 0; k < laplacian.outerSize(); ++k) {
    for (Eigen::SparseMatrix<double>::InnerIterator it(laplacian, k); it; ++it) {
      const int r = slot[static_cast<std::size_t>(it.row())];
      if (r < 0) continue;
      const int c = slot[static_cast<std::size_t>(it.col())];
      if (c >= 0) {
        luu.emplace_back(r, c, it.value());
        continue;
      }
      int& b = boundary_slot[static_cast<std::size_t>(it.col())];
      if (b < 0) {
        b = static_cast<int>(h.boundary_.size());
        h.boundary_.push_back(static_cast<int>(it.col()));
      }
      h.couplings_.push_back({r, b, -it.value()});
      touches_known[static_cast<std::size_t>(r)] = 1;
    }
  }
  // Boundary in ascending vertex order (it was collected in column order).
  {
    std::vector<int> order(h.boundary_.size());
    for (std::size_t i = 0; i < order.size(); ++i) order[i] = static_cast<int>(i);
    std::sort(order.begin(), order.end(), [&](int a, int b) { return h.boundary_[static_cast<std::size_t>(a)] < h.boundary_[static_cast<std::size_t>(b)]; });
    std::vector<int> rank(order.size());
    std::vector<int> sorted(order.size());
    for (std::size_t i = 0; i < order.size(); ++i) {
      rank[static_cast<std::size_t>(order[i])] = static_cast<int>(i);
      sorted[i] = h.boundary_[static_cast<std::size_t>(order[i])];
    }
    h.boundary_.swap(sorted);
    for (Coupling& c : h.couplings_) c.boundary_index = rank[static_cast<std::size_t>(c.boundary_index)];
  }
  // A tiny diagonal keeps components with no known vertex solvable (they
  // come out ~0 and are reported as not reached).
  for (Eigen::Index i = 0; i < nu; ++i) luu.emplace_back(i, i, 1e-9);
  Eigen::SparseMatrix<double> a(nu, nu);
  a.setFromTriplets(luu.begin(), luu.end());
  auto solver = std::make_shared<Solver>();
  solver->ldlt.compute(a);
  if (solver->ldlt.info() != Eigen::Success) {
    return makeError(ErrorCode::kInvalidMesh, "inpainting: the target Laplacian could not be factorised");
  }
  h.solver_ = std::move(solver);
  // Components that touch no known vertex: find them by propagating from the
  // unknowns adjacent to known ones.
  h.reached_.assign(h.unknown_.size(), 0);
  std::vector<int> stack;
  for (std::size_t i = 0; i < touches_known.size(); ++i) {
    if (touches_known[i]) {
      h.reached_[i] = 1;
      stack.push_back(static_cast<int>(i));
    }
  }
  while (!stack.empty()) {
    const int v = h.unknown_[static_cast<std::size_t>(stack.back())];
    stack.pop_back();
    for (Eigen::SparseMatrix<double>::InnerIterator it(laplacian, v); it; ++it) {
      const int c = slot[static_cast<std::size_t>(it.row())];
      if (c >= 0 && !h.reached_[static_cast<std::size_t>(c)]) {
        h.reached_[static_cast<std::size_t>(c)] = 1;
        stack.push_back(c);
      }
    }
  }
  return h;
}

Eigen::MatrixXd HarmonicInpainting::solve(const Eigen::MatrixXd& boundary_values) const {
  Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(unknown_.size()), boundary_values.cols());
  for (const Coupling& c : couplings_) rhs.row(c.unknown_index) += c.weight * boundary_values.row(c.boundary_index);
  return solver_->ldlt.solve(rhs);
}

Eigen::MatrixXd HarmonicInpainting::apply(const Eigen::MatrixXd& values) const {
  Eigen::MatrixXd out = values;
  if (unknown_.empty()) return out;
  Eigen::MatrixXd boundary(static_cast<Eigen::Index>(boundary_.size()), values.cols());
  for (std::size_t i = 0; i < boundary_.size(); ++i) boundary.row(static_cast<Eigen::Index>(i)) = values.row(boundary_[i]);
  const Eigen::MatrixXd x = solve(boundary);
  for (std::size_t i = 0; i < unknown_.size(); ++i) {
    if (reached(i)) out.row(unknown_[i]) = x.row(static_cast<Eigen::Index>(i));
  }
  return out;
}

Result<Eigen::MatrixXd> inpaintHarmonic(const Eigen::SparseMatrix<double>& laplacian, const std::vector<char>& known,
                                        const Eigen::MatrixXd& values) {
  const std::size_t unknown = static_cast<std::size_t>(std::count(known.begin(), known.end(), 0));
  if (unknown == 0 || unknown == known.size()) return values;
  auto inpainting = HarmonicInpainting::create(laplacian, known);
  if (!inpainting) return inpainting.error();
  return inpainting->apply(values);
}

}  // namespace core
