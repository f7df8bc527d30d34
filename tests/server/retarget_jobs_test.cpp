// Job kind "retarget" through the service: mesh + marker placement + TRC clip
// -> animated GLB, byte-identical to `rigport retarget` in-process.
#include <gtest/gtest.h>

#include <cstdlib>
#include <fstream>
#include <functional>
#include <sstream>

#include "core/io/landmarks.h"
#include "core/io/mesh_io.h"
#include "core/synthetic/synthetic_head.h"
#include "tests/server/service_fixture.h"
#include "tests/test_support.h"

namespace rigport_test {
namespace {

struct RetargetFiles {
  std::filesystem::path mesh, markers, mocap;
};

// A head with an open mouth, 16 markers from its landmarks, and a 24-frame
// TRC clip (centimetres, shifted) in which the lower-lip and jaw markers open.
// `hidden(marker, frame)` leaves a sample out (a gap).
RetargetFiles writeRetargetFiles(const std::filesystem::path& dir,
                                 const std::function<bool(const std::string&, int)>& hidden = {}) {
  core::HeadShape shape;
  shape.mouth_open = 0.04;
  const core::SyntheticHead head = core::generateHead(shape, core::HeadResolution{64, 56});
  const char* names[] = {"brow_right_0", "brow_right_4", "brow_left_0", "brow_left_4", "nose_bridge_0", "nose_base_2",
                         "eye_right_0", "eye_left_3", "jaw_04", "jaw_08", "jaw_12", "mouth_outer_0",
                         "mouth_outer_3", "mouth_outer_6", "mouth_outer_9", "mouth_outer_10"};
  core::LandmarkSet markers;
  for (const char* n : names) markers.landmarks.push_back(head.landmarks.landmarks[static_cast<std::size_t>(head.landmarks.indexOf(n))]);
  auto placed = core::resolveLandmarks(markers, head.mesh, "head");
  EXPECT_TRUE(placed.ok());
  RetargetFiles f{dir / "face.glb", dir / "face.markers.json", dir / "jaw.trc"};
  EXPECT_TRUE(core::writeMeshGlb(head.mesh, f.mesh).ok());
  std::ofstream(f.markers) << core::formatLandmarks(markers);
  const int frames = 24;
  std::ostringstream trc;
  trc << "PathFileType\t4\t(X/Y/Z)\tjaw.trc\n"
      << "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\tOrigDataStartFrame\tOrigNumFrames\n"
      << "30.00\t30.00\t" << frames << "\t" << markers.landmarks.size() << "\tcm\t30.00\t1\t" << frames << "\n"
      << "Frame#\tTime";
  for (const auto& m : markers.landmarks) trc << "\t" << m.name << "\t\t";
  trc << "\n\t";
  for (std::size_t i = 1; i <= markers.landmarks.size(); ++i) trc << "\tX" << i << "\tY" << i << "\tZ" << i;
  trc << "\n\n";
  for (int frame = 0; frame < frames; ++frame) {
    trc << frame + 1 << "\t" << frame / 30.0;
    for (std::size_t i = 0; i < markers.landmarks.size(); ++i) {
      Eigen::Vector3d p = placed->row(static_cast<Eigen::Index>(i)).transpose();
      const std::string& name = markers.landmarks[i].name;
      if (name == "jaw_08" || name == "mouth_outer_9" || name == "mouth_outer_10") {
        p += Eigen::Vector3d(0.0, -0.006, -0.001) * frame / (frames - 1.0);
      }
      p = 100.0 * p + Eigen::Vector3d(2.0, 60.0, 0.0);
      if (hidden && hidden(name, frame)) {
        trc << "\t\t\t";
        continue;
      }
      trc << "\t" << p.x() << "\t" << p.y() << "\t" << p.z();
    }
    trc << "\n";
  }
  std::ofstream(f.mocap) << trc.str();
  return f;
}

std::string fileText(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

Reply submitRetarget(httplib::Client& client, const RetargetFiles& f, const std::string& options) {
  httplib::MultipartFormDataItems items = {
      {"spec", R"({"kind":"retarget","options":)" + options + "}", "spec.json", "application/json"},
      {"mesh", fileText(f.mesh), "face.glb", "model/gltf-binary"},
      {"markers", fileText(f.markers), "face.markers.json", "application/json"},
      {"mocap", fileText(f.mocap), "jaw.trc", "text/plain"}};
  auto res = client.Post("/v1/jobs", items);
  Reply r;
  if (!res) return r;
  r.status = res->status;
  r.raw = res->body;
  r.body = nlohmann::json::parse(res->body, nullptr, false);
  return r;
}

TEST(RetargetJobs, ServiceResultEqualsTheCliAndIsValidGltf) {
  const auto dir = makeTempDir("retarget");
  const RetargetFiles files = writeRetargetFiles(dir);
  const auto cli_out = dir / "cli.glb";
  const std::string cmd = std::string("'") + RIGPORT_CLI_PATH + "' -q retarget --mesh '" + files.mesh.string() +
                          "' --markers '" + files.markers.string() + "' --mocap '" + files.mocap.string() + "' -o '" +
                          cli_out.string() + "' --method geodesic";
  ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd;

  InProcessService service(testConfig(dir / "data"));
  auto client = service.client();
  Reply job = submitRetarget(*client, files, R"({"method":"geodesic"})");
  ASSERT_EQ(job.status, 202) << job.raw;
  const nlohmann::json done = waitForJob(*client, job.body["id"]);
  ASSERT_EQ(done["status"], "succeeded") << done.dump();
  Reply result = get(*client, "/v1/jobs/" + done["id"].get<std::string>() + "/result");
  ASSERT_EQ(result.status, 200);
  EXPECT_TRUE(result.raw == fileText(cli_out)) << "service retarget differs from the in-process CLI";
  const auto glb = dir / "service.glb";
  std::ofstream(glb, std::ios::binary) << result.raw;
  EXPECT_GLTF_VALID(glb);
  Reply diagnostics = get(*client, "/v1/jobs/" + done["id"].get<std::string>() + "/diagnostics");
  EXPECT_EQ(diagnostics.status, 200);
  EXPECT_FALSE(done["cache_hit"].get<bool>());

  // Another clip on the same mesh and markers reuses the distance fields.
  Reply again = submitRetarget(*client, files, R"({"method":"geodesic"})");
  ASSERT_EQ(again.status, 202) << again.raw;
  const nlohmann::json again_done = waitForJob(*client, again.body["id"]);
  ASSERT_EQ(again_done["status"], "succeeded");
  EXPECT_TRUE(again_done["cache_hit"].get<bool>());
  EXPECT_TRUE(get(*client, "/v1/jobs/" + again_done["id"].get<std::string>() + "/result").raw == result.raw);
  EXPECT_EQ(metricValue(*client, "rigport_cache_misses_total{cache=\"distances\"}"), 1.0);
}

TEST(RetargetJobs, BadOptionsAndClipsAreRejectedBeforeQueueing) {
  const auto dir = makeTempDir("retarget_errors");
  const RetargetFiles files = writeRetargetFiles(dir);
  InProcessService service(testConfig(dir / "data"));
  auto client = service.client();
  Reply r = submitRetarget(*client, files, R"({"method":"manhattan"})");
  EXPECT_EQ(r.status, 400) << r.raw;
  EXPECT_NE(r.body.value("detail", "").find("method"), std::string::npos) << r.raw;
  std::ofstream(files.mocap) << "PathFileType\t4\n";  // truncated clip
  r = submitRetarget(*client, files, "{}");
  EXPECT_EQ(r.status, 400) << r.raw;
  EXPECT_NE(r.body.value("detail", "").find("jaw.trc"), std::string::npos) << r.raw;
  EXPECT_TRUE(get(*client, "/v1/jobs").body["items"].empty());
}

// Stiffness out of its 1-9 scale, or for a marker the placement does not
// have, is refused at submission naming the marker (invalid-option, 400, as
// every option out of range), not accepted and failed later.
TEST(RetargetJobs, BadStiffnessIsRefusedAtSubmissionNamingTheMarker) {
  const auto dir = makeTempDir("retarget_stiffness");
  const RetargetFiles files = writeRetargetFiles(dir);
  InProcessService service(testConfig(dir / "data"));
  auto client = service.client();
  auto submit = [&](const std::string& stiffness) {
    httplib::MultipartFormDataItems items = {
        {"spec", R"({"kind":"retarget"})", "spec.json", "application/json"},
        {"mesh", fileText(files.mesh), "face.glb", "model/gltf-binary"},
        {"markers", fileText(files.markers), "face.markers.json", "application/json"},
        {"mocap", fileText(files.mocap), "jaw.trc", "text/plain"},
        {"stiffness", stiffness, "stiffness.json", "application/json"}};
    auto res = client->Post("/v1/jobs", items);
    return res ? std::make_pair(res->status, nlohmann::json::parse(res->body, nullptr, false))
               : std::make_pair(0, nlohmann::json());
  };
  const auto [negative_status, negative] = submit(R"({"jaw_08": -2})");
  EXPECT_EQ(negative_status, 400) << negative.dump();
  EXPECT_EQ(negative.value("type", ""), "urn:rigport:problem:invalid-option");
  EXPECT_NE(negative.value("detail", "").find("stiffness of jaw_08 is -2 (the scale is 1-9)"), std::string::npos)
      << negative.dump();
  const auto [unknown_status, unknown] = submit(R"({"chin_tip": 3})");
  EXPECT_EQ(unknown_status, 400) << unknown.dump();
  EXPECT_NE(unknown.value("detail", "").find("'chin_tip' is not a marker"), std::string::npos) << unknown.dump();
  EXPECT_TRUE(get(*client, "/v1/jobs").body["items"].empty());
  const auto [good_status, good] = submit(R"({"jaw_08": 4})");
  ASSERT_EQ(good_status, 202) << good.dump();
  EXPECT_EQ(waitForJob(*client, good["id"])["status"], "succeeded");
}

// A marker hidden for 16 frames (longer than the 10 interpolated by
// default): carried by its neighbours and listed in the diagnostics; an
// error when long-gap filling is off; interpolated when max_gap_frames covers it.
TEST(RetargetJobs, LongClipGapsAreFilledFromNeighboursOrRefusedOnRequest) {
  const auto dir = makeTempDir("retarget_gaps");
  const RetargetFiles files =
      writeRetargetFiles(dir, [](const std::string& name, int f) { return name == "mouth_outer_3" && f >= 4 && f < 20; });
  InProcessService service(testConfig(dir / "data"));
  auto client = service.client();

  Reply job = submitRetarget(*client, files, "{}");
  ASSERT_EQ(job.status, 202) << job.raw;
  nlohmann::json done = waitForJob(*client, job.body["id"]);
  ASSERT_EQ(done["status"], "succeeded") << done.dump();
  nlohmann::json gaps = get(*client, "/v1/jobs/" + done["id"].get<std::string>() + "/diagnostics").body["gaps"];
  ASSERT_EQ(gaps.size(), 1u) << gaps.dump();
  EXPECT_EQ(gaps[0]["marker"], "mouth_outer_3");
  EXPECT_EQ(gaps[0]["first_frame"], 4);
  EXPECT_EQ(gaps[0]["frames"], 16);
  EXPECT_EQ(gaps[0]["fill"], "neighbours");
  EXPECT_GE(gaps[0]["donors"].size(), 3u);

  Reply refused = submitRetarget(*client, files, R"({"fill_long_gaps":false})");
  EXPECT_EQ(refused.status, 400) << refused.raw;
  EXPECT_NE(refused.body.value("detail", "").find("'mouth_outer_3' is missing for 16 frames"), std::string::npos)
      << refused.raw;

  Reply interpolated = submitRetarget(*client, files, R"({"max_gap_frames":16})");
  ASSERT_EQ(interpolated.status, 202) << interpolated.raw;
  done = waitForJob(*client, interpolated.body["id"]);
  ASSERT_EQ(done["status"], "succeeded") << done.dump();
  gaps = get(*client, "/v1/jobs/" + done["id"].get<std::string>() + "/diagnostics").body["gaps"];
  ASSERT_EQ(gaps.size(), 1u) << gaps.dump();
  EXPECT_EQ(gaps[0]["fill"], "interpolated");
  EXPECT_TRUE(gaps[0]["donors"].empty());

  for (const char* bad : {R"({"max_gap_frames":-1})", R"({"max_gap_frames":2.5})", R"({"fill_long_gaps":"yes"})"}) {
    Reply r = submitRetarget(*client, files, bad);
    EXPECT_EQ(r.status, 400) << bad << " " << r.raw;
  }
}

}  // namespace
}  // namespace rigport_test
