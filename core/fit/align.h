// The similarity that carries the reference into the scan's frame
// (docs/FIT.md 2.2): from the scan's landmarks, or searched without them
// (align_search.h); and the units it implies.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

#include "core/base/error.h"
#include "core/fit/align_search.h"
#include "core/geometry/similarity.h"
#include "core/io/landmarks.h"

namespace core {

struct AlignmentReport {
  std::string method;                  // "landmarks" or "search"
  double rotation_deg = 0.0;           // angle of the rotation reference -> scan
  double yaw_deg = 0.0, pitch_deg = 0.0, roll_deg = 0.0;  // about Y, X, Z (applied Z, then X, then Y)
  double scale = 1.0;                  // scan units per reference unit (units and head size)
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();
  double rms_residual = 0.0;           // landmarks: their rms misfit; search: trimmed rms; scan units
  double inlier_fraction = 1.0;        // search only
  int hypotheses = 0;                  // search only
  double runner_up_ratio = 0.0;        // search only: best score / runner-up's (near 1: ambiguous)
  std::vector<std::string> landmarks_dropped;  // named: off by far more than the others
};

// reference_to_scan from paired landmarks (>= 4): Umeyama, then a landmark
// whose leave-one-out misfit exceeds 3x the median and `drop_distance`
// (scan units) is dropped and named, once.
struct LandmarkAlignment {
  Similarity reference_to_scan;
  std::vector<char> kept;              // #pairs
};
Result<LandmarkAlignment> alignByLandmarks(const LandmarkPairs& pairs, double drop_distance, AlignmentReport& report);

// The scan's units from the alignment's scale (scan units per reference
// unit): the reference's own unit from a head's size (its RMS radius about
// the centroid is 6-16 cm), the scan's the one of mm, cm, m, in whose ratio
// is log-nearest to the scale; what is left is the head's size against the
// reference's. `given`: "auto" or one of those names (then only the size is
// measured). Error: an unknown name, or a reference no head's size in any unit.
struct ScanUnits {
  std::string name;          // mm, cm, m, in
  double unit_scale = 1.0;   // scan units per reference unit
  double size_ratio = 1.0;   // scale / unit_scale
};
Result<ScanUnits> scanUnits(double scale, double reference_rms_radius, const std::string& given);

// Yaw, pitch and roll of a rotation (as AlignmentReport), degrees.
Eigen::Vector3d yawPitchRollDeg(const Eigen::Matrix3d& rotation);

}  // namespace core
