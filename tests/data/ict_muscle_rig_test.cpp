// The reference muscle rig (core/muscle_rig) on the ICT face
// (../shared/data/ict, MANIFEST.md there): it builds, rest is the identity,
// the expressions move the face the way they should, and its expressiveness:
// for each of the ICT face's 53 blend shapes, the bounded least-squares
// control values (box-constrained Gauss-Newton, finite differences over the
// controls) and the E they reach (docs/ACCURACY.md: E = sum_v |d_out - d_gt| /
// sum_v |d_gt|). The table is printed and recorded in docs/COMPONENTS.md.
// Skips when the data is absent.
#include <algorithm>
#include <cstdio>
#include <vector>

#include <gtest/gtest.h>

#include "core/components/bake.h"
#include "core/components/pose.h"
#include "core/components/pose_spec.h"
#include "core/io/landmarks.h"
#include "core/io/rig_io.h"
#include "core/muscle_rig/muscle_rig.h"
#include "core/rig/skinning.h"
#include "core/transfer/parts_occlusion.h"
#include "tests/core/muscle_rig/muscle_rig_fixture.h"
#include "tests/test_support.h"

namespace rigport_test {
namespace {

struct IctFace {
  core::Rig rig;
  core::LandmarkSet landmarks;
};

std::optional<IctFace> readIctFace(const std::filesystem::path& data, const char* file = "source_face.glb") {
  auto rig = core::readRig(data / "ict" / file);
  auto landmarks = core::readLandmarks(data / "ict/source_face.landmarks.json");
  EXPECT_TRUE(rig.ok() && landmarks.ok());
  if (!rig || !landmarks) return std::nullopt;
  return IctFace{rig->rig, *landmarks};
}

// The ICT full rig (face, eyeballs, teeth, gums, lashes) with the muscle rig
// built on it, its joints and the face's skin weights passed as
// `rigport muscle-rig` passes them.
struct IctFullMuscleRig {
  core::Rig rig;
  core::LandmarkSet landmarks;
  core::MuscleRigOptions options;
  core::MuscleRig muscle;
};

std::optional<IctFullMuscleRig> readIctFullMuscleRig(const std::filesystem::path& data) {
  auto full = readIctFace(data, "source_face_full.glb");
  if (!full) return std::nullopt;
  EXPECT_TRUE(full->rig.skin.has_value());
  core::MuscleRigOptions options;
  options.joints = core::namedNodeTransforms(full->rig);
  options.joint_weights = core::faceJointWeights(full->rig);
  auto muscle = core::buildMuscleRig(full->rig.mesh, full->landmarks, options);
  EXPECT_TRUE(muscle.ok()) << muscle.error().message;
  if (!muscle) return std::nullopt;
  return IctFullMuscleRig{std::move(full->rig), std::move(full->landmarks), std::move(options), std::move(*muscle)};
}

TEST(IctMuscleRig, BuildsRestsAndExpressesOnTheIctFace) {
  RIGPORT_REQUIRE_SHARED_DATA(data);
  const auto ict = readIctFace(data);
  ASSERT_TRUE(ict.has_value());
  auto rig = core::buildMuscleRig(ict->rig.mesh, ict->landmarks);
  ASSERT_TRUE(rig.ok()) << rig.error().message;
  auto rest = core::evaluatePose(ict->rig.mesh.positions, ict->rig.mesh.triangles, rig->components, {});
  ASSERT_TRUE(rest.ok());
  EXPECT_LT((rest->positions - ict->rig.mesh.positions).cwiseAbs().maxCoeff(), 1e-9);
  expectExpressionDirections(ict->rig.mesh, ict->landmarks, *rig);
}

TEST(IctMuscleRig, TheEyeballsLookWhereTheGazeGoesAndTheLidsFollow) {
  RIGPORT_REQUIRE_SHARED_DATA(data);
  const auto full = readIctFullMuscleRig(data);
  ASSERT_TRUE(full.has_value());
  int joint_aims = 0;
  for (const core::AimConstraint& aim : full->muscle.components.aim_constraints) joint_aims += aim.joint ? 1 : 0;
  EXPECT_EQ(joint_aims, 2);  // the ICT rig's two eye joints, found by position
  // The jaw joint is found at the hinge: the jaw cluster pivots on it with the face's own jaw weights.
  const auto& clusters = full->muscle.components.clusters;
  const core::Cluster& jaw = clusters[static_cast<std::size_t>(core::indexByName(clusters, "jaw"))];
  EXPECT_LT((jaw.pivot.position - full->options.joints.at("jaw").topRightCorner<3, 1>()).norm(), 1e-12);
  ASSERT_FALSE(jaw.members.empty());
  for (const core::ClusterMember& m : jaw.members) EXPECT_DOUBLE_EQ(m.weight, full->options.joint_weights.at("jaw")(m.vertex));
  core::PoseSpec look;
  look.controls = {{"look_left", 1.0}};
  auto rest = core::poseRig(full->rig, &full->muscle.components, {});
  auto posed = core::poseRig(full->rig, &full->muscle.components, look);
  ASSERT_TRUE(rest.ok() && posed.ok()) << (posed ? rest.error().message : posed.error().message);
  int eyeballs = 0;
  for (std::size_t p = 0; p < posed->rig.parts.size(); ++p) {
    const std::string& name = posed->rig.parts[p].name;
    if (name.find("eyeball") == std::string::npos) continue;
    ++eyeballs;
    const Eigen::MatrixX3d& before = rest->rig.parts[p].mesh.positions;
    const Eigen::MatrixX3d& after = posed->rig.parts[p].mesh.positions;
    // The front of the eye (largest z: glTF heads look down +Z) turns to the subject's left (+X), by about
    // 30 degrees of the eye's radius; the eyeball stays the same ball.
    Eigen::Index front = 0;
    before.col(2).maxCoeff(&front);
    EXPECT_GT(after(front, 0) - before(front, 0), 0.3) << name;
    for (const Eigen::Index anchor : {Eigen::Index{0}, front}) {  // rigid: distances within it kept
      const Eigen::VectorXd d_before = (before.rowwise() - before.row(anchor)).rowwise().norm();
      const Eigen::VectorXd d_after = (after.rowwise() - after.row(anchor)).rowwise().norm();
      EXPECT_LT((d_after - d_before).cwiseAbs().maxCoeff(), 1e-4) << name;
    }
  }
  EXPECT_EQ(eyeballs, 2);
  // The lids follow, less than the eye: the upper lid's landmark moves left by a fraction of the eye's front.
  const int lid = full->landmarks.landmarks[static_cast<std::size_t>(full->landmarks.indexOf("eye_left_1"))].vertex;
  const double lid_motion = posed->rig.mesh.positions(lid, 0) - rest->rig.mesh.positions(lid, 0);
  EXPECT_GT(lid_motion, 0.02);
  EXPECT_LT(lid_motion, 0.5);
}

TEST(IctMuscleRig, TheLowerTeethOpenWithTheJawTheUpperTeethAndTheFaceDoNotMoveTwice) {
  RIGPORT_REQUIRE_SHARED_DATA(data);
  const auto full = readIctFullMuscleRig(data);
  ASSERT_TRUE(full.has_value());
  const auto& clusters = full->muscle.components.clusters;
  const core::Cluster& jaw = clusters[static_cast<std::size_t>(core::indexByName(clusters, "jaw"))];
  EXPECT_EQ(jaw.joint, "jaw");  // the cluster carries the rig's jaw joint
  core::PoseSpec open;
  open.controls = {{"jaw_open", 1.0}};
  auto posed = core::poseRig(full->rig, &full->muscle.components, open);
  ASSERT_TRUE(posed.ok()) << posed.error().message;
  ASSERT_EQ(posed->report.carried_joints.count("jaw"), 1u);
  const Eigen::Affine3d motion(posed->report.carried_joints.at("jaw"));
  // The face is where the components put it: the jaw joint's skinning does not move it again.
  auto components = core::evaluatePose(full->rig.mesh.positions, full->rig.mesh.triangles, full->muscle.components, open.controls,
                                       core::jointPositionOptions(full->rig.nodes, full->rig.nodes));
  ASSERT_TRUE(components.ok()) << components.error().message;
  EXPECT_LT((posed->rig.mesh.positions - components->positions).cwiseAbs().maxCoeff(), 1e-6);
  // Teeth: what is skinned to the jaw alone moves as the cluster moves it; what the jaw does not carry stays.
  const auto& joints = full->rig.skin->joints;
  const auto jaw_column = std::find_if(joints.begin(), joints.end(),
                                       [&](int n) { return full->rig.nodes[static_cast<std::size_t>(n)].name == "jaw"; }) - joints.begin();
  ASSERT_LT(jaw_column, static_cast<std::ptrdiff_t>(joints.size()));
  int lower = 0, upper = 0;
  for (std::size_t p = 0; p < full->rig.parts.size(); ++p) {
    const core::RigPart& part = full->rig.parts[p];
    if (part.name != "teeth" || part.weights.rows() == 0) continue;
    const Eigen::MatrixXd weights(part.weights);
    for (Eigen::Index v = 0; v < part.mesh.positions.rows(); ++v) {
      const Eigen::Vector3d rest = part.mesh.positions.row(v).transpose();
      const Eigen::Vector3d now = posed->rig.parts[p].mesh.positions.row(v).transpose();
      if (weights(v, jaw_column) > 1.0 - 1e-6) {
        ++lower;
        EXPECT_LT((now - motion * rest).norm(), 1e-4) << "lower tooth vertex " << v;
      } else if (weights(v, jaw_column) < 1e-6) {
        ++upper;
        EXPECT_LT((now - rest).norm(), 1e-6) << "upper tooth vertex " << v;
      }
    }
  }
  EXPECT_GT(lower, 100);
  EXPECT_GT(upper, 100);
  // And the chin drops by centimetres.
  const int chin = full->landmarks.landmarks[static_cast<std::size_t>(full->landmarks.indexOf("jaw_08"))].vertex;
  const double chin_drop = full->rig.mesh.positions(chin, 1) - posed->rig.mesh.positions(chin, 1);
  EXPECT_GT(chin_drop, 1.0);

  // Baked, the parts the presets move get targets of their own: played at the rest skeleton, each mesh
  // shows what poseRig poses (surprise opens the jaw: teeth and gums; blink closes the lids: lashes).
  core::Rig baked = full->rig;
  auto report = core::bakePresets(baked, full->muscle.components, {"surprise", "blink"});
  ASSERT_TRUE(report.ok()) << report.error().message;
  for (const std::string preset : {"surprise", "blink"}) {
    core::PoseSpec spec;
    spec.preset = preset;
    auto truth = core::poseRig(full->rig, &full->muscle.components, spec);
    ASSERT_TRUE(truth.ok()) << truth.error().message;
    std::vector<std::string> moved;
    for (std::size_t p = 0; p < baked.parts.size(); ++p) {
      const core::Rig part = core::partAsRig(baked, baked.parts[p]);
      const int t = core::indexByName(part.morph_targets, preset);
      if (t < 0) continue;
      moved.push_back(part.mesh_name);
      core::Pose played{baked.nodes, Eigen::VectorXd::Zero(static_cast<Eigen::Index>(part.morph_targets.size()))};
      played.morph_weights(t) = 1.0;
      EXPECT_LT((core::poseMesh(part, played) - truth->rig.parts[p].mesh.positions).cwiseAbs().maxCoeff(), 1e-6)
          << preset << " " << part.mesh_name;
    }
    if (preset == "surprise") {
      EXPECT_NE(std::find(moved.begin(), moved.end(), "teeth"), moved.end()) << preset;
    } else {
      EXPECT_NE(std::find_if(moved.begin(), moved.end(), [](const std::string& n) { return n.find("eyelashes") == 0; }),
                moved.end()) << preset;
    }
  }
  const auto path = rigport_test::makeTempDir("ict_jaw_bake") / "baked.glb";
  ASSERT_TRUE(core::writeRigGlb(baked, path));
  EXPECT_GLTF_VALID(path);
}

// Eyeballs, teeth, gums and tongue stay behind the skin (the transfer's
// check, core/transfer/parts_occlusion.h) in every preset and in a full look
// each way with the jaw open: the eyelid and cornea sculptors hold the lids
// over a turned eye.
TEST(IctMuscleRig, EveryPresetKeepsTheInnerPartsBehindTheSkin) {
  RIGPORT_REQUIRE_SHARED_DATA(data);
  const auto full = readIctFullMuscleRig(data);
  ASSERT_TRUE(full.has_value());
  auto rest = core::poseRig(full->rig, &full->muscle.components, {});
  ASSERT_TRUE(rest.ok()) << rest.error().message;
  Eigen::MatrixX3d landmark_positions(static_cast<Eigen::Index>(full->landmarks.landmarks.size()), 3);
  Eigen::Vector3d toward = Eigen::Vector3d::Zero();
  for (std::size_t l = 0; l < full->landmarks.landmarks.size(); ++l) {
    const int v = full->landmarks.landmarks[l].vertex;
    landmark_positions.row(static_cast<Eigen::Index>(l)) = rest->rig.mesh.positions.row(v);
    toward += rest->rig.mesh.normals.row(v).transpose();
  }
  const core::SkinOcclusion skin(rest->rig.mesh, core::faceForward(landmark_positions, toward));
  auto inFront = [&](const core::PosedRig& posed) {
    std::vector<const Eigen::MatrixX3d*> parts;
    for (const core::RigPart& part : posed.rig.parts) parts.push_back(&part.mesh.positions);
    return core::partsInFront(skin, posed.rig.mesh.positions, parts);
  };
  const std::vector<int> at_rest = inFront(*rest);
  // The check sees a poke: the teeth pushed 1 cm forward stand in front of the lips.
  core::PosedRig pushed = *rest;
  for (core::RigPart& part : pushed.rig.parts) {
    if (part.name == "teeth") part.mesh.positions.rowwise() += skin.forward().transpose();
  }
  const std::vector<int> poked = inFront(pushed);
  for (std::size_t p = 0; p < poked.size(); ++p) {
    if (pushed.rig.parts[p].name == "teeth") {
      EXPECT_GT(poked[p], at_rest[p] + 10);
    }
  }
  std::vector<core::PoseSpec> poses;
  for (const auto& [preset, values] : full->muscle.components.presets) poses.push_back(core::PoseSpec{preset, {}, {}, {}});
  for (const char* look : {"look_left", "look_right", "look_up", "look_down"}) {
    poses.push_back(core::PoseSpec{"", {{look, 1.0}, {"jaw_open", 1.0}}, {}, {}});
  }
  for (const core::PoseSpec& spec : poses) {
    auto posed = core::poseRig(full->rig, &full->muscle.components, spec);
    ASSERT_TRUE(posed.ok()) << posed.error().message;
    const std::vector<int> now = inFront(*posed);
    std::string label = spec.preset;
    for (const auto& [control, value] : spec.controls) label += (label.empty() ? "" : " + ") + control;
    for (std::size_t p = 0; p < now.size(); ++p) {
      const std::string& name = posed->rig.parts[p].name;
      if (name.find("eyelashes") == 0) continue;  // lashes stand on the skin
      if (now[p] > 0) std::printf("%-24s %-12s %5d in front (rest %d)\n", label.c_str(), name.c_str(), now[p], at_rest[p]);
      // A full sideways look leaves a few eyeball vertices at the outer
      // corner up to ~2 mm in front (docs/COMPONENTS.md): at most 0.5%.
      const bool sideways = spec.controls.count("look_left") || spec.controls.count("look_right");
      const auto allowed = sideways ? static_cast<int>(0.005 * static_cast<double>(posed->rig.parts[p].mesh.positions.rows())) : 0;
      EXPECT_LE(now[p], at_rest[p] + allowed) << label << ": " << name;
    }
  }
}

// E of a displacement field against the truth (docs/ACCURACY.md).
double shapeError(const Eigen::MatrixX3d& out, const Eigen::MatrixX3d& truth) {
  const double denominator = truth.rowwise().norm().sum();
  return denominator > 0.0 ? (out - truth).rowwise().norm().sum() / denominator : 0.0;
}

// Fits bounded control values so the posed face best matches rest + target
// (least squares): Gauss-Newton steps, each solving the box-constrained
// linear problem by projected coordinate descent, Jacobian by forward
// differences; a step is kept only when it lowers the squared residual.
class ControlFit {
 public:
  ControlFit(const core::Mesh& face, const core::ComponentsDocument& doc) : face_(face), doc_(doc) {}

