#include "tests/test_support.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <map>
#include <random>
#include <sstream>
#include <utility>
#include <vector>

#include "core/rig/skinning.h"

namespace rigport_test {

std::optional<std::filesystem::path> sharedDataDir() {
  if (const char* env = std::getenv("RIGPORT_SHARED_DATA"); env && *env) {
    std::filesystem::path p(env);
    if (std::filesystem::exists(p / "MANIFEST.md")) return p;
    return std::nullopt;
  }
  const std::filesystem::path p = std::filesystem::path(RIGPORT_SOURCE_DIR) / ".." / "shared" / "data";
  if (std::filesystem::exists(p / "MANIFEST.md")) return std::filesystem::weakly_canonical(p);
  return std::nullopt;
}

std::filesystem::path makeTempDir(const std::string& name) {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  std::string test = info ? std::string(info->test_suite_name()) + "." + info->name() : "global";
  const std::filesystem::path dir = std::filesystem::path(RIGPORT_TEST_TMP_DIR) / (test + "." + name);
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

CommandResult runCommand(const std::string& command) {
  CommandResult result;
  FILE* pipe = popen((command + " 2>&1").c_str(), "r");
  if (!pipe) {
    result.output = "popen failed";
    return result;
  }
  std::array<char, 4096> buf{};
  while (fgets(buf.data(), buf.size(), pipe)) result.output += buf.data();
  const int status = pclose(pipe);
  result.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return result;
}

ValidatorResult validateGltf(const std::filesystem::path& file) {
  ValidatorResult result;
  const std::string script = std::string(RIGPORT_SOURCE_DIR) + "/tests/tools/validate_gltf.mjs";
  const CommandResult run = runCommand("node '" + script + "' '" + file.string() + "'");
  result.output = run.output;
  if (run.exit_code != 0 && run.exit_code != 1) return result;
  const auto pos = result.output.find("\"errors\":");
  const auto wpos = result.output.find("\"warnings\":");
  if (pos == std::string::npos || wpos == std::string::npos) return result;
  result.ran = true;
  result.errors = std::atoi(result.output.c_str() + pos + 9);
  result.warnings = std::atoi(result.output.c_str() + wpos + 11);
  return result;
}

Eigen::MatrixX3d displacementAtKey(const core::Rig& rig, Eigen::Index key) {
  const core::Animation& clip = rig.animations.at(0);
  const double time = clip.channels.at(0).times(key);
  return core::poseMesh(rig, core::samplePose(rig, clip, time)) - rig.mesh.positions;
}

::testing::AssertionResult matricesNear(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b, double tol) {
  if (a.rows() != b.rows() || a.cols() != b.cols()) {
    return ::testing::AssertionFailure() << "shape " << a.rows() << "x" << a.cols() << " vs " << b.rows() << "x"
                                         << b.cols();
  }
  for (Eigen::Index i = 0; i < a.rows(); ++i) {
    for (Eigen::Index j = 0; j < a.cols(); ++j) {
      const double d = std::abs(a(i, j) - b(i, j));
      if (!(d <= tol)) {
        return ::testing::AssertionFailure() << "(" << i << ", " << j << "): " << a(i, j) << " vs " << b(i, j)
                                             << " differ by " << d << " > " << tol;
      }
    }
  }
  return ::testing::AssertionSuccess();
}

Icosphere unitIcosphere(int levels) {
  const double g = (1.0 + std::sqrt(5.0)) / 2.0;
  std::vector<Eigen::Vector3d> v = {{-1, g, 0}, {1, g, 0}, {-1, -g, 0}, {1, -g, 0}, {0, -1, g}, {0, 1, g},
                                    {0, -1, -g}, {0, 1, -g}, {g, 0, -1}, {g, 0, 1}, {-g, 0, -1}, {-g, 0, 1}};
  for (auto& p : v) p.normalize();
  std::vector<Eigen::Vector3i> f = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
                                    {11, 10, 2}, {10, 7, 6}, {7, 1, 8},  {3, 9, 4}, {3, 4, 2},   {3, 2, 6}, {3, 6, 8},
                                    {3, 8, 9},   {4, 9, 5},  {2, 4, 11}, {6, 2, 10}, {8, 6, 7},  {9, 8, 1}};
  for (int l = 0; l < levels; ++l) {
    std::map<std::pair<int, int>, int> mid;
    auto midpoint = [&](int a, int b) {
      const auto key = std::minmax(a, b);
      auto it = mid.find(key);
      if (it != mid.end()) return it->second;
      v.push_back((v[static_cast<std::size_t>(a)] + v[static_cast<std::size_t>(b)]).normalized());
      const int id = static_cast<int>(v.size()) - 1;
      mid.emplace(key, id);
      return id;
    };
    std::vector<Eigen::Vector3i> next;
    for (const auto& t : f) {
      const int ab = midpoint(t(0), t(1)), bc = midpoint(t(1), t(2)), ca = midpoint(t(2), t(0));
      next.emplace_back(t(0), ab, ca);
      next.emplace_back(t(1), bc, ab);
      next.emplace_back(t(2), ca, bc);
      next.emplace_back(ab, bc, ca);
    }
    f = std::move(next);
  }
  Icosphere mesh;
  mesh.positions.resize(static_cast<Eigen::Index>(v.size()), 3);
  for (std::size_t i = 0; i < v.size(); ++i) mesh.positions.row(static_cast<Eigen::Index>(i)) = v[i].transpose();
  mesh.triangles.resize(static_cast<Eigen::Index>(f.size()), 3);
  for (std::size_t i = 0; i < f.size(); ++i) mesh.triangles.row(static_cast<Eigen::Index>(i)) = f[i].transpose();
  return mesh;
}

Eigen::MatrixX3d randomPoints(int n, unsigned seed, double half_width) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-half_width, half_width);
  Eigen::MatrixX3d p(n, 3);
  for (int i = 0; i < n; ++i) p.row(i) << u(rng), u(rng), u(rng);
  return p;
}

