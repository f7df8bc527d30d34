// Mocap marker trajectories in the Motion Analysis TRC layout (tab separated:
// PathFileType line, header names line, header values line with DataRate,
// NumFrames, NumMarkers, Units..., marker-name line, X1/Y1/Z1 line, optional
// empty line, then `Frame# Time x y z ...` rows).
#pragma once

#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Core>

#include "core/base/error.h"

namespace core {

// How a gap was filled.
enum class GapFill {
  kInterpolated,    // linear in time between the samples either side (held at a clip end)
  kFromNeighbours,  // carried by the rigid motion of nearby markers (TrcGap::donors)
};

struct TrcGap {
  std::string marker;
  int first_frame = 0;   // 0-based frame index of the first missing sample
  int frame_count = 0;   // consecutive missing frames
  GapFill fill = GapFill::kInterpolated;
  std::vector<std::string> donors;  // kFromNeighbours: the markers it moved with
};

struct MarkerTrajectories {
  std::vector<std::string> marker_names;  // unique, file order
  double data_rate = 0.0;                 // frames per second
  std::string units;                      // as written ("mm", "cm", "m")
  double units_to_metres = 1.0;           // 0.001 for mm, 0.01 for cm, 1 for m
  Eigen::VectorXd times;                  // #frames seconds (from the Time column)
  // #frames by 3*#markers, in file units: row f = x0 y0 z0 x1 y1 z1 ... at frame f.
  Eigen::MatrixXd positions;
  std::vector<TrcGap> filled_gaps;        // gaps filled by interpolation, reported
  int header_frame_count = 0;             // NumFrames as written in the header (may differ only when
                                          // TrcReadOptions::allow_frame_count_mismatch is set)

  int frameCount() const { return static_cast<int>(positions.rows()); }
  int markerCount() const { return static_cast<int>(marker_names.size()); }
  // The marker called `name`, or else the one called "<subject>:<name>" (as
  // Vicon exports name them); -1 when absent or when several subjects have it.
  int markerIndex(std::string_view name) const;
};

struct TrcReadOptions {
  // Gaps (empty or NaN cells) up to this many frames are filled by linear interpolation (held at clip ends).
  int max_gap_frames = 10;
  // Longer gaps follow the rigid motion of the 3-4 nearest markers present throughout; false: an error.
  bool fill_long_gaps = true;
  // true: a header NumFrames unlike the row count is reported (header_frame_count), rows used; false: an error.
  bool allow_frame_count_mismatch = false;
};

// `label` (usually the file name) starts every error message, followed by the
// 1-based line number. Codes: kParse for malformed or inconsistent content and
// for gaps that cannot be filled (TrcReadOptions), kUnsupported for unknown Units,
// kInvalidArgument for a negative max_gap_frames, kIo (readTrc) for unreadable files.
Result<MarkerTrajectories> parseTrc(std::string_view text, const std::string& label,
                                    const TrcReadOptions& options = {});
Result<MarkerTrajectories> readTrc(const std::filesystem::path& path, const TrcReadOptions& options = {});

}  // namespace core
