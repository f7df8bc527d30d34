// The pose JSON (parsePoseSpec): every key read, every error naming the file
// and the field; and poseRig on a four-vertex skinned rig: components, morph
// weights and joint rotations move what they drive and nothing else, the
// output is static, and unknown names are refused with "did you mean".
#include "core/components/pose_spec.h"

#include <array>
#include <cmath>

#include <gtest/gtest.h>

#include "core/components/bake.h"
#include "core/io/components_io.h"
#include "core/io/rig_io.h"
#include "core/rig/skinning.h"

namespace {

bool contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

// The error message of a spec that must fail to parse.
std::string parseError(const std::string& json) {
  auto spec = core::parsePoseSpec(json, "pose.json");
  EXPECT_FALSE(spec) << json;
  return spec ? std::string() : spec.error().message;
}

TEST(PoseSpec, ReadsEveryKey) {
  auto spec = core::parsePoseSpec(R"({"preset": "smile", "controls": {"smile": 0.5, "blink": 1},
                                      "morph_weights": {"jawOpen": 1}, "joints": {"jaw": [10, -5, 2.5]}})",
                                   "pose.json");
  ASSERT_TRUE(spec) << spec.error().message;
  EXPECT_EQ(spec->preset, "smile");
  EXPECT_EQ(spec->controls, (std::map<std::string, double>{{"blink", 1.0}, {"smile", 0.5}}));
  EXPECT_EQ(spec->morph_weights, (std::map<std::string, double>{{"jawOpen", 1.0}}));
  ASSERT_EQ(spec->joint_rotations.size(), 1u);
  EXPECT_EQ(spec->joint_rotations.at("jaw"), Eigen::Vector3d(10.0, -5.0, 2.5));
}

TEST(PoseSpec, EmptyObjectIsTheRestPose) {
  auto spec = core::parsePoseSpec("{}", "pose.json");
  ASSERT_TRUE(spec) << spec.error().message;
  EXPECT_TRUE(spec->preset.empty());
  EXPECT_TRUE(spec->controls.empty() && spec->morph_weights.empty() && spec->joint_rotations.empty());
}

TEST(PoseSpec, EachErrorNamesTheFileAndTheField) {
  std::string message = parseError(R"({"morph_weight": {"jawOpen": 1}})");
  EXPECT_TRUE(contains(message, "pose.json: morph_weight: unknown key")) << message;
  EXPECT_TRUE(contains(message, "did you mean \"morph_weights\"")) << message;

  message = parseError(R"({"preset": 3})");
  EXPECT_TRUE(contains(message, "pose.json: preset: must be a non-empty string")) << message;
  message = parseError(R"({"preset": ""})");
  EXPECT_TRUE(contains(message, "pose.json: preset:")) << message;

  message = parseError(R"({"controls": [1, 2]})");
  EXPECT_TRUE(contains(message, "pose.json: controls: must be an object")) << message;
  message = parseError(R"({"controls": {"smile": "high"}})");
  EXPECT_TRUE(contains(message, "pose.json: controls.smile: must be a number")) << message;
  message = parseError(R"({"morph_weights": {"jawOpen": true}})");
  EXPECT_TRUE(contains(message, "pose.json: morph_weights.jawOpen: must be a number")) << message;
  message = parseError(R"({"morph_weights": {"": 1}})");
  EXPECT_TRUE(contains(message, "pose.json: morph_weights: an empty name")) << message;

  message = parseError(R"({"joints": {"jaw": [10, 0]}})");
  EXPECT_TRUE(contains(message, "pose.json: joints.jaw: must be [x, y, z]")) << message;
  message = parseError(R"({"joints": {"jaw": [10, null, 0]}})");
  EXPECT_TRUE(contains(message, "pose.json: joints.jaw[1]: must be a number")) << message;
  message = parseError(R"({"joints": {"jaw": 10}})");
  EXPECT_TRUE(contains(message, "pose.json: joints.jaw:")) << message;

  message = parseError("[1, 2, 3]");
  EXPECT_TRUE(contains(message, "pose.json: expected a JSON object")) << message;
  // JSON has no NaN or Inf: a number out of range is how one arrives.
  message = parseError(R"({"morph_weights": {"jawOpen": 1e400}})");
  EXPECT_TRUE(contains(message, "pose.json: not valid pose JSON")) << message;
  message = parseError(R"({"preset": )");
  EXPECT_TRUE(contains(message, "pose.json: not valid pose JSON")) << message;
}