  Eigen::MatrixX3d displacement(const Eigen::VectorXd& x) const {
    std::map<std::string, double> values;
    for (std::size_t i = 0; i < doc_.controls.size(); ++i) values[doc_.controls[i].name] = x(static_cast<Eigen::Index>(i));
    auto pose = core::evaluatePose(face_.positions, face_.triangles, doc_, values);
    EXPECT_TRUE(pose.ok());
    return pose ? Eigen::MatrixX3d(pose->positions - face_.positions) : Eigen::MatrixX3d(face_.positions * 0.0);
  }

  Eigen::MatrixXd jacobian(const Eigen::VectorXd& x, const Eigen::MatrixX3d& at_x) const {
    const Eigen::Index n = x.size(), rows = at_x.size();
    Eigen::MatrixXd j(rows, n);
    for (Eigen::Index i = 0; i < n; ++i) {
      const core::Control& c = doc_.controls[static_cast<std::size_t>(i)];
      double h = 0.05 * (c.max - c.min);
      if (x(i) + h > c.max) h = -h;
      Eigen::VectorXd xh = x;
      xh(i) += h;
      const Eigen::MatrixX3d d = (displacement(xh) - at_x) / h;
      j.col(i) = Eigen::Map<const Eigen::VectorXd>(d.data(), rows);
    }
    return j;
  }

