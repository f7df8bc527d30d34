#include "core/io/trc_io.h"

#include <cmath>
#include <cstdio>
#include <functional>
#include <random>
#include <string>

#include <Eigen/Geometry>

#include <gtest/gtest.h>

#include "tests/test_support.h"

namespace {

// Header for `markers` markers in the OpenSim layout (line 6 empty).
std::string trcHeader(int frames, const std::vector<std::string>& markers, const std::string& units = "mm") {
  std::string s = "PathFileType\t4\t(X/Y/Z)\ttest.trc\n";
  s += "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\tOrigDataStartFrame\tOrigNumFrames\n";
  s += "100.00\t100.00\t" + std::to_string(frames) + "\t" + std::to_string(markers.size()) + "\t" + units +
       "\t100.00\t1\t" + std::to_string(frames) + "\n";
  s += "Frame#\tTime";
  for (const auto& m : markers) s += "\t" + m + "\t\t";
  s += "\n\t";
  for (std::size_t i = 1; i <= markers.size(); ++i) {
    const std::string k = std::to_string(i);
    s += "\tX" + k + "\tY" + k + "\tZ" + k;
  }
  s += "\n\n";
  return s;
}

// Two markers, 5 frames at 100 Hz: A moves along x, B along y.
const std::string kSmallTrc = trcHeader(5, {"A", "B"}) +
                              "1\t0.00\t0\t0\t0\t10\t0\t0\n"
                              "2\t0.01\t1\t0\t0\t10\t1\t0\n"
                              "3\t0.02\t2\t0\t0\t10\t2\t0\n"
                              "4\t0.03\t3\t0\t0\t10\t3\t0\n"
                              "5\t0.04\t4\t0\t0\t10\t4\t0\n";

// A with a 2-frame gap (frames 1-2, empty and NaN cells), B missing at frame 0 (clip start).
// Two frames of A and B whose second row has a non-numeric Y for A (line 8).
const std::string kBadCellTrc = trcHeader(2, {"A", "B"}) + "1\t0.00\t0\t0\t0\t10\t0\t0\n2\t0.01\t1\tabc\t0\t10\t1\t0\n";

const std::string kGappedTrc = trcHeader(5, {"A", "B"}) +
                               "1\t0.00\t0\t0\t0\t\t\t\n"
                               "2\t0.01\t\t\t\t10\t1\t0\n"
                               "3\t0.02\tNaN\tNaN\tNaN\t10\t2\t0\n"
                               "4\t0.03\t3\t0\t0\t10\t3\t0\n"
                               "5\t0.04\t4\t0\t0\t10\t4\t0\n";

std::string replaceAll(std::string s, const std::string& from, const std::string& to) {
  for (std::size_t pos = 0; (pos = s.find(from, pos)) != std::string::npos; pos += to.size()) {
    s.replace(pos, from.size(), to);
  }
  return s;
}

// Vicon exports name markers "Subject:Marker": found by the marker's own
// name, an exact name first, never a guess between two subjects.
TEST(TrcIo, SubjectPrefixedMarkersAreFoundByTheirOwnName) {
  auto traj = core::parseTrc(trcHeader(1, {"Actor1:A", "Actor1:B", "B", "S1:C", "S2:C", ":D"}) +
                                 "1\t0.00\t0\t0\t0\t1\t0\t0\t2\t0\t0\t3\t0\t0\t4\t0\t0\t5\t0\t0\n",
                             "prefixed.trc");
  ASSERT_TRUE(traj) << traj.error().message;
  EXPECT_EQ(traj->markerIndex("A"), 0);
  EXPECT_EQ(traj->markerIndex("Actor1:A"), 0);
  EXPECT_EQ(traj->markerIndex("B"), 2);  // the exact name wins over Actor1:B
  EXPECT_EQ(traj->markerIndex("C"), -1); // two subjects carry it
  EXPECT_EQ(traj->markerIndex("S2:C"), 4);
  EXPECT_EQ(traj->markerIndex("D"), -1); // an empty subject is no subject
  EXPECT_EQ(traj->markerIndex("1:A"), -1);
}

TEST(TrcIo, ParsesHandWrittenFile) {
  auto traj = core::parseTrc(kSmallTrc, "small.trc");
  ASSERT_TRUE(traj) << traj.error().message;
  EXPECT_EQ(traj->markerCount(), 2);
  EXPECT_EQ(traj->frameCount(), 5);
  EXPECT_EQ(traj->marker_names, (std::vector<std::string>{"A", "B"}));
  EXPECT_EQ(traj->markerIndex("B"), 1);
  EXPECT_EQ(traj->markerIndex("C"), -1);
  EXPECT_DOUBLE_EQ(traj->data_rate, 100.0);
  EXPECT_EQ(traj->units, "mm");
  EXPECT_DOUBLE_EQ(traj->units_to_metres, 0.001);
  EXPECT_EQ(traj->header_frame_count, 5);
  ASSERT_EQ(traj->positions.cols(), 6);
  EXPECT_DOUBLE_EQ(traj->times(3), 0.03);
  EXPECT_DOUBLE_EQ(traj->positions(3, 0), 3.0);  // A.x at frame 3
  EXPECT_DOUBLE_EQ(traj->positions(3, 3), 10.0); // B.x
  EXPECT_DOUBLE_EQ(traj->positions(3, 4), 3.0);  // B.y
  EXPECT_TRUE(traj->filled_gaps.empty());
}

TEST(TrcIo, ToleratesCrlfTrailingTabsAndNoBlankLine) {
  std::string text = replaceAll(kSmallTrc, "\n", "\t\r\n");
  auto crlf = core::parseTrc(text, "crlf.trc");
  ASSERT_TRUE(crlf) << crlf.error().message;
  auto plain = core::parseTrc(kSmallTrc, "small.trc");
  ASSERT_TRUE(plain);
  EXPECT_EQ(crlf->positions, plain->positions);
  EXPECT_EQ(crlf->times, plain->times);
  auto bom = core::parseTrc("\xEF\xBB\xBF" + kSmallTrc, "bom.trc");
  ASSERT_TRUE(bom) << bom.error().message;
  EXPECT_EQ(bom->positions, plain->positions);
  // Without the optional empty line 6, and without a final newline.
  std::string compact = replaceAll(kSmallTrc, "\n\n", "\n");
  compact.pop_back();
  auto c = core::parseTrc(compact, "compact.trc");
  ASSERT_TRUE(c) << c.error().message;
  EXPECT_EQ(c->positions, plain->positions);
}

TEST(TrcIo, UnitsGiveScaleToMetres) {
  const std::vector<std::pair<std::string, double>> cases = {{"mm", 0.001}, {"cm", 0.01}, {"m", 1.0}};
  for (const auto& [units, scale] : cases) {
    std::string text = trcHeader(1, {"A"}, units) + "1\t0\t1\t2\t3\n";
    auto traj = core::parseTrc(text, "units.trc");
    ASSERT_TRUE(traj) << traj.error().message;
    EXPECT_EQ(traj->units, units);
    EXPECT_DOUBLE_EQ(traj->units_to_metres, scale);
  }
  auto inches = core::parseTrc(trcHeader(1, {"A"}, "in") + "1\t0\t1\t2\t3\n", "in.trc");
  ASSERT_FALSE(inches);
  EXPECT_EQ(inches.error().code, core::ErrorCode::kUnsupported);
  EXPECT_NE(inches.error().message.find("'in'"), std::string::npos) << inches.error().message;
}

TEST(TrcIo, FillsShortGapsByInterpolationAndReportsThem) {
  auto traj = core::parseTrc(kGappedTrc, "gapped.trc");
  ASSERT_TRUE(traj) << traj.error().message;
  ASSERT_TRUE(traj->positions.allFinite());
  // A: linear between frame 0 (x=0) and frame 3 (x=3).
  EXPECT_NEAR(traj->positions(1, 0), 1.0, 1e-12);
  EXPECT_NEAR(traj->positions(2, 0), 2.0, 1e-12);
  // B at the clip start: held at the first sample (frame 1).
  EXPECT_DOUBLE_EQ(traj->positions(0, 3), 10.0);
  EXPECT_DOUBLE_EQ(traj->positions(0, 4), 1.0);
  ASSERT_EQ(traj->filled_gaps.size(), 2u);
  EXPECT_EQ(traj->filled_gaps[0].marker, "A");
  EXPECT_EQ(traj->filled_gaps[0].first_frame, 1);
  EXPECT_EQ(traj->filled_gaps[0].frame_count, 2);
  EXPECT_EQ(traj->filled_gaps[1].marker, "B");
  EXPECT_EQ(traj->filled_gaps[1].first_frame, 0);
  EXPECT_EQ(traj->filled_gaps[1].frame_count, 1);
}

TEST(TrcIo, GapAtClipEndIsHeld) {
  std::string text = trcHeader(3, {"A"}) + "1\t0\t1\t2\t3\n2\t0.01\t4\t5\t6\n3\t0.02\t\t\t\n";
  auto traj = core::parseTrc(text, "end.trc");
  ASSERT_TRUE(traj) << traj.error().message;
  EXPECT_EQ(traj->positions.row(2), traj->positions.row(1));
}

TEST(TrcIo, TooLongGapIsAnErrorNamingMarkerAndFrames) {
  core::TrcReadOptions options;
  options.max_gap_frames = 1;
  auto traj = core::parseTrc(kGappedTrc, "gapped.trc", options);
  ASSERT_FALSE(traj);
  EXPECT_EQ(traj.error().code, core::ErrorCode::kParse);
  const std::string& msg = traj.error().message;
  EXPECT_NE(msg.find("gapped.trc"), std::string::npos) << msg;
  EXPECT_NE(msg.find("'A'"), std::string::npos) << msg;
  EXPECT_NE(msg.find("frames 1..2"), std::string::npos) << msg;
  // Two markers: too few neighbours to carry A through the gap.
  EXPECT_NE(msg.find("fewer than 3 other markers"), std::string::npos) << msg;
  options.max_gap_frames = -1;
  auto bad = core::parseTrc(kSmallTrc, "small.trc", options);
  ASSERT_FALSE(bad);
  EXPECT_EQ(bad.error().code, core::ErrorCode::kInvalidArgument);
}

// Five markers on a rigid plate that turns and slides, sampled at 100 Hz;
// `hide(marker, frame)` leaves a sample out.
std::string rigidPlateTrc(int frames, const std::function<bool(int, int)>& hide, Eigen::MatrixXd& truth) {
  const std::vector<std::string> names{"P0", "P1", "P2", "P3", "Q"};
  const Eigen::Matrix<double, 5, 3> local{{0, 0, 0}, {30, 0, 0}, {0, 25, 0}, {30, 25, 5}, {18, 12, 10}};
  truth.resize(frames, 15);
  std::string text = trcHeader(frames, names);
  for (int f = 0; f < frames; ++f) {
    const double t = 0.01 * f;
    const Eigen::Matrix3d rotation =
        (Eigen::AngleAxisd(6.0 * t, Eigen::Vector3d::UnitY()) * Eigen::AngleAxisd(0.8 * t, Eigen::Vector3d::UnitX()))
            .toRotationMatrix();
    const Eigen::Vector3d shift(100 * t, 5 * std::sin(6 * t), 700);
    text += std::to_string(f + 1) + "\t" + std::to_string(t);
    for (int m = 0; m < 5; ++m) {
      const Eigen::Vector3d p = rotation * local.row(m).transpose() + shift;
      truth.block<1, 3>(f, 3 * m) = p.transpose();
      for (int c = 0; c < 3; ++c) {
        char cell[32];
        std::snprintf(cell, sizeof cell, "%.9f", p(c));
        text += "\t" + (hide(m, f) ? std::string() : std::string(cell));
      }
    }
    text += "\n";
  }
  return text;
}

TEST(TrcIo, LongGapsAreCarriedByTheMarkersNearby) {
  // Q hidden for 40 frames mid-clip and for the first 15; P3 for 3 frames
  // inside Q's gap (interpolated first; still a donor, as it is measured on
  // both sides). A straight line in time would cut the turn.
  Eigen::MatrixXd truth;
  const std::string text = rigidPlateTrc(
      90, [](int m, int f) { return (m == 4 && ((f >= 30 && f < 70) || f < 15)) || (m == 3 && f >= 50 && f < 53); },
      truth);
  auto traj = core::parseTrc(text, "plate.trc");
  ASSERT_TRUE(traj) << traj.error().message;
  ASSERT_EQ(traj->filled_gaps.size(), 3u);
  EXPECT_EQ(traj->filled_gaps[0].marker, "P3");
  EXPECT_EQ(traj->filled_gaps[0].fill, core::GapFill::kInterpolated);
  for (int k : {1, 2}) {
    const core::TrcGap& gap = traj->filled_gaps[static_cast<std::size_t>(k)];
    EXPECT_EQ(gap.marker, "Q");
    EXPECT_EQ(gap.fill, core::GapFill::kFromNeighbours);
    EXPECT_EQ(gap.donors.size(), 4u);
  }
  EXPECT_EQ(traj->filled_gaps[1].first_frame, 0);
  EXPECT_EQ(traj->filled_gaps[2].first_frame, 30);
  EXPECT_EQ(traj->filled_gaps[2].frame_count, 40);
  double worst = 0.0;
  for (int f = 0; f < 70; ++f) {
    worst = std::max(worst, (traj->positions.block<1, 3>(f, 12) - truth.block<1, 3>(f, 12)).norm());
  }
  // Rigid motion is carried exactly, up to the printed decimals and P3's
  // interpolated frames (a 3-frame chord of the turn: 0.04 of the plate's 30).
  EXPECT_LT(worst, 0.1);
  const Eigen::RowVector3d line = 0.5 * (truth.block<1, 3>(29, 12) + truth.block<1, 3>(70, 12));
  EXPECT_GT((line - truth.block<1, 3>(50, 12)).norm(), 10.0) << "the test's motion must defeat interpolation";

  core::TrcReadOptions strict;
  strict.fill_long_gaps = false;
  auto refused = core::parseTrc(text, "plate.trc", strict);
  ASSERT_FALSE(refused);
  EXPECT_NE(refused.error().message.find("marker 'Q' is missing for 15 frames"), std::string::npos)
      << refused.error().message;
  EXPECT_NE(refused.error().message.find("fill_long_gaps is off"), std::string::npos) << refused.error().message;
}

TEST(TrcIo, LongGapNeedsNeighboursPresentThroughoutIt) {
  // P0's gap overlaps long gaps of P1 and Q: two neighbours left, not enough
  // for a rotation (one long-gap estimate never carries another).
  Eigen::MatrixXd truth;
  const std::string text = rigidPlateTrc(
      60, [](int m, int f) { return (m == 4 && f >= 20 && f < 40) || (m <= 1 && f >= 35 && f < 50); }, truth);
  auto traj = core::parseTrc(text, "plate.trc");
  ASSERT_FALSE(traj);
  const std::string& msg = traj.error().message;
  EXPECT_NE(msg.find("plate.trc:42-56"), std::string::npos) << msg;  // frame 0 is line 7
  EXPECT_NE(msg.find("marker 'P0' is missing for 15 frames (frames 35..49"), std::string::npos) << msg;
  EXPECT_NE(msg.find("fewer than 3 other markers"), std::string::npos) << msg;
}

TEST(TrcIo, MarkerWithNoSamplesIsAnError) {
  std::string text = trcHeader(2, {"A", "B"}) + "1\t0\t1\t2\t3\t\t\t\n2\t0.01\t1\t2\t3\t\t\t\n";
  auto traj = core::parseTrc(text, "empty_marker.trc");
  ASSERT_FALSE(traj);
  EXPECT_NE(traj.error().message.find("'B'"), std::string::npos) << traj.error().message;
}

// Each case: text, a fragment the message must contain.
TEST(TrcIo, MalformedContentGivesErrorsNamingLabelAndLine) {
  const std::string rows = "1\t0.00\t0\t0\t0\t10\t0\t0\n2\t0.01\t1\t0\t0\t10\t1\t0\n";
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"", "not a TRC file"},
      {"hello world\n", "not a TRC file"},
      {trcHeader(2, {"A", "A"}) + rows, "duplicate marker name 'A'"},
      {replaceAll(trcHeader(2, {"A", "B"}), "\t2\tmm", "\t3\tmm") + rows, "NumMarkers = 3"},
      {trcHeader(3, {"A", "B"}) + rows, "NumFrames = 3"},
      {kBadCellTrc, "'abc' of marker 'A' (Y)"},
      {trcHeader(2, {"A", "B"}) + "1\t0.00\t0\t0\t0\t10\t0\t0\n2\t0.00\t1\t0\t0\t10\t1\t0\n", "does not increase"},
      {trcHeader(2, {"A", "B"}) + "1\t0.00\t0\t0\t0\t10\t0\t0\n2\t0.01\t1\t0\t0\t10\t1\n", "truncated"},
      {trcHeader(2, {"A", "B"}) + "1\t0.00\t0\t0\t0\t10\t0\t0\t7\n" + rows, "more than"},
      {trcHeader(0, {"A", "B"}), "no data rows"},
      {replaceAll(trcHeader(2, {"A", "B"}), "100.00\t100.00", "x\t100.00") + rows, "DataRate"},
      {replaceAll(trcHeader(2, {"A", "B"}), "\tUnits", "\tUnitz") + rows, "'Units'"},
  };
  for (const auto& [text, fragment] : cases) {
    auto traj = core::parseTrc(text, "bad.trc");
    ASSERT_FALSE(traj) << "expected an error containing '" << fragment << "' for:\n" << text;
    const std::string& msg = traj.error().message;
    EXPECT_EQ(msg.rfind("bad.trc", 0), 0u) << msg;
    EXPECT_NE(msg.find(fragment), std::string::npos) << "message '" << msg << "' lacks '" << fragment << "'";
  }
  // Line numbers: the bad Y cell is on line 8 (line 6 is empty, rows start at 7).
  auto bad_cell = core::parseTrc(kBadCellTrc, "bad.trc");
  ASSERT_FALSE(bad_cell);
  EXPECT_EQ(bad_cell.error().message.rfind("bad.trc:8:", 0), 0u) << bad_cell.error().message;
}

