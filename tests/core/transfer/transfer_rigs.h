// The generated rigs the transfer tests share (tests/core/transfer/transfer_*_test.cpp):
// the source rig, prepared once, and two targets of other proportions and
// topology. Each is built on first use and kept for the test binary's life.
#pragma once

#include <utility>

#include <gtest/gtest.h>

#include "core/synthetic/synthetic_rig.h"
#include "core/transfer/transfer.h"

namespace rigport_test::transfer {

inline const core::SyntheticRig& sourceRig() {
  static const core::SyntheticRig rig = core::generateRig(core::HeadShape{}, core::HeadResolution{96, 88});
  return rig;
}

inline const core::PreparedRig& preparedSource() {
  static const core::PreparedRig prepared = [] {
    auto p = core::prepareRig(sourceRig().rig, sourceRig().landmarks, "source");
    EXPECT_TRUE(p) << (p ? "" : p.error().message);
    return std::move(*p);
  }();
  return prepared;
}

// The lip tests' target: another head's proportions, jittered vertices,
// alternating diagonals (its lips are close: closest point can cross them).
inline const core::SyntheticRig& lipTarget() {
  static const core::SyntheticRig target = [] {
    const core::HeadResolution res{.columns = 84, .rows = 80, .alternate_diagonals = true, .jitter = 0.2, .seed = 4};
    return core::generateRig(core::randomHeadShape(4, 0.15), res);
  }();
  return target;
}

// Another head of other proportions and topology (jittered, alternating
// diagonals), for the tests that need just some other face.
inline const core::SyntheticRig& otherHead() {
  static const core::SyntheticRig target = [] {
    const core::HeadResolution res{.columns = 70, .rows = 66, .alternate_diagonals = true, .jitter = 0.25, .seed = 9};
    return core::generateRig(core::randomHeadShape(9, 0.2), res);
  }();
  return target;
}

}  // namespace rigport_test::transfer