// A quad in the XY plane: vertices 0, 1 (y = 0) on the root joint, 2, 3
// (y = 2) on the jaw joint at (0, 1, 0); morph target jawOpen moves vertex 3
// by +z. An unskinned part (a triangle, target jawOpen too) on the jaw node.
core::Rig quadRig() {
  core::Rig rig;
  rig.mesh.positions.resize(4, 3);
  rig.mesh.positions << 0, 0, 0, 1, 0, 0, 1, 2, 0, 0, 2, 0;
  rig.mesh.triangles.resize(2, 3);
  rig.mesh.triangles << 0, 1, 2, 0, 2, 3;
  rig.mesh_name = "face";
  core::Node root, jaw, face;
  root.name = "root";
  jaw.name = "jaw";
  jaw.parent = 0;
  jaw.translation = Eigen::Vector3d(0, 1, 0);
  face.name = "face";
  rig.nodes = {root, jaw, face};
  rig.mesh_node = 2;
  core::Skin skin;
  skin.joints = {0, 1};
  const std::vector<Eigen::Matrix4d> world = core::nodeWorldTransforms(rig.nodes);
  skin.inverse_bind = {world[0].inverse(), world[1].inverse()};
  rig.skin = skin;
  rig.weights.resize(4, 2);
  rig.weights.insert(0, 0) = 1.0;
  rig.weights.insert(1, 0) = 1.0;
  rig.weights.insert(2, 1) = 1.0;
  rig.weights.insert(3, 1) = 1.0;
  rig.weights.makeCompressed();
  core::MorphTarget jaw_open;
  jaw_open.name = "jawOpen";
  jaw_open.position_deltas = Eigen::MatrixX3d::Zero(4, 3);
  jaw_open.position_deltas(3, 2) = 0.5;
  rig.morph_targets = {jaw_open};
  rig.morph_default_weights = Eigen::VectorXd::Zero(1);

  core::RigPart tooth;
  tooth.name = "tooth";
  tooth.node = 1;
  tooth.mesh.positions.resize(3, 3);
  tooth.mesh.positions << 0, 1, 0.1, 0.5, 1, 0.1, 0, 1.5, 0.1;  // world space, as read
  tooth.mesh.triangles.resize(1, 3);
  tooth.mesh.triangles << 0, 1, 2;
  core::MorphTarget tooth_open = jaw_open;
  tooth_open.position_deltas = Eigen::MatrixX3d::Zero(3, 3);
  tooth_open.position_deltas(0, 1) = -0.25;
  tooth.morph_targets = {tooth_open};
  tooth.morph_default_weights = Eigen::VectorXd::Zero(1);
  rig.parts = {tooth};
  return rig;
}

// A cluster on vertex 1 raised by control "raise" (0.5 per unit), which also
// drives jawOpen by 0.25 per unit; preset "up" sets raise to 1.
core::ComponentsDocument quadComponents() {
  auto doc = core::parseComponents(R"({"format": "rigport.components", "version": 1,
      "clusters": [{"name": "corner", "pivot": {"vertex": 0}, "members": [{"vertex": 1}]}],
      "controls": [{"name": "raise", "range": [0, 2],
                    "drives": [{"cluster": "corner", "channel": "translate_y", "gain": 0.5},
                               {"morph": "jawOpen", "gain": 0.25}]}],
      "presets": {"up": {"controls": {"raise": 1}}}})",
                                   "quad.components.json");
  EXPECT_TRUE(doc) << doc.error().message;
  return doc ? *doc : core::ComponentsDocument{};
}

const core::PoseLabels kLabels{"pose.json", "quad.components.json"};

core::PoseSpec spec(const std::string& json) {
  auto parsed = core::parsePoseSpec(json, "pose.json");
  EXPECT_TRUE(parsed) << parsed.error().message;
  return parsed ? *parsed : core::PoseSpec{};
}

