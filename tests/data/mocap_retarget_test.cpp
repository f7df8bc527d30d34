// The AnimFace nose and eyebrow clips (41 markers, 60 Hz, cm) drive the ICT
// source face (../shared/data/mocap, MANIFEST.md there) with each distance
// method. Skips when the shared data is absent.
#include <cstdio>
#include <map>
#include <optional>

#include <gtest/gtest.h>

#include "core/io/mesh_io.h"
#include "core/retarget/retarget.h"
#include "core/io/rig_io.h"
#include "core/io/trc_io.h"
#include "tests/test_support.h"

namespace {

struct IctFace {
  core::Mesh mesh;
  core::LandmarkSet markers;
  std::map<core::DistanceMethod, core::MarkerDistances> distances;
};

// Loaded once; distances per method made on first use.
IctFace* ictFace(const std::filesystem::path& data) {
  static std::optional<IctFace> face;
  static bool tried = false;
  if (!tried) {
    tried = true;
    auto mesh = core::readMesh(data / "ict" / "source_face.glb");
    auto markers = core::readLandmarks(data / "mocap" / "ict_markers.json");
    EXPECT_TRUE(mesh) << mesh.error().message;
    EXPECT_TRUE(markers) << markers.error().message;
    if (mesh && markers) face = IctFace{std::move(mesh->mesh), std::move(*markers), {}};
  }
  return face ? &*face : nullptr;
}

const core::MarkerDistances& distancesFor(IctFace& face, core::DistanceMethod method) {
  auto it = face.distances.find(method);
  if (it == face.distances.end()) {
    core::MarkerDistanceOptions o;
    o.method = method;
    auto d = core::computeMarkerDistances(face.mesh, face.markers, "source_face.glb", o);
    EXPECT_TRUE(d) << d.error().message;
    it = face.distances.emplace(method, std::move(*d)).first;
  }
  return it->second;
}

void checkClip(const std::filesystem::path& data, const std::string& clip_name) {
  IctFace* face = ictFace(data);
  ASSERT_NE(face, nullptr);
  auto clip = core::readTrc(data / "mocap" / clip_name);
  ASSERT_TRUE(clip) << clip.error().message;
  ASSERT_EQ(clip->markerCount(), 41);
  ASSERT_GT(clip->frameCount(), 800);

  for (core::DistanceMethod method : {core::DistanceMethod::kEuclidean, core::DistanceMethod::kGeodesic,
                                      core::DistanceMethod::kHybrid}) {
    SCOPED_TRACE(std::string(clip_name) + " " + core::distanceMethodName(method));
    const core::MarkerDistances& distances = distancesFor(*face, method);
    auto out = core::retargetMocap(face->mesh, distances, *clip);
    ASSERT_TRUE(out) << out.error().message;
    const core::RetargetReport& r = out->report;
    const core::Rig& rig = out->rig;
    std::printf("%s %-9s: rank %d, relative error %.2e, rms %.3g mm, max bound %.3g mm; marker residual max %.2e mm; "
                "max marker displacement %.2f mm; scale %.4f, similarity rms %.2f mm, jacobian sv [%.2f, %.2f]; "
                "regions %zu of %d loops; distances %.0f ms; head motion %.2f deg %.1f mm\n",
                clip_name.c_str(), core::distanceMethodName(method), r.rank, r.relative_error, 10 * r.rms_error,
                10 * r.max_error, 10 * r.marker_max_residual, 10 * r.max_marker_displacement, r.similarity_scale,
                10 * r.similarity_rms, r.jacobian_min_singular, r.jacobian_max_singular, r.regions.size(),
                r.boundary_loops, distances.compute_ms, r.head_max_rotation_deg, 10 * r.head_max_translation);

    // The ICT face is in centimetres (a ~48 cm head diagonal), like the TRC:
    // the similarity scale is the actor-to-ICT size ratio (~0.9, MANIFEST).
    ASSERT_GT(r.mesh_diagonal, 30.0);
    ASSERT_LT(r.mesh_diagonal, 60.0);
    EXPECT_GT(r.similarity_scale, 0.8);
    EXPECT_LT(r.similarity_scale, 1.0);
    EXPECT_LT(r.similarity_rms, 1.0);  // cm; MANIFEST: 0.77 cm on 8 groups
    // Head motion (a few degrees, centimetres) is removed before the RBF.
    EXPECT_TRUE(r.head_motion_removed);
    EXPECT_GT(r.head_max_rotation_deg, 1.0);
    // Every frame finite.
    for (const auto& t : rig.morph_targets) ASSERT_TRUE(t.position_deltas.allFinite()) << t.name;
    ASSERT_TRUE(rig.animations.at(0).channels.at(0).values.allFinite());
    EXPECT_EQ(rig.animations[0].channels[0].values.rows(), clip->frameCount());
    EXPECT_TRUE(r.tolerance_met);
    EXPECT_LE(r.relative_error, 0.05);
    EXPECT_LT(r.rank, 40);
    // The RBF interpolates the markers (no stiffness).
    EXPECT_LT(r.marker_max_residual, 1e-8);
    // Reasonable magnitudes: facial motion of millimetres to centimetres.
    EXPECT_GT(r.max_marker_displacement, 0.2);
    EXPECT_LT(r.max_marker_displacement, 5.0);

    // Markers followed: the baked mesh at each marker's location (barycentric
    // on its face) moves as the calibrated marker, sampled every 40 frames.
    double worst = 0.0, max_vertex = 0.0;
    for (int f = 0; f < clip->frameCount(); f += 40) {
      const Eigen::MatrixX3d d = rigport_test::displacementAtKey(rig, f);
      max_vertex = std::max(max_vertex, d.rowwise().norm().maxCoeff());
      for (std::size_t i = 0; i < face->markers.landmarks.size(); ++i) {
        const core::Landmark& lm = face->markers.landmarks[i];
        Eigen::RowVector3d at = Eigen::RowVector3d::Zero();
        for (int k = 0; k < 3; ++k) at += lm.barycentric(k) * d.row(face->mesh.triangles(lm.face, k));
        const Eigen::RowVector3d expected = out->marker_displacements.block(f, 3 * static_cast<Eigen::Index>(i), 1, 3);
        worst = std::max(worst, (at - expected).norm());
      }
    }
    std::printf("  worst marker-following error %.3f mm (of max displacement %.2f mm); max vertex displacement %.2f mm\n",
                10 * worst, 10 * r.max_marker_displacement, 10 * max_vertex);
    EXPECT_LT(worst, 0.15 * r.max_marker_displacement + 1e-3 * r.mesh_diagonal);
    EXPECT_LT(max_vertex, 2.0 * r.max_marker_displacement);
    if (method == core::DistanceMethod::kHybrid) {
      EXPECT_GE(r.regions.size(), 2u);  // mouth and eyes at least
    }

    const std::filesystem::path dir = rigport_test::makeTempDir("mocap_retarget");
    const std::filesystem::path file = dir / (clip_name + "." + core::distanceMethodName(method) + ".glb");
    ASSERT_TRUE(core::writeRigGlb(rig, file));
    EXPECT_GLTF_VALID(file);
  }
}

TEST(MocapRetarget, NoseClipDrivesTheIctFaceWithEveryMethod) {
  RIGPORT_REQUIRE_SHARED_DATA(data);
  checkClip(data, "animface_nose.trc");
}

TEST(MocapRetarget, EyebrowsClipDrivesTheIctFaceWithEveryMethod) {
  RIGPORT_REQUIRE_SHARED_DATA(data);
  checkClip(data, "animface_eyebrows.trc");
}

}  // namespace