namespace {

Eigen::RowVector3d landmarkPoint(const core::SyntheticRig& head, const char* name) {
  const core::Landmark& l = head.landmarks.landmarks[static_cast<std::size_t>(head.landmarks.indexOf(name))];
  return core::interpolateOnFace(head.rig.mesh.positions, head.rig.mesh.triangles, l.face, l.barycentric);
}

}  // namespace

core::SyntheticRig pressLips(core::SyntheticRig head) {
  const Eigen::VectorXi& truth = head.rig.attributes.labels.at("REGION");
  double upper_bottom = std::numeric_limits<double>::infinity(), lower_top = -upper_bottom;
  for (Eigen::Index v = 0; v < truth.size(); ++v) {
    if (truth(v) == core::kRegionUpperLip) upper_bottom = std::min(upper_bottom, head.rig.mesh.positions(v, 1));
    if (truth(v) == core::kRegionLowerLip) lower_top = std::max(lower_top, head.rig.mesh.positions(v, 1));
  }
  const double slit = upper_bottom - lower_top;
  EXPECT_GT(slit, 0.0);
  for (Eigen::Index v = 0; v < truth.size(); ++v) {
    if (truth(v) == core::kRegionUpperLip) head.rig.mesh.positions(v, 1) -= 0.49 * slit;
    if (truth(v) == core::kRegionLowerLip) head.rig.mesh.positions(v, 1) += 0.49 * slit;
  }
  head.rig.mesh.normals = core::computeVertexNormals(head.rig.mesh.positions, head.rig.mesh.triangles);
  return head;
}

core::SyntheticRig sagMouth(core::SyntheticRig head, double depth) {
  const Eigen::RowVector3d right = landmarkPoint(head, "mouth_outer_0"), left = landmarkPoint(head, "mouth_outer_6");
  const Eigen::RowVector3d centre = 0.5 * (landmarkPoint(head, "mouth_inner_2") + landmarkPoint(head, "mouth_inner_6"));
  const double width = (left - right).norm();
  for (Eigen::Index v = 0; v < head.rig.mesh.vertexCount(); ++v) {
    const Eigen::RowVector3d d = head.rig.mesh.positions.row(v) - centre;
    const double x = d(0) / (0.3 * width), y = d(1) / (0.3 * width);
    head.rig.mesh.positions(v, 1) -= depth * width * std::exp(-x * x - y * y);
  }
  head.rig.mesh.normals = core::computeVertexNormals(head.rig.mesh.positions, head.rig.mesh.triangles);
  return head;
}

const core::SyntheticRig& touchingLipsSource() {
  static const core::SyntheticRig rig = pressLips(core::generateRig({}, core::HeadResolution{96, 88}));
  return rig;
}

const core::PreparedRig& preparedTouchingLipsSource() {
  static const core::PreparedRig prepared = [] {
    auto p = core::prepareRig(touchingLipsSource().rig, touchingLipsSource().landmarks, "source");
    EXPECT_TRUE(p) << (p ? "" : p.error().message);
    return std::move(*p);
  }();
  return prepared;
}

const core::SyntheticRig& saggingMouthTarget() {
  static const core::SyntheticRig target = [] {
    const core::HeadResolution res{.columns = 84, .rows = 80, .alternate_diagonals = true, .jitter = 0.2, .seed = 4};
    return sagMouth(pressLips(core::generateRig(core::randomHeadShape(4, 0.15), res)), 0.3);
  }();
  return target;
}

core::LandmarkSet tenLandmarks(const core::SyntheticRig& head) {
  core::LandmarkSet ten;
  for (const char* name : {"eye_right_0", "eye_right_3", "eye_left_0", "eye_left_3", "nose_bridge_3", "nose_base_0",
                           "nose_base_4", "mouth_outer_0", "mouth_outer_6", "jaw_08"}) {
    core::Landmark p;
    p.name = name;
    p.kind = core::LandmarkKind::kPosition;
    p.position = landmarkPoint(head, name).transpose();
    ten.landmarks.push_back(p);
  }
  return ten;
}

}  // namespace rigport_test