  Eigen::VectorXd fit(const Eigen::MatrixX3d& target, int iterations) const {
    const Eigen::Index n = static_cast<Eigen::Index>(doc_.controls.size());
    Eigen::VectorXd x = Eigen::VectorXd::Zero(n), lo(n), hi(n);
    for (Eigen::Index i = 0; i < n; ++i) {
      lo(i) = doc_.controls[static_cast<std::size_t>(i)].min;
      hi(i) = doc_.controls[static_cast<std::size_t>(i)].max;
    }
    const Eigen::Map<const Eigen::VectorXd> b(target.data(), target.size());
    Eigen::MatrixX3d at_x = displacement(x);
    double cost = (Eigen::Map<const Eigen::VectorXd>(at_x.data(), at_x.size()) - b).squaredNorm();
    double damping = 1e-3;
    for (int it = 0; it < iterations; ++it) {
      const Eigen::MatrixXd j = jacobian(x, at_x);
      const Eigen::VectorXd r = b - Eigen::Map<const Eigen::VectorXd>(at_x.data(), at_x.size());
      // min |J dx - r|^2 + lambda |D dx|^2, lo <= x + dx <= hi (Levenberg-Marquardt):
      // coordinate descent on the damped normal equations; a rejected step raises the damping.
      const Eigen::MatrixXd h = j.transpose() * j;
      const Eigen::VectorXd g = j.transpose() * r;
      bool improved = false;
      for (int attempt = 0; attempt < 6 && !improved; ++attempt, damping *= 10.0) {
        Eigen::MatrixXd damped = h;
        damped.diagonal() *= 1.0 + damping;
        Eigen::VectorXd dx = Eigen::VectorXd::Zero(n);
        for (int sweep = 0; sweep < 300; ++sweep) {
          for (Eigen::Index i = 0; i < n; ++i) {
            if (damped(i, i) <= 0.0) continue;
            const double step = (g(i) - damped.row(i).dot(dx)) / damped(i, i);
            dx(i) = std::clamp(dx(i) + step, lo(i) - x(i), hi(i) - x(i));
          }
        }
        const Eigen::VectorXd candidate = x + dx;
        const Eigen::MatrixX3d at_candidate = displacement(candidate);
        const double candidate_cost =
            (Eigen::Map<const Eigen::VectorXd>(at_candidate.data(), at_candidate.size()) - b).squaredNorm();
        if (candidate_cost < cost) {
          x = candidate;
          at_x = at_candidate;
          cost = candidate_cost;
          improved = true;
          damping = std::max(damping / 30.0, 1e-6);  // the *= 10 of the loop follows
        }
      }
      if (!improved) break;
    }
    return x;
  }

