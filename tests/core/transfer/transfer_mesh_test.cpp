// Tests core/transfer/transfer.cpp on what a target or source mesh comes
// with: vertices split at UV seams and hard edges, closed pieces no landmark
// is on (eyeballs), faces wound inside out and normals against the winding;
// normal deltas against a full recompute.
#include "core/transfer/transfer.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "core/geometry/mesh.h"
#include "core/io/landmarks.h"
#include "core/io/rig_io.h"
#include "tests/core/transfer/transfer_rigs.h"
#include "tests/test_support.h"

namespace {

using rigport_test::matricesNear;
using namespace rigport_test::transfer;

// The generated rig with normal deltas (those of its own mesh under each
// shape), prepared; and the other head its tests transfer it to.
const core::PreparedRig& preparedWithNormalDeltas() {
  static const core::PreparedRig prepared = [] {
    core::Rig rig = sourceRig().rig;
    const Eigen::MatrixX3d rest = core::computeVertexNormals(rig.mesh.positions, rig.mesh.triangles);
    for (auto& shape : rig.morph_targets) {
      shape.normal_deltas =
          core::computeVertexNormals(rig.mesh.positions + shape.position_deltas, rig.mesh.triangles) - rest;
    }
    auto p = core::prepareRig(rig, sourceRig().landmarks, "source with normal deltas");
    EXPECT_TRUE(p) << p.error().message;
    return std::move(*p);
  }();
  return prepared;
}
core::SyntheticRig headForNormalDeltas() {
  const core::HeadResolution res{.columns = 70, .rows = 66, .alternate_diagonals = true, .seed = 5};
  return core::generateRig(core::randomHeadShape(5, 0.2), res);
}

// `mesh` split down the middle (x = 0, lips included) as exporters split a
// mesh at a UV seam: the vertices of faces on both sides get a second copy
// (appended) for the faces on the +x side. Positions, normals and regions are
// copied; `pairs` lists (original, copy).
struct SplitMesh {
  core::Mesh mesh;
  std::vector<std::pair<Eigen::Index, Eigen::Index>> pairs;
};
SplitMesh splitDownTheMiddle(const core::Mesh& mesh) {
  SplitMesh out{mesh, {}};
  core::Mesh& split = out.mesh;
  std::vector<char> left(static_cast<std::size_t>(split.vertexCount()), 0), right(left.size(), 0);
  std::vector<char> right_face(static_cast<std::size_t>(split.triangles.rows()), 0);
  for (Eigen::Index f = 0; f < split.triangles.rows(); ++f) {
    double x = 0;
    for (int k = 0; k < 3; ++k) x += split.positions(split.triangles(f, k), 0);
    right_face[static_cast<std::size_t>(f)] = x > 0.0;
    for (int k = 0; k < 3; ++k) (x > 0.0 ? right : left)[static_cast<std::size_t>(split.triangles(f, k))] = 1;
  }
  std::vector<Eigen::Index> copy_of(left.size(), -1);
  const Eigen::Index n = split.vertexCount();
  for (Eigen::Index v = 0; v < n; ++v) {
    if (left[static_cast<std::size_t>(v)] && right[static_cast<std::size_t>(v)]) {
      copy_of[static_cast<std::size_t>(v)] = n + static_cast<Eigen::Index>(out.pairs.size());
      out.pairs.emplace_back(v, copy_of[static_cast<std::size_t>(v)]);
    }
  }
  const auto extra = static_cast<Eigen::Index>(out.pairs.size());
  split.positions.conservativeResize(n + extra, 3);
  split.normals.conservativeResize(n + extra, 3);
  split.regions.conservativeResize(n + extra);
  for (const auto& [v, c] : out.pairs) {
    split.positions.row(c) = split.positions.row(v);
    split.normals.row(c) = split.normals.row(v);
    split.regions(c) = split.regions(v);
  }
  for (Eigen::Index f = 0; f < split.triangles.rows(); ++f) {
    if (!right_face[static_cast<std::size_t>(f)]) continue;
    for (int k = 0; k < 3; ++k) {
      const Eigen::Index c = copy_of[static_cast<std::size_t>(split.triangles(f, k))];
      if (c >= 0) split.triangles(f, k) = static_cast<int>(c);
    }
  }
  return out;
}

// Exported meshes are split at UV seams and hard edges: one surface point,
// several vertices, each with only its side's faces and, at a hard edge, its
// own normal. Every copy must get the same weights and deltas, or the seam
// parts when the mesh moves. Here the head is split down the middle and made
// a hard edge whose copies' normals differ by 40 degrees, more than the 30
// that make a lone copy untrustworthy.
TEST(TransferRig, CopiesOfASplitPointTakeTheSameWeightsAndShapes) {
  const core::HeadResolution res{.columns = 70, .rows = 66, .alternate_diagonals = true, .jitter = 0.25, .seed = 9};
  core::SyntheticRig other = core::generateRig(core::randomHeadShape(9, 0.2), res);
  other.rig.mesh.normals = core::computeSeamlessVertexNormals(other.rig.mesh.positions, other.rig.mesh.triangles);
  SplitMesh cut = splitDownTheMiddle(other.rig.mesh);
  core::Mesh& split = cut.mesh;
  ASSERT_GT(cut.pairs.size(), 40u);
  const Eigen::Matrix3d hard = Eigen::AngleAxisd(40.0 * std::numbers::pi / 180.0, Eigen::Vector3d::UnitY()).toRotationMatrix();
  for (const auto& [v, c] : cut.pairs) split.normals.row(v) = split.normals.row(v) * hard.transpose();  // the lower-indexed copy's side turned
  auto result = core::transferRig(preparedSource(), split, other.landmarks, "split");
  ASSERT_TRUE(result) << result.error().message;
  const core::Rig& out = result->rig;
  const double diag = core::boundingBoxDiagonal(split.positions);
  double weight_gap = 0.0, delta_gap = 0.0;
  for (const auto& [v, c] : cut.pairs) {
    weight_gap = std::max(weight_gap, (Eigen::VectorXd(out.weights.row(v)) - Eigen::VectorXd(out.weights.row(c))).cwiseAbs().maxCoeff());
    for (const auto& t : out.morph_targets) delta_gap = std::max(delta_gap, (t.position_deltas.row(v) - t.position_deltas.row(c)).norm());
  }
  EXPECT_LT(weight_gap, 1e-9);
  EXPECT_LT(delta_gap, 1e-9 * diag);
  // The output keeps the split and each copy's own normal.
  EXPECT_EQ(out.mesh.triangles, split.triangles);
  EXPECT_TRUE(out.mesh.normals == split.normals);
}

// Under a shape, the two sides of a UV seam (copies with one normal) must
// shade as one surface: their normal deltas are those of the mesh's normals
// computed across the seam (computeSeamlessVertexNormals), not of each
// side's faces alone. The two sides of a hard edge (copies with their own
// normals) keep their own.
TEST(TransferRig, NormalDeltasShadeAUvSeamAsOneSurfaceAndKeepHardEdges) {
  const core::PreparedRig& prepared = preparedWithNormalDeltas();
  core::SyntheticRig target = headForNormalDeltas();
  target.rig.mesh.normals = core::computeSeamlessVertexNormals(target.rig.mesh.positions, target.rig.mesh.triangles);
  const SplitMesh seam = splitDownTheMiddle(target.rig.mesh);
  auto split = core::transferRig(prepared, seam.mesh, target.landmarks, "uv seam");
  ASSERT_TRUE(split) << split.error().message;
  const core::Mesh& mesh = seam.mesh;
  auto zeroed = [](Eigen::MatrixX3d d) {
    for (Eigen::Index v = 0; v < d.rows(); ++v) {
      if (d.row(v).cwiseAbs().maxCoeff() < 1e-12) d.row(v).setZero();
    }
    return d;
  };
  const Eigen::MatrixX3d base = core::computeSeamlessVertexNormals(mesh.positions, mesh.triangles);
  const Eigen::MatrixX3d base_apart = core::computeVertexNormals(mesh.positions, mesh.triangles);
  double apart_gap = 0.0;  // how far each side's own faces would be off at the seam
  for (const auto& shape : split->rig.morph_targets) {
    const Eigen::MatrixX3d moved = mesh.positions + shape.position_deltas;
    EXPECT_TRUE(shape.normal_deltas == zeroed(core::computeSeamlessVertexNormals(moved, mesh.triangles) - base))
        << shape.name;
    const Eigen::MatrixX3d apart = core::computeVertexNormals(moved, mesh.triangles) - base_apart;
    for (const auto& [v, c] : seam.pairs) {
      EXPECT_TRUE(shape.normal_deltas.row(v) == shape.normal_deltas.row(c)) << shape.name << " vertex " << v;
      apart_gap = std::max(apart_gap, (apart.row(c) - shape.normal_deltas.row(c)).norm());
    }
  }
  EXPECT_GT(apart_gap, 0.01);

  // The same cut as a hard edge: each side's normal delta is that of its own
  // faces (the normals of the split mesh computed apart).
  SplitMesh edge = splitDownTheMiddle(target.rig.mesh);
  edge.mesh.normals = core::computeVertexNormals(edge.mesh.positions, edge.mesh.triangles);
  auto hard = core::transferRig(prepared, edge.mesh, target.landmarks, "hard edge");
  ASSERT_TRUE(hard);
  const Eigen::MatrixX3d edge_base = core::computeVertexNormals(edge.mesh.positions, edge.mesh.triangles);
  for (const auto& shape : hard->rig.morph_targets) {
    EXPECT_TRUE(shape.normal_deltas ==
                zeroed(core::computeVertexNormals(edge.mesh.positions + shape.position_deltas, edge.mesh.triangles) -
                       edge_base))
        << shape.name;
  }
}

// A closed sphere (UV sphere, poles shared) appended to `mesh`; returns its
// first vertex.
Eigen::Index appendSphere(core::Mesh& mesh, const Eigen::Vector3d& centre, double radius) {
  constexpr int kAround = 20, kRings = 12;
  const Eigen::Index base = mesh.positions.rows();
  std::vector<Eigen::Vector3d> points{centre + Eigen::Vector3d(0, radius, 0)};
  for (int i = 1; i < kRings; ++i) {
    for (int j = 0; j < kAround; ++j) {
      const double theta = std::numbers::pi * i / kRings, phi = 2 * std::numbers::pi * j / kAround;
      points.push_back(centre + radius * Eigen::Vector3d(std::sin(theta) * std::cos(phi), std::cos(theta),
                                                         std::sin(theta) * std::sin(phi)));
    }
  }
  points.push_back(centre - Eigen::Vector3d(0, radius, 0));
  const int bottom = static_cast<int>(points.size()) - 1;
  auto ring = [](int i, int j) { return 1 + (i - 1) * kAround + (j % kAround); };
  std::vector<Eigen::Vector3i> faces;
  for (int j = 0; j < kAround; ++j) {
    faces.emplace_back(0, ring(1, j + 1), ring(1, j));
    faces.emplace_back(bottom, ring(kRings - 1, j), ring(kRings - 1, j + 1));
    for (int i = 1; i + 1 < kRings; ++i) {
      faces.emplace_back(ring(i, j), ring(i, j + 1), ring(i + 1, j));
      faces.emplace_back(ring(i, j + 1), ring(i + 1, j + 1), ring(i + 1, j));
    }
  }
  mesh.positions.conservativeResize(base + static_cast<Eigen::Index>(points.size()), 3);
  for (std::size_t k = 0; k < points.size(); ++k) {
    mesh.positions.row(base + static_cast<Eigen::Index>(k)) = points[k].transpose();
  }
  const Eigen::Index first_face = mesh.triangles.rows();
  mesh.triangles.conservativeResize(first_face + static_cast<Eigen::Index>(faces.size()), 3);
  for (std::size_t k = 0; k < faces.size(); ++k) {
    const Eigen::Vector3i corners = faces[k].array() + static_cast<int>(base);
    mesh.triangles.row(first_face + static_cast<Eigen::Index>(k)) = corners.transpose();
  }
  return base;
}

// Eyeballs modelled in the face's mesh: closed pieces no landmark is on. The
// lids resting on them must not be matched to them (the face gets the rig it
// gets without them); each follows one joint rigidly and takes no shape
// deltas.
TEST(TransferRig, ClosedPiecesWithoutLandmarksAreNotMatchedAsSkin) {
  const core::HeadResolution res{.columns = 80, .rows = 72, .alternate_diagonals = false, .jitter = 0.0, .seed = 5};
  const core::SyntheticRig face = core::generateRig(core::randomHeadShape(5, 0.1), res);
  auto corners = core::resolveLandmarks(face.landmarks, face.rig.mesh, "face");
  ASSERT_TRUE(corners) << corners.error().message;
  core::Mesh skin = face.rig.mesh;  // as a scan or sculpt comes: no labels or UVs to extend
  skin.regions.resize(0);
  skin.uvs.resize(0, 2);
  core::Mesh with_eyes = skin;
  const Eigen::Index nv = with_eyes.vertexCount();
  std::vector<Eigen::Index> ball_starts;
  for (const char* side : {"eye_right_", "eye_left_"}) {
    const Eigen::Vector3d inner = corners->row(face.landmarks.indexOf(std::string(side) + "0")).transpose();
    const Eigen::Vector3d outer = corners->row(face.landmarks.indexOf(std::string(side) + "3")).transpose();
    const double radius = 0.6 * (outer - inner).norm();
    // The ball's front reaches the lids' line between the corners.
    ball_starts.push_back(appendSphere(with_eyes, 0.5 * (inner + outer) - Eigen::Vector3d(0, 0, 0.9 * radius), radius));
  }
  with_eyes.normals.resize(0, 3);  // recomputed by the transfer, as for a file without normals
  auto plain = core::transferRig(preparedSource(), skin, face.landmarks, "face");
  auto eyes = core::transferRig(preparedSource(), with_eyes, face.landmarks, "face with eyes");
  ASSERT_TRUE(plain) << plain.error().message;
  ASSERT_TRUE(eyes) << eyes.error().message;
  EXPECT_EQ(eyes->report.warp.detached_pieces, 2);
  EXPECT_EQ(eyes->report.warp.detached_vertices, with_eyes.vertexCount() - nv);
  ASSERT_FALSE(eyes->report.warp.warnings.empty());
  EXPECT_NE(eyes->report.warp.warnings.back().find("not matched as skin"), std::string::npos);
  EXPECT_EQ(plain->report.warp.detached_pieces, 0);

  const double diagonal = core::boundingBoxDiagonal(face.rig.mesh.positions);
  for (std::size_t k = 0; k < plain->rig.morph_targets.size(); ++k) {
    const Eigen::MatrixX3d& alone = plain->rig.morph_targets[k].position_deltas;
    const Eigen::MatrixX3d& d = eyes->rig.morph_targets[k].position_deltas;
    EXPECT_LT((d.topRows(nv) - alone).cwiseAbs().maxCoeff(), 1e-9 * diagonal) << plain->rig.morph_targets[k].name;
    EXPECT_TRUE(d.bottomRows(d.rows() - nv).isZero(0.0)) << plain->rig.morph_targets[k].name;
  }
  const Eigen::MatrixXd weights(eyes->rig.weights);
  EXPECT_LT((weights.topRows(nv) - Eigen::MatrixXd(plain->rig.weights)).cwiseAbs().maxCoeff(), 1e-9);
  // Each ball follows one joint rigidly.
  ball_starts.push_back(weights.rows());
  for (std::size_t b = 0; b + 1 < ball_starts.size(); ++b) {
    const Eigen::RowVectorXd first = weights.row(ball_starts[b]);
    EXPECT_EQ(first.maxCoeff(), 1.0);
    EXPECT_EQ(first.sum(), 1.0);
    for (Eigen::Index v = ball_starts[b]; v < ball_starts[b + 1]; ++v) ASSERT_TRUE(weights.row(v) == first) << v;
  }
  const auto glb = rigport_test::makeTempDir("detached") / "eyes.glb";
  ASSERT_TRUE(core::writeRigGlb(eyes->rig, glb)) << glb;
  EXPECT_GLTF_VALID(glb);
}

// Some exporters write faces inside out (corners in clockwise order). The
// transfer must see the same surface: the same weights and shapes as onto the
// correctly wound mesh, which the output keeps as it came. (Swapped corners
// round differently; the sliding's float products carry that to ~1e-9.)
TEST(TransferRig, TargetWithReversedWindingGetsTheSameRig) {
  const core::SyntheticRig& target = lipTarget();
  core::Mesh inside_out = target.rig.mesh;
  inside_out.triangles.col(1).swap(inside_out.triangles.col(2));
  inside_out.normals = -inside_out.normals;
  core::LandmarkSet landmarks = target.landmarks;
  for (core::Landmark& l : landmarks.landmarks) std::swap(l.barycentric(1), l.barycentric(2));
  auto plain = core::transferRig(preparedSource(), target.rig.mesh, target.landmarks, "target");
  auto turned = core::transferRig(preparedSource(), inside_out, landmarks, "inside_out");
  ASSERT_TRUE(plain && turned);
  EXPECT_TRUE(turned->report.warp.target_turned);
  EXPECT_FALSE(plain->report.warp.target_turned);
  const double diag = core::boundingBoxDiagonal(target.rig.mesh.positions);
  EXPECT_TRUE(matricesNear(Eigen::MatrixXd(turned->rig.weights), Eigen::MatrixXd(plain->rig.weights), 1e-8));
  EXPECT_EQ(turned->report.inpainted_vertices, plain->report.inpainted_vertices);
  ASSERT_EQ(turned->rig.morph_targets.size(), plain->rig.morph_targets.size());
  for (std::size_t k = 0; k < plain->rig.morph_targets.size(); ++k) {
    EXPECT_TRUE(matricesNear(turned->rig.morph_targets[k].position_deltas, plain->rig.morph_targets[k].position_deltas,
                             1e-8 * diag))
        << plain->rig.morph_targets[k].name;
  }
  EXPECT_EQ(turned->rig.mesh.triangles, inside_out.triangles);
}

// Normals that point against the faces (flipped on export, or the winding
// reversed without them) would fail the location's normal test at every
// vertex: those vertices are matched by their face normals, the output keeps
// the normals as they came, and a warning counts them.
TEST(TransferRig, TargetWithNormalsAgainstItsWindingGetsTheSameRig) {
  const core::SyntheticRig& target = lipTarget();
  const Eigen::Index nv = target.rig.mesh.vertexCount();
  core::Mesh flipped_normals = target.rig.mesh;
  flipped_normals.normals = -flipped_normals.normals;
  core::Mesh reversed_winding = target.rig.mesh;  // its normals still point outward
  reversed_winding.triangles.col(1).swap(reversed_winding.triangles.col(2));
  core::LandmarkSet reversed_landmarks = target.landmarks;
  for (core::Landmark& l : reversed_landmarks.landmarks) std::swap(l.barycentric(1), l.barycentric(2));
  auto plain = core::transferRig(preparedSource(), target.rig.mesh, target.landmarks, "target");
  auto by_normals = core::transferRig(preparedSource(), flipped_normals, target.landmarks, "flipped_normals");
  auto by_winding = core::transferRig(preparedSource(), reversed_winding, reversed_landmarks, "reversed_winding");
  ASSERT_TRUE(plain && by_normals && by_winding);
  EXPECT_EQ(plain->report.warp.target_normals_against_winding, 0);
  EXPECT_EQ(by_normals->report.warp.target_normals_against_winding, nv);
  EXPECT_EQ(by_winding->report.warp.target_normals_against_winding, nv);
  EXPECT_TRUE(by_winding->report.warp.target_turned);
  const double diag = core::boundingBoxDiagonal(target.rig.mesh.positions);
  for (const auto* result : {&by_normals, &by_winding}) {
    const core::TransferResult& r = **result;
    bool warned = false;
    for (const std::string& w : r.report.warp.warnings) {
      warned = warned || w.find("vertex normals (100%) point against its faces' winding") != std::string::npos;
    }
    EXPECT_TRUE(warned);
    EXPECT_TRUE(matricesNear(Eigen::MatrixXd(r.rig.weights), Eigen::MatrixXd(plain->rig.weights), 1e-8));
    EXPECT_EQ(r.report.inpainted_vertices, plain->report.inpainted_vertices);
    ASSERT_EQ(r.rig.morph_targets.size(), plain->rig.morph_targets.size());
    for (std::size_t k = 0; k < plain->rig.morph_targets.size(); ++k) {
      EXPECT_TRUE(matricesNear(r.rig.morph_targets[k].position_deltas, plain->rig.morph_targets[k].position_deltas,
                               1e-8 * diag))
          << plain->rig.morph_targets[k].name;
    }
  }
  EXPECT_TRUE(by_normals->rig.mesh.normals == flipped_normals.normals);
  EXPECT_TRUE(by_winding->rig.mesh.triangles == reversed_winding.triangles);
}

// The same on the source: its normals steer the refinement's projections.
TEST(TransferRig, SourceWithNormalsAgainstItsWindingGetsTheSameRig) {
  core::Rig flipped = sourceRig().rig;
  flipped.mesh.normals = -flipped.mesh.normals;
  auto prepared = core::prepareRig(flipped, sourceRig().landmarks, "flipped_source");
  ASSERT_TRUE(prepared) << prepared.error().message;
  EXPECT_EQ(prepared->surface.normals_against_winding, flipped.mesh.vertexCount());
  EXPECT_EQ(preparedSource().surface.normals_against_winding, 0);
  const core::SyntheticRig& target = lipTarget();
  auto plain = core::transferRig(preparedSource(), target.rig.mesh, target.landmarks, "target");
  auto result = core::transferRig(*prepared, target.rig.mesh, target.landmarks, "target");
  ASSERT_TRUE(plain && result);
  EXPECT_EQ(result->report.warp.source_normals_against_winding, flipped.mesh.vertexCount());
  bool warned = false;
  for (const std::string& w : result->report.warp.warnings) warned = warned || w.rfind("flipped_source: ", 0) == 0;
  EXPECT_TRUE(warned);
  EXPECT_TRUE(matricesNear(Eigen::MatrixXd(result->rig.weights), Eigen::MatrixXd(plain->rig.weights), 1e-9));
  ASSERT_EQ(result->rig.morph_targets.size(), plain->rig.morph_targets.size());
  const double diag = core::boundingBoxDiagonal(target.rig.mesh.positions);
  for (std::size_t k = 0; k < plain->rig.morph_targets.size(); ++k) {
    EXPECT_TRUE(matricesNear(result->rig.morph_targets[k].position_deltas,
                             plain->rig.morph_targets[k].position_deltas, 1e-9 * diag))
        << plain->rig.morph_targets[k].name;
  }
}

// Normal deltas are recomputed on the target only around moving vertices;
// the result must equal recomputing every vertex normal, bit for bit. The
// target's own normals are written as they came.
TEST(TransferRig, NormalDeltasEqualAFullRecomputeOfTheDisplacedTarget) {
  const core::PreparedRig& prepared = preparedWithNormalDeltas();
  core::SyntheticRig target = headForNormalDeltas();
  // Authored normals (here: the computed ones turned by 10 degrees) stay in
  // the output; the deltas are the change of the computed normals.
  const Eigen::Matrix3d turn = Eigen::AngleAxisd(0.17, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  target.rig.mesh.normals = target.rig.mesh.normals * turn.transpose();
  auto result = core::transferRig(prepared, target.rig.mesh, target.landmarks, "other");
  ASSERT_TRUE(result) << result.error().message;
  const core::Mesh& mesh = target.rig.mesh;
  EXPECT_TRUE(result->rig.mesh.normals == mesh.normals);
  const Eigen::MatrixX3d base = core::computeVertexNormals(mesh.positions, mesh.triangles);
  ASSERT_FALSE(result->rig.morph_targets.empty());
  for (const auto& shape : result->rig.morph_targets) {
    ASSERT_EQ(shape.normal_deltas.rows(), mesh.vertexCount()) << shape.name;
    Eigen::MatrixX3d expected = core::computeVertexNormals(mesh.positions + shape.position_deltas, mesh.triangles) - base;
    for (Eigen::Index v = 0; v < expected.rows(); ++v) {
      if (expected.row(v).cwiseAbs().maxCoeff() < 1e-12) expected.row(v).setZero();
    }
    EXPECT_TRUE(shape.normal_deltas == expected)
        << shape.name << ": max difference " << (shape.normal_deltas - expected).cwiseAbs().maxCoeff();
    EXPECT_GT((shape.normal_deltas.rowwise().norm().array() > 0).count(), 0) << shape.name;
  }
}

}  // namespace