TEST(PoseRig, RestSpecGivesTheRestAndAStaticRig) {
  const core::ComponentsDocument doc = quadComponents();
  auto posed = core::poseRig(quadRig(), &doc, spec("{}"), kLabels);
  ASSERT_TRUE(posed) << posed.error().message;
  const core::Rig& rig = posed->rig;
  EXPECT_LT((rig.mesh.positions - quadRig().mesh.positions).norm(), 1e-12);
  EXPECT_EQ(posed->report.moved_face_vertices, 0);
  EXPECT_FALSE(rig.skin.has_value());
  EXPECT_EQ(rig.weights.size(), 0);
  EXPECT_TRUE(rig.morph_targets.empty() && rig.animations.empty());
  EXPECT_EQ(rig.mesh.normals.rows(), 4);
  EXPECT_NEAR(std::abs(rig.mesh.normals(0, 2)), 1.0, 1e-12);
  ASSERT_EQ(rig.parts.size(), 1u);
  EXPECT_TRUE(rig.parts[0].morph_targets.empty());
  EXPECT_EQ(rig.parts[0].weights.size(), 0);
  EXPECT_EQ(rig.nodes.size(), 3u);
  EXPECT_EQ(rig.mesh_node, 2);
  auto glb = core::encodeRigGlb(rig);
  EXPECT_TRUE(glb) << glb.error().message;
}

TEST(PoseRig, MorphWeightsMoveTheFaceAndThePartsTargetsOfThatName) {
  auto posed = core::poseRig(quadRig(), nullptr, spec(R"({"morph_weights": {"jawOpen": 0.5}})"), kLabels);
  ASSERT_TRUE(posed) << posed.error().message;
  Eigen::MatrixX3d expected = quadRig().mesh.positions;
  expected(3, 2) += 0.25;
  EXPECT_LT((posed->rig.mesh.positions - expected).norm(), 1e-12);
  EXPECT_EQ(posed->report.moved_face_vertices, 1);
  Eigen::MatrixX3d tooth = quadRig().parts[0].mesh.positions;
  tooth(0, 1) -= 0.125;
  EXPECT_LT((posed->rig.parts[0].mesh.positions - tooth).norm(), 1e-12);
}

TEST(PoseRig, JointRotationTurnsItsVerticesAndTheUnskinnedPartOnIt) {
  // 90 degrees about the jaw's X axis: y -> z about the jaw at (0, 1, 0).
  auto posed = core::poseRig(quadRig(), nullptr, spec(R"({"joints": {"jaw": [90, 0, 0]}})"), kLabels);
  ASSERT_TRUE(posed) << posed.error().message;
  const Eigen::MatrixX3d& p = posed->rig.mesh.positions;
  EXPECT_LT((p.topRows(2) - quadRig().mesh.positions.topRows(2)).norm(), 1e-12);  // on the root: still
  EXPECT_LT((p.row(2) - Eigen::RowVector3d(1, 1, 1)).norm(), 1e-12);
  EXPECT_LT((p.row(3) - Eigen::RowVector3d(0, 1, 1)).norm(), 1e-12);
  // The tooth's third corner, 0.5 above the jaw and 0.1 in front, turns to 0.5 in front, 0.1 below.
  EXPECT_LT((posed->rig.parts[0].mesh.positions.row(2) - Eigen::RowVector3d(0, 0.9, 0.5)).norm(), 1e-12);
  const Eigen::Quaterniond turned = posed->rig.nodes[1].rotation;
  EXPECT_NEAR(turned.angularDistance(Eigen::Quaterniond(Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitX()))), 0.0,
              1e-12);
}

TEST(PoseRig, PresetMovesTheClusterAndDrivesItsMorphWeight) {
  const core::ComponentsDocument doc = quadComponents();
  auto posed = core::poseRig(quadRig(), &doc, spec(R"({"preset": "up", "morph_weights": {"jawOpen": 0.5}})"), kLabels);
  ASSERT_TRUE(posed) << posed.error().message;
  Eigen::MatrixX3d expected = quadRig().mesh.positions;
  expected(1, 1) += 0.5;           // the cluster, raise = 1
  expected(3, 2) += 0.5 * 0.75;    // jawOpen: 0.5 given + 0.25 driven
  EXPECT_LT((posed->rig.mesh.positions - expected).norm(), 1e-12);
  EXPECT_DOUBLE_EQ(posed->report.morph_weights.at("jawOpen"), 0.75);
  EXPECT_DOUBLE_EQ(posed->report.control_values.at("raise"), 1.0);

  // Controls override the preset's values.
  posed = core::poseRig(quadRig(), &doc, spec(R"({"preset": "up", "controls": {"raise": 2}})"), kLabels);
  ASSERT_TRUE(posed) << posed.error().message;
  EXPECT_NEAR(posed->rig.mesh.positions(1, 1), 1.0, 1e-12);
  EXPECT_DOUBLE_EQ(posed->report.morph_weights.at("jawOpen"), 0.5);
}

