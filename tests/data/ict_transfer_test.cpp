// Rig transfer of the ICT source rig onto the ICT targets in ../shared/data
// (MANIFEST.md there defines the ground truth *.gt.glb). Prints, per target,
// the blend-shape error E = sum_v |d_out - d_gt| / sum_v |d_gt| (median and
// worst over the 53 shapes) next to the papers' plain method measured here
// (landmark TPS, closest point, barycentric copy of raw deltas). Skips when
// the data is absent.
#include <algorithm>
#include <array>
#include <fstream>
#include <memory>
#include <cstdio>
#include <map>
#include <string_view>
#include <numbers>

#include <gtest/gtest.h>

#include "core/transfer/blendshapes.h"
#include "core/geometry/mesh.h"
#include "core/io/mesh_io.h"
#include "core/io/rig_io.h"
#include "core/rig/skinning.h"
#include "core/solve/tps.h"
#include "core/transfer/transfer.h"
#include "core/jobs/transfer_job.h"
#include "tests/data/scan_scoring.h"
#include "tests/test_support.h"

namespace {

using rigport_test::ShapeErrors;
using rigport_test::shapeErrors;

// The landmarks of `mesh` given by position (for a mesh whose vertex indices
// differ: the surface split at its UV seams).
core::LandmarkSet landmarksByPosition(const core::LandmarkSet& landmarks, const core::Mesh& mesh, const std::string& label) {
  auto at = core::resolveLandmarks(landmarks, mesh, label);
  EXPECT_TRUE(at) << label << ": " << at.error().message;
  core::LandmarkSet by_position = landmarks;
  for (std::size_t i = 0; at && i < by_position.landmarks.size(); ++i) {
    by_position.landmarks[i].kind = core::LandmarkKind::kPosition;
    by_position.landmarks[i].position = at->row(static_cast<Eigen::Index>(i)).transpose();
  }
  return by_position;
}

// The topology of source_face_uv.glb (ICT vertex `ict(v)` at vertex v) with
// the positions of a mesh of the ICT topology, no normals or UVs.
core::Mesh splitAtUvSeams(const core::Mesh& layout, const Eigen::VectorXi& ict, const core::Mesh& whole) {
  core::Mesh split = layout;
  split.normals.resize(0, 3);
  split.uvs.resize(0, 2);
  for (Eigen::Index v = 0; v < split.vertexCount(); ++v) split.positions.row(v) = whole.positions.row(ict(v));
  return split;
}

const core::PreparedRig* ictRig(const std::filesystem::path& data) {
  static std::optional<core::PreparedRig> prepared;
  static bool tried = false;
  if (!tried) {
    tried = true;
    auto rig = core::readRig(data / "ict" / "source_face_skinned.glb");
    auto landmarks = core::readLandmarks(data / "ict" / "source_face.landmarks.json");
    if (rig && landmarks) {
      auto p = core::prepareRig(std::move(rig->rig), *landmarks, "source_face_skinned.glb");
      if (p) prepared = std::move(*p);
    }
  }
  return prepared ? &*prepared : nullptr;
}

// The worst vertex of each shape (issue [5]): spike = max_v |d_out - d_gt| /
// max_v |d_gt|, and the vertices whose error exceeds half the shape's largest
// true displacement (a lip left behind: a fang), with the shapes they are in.
struct Spikes {
  std::vector<double> spike;       // per shape
  int torn = 0;                    // vertices over half the largest displacement, all shapes
  std::string torn_shapes;         // "name:count ..." of the shapes that have any
  std::string worst_shape;
  double worst() const { return *std::max_element(spike.begin(), spike.end()); }
};

Spikes shapeSpikes(const core::Rig& out, const core::Rig& gt) {
  Spikes s;
  double worst = -1.0;
  for (std::size_t k = 0; k < gt.morph_targets.size(); ++k) {
    const Eigen::VectorXd e = (out.morph_targets[k].position_deltas - gt.morph_targets[k].position_deltas).rowwise().norm();
    const double largest = gt.morph_targets[k].position_deltas.rowwise().norm().maxCoeff();
    s.spike.push_back(largest > 0.0 ? e.maxCoeff() / largest : 0.0);
    const int torn = static_cast<int>((e.array() > 0.5 * largest).count());
    s.torn += torn;
    if (torn > 0) s.torn_shapes += gt.morph_targets[k].name + ":" + std::to_string(torn) + " ";
    if (s.spike.back() > worst) {
      worst = s.spike.back();
      s.worst_shape = gt.morph_targets[k].name;
    }
  }
  return s;
}

// p95 of |d_out - d_gt| over vertices near the moving lip/lid that the
// ground truth keeps still, relative to the ground truth's mean motion of the
// moving part.
double stillnessError(const core::Rig& out, const core::Rig& gt, const std::string& shape) {
  std::size_t k = 0;
  while (k < gt.morph_targets.size() && gt.morph_targets[k].name != shape) ++k;
  const Eigen::VectorXd g = gt.morph_targets[k].position_deltas.rowwise().norm();
  const Eigen::VectorXd e = (out.morph_targets[k].position_deltas - gt.morph_targets[k].position_deltas).rowwise().norm();
  const double max_motion = g.maxCoeff();
  double moving_sum = 0;
  int moving = 0;
  std::vector<Eigen::Index> moving_vertices;
  for (Eigen::Index v = 0; v < g.size(); ++v) {
    if (g(v) > 0.5 * max_motion) {
      moving_sum += g(v);
      ++moving;
      moving_vertices.push_back(v);
    }
  }
  const double mean_motion = moving_sum / moving;
  // "Near": within 1.5x the moving part's motion of a moving vertex.
  const double radius = 1.5 * max_motion;
  std::vector<double> still_errors;
  for (Eigen::Index v = 0; v < g.size(); ++v) {
    if (g(v) > 0.05 * mean_motion) continue;
    for (Eigen::Index m : moving_vertices) {
      if ((out.mesh.positions.row(v) - out.mesh.positions.row(m)).norm() < radius) {
        still_errors.push_back(e(v));
        break;
      }
    }
  }
  if (still_errors.empty()) return 0.0;
  std::sort(still_errors.begin(), still_errors.end());
  return still_errors[static_cast<std::size_t>(0.95 * static_cast<double>(still_errors.size() - 1))] / mean_motion;
}

// The papers' method done plainly: landmark TPS, closest point without
// filters, barycentric copy of raw deltas.
core::TransferOptions plainMethod() {
  core::TransferOptions plain;
  plain.warp = core::plainWarpOptions();
  plain.warp.locate.max_relative_distance = 0.0;
  plain.warp.locate.max_normal_angle_deg = 180.0;
  plain.warp.projection.max_normal_angle_deg = 180.0;
  plain.adaptation = core::ShapeAdaptation::kNone;
  plain.repair_unsure = false;
  return plain;
}

class IctTransfer : public ::testing::TestWithParam<std::string> {};

TEST_P(IctTransfer, ShapesBeatThePlainMethodAndOutputIsValid) {
  RIGPORT_REQUIRE_SHARED_DATA(data);
  const core::PreparedRig* source = ictRig(data);
  ASSERT_NE(source, nullptr) << "ICT rig failed to load";
  const std::string name = GetParam();
  auto target = core::readMesh(data / "ict" / "targets" / (name + ".glb"));
  auto landmarks = core::readLandmarks(data / "ict" / "targets" / (name + ".landmarks.json"));
  auto gt = core::readRig(data / "ict" / "targets" / (name + ".gt.glb"));
  ASSERT_TRUE(target && landmarks && gt);

  auto ours = core::transferRig(*source, target->mesh, *landmarks, name);
  ASSERT_TRUE(ours) << ours.error().message;
  const core::TransferOptions plain_options = plainMethod();
  auto plain = core::transferRig(*source, target->mesh, *landmarks, name, plain_options);
  ASSERT_TRUE(plain) << plain.error().message;

  const ShapeErrors e = shapeErrors(ours->rig, gt->rig), p = shapeErrors(plain->rig, gt->rig);
  const Spikes spikes = shapeSpikes(ours->rig, gt->rig), plain_spikes = shapeSpikes(plain->rig, gt->rig);
  std::printf("[ %-28s ] spike worst %.3f (%s), torn vertices %d %s| plain %.3f, %d | quality check: %s, %d repaired\n",
              name.c_str(), spikes.worst(), spikes.worst_shape.c_str(), spikes.torn, spikes.torn_shapes.c_str(),
              plain_spikes.worst(), plain_spikes.torn,
              ours->report.quality.clean() ? "clean" : ours->report.quality.summary().c_str(),
              ours->report.quality.repaired_vertices);
  const double jaw = stillnessError(ours->rig, gt->rig, "jawOpen");
  const double blink = std::max(stillnessError(ours->rig, gt->rig, "eyeBlink_L"), stillnessError(ours->rig, gt->rig, "eyeBlink_R"));
  const double jaw_p = stillnessError(plain->rig, gt->rig, "jawOpen");
  const double blink_p = std::max(stillnessError(plain->rig, gt->rig, "eyeBlink_L"), stillnessError(plain->rig, gt->rig, "eyeBlink_R"));
  std::printf("[ %-28s ] E median %.4f worst %.4f | plain %.4f / %.4f | still-lip p95 %.2f%% (plain %.2f%%) "
              "still-lid p95 %.2f%% (plain %.2f%%) | inpainted %d\n",
              name.c_str(), e.median(), e.worst(), p.median(), p.worst(), 100 * jaw, 100 * jaw_p, 100 * blink,
              100 * blink_p, ours->report.inpainted_vertices);
  // Never meaningfully worse than the plain method (measured: better median
  // and worst on all 9 ICT targets).
  EXPECT_LE(e.median(), p.median() + 0.005);
  EXPECT_LE(e.worst(), p.worst() + 0.005);
  // Lips and lids that the ground truth keeps still stay still on the
  // remeshed targets: within 3% of the moving part's mean motion (measured
  // 0.41-1.76% lips, 0.44-1.86% lids).
  if (name.ends_with("_remesh") || name.starts_with("sparse")) {
    EXPECT_LE(jaw, 0.03) << "jawOpen";
    EXPECT_LE(blink, 0.03) << "eyeBlink_L/R";
  }
  // The parts of the issue's E limits that are met
  // (docs/journal/ACCURACY_HISTORY.md, "Where the issue's E limits stand"):
  // the worst shape of every ordinary identity within 0.12 (measured
  // 0.066-0.119, id_s03_remesh's eyeBlink_R the closest), and the 10-landmark
  // target's median within 0.08 (measured 0.0798). The ordinary medians' 0.03
  // and the cartoon's 0.10 are not met and not asserted.
  if (name.starts_with("id_")) {
    EXPECT_LE(e.worst(), 0.12) << "worst shape of an ordinary identity";
  }
  if (name.starts_with("sparse")) {
    EXPECT_LE(e.median(), 0.08) << "median with 10 landmarks";
  }
  // The worst vertex (issue [5]): no shape leaves a vertex behind by more
  // than half its largest true displacement (a fang). Before the lips' and
  // lids' sides were matched sparse10_s01 had 25 such vertices (spike 0.97);
  // measured now 0.18-0.46, none.
  EXPECT_LE(spikes.worst(), 0.5) << spikes.worst_shape;
  EXPECT_EQ(spikes.torn, 0) << spikes.torn_shapes;
  // The quality check raises no false alarm on these faces (after repairing
  // sparse10_s01's one vertex located across its columella).
  EXPECT_TRUE(ours->report.quality.clean()) << ours->report.quality.summary();
  // And no median or worst E lost for it (docs/ACCURACY.md, measured before
  // the sides; the margin is rounding between builds).
  const std::map<std::string, std::pair<double, double>> before = {
      {"id_s01", {0.0341, 0.0698}},        {"id_s02", {0.0378, 0.1042}},        {"id_s03", {0.0352, 0.0660}},
      {"stylized_s01_cartoon", {0.1362, 0.3046}}, {"id_s01_remesh", {0.0349, 0.1026}}, {"id_s02_remesh", {0.0451, 0.1032}},
      {"id_s03_remesh", {0.0516, 0.1042}}, {"stylized_s01_cartoon_remesh", {0.1559, 0.3097}},
      {"sparse10_s01", {0.0792, 0.1485}}};
  EXPECT_LE(e.median(), before.at(name).first + 0.0005);
  EXPECT_LE(e.worst(), before.at(name).second + 0.0005);

  // Skin rules and the Khronos validator on the written GLB.
  const auto dir = rigport_test::makeTempDir("out");
  ASSERT_TRUE(core::writeRigGlb(ours->rig, dir / (name + ".glb")));
  EXPECT_GLTF_VALID(dir / (name + ".glb"));
}

INSTANTIATE_TEST_SUITE_P(Targets, IctTransfer,
                         ::testing::Values("id_s01", "id_s02", "id_s03", "stylized_s01_cartoon", "id_s01_remesh",
                                           "id_s02_remesh", "id_s03_remesh", "stylized_s01_cartoon_remesh",
                                           "sparse10_s01"));

// The transfer job when it fits (core/jobs/transfer_job.h; docs/FIT.md, "The
// fit as a correspondence"): through the fit's correspondence with the
// targets' landmarks, and with the warp on landmarks the fit found (none
// given). E and the worst vertex against the ground truth, beside the warp
// with the given landmarks; each held at its measured level.
struct FittingTransfer {
  ShapeErrors e;
  Spikes spikes;
  bool clean = false;
  double fit_ms = 0.0;
  std::string warnings;  // the transfer's, joined
};

FittingTransfer transferThroughJob(const core::PreparedRig& source, const core::LoadedMesh& target,
                                   const core::LandmarkSet& landmarks, const std::string& name,
                                   core::CorrespondenceMethod method, const core::Rig& gt) {
  const auto shared = std::shared_ptr<const core::PreparedRig>(&source, [](const core::PreparedRig*) {});
  const core::PrepareRigSource prepare = [&]() -> core::Result<core::PreparedRigSource> {
    return core::PreparedRigSource{shared, nullptr, true};
  };
  core::TransferJobInput input;
  input.target = target;
  input.target_landmarks = landmarks;
  input.target_label = name;
  input.settings.correspondence = method;
  auto job = core::runTransferJob(prepare, std::move(input), core::JobRun{});
  EXPECT_TRUE(job) << name << ": " << job.error().message;
  FittingTransfer out;
  if (!job) return out;
  auto rig = core::readRigGltf(job->output.glb, name, true);
  EXPECT_TRUE(rig) << name;
  if (!rig) return out;
  out.e = shapeErrors(rig->rig, gt);
  out.spikes = shapeSpikes(rig->rig, gt);
  out.clean = job->report.quality.clean();
  out.fit_ms = job->output.timings_ms.at("fit");
  for (const std::string& w : job->report.warnings) out.warnings += w + "\n";
  const auto dir = rigport_test::makeTempDir("fitting_transfer");
  std::ofstream(dir / "out.glb", std::ios::binary)
      .write(reinterpret_cast<const char*>(job->output.glb.data()), static_cast<std::streamsize>(job->output.glb.size()));
  EXPECT_GLTF_VALID(dir / "out.glb");
  return out;
}

TEST(IctTransferFitting, ThroughTheFitAndWithLandmarksFoundByIt) {
  RIGPORT_REQUIRE_SHARED_DATA(data);
  const core::PreparedRig* source = ictRig(data);
  ASSERT_NE(source, nullptr) << "ICT rig failed to load";
  // Measured (docs/FIT.md): through the fit with the given landmarks; with
  // the landmarks the fit found. The remeshed targets' 5-7-vertex eye holes
  // leave their eye corners found 3-10 mm off and lid vertices torn: a known
  // gap, held here at its measured level.
  // {through the fit: median, worst; landmarks found: median, worst, torn vertices}
  const std::map<std::string, std::array<double, 5>> measured = {
      {"id_s01", {0.0270, 0.0706, 0.0461, 0.0922, 0}},
      {"id_s02", {0.0371, 0.0736, 0.0704, 0.1424, 0}},
      {"id_s03", {0.0335, 0.0750, 0.0530, 0.1440, 2}},
      {"stylized_s01_cartoon", {0.1293, 0.2953, 0.1578, 0.2928, 0}},
      {"id_s01_remesh", {0.0391, 0.0936, 0.0714, 0.4500, 12}},
      {"id_s02_remesh", {0.0518, 0.1281, 0.0805, 0.4615, 18}},
      {"id_s03_remesh", {0.0578, 0.1301, 0.0925, 0.4674, 15}},
      {"stylized_s01_cartoon_remesh", {0.1618, 0.2926, 0.2202, 0.3329, 0}},
      {"sparse10_s01", {0.0761, 0.1378, 0.0620, 0.3030, 2}}};
  for (const auto& [name, levels] : measured) {
    auto target = core::readMesh(data / "ict" / "targets" / (name + ".glb"));
    auto landmarks = core::readLandmarks(data / "ict" / "targets" / (name + ".landmarks.json"));
    auto gt = core::readRig(data / "ict" / "targets" / (name + ".gt.glb"));
    ASSERT_TRUE(target && landmarks && gt) << name;
    auto warp = core::transferRig(*source, target->mesh, *landmarks, name);
    ASSERT_TRUE(warp) << warp.error().message;
    const ShapeErrors w = shapeErrors(warp->rig, gt->rig);
    const FittingTransfer fit =
        transferThroughJob(*source, *target, *landmarks, name, core::CorrespondenceMethod::kFit, gt->rig);
    const FittingTransfer found =
        transferThroughJob(*source, *target, {}, name, core::CorrespondenceMethod::kWarp, gt->rig);
    if (fit.e.empty()) continue;
    std::printf("[ %-28s ] E median/worst: warp %.4f/%.4f | through the fit %.4f/%.4f spike %.3f torn %d (fit %.0f ms)"
                " | landmarks found %s\n",
                name.c_str(), w.median(), w.worst(), fit.e.median(), fit.e.worst(), fit.spikes.worst(), fit.spikes.torn,
                fit.fit_ms,
                found.e.empty() ? "(failed)"
                                : (std::to_string(found.e.median()).substr(0, 6) + "/" +
                                   std::to_string(found.e.worst()).substr(0, 6) + " spike " +
                                   std::to_string(found.spikes.worst()).substr(0, 5) + " torn " +
                                   std::to_string(found.spikes.torn)).c_str());
    EXPECT_LE(fit.e.median(), levels[0] + 0.0005) << name;
    EXPECT_LE(fit.e.worst(), levels[1] + 0.0005) << name;
    EXPECT_EQ(fit.spikes.torn, 0) << name << ": " << fit.spikes.torn_shapes;
    EXPECT_TRUE(fit.clean) << name;
    ASSERT_FALSE(found.e.empty()) << name;
    EXPECT_LE(found.e.median(), levels[2] + 0.0005) << name;
    EXPECT_LE(found.e.worst(), levels[3] + 0.0005) << name;
    EXPECT_LE(found.spikes.torn, static_cast<int>(levels[4])) << name << ": " << found.spikes.torn_shapes;
    // id_s01_remesh's right eye hole is a third of the rig's eye rim: the fit
    // says which rims found no opening; the complete targets have all three.
    const bool rims_warned = found.warnings.find("rims found no opening") != std::string::npos;
    if (name == "id_s01_remesh") {
      EXPECT_TRUE(rims_warned) << found.warnings;
    }
    if (!name.ends_with("_remesh")) {
      EXPECT_FALSE(rims_warned) << name << ": " << found.warnings;
    }
  }
}

// Identities the data does not hold, made from the ones it does. ICT
// identities are neutral + sum_m c_m (identity_m - neutral) with c ~ N(0, 1)
// per mode (MANIFEST.md), and the source is that neutral, so
// source + sum_k a_k (id_k - source) with |a| = 1 is another identity of the
// same distribution (coefficients sum_k a_k c_k), and k (id - source) one
// exaggerated k times. ICT deltas are identity independent, so the ground
// truth is the source's own deltas. A check that the pipeline is right in
// general, not for the three targets it was measured on.
struct MadeIdentity {
  const char* name;
  double a[3];  // weights of id_s01..03 - source
};

TEST(IctOtherIdentities, ShapesBeatThePlainMethod) {
  RIGPORT_REQUIRE_SHARED_DATA(data);
  const core::PreparedRig* source = ictRig(data);
  ASSERT_NE(source, nullptr) << "ICT rig failed to load";
  const core::Mesh& src = source->surface.mesh;
  std::vector<Eigen::MatrixX3d> offsets;
  for (int k = 1; k <= 3; ++k) {
    auto identity = core::readMesh(data / "ict" / "targets" / ("id_s0" + std::to_string(k) + ".glb"));
    ASSERT_TRUE(identity) << identity.error().message;
    ASSERT_EQ(identity->mesh.vertexCount(), src.vertexCount());
    offsets.push_back(identity->mesh.positions - src.positions);
  }
  const double r2 = 1.0 / std::numbers::sqrt2, r3 = std::numbers::inv_sqrt3;
  const MadeIdentity made[] = {{"minus_s01", {-1, 0, 0}},     {"minus_s02", {0, -1, 0}},      {"minus_s03", {0, 0, -1}},
                               {"s01_plus_s02", {r2, r2, 0}}, {"s01_minus_s02", {r2, -r2, 0}}, {"s02_plus_s03", {0, r2, r2}},
                               {"s01_minus_s03", {r2, 0, -r2}}, {"s03_minus_s01_s02", {-r3, -r3, r3}},
                               {"s01_x3", {3, 0, 0}},         {"s02_x3", {0, 3, 0}},          {"s03_x3", {0, 0, 3}}};
  const core::TransferOptions plain_options = plainMethod();
  core::Rig truth;  // ICT deltas are identity independent
  truth.morph_targets = source->rig.morph_targets;
  double worst_sum = 0.0, plain_worst_sum = 0.0;
  for (const MadeIdentity& identity : made) {
    core::Mesh mesh = src;
    mesh.normals.resize(0, 3);  // computed by the pipeline, as for a scan without normals
    for (int k = 0; k < 3; ++k) mesh.positions += identity.a[k] * offsets[static_cast<std::size_t>(k)];
    const core::LandmarkSet& landmarks = source->surface.landmarks;  // same topology: the same vertices
    auto ours = core::transferRig(*source, mesh, landmarks, identity.name);
    auto plain = core::transferRig(*source, mesh, landmarks, identity.name, plain_options);
    ASSERT_TRUE(ours) << ours.error().message;
    ASSERT_TRUE(plain) << plain.error().message;
    const ShapeErrors e = shapeErrors(ours->rig, truth), p = shapeErrors(plain->rig, truth);
    const Spikes spikes = shapeSpikes(ours->rig, truth);
    std::printf("[ %-24s ] E median %.4f worst %.4f | plain %.4f / %.4f | inpainted %d | spike %.3f (%s) torn %d %s\n",
                identity.name, e.median(), e.worst(), p.median(), p.worst(), ours->report.inpainted_vertices,
                spikes.worst(), spikes.worst_shape.c_str(), spikes.torn, spikes.torn_shapes.c_str());
    EXPECT_LT(e.median(), p.median()) << identity.name;
    // No lip or lid left behind on the identities of the model's own range
    // (before the sides were matched: 4-31 such vertices on 5 of the 8). The
    // identities exaggerated 3x are registered a centimetre off in places
    // (s03_x3: hundreds of vertices, not an opening's side): printed only.
    if (!std::string_view(identity.name).ends_with("_x3")) {
      EXPECT_LE(spikes.worst(), 0.5) << identity.name << " " << spikes.worst_shape;
      EXPECT_EQ(spikes.torn, 0) << identity.name << " " << spikes.torn_shapes;
    }
    worst_sum += e.worst();
    plain_worst_sum += p.worst();
  }
  // The worst shape is better on average, not on every identity: on
  // s02_plus_s03 eyeBlink_L is 0.137 against the plain method's 0.121
  // (measured 2026-11-22; docs/journal/ACCURACY_HISTORY.md, "Other identities").
  EXPECT_LT(worst_sum, plain_worst_sum);
}

// Stylised faces the data does not hold, made from the identities it does:
// a cartoon-like stylisation D (a nose inflated and pushed forward about its
// tip, the face below the mouth-corner line widened and dropped, a forehead
// bulge, non-uniform scale), smooth and one-to-one, applied to id_s01-03.
// Same topology, so the landmarks are the source's vertices, and the truth
// is each expression carried through the stylisation: D(X + delta) - D(X).
// The issue's requirement: the default must not lose to the papers' plain
// method on any kind of face (docs/journal/ACCURACY_HISTORY.md, "Stylised faces").
struct Stylisation {
  double nose_inflate, nose_push, jaw_widen, jaw_drop, forehead, scale_x, scale_y, scale_z;
};

TEST(IctMadeCartoons, TheDefaultDoesNotLoseToThePlainMethod) {
  RIGPORT_REQUIRE_SHARED_DATA(data);
  const core::PreparedRig* source = ictRig(data);
  ASSERT_NE(source, nullptr) << "ICT rig failed to load";
  const core::LandmarkSet& landmarks = source->surface.landmarks;
  const Stylisation styles[] = {{0.35, 0.25, 0.15, 0.10, 0.20, 1.10, 0.95, 1.00},
                                {0.50, 0.10, 0.25, 0.05, 0.10, 0.95, 1.05, 1.10},
                                {0.20, 0.35, 0.10, 0.20, 0.30, 1.00, 1.10, 0.90},
                                {0.45, 0.30, 0.30, 0.15, 0.00, 1.15, 1.00, 1.05},
                                {0.25, 0.20, 0.05, 0.25, 0.25, 0.90, 0.90, 1.00}};
  const core::TransferOptions plain_options = plainMethod();
  double median_sum = 0.0, plain_median_sum = 0.0;
  int wins = 0, cases = 0;
  for (int k = 1; k <= 3; ++k) {
    const std::string id = "id_s0" + std::to_string(k);
    auto identity = core::readMesh(data / "ict" / "targets" / (id + ".glb"));
    ASSERT_TRUE(identity) << identity.error().message;
    const Eigen::MatrixX3d x = identity->mesh.positions;
    auto at = core::resolveLandmarks(landmarks, identity->mesh, id);
    ASSERT_TRUE(at) << at.error().message;
    const auto point = [&](const std::string& name) -> Eigen::RowVector3d {
      for (std::size_t i = 0; i < landmarks.landmarks.size(); ++i) {
        if (landmarks.landmarks[i].name == name) return at->row(static_cast<Eigen::Index>(i));
      }
      ADD_FAILURE() << "no landmark " << name;
      return Eigen::RowVector3d::Zero();
    };
    // The face's frame from its landmarks: forward from the jaw line to the
    // nose tip, up from the chin to the brows.
    const Eigen::RowVector3d tip = point("nose_bridge_3"), chin = point("jaw_08");
    const Eigen::RowVector3d brows = 0.5 * (point("brow_right_2") + point("brow_left_2"));
    const Eigen::RowVector3d mouth = 0.5 * (point("mouth_outer_0") + point("mouth_outer_6"));
    const double size = (point("eye_right_0") - point("eye_left_3")).norm();
    Eigen::RowVector3d jaw_mid = Eigen::RowVector3d::Zero();
    for (int j = 0; j <= 16; ++j) jaw_mid += point((j < 10 ? "jaw_0" : "jaw_") + std::to_string(j)) / 17.0;
    Eigen::RowVector3d up = (brows - chin).normalized();
    Eigen::RowVector3d forward = tip - jaw_mid;
    forward = (forward - forward.dot(up) * up).normalized();
    const Eigen::RowVector3d side = up.cross(forward);
    const Eigen::RowVector3d forehead = brows + 0.45 * size * up;
    for (std::size_t s = 0; s < std::size(styles); ++s) {
      const Stylisation& st = styles[s];
      const auto stylise = [&](const Eigen::RowVector3d& p) -> Eigen::RowVector3d {
        const double sn = 0.35 * size;
        const double nose = std::exp(-(p - tip).squaredNorm() / (2 * sn * sn));
        Eigen::RowVector3d q = p + nose * (st.nose_inflate * (p - tip) + st.nose_push * sn * forward);
        const double below = std::clamp(-(p - mouth).dot(up) / (0.6 * size), 0.0, 1.0);
        const double smooth = below * below * (3 - 2 * below);
        q += smooth * (st.jaw_widen * (p - mouth).dot(side) * side - st.jaw_drop * 0.3 * size * up);
        const double sf = 0.5 * size;
        q += st.forehead * sf * std::exp(-(p - forehead).squaredNorm() / (2 * sf * sf)) * forward;
        const Eigen::RowVector3d r = q - jaw_mid;
        return jaw_mid + st.scale_x * r.dot(side) * side + st.scale_y * r.dot(up) * up + st.scale_z * r.dot(forward) * forward;
      };
      core::Mesh mesh = identity->mesh;
      mesh.normals.resize(0, 3);
      for (Eigen::Index v = 0; v < x.rows(); ++v) mesh.positions.row(v) = stylise(x.row(v));
      core::Rig truth;
      truth.morph_targets = source->rig.morph_targets;  // ICT deltas are identity independent
      for (auto& shape : truth.morph_targets) {
        for (Eigen::Index v = 0; v < x.rows(); ++v) {
          shape.position_deltas.row(v) = stylise(x.row(v) + shape.position_deltas.row(v)) - mesh.positions.row(v);
        }
      }
      const std::string name = id + "_cartoon" + std::to_string(s);
      auto ours = core::transferRig(*source, mesh, landmarks, name);
      auto plain = core::transferRig(*source, mesh, landmarks, name, plain_options);
      ASSERT_TRUE(ours && plain) << name;
      const ShapeErrors e = shapeErrors(ours->rig, truth), p = shapeErrors(plain->rig, truth);
      const Spikes spikes = shapeSpikes(ours->rig, truth), plain_spikes = shapeSpikes(plain->rig, truth);
      std::printf("[ %-18s ] E median %.4f worst %.4f | plain %.4f / %.4f | spike %.2f torn %d (plain %.2f, %d) | %s\n",
                  name.c_str(), e.median(), e.worst(), p.median(), p.worst(), spikes.worst(),
                  spikes.torn, plain_spikes.worst(), plain_spikes.torn, ours->report.adaptation.c_str());
      // Not meaningfully worse than the plain method on any of them (the
      // margin as for the ICT targets; measured: every median better by
      // 0.006-0.021, two worsts above by 0.0006 and 0.0008), and better in
      // sum. No vertex left behind (the plain method leaves 53-217).
      EXPECT_LE(e.median(), p.median() + 0.005) << name;
      EXPECT_LE(e.worst(), p.worst() + 0.005) << name;
      EXPECT_EQ(spikes.torn, 0) << name << " " << spikes.torn_shapes;
      median_sum += e.median();
      plain_median_sum += p.median();
      wins += e.median() < p.median();
      ++cases;
    }
  }
  std::printf("default median below the plain method's on %d of %d made cartoons\n", wins, cases);
  EXPECT_LT(median_sum, plain_median_sum);
}

// What limits E (printed; measured in docs/journal/ACCURACY_HISTORY_TARGETS.md,
// "Ordinary identities", summarised in docs/ACCURACY.md). On the
// same-topology targets the true correspondence is known (target vertex i is
// source vertex i), so the error can be split: the true correspondence with
// raw deltas reproduces the ordinary identity's ground truth exactly (ICT
// deltas are identity independent), and a dense map through the TRUE
// positions of the rig's own dense centres (landmarks + farthest-point
// samples), projected and located like the pipeline does, bounds what any
// correspondence interpolated from those centres can reach.
TEST(IctTransferLimits, TrueCorrespondenceAndTrueDenseCentres) {
  RIGPORT_REQUIRE_SHARED_DATA(data);
  const core::PreparedRig* source = ictRig(data);
  ASSERT_NE(source, nullptr);
  const core::Mesh& src = source->surface.mesh;
  std::vector<int> face_of(static_cast<std::size_t>(src.vertexCount()), -1);
  for (Eigen::Index f = 0; f < src.triangleCount(); ++f) {
    for (int k = 0; k < 3; ++k) face_of[static_cast<std::size_t>(src.triangles(f, k))] = static_cast<int>(f);
  }
  for (const std::string name : {"id_s01", "stylized_s01_cartoon"}) {
    auto target = core::readMesh(data / "ict" / "targets" / (name + ".glb"));
    auto gt = core::readRig(data / "ict" / "targets" / (name + ".gt.glb"));
    auto landmarks = core::readLandmarks(data / "ict" / "targets" / (name + ".landmarks.json"));
    ASSERT_TRUE(target && gt && landmarks);
    core::Mesh mesh = target->mesh;
    mesh.normals = core::computeVertexNormals(mesh.positions, mesh.triangles);
    ASSERT_EQ(mesh.vertexCount(), src.vertexCount());
    auto errors = [&](const core::TargetLocations& at, const std::vector<Eigen::Matrix3d>& adaptation) {
      return shapeErrors(
          core::transferMorphTargets(source->rig.morph_targets, src.triangles, at, adaptation, mesh, nullptr),
          gt->rig.morph_targets);
    };
    // The true correspondence.
    core::TargetLocations truth;
    truth.on_source.resize(static_cast<std::size_t>(mesh.vertexCount()));
    truth.mismatched = Eigen::VectorXi::Zero(mesh.vertexCount());
    for (Eigen::Index v = 0; v < mesh.vertexCount(); ++v) {
      core::SurfacePoint& sp = truth.on_source[static_cast<std::size_t>(v)];
      sp.face = face_of[static_cast<std::size_t>(v)];
      for (int k = 0; k < 3; ++k) sp.barycentric(k) = src.triangles(sp.face, k) == v ? 1.0 : 0.0;
    }
    const ShapeErrors exact = errors(truth, {Eigen::Matrix3d::Identity()});
    // A dense map through the true positions of the dense centres.
    const Eigen::Index nl = source->surface.landmark_positions.rows();
    Eigen::MatrixX3d centre_targets(source->surface.dense_centres.rows(), 3);
    for (Eigen::Index i = 0; i < nl; ++i) {
      centre_targets.row(i) = mesh.positions.row(source->surface.landmarks.landmarks[static_cast<std::size_t>(i)].vertex);
    }
    for (std::size_t k = 0; k < source->surface.dense_vertices.size(); ++k) {
      centre_targets.row(nl + static_cast<Eigen::Index>(k)) = mesh.positions.row(source->surface.dense_vertices[k]);
    }
    const core::TpsWarp dense = source->surface.dense_factorization->fit(centre_targets);
    const Eigen::MatrixX3d warped = dense.apply(src.positions);
    const core::ClosestPointIndex index(mesh.positions, mesh.triangles);
    const double diagonal = core::boundingBoxDiagonal(mesh.positions);
    const core::GuideModel guide = core::projectToTarget(warped, core::computeVertexNormals(warped, src.triangles),
                                                         index, diagonal, core::ProjectionOptions{});
    const ShapeErrors centres =
        errors(core::locateOnGuide(mesh, guide.positions, *source->surface.guide_index, core::LocateOptions{}),
               {Eigen::Matrix3d::Identity()});
    // The true correspondence with deltas adapted by the local Jacobian of the
    // true map (smoothed as ShapeAdaptation::kLocal does).
    core::TpsOptions smooth;
    smooth.regularization = core::TransferOptions{}.local_smoothing * source->surface.diagonal;
    smooth.leave_one_out = false;
    auto smooth_map = core::fitTps(source->surface.dense_centres, centre_targets, smooth);
    ASSERT_TRUE(smooth_map) << smooth_map.error().message;
    const ShapeErrors adapted = errors(truth, smooth_map->jacobians(src.positions));
    core::TransferOptions raw;
    raw.adaptation = core::ShapeAdaptation::kNone;
    auto ours = core::transferRig(*source, target->mesh, *landmarks, name, raw);
    ASSERT_TRUE(ours) << ours.error().message;
    const ShapeErrors pipeline = shapeErrors(ours->rig, gt->rig);
    std::printf("[ %-28s ] E median/worst, raw deltas: true correspondence %.4f/%.4f | dense map through the %ld true "
                "centres %.4f/%.4f | the pipeline %.4f/%.4f || true correspondence, deltas by the local Jacobian "
                "%.4f/%.4f\n",
                name.c_str(), exact.median(), exact.worst(), static_cast<long>(centre_targets.rows()),
                centres.median(), centres.worst(), pipeline.median(), pipeline.worst(), adapted.median(), adapted.worst());
    // The true correspondence beats the estimated one.
    EXPECT_LT(exact.median(), pipeline.median());
    if (name == "id_s01") {
      EXPECT_LT(exact.worst(), 1e-9) << "ordinary identities keep ICT's deltas unchanged";
      // On an ordinary identity even the true centres alone beat the
      // estimated correspondence: E follows the correspondence, not something
      // else in the pipeline. (On the cartoon the estimate, slid to where the
      // map bends least, scores below the true centres' raw deltas: measured
      // 0.130 vs 0.134; there the deltas' adaptation, not the map, limits E.)
      EXPECT_LT(centres.median(), pipeline.median());
    }
  }
}

// An identity exported as glTF exports textured faces: split at the UV seams
// (source_face_uv.glb's topology, 409 points in two copies). It is the same
// surface as the unsplit identity: the same E, and both copies of every split
// point take the same weights and deltas (before copies were matched as one
// point, one pair on id_s01 parted by 0.16 mm).
TEST(IctTransferSplit, IdentitySplitAtUvSeamsMatchesAsOneSurface) {
  RIGPORT_REQUIRE_SHARED_DATA(data);
  const core::PreparedRig* source = ictRig(data);
  ASSERT_NE(source, nullptr);
  auto uv = core::readRig(data / "ict" / "source_face_uv.glb");
  ASSERT_TRUE(uv) << uv.error().message;
  const auto field = uv->rig.attributes.fields.find("ICT_VERTEX");
  ASSERT_NE(field, uv->rig.attributes.fields.end());
  const Eigen::VectorXi ict = field->second.col(0).cast<int>();
  for (const std::string name : {"id_s01", "id_s02"}) {
    auto identity = core::readMesh(data / "ict" / "targets" / (name + ".glb"));
    auto landmarks = core::readLandmarks(data / "ict" / "targets" / (name + ".landmarks.json"));
    auto gt = core::readRig(data / "ict" / "targets" / (name + ".gt.glb"));
    ASSERT_TRUE(identity && landmarks && gt);
    const core::Mesh split = splitAtUvSeams(uv->rig.mesh, ict, identity->mesh);
    const core::LandmarkSet by_position = landmarksByPosition(*landmarks, identity->mesh, name);
    auto whole = core::transferRig(*source, identity->mesh, *landmarks, name);
    auto parts = core::transferRig(*source, split, by_position, name + " split");
    ASSERT_TRUE(whole && parts);
    core::Rig truth = gt->rig;  // the ground truth on the split topology
    for (auto& t : truth.morph_targets) {
      Eigen::MatrixX3d d(split.vertexCount(), 3);
      for (Eigen::Index v = 0; v < split.vertexCount(); ++v) d.row(v) = t.position_deltas.row(ict(v));
      t.position_deltas = d;
    }
    const ShapeErrors e_whole = shapeErrors(whole->rig, gt->rig), e_split = shapeErrors(parts->rig, truth);
    double weight_gap = 0.0, delta_gap = 0.0;
    std::vector<Eigen::Index> first(static_cast<std::size_t>(identity->mesh.vertexCount()), -1);
    int pairs = 0;
    for (Eigen::Index v = 0; v < split.vertexCount(); ++v) {
      Eigen::Index& f = first[static_cast<std::size_t>(ict(v))];
      if (f < 0) {
        f = v;
        continue;
      }
      ++pairs;
      const core::Rig& r = parts->rig;
      weight_gap = std::max(weight_gap, (Eigen::VectorXd(r.weights.row(v)) - Eigen::VectorXd(r.weights.row(f))).cwiseAbs().maxCoeff());
      for (const auto& t : r.morph_targets) delta_gap = std::max(delta_gap, (t.position_deltas.row(v) - t.position_deltas.row(f)).norm());
    }
    std::printf("[ %-28s ] split at UV seams (%d points in two copies): E median/worst %.4f/%.4f (unsplit %.4f/%.4f); "
                "largest gap between copies: weight %.2g, delta %.2g cm\n",
                name.c_str(), pairs, e_split.median(), e_split.worst(), e_whole.median(), e_whole.worst(), weight_gap,
                delta_gap);
    EXPECT_GT(pairs, 0);
    EXPECT_NEAR(e_split.median(), e_whole.median(), 0.002);
    EXPECT_NEAR(e_split.worst(), e_whole.worst(), 0.005);
    EXPECT_LT(weight_gap, 1e-9);
    EXPECT_LT(delta_gap, 1e-9);
  }
}

// The ICT UV layout (source_face_uv.glb: the surface split at its seams, a
// multi-tile atlas with charts that wrap around) carried onto an identity of
// the source's topology: each output triangle is a source triangle, so its
// UVs should be those the layout gives it. Per-vertex UVs alone put every
// triangle along a seam across the atlas; splitting the target where the
// seams cross keeps each on one chart.
TEST(IctTransferUvs, EveryTriangleStaysOnOneChart) {
  RIGPORT_REQUIRE_SHARED_DATA(data);
  auto uv = core::readRig(data / "ict" / "source_face_uv.glb");
  auto plain = core::readMesh(data / "ict" / "source_face.glb");
  auto source_landmarks = core::readLandmarks(data / "ict" / "source_face.landmarks.json");
  ASSERT_TRUE(uv && plain && source_landmarks);
  const Eigen::VectorXi ict = uv->rig.attributes.fields.at("ICT_VERTEX").col(0).cast<int>();
  const core::LandmarkSet by_position = landmarksByPosition(*source_landmarks, plain->mesh, "source_face.glb");
  core::Rig layout;
  layout.mesh = uv->rig.mesh;
  auto source = core::prepareRig(layout, by_position, "source_face_uv.glb");
  ASSERT_TRUE(source) << source.error().message;
  // Its triangles are source_face.glb's, corner for corner.
  const Eigen::MatrixX3i& uv_tris = uv->rig.mesh.triangles;
  ASSERT_EQ(uv_tris.rows(), plain->mesh.triangleCount());
  for (Eigen::Index f = 0; f < uv_tris.rows(); ++f) {
    for (int k = 0; k < 3; ++k) ASSERT_EQ(ict(uv_tris(f, k)), plain->mesh.triangles(f, k)) << "triangle " << f;
  }
  auto span = [](const Eigen::MatrixX2d& uvs, const Eigen::MatrixX3i& tris, Eigen::Index f) {
    Eigen::Matrix<double, 3, 2> corners;
    for (int k = 0; k < 3; ++k) corners.row(k) = uvs.row(tris(f, k));
    return (corners.colwise().maxCoeff() - corners.colwise().minCoeff()).maxCoeff();
  };
  double layout_span = 0.0;
  for (Eigen::Index f = 0; f < uv_tris.rows(); ++f) layout_span = std::max(layout_span, span(uv->rig.mesh.uvs, uv_tris, f));

  core::TransferOptions options;
  options.weights = options.joints = options.shapes = options.animations = false;
  options.uvs = true;
  for (const std::string name : {"id_s01", "id_s02_remesh"}) {
    auto target = core::readMesh(data / "ict" / "targets" / (name + ".glb"));
    auto landmarks = core::readLandmarks(data / "ict" / "targets" / (name + ".landmarks.json"));
    ASSERT_TRUE(target && landmarks);
    auto result = core::transferRig(*source, target->mesh, *landmarks, name, options);
    ASSERT_TRUE(result) << result.error().message;
    const core::Mesh& out = result->rig.mesh;
    const Eigen::Index nt = target->mesh.vertexCount();
    ASSERT_EQ(out.vertexCount(), nt + result->report.uv_seam_vertices);
    EXPECT_GT(result->report.uv_seam_vertices, 50);
    double widest = 0.0;
    for (Eigen::Index f = 0; f < out.triangleCount(); ++f) widest = std::max(widest, span(out.uvs, out.triangles, f));
    std::vector<double> errors;
    if (name == "id_s01") {
      for (Eigen::Index f = 0; f < out.triangleCount(); ++f) {
        for (int k = 0; k < 3; ++k) errors.push_back((out.uvs.row(out.triangles(f, k)) - uv->rig.mesh.uvs.row(uv_tris(f, k))).norm());
      }
      std::sort(errors.begin(), errors.end());
    }
    std::printf("[ %-28s ] UVs: %d vertices added at seams (%d extended), widest triangle %.3f (the layout's %.3f)\n",
                name.c_str(), result->report.uv_seam_vertices, result->report.uv_extended_vertices, widest, layout_span);
    EXPECT_LT(widest, 2.0 * layout_span) << name;
    if (!errors.empty()) {
      const double p99 = errors[errors.size() * 99 / 100];
      std::printf("[ %-28s ] UVs: corner error against the layout's own: median %.4f, p99 %.4f\n", name.c_str(),
                  errors[errors.size() / 2], p99);
      EXPECT_LT(p99, 0.05) << name;
    }
  }

  // The identity already split at the layout's seams (its export's own UV
  // copies): each copy takes its own side, so the layout comes back vertex
  // for vertex and hardly any vertex needs a further copy.
  auto identity = core::readMesh(data / "ict" / "targets" / "id_s01.glb");
  auto landmarks = core::readLandmarks(data / "ict" / "targets" / "id_s01.landmarks.json");
  ASSERT_TRUE(identity && landmarks);
  const core::Mesh split = splitAtUvSeams(uv->rig.mesh, ict, identity->mesh);
  auto result = core::transferRig(*source, split, landmarksByPosition(*landmarks, identity->mesh, "id_s01"), "id_s01 split",
                                  options);
  ASSERT_TRUE(result) << result.error().message;
  const core::Mesh& out = result->rig.mesh;
  std::vector<double> errors;
  for (Eigen::Index v = 0; v < split.vertexCount(); ++v) errors.push_back((out.uvs.row(v) - uv->rig.mesh.uvs.row(v)).norm());
  std::sort(errors.begin(), errors.end());
  double widest = 0.0;
  for (Eigen::Index f = 0; f < out.triangleCount(); ++f) widest = std::max(widest, span(out.uvs, out.triangles, f));
  std::printf("[ %-28s ] UVs onto the identity split at the layout's seams: %d vertices added, widest triangle %.3f, "
              "vertex error median %.4f, p99 %.4f\n",
              "id_s01 split", result->report.uv_seam_vertices, widest, errors[errors.size() / 2],
              errors[errors.size() * 99 / 100]);
  EXPECT_LT(widest, 2.0 * layout_span);
  EXPECT_LT(errors[errors.size() * 99 / 100], 0.05);
}

// Distance between the upper and lower inner-lip midpoints (papers 000 sec.
// 5.3.1) on `rig` posed by `clip` at 61 times over 0-2 s.
std::vector<double> innerLipGaps(const core::Rig& rig, const core::LandmarkSet& set, const core::Animation& clip) {
  auto at = [&](const char* n, const Eigen::MatrixX3d& posed) {
    const auto& l = set.landmarks[static_cast<std::size_t>(set.indexOf(n))];
    if (l.kind == core::LandmarkKind::kVertex) return Eigen::RowVector3d(posed.row(l.vertex));
    Eigen::RowVector3d p = Eigen::RowVector3d::Zero();
    for (int k = 0; k < 3; ++k) p += l.barycentric(k) * posed.row(rig.mesh.triangles(l.face, k));
    return p;
  };
  std::vector<double> gaps;
  for (int k = 0; k <= 60; ++k) {
    const Eigen::MatrixX3d posed = core::poseMesh(rig, core::samplePose(rig, clip, k / 30.0));
    gaps.push_back((at("mouth_inner_2", posed) - at("mouth_inner_6", posed)).norm());
  }
  return gaps;
}

// The ICT rig's "jaw_open_head_turn" (the data's manifest names it).
std::size_t jawClipIndex(const core::Rig& rig) {
  for (std::size_t a = 0; a < rig.animations.size(); ++a) {
    if (rig.animations[a].name == "jaw_open_head_turn") return a;
  }
  ADD_FAILURE() << "no clip jaw_open_head_turn";
  return 0;
}
const core::Animation& jawClip(const core::Rig& rig) { return rig.animations[jawClipIndex(rig)]; }

TEST(IctTransferAnimation, MouthStrainFollowsTheSourceOverTheSkinnedClip) {
  // Papers 000 sec. 5.3.1: eps = (l1 - l0) / l0 with l the distance between
  // the upper and lower inner-lip midpoints on the posed mesh.
  RIGPORT_REQUIRE_SHARED_DATA(data);
  const core::PreparedRig* source = ictRig(data);
  ASSERT_NE(source, nullptr);
  const core::Rig& s = source->rig;
  const std::vector<double> ls = innerLipGaps(s, source->surface.landmarks, jawClip(s));
  for (const std::string name : {"id_s02", "stylized_s01_cartoon", "id_s02_remesh", "stylized_s01_cartoon_remesh"}) {
    auto target = core::readMesh(data / "ict" / "targets" / (name + ".glb"));
    auto landmarks = core::readLandmarks(data / "ict" / "targets" / (name + ".landmarks.json"));
    ASSERT_TRUE(target && landmarks);
    auto out = core::transferRig(*source, target->mesh, *landmarks, name);
    ASSERT_TRUE(out) << out.error().message;
    const core::Rig& t = out->rig;
    const std::vector<double> lt = innerLipGaps(t, *landmarks, jawClip(t));
    const double l0s = ls.front(), l0t = lt.front();  // the clip starts at rest
    std::vector<double> es, et, os, ot;
    for (std::size_t k = 0; k < ls.size(); ++k) {
      es.push_back(ls[k] / l0s - 1);
      et.push_back(lt[k] / l0t - 1);
      os.push_back(ls[k] - l0s);
      ot.push_back((lt[k] - l0t) / out->report.global_scale);
    }
    const double opening_ratio = *std::max_element(ot.begin(), ot.end()) / *std::max_element(os.begin(), os.end());
    const Eigen::Map<Eigen::VectorXd> a(es.data(), static_cast<Eigen::Index>(es.size())), b(et.data(), static_cast<Eigen::Index>(et.size()));
    const Eigen::VectorXd ac = a.array() - a.mean(), bc = b.array() - b.mean();
    const double correlation = ac.dot(bc) / (ac.norm() * bc.norm());
    const double amplitude = (b.maxCoeff() - b.minCoeff()) / (a.maxCoeff() - a.minCoeff());
    std::printf("[ %-28s ] mouth strain correlation %.4f, strain amplitude ratio %.3f (rest gap source %.3f target %.3f), "
                "opening amplitude ratio (size-normalised) %.3f\n",
                name.c_str(), correlation, amplitude, l0s, l0t, opening_ratio);
    EXPECT_GE(correlation, 0.99);
    // The relative strain's amplitude depends on the rest gap, which differs
    // between identities (the ICT neutral's lips touch: 0.08 cm); the absolute
    // opening, normalised by face size, is what the transfer must preserve.
    EXPECT_NEAR(opening_ratio, 1.0, 0.1);
  }
}

TEST(IctTransferAnimation, JawExaggerationOpensTheMouthFarther) {
  // Papers 000 sec. 5.4.2: a percentage that exaggerates the movements. The
  // ICT jaw opens by rotation alone (18 degrees): at 1.5 the transferred
  // rig's lips move as the plain transfer's do with its jaw keys turned 27
  // degrees about the same axis.
  RIGPORT_REQUIRE_SHARED_DATA(data);
  const core::PreparedRig* source = ictRig(data);
  ASSERT_NE(source, nullptr);
  const std::string name = "id_s02_remesh";
  auto target = core::readMesh(data / "ict" / "targets" / (name + ".glb"));
  auto landmarks = core::readLandmarks(data / "ict" / "targets" / (name + ".landmarks.json"));
  ASSERT_TRUE(target && landmarks);
  core::TransferOptions exaggerated;
  exaggerated.joint_exaggeration["jaw"] = 1.5;
  auto plain = core::transferRig(*source, target->mesh, *landmarks, name);
  auto more = core::transferRig(*source, target->mesh, *landmarks, name, exaggerated);
  ASSERT_TRUE(plain && more);

  core::Rig turned_farther = plain->rig;
  core::Animation& clip = turned_farther.animations[jawClipIndex(turned_farther)];
  int jaw_channels = 0;
  for (auto& c : clip.channels) {
    if (c.path != core::AnimationPath::kRotation || turned_farther.nodes[static_cast<std::size_t>(c.node)].name != "jaw") continue;
    ++jaw_channels;
    const Eigen::Quaterniond rest = turned_farther.nodes[static_cast<std::size_t>(c.node)].rotation;
    for (Eigen::Index k = 0; k < c.values.rows(); ++k) {
      const Eigen::AngleAxisd turn(rest.conjugate() * Eigen::Quaterniond(c.values(k, 3), c.values(k, 0), c.values(k, 1), c.values(k, 2)));
      c.values.row(k) = (rest * Eigen::Quaterniond(Eigen::AngleAxisd(1.5 * turn.angle(), turn.axis()))).coeffs().transpose();
    }
  }
  ASSERT_EQ(jaw_channels, 1);
  const std::vector<double> expected = innerLipGaps(turned_farther, *landmarks, jawClip(turned_farther));
  const std::vector<double> gaps = innerLipGaps(more->rig, *landmarks, jawClip(more->rig));
  const std::vector<double> before = innerLipGaps(plain->rig, *landmarks, jawClip(plain->rig));
  for (std::size_t k = 0; k < gaps.size(); ++k) EXPECT_NEAR(gaps[k], expected[k], 1e-9) << "sample " << k;
  const double ratio = (*std::max_element(gaps.begin(), gaps.end()) - gaps.front()) /
                       (*std::max_element(before.begin(), before.end()) - before.front());
  std::printf("[ %-28s ] widest opening with the jaw exaggerated 1.5x: %.3f times\n", name.c_str(), ratio);
  EXPECT_GT(ratio, 1.3);
  // The shapes were not asked to change.
  EXPECT_EQ(more->rig.morph_targets[0].position_deltas, plain->rig.morph_targets[0].position_deltas);
}

}  // namespace