TEST(TrcIo, FrameCountMismatchCanBeAllowed) {
  const std::string text = trcHeader(9, {"A", "B"}) + "1\t0.00\t0\t0\t0\t10\t0\t0\n2\t0.01\t1\t0\t0\t10\t1\t0\n";
  core::TrcReadOptions options;
  options.allow_frame_count_mismatch = true;
  auto traj = core::parseTrc(text, "trimmed.trc", options);
  ASSERT_TRUE(traj) << traj.error().message;
  EXPECT_EQ(traj->frameCount(), 2);
  EXPECT_EQ(traj->header_frame_count, 9);
}

// Every prefix of a valid file (and of its CRLF form) must give a clean Error
// or a valid parse; a valid parse of a prefix must have all its frames finite.
TEST(TrcIo, EveryTruncationGivesCleanErrorOrValidParse) {
  for (const std::string& full : {kGappedTrc, replaceAll(kSmallTrc, "\n", "\r\n")}) {
    int ok = 0;
    for (std::size_t n = 0; n < full.size(); ++n) {
      auto traj = core::parseTrc(std::string_view(full).substr(0, n), "cut.trc");
      if (traj) {
        ++ok;
        EXPECT_EQ(traj->frameCount(), 5) << "prefix " << n;
        EXPECT_TRUE(traj->positions.allFinite()) << "prefix " << n;
      } else {
        EXPECT_FALSE(traj.error().message.empty());
        EXPECT_EQ(traj.error().message.rfind("cut.trc", 0), 0u) << traj.error().message;
      }
    }
    // Only cuts inside the last number (or its line ending) can parse.
    EXPECT_LE(ok, 4);
  }
}

