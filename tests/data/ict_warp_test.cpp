// Warp + dense correspondence of the ICT source face onto the ICT targets in
// ../shared/data (MANIFEST.md there defines them). Skips when absent.
#include <algorithm>
#include <cstdio>
#include <map>
#include <string>
#include <tuple>

#include <gtest/gtest.h>

#include "core/io/mesh_io.h"
#include "core/correspond/warp_job.h"
#include "tests/test_support.h"

namespace {

// Loaded and prepared once for the whole suite (7.5 MB GLB).
const core::PreparedSource* ictSource(const std::filesystem::path& data) {
  static std::optional<core::PreparedSource> prepared;
  static bool tried = false;
  if (!tried) {
    tried = true;
    auto mesh = core::readMesh(data / "ict" / "source_face.glb");
    auto landmarks = core::readLandmarks(data / "ict" / "source_face.landmarks.json");
    if (mesh && landmarks) {
      auto p = core::prepareSource(mesh->mesh, *landmarks, "source_face.glb");
      if (p) prepared = std::move(*p);
    }
  }
  return prepared ? &*prepared : nullptr;
}

struct Target {
  core::LoadedMesh mesh;
  core::LandmarkSet landmarks;
};

std::optional<Target> loadTarget(const std::filesystem::path& data, const std::string& name) {
  auto mesh = core::readMesh(data / "ict" / "targets" / (name + ".glb"));
  auto landmarks = core::readLandmarks(data / "ict" / "targets" / (name + ".landmarks.json"));
  if (!mesh || !landmarks) return std::nullopt;
  return Target{std::move(*mesh), std::move(*landmarks)};
}

double quantile(std::vector<double> v, double q) {
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<std::size_t>(q * static_cast<double>(v.size())))];
}

// The pipelines [1]'s accuracy limits must hold for: the default one (with
// the dense-map refinement the rig transfer needs), and the light one that
// meets [1]'s 20 ms (core::lightWarpOptions, `rigport warp --light`;
// docs/BENCHMARKS.md).
enum class Pipeline { kDefault, kLight };

core::WarpOptions optionsFor(Pipeline pipeline) {
  return pipeline == Pipeline::kLight ? core::lightWarpOptions() : core::WarpOptions{};
}

std::string pipelineName(Pipeline pipeline) { return pipeline == Pipeline::kLight ? "light" : "default"; }

using TargetAndPipeline = std::tuple<std::string, Pipeline>;

std::string caseName(const ::testing::TestParamInfo<TargetAndPipeline>& param) {
  return std::get<0>(param.param) + "_" + pipelineName(std::get<1>(param.param));
}

class IctWarp : public ::testing::TestWithParam<TargetAndPipeline> {};

TEST_P(IctWarp, RemeshedTargetLandmarksExactProjectionCloseFoldsReported) {
  RIGPORT_REQUIRE_SHARED_DATA(data);
  const core::PreparedSource* source = ictSource(data);
  ASSERT_NE(source, nullptr) << "ICT source failed to load";
  const auto& [name, pipeline] = GetParam();
  auto target = loadTarget(data, name);
  ASSERT_TRUE(target) << name;
  auto result = core::runWarp(*source, target->mesh.mesh, target->landmarks, name, optionsFor(pipeline));
  ASSERT_TRUE(result) << result.error().message;
  const core::WarpReport& r = result->report;
  const double diag = r.target_diagonal;
  std::printf("[ %s, %s ] landmarks %d rms %.2e (%.1e diag) p95 %.3f%% mean %.3f%% max %.3f%% of diag, flipped %d, "
              "collapsed %d, unmatched %d, low-confidence %d, suspicious %zu\n",
              name.c_str(), pipelineName(pipeline).c_str(), r.landmark_count, r.landmark_rms_residual, r.landmark_rms_residual / diag,
              100 * r.p95_distance / diag, 100 * r.mean_distance / diag, 100 * r.max_distance / diag,
              r.flipped_triangles, r.collapsed_triangles, r.unmatched_source_vertices, r.low_confidence_vertices,
              r.suspicious_landmarks.size());
  EXPECT_LE(r.landmark_rms_residual, 1e-6 * diag);
  EXPECT_LE(r.p95_distance, 0.005 * diag);
  // Folds are reported, not hidden. Where the fine source lies on a much
  // coarser target some tiny folds are unavoidable; more than 5% would mean
  // the correspondence broke down.
  EXPECT_GE(r.flipped_triangles, 0);
  EXPECT_LT(r.flipped_triangles, r.source_triangles / 20);
  EXPECT_TRUE(r.suspicious_landmarks.empty()) << r.suspicious_landmarks.front();
  EXPECT_EQ(static_cast<Eigen::Index>(result->guide.positions.rows()), source->mesh.vertexCount());
}

