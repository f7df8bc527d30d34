// Tests the warp's use of rims (core/correspond/rims.h in target_setup.cpp and
// dense_refinement.cpp), each against the warp with it switched off: matched
// rims and the neck cut joining the warp, rim vertices and slivers located on
// the guide's rims, and holes the source lacks left as they were.
#include "core/correspond/rims.h"

#include <cmath>
#include <cstdio>
#include <vector>

#include <gtest/gtest.h>

#include "core/synthetic/synthetic_head.h"
#include "core/correspond/warp_job.h"
#include "tests/core/correspond/warp_comparison.h"

namespace {

using namespace rigport_test::correspond;

// The synthetic head with its neck drawn out (everything below the chin
// stretched down): the face landmarks say nothing about it, and projection
// cannot pull the warped neck along the tube, so without rims the source's
// neck cut stops short of the target's and the rim region goes unmatched.
TEST(Correspondence, MatchedRimsPullTheNeckCutOntoTheTargets) {
  const auto source = core::generateHead();
  core::SyntheticHead target = core::generateHead(core::randomHeadShape(7, 0.1), core::HeadResolution{88, 70, true, 0.2, 7});
  const double chin = target.mesh.positions.col(1).minCoeff() * 0.55;
  for (Eigen::Index v = 0; v < target.mesh.positions.rows(); ++v) {
    const double y = target.mesh.positions(v, 1);
    if (y < chin) target.mesh.positions(v, 1) = chin + 1.6 * (y - chin);
  }
  target.mesh.normals = core::computeVertexNormals(target.mesh.positions, target.mesh.triangles);
  auto prepared = core::prepareSource(source.mesh, source.landmarks, "source");
  ASSERT_TRUE(prepared);
  ASSERT_FALSE(prepared->rims.empty());
  core::WarpOptions without;
  without.rim_matching = false;
  auto off = core::runWarp(*prepared, target.mesh, target.landmarks, "long_neck", without);
  auto on = core::runWarp(*prepared, target.mesh, target.landmarks, "long_neck");
  ASSERT_TRUE(off && on);
  EXPECT_EQ(off->report.matched_rims, 0);
  EXPECT_GE(on->report.matched_rims, 1);
  // Mean distance of the guide's outer-rim vertices (the source's longest
  // rim: neck cut and back opening) to the target's outer rim.
  const std::vector<core::Rim> target_rims =
      core::meshRims(target.mesh, core::coincidentVertexRepresentatives(target.mesh.positions));
  auto rimGap = [&](const core::WarpResult& r) {
    double sum = 0.0;
    for (int v : prepared->rims[0].vertices) {
      sum += std::sqrt(core::closestPointOnRim(r.guide.positions.row(v).transpose(),
                                               (prepared->rim_vertices.tangent.row(v) * r.landmark_warp.affine().topRows<3>()).transpose(),
                                               target_rims[0], target.mesh.positions)
                           .sq_distance);
    }
    return sum / static_cast<double>(prepared->rims[0].vertices.size());
  };
  const double gap_off = rimGap(*off), gap_on = rimGap(*on);
  std::printf("[ long neck ] outer rim gap %.4f -> %.4f (diagonal %.3f), low-confidence vertices %d -> %d\n", gap_off,
              gap_on, on->report.target_diagonal, off->report.low_confidence_vertices, on->report.low_confidence_vertices);
  EXPECT_LT(gap_on, 0.5 * gap_off);
  EXPECT_LT(on->report.low_confidence_vertices, off->report.low_confidence_vertices);
}

// A neck pushed far forward below the chin (as on a strongly exaggerated
// identity): the face's landmarks say nothing of it, so the landmark warp
// leaves the source's neck on the wrong side of the target's, where closest
// points hold it. The neck cut, matched and paired point for point, joins the
// warp and brings it over. Same topology: target vertex v is source vertex v.
TEST(Correspondence, NeckCutJoinsTheWarpWhenNoLandmarkPinsIt) {
  const auto source = core::generateHead();
  core::SyntheticHead target = source;
  const double bottom = source.mesh.positions.col(1).minCoeff(), chin = 0.55 * bottom;
  const double depth = source.mesh.positions.col(2).maxCoeff() - source.mesh.positions.col(2).minCoeff();
  std::vector<Eigen::Index> neck;  // sheared forward, by 3/4 of the head's depth at the cut
  for (Eigen::Index v = 0; v < target.mesh.positions.rows(); ++v) {
    const double below = chin - target.mesh.positions(v, 1);
    if (below <= 0.0) continue;
    target.mesh.positions(v, 2) += 0.75 * depth * below / (chin - bottom);
    neck.push_back(v);
  }
  target.mesh.normals = core::computeVertexNormals(target.mesh.positions, target.mesh.triangles);
  auto prepared = core::prepareSource(source.mesh, source.landmarks, "source");
  ASSERT_TRUE(prepared);
  core::WarpOptions landmarks_only;
  landmarks_only.rim_warp_points = 0;
  auto off = core::runWarp(*prepared, target.mesh, target.landmarks, "neck_forward", landmarks_only);
  auto on = core::runWarp(*prepared, target.mesh, target.landmarks, "neck_forward");
  ASSERT_TRUE(off && on);
  EXPECT_EQ(off->report.rims_in_warp, 0);
  EXPECT_EQ(on->report.rims_in_warp, 1);  // the outer rim; the mouth and eyes carry landmarks
  const double slide_off = meanDistanceFromTrueSource(*off, source.mesh, neck, depth);
  const double slide_on = meanDistanceFromTrueSource(*on, source.mesh, neck, depth);
  std::printf("[ neck forward ] %zu neck vertices, mean distance from their true source point %.4f -> %.4f "
              "(head depth %.3f)\n", neck.size(), slide_off, slide_on, depth);
  EXPECT_LT(slide_on, 0.5 * slide_off);
}

// A target whose eye holes end in a curled margin (as a lid's does): each
// eye-rim vertex stands a little off the surface and beyond the source's
// border, so its closest point on the guide falls inside the lid, short of
// the border it is. Located on the guide's rim instead, it lands next to its
// true point. Same topology: target vertex v is source vertex v.
// The generated head's eye rims (rims 1 and 2; rim 0 is the open back and
// neck) curled off like a lid margin: each rim vertex moved away from its
// hole along the surface by 0.3 of the rim's mean edge and lifted off the
// surface by as much. Returns the moved vertices.
std::vector<Eigen::Index> curlEyeRims(const core::SyntheticHead& source, const std::vector<core::Rim>& rims,
                                      core::SyntheticHead& target) {
  std::vector<Eigen::Index> moved;
  for (std::size_t r = 1; r < rims.size(); ++r) {
    const core::Rim& rim = rims[r];
    Eigen::RowVector3d centre = Eigen::RowVector3d::Zero();
    for (int v : rim.vertices) centre += source.mesh.positions.row(v);
    centre /= static_cast<double>(rim.vertices.size());
    const double step = 0.3 * rim.length / static_cast<double>(rim.vertices.size());
    for (int v : rim.vertices) {
      const Eigen::RowVector3d n = source.mesh.normals.row(v);
      Eigen::RowVector3d away = source.mesh.positions.row(v) - centre;
      away -= away.dot(n) * n;
      target.mesh.positions.row(v) += step * (away.normalized() + n);
      moved.push_back(v);
    }
  }
  return moved;
}

TEST(Correspondence, RimVerticesAreLocatedOnTheGuidesRims) {
  const auto source = core::generateHead();
  core::SyntheticHead target = source;
  const std::vector<core::Rim> rims =
      core::meshRims(source.mesh, core::coincidentVertexRepresentatives(source.mesh.positions));
  ASSERT_EQ(rims.size(), 3u);  // the open back and neck, two eye holes (the lips are closed)
  const std::vector<Eigen::Index> eye_rims = curlEyeRims(source, rims, target);
  target.mesh.normals = core::computeVertexNormals(target.mesh.positions, target.mesh.triangles);
  auto [off, on] = warpOffAndOn(&core::WarpOptions::rim_location, source, target.mesh, target.landmarks);
  ASSERT_TRUE(off && on);
  EXPECT_EQ(off->report.rim_located_vertices, 0);
  EXPECT_GT(on->report.rim_located_vertices, static_cast<int>(eye_rims.size()) / 2);
  const double h = source.mesh.positions.col(1).maxCoeff() - source.mesh.positions.col(1).minCoeff();
  const double error_off = meanDistanceFromTrueSource(*off, source.mesh, eye_rims, h);
  const double error_on = meanDistanceFromTrueSource(*on, source.mesh, eye_rims, h);
  std::printf("[ curled eye margins ] %zu eye-rim vertices, mean distance from their true source point %.5f -> "
              "%.5f (%d target vertices located on the guide's rims)\n", eye_rims.size(), error_off, error_on,
              on->report.rim_located_vertices);
  EXPECT_LT(error_on, 0.5 * error_off);
}

// A remesher can leave a vertex a few percent of an edge from a rim vertex
// (a sliver at the constrained border). It stands off the surface as the rim
// does and is located as a rim point: beside its rim vertex on the guide's
// rim, not on the curled margin.
TEST(Correspondence, VerticesAtARimAreLocatedAsRimPoints) {
  const auto source = core::generateHead();
  core::SyntheticHead target = source;
  const std::vector<core::Rim> rims =
      core::meshRims(source.mesh, core::coincidentVertexRepresentatives(source.mesh.positions));
  ASSERT_EQ(rims.size(), 3u);
  std::vector<char> on_rim(static_cast<std::size_t>(source.mesh.vertexCount()), 0);
  for (const core::Rim& rim : rims) {
    for (int v : rim.vertices) on_rim[static_cast<std::size_t>(v)] = 1;
  }
  std::vector<char> has_landmark(static_cast<std::size_t>(source.mesh.triangles.rows()), 0);
  for (const core::Landmark& l : source.landmarks.landmarks) has_landmark[static_cast<std::size_t>(l.face)] = 1;
  curlEyeRims(source, rims, target);
  // Every fourth eye-rim vertex gets a sliver: a new vertex 5% of the way
  // from it to the centroid of a face it has with two off-rim corners, moved
  // with it; the face is split in three.
  std::vector<Eigen::Index> slivers;
  std::vector<Eigen::RowVector3d> truth;  // the sliver's point on the source
  std::vector<Eigen::Vector3i> added;
  const Eigen::Index nv = source.mesh.vertexCount();
  std::vector<Eigen::RowVector3d> positions;
  std::vector<int> sliver_of;  // its rim vertex
  for (std::size_t r = 1; r < rims.size(); ++r) {
    for (std::size_t i = 0; i < rims[r].vertices.size(); i += 4) {
      const int v = rims[r].vertices[i];
      for (Eigen::Index f = 0; f < source.mesh.triangles.rows(); ++f) {
        const Eigen::Vector3i t = source.mesh.triangles.row(f).transpose();
        int k = 0;
        while (k < 3 && t(k) != v) ++k;
        if (k == 3 || has_landmark[static_cast<std::size_t>(f)] || on_rim[static_cast<std::size_t>(t((k + 1) % 3))] ||
            on_rim[static_cast<std::size_t>(t((k + 2) % 3))]) {
          continue;
        }
        auto sliver = [&](const Eigen::MatrixX3d& p) {
          const Eigen::RowVector3d centroid = (p.row(t(0)) + p.row(t(1)) + p.row(t(2))) / 3.0;
          return Eigen::RowVector3d(p.row(v) + 0.05 * (centroid - p.row(v)));
        };
        const auto w = static_cast<int>(nv + static_cast<Eigen::Index>(positions.size()));
        truth.push_back(sliver(source.mesh.positions));
        positions.push_back(sliver(source.mesh.positions) + target.mesh.positions.row(v) - source.mesh.positions.row(v));
        slivers.push_back(w);
        sliver_of.push_back(v);
        target.mesh.triangles.row(f) << t(0), t(1), w;
        added.push_back({t(1), t(2), w});
        added.push_back({t(2), t(0), w});
        has_landmark[static_cast<std::size_t>(f)] = 1;  // split once
        break;
      }
    }
  }
  ASSERT_GT(slivers.size(), 4u);
  target.mesh.positions.conservativeResize(nv + static_cast<Eigen::Index>(positions.size()), 3);
  target.mesh.regions.conservativeResize(target.mesh.positions.rows());
  for (std::size_t i = 0; i < positions.size(); ++i) {
    target.mesh.positions.row(nv + static_cast<Eigen::Index>(i)) = positions[i];
    target.mesh.regions(nv + static_cast<Eigen::Index>(i)) = source.mesh.regions(sliver_of[i]);
  }
  ASSERT_EQ(target.mesh.uvs.rows(), 0);
  const Eigen::Index nf = target.mesh.triangles.rows();
  target.mesh.triangles.conservativeResize(nf + static_cast<Eigen::Index>(added.size()), 3);
  for (std::size_t i = 0; i < added.size(); ++i) target.mesh.triangles.row(nf + static_cast<Eigen::Index>(i)) = added[i].transpose();
  target.mesh.normals = core::computeVertexNormals(target.mesh.positions, target.mesh.triangles);

  auto [off, on] = warpOffAndOn(&core::WarpOptions::rim_location, source, target.mesh, target.landmarks);
  ASSERT_TRUE(off && on) << (off ? on.error().message : off.error().message);
  auto error = [&](const core::WarpResult& r) {
    double sum = 0.0;
    for (std::size_t i = 0; i < slivers.size(); ++i) {
      const core::SurfacePoint& at = r.locations.on_source[static_cast<std::size_t>(slivers[i])];
      EXPECT_TRUE(at.found()) << "sliver " << slivers[i];
      if (at.found()) sum += (core::interpolateOnFace(source.mesh.positions, source.mesh.triangles, at.face, at.barycentric) - truth[i]).norm();
    }
    return sum / static_cast<double>(slivers.size());
  };
  const double error_off = error(*off), error_on = error(*on);
  std::printf("[ slivers at curled eye rims ] %zu slivers, mean distance from their true source point %.5f -> %.5f\n",
              slivers.size(), error_off, error_on);
  EXPECT_LT(error_on, 0.5 * error_off);
}

// A scan with holes of its own (here: 40 small ones on the back of the
// head) keeps their vertices where the surface location put them: no source
// rim is near them.
TEST(Correspondence, HolesTheSourceLacksKeepTheirSurfaceLocations) {
  const auto source = core::generateHead();
  core::SyntheticHead target = source;
  const Eigen::Index nf = source.mesh.triangles.rows();
  std::vector<char> keep(static_cast<std::size_t>(nf), 1);
  // Each hole one triangle, touching no rim and no other hole.
  std::vector<char> taken(static_cast<std::size_t>(source.mesh.vertexCount()), 0);
  for (const core::Rim& rim : core::meshRims(source.mesh, core::coincidentVertexRepresentatives(source.mesh.positions))) {
    for (int v : rim.vertices) taken[static_cast<std::size_t>(v)] = 1;
  }
  int holes = 0;
  for (Eigen::Index f = 0; f < nf && holes < 40; f += 37) {
    const Eigen::RowVector3i t = source.mesh.triangles.row(f);
    Eigen::RowVector3d centre = Eigen::RowVector3d::Zero();
    for (int c = 0; c < 3; ++c) centre += source.mesh.positions.row(t(c)) / 3.0;
    if (centre.z() > 0.0) continue;  // the side and back of the head (the face looks toward +z)
    if (taken[static_cast<std::size_t>(t(0))] || taken[static_cast<std::size_t>(t(1))] || taken[static_cast<std::size_t>(t(2))]) continue;
    for (int c = 0; c < 3; ++c) taken[static_cast<std::size_t>(t(c))] = 1;
    keep[static_cast<std::size_t>(f)] = 0;
    ++holes;
  }
  ASSERT_EQ(holes, 40);
  std::vector<int> new_index(static_cast<std::size_t>(nf), -1);
  Eigen::MatrixX3i kept(nf - holes, 3);
  for (Eigen::Index f = 0, k = 0; f < nf; ++f) {
    if (!keep[static_cast<std::size_t>(f)]) continue;
    new_index[static_cast<std::size_t>(f)] = static_cast<int>(k);
    kept.row(k++) = source.mesh.triangles.row(f);
  }
  target.mesh.triangles = kept;
  for (core::Landmark& l : target.landmarks.landmarks) {
    l.face = new_index[static_cast<std::size_t>(l.face)];
    ASSERT_GE(l.face, 0) << l.name;
  }
  auto [off, on] = warpOffAndOn(&core::WarpOptions::rim_location, source, target.mesh, target.landmarks);
  ASSERT_TRUE(off && on);
  const std::vector<core::Rim> rims =
      core::meshRims(target.mesh, core::coincidentVertexRepresentatives(target.mesh.positions));
  ASSERT_EQ(rims.size(), 3u + 40u);
  int hole_vertices = 0, moved = 0;
  for (const core::Rim& rim : rims) {
    if (rim.vertices.size() != 3) continue;  // one removed triangle
    for (int v : rim.vertices) {
      ++hole_vertices;
      const core::SurfacePoint& a = off->locations.on_source[static_cast<std::size_t>(v)];
      const core::SurfacePoint& b = on->locations.on_source[static_cast<std::size_t>(v)];
      moved += a.face != b.face || a.barycentric != b.barycentric;
    }
  }
  EXPECT_EQ(hole_vertices, 120);
  EXPECT_EQ(moved, 0);
  EXPECT_GT(on->report.rim_located_vertices, 0);  // the eye holes' and the back's rims still are
}

}  // namespace