// A part of one triangle (corners x, y, z row by row) on `node`, unskinned.
core::RigPart trianglePart(const std::string& name, int node, const std::array<double, 9>& corners) {
  core::RigPart part;
  part.name = name;
  part.node = node;
  part.mesh.positions = Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(corners.data());
  part.mesh.triangles.resize(1, 3);
  part.mesh.triangles << 0, 1, 2;
  return part;
}

TEST(PoseRig, AnOpenPartTouchingTheFaceRidesOnItsComponentsASolidOneDoesNot) {
  // A lash-like triangle hanging on face vertex 1 (which the preset raises
  // by 0.5), a closed tetrahedron touching the same vertex, and an open
  // sheet touching it but reaching far from the face (as gums in a mouth).
  core::Rig rig = quadRig();
  core::RigPart lash = trianglePart("lash", 0, {1.0, 0.0, 0.001, 1.02, 0.0, 0.02, 1.0, 0.03, 0.02});
  core::RigPart ball = lash;
  ball.name = "ball";
  ball.mesh.positions.resize(4, 3);
  ball.mesh.positions << 1.0, 0.0, 0.001, 1.3, 0.0, 0.3, 1.0, 0.3, 0.3, 1.3, 0.3, 0.6;
  ball.mesh.triangles.resize(4, 3);
  ball.mesh.triangles << 0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3;
  core::RigPart sheet = lash;
  sheet.name = "sheet";
  sheet.mesh.positions << 1.0, 0.0, 0.001, 1.5, 0.0, 0.5, 1.0, 0.5, 0.5;
  rig.parts.push_back(lash);
  rig.parts.push_back(ball);
  rig.parts.push_back(sheet);
  const core::ComponentsDocument doc = quadComponents();
  auto posed = core::poseRig(rig, &doc, spec(R"({"preset": "up"})"), kLabels);
  ASSERT_TRUE(posed) << posed.error().message;
  ASSERT_EQ(posed->rig.parts.size(), 4u);
  const Eigen::MatrixX3d lash_motion = posed->rig.parts[1].mesh.positions - lash.mesh.positions;
  for (Eigen::Index v = 0; v < 3; ++v) EXPECT_LT((lash_motion.row(v) - Eigen::RowVector3d(0, 0.5, 0)).norm(), 1e-12) << v;
  EXPECT_LT((posed->rig.parts[2].mesh.positions - ball.mesh.positions).norm(), 1e-12);
  EXPECT_LT((posed->rig.parts[3].mesh.positions - sheet.mesh.positions).norm(), 1e-12);
}

std::string poseError(const core::ComponentsDocument* doc, const std::string& json, core::Rig rig = quadRig()) {
  auto posed = core::poseRig(std::move(rig), doc, spec(json), kLabels);
  EXPECT_FALSE(posed) << json;
  return posed ? std::string() : posed.error().message;
}

TEST(PoseRig, AnAimedJointTurnsToItsTargetWithWhatItCarries) {
  // The jaw at (0, 1, 0) aims at a locator 5 in front of it; look_left moves
  // the locator 5 along +X: the jaw turns 45 degrees about +Y (its up).
  auto doc = core::parseComponents(R"({"format": "rigport.components", "version": 1,
      "locators": [{"name": "aim", "binding": {"position": [0, 1, 5]}}],
      "aim_constraints": [{"name": "jaw_aim", "constrained_joint": "jaw", "targets": [{"locator": "aim"}]}],
      "controls": [{"name": "look_left", "drives": [{"locator": "aim", "channel": "translate_x", "gain": 5}]}]})",
                                   "quad.components.json");
  ASSERT_TRUE(doc) << doc.error().message;
  auto rest = core::poseRig(quadRig(), &*doc, spec("{}"), kLabels);
  ASSERT_TRUE(rest) << rest.error().message;
  EXPECT_LT((rest->rig.mesh.positions - quadRig().mesh.positions).norm(), 1e-12);  // rest aim: no turn
  auto posed = core::poseRig(quadRig(), &*doc, spec(R"({"controls": {"look_left": 1}})"), kLabels);
  ASSERT_TRUE(posed) << posed.error().message;
  ASSERT_EQ(posed->report.joint_aims.count("jaw"), 1u);
  const double h = std::sqrt(0.5);
  const Eigen::MatrixX3d& p = posed->rig.mesh.positions;
  EXPECT_LT((p.row(2) - Eigen::RowVector3d(h, 2.0, -h)).norm(), 1e-12);  // (1, 1, 0) from the jaw, turned
  EXPECT_LT((p.row(3) - Eigen::RowVector3d(0.0, 2.0, 0.0)).norm(), 1e-12);  // on the axis: stays
  // The tooth on the jaw's node turns with it: (0, 0.5, 0.1) from the jaw -> (0.1 h, 0.5, 0.1 h).
  EXPECT_LT((posed->rig.parts[0].mesh.positions.row(2) - Eigen::RowVector3d(0.1 * h, 1.5, 0.1 * h)).norm(), 1e-12);

  // A joint the rig lacks is named.
  core::ComponentsDocument missing = *doc;
  missing.aim_constraints[0].constrained = "jaww";
  const std::string message = poseError(&missing, "{}");
  EXPECT_TRUE(contains(message, "aim_constraints[0] \"jaw_aim\": the rig has no joint \"jaww\" (did you mean \"jaw\"?)"))
      << message;
}