INSTANTIATE_TEST_SUITE_P(Remeshed, IctWarp,
                         ::testing::Combine(::testing::Values("id_s01_remesh", "id_s02_remesh", "id_s03_remesh",
                                                              "stylized_s01_cartoon_remesh", "sparse10_s01"),
                                            ::testing::Values(Pipeline::kDefault, Pipeline::kLight)),
                         caseName);

class IctSameTopology : public ::testing::TestWithParam<TargetAndPipeline> {};

// Same topology: vertex v of the target is the true counterpart of source v.
TEST_P(IctSameTopology, GuideVerticesLandNearTheirTrueCounterparts) {
  RIGPORT_REQUIRE_SHARED_DATA(data);
  const core::PreparedSource* source = ictSource(data);
  ASSERT_NE(source, nullptr);
  const auto& [name, pipeline] = GetParam();
  auto target = loadTarget(data, name);
  ASSERT_TRUE(target);
  auto result = core::runWarp(*source, target->mesh.mesh, target->landmarks, name, optionsFor(pipeline));
  ASSERT_TRUE(result) << result.error().message;
  const double diag = result->report.target_diagonal;
  std::vector<double> error(static_cast<std::size_t>(source->mesh.vertexCount()));
  // The face: vertices within 3 cm-equivalents (6% of the diagonal) of a landmark.
  std::vector<double> face_error;
  for (Eigen::Index v = 0; v < source->mesh.vertexCount(); ++v) {
    const double e = (result->guide.positions.row(v) - target->mesh.mesh.positions.row(v)).norm() / diag;
    error[static_cast<std::size_t>(v)] = e;
    const double to_landmark =
        (source->landmark_positions.rowwise() - source->mesh.positions.row(v)).rowwise().norm().minCoeff();
    if (to_landmark < 0.06 * source->diagonal) face_error.push_back(e);
  }
  double mean = 0;
  for (double e : error) mean += e;
  mean /= static_cast<double>(error.size());
  std::printf("[ %s, %s ] guide vs true vertex, %% of diagonal: all mean %.3f median %.3f p95 %.3f; face (%zu vertices) "
              "median %.3f p95 %.3f\n",
              name.c_str(), pipelineName(pipeline).c_str(), 100 * mean, 100 * quantile(error, 0.5), 100 * quantile(error, 0.95),
              face_error.size(), 100 * quantile(face_error, 0.5), 100 * quantile(face_error, 0.95));
  EXPECT_LE(mean, 0.01);
  EXPECT_LE(quantile(error, 0.5), 0.01);
  EXPECT_LE(quantile(face_error, 0.95), 0.01);
}

INSTANTIATE_TEST_SUITE_P(SameTopology, IctSameTopology,
                         ::testing::Combine(::testing::Values("id_s01", "id_s02", "id_s03", "stylized_s01_cartoon"),
                                            ::testing::Values(Pipeline::kDefault, Pipeline::kLight)),
                         caseName);

TEST(IctWarpLandmarks, SwappedMouthCornersAreNamed) {
  RIGPORT_REQUIRE_SHARED_DATA(data);
  const core::PreparedSource* source = ictSource(data);
  ASSERT_NE(source, nullptr);
  auto target = loadTarget(data, "id_s02_remesh");
  ASSERT_TRUE(target);
  const int a = target->landmarks.indexOf("mouth_outer_0");
  const int b = target->landmarks.indexOf("mouth_outer_6");
  ASSERT_GE(a, 0);
  ASSERT_GE(b, 0);
  std::swap(target->landmarks.landmarks[static_cast<std::size_t>(a)].name,
            target->landmarks.landmarks[static_cast<std::size_t>(b)].name);
  auto result = core::runWarp(*source, target->mesh.mesh, target->landmarks, "id_s02_remesh (swapped)");
  ASSERT_TRUE(result) << result.error().message;
  const auto& s = result->report.suspicious_landmarks;
  EXPECT_NE(std::find(s.begin(), s.end(), "mouth_outer_0"), s.end());
  EXPECT_NE(std::find(s.begin(), s.end(), "mouth_outer_6"), s.end());
  EXPECT_LE(s.size(), 3u);
}

}  // namespace
