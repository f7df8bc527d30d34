// Tests the warp's refinement (core/correspond/dense_refinement.cpp and the
// sliding of core/correspond/correspondence.cpp), each stage against the warp
// with it switched off: target pulls, the smoothed and the partial guide,
// sliding centres, and landmarks a sparse target does not name.
#include "core/correspond/correspondence.h"

#include <cmath>
#include <cstdio>
#include <limits>
#include <numeric>
#include <random>
#include <set>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "core/synthetic/synthetic_head.h"
#include "core/correspond/warp_job.h"
#include "tests/core/correspond/warp_comparison.h"
#include "tests/test_support.h"

namespace {

using namespace rigport_test::correspond;

// The generated head bent by a smooth space warp (same topology), and the 10
// landmarks a sparse target would name (eye and mouth corners, nose tip and
// wings, chin); `others` gets the indices of the rest.
core::SyntheticHead bentHead(const core::SyntheticHead& source) {
  const double h = source.mesh.positions.col(1).maxCoeff() - source.mesh.positions.col(1).minCoeff();
  core::SyntheticHead target = source;
  for (Eigen::Index v = 0; v < target.mesh.positions.rows(); ++v) {
    const double y = target.mesh.positions(v, 1) / h, x = target.mesh.positions(v, 0) / h;
    target.mesh.positions(v, 2) *= 1.0 + 0.4 * y * y;
    target.mesh.positions(v, 1) += 0.06 * h * std::sin(5.0 * x);
  }
  target.mesh.normals = core::computeVertexNormals(target.mesh.positions, target.mesh.triangles);
  return target;
}

core::LandmarkSet sparseLandmarks(const core::LandmarkSet& all, std::vector<Eigen::Index>* others = nullptr) {
  const std::set<std::string> named = {"eye_right_0", "eye_right_3", "eye_left_0", "eye_left_3", "nose_bridge_3",
                                       "nose_base_0", "nose_base_4", "mouth_outer_0", "mouth_outer_6", "jaw_08"};
  core::LandmarkSet sparse;
  for (std::size_t l = 0; l < all.landmarks.size(); ++l) {
    if (named.count(all.landmarks[l].name)) {
      sparse.landmarks.push_back(all.landmarks[l]);
    } else if (others) {
      others->push_back(static_cast<Eigen::Index>(l));
    }
  }
  return sparse;
}

// The generated head with its lips pushed out along the normals by a
// Gaussian bump (amplitude and width relative to the head height) well beyond
// what the landmarks say, as on an exaggerated identity. Same topology:
// target vertex v is source vertex v; `lips` gets the vertices within two
// widths of the mouth's centre.
core::SyntheticHead fullerLips(const core::SyntheticHead& source, double amplitude, double width,
                               std::vector<Eigen::Index>& lips) {
  const double h = source.mesh.positions.col(1).maxCoeff() - source.mesh.positions.col(1).minCoeff();
  auto landmarks = core::resolveLandmarks(source.landmarks, source.mesh, "source");
  EXPECT_TRUE(landmarks);
  const Eigen::RowVector3d mouth = 0.5 * (landmarks->row(source.landmarks.indexOf("mouth_outer_3")) +
                                          landmarks->row(source.landmarks.indexOf("mouth_outer_9")));
  core::SyntheticHead target = source;
  const double sigma = width * h;
  for (Eigen::Index v = 0; v < source.mesh.vertexCount(); ++v) {
    const double r2 = (source.mesh.positions.row(v) - mouth).squaredNorm() / (sigma * sigma);
    if (r2 > 9.0) continue;
    target.mesh.positions.row(v) += amplitude * h * std::exp(-0.5 * r2) * source.mesh.normals.row(v);
    if (r2 < 4.0) lips.push_back(v);
  }
  target.mesh.normals = core::computeVertexNormals(target.mesh.positions, target.mesh.triangles);
  return target;
}

// Projection from the warped source lands on the front of the fuller lips
// and never reaches the parts of the target it does not already cover; the
// target's own vertices pulling the surface do.
TEST(Correspondence, TargetPullsReachWhatProjectionDoesNot) {
  const auto source = core::generateHead();
  std::vector<Eigen::Index> lips;
  const core::SyntheticHead target = fullerLips(source, 0.06, 0.05, lips);
  auto [off, on] = warpOffAndOn(&core::WarpOptions::target_pulls, source, target.mesh, target.landmarks);
  ASSERT_TRUE(off && on);
  EXPECT_EQ(off->report.target_pulls, 0);
  // About a quarter of the vertices are sampled; nearly all of them match.
  EXPECT_GT(on->report.target_pulls, target.mesh.vertexCount() / 6);
  const double h = source.mesh.positions.col(1).maxCoeff() - source.mesh.positions.col(1).minCoeff();
  const double error_off = meanDistanceFromTrueSource(*off, source.mesh, lips, h);
  const double error_on = meanDistanceFromTrueSource(*on, source.mesh, lips, h);
  std::printf("[ fuller lips ] %zu vertices, mean distance from their true source point %.5f -> %.5f (head height "
              "%.3f, %d target pulls)\n", lips.size(), error_off, error_on, h, on->report.target_pulls);
  EXPECT_LT(error_on, 0.9 * error_off);
}

// Where projection crowds the guide's vertices (around much fuller lips,
// matched with 10 landmarks), its triangles fold and locations on them
// scatter; on the smoothed guide the lips land closer to their true points.
TEST(Correspondence, SmoothedGuideLocatesCloserThanTheGuide) {
  const auto source = core::generateHead();
  std::vector<Eigen::Index> lips;
  const core::SyntheticHead target = fullerLips(source, 0.10, 0.03, lips);
  auto [off, on] =
      warpOffAndOn(&core::WarpOptions::smooth_guide, source, target.mesh, sparseLandmarks(target.landmarks));
  ASSERT_TRUE(off && on);
  EXPECT_TRUE(off->guide.positions == on->guide.positions);  // the guide itself is the same
  const double h = source.mesh.positions.col(1).maxCoeff() - source.mesh.positions.col(1).minCoeff();
  const double error_off = meanDistanceFromTrueSource(*off, source.mesh, lips, h);
  const double error_on = meanDistanceFromTrueSource(*on, source.mesh, lips, h);
  std::printf("[ much fuller lips, 10 landmarks ] %zu vertices located on the guide / the smoothed guide: mean "
              "distance from their true source point %.5f -> %.5f\n", lips.size(), error_off, error_on);
  EXPECT_LT(error_on, 0.95 * error_off);
}

// A transfer projects only the guide vertices it reads (the projection
// sample and the dense centres' vertices); where the target is located, the
// dense map and the vertices projected are exactly those of the full guide.
TEST(Correspondence, APartialGuideLocatesExactlyAsTheFullOne) {
  const auto source = core::generateHead();
  std::vector<Eigen::Index> lips;
  const core::SyntheticHead target = fullerLips(source, 0.06, 0.05, lips);
  auto [partial, full] = warpOffAndOn(&core::WarpOptions::full_guide, source, target.mesh, target.landmarks);
  ASSERT_TRUE(partial && full);
  const Eigen::Index nv = source.mesh.vertexCount();
  EXPECT_EQ(full->report.projected_source_vertices, nv);
  EXPECT_GT(partial->report.projected_source_vertices, 0);
  EXPECT_LT(partial->report.projected_source_vertices, nv / 2);
  int projected = 0;
  for (Eigen::Index v = 0; v < nv; ++v) {
    if (partial->guide.on_target[static_cast<std::size_t>(v)].found()) {
      ++projected;
      EXPECT_EQ(partial->guide.positions.row(v), full->guide.positions.row(v)) << "source vertex " << v;
    } else {
      EXPECT_EQ(partial->guide.positions.row(v), partial->warped_positions.row(v)) << "source vertex " << v;
    }
  }
  EXPECT_EQ(projected + partial->report.unmatched_source_vertices, partial->report.projected_source_vertices);
  ASSERT_TRUE(partial->dense_map && full->dense_map);
  EXPECT_EQ(partial->dense_map->apply(source.mesh.positions), full->dense_map->apply(source.mesh.positions));
  const core::TargetLocations& a = partial->locations;
  const core::TargetLocations& b = full->locations;
  for (Eigen::Index v = 0; v < target.mesh.vertexCount(); ++v) {
    const auto i = static_cast<std::size_t>(v);
    ASSERT_EQ(a.on_source[i].face, b.on_source[i].face) << "target vertex " << v;
    EXPECT_EQ(a.on_source[i].barycentric, b.on_source[i].barycentric) << "target vertex " << v;
  }
  EXPECT_EQ(a.confidence, b.confidence);
  EXPECT_EQ(a.mismatched, b.mismatched);
  EXPECT_EQ(partial->report.flipped_triangles, full->report.flipped_triangles);

  // Located on the guide itself (no smoothed guide), every vertex is projected.
  auto prepared = core::prepareSource(source.mesh, source.landmarks, "source");
  ASSERT_TRUE(prepared);
  core::WarpOptions light = core::lightWarpOptions();
  light.full_guide = false;
  auto on_guide = core::runWarp(*prepared, target.mesh, target.landmarks, "light", light);
  ASSERT_TRUE(on_guide);
  EXPECT_EQ(on_guide->report.projected_source_vertices, nv);
}

// Points displaced within their own tangent planes off an affine image slide
// back onto it: the affine map is the only one of zero bending energy that
// the fixed points allow.
TEST(Correspondence, SlidingInTangentPlanesRestoresAnAffineMap) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Eigen::MatrixX3d centres(40, 3);
  for (Eigen::Index i = 0; i < 40; ++i) centres.row(i) << u(rng), u(rng), u(rng);
  Eigen::Matrix3d a;
  a << 1.2, 0.1, -0.3, 0.0, 0.8, 0.2, 0.1, -0.1, 1.1;
  const Eigen::MatrixX3d affine = (centres * a.transpose()).rowwise() + Eigen::RowVector3d(0.5, -1.0, 2.0);
  auto factorization = core::TpsFactorization::create(centres);
  ASSERT_TRUE(factorization);
  const Eigen::MatrixXd bending = factorization->bendingEnergyMatrix();
  std::vector<int> sliding;
  Eigen::MatrixX3d normals(25, 3);
  Eigen::MatrixX3d displaced = affine;
  for (int i = 0; i < 25; ++i) {
    const int row = 15 + i;
    sliding.push_back(row);
    const Eigen::Vector3d n = Eigen::Vector3d(u(rng), u(rng), u(rng)).normalized();
    normals.row(i) = 3.0 * n.transpose();  // any length
    const Eigen::Vector3d in_plane = n.unitOrthogonal() * u(rng) + n.cross(n.unitOrthogonal()) * u(rng);
    displaced.row(row) += 0.2 * in_plane.transpose();
  }
  const double before = (displaced.transpose() * bending * displaced).trace();
  const Eigen::MatrixX3d slid = core::slideInTangentPlanes(bending, displaced, sliding, normals, 200);
  EXPECT_GT(before, 1e-3);
  EXPECT_LT((slid.transpose() * bending * slid).trace(), 1e-12 * before + 1e-14);
  EXPECT_TRUE(rigport_test::matricesNear(slid, affine, 1e-6));
  // Fixed rows did not move; sliding rows moved within their planes.
  EXPECT_TRUE(slid.topRows(15).isApprox(displaced.topRows(15)));
  for (int i = 0; i < 25; ++i) {
    EXPECT_NEAR((slid.row(15 + i) - displaced.row(15 + i)).dot(normals.row(i).normalized()), 0.0, 1e-12);
  }
  // A point without a plane (zero or NaN normal) stays; the others still slide.
  normals.row(0).setZero();
  normals.row(1).setConstant(std::numeric_limits<double>::quiet_NaN());
  const Eigen::MatrixX3d planeless = core::slideInTangentPlanes(bending, displaced, sliding, normals, 200);
  ASSERT_TRUE(planeless.allFinite());
  EXPECT_EQ(planeless.row(15), displaced.row(15));
  EXPECT_EQ(planeless.row(16), displaced.row(16));
  EXPECT_LT((planeless.transpose() * bending * planeless).trace(), 0.5 * before);
}

