// The rig's other meshes (core/transfer/parts.h): a closed part moves as one
// rigid body whatever the dense map does to the space around it, an open one
// follows the map vertex by vertex; a transfer carries both by vertex index
// and writes them back, valid.
#include "core/transfer/parts.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <string>

#include "core/io/rig_io.h"
#include "core/solve/tps.h"
#include "tests/core/transfer/transfer_rigs.h"
#include "tests/test_support.h"

namespace {

using core::RigPart;

// A closed box (8 corners, 12 outward triangles) about `centre`.
core::Mesh box(const Eigen::Vector3d& centre, double half) {
  core::Mesh m;
  m.positions.resize(8, 3);
  for (int i = 0; i < 8; ++i) {
    m.positions.row(i) = (centre + half * Eigen::Vector3d(i & 1 ? 1 : -1, i & 2 ? 1 : -1, i & 4 ? 1 : -1)).transpose();
  }
  m.triangles.resize(12, 3);
  m.triangles << 0, 2, 1, 1, 2, 3, 4, 5, 6, 5, 7, 6, 0, 1, 4, 1, 5, 4, 2, 6, 3, 3, 6, 7, 0, 4, 2, 2, 4, 6, 1, 3, 5, 3, 7, 5;
  m.normals = core::computeVertexNormals(m.positions, m.triangles);
  return m;
}

// An open 3 x 3 sheet (a lash card) at height z.
core::Mesh sheet(double z) {
  core::Mesh m;
  m.positions.resize(9, 3);
  for (int i = 0; i < 9; ++i) m.positions.row(i) << 0.1 * (i % 3), 0.1 * (i / 3), z;
  m.triangles.resize(8, 3);
  int t = 0;
  for (int r = 0; r < 2; ++r) {
    for (int c = 0; c < 2; ++c) {
      const int v = 3 * r + c;
      m.triangles.row(t++) << v, v + 1, v + 4;
      m.triangles.row(t++) << v, v + 4, v + 3;
    }
  }
  m.normals = core::computeVertexNormals(m.positions, m.triangles);
  return m;
}

// A map that bends space: a twist and a bulge fitted through a 4^3 grid.
core::TpsWarp bendingMap() {
  Eigen::MatrixX3d from(64, 3), to(64, 3);
  int i = 0;
  for (int x = 0; x < 4; ++x) {
    for (int y = 0; y < 4; ++y) {
      for (int z = 0; z < 4; ++z, ++i) {
        const Eigen::Vector3d p(x - 1.5, y - 1.5, z - 1.5);
        from.row(i) = p.transpose();
        to.row(i) = (1.3 * p + Eigen::Vector3d(0.2 * p.y() * p.z(), 0.1 * p.x() * p.x(), 0.5)).transpose();
      }
    }
  }
  auto map = core::fitTps(from, to);
  EXPECT_TRUE(map) << (map ? "" : map.error().message);
  return std::move(*map);
}

RigPart withShape(std::string name, core::Mesh mesh) {
  RigPart part;
  part.name = std::move(name);
  part.mesh = std::move(mesh);
  core::MorphTarget t;
  t.name = "look";
  t.position_deltas = Eigen::MatrixX3d::Zero(part.mesh.vertexCount(), 3);
  t.position_deltas(0, 0) = 0.05;
  part.morph_targets.push_back(t);
  part.morph_default_weights = Eigen::VectorXd::Zero(1);
  return part;
}

TEST(CarryParts, AClosedPartMovesAsOneBodyAndAnOpenOneFollowsTheMap) {
  const core::TpsWarp map = bendingMap();
  const std::vector<RigPart> parts = {withShape("eyeball", box(Eigen::Vector3d(0.3, -0.2, 0.4), 0.4)),
                                      withShape("lashes", sheet(0.2))};
  EXPECT_TRUE(core::isSolid(parts[0].mesh));
  EXPECT_FALSE(core::isSolid(parts[1].mesh));
  const core::CarriedParts out =
      core::carryParts(parts, map, [](const Eigen::Vector3d&) { return Eigen::Matrix3d::Identity(); }, Eigen::Matrix3d::Identity());
  ASSERT_EQ(out.parts.size(), 2u);
  EXPECT_TRUE(out.report[0].rigid);
  EXPECT_FALSE(out.report[1].rigid);

  // The box: every distance scaled by one factor (it stays a box), the map
  // did bend it (residual), and its shape's delta scaled with it.
  const Eigen::MatrixX3d& a = parts[0].mesh.positions;
  const Eigen::MatrixX3d& b = out.parts[0].mesh.positions;
  const double scale = out.report[0].scale;
  EXPECT_GT(out.report[0].fit_residual, 1e-3);
  for (int i = 0; i < 8; ++i) {
    for (int j = i + 1; j < 8; ++j) {
      EXPECT_NEAR((b.row(i) - b.row(j)).norm(), scale * (a.row(i) - a.row(j)).norm(), 1e-9) << i << "-" << j;
    }
  }
  EXPECT_NEAR(out.parts[0].morph_targets[0].position_deltas.row(0).norm(), scale * 0.05, 1e-9);
  EXPECT_TRUE((out.parts[0].mesh.triangles.array() == parts[0].mesh.triangles.array()).all());

  // The sheet: each vertex where the map puts it.
  EXPECT_TRUE(rigport_test::matricesNear(out.parts[1].mesh.positions, map.apply(parts[1].mesh.positions), 1e-12));
  EXPECT_NEAR(out.parts[1].mesh.normals.row(4).norm(), 1.0, 1e-12);
}

// The synthetic source rig with an eyeball-like box by the left eye,
// skinned to the head joint, and a lash sheet.
core::Rig rigWithEyeballAndLashes() {
  using namespace rigport_test::transfer;
  core::Rig rig = sourceRig().rig;
  const core::Landmark* eye = nullptr;
  for (const auto& l : sourceRig().landmarks.landmarks) {
    if (l.name == "eye_L_outer" || (eye == nullptr && l.name.rfind("eye", 0) == 0)) eye = &l;
  }
  EXPECT_NE(eye, nullptr);
  if (eye == nullptr) return rig;
  const Eigen::Vector3d at = eye->kind == core::LandmarkKind::kVertex ? Eigen::Vector3d(rig.mesh.positions.row(eye->vertex).transpose())
                                                                      : eye->position;
  const double size = 0.01 * core::boundingBoxDiagonal(rig.mesh.positions);
  RigPart eyeball = withShape("eyeball_L", box(at - Eigen::Vector3d(0, 0, 2 * size), size));
  RigPart lashes = withShape("lashes_L", sheet(0.0));
  lashes.mesh.positions = (lashes.mesh.positions * size * 5).rowwise() + at.transpose();
  for (RigPart* part : {&eyeball, &lashes}) {
    part->node = static_cast<int>(rig.nodes.size());
    core::Node node;
    node.name = part->name;
    rig.nodes.push_back(node);
    std::vector<Eigen::Triplet<double>> w;
    for (Eigen::Index v = 0; v < part->mesh.vertexCount(); ++v) w.emplace_back(static_cast<int>(v), 0, 1.0);
    part->weights.resize(part->mesh.vertexCount(), static_cast<Eigen::Index>(rig.skin->joints.size()));
    part->weights.setFromTriplets(w.begin(), w.end());
    rig.parts.push_back(*part);
  }
  return rig;
}

TEST(CarryParts, ATransferCarriesTheRigsOtherMeshesAndWritesThemValid) {
  using namespace rigport_test::transfer;
  const core::Rig rig = rigWithEyeballAndLashes();
  ASSERT_EQ(rig.parts.size(), 2u);
  auto prepared = core::prepareRig(rig, sourceRig().landmarks, "source");
  ASSERT_TRUE(prepared) << prepared.error().message;
  const core::SyntheticRig& target = otherHead();
  auto out = core::transferRig(*prepared, target.rig.mesh, target.landmarks, "other head");
  ASSERT_TRUE(out) << out.error().message;
  ASSERT_EQ(out->rig.parts.size(), 2u);
  ASSERT_EQ(out->report.parts.size(), 2u);
  EXPECT_TRUE(out->report.parts[0].rigid);
  EXPECT_FALSE(out->report.parts[1].rigid);
  for (std::size_t p = 0; p < 2; ++p) {
    const RigPart& carried = out->rig.parts[p];
    EXPECT_EQ(carried.name, rig.parts[p].name);
    EXPECT_EQ(carried.node, rig.parts[p].node);
    EXPECT_TRUE((carried.mesh.triangles.array() == rig.parts[p].mesh.triangles.array()).all());
    EXPECT_EQ((carried.weights - rig.parts[p].weights).norm(), 0.0);
    EXPECT_EQ(carried.morph_targets.size(), 1u);
    EXPECT_FALSE(carried.mesh.positions.isApprox(rig.parts[p].mesh.positions)) << carried.name << " moved with the face";
  }
  const auto path = rigport_test::makeTempDir("carry_parts") / "with_parts.glb";
  const auto written = core::writeRigGlb(out->rig, path);
  ASSERT_TRUE(written) << written.error().message;
  EXPECT_GLTF_VALID(path);
  auto back = core::readRig(path);
  ASSERT_TRUE(back) << back.error().message;
  EXPECT_EQ(back->rig.parts.size(), 2u);
}

// A 2 x 2 PNG: the bytes of a texture are carried, never decoded.
const std::vector<std::uint8_t> kPng = {
    0x89, 0x50, 0x4e, 0x47, 0x0d, 0x0a, 0x1a, 0x0a, 0x00, 0x00, 0x00, 0x0d, 0x49, 0x48, 0x44, 0x52, 0x00, 0x00, 0x00,
    0x02, 0x00, 0x00, 0x00, 0x02, 0x08, 0x02, 0x00, 0x00, 0x00, 0xfd, 0xd4, 0x9a, 0x73, 0x00, 0x00, 0x00, 0x12, 0x49,
    0x44, 0x41, 0x54, 0x78, 0x9c, 0x63, 0xf8, 0xcf, 0xc0, 0xc0, 0x00, 0xc2, 0x0c, 0xff, 0x41, 0x00, 0x00, 0x26, 0xe8,
    0x06, 0xfa, 0x12, 0x40, 0x5f, 0xcc, 0x00, 0x00, 0x00, 0x00, 0x49, 0x45, 0x4e, 0x44, 0xae, 0x42, 0x60, 0x82};

TEST(CarryParts, ATransferKeepsThePartsMaterialsAndCarriesTheFacesToTheTargetsTriangles) {
  using namespace rigport_test::transfer;
  core::Rig rig = rigWithEyeballAndLashes();
  ASSERT_EQ(rig.parts.size(), 2u);
  // Face: left and right halves in two materials, the right one textured;
  // eyeball: a glossy material; lashes: none.
  rig.images.push_back({"skin_albedo", "image/png", kPng});
  core::Material left;
  left.name = "skin_left";
  left.base_color_factor << 0.9, 0.6, 0.5, 1.0;
  core::Material right;
  right.name = "skin_right";
  right.roughness_factor = 0.4;
  right.base_color_texture = core::TextureBinding{};
  right.base_color_texture->image = 0;
  core::Material eye;
  eye.name = "eye";
  eye.metallic_factor = 0.0;
  rig.materials = {left, right, eye};
  const double mid = rig.mesh.positions.col(0).mean();
  auto side_of = [&](const core::Mesh& mesh, Eigen::Index f) {
    double x = 0;
    for (int k = 0; k < 3; ++k) x += mesh.positions(mesh.triangles(f, k), 0) / 3;
    return x < mid ? 0 : 1;
  };
  for (Eigen::Index f = 0; f < rig.mesh.triangleCount(); ++f) rig.triangle_materials.push_back(side_of(rig.mesh, f));
  rig.parts[0].triangle_materials.assign(static_cast<std::size_t>(rig.parts[0].mesh.triangleCount()), 2);

  auto prepared = core::prepareRig(rig, sourceRig().landmarks, "source");
  ASSERT_TRUE(prepared) << prepared.error().message;
  const core::SyntheticRig& target = otherHead();
  auto out = core::transferRig(*prepared, target.rig.mesh, target.landmarks, "other head");
  ASSERT_TRUE(out) << out.error().message;
  const core::Rig& result = out->rig;
  EXPECT_EQ(result.parts[0].triangle_materials, rig.parts[0].triangle_materials);
  EXPECT_TRUE(result.parts[1].triangle_materials.empty());
  // The face: the target's triangles, each in the material of where it lies
  // on the source (both heads are centred on x = 0 by construction).
  ASSERT_EQ(static_cast<Eigen::Index>(result.triangle_materials.size()), result.mesh.triangleCount());
  const double target_mid = result.mesh.positions.col(0).mean();
  int agree = 0;
  int off_midline = 0;
  for (Eigen::Index f = 0; f < result.mesh.triangleCount(); ++f) {
    double x = 0;
    for (int k = 0; k < 3; ++k) x += result.mesh.positions(result.mesh.triangles(f, k), 0) / 3;
    if (std::abs(x - target_mid) < 0.02 * core::boundingBoxDiagonal(result.mesh.positions)) continue;
    ++off_midline;
    agree += result.triangle_materials[static_cast<std::size_t>(f)] == (x < target_mid ? 0 : 1);
  }
  ASSERT_GT(off_midline, 100);
  EXPECT_EQ(agree, off_midline) << "triangles away from the midline in the other side's material";
  // The texture is laid out on the source's UVs: the face's material keeps
  // its factors without it, and the image nothing uses any more is dropped.
  ASSERT_EQ(result.materials.size(), 3u);
  EXPECT_EQ(result.materials[1].name, "skin_right");
  EXPECT_FALSE(result.materials[1].base_color_texture.has_value());
  EXPECT_DOUBLE_EQ(result.materials[1].roughness_factor, 0.4);
  EXPECT_TRUE(result.images.empty());
  const bool warned = std::any_of(out->report.warnings.begin(), out->report.warnings.end(), [](const std::string& w) {
    return w.find("skin_right") != std::string::npos && w.find("textures") != std::string::npos;
  });
  EXPECT_TRUE(warned);

  const auto path = rigport_test::makeTempDir("carry_materials") / "with_materials.glb";
  ASSERT_TRUE(core::writeRigGlb(result, path));
  EXPECT_GLTF_VALID(path);
  auto back = core::readRig(path);
  ASSERT_TRUE(back) << back.error().message;
  EXPECT_EQ(back->rig.mesh.vertexCount(), result.mesh.vertexCount());
  // (grouped into a primitive per material on the way: the same counts)
  auto counts = [](const std::vector<int>& materials) {
    std::map<int, int> n;
    for (const int m : materials) ++n[m];
    return n;
  };
  EXPECT_EQ(counts(back->rig.triangle_materials), counts(result.triangle_materials));
  ASSERT_EQ(back->rig.parts.size(), 2u);
  EXPECT_EQ(back->rig.parts[0].triangle_materials, result.parts[0].triangle_materials);
  ASSERT_EQ(back->rig.materials.size(), 3u);
  EXPECT_EQ(back->rig.materials[2].name, "eye");
  EXPECT_DOUBLE_EQ(back->rig.materials[2].metallic_factor, 0.0);
}

TEST(CarryParts, AWrittenPartWithWrongWeightsIsNamed) {
  using namespace rigport_test::transfer;
  core::Rig rig = sourceRig().rig;
  RigPart part = withShape("teeth", box(Eigen::Vector3d::Zero(), 0.1));
  part.node = static_cast<int>(rig.nodes.size());
  core::Node node;
  node.name = "teeth";
  rig.nodes.push_back(node);
  part.weights.resize(3, static_cast<Eigen::Index>(rig.skin->joints.size()));  // 3 rows for 8 vertices
  rig.parts.push_back(part);
  auto bytes = core::encodeRigGlb(rig);
  ASSERT_FALSE(bytes);
  EXPECT_NE(bytes.error().message.find("teeth"), std::string::npos) << bytes.error().message;
}

}  // namespace