 private:
  const core::Mesh& face_;
  const core::ComponentsDocument& doc_;
};

TEST(IctMuscleRig, ExpressivenessAgainstTheIctBlendShapes) {
  RIGPORT_REQUIRE_SHARED_DATA(data);
  const auto ict = readIctFace(data);
  ASSERT_TRUE(ict.has_value());
  auto rig = core::buildMuscleRig(ict->rig.mesh, ict->landmarks);
  ASSERT_TRUE(rig.ok()) << rig.error().message;
  const ControlFit fitter(ict->rig.mesh, rig->components);
  std::vector<double> errors;
  std::printf("| shape | E | largest controls |\n|---|---|---|\n");
  for (const core::MorphTarget& shape : ict->rig.morph_targets) {
    const Eigen::VectorXd x = fitter.fit(shape.position_deltas, 6);
    const double e = shapeError(fitter.displacement(x), shape.position_deltas);
    errors.push_back(e);
    std::vector<std::pair<double, std::string>> used;
    for (Eigen::Index i = 0; i < x.size(); ++i) {
      if (x(i) > 0.05) used.push_back({x(i), rig->components.controls[static_cast<std::size_t>(i)].name});
    }
    std::sort(used.rbegin(), used.rend());
    std::string top;
    for (std::size_t k = 0; k < std::min<std::size_t>(3, used.size()); ++k) {
      char buffer[96];
      std::snprintf(buffer, sizeof buffer, "%s%s %.2f", k ? ", " : "", used[k].second.c_str(), used[k].first);
      top += buffer;
    }
    std::printf("| %s | %.3f | %s |\n", shape.name.c_str(), e, top.c_str());
    // Least squares minimises the squared residual, E sums its norms: for a
    // shape the rig cannot make (eye gaze: no eyeballs; cheek puff) the fit
    // may trade a little E for a lower squared error, never much.
    EXPECT_LT(e, 1.1) << shape.name << ": the fit is worse than doing nothing";
  }
  std::vector<double> sorted = errors;
  std::sort(sorted.begin(), sorted.end());
  const double median = sorted[sorted.size() / 2];
  std::printf("shapes %zu, median E %.3f, best %.3f, worst %.3f\n", sorted.size(), median, sorted.front(), sorted.back());
  EXPECT_EQ(errors.size(), 53u);
  EXPECT_LT(median, 0.85);  // measured 0.810 (docs/COMPONENTS.md)
}

}  // namespace
}  // namespace rigport_test
