#include "core/base/parallel.h"
#include "core/retarget/retarget.h"

#include <cmath>
#include <filesystem>

#include <gtest/gtest.h>

#include "core/solve/geodesic.h"
#include "core/io/mesh_io.h"
#include "core/io/rig_io.h"
#include "core/synthetic/synthetic_head.h"
#include "tests/test_support.h"

namespace {

using rigport_test::matricesNear;

// A head with an open mouth slit (half-height 0.04 rad of latitude, ~4 mm).
const core::SyntheticHead& head() {
  static const core::SyntheticHead h = [] {
    core::HeadShape shape;
    shape.mouth_open = 0.04;
    return core::generateHead(shape, core::HeadResolution{128, 112});
  }();
  return h;
}

// An AnimFace-like layout from the head's landmarks: brows, nose, eye lids,
// cheek-ish jaw points, the outer lip line (corners, 3 upper, 3 lower), chin.
core::LandmarkSet markerSet() {
  const char* names[] = {"brow_right_0", "brow_right_2", "brow_right_4", "brow_left_0", "brow_left_2", "brow_left_4",
                         "nose_bridge_0", "nose_bridge_3", "nose_base_0", "nose_base_4",
                         "eye_right_0", "eye_right_1", "eye_right_3", "eye_right_4",
                         "eye_left_0", "eye_left_2", "eye_left_3", "eye_left_5",
                         "jaw_04", "jaw_06", "jaw_08", "jaw_10", "jaw_12",
                         "mouth_outer_0", "mouth_outer_2", "mouth_outer_3", "mouth_outer_4",
                         "mouth_outer_6", "mouth_outer_8", "mouth_outer_9", "mouth_outer_10"};
  core::LandmarkSet set;
  for (const char* n : names) {
    const int i = head().landmarks.indexOf(n);
    EXPECT_GE(i, 0) << n;
    set.landmarks.push_back(head().landmarks.landmarks[static_cast<std::size_t>(i)]);
  }
  return set;
}

bool isMoving(const std::string& name) {
  return name == "mouth_outer_8" || name == "mouth_outer_9" || name == "mouth_outer_10" || name == "jaw_06" ||
         name == "jaw_08" || name == "jaw_10";
}

const Eigen::Vector3d kJawOpen(0.0, -0.008, -0.002);  // metres at the last frame

// Jaw-open clip in "mocap space": centimetres, rotated and shifted, so the
// calibration has scale, rotation and translation to undo.
const Eigen::Matrix3d kMocapRotation = Eigen::AngleAxisd(0.3, Eigen::Vector3d(0.2, 1.0, -0.1).normalized()).toRotationMatrix();

core::MarkerTrajectories jawOpenClip(const core::LandmarkSet& markers, int frames) {
  auto placed = core::resolveLandmarks(markers, head().mesh, "head");
  EXPECT_TRUE(placed);
  core::MarkerTrajectories clip;
  clip.data_rate = 30.0;
  clip.units = "cm";
  clip.units_to_metres = 0.01;
  clip.times = Eigen::VectorXd::LinSpaced(frames, 0.0, (frames - 1) / 30.0);
  clip.positions.resize(frames, 3 * static_cast<Eigen::Index>(markers.landmarks.size()));
  for (std::size_t i = 0; i < markers.landmarks.size(); ++i) {
    clip.marker_names.push_back(markers.landmarks[i].name);
    for (int f = 0; f < frames; ++f) {
      Eigen::Vector3d p = placed->row(static_cast<Eigen::Index>(i)).transpose();
      if (isMoving(markers.landmarks[i].name)) p += kJawOpen * (static_cast<double>(f) / (frames - 1));
      clip.positions.block(f, 3 * static_cast<Eigen::Index>(i), 1, 3) =
          (100.0 * kMocapRotation * p + Eigen::Vector3d(3.0, 70.0, -2.0)).transpose();
    }
  }
  return clip;
}

// Head motion is measured on markers that do not move with the jaw.
core::RetargetOptions jawOptions() {
  core::RetargetOptions o;
  o.head_markers = {"brow_right_0", "brow_right_4", "brow_left_0", "brow_left_4", "nose_bridge_0", "eye_right_0",
                    "eye_left_3"};
  return o;
}

const core::MarkerDistances& distancesFor(core::DistanceMethod method) {
  static std::map<core::DistanceMethod, core::MarkerDistances> cache;
  auto it = cache.find(method);
  if (it == cache.end()) {
    core::MarkerDistanceOptions o;
    o.method = method;
    auto d = core::computeMarkerDistances(head().mesh, markerSet(), "head", o);
    EXPECT_TRUE(d) << d.error().message;
    it = cache.emplace(method, std::move(*d)).first;
  }
  return it->second;
}

// #V by 3 displacement of the baked rig at frame f.
// Vertices just above the mouth slit near the midline (the upper lip's edge).
std::vector<int> upperLipVertices() {
  const core::Mesh& mesh = head().mesh;
  const auto loops = core::boundaryLoops(mesh);
  // The mouth loop: the one nearest the lip landmarks' centre.
  auto lips = core::resolveLandmarks(markerSet(), mesh, "head");
  Eigen::RowVector3d mouth = Eigen::RowVector3d::Zero();
  int n = 0;
  for (std::size_t i = 0; i < markerSet().landmarks.size(); ++i) {
    if (markerSet().landmarks[i].name.rfind("mouth_outer_", 0) == 0) mouth += lips->row(static_cast<Eigen::Index>(i)), ++n;
  }
  mouth /= n;
  std::size_t best = 0;
  double best_d = 1e9;
  for (std::size_t l = 0; l < loops.size(); ++l) {
    Eigen::RowVector3d c = Eigen::RowVector3d::Zero();
    for (int v : loops[l].vertices) c += mesh.positions.row(v);
    c /= static_cast<double>(loops[l].vertices.size());
    if ((c - mouth).norm() < best_d) best_d = (c - mouth).norm(), best = l;
  }
  double top = -1e9, front = -1e9;
  for (int v : loops[best].vertices) {
    if (std::abs(mesh.positions(v, 0)) < 0.01) top = std::max(top, mesh.positions(v, 1));
    front = std::max(front, mesh.positions(v, 2));
  }
  std::vector<int> out;
  for (Eigen::Index v = 0; v < mesh.vertexCount(); ++v) {
    const Eigen::RowVector3d p = mesh.positions.row(v);
    if (std::abs(p.x()) < 0.01 && p.y() >= top - 1e-9 && p.y() < top + 0.003 && p.z() > front - 0.02) out.push_back(static_cast<int>(v));
  }
  return out;
}

struct Decoupling {
  double upper_ratio = 0.0;  // mean |upper-lip vertex displacement| / |lower-lip marker displacement|
  double lower_ratio = 0.0;  // the same for lower-lip-edge vertices (should move: > 0.5)
};

Decoupling measureDecoupling(core::DistanceMethod method) {
  const core::LandmarkSet markers = markerSet();
  const int frames = 10;
  auto out = core::retargetMocap(head().mesh, distancesFor(method), jawOpenClip(markers, frames), jawOptions());
  EXPECT_TRUE(out) << out.error().message;
  const Eigen::MatrixX3d d = rigport_test::displacementAtKey(out->rig, frames - 1);
  const std::vector<int> upper = upperLipVertices();
  EXPECT_GE(upper.size(), 3u);
  double mean = 0.0;
  for (int v : upper) mean += d.row(v).norm();
  mean /= static_cast<double>(upper.size());
  // The lower lip's edge: the upper set mirrored below the slit.
  double lower = 0.0;
  int nl = 0;
  const Eigen::MatrixX3d& pos = head().mesh.positions;
  double top = 1e9;
  for (int v : upper) top = std::min(top, pos(v, 1));
  for (Eigen::Index v = 0; v < pos.rows(); ++v) {
    if (std::abs(pos(v, 0)) < 0.01 && pos(v, 1) < top - 0.006 && pos(v, 1) > top - 0.011 && pos(v, 2) > 0.05) {
      lower += d.row(v).norm();
      ++nl;
    }
  }
  return {mean / kJawOpen.norm(), nl > 0 ? lower / nl / kJawOpen.norm() : 0.0};
}

TEST(Retarget, GeodesicAndHybridKeepTheUpperLipStillWhenTheJawOpens) {
  const Decoupling euclidean = measureDecoupling(core::DistanceMethod::kEuclidean);
  const Decoupling geodesic = measureDecoupling(core::DistanceMethod::kGeodesic);
  const Decoupling hybrid = measureDecoupling(core::DistanceMethod::kHybrid);
  std::printf("upper-lip displacement / lower-lip marker displacement: euclidean %.3f, geodesic %.3f, hybrid %.3f\n",
              euclidean.upper_ratio, geodesic.upper_ratio, hybrid.upper_ratio);
  std::printf("lower-lip displacement / lower-lip marker displacement: euclidean %.3f, geodesic %.3f, hybrid %.3f\n",
              euclidean.lower_ratio, geodesic.lower_ratio, hybrid.lower_ratio);
  EXPECT_LT(geodesic.upper_ratio, 0.10);
  EXPECT_LT(hybrid.upper_ratio, 0.10);
  // Paper 002 fig. 5.2: the Euclidean distance drags the upper lip along.
  EXPECT_GT(euclidean.upper_ratio, 2.0 * geodesic.upper_ratio);
  EXPECT_GT(euclidean.upper_ratio, 2.0 * hybrid.upper_ratio);
  // The lower lip itself does follow.
  EXPECT_GT(geodesic.lower_ratio, 0.5);
  EXPECT_GT(hybrid.lower_ratio, 0.5);
}

TEST(Retarget, HybridRegionsAreTheMouthAndEyesNotTheRim) {
  const core::MarkerDistances& d = distancesFor(core::DistanceMethod::kHybrid);
  EXPECT_EQ(d.boundary_loops, 4);  // rim, two eyes, mouth
  ASSERT_EQ(d.regions.size(), 3u);
  for (const auto& r : d.regions) {
    EXPECT_GT(r.loop, 0);  // never the longest loop
    EXPECT_GT(r.centroid.z(), 0.0) << "loop " << r.loop;  // on the face side
    EXPECT_GT(r.region_vertices, r.loop_vertices);
  }
  ASSERT_EQ(d.geodesic_weight.size(), head().mesh.vertexCount());
  EXPECT_GE(d.geodesic_weight.minCoeff(), 0.0);
  EXPECT_LE(d.geodesic_weight.maxCoeff(), 1.0);
  const double inside = static_cast<double>((d.geodesic_weight.array() == 1.0).count()) / d.geodesic_weight.size();
  EXPECT_GT(inside, 0.02);
  EXPECT_LT(inside, 0.5);
  // The back of the head is Euclidean.
  for (Eigen::Index v = 0; v < head().mesh.vertexCount(); ++v) {
    if (head().mesh.positions(v, 2) < -0.05) {
      ASSERT_EQ(d.geodesic_weight(v), 0.0) << "vertex " << v;
    }
  }
}

TEST(Retarget, CalibrationUndoesMocapUnitsRotationAndOffset) {
  auto out = core::retargetMocap(head().mesh, distancesFor(core::DistanceMethod::kEuclidean), jawOpenClip(markerSet(), 5),
                                jawOptions());
  ASSERT_TRUE(out) << out.error().message;
  const auto& r = out->report;
  EXPECT_NEAR(r.similarity_scale, 0.01, 1e-9);
  EXPECT_LT(r.similarity_rms, 1e-9);
  EXPECT_NEAR(r.jacobian_min_singular, 1.0, 1e-6);
  EXPECT_NEAR(r.jacobian_max_singular, 1.0, 1e-6);
  EXPECT_NEAR(r.max_marker_displacement, kJawOpen.norm(), 1e-9);
  // Calibrated displacements of a moving marker are the jaw motion in mesh space.
  const int i = markerSet().indexOf("mouth_outer_9");
  EXPECT_TRUE(matricesNear(out->marker_displacements.block(4, 3 * i, 1, 3), kJawOpen.transpose(), 1e-9));
  EXPECT_LT(r.marker_max_residual, 1e-9);
}

// Head motion is found on the markers the expression leaves still, without
// being told which: the jaw clip with a nod and a turn added (mocap space)
// retargets as the plain jaw clip. Aligned on all markers, the fit turns the
// head with the jaw and leaves the still markers moving.
TEST(Retarget, HeadMotionIsMeasuredOnTheMarkersTheExpressionLeavesStill) {
  const int frames = 9;
  core::MarkerTrajectories clip = jawOpenClip(markerSet(), frames);
  const Eigen::Vector3d pivot = clip.positions.block(0, 0, 1, 3).transpose();
  for (int f = 1; f < frames; ++f) {
    const Eigen::Matrix3d turn = (Eigen::AngleAxisd(0.015 * f, Eigen::Vector3d::UnitX()) *
                                  Eigen::AngleAxisd(-0.01 * f, Eigen::Vector3d::UnitY())).toRotationMatrix();
    for (Eigen::Index i = 0; i < clip.positions.cols() / 3; ++i) {
      const Eigen::Vector3d p = clip.positions.block(f, 3 * i, 1, 3).transpose();
      clip.positions.block(f, 3 * i, 1, 3) = (turn * (p - pivot) + pivot + Eigen::Vector3d(0.2 * f, 0.0, 0.1)).transpose();
    }
  }
  const core::MarkerDistances& distances = distancesFor(core::DistanceMethod::kEuclidean);
  auto found = core::retargetMocap(head().mesh, distances, clip, core::RetargetOptions{});
  ASSERT_TRUE(found) << found.error().message;
  for (const std::string& name : found->report.head_markers) EXPECT_FALSE(isMoving(name)) << name;
  EXPECT_GT(found->report.head_max_rotation_deg, 5.0);
  core::RetargetOptions everything;
  for (const auto& lm : markerSet().landmarks) everything.head_markers.push_back(lm.name);
  auto all = core::retargetMocap(head().mesh, distances, clip, everything);
  ASSERT_TRUE(all) << all.error().message;
  // Calibrated displacements at the last frame: the jaw's, and nothing else.
  auto worstStill = [](const core::RetargetOutput& out) {
    double worst = 0.0;
    for (std::size_t i = 0; i < markerSet().landmarks.size(); ++i) {
      if (isMoving(markerSet().landmarks[i].name)) continue;
      worst = std::max(worst, out.marker_displacements.block(frames - 1, 3 * static_cast<Eigen::Index>(i), 1, 3).norm());
    }
    return worst;
  };
  const int moving = markerSet().indexOf("mouth_outer_9");
  EXPECT_TRUE(matricesNear(found->marker_displacements.block(frames - 1, 3 * moving, 1, 3), kJawOpen.transpose(), 1e-9));
  EXPECT_LT(worstStill(*found), 1e-9);
  EXPECT_GT(worstStill(*all), 0.05 * kJawOpen.norm());
}

core::RetargetOptions compressed(double tolerance, core::BakeError metric = core::BakeError::kRelativeFrobenius) {
  core::RetargetOptions o = jawOptions();
  o.bake.tolerance = tolerance;
  o.bake.metric = metric;
  o.bake.measure_max_error = true;
  return o;
}

// A richer clip: several independent motions so the rank is > 1.
core::MarkerTrajectories richClip(int frames) {
  const core::LandmarkSet markers = markerSet();
  core::MarkerTrajectories clip = jawOpenClip(markers, frames);
  for (std::size_t i = 0; i < markers.landmarks.size(); ++i) {
    for (int f = 0; f < frames; ++f) {
      const double t = static_cast<double>(f) / frames;
      const Eigen::Vector3d wobble(0.2 * std::sin(6.3 * t + static_cast<double>(i)), 0.15 * std::cos(3.1 * t * (i % 3 + 1)),
                                   0.1 * std::sin(9.0 * t * (i % 2 + 1)));
      clip.positions.block(f, 3 * static_cast<Eigen::Index>(i), 1, 3) += (f == 0 ? Eigen::Vector3d::Zero() : wobble).transpose();
    }
  }
  return clip;
}

TEST(Retarget, CompressedRankMeetsTheToleranceAgainstExactFrames) {
  const core::MarkerTrajectories clip = richClip(60);
  const core::MarkerDistances& d = distancesFor(core::DistanceMethod::kHybrid);
  core::RetargetOptions exact_options = jawOptions();
  exact_options.bake.exact = true;
  auto exact = core::retargetMocap(head().mesh, d, clip, exact_options);
  ASSERT_TRUE(exact) << exact.error().message;
  ASSERT_EQ(exact->rig.morph_targets.size(), 60u);
  double total = 0.0;
  for (const auto& t : exact->rig.morph_targets) total += t.position_deltas.squaredNorm();

  for (double tol : {0.1, 0.01, 0.001}) {
    auto out = core::retargetMocap(head().mesh, d, clip, compressed(tol));
    ASSERT_TRUE(out) << out.error().message;
    const auto& r = out->report;
    double err2 = 0.0, max_err = 0.0;
    for (int f = 0; f < 60; ++f) {
      const Eigen::MatrixX3d e = rigport_test::displacementAtKey(out->rig, f) - exact->rig.morph_targets[static_cast<std::size_t>(f)].position_deltas;
      err2 += e.squaredNorm();
      max_err = std::max(max_err, e.rowwise().norm().maxCoeff());
    }
    const double relative = std::sqrt(err2 / total);
    EXPECT_TRUE(r.tolerance_met);
    EXPECT_LE(relative, tol * (1 + 1e-6)) << "tolerance " << tol;
    EXPECT_NEAR(relative, r.relative_error, 1e-6 + 1e-3 * r.relative_error) << "tolerance " << tol;
    EXPECT_NEAR(max_err, r.max_error, 1e-6 * d.mesh_diagonal + 1e-3 * r.max_error) << "tolerance " << tol;
    EXPECT_NEAR(r.rms_error, std::sqrt(err2 / (60.0 * static_cast<double>(head().mesh.vertexCount()))), 1e-9);
    EXPECT_GE(r.rank, 1);
    EXPECT_LE(r.rank, 64);
    std::printf("tolerance %g: rank %d, relative %.3g, max %.3g m\n", tol, r.rank, r.relative_error, r.max_error);
  }
  // Max-vertex metric: the guaranteed bound holds, and the measured error is below it.
  auto mv = core::retargetMocap(head().mesh, d, clip, compressed(2e-4, core::BakeError::kMaxVertex));
  ASSERT_TRUE(mv);
  EXPECT_TRUE(mv->report.tolerance_met);
  EXPECT_LE(mv->report.max_error, 2e-4);
  // Smaller tolerance, larger rank.
  auto loose = core::retargetMocap(head().mesh, d, clip, compressed(0.1));
  auto tight = core::retargetMocap(head().mesh, d, clip, compressed(0.001));
  ASSERT_TRUE(loose);
  ASSERT_TRUE(tight);
  EXPECT_LT(loose->report.rank, tight->report.rank);
}

TEST(Retarget, ExactModeReproducesEveryFrameAndTheMarkers) {
  const int frames = 12;
  const core::MarkerTrajectories clip = richClip(frames);
  core::RetargetOptions o = jawOptions();
  o.bake.exact = true;
  const core::MarkerDistances& d = distancesFor(core::DistanceMethod::kGeodesic);
  auto out = core::retargetMocap(head().mesh, d, clip, o);
  ASSERT_TRUE(out) << out.error().message;
  const core::Rig& rig = out->rig;
  ASSERT_EQ(rig.morph_targets.size(), static_cast<std::size_t>(frames));
  const auto& channel = rig.animations.at(0).channels.at(0);
  EXPECT_TRUE(matricesNear(channel.values, Eigen::MatrixXd::Identity(frames, frames), 0.0));
  EXPECT_NEAR(channel.times(frames - 1), (frames - 1) / 30.0, 1e-12);
  EXPECT_LT(rig.morph_targets[0].position_deltas.cwiseAbs().maxCoeff(), 1e-12);  // the rest frame
  // At each marker (barycentric on its face) the frame's displacement is the marker's.
  const core::LandmarkSet markers = markerSet();
  double worst = 0.0;
  for (int f = 1; f < frames; ++f) {
    const Eigen::MatrixX3d& delta = rig.morph_targets[static_cast<std::size_t>(f)].position_deltas;
    for (std::size_t i = 0; i < markers.landmarks.size(); ++i) {
      const auto& lm = markers.landmarks[i];
      Eigen::RowVector3d at = Eigen::RowVector3d::Zero();
      for (int k = 0; k < 3; ++k) at += lm.barycentric(k) * delta.row(head().mesh.triangles(lm.face, k));
      const Eigen::RowVector3d expected = out->marker_displacements.block(f, 3 * static_cast<Eigen::Index>(i), 1, 3);
      worst = std::max(worst, (at - expected).norm());
    }
  }
  // Within the discretisation (kernel cone at the marker vs a linear triangle).
  EXPECT_LT(worst, 0.15 * out->report.max_marker_displacement);
  EXPECT_LT(out->report.marker_max_residual, 1e-9);
  // Exact mode refuses long clips.
  o.bake.max_exact_frames = 5;
  auto refused = core::retargetMocap(head().mesh, d, clip, o);
  ASSERT_FALSE(refused);
  EXPECT_EQ(refused.error().code, core::ErrorCode::kInvalidArgument);
}

TEST(Retarget, OutputIsAValidGlbWithDeterministicBytes) {
  const core::MarkerTrajectories clip = richClip(40);
  const core::LandmarkSet markers = markerSet();
  const std::filesystem::path dir = rigport_test::makeTempDir("retarget_glb");
  // The whole job (Euclidean distances included) on 1 and 2 threads, and the
  // job on cached hybrid distances on 1 and 2 threads: the same bytes.
  // (Geodesic distances are computed once here: their own determinism is
  // core/solve/geodesic.cpp's to test.)
  auto bytesFor = [&](int threads, bool one_off) -> std::vector<std::uint8_t> {
    const core::ScopedThreadCount scope(threads);
    core::RetargetOptions o = jawOptions();
    core::MarkerDistanceOptions dopt;
    dopt.method = core::DistanceMethod::kEuclidean;
    auto out = one_off ? core::retargetMocap(head().mesh, markers, clip, "head", dopt, o)
                       : core::retargetMocap(head().mesh, distancesFor(core::DistanceMethod::kHybrid), clip, o);
    EXPECT_TRUE(out) << out.error().message;
    if (!out) return {};
    auto bytes = core::encodeRigGlb(out->rig);
    EXPECT_TRUE(bytes) << bytes.error().message;
    return bytes ? *bytes : std::vector<std::uint8_t>{};
  };
  EXPECT_TRUE(bytesFor(1, true) == bytesFor(2, true)) << "GLB bytes depend on the thread count";
  const std::vector<std::uint8_t> hybrid = bytesFor(1, false);
  EXPECT_TRUE(hybrid == bytesFor(2, false)) << "GLB bytes depend on the thread count";
  EXPECT_FALSE(hybrid.empty());

  core::RetargetOptions o = jawOptions();
  auto out = core::retargetMocap(head().mesh, distancesFor(core::DistanceMethod::kHybrid), clip, o);
  ASSERT_TRUE(out) << out.error().message;
  ASSERT_TRUE(core::writeRigGlb(out->rig, dir / "retarget.glb"));
  EXPECT_GLTF_VALID(dir / "retarget.glb");
  // Round trip: the animation's weights channel is on the mesh node.
  auto back = core::readRig(dir / "retarget.glb");
  ASSERT_TRUE(back) << back.error().message;
  EXPECT_EQ(back->rig.morph_targets.size(), out->rig.morph_targets.size());
  ASSERT_EQ(back->rig.animations.size(), 1u);
  EXPECT_EQ(back->rig.animations[0].name, "mocap");
  EXPECT_EQ(back->rig.animations[0].channels[0].path, core::AnimationPath::kWeights);
  EXPECT_EQ(back->rig.morph_targets[0].name, "mode_00");
  // Diagnostics JSON with the stable keys.
  const std::string json = core::formatRetargetDiagnostics(out->report, {{"write", 1.0}});
  for (const char* key : {"\"method\": \"hybrid\"", "\"marker_max_residual\"", "\"rank\"", "\"geodesic_regions\"",
                          "\"timings_ms\"", "\"factorise\"", "\"write\"", "\"head_max_rotation_deg\"",
                          "\"head_markers\""}) {
    EXPECT_NE(json.find(key), std::string::npos) << key;
  }
  // Exact mode output is valid too.
  o.bake.exact = true;
  auto exact = core::retargetMocap(head().mesh, distancesFor(core::DistanceMethod::kHybrid), clip, o);
  ASSERT_TRUE(exact);
  ASSERT_TRUE(core::writeRigGlb(exact->rig, dir / "retarget_exact.glb"));
  EXPECT_GLTF_VALID(dir / "retarget_exact.glb");
}

TEST(Retarget, StiffnessLetsAMarkerGo) {
  core::RetargetOptions o = jawOptions();
  o.stiffness["mouth_outer_9"] = 9.0;
  auto stiff = core::retargetMocap(head().mesh, distancesFor(core::DistanceMethod::kEuclidean), jawOpenClip(markerSet(), 5), o);
  ASSERT_TRUE(stiff) << stiff.error().message;
  EXPECT_GT(stiff->report.marker_max_residual, 1e-5);
  o.stiffness["no_such_marker"] = 2.0;
  EXPECT_FALSE(core::retargetMocap(head().mesh, distancesFor(core::DistanceMethod::kEuclidean), jawOpenClip(markerSet(), 5), o));
}

// A placed marker the clip does not carry is left out and named: the result
// is the retarget with a placement that never had it.
TEST(Retarget, APlacedMarkerTheClipLacksIsLeftOutAndNamed) {
  const core::LandmarkSet markers = markerSet();
  const core::MarkerTrajectories clip = jawOpenClip(markers, 12);
  const std::string lost = "brow_right_2";
  const int k = clip.markerIndex(lost);
  ASSERT_GE(k, 0);
  core::MarkerTrajectories without = clip;
  without.marker_names.erase(without.marker_names.begin() + k);
  Eigen::MatrixXd kept(clip.frameCount(), clip.positions.cols() - 3);
  kept << clip.positions.leftCols(3 * k), clip.positions.rightCols(clip.positions.cols() - 3 * (k + 1));
  without.positions = kept;
  core::RetargetOptions options = jawOptions();
  options.stiffness[lost] = 5.0;  // options naming the lost marker do not fail the job
  auto out = core::retargetMocap(head().mesh, distancesFor(core::DistanceMethod::kEuclidean), without, options);
  ASSERT_TRUE(out) << out.error().message;
  EXPECT_EQ(out->report.markers_not_in_clip, std::vector<std::string>{lost});
  EXPECT_EQ(out->report.markers, static_cast<int>(markers.landmarks.size()) - 1);

  core::LandmarkSet fewer = markers;
  fewer.landmarks.erase(fewer.landmarks.begin() + fewer.indexOf(lost));
  core::MarkerDistanceOptions euclidean;
  euclidean.method = core::DistanceMethod::kEuclidean;
  auto distances = core::computeMarkerDistances(head().mesh, fewer, "fewer", euclidean);
  ASSERT_TRUE(distances) << distances.error().message;
  auto expected = core::retargetMocap(head().mesh, *distances, without, jawOptions());
  ASSERT_TRUE(expected) << expected.error().message;
  ASSERT_EQ(out->rig.morph_targets.size(), expected->rig.morph_targets.size());
  for (std::size_t t = 0; t < out->rig.morph_targets.size(); ++t) {
    EXPECT_TRUE(out->rig.morph_targets[t].position_deltas == expected->rig.morph_targets[t].position_deltas) << t;
  }
  EXPECT_GT(out->rig.morph_targets.size(), 0u);
}

// A clip whose markers carry a subject prefix ("Actor1:chin") drives the
// mesh as the same clip without it, and no marker is reported unused.
TEST(Retarget, SubjectPrefixedClipMarkersDriveTheirPlacedMarkers) {
  const core::MarkerTrajectories clip = jawOpenClip(markerSet(), 6);
  core::MarkerTrajectories prefixed = clip;
  for (auto& name : prefixed.marker_names) name = "Actor1:" + name;
  const core::MarkerDistances& d = distancesFor(core::DistanceMethod::kEuclidean);
  auto plain = core::retargetMocap(head().mesh, d, clip, jawOptions());
  auto out = core::retargetMocap(head().mesh, d, prefixed, jawOptions());
  ASSERT_TRUE(plain && out) << (out ? plain.error().message : out.error().message);
  EXPECT_TRUE(out->report.unused_clip_markers.empty());
  EXPECT_TRUE(out->report.markers_not_in_clip.empty());
  ASSERT_EQ(out->rig.morph_targets.size(), plain->rig.morph_targets.size());
  for (std::size_t t = 0; t < out->rig.morph_targets.size(); ++t) {
    EXPECT_TRUE(out->rig.morph_targets[t].position_deltas == plain->rig.morph_targets[t].position_deltas) << t;
  }
}

TEST(Retarget, BadInputsGiveClearErrors) {
  const core::MarkerDistances& d = distancesFor(core::DistanceMethod::kEuclidean);
  core::MarkerTrajectories clip = jawOpenClip(markerSet(), 5);
  core::MarkerTrajectories renamed = clip;
  for (auto& name : renamed.marker_names) name += "_other_session";
  auto missing = core::retargetMocap(head().mesh, d, renamed);
  ASSERT_FALSE(missing);
  EXPECT_EQ(missing.error().code, core::ErrorCode::kInvalidLandmarks);
  const std::string& message = missing.error().message;
  EXPECT_NE(message.find("none of the 31 placed markers"), std::string::npos) << message;
  EXPECT_NE(message.find(clip.marker_names[2]), std::string::npos) << message;

  core::RetargetOptions o = jawOptions();
  o.rest_frame = 5;
  EXPECT_FALSE(core::retargetMocap(head().mesh, d, clip, o));

  core::MarkerTrajectories nan = clip;
  nan.positions(2, 4) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(core::retargetMocap(head().mesh, d, nan));

  core::Mesh other = head().mesh;
  other.positions.conservativeResize(other.positions.rows() - 1, 3);
  EXPECT_FALSE(core::retargetMocap(other, d, clip));

  core::LandmarkSet three = markerSet();
  three.landmarks.resize(3);
  EXPECT_FALSE(core::computeMarkerDistances(head().mesh, three, "three"));
}

}  // namespace
