// The face frame of the reference muscle rig: landmarks resolved by name, axes
// and scale from eye corners and mouth (iBUG 68 layout: 36/45 outer eye
// corners, 48-67 lips).
#include "core/muscle_rig/face_frame.h"

#include <algorithm>
#include <cassert>
#include <limits>

namespace core {

Eigen::Vector3d FaceFrame::toFrame(const Eigen::Vector3d& p) const {
  const Eigen::Vector3d d = (p - origin) / iod;
  return {d.dot(right), d.dot(up), d.dot(forward)};
}

Eigen::Vector3d FaceFrame::toModel(const Eigen::Vector3d& local) const {
  return origin + iod * (local.x() * right + local.y() * up + local.z() * forward);
}

const Eigen::Vector3d& FaceFrame::at(const std::string& name) const {
  const auto it = landmarks.find(name);
  assert(it != landmarks.end());
  return it->second;
}

Eigen::Vector3d FaceFrame::offset(const std::string& name, int side, double x, double y, double z) const {
  return at(name) + iod * (side * x * right + y * up + z * forward);
}

const std::vector<std::string>& muscleRigLandmarkNames() {
  static const std::vector<std::string> names = [] {
    std::vector<std::string> n;
    auto add = [&](const std::string& prefix, int count, bool two_digits) {
      for (int i = 0; i < count; ++i) n.push_back(prefix + (two_digits && i < 10 ? "0" : "") + std::to_string(i));
    };
    add("jaw_", 17, true);
    add("brow_right_", 5, false);
    add("brow_left_", 5, false);
    add("nose_bridge_", 4, false);
    add("nose_base_", 5, false);
    add("eye_right_", 6, false);
    add("eye_left_", 6, false);
    add("mouth_outer_", 12, false);
    add("mouth_inner_", 8, false);
    return n;
  }();
  return names;
}

Result<FaceFrame> buildFaceFrame(const Mesh& face, const LandmarkSet& landmarks, const std::string& label) {
  for (const std::string& name : muscleRigLandmarkNames()) {
    if (landmarks.indexOf(name) < 0) {
      return makeError(ErrorCode::kInvalidLandmarks,
                       label + ": landmark \"" + name + "\" is missing (the muscle rig needs the 68 iBUG landmarks)");
    }
  }
  auto positions = resolveLandmarks(landmarks, face, label);
  if (!positions) return positions.error();
  FaceFrame frame;
  for (std::size_t i = 0; i < landmarks.landmarks.size(); ++i) {
    frame.landmarks[landmarks.landmarks[i].name] = positions->row(static_cast<Eigen::Index>(i)).transpose();
  }
  const Eigen::Vector3d eye_r = frame.at("eye_right_0"), eye_l = frame.at("eye_left_3");
  const Eigen::Vector3d mouth = 0.5 * (frame.at("mouth_outer_0") + frame.at("mouth_outer_6"));
  frame.iod = (eye_l - eye_r).norm();
  frame.origin = 0.5 * (eye_l + eye_r);
  if (!(frame.iod > 0.0)) return makeError(ErrorCode::kInvalidLandmarks, label + ": the outer eye corners coincide");
  frame.right = (eye_l - eye_r) / frame.iod;
  Eigen::Vector3d up = frame.origin - mouth;
  up -= up.dot(frame.right) * frame.right;
  if (!(up.norm() > 0.1 * frame.iod)) {
    return makeError(ErrorCode::kInvalidLandmarks, label + ": the mouth is at the height of the eyes");
  }
  frame.up = up.normalized();
  frame.forward = frame.right.cross(frame.up);
  frame.vertices = std::make_shared<const PointCloudIndex>(face.positions);
  return frame;
}

double MouthLine::heightAt(double x_frame) const {
  if (x_frame <= x.front()) return y.front();
  if (x_frame >= x.back()) return y.back();
  const auto hi = static_cast<std::size_t>(std::upper_bound(x.begin(), x.end(), x_frame) - x.begin());
  const double t = (x_frame - x[hi - 1]) / std::max(x[hi] - x[hi - 1], 1e-12);
  return y[hi - 1] + t * (y[hi] - y[hi - 1]);
}

MouthLine buildMouthLine(const FaceFrame& frame) {
  // Inner contour: 0 right corner, 1-3 upper, 4 left corner, 5-7 lower (7 under 1).
  auto inner = [&](int i) { return frame.toFrame(frame.at("mouth_inner_" + std::to_string(i))); };
  std::vector<Eigen::Vector3d> points = {inner(0), 0.5 * (inner(1) + inner(7)), 0.5 * (inner(2) + inner(6)),
                                         0.5 * (inner(3) + inner(5)), inner(4)};
  std::sort(points.begin(), points.end(), [](const auto& a, const auto& b) { return a.x() < b.x(); });
  MouthLine line;
  for (const Eigen::Vector3d& p : points) {
    if (!line.x.empty() && p.x() <= line.x.back() + 1e-9) continue;
    line.x.push_back(p.x());
    line.y.push_back(p.y());
  }
  if (line.x.size() < 2) {  // degenerate contour: a flat line through the corners
    line.x = {-1.0, 1.0};
    line.y = {points.front().y(), points.front().y()};
  }
  return line;
}

int FaceFrame::nearestVertex(const Eigen::Vector3d& point) const { return vertices->nearest(point).index; }

}  // namespace core
