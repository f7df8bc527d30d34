// Mocap calibration for retargetMocap: the rest frame's markers mapped onto
// the placed markers by a similarity (Umeyama 1991) and the local Jacobian of
// a TPS (Bookstein 1989) from the aligned rest markers to the placed ones
// (paper 002 algorithm 4.1, here instead of 1:1 offsets); rigid head motion
// measured on the markers the expression moves least and removed.
#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

#include <Eigen/Geometry>
#include <Eigen/SVD>

#include "core/geometry/similarity.h"
#include "core/retarget/retarget_stages.h"
#include "core/solve/tps.h"

namespace core {

namespace {

Result<Calibration> calibrate(const Eigen::MatrixX3d& rest, const Eigen::MatrixX3d& placed, const RetargetOptions& options) {
  Calibration c;
  c.similarity = fitSimilarity(rest, placed);
  const Eigen::MatrixX3d aligned =
      ((c.similarity.scale * rest * c.similarity.rotation.transpose()).rowwise() + c.similarity.translation.transpose()).eval();
  c.similarity_rms = c.similarity.rms_residual;
  const Eigen::Matrix3d linear = c.similarity.scale * c.similarity.rotation;
  std::vector<Eigen::Matrix3d> jacobians(static_cast<std::size_t>(rest.rows()), Eigen::Matrix3d::Identity());
  if (options.calibration_jacobian) {
    TpsOptions tps;
    tps.regularization = options.calibration_regularization * boundingBoxDiagonal(placed);
    tps.leave_one_out = false;
    auto warp = fitTps(aligned, placed, tps);
    if (!warp) return warp.error();
    jacobians = warp->jacobians(aligned);
  }
  c.min_singular = std::numeric_limits<double>::infinity();
  for (const Eigen::Matrix3d& j : jacobians) {
    const Eigen::Vector3d sv = Eigen::JacobiSVD<Eigen::Matrix3d>(j).singularValues();
    c.min_singular = std::min(c.min_singular, sv(2));
    c.max_singular = std::max(c.max_singular, sv(0));
    c.maps.push_back(j * linear);
  }
  return c;
}

// Rotation and translation taking a frame's head markers onto the rest
// frame's (Umeyama; the rotation does not depend on the scale).
struct RigidMotion {
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  Eigen::RowVector3d translation = Eigen::RowVector3d::Zero();
};

// frames: #frames x 3#markers (marker i in columns 3i..3i+2), rest: #markers x 3.
std::vector<RigidMotion> headMotion(const Eigen::MatrixXd& frames, const Eigen::MatrixX3d& rest,
                                    const std::vector<Eigen::Index>& head) {
  const auto nh = static_cast<Eigen::Index>(head.size());
  Eigen::MatrixX3d rest_head(nh, 3), frame_head(nh, 3);
  for (Eigen::Index h = 0; h < nh; ++h) rest_head.row(h) = rest.row(head[static_cast<std::size_t>(h)]);
  const Eigen::RowVector3d rest_mean = rest_head.colwise().mean();
  std::vector<RigidMotion> motion(static_cast<std::size_t>(frames.rows()));
  for (Eigen::Index f = 0; f < frames.rows(); ++f) {
    for (Eigen::Index h = 0; h < nh; ++h) frame_head.row(h) = frames.block(f, 3 * head[static_cast<std::size_t>(h)], 1, 3);
    RigidMotion& m = motion[static_cast<std::size_t>(f)];
    m.rotation = fitSimilarity(frame_head, rest_head).rotation;
    m.translation = rest_mean - frame_head.colwise().mean() * m.rotation.transpose();
  }
  return motion;
}

// The markers the expression moves least: aligned on the current set, each
// marker's rms distance from its rest position over the clip; the half at or
// below the median is the next set (two rounds from all markers). A jaw
// opening moves a third of the AnimFace markers by centimetres; aligned on
// all of them, the fit turns the whole head with it (measured on a still face
// with a known head motion and a 2 cm jaw, brow or cheek movement added: the
// removal left 0.13-0.27 cm of error on the average marker; on the stable
// half, none). Fewer than 6 markers: all.
std::vector<Eigen::Index> stableHeadMarkers(const Eigen::MatrixXd& frames, const Eigen::MatrixX3d& rest) {
  const Eigen::Index nm = rest.rows();
  std::vector<Eigen::Index> head(static_cast<std::size_t>(nm));
  std::iota(head.begin(), head.end(), Eigen::Index{0});
  if (nm < 6) return head;
  for (int round = 0; round < 2; ++round) {
    const std::vector<RigidMotion> motion = headMotion(frames, rest, head);
    std::vector<double> moved(static_cast<std::size_t>(nm), 0.0);
    for (Eigen::Index f = 0; f < frames.rows(); ++f) {
      const RigidMotion& m = motion[static_cast<std::size_t>(f)];
      for (Eigen::Index i = 0; i < nm; ++i) {
        const Eigen::RowVector3d aligned = frames.block(f, 3 * i, 1, 3) * m.rotation.transpose() + m.translation;
        moved[static_cast<std::size_t>(i)] += (aligned - rest.row(i)).squaredNorm();
      }
    }
    std::vector<double> sorted = moved;
    const auto middle = sorted.begin() + static_cast<std::ptrdiff_t>(nm / 2);
    std::nth_element(sorted.begin(), middle, sorted.end());
    head.clear();
    for (Eigen::Index i = 0; i < nm; ++i) {
      if (moved[static_cast<std::size_t>(i)] <= *middle) head.push_back(i);
    }
  }
  return head;
}

// The rest frame's markers: #M by 3, mocap units.
Eigen::MatrixX3d restMarkers(const MarkerTrajectories& clip, const std::vector<int>& column, int rest_frame) {
  const auto nm = static_cast<Eigen::Index>(column.size());
  Eigen::MatrixX3d rest(nm, 3);
  for (Eigen::Index i = 0; i < nm; ++i) {
    rest.row(i) = clip.positions.block(rest_frame, 3 * column[static_cast<std::size_t>(i)], 1, 3);
  }
  return rest;
}

// The clip's columns in marker-set order: #frames by 3#M (marker i in
// columns 3i..3i+2), mocap units.
Eigen::MatrixXd framesInSetOrder(const MarkerTrajectories& clip, const std::vector<int>& column) {
  const auto nm = static_cast<Eigen::Index>(column.size());
  Eigen::MatrixXd frames(clip.frameCount(), 3 * nm);
  for (Eigen::Index i = 0; i < nm; ++i) {
    frames.middleCols(3 * i, 3) = clip.positions.middleCols(3 * column[static_cast<std::size_t>(i)], 3);
  }
  return frames;
}

// The markers rigid head motion is measured on (indices into the marker
// set): the `named` ones, or the stable half of the set (stableHeadMarkers).
Result<std::vector<Eigen::Index>> chooseHeadMarkers(const std::vector<std::string>& marker_names,
                                                    const std::vector<std::string>& named, const Eigen::MatrixXd& frames,
                                                    const Eigen::MatrixX3d& rest) {
  std::vector<Eigen::Index> head;
  for (const std::string& name : named) {
    const auto it = std::find(marker_names.begin(), marker_names.end(), name);
    if (it == marker_names.end()) {
      return makeError(ErrorCode::kInvalidArgument, "retarget: unknown head marker " + name);
    }
    head.push_back(it - marker_names.begin());
  }
  if (head.empty()) head = stableHeadMarkers(frames, rest);
  if (head.size() < 3) {
    return makeError(ErrorCode::kInvalidArgument, "retarget: at least 3 head markers are needed to remove head motion");
  }
  return head;
}

// frames: #frames by 3#M, rest: #M by 3 (mocap units); head_motion: one per frame.
MeshSpaceDisplacements displacementsInMeshSpace(const Eigen::MatrixXd& frames, const Eigen::MatrixX3d& rest,
                                                const Calibration& calibration,
                                                const std::vector<RigidMotion>& head_motion, bool remove_head_motion) {
  const Eigen::Index nm = rest.rows();
  const int nf = static_cast<int>(frames.rows());
  MeshSpaceDisplacements out;
  Eigen::MatrixXd& rhs = out.rhs;
  rhs.resize(nm, 3 * static_cast<Eigen::Index>(nf));
  Eigen::MatrixX3d frame(nm, 3);
  for (int f = 0; f < nf; ++f) {
    for (Eigen::Index i = 0; i < nm; ++i) frame.row(i) = frames.block(f, 3 * i, 1, 3);
    const Eigen::Matrix3d& rotation = head_motion[static_cast<std::size_t>(f)].rotation;
    const Eigen::RowVector3d& translation = head_motion[static_cast<std::size_t>(f)].translation;
    out.head_max_rotation_deg = std::max(out.head_max_rotation_deg,
                                         Eigen::AngleAxisd(rotation).angle() * 180.0 / 3.14159265358979323846);
    out.head_max_translation = std::max(out.head_max_translation, calibration.similarity.scale * translation.norm());
    if (remove_head_motion) frame = ((frame * rotation.transpose()).rowwise() + translation).eval();
    for (Eigen::Index i = 0; i < nm; ++i) {
      const Eigen::Vector3d d = (frame.row(i) - rest.row(i)).transpose();
      rhs.block(i, 3 * f, 1, 3) = (calibration.maps[static_cast<std::size_t>(i)] * d).transpose();
    }
  }
  for (int f = 0; f < nf; ++f) {
    for (Eigen::Index i = 0; i < nm; ++i) {
      out.max_marker_displacement = std::max(out.max_marker_displacement, rhs.block(i, 3 * f, 1, 3).norm());
    }
  }
  return out;
}

}  // namespace

Result<CalibratedClip> calibrateClip(const MarkerDistances& distances, const MarkerTrajectories& clip,
                                     const std::vector<int>& column, const RetargetOptions& options) {
  const Eigen::MatrixX3d rest = restMarkers(clip, column, options.rest_frame);
  if (auto ok = checkTpsCentres(distances.marker_positions); !ok) return ok.error();
  auto calibration = calibrate(rest, distances.marker_positions, options);
  if (!calibration) return calibration.error();
  const Eigen::MatrixXd frames = framesInSetOrder(clip, column);
  auto head = chooseHeadMarkers(distances.marker_names, options.head_markers, frames, rest);
  if (!head) return head.error();
  const std::vector<RigidMotion> head_motion = headMotion(frames, rest, *head);
  MeshSpaceDisplacements displacements =
      displacementsInMeshSpace(frames, rest, *calibration, head_motion, options.remove_head_motion);
  return CalibratedClip{std::move(*calibration), std::move(*head), std::move(displacements)};
}

}  // namespace core
