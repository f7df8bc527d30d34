// Tests the rig writer of core/io/gltf_rig_write.cpp (encodeRigGlb,
// writeRigGlb) on a hand-built rig: influence limits, weight encodings,
// labels and fields, sparse morph targets, determinism, the node the mesh
// hangs from, and the rigs it refuses.
#include "core/io/rig_io.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cstring>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <utility>
#include <vector>

#include "tests/core/io/rig_io_support.h"
#include "tests/gltf_builder.h"
#include "tests/test_support.h"

namespace {

using core::ErrorCode;
using core::LoadedRig;
using core::Rig;
using core::RigWriteOptions;
using core::WeightEncoding;
using namespace rigport_test::gltf;
using namespace rigport_test::rig_io;
using rigport_test::matricesNear;

// Element `i`, component `c` of an accessor with a bufferView (no sparse), as
// the raw integer or float the file holds.
double rawComponent(const json& doc, const ByteVector& bin, int accessor, std::size_t i, int c) {
  const json& a = doc["accessors"][accessor];
  const json& view = doc["bufferViews"][a["bufferView"].get<int>()];
  const int type = a["componentType"];
  const std::size_t size = type == kFloat ? 4 : type == kUnsignedShort ? 2 : 1;
  const std::size_t components = a["type"] == "SCALAR" ? 1 : a["type"] == "VEC2" ? 2 : a["type"] == "VEC3" ? 3 : 4;
  const std::size_t stride = view.value("byteStride", components * size);
  const std::size_t offset = view.value("byteOffset", 0) + a.value("byteOffset", 0) + i * stride + c * size;
  if (type == kFloat) {
    float f = 0;
    std::memcpy(&f, bin.data() + offset, 4);
    return f;
  }
  if (type == kUnsignedShort) return bin[offset] | bin[offset + 1] << 8;
  return bin[offset];
}

// The kept influences of vertex 0 (largest first) for `max_influences`.
std::map<int, double> expectedVertex0(int max_influences) {
  const double w0[kJoints] = {0.3, 0.25, 0.2, 0.1, 0.1, 0.05};
  std::map<int, double> kept;
  double sum = 0;
  for (int j = 0; j < std::min(max_influences, kJoints); ++j) sum += w0[j];  // already in rank order
  for (int j = 0; j < std::min(max_influences, kJoints); ++j) kept[j] = w0[j] / sum;
  return kept;
}

// ===========================================================================
// Writer rules on the hand-built rig

TEST(RigWrite, HandBuiltRigRoundTripsAndIsClean) {
  const Rig rig = makeRig();
  const ByteVector bytes = mustEncode(rig);
  const LoadedRig back = mustRead(bytes);
  Rig expected = rig;
  expected.weights = back.rig.weights;  // vertex 0 loses influences: checked below
  expectRigsEqual(expected, back.rig, false);
  EXPECT_EQ(back.report.warnings, std::vector<std::string>{});
  EXPECT_GLB_CLEAN(bytes, "hand_built");
}

// A 2 x 2 PNG (the writer embeds the bytes as they are).
const std::vector<std::uint8_t> kPng = {
    0x89, 0x50, 0x4e, 0x47, 0x0d, 0x0a, 0x1a, 0x0a, 0x00, 0x00, 0x00, 0x0d, 0x49, 0x48, 0x44, 0x52, 0x00, 0x00, 0x00,
    0x02, 0x00, 0x00, 0x00, 0x02, 0x08, 0x02, 0x00, 0x00, 0x00, 0xfd, 0xd4, 0x9a, 0x73, 0x00, 0x00, 0x00, 0x12, 0x49,
    0x44, 0x41, 0x54, 0x78, 0x9c, 0x63, 0xf8, 0xcf, 0xc0, 0xc0, 0x00, 0xc2, 0x0c, 0xff, 0x41, 0x00, 0x00, 0x26, 0xe8,
    0x06, 0xfa, 0x12, 0x40, 0x5f, 0xcc, 0x00, 0x00, 0x00, 0x00, 0x49, 0x45, 0x4e, 0x44, 0xae, 0x42, 0x60, 0x82};

// The hand-built rig with an unskinned part and materials: the face in two
// (one textured through both UV sets, with a sampler), the part in a third.
Rig makeRigWithMaterials() {
  Rig rig = makeRig();
  core::RigPart part;
  part.name = "plate";
  part.mesh = makeGridMesh();
  part.mesh.positions.col(2).array() += 0.5;
  part.node = static_cast<int>(rig.nodes.size());
  rig.nodes.push_back({"plate_node", -1, Eigen::Vector3d::Zero(), Eigen::Quaterniond::Identity(), Eigen::Vector3d::Ones()});
  rig.images.push_back({"albedo", "image/png", kPng});
  core::Material skin;
  skin.name = "skin";
  skin.base_color_factor << 0.8, 0.6, 0.5, 1.0;
  skin.base_color_texture = core::TextureBinding{};
  skin.base_color_texture->image = 0;
  skin.base_color_texture->sampler = {9729, 9987, 33071, 33648};
  skin.emissive_texture = core::TextureBinding{};  // (a normal texture would ask for TANGENTs)
  skin.emissive_texture->image = 0;
  skin.emissive_texture->texcoord = 1;
  skin.double_sided = true;
  core::Material lips;
  lips.name = "lips";
  lips.roughness_factor = 0.3;
  lips.alpha_mode = "MASK";
  lips.alpha_cutoff = 0.25;
  core::Material enamel;
  enamel.name = "enamel";
  enamel.emissive_factor << 0.1, 0.1, 0.0;
  enamel.occlusion_texture = core::TextureBinding{};
  enamel.occlusion_texture->image = 0;
  enamel.occlusion_texture->scale = 0.75;
  rig.materials = {skin, lips, enamel};
  rig.triangle_materials = {0, 1, 0, 1, 1, 0, -1, 0};  // one triangle without a material
  part.triangle_materials.assign(static_cast<std::size_t>(part.mesh.triangleCount()), 2);
  rig.parts.push_back(part);
  return rig;
}

TEST(RigWrite, MaterialsTexturesAndPartsRoundTripVertexForVertexAndAreClean) {
  const Rig rig = makeRigWithMaterials();
  const ByteVector bytes = mustEncode(rig);
  const LoadedRig back = mustRead(bytes);
  // A primitive per material, drawing the same vertices: read back as one mesh.
  EXPECT_EQ(back.rig.mesh.vertexCount(), rig.mesh.vertexCount());
  Rig expected = rig;
  expected.weights = back.rig.weights;  // vertex 0 loses influences (HandBuiltRigRoundTripsAndIsClean)
  // Triangles come back grouped by material in order of first use, each
  // group in its order.
  std::vector<Eigen::Index> order;
  for (const int m : {0, 1, -1}) {
    for (Eigen::Index f = 0; f < rig.mesh.triangleCount(); ++f) {
      if (rig.triangle_materials[static_cast<std::size_t>(f)] == m) order.push_back(f);
    }
  }
  for (std::size_t i = 0; i < order.size(); ++i) {
    expected.mesh.triangles.row(static_cast<Eigen::Index>(i)) = rig.mesh.triangles.row(order[i]);
    expected.triangle_materials[i] = rig.triangle_materials[static_cast<std::size_t>(order[i])];
  }
  expectRigsEqual(expected, back.rig, false);
  EXPECT_EQ(back.report.warnings, std::vector<std::string>{});
  EXPECT_GLB_CLEAN(bytes, "materials");
  // Written again, the file is the same: nothing drifts on a second round trip.
  EXPECT_EQ(mustEncode(back.rig), mustEncode(expected));
}

TEST(RigWrite, RejectsMaterialsThatWouldWriteAnInvalidFile) {
  auto message = [](const Rig& rig) {
    auto bytes = core::encodeRigGlb(rig);
    return bytes.ok() ? std::string("accepted") : bytes.error().message;
  };
  Rig rig = makeRigWithMaterials();
  rig.triangle_materials.pop_back();
  EXPECT_NE(message(rig).find("triangle_materials has 7 entries for 8 triangles"), std::string::npos) << message(rig);
  rig = makeRigWithMaterials();
  rig.parts[0].triangle_materials[3] = 7;
  EXPECT_NE(message(rig).find("part 0 'plate'"), std::string::npos) << message(rig);
  EXPECT_NE(message(rig).find("material 7"), std::string::npos) << message(rig);
  rig = makeRigWithMaterials();
  rig.materials[0].emissive_texture->texcoord = 2;
  EXPECT_NE(message(rig).find("reads TEXCOORD_2 but the mesh has 2 UV sets"), std::string::npos) << message(rig);
  rig = makeRigWithMaterials();
  rig.images[0].mime_type = "image/ktx2";
  EXPECT_NE(message(rig).find("image 0 'albedo'"), std::string::npos) << message(rig);
}

TEST(RigWrite, KeepsTheFourLargestInfluencesRenormalised) {
  const Rig rig = makeRig();
  const LoadedRig back = mustRead(mustEncode(rig));
  const std::map<int, double> kept = row(back.rig.weights, 0);
  const std::map<int, double> expected = expectedVertex0(4);  // tie 3 vs 4: the lower joint
  ASSERT_EQ(kept.size(), expected.size());
  for (const auto& [joint, w] : expected) EXPECT_NEAR(kept.at(joint), w, 1e-7) << "joint " << joint;
  // Other vertices: 3 influences (the repeated joint merged), unchanged.
  const Eigen::MatrixXd original = dense(rig.weights);
  const Eigen::MatrixXd read = dense(back.rig.weights);
  EXPECT_TRUE(matricesNear(original.bottomRows(original.rows() - 1), read.bottomRows(read.rows() - 1), 1e-7));
  EXPECT_EQ(row(back.rig.weights, 1).size(), 3u);
}

TEST(RigWrite, EightInfluencesUseASecondJointsWeightsSet) {
  const Rig rig = makeRig();
  RigWriteOptions options;
  options.max_influences = 8;
  const ByteVector bytes = mustEncode(rig, options);
  const auto [doc, bin] = splitGlb(bytes);
  const json& attributes = doc["meshes"][0]["primitives"][0]["attributes"];
  EXPECT_TRUE(attributes.contains("JOINTS_1"));
  EXPECT_TRUE(attributes.contains("WEIGHTS_1"));
  const LoadedRig back = mustRead(bytes);
  EXPECT_TRUE(matricesNear(dense(back.rig.weights), dense(rig.weights), 1e-7));
  EXPECT_GLB_CLEAN(bytes, "eight_influences");

  options.max_influences = 9;
  auto bad = core::encodeRigGlb(rig, options);
  ASSERT_FALSE(bad.ok());
  EXPECT_EQ(bad.error().code, ErrorCode::kInvalidArgument);
}

TEST(RigWrite, QuantisedWeightsSumExactlyPerVertex) {
  const Rig rig = makeRig();
  for (const auto& [encoding, scale] :
       {std::pair{WeightEncoding::kUnorm8, 255}, std::pair{WeightEncoding::kUnorm16, 65535}}) {
    SCOPED_TRACE(scale);
    for (const int max_influences : {4, 8}) {
      RigWriteOptions options;
      options.weight_encoding = encoding;
      options.max_influences = max_influences;
      const ByteVector bytes = mustEncode(rig, options);
      const auto [doc, bin] = splitGlb(bytes);
      const json& attributes = doc["meshes"][0]["primitives"][0]["attributes"];
      const int sets = attributes.contains("WEIGHTS_1") ? 2 : 1;
      EXPECT_EQ(sets, max_influences == 8 ? 2 : 1);
      for (std::size_t v = 0; v < static_cast<std::size_t>(rig.mesh.vertexCount()); ++v) {
        long total = 0;
        for (int s = 0; s < sets; ++s) {
          const int accessor = attributes["WEIGHTS_" + std::to_string(s)];
          EXPECT_TRUE(doc["accessors"][accessor].value("normalized", false));
          for (int c = 0; c < 4; ++c) total += static_cast<long>(rawComponent(doc, bin, accessor, v, c));
        }
        EXPECT_EQ(total, scale) << "vertex " << v;
      }
      const LoadedRig back = mustRead(bytes);
      const Eigen::MatrixXd read = dense(back.rig.weights);
      EXPECT_TRUE(matricesNear(read.rowwise().sum(), Eigen::VectorXd::Ones(read.rows()), 1e-12));
      Eigen::MatrixXd expected = dense(rig.weights);
      if (max_influences == 4) {
        expected.row(0).setZero();
        for (const auto& [joint, w] : expectedVertex0(4)) expected(0, joint) = w;
      }
      EXPECT_TRUE(matricesNear(read, expected, 1.0 / scale));
      EXPECT_GLB_CLEAN(bytes, "unorm" + std::to_string(scale) + "_" + std::to_string(max_influences));
    }
  }
}

TEST(RigWrite, FloatWeightsSumToOneInFloat) {
  const Rig rig = makeRig();
  const ByteVector bytes = mustEncode(rig);
  const auto [doc, bin] = splitGlb(bytes);
  const int accessor = doc["meshes"][0]["primitives"][0]["attributes"]["WEIGHTS_0"];
  for (std::size_t v = 0; v < static_cast<std::size_t>(rig.mesh.vertexCount()); ++v) {
    float sum = 0;
    for (int c = 0; c < 4; ++c) sum += static_cast<float>(rawComponent(doc, bin, accessor, v, c));
    EXPECT_EQ(sum, 1.0f) << "vertex " << v;
  }
}

TEST(RigWrite, EncodingIsDeterministic) {
  const Rig rig = makeRig();
  EXPECT_EQ(mustEncode(rig), mustEncode(rig));
  RigWriteOptions options;
  options.weight_encoding = WeightEncoding::kUnorm16;
  options.sparse_morph_targets = false;
  EXPECT_EQ(mustEncode(rig, options), mustEncode(rig, options));
}

TEST(RigWrite, LabelsAndFieldsRoundTrip) {
  const Rig rig = makeRig();
  const ByteVector bytes = mustEncode(rig);
  const auto [doc, bin] = splitGlb(bytes);
  const json& attributes = doc["meshes"][0]["primitives"][0]["attributes"];
  EXPECT_EQ(doc["accessors"][attributes["_PART"].get<int>()]["componentType"], kUnsignedShort);
  EXPECT_EQ(doc["accessors"][attributes["_SIDE"].get<int>()]["componentType"], kUnsignedByte);
  EXPECT_EQ(doc["accessors"][attributes["_OFFSET"].get<int>()]["type"], "VEC3");
  const LoadedRig back = mustRead(bytes);
  expectAttributesEqual(rig, back.rig);

  Rig negative = makeRig();
  negative.attributes.labels["SIDE"](3) = -1;
  auto error = core::encodeRigGlb(negative);
  ASSERT_FALSE(error.ok());
  EXPECT_EQ(error.error().code, ErrorCode::kInvalidArgument);
  EXPECT_NE(error.error().message.find("vertex 3"), std::string::npos) << error.error().message;
  negative.attributes.labels["SIDE"](3) = 70000;
  EXPECT_FALSE(core::encodeRigGlb(negative).ok());
}

TEST(RigWrite, MorphTargetsAreSparseWhenSmallerAndZeroTargetsHaveNoData) {
  const Rig rig = makeRig();
  const ByteVector bytes = mustEncode(rig);
  const auto [doc, bin] = splitGlb(bytes);
  const json& targets = doc["meshes"][0]["primitives"][0]["targets"];
  const json& smile = doc["accessors"][targets[0]["POSITION"].get<int>()];
  const json& flat = doc["accessors"][targets[1]["POSITION"].get<int>()];
  EXPECT_TRUE(smile.contains("sparse"));
  EXPECT_EQ(smile["sparse"]["count"], 2);
  EXPECT_EQ(smile["min"], json::array({-0.25, 0, 0}));  // implicit zeros included
  EXPECT_EQ(smile["max"], json::array({0, 0.125, 0.5}));
  EXPECT_FALSE(flat.contains("bufferView"));
  EXPECT_FALSE(flat.contains("sparse"));
  EXPECT_EQ(doc["meshes"][0]["extras"]["targetNames"], json::array({"smile", "flat"}));
  EXPECT_EQ(doc["meshes"][0]["weights"], json::array({0.25, 0}));

  RigWriteOptions dense_options;
  dense_options.sparse_morph_targets = false;
  const ByteVector dense_bytes = mustEncode(rig, dense_options);
  const auto [dense_doc, dense_bin] = splitGlb(dense_bytes);
  EXPECT_TRUE(
      dense_doc["accessors"][dense_doc["meshes"][0]["primitives"][0]["targets"][0]["POSITION"].get<int>()].contains(
          "bufferView"));
  expectMorphTargetsEqual(rig, mustRead(dense_bytes).rig);
  EXPECT_GLB_CLEAN(dense_bytes, "dense_morphs");
}

TEST(RigWrite, RejectsNegativeWeightsAndUnweightedVertices) {
  Rig rig = makeRig();
  rig.weights.coeffRef(5, 5) = -0.25;
  auto negative = core::encodeRigGlb(rig);
  ASSERT_FALSE(negative.ok());
  EXPECT_EQ(negative.error().code, ErrorCode::kInvalidArgument);
  EXPECT_NE(negative.error().message.find("vertex 5"), std::string::npos) << negative.error().message;

  rig = makeRig();
  for (core::SkinWeights::InnerIterator it(rig.weights, 4); it; ++it) it.valueRef() = 0.0;
  auto empty = core::encodeRigGlb(rig);
  ASSERT_FALSE(empty.ok());
  EXPECT_EQ(empty.error().code, ErrorCode::kInvalidArgument);
  EXPECT_NE(empty.error().message.find("vertex 4 "), std::string::npos) << empty.error().message;
}

TEST(RigWrite, RejectsAnInverseBindMatrixThatIsNotAffine) {
  Rig rig = makeRig();
  rig.skin->inverse_bind[2](3, 0) = 0.5;
  auto bytes = core::encodeRigGlb(rig);
  ASSERT_FALSE(bytes.ok());
  EXPECT_EQ(bytes.error().code, ErrorCode::kInvalidArgument);
  EXPECT_NE(bytes.error().message.find("joint 2"), std::string::npos) << bytes.error().message;

  rig = makeRig();
  rig.skin->inverse_bind[2](3, 0) = 1e-12;  // float noise: written as exactly 0 0 0 1
  const LoadedRig back = mustRead(mustEncode(rig));
  EXPECT_EQ(back.rig.skin->inverse_bind[2].row(3), Eigen::RowVector4d(0, 0, 0, 1));
}

TEST(RigWrite, RejectsBrokenHierarchiesAndAnimations) {
  Rig cycle = makeRig();
  cycle.nodes[1].parent = 7;  // root under the last joint
  auto bytes = core::encodeRigGlb(cycle);
  ASSERT_FALSE(bytes.ok());
  EXPECT_EQ(bytes.error().code, ErrorCode::kInvalidArgument);
  EXPECT_NE(bytes.error().message.find("cycle"), std::string::npos) << bytes.error().message;

  Rig bad_node = makeRig();
  bad_node.animations[0].channels[0].node = 42;
  bytes = core::encodeRigGlb(bad_node);
  ASSERT_FALSE(bytes.ok());
  EXPECT_NE(bytes.error().message.find("animation 0 'wave' channel 0"), std::string::npos) << bytes.error().message;

  Rig bad_parent = makeRig();
  bad_parent.nodes[1].parent = 99;
  bytes = core::encodeRigGlb(bad_parent);
  ASSERT_FALSE(bytes.ok());
  EXPECT_NE(bytes.error().message.find("node 1 'root' has parent 99"), std::string::npos) << bytes.error().message;

  Rig weights_elsewhere = makeRig();
  weights_elsewhere.animations[0].channels[2].node = 3;
  EXPECT_FALSE(core::encodeRigGlb(weights_elsewhere).ok());

  Rig bad_shape = makeRig();
  bad_shape.animations[0].channels[2].values.conservativeResize(4, 2);
  EXPECT_FALSE(core::encodeRigGlb(bad_shape).ok());

  Rig bad_times = makeRig();
  bad_times.animations[0].channels[0].times(2) = 0.5;
  EXPECT_FALSE(core::encodeRigGlb(bad_times).ok());
}

TEST(RigWrite, SkinnedMeshNodeIsWrittenAsAnIdentityRoot) {
  Rig rig = makeRig();
  rig.nodes[0].parent = 1;
  rig.nodes[0].translation = Eigen::Vector3d(1, 2, 3);
  const ByteVector bytes = mustEncode(rig);
  const LoadedRig back = mustRead(bytes);
  EXPECT_EQ(back.rig.mesh_node, 0);
  EXPECT_EQ(back.rig.nodes[0].parent, -1);
  EXPECT_EQ(back.rig.nodes[0].translation, Eigen::Vector3d::Zero());
  EXPECT_TRUE(matricesNear(back.rig.mesh.positions, rig.mesh.positions, 1e-6));  // bind space untouched
  EXPECT_GLB_CLEAN(bytes, "reset_mesh_node");

  // With a child, the node keeps its transform and the mesh moves to a new root.
  rig.nodes.push_back({"child", 0, Eigen::Vector3d(0, 1, 0), Eigen::Quaterniond::Identity(), Eigen::Vector3d::Ones()});
  const ByteVector appended = mustEncode(rig);
  const LoadedRig back2 = mustRead(appended);
  ASSERT_EQ(back2.rig.nodes.size(), rig.nodes.size() + 1);
  EXPECT_EQ(back2.rig.mesh_node, static_cast<int>(rig.nodes.size()));
  EXPECT_EQ(back2.rig.nodes[0].parent, 1);
  EXPECT_EQ(back2.rig.nodes[0].translation, Eigen::Vector3d(1, 2, 3));
  EXPECT_EQ(back2.rig.animations[0].channels[2].node, back2.rig.mesh_node);  // weights follow the mesh
  EXPECT_GLB_CLEAN(appended, "appended_mesh_node");
}

TEST(RigWrite, UnskinnedMeshUnderATransformedNodeStaysInWorldSpace) {
  Rig rig = makeRig();
  rig.skin.reset();
  rig.weights = core::SkinWeights();
  rig.nodes[0].parent = 1;
  rig.nodes[0].rotation = Eigen::Quaterniond(Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()));
  rig.nodes[0].scale = Eigen::Vector3d(2, 2, -2);  // mirrored: the winding flips on write and back on read
  const ByteVector bytes = mustEncode(rig);
  const LoadedRig back = mustRead(bytes);
  expectRigsEqual(rig, back.rig, false);
  EXPECT_GLB_CLEAN(bytes, "unskinned_transformed");

