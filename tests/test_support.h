// Shared helpers for rigport tests: where the real data lives, the Khronos
// validator, matrix comparison with (i, j) in the failure message.
#pragma once

#include <filesystem>
#include <optional>
#include <string>

#include <Eigen/Core>
#include <gtest/gtest.h>

#include "core/rig/rig.h"
#include "core/synthetic/synthetic_rig.h"
#include "core/transfer/transfer.h"

namespace rigport_test {

// ../shared/data beside the repository (or $RIGPORT_SHARED_DATA); nullopt when absent.
std::optional<std::filesystem::path> sharedDataDir();

// Skips the current test with a clear message when ../shared/data is absent.
#define RIGPORT_REQUIRE_SHARED_DATA(var)                                                        \
  const auto var##_opt = ::rigport_test::sharedDataDir();                                       \
  if (!var##_opt) GTEST_SKIP() << "../shared/data not found (set RIGPORT_SHARED_DATA): skipped"; \
  const std::filesystem::path var = *var##_opt

// A fresh empty directory under the build tree's temp area, unique per test.
std::filesystem::path makeTempDir(const std::string& name);

// A shell command's exit code (-1 when it did not exit) and its stdout+stderr.
struct CommandResult {
  int exit_code = -1;
  std::string output;
};
CommandResult runCommand(const std::string& command);

struct ValidatorResult {
  bool ran = false;      // false: node or gltf-validator missing (message in `output`)
  int errors = -1;
  int warnings = -1;
  std::string output;    // the validator's JSON line(s)
};

// Runs tests/tools/validate_gltf.mjs (Khronos gltf-validator) on `file`.
ValidatorResult validateGltf(const std::filesystem::path& file);

// Fails the test unless the validator ran and reported zero errors.
#define EXPECT_GLTF_VALID(path)                                                            \
  do {                                                                                     \
    const auto vr_ = ::rigport_test::validateGltf(path);                                   \
    EXPECT_TRUE(vr_.ran) << "glTF validator did not run: " << vr_.output;                  \
    EXPECT_EQ(vr_.errors, 0) << "glTF validator errors in " << (path) << ": " << vr_.output; \
  } while (0)

// Unit icosphere: an icosahedron subdivided 1:4 `levels` times, vertices
// projected onto the sphere (~20 * 4^levels faces; levels = 5: 10242 vertices).
struct Icosphere {
  Eigen::MatrixX3d positions;
  Eigen::MatrixX3i triangles;
};
Icosphere unitIcosphere(int levels);

// Displacement of the rig's mesh from rest at key `key` of its first
// animation's first channel (core::samplePose + core::poseMesh).
Eigen::MatrixX3d displacementAtKey(const core::Rig& rig, Eigen::Index key);

// n points drawn uniformly from the cube [-half_width, half_width]^3
// (std::mt19937 seeded with `seed`: the same points on every machine).
Eigen::MatrixX3d randomPoints(int n, unsigned seed, double half_width = 1.0);

// A generated rig with its lips pressed together: each painted lip moved
// towards the other until the slit (still an open boundary) is a fiftieth
// of its height, as ICT's lips touch in the neutral.
core::SyntheticRig pressLips(core::SyntheticRig head);

// The same head with its mouth sagging in the middle by `depth` times the
// mouth's width (a smile's corners): a warp pinned at the mouth corners lays
// another face's upper lip over its lower one.
core::SyntheticRig sagMouth(core::SyntheticRig head, double depth);

// The generated rig with its lips pressed (96 x 88 cells), and a target of
// other proportions and topology (84 x 80, alternating diagonals, jittered)
// with its lips pressed and its mouth sagging by 0.3 of its width, whose
// lips a warp on 10 landmarks lays across each other: the lip tests' pair.
const core::SyntheticRig& touchingLipsSource();
const core::PreparedRig& preparedTouchingLipsSource();  // prepareRig of it, once
const core::SyntheticRig& saggingMouthTarget();

// The 10 landmarks of a sparse target (eye and mouth corners, nose tip and
// wings, chin) of a generated head, as positions.
core::LandmarkSet tenLandmarks(const core::SyntheticRig& head);

// Compares two matrices elementwise; the failure names the first (i, j) apart.
::testing::AssertionResult matricesNear(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b, double tol);

}  // namespace rigport_test