TEST(PoseRig, AJointCarriedByAClusterMovesWhatItCarriesAndTheFaceOnce) {
  // The chin cluster on vertices 2 and 3, pivot at the jaw joint (0, 1, 0), carries the jaw; "open"
  // turns it 90 degrees about +X: (x, y, z) from the pivot -> (x, -z, y).
  auto doc = core::parseComponents(R"({"format": "rigport.components", "version": 1,
      "clusters": [{"name": "chin", "pivot": {"position": [0, 1, 0]}, "members": [{"vertex": 2}, {"vertex": 3}],
                    "joint": "jaw"}],
      "controls": [{"name": "open", "drives": [{"cluster": "chin", "channel": "rotate_x", "gain": 90}]}],
      "presets": {"open": {"controls": {"open": 1}}}})",
                                   "quad.components.json");
  ASSERT_TRUE(doc) << doc.error().message;
  auto posed = core::poseRig(quadRig(), &*doc, spec(R"({"preset": "open"})"), kLabels);
  ASSERT_TRUE(posed) << posed.error().message;
  ASSERT_EQ(posed->report.carried_joints.count("jaw"), 1u);
  const Eigen::MatrixX3d& p = posed->rig.mesh.positions;
  // The face's vertices on the jaw turn once (by the cluster), not again by the jaw's skinning.
  EXPECT_LT((p.row(2) - Eigen::RowVector3d(1.0, 1.0, 1.0)).norm(), 1e-12);
  EXPECT_LT((p.row(3) - Eigen::RowVector3d(0.0, 1.0, 1.0)).norm(), 1e-12);
  EXPECT_LT((p.row(0) - quadRig().mesh.positions.row(0)).norm(), 1e-12);
  // The tooth on the jaw's node turns with the jaw: (0, 1, 0.1) -> (0, 0.9, 0), (0, 1.5, 0.1) -> (0, 0.9, 0.5).
  const Eigen::MatrixX3d& tooth = posed->rig.parts[0].mesh.positions;
  EXPECT_LT((tooth.row(0) - Eigen::RowVector3d(0.0, 0.9, 0.0)).norm(), 1e-12);
  EXPECT_LT((tooth.row(2) - Eigen::RowVector3d(0.0, 0.9, 0.5)).norm(), 1e-12);

  // Stubble on the chin around vertex 2, on the jaw's node or skinned to the jaw, rides on the face's
  // motion there, (0, -1, 1), and is not turned again by the carried jaw.
  core::Rig stubbly = quadRig();
  const core::RigPart on_node = trianglePart("stubble_on_node", 1, {1.0, 2.0, 0.001, 0.99, 2.0, 0.002, 1.0, 1.99, 0.002});
  core::RigPart skinned = on_node;
  skinned.name = "stubble_skinned";
  skinned.weights.resize(3, 2);
  for (int v = 0; v < 3; ++v) skinned.weights.insert(v, 1) = 1.0;
  skinned.weights.makeCompressed();
  stubbly.parts.push_back(on_node);
  stubbly.parts.push_back(skinned);
  auto stubble = core::poseRig(stubbly, &*doc, spec(R"({"preset": "open"})"), kLabels);
  ASSERT_TRUE(stubble) << stubble.error().message;
  const Eigen::RowVector3d chin_motion(0.0, -1.0, 1.0);
  for (std::size_t s = 1; s < 3; ++s) {
    const Eigen::MatrixX3d motion = stubble->rig.parts[s].mesh.positions - stubbly.parts[s].mesh.positions;
    for (Eigen::Index v = 0; v < 3; ++v) {
      EXPECT_LT((motion.row(v) - chin_motion).norm(), 1e-12) << stubbly.parts[s].name << " vertex " << v;
    }
  }
  // ... and so baked (held at the rest skeleton: the ride alone).
  auto stubbly_report = core::bakePresets(stubbly, *doc);
  ASSERT_TRUE(stubbly_report) << stubbly_report.error().message;
  for (std::size_t s = 1; s < 3; ++s) {
    ASSERT_EQ(stubbly.parts[s].morph_targets.size(), 1u) << stubbly.parts[s].name;
    const Eigen::MatrixX3d& deltas = stubbly.parts[s].morph_targets[0].position_deltas;
    for (Eigen::Index v = 0; v < 3; ++v) {
      EXPECT_LT((deltas.row(v) - chin_motion).norm(), 1e-12) << stubbly.parts[s].name << " vertex " << v;
    }
  }

  // Baked: the face's target holds the cluster's motion, the tooth gets a target of its own.
  core::Rig baked = quadRig();
  auto report = core::bakePresets(baked, *doc);
  ASSERT_TRUE(report) << report.error().message;
  EXPECT_LT((baked.morph_targets.back().position_deltas.row(2) - Eigen::RowVector3d(0.0, -1.0, 1.0)).norm(), 1e-12);
  ASSERT_EQ(baked.parts[0].morph_targets.size(), 2u);
  EXPECT_EQ(baked.parts[0].morph_targets[1].name, "open");
  EXPECT_LT((baked.parts[0].morph_targets[1].position_deltas.row(0) - Eigen::RowVector3d(0.0, -0.1, -0.1)).norm(), 1e-12);
  EXPECT_EQ(baked.parts[0].morph_default_weights.size(), 2);

  // A joint the rig lacks is named.
  core::ComponentsDocument missing = *doc;
  missing.clusters[0].joint = "jaww";
  const std::string message = poseError(&missing, "{}");
  EXPECT_TRUE(contains(message, "clusters[0] \"chin\": joint: the rig has no joint \"jaww\" (did you mean \"jaw\"?)"))
      << message;
}

