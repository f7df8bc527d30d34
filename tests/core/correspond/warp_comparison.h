// Helpers the warp stage tests share (tests/core/correspond/dense_refinement_test.cpp,
// warp_rims_test.cpp): a warp run with one of its switches off and with the
// defaults, and how far the located target vertices are from their true
// source points.
#pragma once

#include <vector>

#include "core/correspond/warp_job.h"
#include "core/synthetic/synthetic_head.h"

namespace rigport_test::correspond {

// Same topology: target vertex v's true source point is source vertex v.
// The mean distance of the located points of `vertices` from theirs; a
// vertex located nowhere counts `miss`.
inline double meanDistanceFromTrueSource(const core::WarpResult& r, const core::Mesh& source,
                                         const std::vector<Eigen::Index>& vertices, double miss) {
  double sum = 0.0;
  for (Eigen::Index v : vertices) {
    const core::SurfacePoint& at = r.locations.on_source[static_cast<std::size_t>(v)];
    if (!at.found()) {
      sum += miss;
      continue;
    }
    Eigen::RowVector3d p = Eigen::RowVector3d::Zero();
    for (int c = 0; c < 3; ++c) p += at.barycentric(c) * source.positions.row(source.triangles(at.face, c));
    sum += (p - source.positions.row(v)).norm();
  }
  return sum / static_cast<double>(vertices.size());
}

// The target warped with a WarpOptions switch off, and with the defaults (on).
struct OffAndOn {
  core::Result<core::WarpResult> off, on;
};
inline OffAndOn warpOffAndOn(bool core::WarpOptions::*member, const core::SyntheticHead& source,
                             const core::Mesh& target, const core::LandmarkSet& landmarks) {
  auto prepared = core::prepareSource(source.mesh, source.landmarks, "source");
  if (!prepared) return {prepared.error(), prepared.error()};
  core::WarpOptions off;
  off.*member = false;
  return {core::runWarp(*prepared, target, landmarks, "off", off), core::runWarp(*prepared, target, landmarks, "on")};
}

}  // namespace rigport_test::correspond