// Matched with 10 landmarks, as a sparse target would be: sliding the dense
// centres locates the bent head closer to the truth than projection alone.
TEST(Correspondence, SlidingCentresLocateASparselyLandmarkedTargetCloser) {
  const auto source = core::generateHead();
  const core::SyntheticHead target = bentHead(source);
  const core::LandmarkSet sparse = sparseLandmarks(target.landmarks);
  ASSERT_EQ(sparse.landmarks.size(), 10u);
  auto prepared = core::prepareSource(source.mesh, source.landmarks, "source");
  ASSERT_TRUE(prepared);
  core::WarpOptions projected_only;
  projected_only.slide_centres = false;
  auto off = core::runWarp(*prepared, target.mesh, sparse, "bent", projected_only);
  auto on = core::runWarp(*prepared, target.mesh, sparse, "bent");
  ASSERT_TRUE(off && on);
  EXPECT_EQ(off->report.slid_centres, 0);
  EXPECT_GT(on->report.slid_centres, 200);
  EXPECT_GT(on->report.mean_slide, 0.0);
  std::vector<Eigen::Index> every(static_cast<std::size_t>(target.mesh.vertexCount()));
  std::iota(every.begin(), every.end(), Eigen::Index{0});
  const double h = source.mesh.positions.col(1).maxCoeff() - source.mesh.positions.col(1).minCoeff();
  const double error_off = meanDistanceFromTrueSource(*off, source.mesh, every, h);
  const double error_on = meanDistanceFromTrueSource(*on, source.mesh, every, h);
  std::printf("[ bent head, 10 landmarks ] mean distance from the true source point %.5f -> %.5f (head height %.3f), "
              "%d centres slid %.5f on average\n", error_off, error_on, h, on->report.slid_centres, on->report.mean_slide);
  EXPECT_LT(error_on, 0.95 * error_off);
}

