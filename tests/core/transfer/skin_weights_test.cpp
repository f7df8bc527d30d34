#include <vector>

#include <gtest/gtest.h>

#include "core/solve/inpainting.h"
#include "core/synthetic/synthetic_head.h"
#include "tests/test_support.h"

namespace {

// Real assets split vertices along UV seams (same position, separate
// indices). The harmonic inpainting of skin weights and shapes must see one
// surface: both copies of a seam vertex get one value, the value the unsplit
// mesh gives, or the seam opens when the character moves.
TEST(Inpainting, VerticesSplitAtASeamGetTheUnsplitSolution) {
  const core::Mesh mesh = core::generateHead(core::HeadShape{}, core::HeadResolution{.columns = 40, .rows = 36}).mesh;
  const Eigen::Index nv = mesh.vertexCount();
  // Split every vertex shared by faces on both sides of x = 0 (through the
  // nose and the lips): faces on the +x side take a copy.
  auto plus_side = [&](Eigen::Index f) {
    return mesh.positions(mesh.triangles(f, 0), 0) + mesh.positions(mesh.triangles(f, 1), 0) +
               mesh.positions(mesh.triangles(f, 2), 0) > 0.0;
  };
  std::vector<int> sides(static_cast<std::size_t>(nv), 0);
  for (Eigen::Index f = 0; f < mesh.triangleCount(); ++f) {
    for (int k = 0; k < 3; ++k) sides[static_cast<std::size_t>(mesh.triangles(f, k))] |= plus_side(f) ? 2 : 1;
  }
  std::vector<int> original;  // original vertex of each split vertex
  for (Eigen::Index v = 0; v < nv; ++v) original.push_back(static_cast<int>(v));
  core::Mesh split = mesh;
  std::vector<int> copy(static_cast<std::size_t>(nv), -1);
  for (Eigen::Index v = 0; v < nv; ++v) {
    if (sides[static_cast<std::size_t>(v)] == 3) copy[static_cast<std::size_t>(v)] = static_cast<int>(original.size());
    if (sides[static_cast<std::size_t>(v)] == 3) original.push_back(static_cast<int>(v));
  }
  const auto ns = static_cast<Eigen::Index>(original.size());
  ASSERT_GT(ns - nv, 10);
  split.positions.resize(ns, 3);
  for (Eigen::Index v = 0; v < ns; ++v) split.positions.row(v) = mesh.positions.row(original[static_cast<std::size_t>(v)]);
  for (Eigen::Index f = 0; f < mesh.triangleCount(); ++f) {
    if (!plus_side(f)) continue;
    for (int k = 0; k < 3; ++k) {
      const int c = copy[static_cast<std::size_t>(mesh.triangles(f, k))];
      if (c >= 0) split.triangles(f, k) = c;
    }
  }
  // Unknown: a patch around the mouth, across the seam; known values: the
  // positions themselves (any smooth field will do).
  const Eigen::RowVector3d centre = mesh.positions.colwise().mean() +
                                    Eigen::RowVector3d(0.0, -0.3, 1.0) * core::boundingBoxDiagonal(mesh.positions) * 0.3;
  const double radius = 0.25 * core::boundingBoxDiagonal(mesh.positions);
  auto knownOf = [&](const Eigen::MatrixX3d& p) {
    std::vector<char> known(static_cast<std::size_t>(p.rows()));
    for (Eigen::Index v = 0; v < p.rows(); ++v) known[static_cast<std::size_t>(v)] = (p.row(v) - centre).norm() > radius;
    return known;
  };
  const std::vector<char> known = knownOf(mesh.positions), known_split = knownOf(split.positions);
  int unknown_on_seam = 0;
  for (Eigen::Index v = nv; v < ns; ++v) unknown_on_seam += known_split[static_cast<std::size_t>(v)] ? 0 : 1;
  ASSERT_GT(unknown_on_seam, 3);

  auto whole = core::inpaintHarmonic(core::uniformLaplacian(mesh.positions, mesh.triangles), known, mesh.positions);
  auto parts = core::inpaintHarmonic(core::uniformLaplacian(split.positions, split.triangles), known_split,
                                     split.positions);
  ASSERT_TRUE(whole && parts);
  for (Eigen::Index v = 0; v < ns; ++v) {
    const Eigen::RowVector3d expected = whole->row(original[static_cast<std::size_t>(v)]);
    ASSERT_LT((parts->row(v) - expected).norm(), 1e-9) << "vertex " << v << " (copy of " << original[static_cast<std::size_t>(v)] << ")";
  }
}

}  // namespace
