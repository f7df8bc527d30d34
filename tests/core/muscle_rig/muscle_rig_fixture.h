// Shared checks of the reference muscle rig (core/muscle_rig): how a preset
// moves named landmarks, measured in the face's own frame (units of the
// inter-ocular distance), and the expression directions any face must show.
// Used by tests/core/muscle_rig (generated heads) and tests/data (ICT face).
#pragma once

#include <map>
#include <string>

#include <gtest/gtest.h>

#include "core/components/pose.h"
#include "core/io/landmarks.h"
#include "core/muscle_rig/face_frame.h"
#include "core/muscle_rig/muscle_rig.h"

namespace rigport_test {

// Each landmark's motion at `controls`, in frame units (x right, y up, z forward).
inline std::map<std::string, Eigen::Vector3d> landmarkMotion(const core::Mesh& face, const core::LandmarkSet& landmarks,
                                                             const core::MuscleRig& rig,
                                                             const std::map<std::string, double>& controls) {
  auto frame = core::buildFaceFrame(face, landmarks, "face");
  EXPECT_TRUE(frame.ok());
  auto pose = core::evaluatePose(face.positions, face.triangles, rig.components, controls);
  EXPECT_TRUE(pose.ok()) << (pose ? "" : pose.error().message);
  std::map<std::string, Eigen::Vector3d> motion;
  if (!frame || !pose) return motion;
  auto positions = core::resolveLandmarks(landmarks, face, "face");
  const std::vector<int> vertices = core::landmarkVertices(landmarks, face, *positions);
  for (std::size_t i = 0; i < landmarks.landmarks.size(); ++i) {
    const int v = vertices[i];
    const Eigen::Vector3d d = pose->positions.row(v) - face.positions.row(v);
    motion[landmarks.landmarks[i].name] = {d.dot(frame->right) / frame->iod, d.dot(frame->up) / frame->iod,
                                           d.dot(frame->forward) / frame->iod};
  }
  return motion;
}

inline std::map<std::string, Eigen::Vector3d> presetMotion(const core::Mesh& face, const core::LandmarkSet& landmarks,
                                                           const core::MuscleRig& rig, const std::string& preset) {
  auto controls = core::presetControls(rig.components, preset);
  EXPECT_TRUE(controls.ok());
  return landmarkMotion(face, landmarks, rig, controls ? *controls : std::map<std::string, double>{});
}

// The directions of the universal expressions and a few single actions, in
// frame units: mouth corners (mouth_outer_0 right, _6 left), inner brows
// (brow_right_4, brow_left_0), chin (jaw_08), upper lids (eye_*_1).
inline void expectExpressionDirections(const core::Mesh& face, const core::LandmarkSet& landmarks,
                                       const core::MuscleRig& rig) {
  constexpr double kClear = 0.01;  // iod: a motion the eye sees
  const auto joy = presetMotion(face, landmarks, rig, "joy");
  EXPECT_GT(joy.at("mouth_outer_6").y(), kClear) << "joy: left mouth corner up";
  EXPECT_GT(joy.at("mouth_outer_0").y(), kClear) << "joy: right mouth corner up";
  EXPECT_GT(joy.at("mouth_outer_6").x(), kClear) << "joy: left corner outwards";
  EXPECT_LT(joy.at("mouth_outer_0").x(), -kClear) << "joy: right corner outwards";
  const auto sad = presetMotion(face, landmarks, rig, "sadness");
  EXPECT_LT(sad.at("mouth_outer_6").y(), -kClear) << "sadness: corners down";
  EXPECT_GT(sad.at("brow_left_0").y(), kClear) << "sadness: inner brows up";
  const auto anger = presetMotion(face, landmarks, rig, "anger");
  EXPECT_LT(anger.at("brow_left_0").y(), -kClear) << "anger: inner brows down";
  EXPECT_LT(anger.at("brow_left_0").x() - anger.at("brow_right_4").x(), -kClear) << "anger: brows drawn together";
  const auto fear = presetMotion(face, landmarks, rig, "fear");
  EXPECT_GT(fear.at("brow_left_0").y(), kClear) << "fear: inner brows up";
  EXPECT_GT(fear.at("mouth_outer_6").x(), kClear) << "fear: lips stretched";
  const auto surprise = presetMotion(face, landmarks, rig, "surprise");
  EXPECT_GT(surprise.at("brow_left_2").y(), 2 * kClear) << "surprise: brows up";
  EXPECT_GT(surprise.at("brow_right_2").y(), 2 * kClear) << "surprise: brows up";
  EXPECT_LT(surprise.at("jaw_08").y(), -2 * kClear) << "surprise: jaw drops";
  const auto disgust = presetMotion(face, landmarks, rig, "disgust");
  EXPECT_GT(disgust.at("mouth_outer_4").y(), kClear) << "disgust: upper lip raised";
  const auto pucker = presetMotion(face, landmarks, rig, "pucker");
  EXPECT_LT(pucker.at("mouth_outer_6").x(), -kClear) << "pucker: corners inwards";
  const auto blink = presetMotion(face, landmarks, rig, "blink");
  EXPECT_LT(blink.at("eye_left_1").y(), -2 * kClear) << "blink: upper lid down";
  const auto smile_left = presetMotion(face, landmarks, rig, "smile_left");
  EXPECT_GT(smile_left.at("mouth_outer_6").y(), kClear) << "smile_left: left corner up";
  EXPECT_LT(std::abs(smile_left.at("mouth_outer_0").y()), 0.5 * smile_left.at("mouth_outer_6").y())
      << "smile_left: the right corner stays";
}

}  // namespace rigport_test
