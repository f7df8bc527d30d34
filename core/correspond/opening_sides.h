// The two sides of each opening of a face (upper and lower lip around the
// mouth, upper and lower lid around an eye), found from the mesh itself: an
// opening is an open boundary (core/correspond/rims.h) that a landmark lies on, split
// at its corners (the rim vertices nearest its two landmarks farthest apart,
// or its two vertices farthest apart) into two chains; the surface near it
// takes the side of the chain it is nearer along the surface, by more than
// a rim edge at a corner (nearer a corner neither side is sure). Matching
// and inpainting never cross from one side to the other: where the lips
// touch, a lower-lip vertex is a hair from the upper lip in space but a
// mouth's width away along the surface.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include "core/geometry/mesh.h"
#include "core/correspond/rims.h"

namespace core {

struct OpeningSideOptions {
  // A rim is an opening (mouth, eyes; not a neck cut) when a landmark lies within this fraction of the diagonal of it.
  double landmark_distance = 0.02;
  // Sides are given within this fraction of the opening's width of its rim; landmarks as near mark its corners.
  double zone = 0.5;
};

// Sides are bits of a 64-bit closest-point label mask, two per opening.
inline constexpr std::size_t kMaxOpenings = 32;

// An opening: a rim and the two vertices of it where its sides meet.
struct Opening {
  int rim = -1;                     // index into the mesh's rims
  std::array<int, 2> corners{};     // positions in rim.vertices: side 0 runs from corners[0] to corners[1] in loop order
  double width = 0.0;               // corner to corner, model units
};

// The openings of a mesh: rims a landmark lies on (`landmarks`: #L by 3
// positions on the mesh), split at the rim vertices nearest to the
// opening's two landmarks farthest apart (mouth corners, eye corners), or
// at its two vertices farthest apart when fewer than two landmarks lie
// within `zone` of its width of it; at most kMaxOpenings, longest rims first.
std::vector<Opening> findOpenings(const Mesh& mesh, const std::vector<Rim>& rims, const Eigen::MatrixX3d& landmarks,
                                  const OpeningSideOptions& options = {});

// The rim split at the vertices nearest to `corner_points` (2 by 3, in
// order: where another mesh's corners land on this one). rim -1 when both
// are nearest to one vertex.
Opening openingAtCorners(const Rim& rim, int rim_index, const Eigen::MatrixX3d& positions,
                         const Eigen::Matrix<double, 2, 3>& corner_points);

// Per vertex of `mesh`: 2 * k + s for side s (0, 1) of openings[k];
// kBetweenSides near an opening but on neither side (at a corner, where the
// sides meet); kOffOpenings elsewhere. Every copy of a split point
// (`representative` as for meshRims) takes its point's side.
inline constexpr int kOffOpenings = -1;
inline constexpr int kBetweenSides = -2;
// adjacency: vertexAdjacency of the mesh (its split points apart; the
// copies are joined here).
std::vector<int> openingSides(const Mesh& mesh, const VertexAdjacency& adjacency, const std::vector<int>& representative,
                              const std::vector<Rim>& rims, const std::vector<Opening>& openings,
                              const OpeningSideOptions& options = {});

// As label bits for the closest-point filters (ClosestPointFilters,
// ClosestPointIndex face labels): a vertex on a side allows only faces with
// that side's bit, a vertex on none every face; a face carries the sides of
// its corners, or every bit when none of them is on a side. Empty when no
// vertex is on a side.
std::vector<std::uint64_t> sideMasks(const std::vector<int>& sides);
std::vector<std::uint64_t> sideFaceSets(const std::vector<int>& sides, const Eigen::MatrixX3i& triangles);

// Removes from `laplacian` (#V by #V, e.g. uniformLaplacian) its edges
// between vertices on the two sides of an opening, each diagonal lowered by
// the weight it loses: a value inpainted on a lip comes from that lip, the
// corners and the skin beyond, never straight across the mouth (an open
// mouth has no such edge; a sealed or welded one does).
void cutAcrossSides(Eigen::SparseMatrix<double>& laplacian, const std::vector<int>& sides);

// True when sides a and b (openingSides values) are the two sides of one opening.
inline bool oppositeSides(int a, int b) { return a >= 0 && b >= 0 && a != b && a / 2 == b / 2; }

}  // namespace core