TEST(TrcIo, GarbageBytesGiveCleanErrors) {
  std::mt19937 rng(5);
  std::uniform_int_distribution<int> byte(0, 255);
  for (int trial = 0; trial < 200; ++trial) {
    std::string text = trial % 2 ? kSmallTrc : std::string();
    const int n = 1 + trial * 3;
    for (int i = 0; i < n; ++i) {
      const char c = static_cast<char>(byte(rng));
      if (text.empty() || trial % 4 == 0) {
        text.push_back(c);
      } else {
        text[static_cast<std::size_t>(byte(rng)) % text.size()] = c;  // corrupt a valid file in place
      }
    }
    auto traj = core::parseTrc(text, "garbage.trc");
    if (!traj) EXPECT_FALSE(traj.error().message.empty());
    else EXPECT_TRUE(traj->positions.allFinite());
  }
}

TEST(TrcIo, MissingFileIsAnIoError) {
  auto traj = core::readTrc("/nonexistent/dir/missing.trc");
  ASSERT_FALSE(traj);
  EXPECT_EQ(traj.error().code, core::ErrorCode::kIo);
}

TEST(TrcIo, ReadsTheRealAnimFaceClips) {
  RIGPORT_REQUIRE_SHARED_DATA(data);
  for (const auto& [file, frames] : std::vector<std::pair<std::string, int>>{{"animface_nose.trc", 962},
                                                                              {"animface_eyebrows.trc", 902}}) {
    auto traj = core::readTrc(data / "mocap" / file);
    ASSERT_TRUE(traj) << traj.error().message;
    EXPECT_EQ(traj->markerCount(), 41) << file;
    EXPECT_EQ(traj->frameCount(), frames) << file;
    EXPECT_DOUBLE_EQ(traj->data_rate, 60.0) << file;
    EXPECT_EQ(traj->units, "cm") << file;
    EXPECT_DOUBLE_EQ(traj->units_to_metres, 0.01) << file;
    EXPECT_TRUE(traj->positions.allFinite()) << file;
    EXPECT_GE(traj->markerIndex("Chin"), 0) << file;
    EXPECT_GE(traj->markerIndex("NoseHead"), 0) << file;
    EXPECT_DOUBLE_EQ(traj->times(0), 0.0) << file;
    // A face ~13 cm wide (MANIFEST): marker x spread in frame 0 between 8 and 20 cm.
    Eigen::VectorXd x(41);
    for (int m = 0; m < 41; ++m) x(m) = traj->positions(0, 3 * m);
    EXPECT_GT(x.maxCoeff() - x.minCoeff(), 8.0) << file;
    EXPECT_LT(x.maxCoeff() - x.minCoeff(), 20.0) << file;
  }
}

}  // namespace