  rig.mesh_node = -1;  // no node: a root node is made for the mesh
  rig.animations.clear();
  const LoadedRig back2 = mustRead(mustEncode(rig));
  EXPECT_EQ(back2.rig.mesh_node, static_cast<int>(rig.nodes.size()));
  EXPECT_EQ(back2.rig.nodes.back().name, "grid");
  EXPECT_TRUE(matricesNear(back2.rig.mesh.positions, rig.mesh.positions, 1e-6));
}

TEST(RigWrite, WriteRigGlbThenReadRig) {
  const Rig rig = makeRig();
  const auto path = rigport_test::makeTempDir("write") / "rig.glb";
  ASSERT_TRUE(core::writeRigGlb(rig, path).ok());
  auto back = core::readRig(path);
  ASSERT_TRUE(back.ok()) << back.error().message;
  EXPECT_EQ(back->rig.morph_targets.size(), 2u);
  Rig bad = rig;
  bad.mesh_node = 99;
  auto status = core::writeRigGlb(bad, path);
  ASSERT_FALSE(status.ok());
  EXPECT_EQ(status.error().message.rfind("rig.glb: ", 0), 0u) << status.error().message;
}

TEST(RigWrite, ReadRigAcceptsGltfTextWithABufferFileBesideIt) {
  const Rig rig = makeRig();
  auto [doc, bin] = splitGlb(mustEncode(rig));
  const auto dir = rigport_test::makeTempDir("text");
  doc["buffers"][0]["uri"] = "rig.bin";
  std::ofstream(dir / "rig.gltf") << doc.dump();
  std::ofstream(dir / "rig.bin", std::ios::binary)
      .write(reinterpret_cast<const char*>(bin.data()), static_cast<std::streamsize>(bin.size()));
  auto back = core::readRig(dir / "rig.gltf");
  ASSERT_TRUE(back.ok()) << back.error().message;
  EXPECT_EQ(back->report.format, core::MeshFormat::kGltf);
  expectMorphTargetsEqual(rig, back->rig);
}

}  // namespace
