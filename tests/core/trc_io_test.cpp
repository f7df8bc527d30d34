#include "core/trc_io.h"

#include <cmath>
#include <random>
#include <string>

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
  options.max_gap_frames = -1;
  auto bad = core::parseTrc(kSmallTrc, "small.trc", options);
  ASSERT_FALSE(bad);
  EXPECT_EQ(bad.error().code, core::ErrorCode::kInvalidArgument);
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
