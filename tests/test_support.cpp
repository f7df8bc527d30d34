#include "tests/test_support.h"

#include <array>
#include <cstdio>
#include <cstdlib>
#include <sstream>

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

ValidatorResult validateGltf(const std::filesystem::path& file) {
  ValidatorResult result;
  const std::string script = std::string(RIGPORT_SOURCE_DIR) + "/tests/tools/validate_gltf.mjs";
  const std::string cmd = "node '" + script + "' '" + file.string() + "' 2>&1";
  FILE* pipe = popen(cmd.c_str(), "r");
  if (!pipe) {
    result.output = "popen failed";
    return result;
  }
  std::array<char, 4096> buf{};
  while (fgets(buf.data(), buf.size(), pipe)) result.output += buf.data();
  const int status = pclose(pipe);
  const int code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  if (code != 0 && code != 1) return result;
  const auto pos = result.output.find("\"errors\":");
  const auto wpos = result.output.find("\"warnings\":");
  if (pos == std::string::npos || wpos == std::string::npos) return result;
  result.ran = true;
  result.errors = std::atoi(result.output.c_str() + pos + 9);
  result.warnings = std::atoi(result.output.c_str() + wpos + 11);
  return result;
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

}  // namespace rigport_test