// The source landmarks a sparse target does not name are refined like the
// dense samples instead of staying where the landmark warp put them: the
// final dense map carries them closer to their true places on the target.
TEST(Correspondence, LandmarksTheTargetDoesNotNameFollowTheRefinement) {
  const auto source = core::generateHead();
  const core::SyntheticHead target = bentHead(source);
  auto truth = core::resolveLandmarks(target.landmarks, target.mesh, "bent");  // same topology: the true places
  ASSERT_TRUE(truth);
  std::vector<Eigen::Index> unnamed;
  const core::LandmarkSet sparse = sparseLandmarks(target.landmarks, &unnamed);
  auto prepared = core::prepareSource(source.mesh, source.landmarks, "source");
  ASSERT_TRUE(prepared);
  auto r = core::runWarp(*prepared, target.mesh, sparse, "bent");
  ASSERT_TRUE(r) << r.error().message;
  ASSERT_TRUE(r->dense_map);
  const Eigen::MatrixX3d by_warp = r->landmark_warp.apply(prepared->landmark_positions);
  const Eigen::MatrixX3d by_map = r->dense_map->apply(prepared->landmark_positions);
  const core::ClosestPointIndex surface(target.mesh.positions, target.mesh.triangles);
  double warp_error = 0.0, map_error = 0.0, warp_off = 0.0, map_off = 0.0;
  for (Eigen::Index l : unnamed) {
    warp_error += (by_warp.row(l) - truth->row(l)).norm();
    map_error += (by_map.row(l) - truth->row(l)).norm();
    warp_off += std::sqrt(surface.closestPoint(by_warp.row(l).transpose()).sq_distance);
    map_off += std::sqrt(surface.closestPoint(by_map.row(l).transpose()).sq_distance);
  }
  const double n = static_cast<double>(unnamed.size());
  std::printf("[ bent head, %zu of 68 landmarks ] the other landmarks from their true places: %.5f by the landmark "
              "warp, %.5f by the refined dense map; off the target surface %.5f and %.5f\n",
              sparse.landmarks.size(), warp_error / n, map_error / n, warp_off / n, map_off / n);
  EXPECT_LT(map_error, 0.95 * warp_error);
  EXPECT_LT(map_off, 0.5 * warp_off);
}

}  // namespace