TEST(PoseRig, UnknownNamesAreRefusedWithTheirField) {
  const core::ComponentsDocument doc = quadComponents();
  std::string message = poseError(&doc, R"({"preset": "upp"})");
  EXPECT_TRUE(contains(message, "pose.json: preset: unknown preset \"upp\" in quad.components.json")) << message;
  EXPECT_TRUE(contains(message, "did you mean \"up\"")) << message;
  message = poseError(&doc, R"({"controls": {"rasie": 1}})");
  EXPECT_TRUE(contains(message, "pose.json: controls.rasie: unknown control")) << message;
  EXPECT_TRUE(contains(message, "did you mean \"raise\"")) << message;
  message = poseError(&doc, R"({"morph_weights": {"jawOpn": 1}})");
  EXPECT_TRUE(contains(message, "pose.json: morph_weights.jawOpn: the rig has no morph target")) << message;
  EXPECT_TRUE(contains(message, "did you mean \"jawOpen\"")) << message;
  message = poseError(&doc, R"({"joints": {"jw": [1, 0, 0]}})");
  EXPECT_TRUE(contains(message, "pose.json: joints.jw: the rig has no joint")) << message;
  EXPECT_TRUE(contains(message, "did you mean \"jaw\"")) << message;

  message = poseError(nullptr, R"({"preset": "up"})");
  EXPECT_TRUE(contains(message, "pose.json: preset: needs a components document")) << message;
  message = poseError(nullptr, R"({"controls": {"raise": 1}})");
  EXPECT_TRUE(contains(message, "pose.json: controls: need a components document")) << message;

  // A control driving a morph target the rig lacks: named in the document's file.
  core::Rig no_shapes = quadRig();
  no_shapes.morph_targets.clear();
  no_shapes.morph_default_weights.resize(0);
  no_shapes.parts.clear();
  message = poseError(&doc, R"({"preset": "up"})", no_shapes);
  EXPECT_TRUE(contains(message, "quad.components.json: controls drive morph target \"jawOpen\"")) << message;
}

}  // namespace
