// Job kind "fit" through the service: a reference rig (uploaded as for
// transfers) and a head scan -> the rig rebuilt on the fitted reference,
// byte-identical to `rigport fit` in-process and to `rigport fit --server`;
// what submission refuses; the fit cache; cancellation; the gate's refusal.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <set>
#include <thread>

#include "api/types.h"
#include "core/io/landmarks.h"
#include "core/io/mesh_io.h"
#include "core/io/rig_io.h"
#include "core/jobs/fit_options.h"
#include "core/synthetic/synthetic_head.h"
#include "core/synthetic/synthetic_rig.h"
#include "tests/server/service_fixture.h"
#include "tests/test_support.h"

namespace rigport_test {
namespace {

struct FitFiles {
  std::filesystem::path rig, landmarks, scan, scan_landmarks;
  TransferFiles reference() const { return {rig, landmarks, {}, {}, {}}; }  // what uploadRig sends
};

std::string fileText(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

void writeText(const std::filesystem::path& p, const std::string& text) {
  std::ofstream out(p, std::ios::binary);
  out << text;
  ASSERT_TRUE(out.flush()) << p;
}

// An ASCII PLY of points alone (a cloud: no faces, no normals).
void writePlyCloud(const std::filesystem::path& p, const Eigen::MatrixX3d& points) {
  std::string text = "ply\nformat ascii 1.0\nelement vertex " + std::to_string(points.rows()) +
                     "\nproperty float x\nproperty float y\nproperty float z\nend_header\n";
  char line[96];
  for (Eigen::Index i = 0; i < points.rows(); ++i) {
    std::snprintf(line, sizeof line, "%.6g %.6g %.6g\n", points(i, 0), points(i, 1), points(i, 2));
    text += line;
  }
  writeText(p, text);
}

// The reference: the generated rig (68 landmarks). The scan: another identity
// (seed 3), sampled on another jittered grid, in millimetres, as a point cloud
// with its landmarks as positions. `scan_cells` sets the scan's grid,
// `reference_cells` the rig's (larger = slower jobs); `scale` multiplies the
// scan (1.6: a head far larger than the reference). Coarser grids do not
// pass as they should: a 48-cell reference ends its inner mouth corners over
// 0.006 d from the scan's (the gate warns), and on a cloud of under ~6000
// points a jaw landmark can lie farther from the nearest point than the
// 0.01 d allowed (refused as off the scan).
FitFiles writeFitFiles(const std::filesystem::path& dir, int scan_cells = 120, int reference_cells = 72,
                       double scale = 1.0) {
  std::filesystem::create_directories(dir);
  FitFiles f{dir / "reference.glb", dir / "reference.landmarks.json", dir / "scan.ply", dir / "scan.landmarks.json"};
  core::HeadResolution reference_res;
  reference_res.columns = reference_cells;
  reference_res.rows = reference_cells * 5 / 6;
  const core::SyntheticRig rig = core::generateRig({}, reference_res);
  EXPECT_TRUE(core::writeRigGlb(rig.rig, f.rig).ok());
  writeText(f.landmarks, core::formatLandmarks(rig.landmarks));

  core::HeadResolution scan_res;
  scan_res.columns = scan_cells;
  scan_res.rows = scan_cells * 7 / 8;
  scan_res.alternate_diagonals = true;
  scan_res.jitter = 0.3;
  scan_res.seed = 3;
  const core::SyntheticHead head = core::generateHead(core::randomHeadShape(3, 0.15), scan_res);
  const double to_mm = 1000.0 * scale;
  writePlyCloud(f.scan, to_mm * head.mesh.positions);
  auto positions = core::resolveLandmarks(head.landmarks, head.mesh, "scan");
  EXPECT_TRUE(positions.ok());
  core::LandmarkSet placed;
  for (std::size_t i = 0; i < head.landmarks.landmarks.size(); ++i) {
    core::Landmark l;
    l.name = head.landmarks.landmarks[i].name;
    l.kind = core::LandmarkKind::kPosition;
    l.position = to_mm * positions->row(static_cast<Eigen::Index>(i)).transpose();
    placed.landmarks.push_back(l);
  }
  writeText(f.scan_landmarks, core::formatLandmarks(placed));
  return f;
}

std::string quoted(const std::filesystem::path& p) { return "'" + p.string() + "'"; }

// `rigport fit` on `f` (with its scan landmarks unless `searched`), writing
// out.glb and out.json in `dir`; `flags` are appended (--server, --options...).
CliRun runCliFit(const FitFiles& f, const std::filesystem::path& dir, const std::string& flags = "",
                 bool searched = false) {
  std::filesystem::remove(dir / "out.glb");
  std::filesystem::remove(dir / "out.json");
  return runRigportCli("fit --reference " + quoted(f.rig) + " --reference-landmarks " + quoted(f.landmarks) +
                       " --scan " + quoted(f.scan) +
                       (searched ? std::string() : " --scan-landmarks " + quoted(f.scan_landmarks)) + " -o " +
                       quoted(dir / "out.glb") + " --diagnostics " + quoted(dir / "out.json") + " " + flags);
}

Reply postParts(httplib::Client& client, const httplib::MultipartFormDataItems& items) {
  auto res = client.Post("/v1/jobs", items);
  Reply r;
  if (!res) return r;
  r.status = res->status;
  r.raw = res->body;
  r.content_type = res->get_header_value("Content-Type");
  r.body = nlohmann::json::parse(res->body, nullptr, false);
  return r;
}

// A fit job's multipart body: the spec, the scan and (when not empty) the
// scan landmarks, each as text with its file name.
httplib::MultipartFormDataItems fitParts(const std::string& rig_id, const std::string& scan, const std::string& scan_name,
                                         const std::string& landmarks, const nlohmann::json& options = nlohmann::json::object()) {
  const nlohmann::json spec = {{"kind", "fit"}, {"rig", rig_id}, {"options", options}};
  httplib::MultipartFormDataItems items = {{"spec", spec.dump(), "spec.json", "application/json"},
                                           {"scan", scan, scan_name, "application/octet-stream"}};
  if (!landmarks.empty()) items.push_back({"scan_landmarks", landmarks, "scan.landmarks.json", "application/json"});
  return items;
}

Reply submitFit(httplib::Client& client, const std::string& rig_id, const FitFiles& f, bool with_landmarks = true,
                const nlohmann::json& options = nlohmann::json::object()) {
  return postParts(client, fitParts(rig_id, fileText(f.scan), f.scan.filename().string(),
                                    with_landmarks ? fileText(f.scan_landmarks) : "", options));
}

std::string uploadReference(httplib::Client& client, const FitFiles& f) {
  const Reply rig = uploadRig(client, f.reference());
  EXPECT_EQ(rig.status, 201) << rig.raw;
  return rig.body.value("id", "");
}

TEST(FitJobs, ServiceResultEqualsTheCliAndASecondJobTakesTheCachedReference) {
  const auto dir = makeTempDir("fit_lifecycle");
  const FitFiles files = writeFitFiles(dir);
  const CliRun cli = runCliFit(files, dir);
  ASSERT_EQ(cli.exit_code, 0) << cli.log;
  const std::string expected = fileText(dir / "out.glb");
  ASSERT_FALSE(expected.empty());

  InProcessService service(testConfig(dir / "data"));
  auto client = service.client();
  const std::string rig_id = uploadReference(*client, files);
  const Reply job = submitFit(*client, rig_id, files);
  ASSERT_EQ(job.status, 202) << job.raw;
  EXPECT_EQ(job.body["kind"], "fit");
  const std::string id = job.body["id"];
  const nlohmann::json done = waitForJob(*client, id);
  ASSERT_EQ(done["status"], "succeeded") << done.dump();
  EXPECT_EQ(done["progress"], 1.0);
  EXPECT_FALSE(done["cache_hit"].get<bool>());
  EXPECT_EQ(done["files"]["scan"], "scan.ply") << done.dump();
  EXPECT_EQ(done["files"]["scan_landmarks"], "scan.landmarks.json") << done.dump();
  const nlohmann::json& t = done["timings_ms"];
  for (const char* stage : {"read", "prepare", "scan", "align", "fit", "gate", "rebuild", "write", "total"}) {
    EXPECT_TRUE(t.contains(stage)) << stage << ": " << done.dump();
  }
  EXPECT_GT(t["prepare"].get<double>(), 0.0);
  EXPECT_GT(t["total"].get<double>(), 0.0);
  std::printf("fit job (%s): %s\n", done["files"]["scan"].get<std::string>().c_str(), t.dump().c_str());

  const Reply result = get(*client, "/v1/jobs/" + id + "/result");
  ASSERT_EQ(result.status, 200);
  EXPECT_EQ(result.content_type, "model/gltf-binary");
  EXPECT_TRUE(result.raw == expected) << "service fit differs from the in-process CLI (" << result.raw.size() << " vs "
                                      << expected.size() << " bytes)";
  writeText(dir / "service.glb", result.raw);
  EXPECT_GLTF_VALID(dir / "service.glb");

  const Reply diagnostics = get(*client, "/v1/jobs/" + id + "/diagnostics");
  ASSERT_EQ(diagnostics.status, 200);
  const nlohmann::json& d = diagnostics.body;
  EXPECT_EQ(d["verdict"], "ok") << diagnostics.raw.substr(0, 600);
  EXPECT_TRUE(d["reasons"].empty()) << d["reasons"].dump();
  EXPECT_EQ(d["alignment"]["method"], "landmarks");
  EXPECT_TRUE(d["scan"]["point_cloud"].get<bool>());
  EXPECT_EQ(d["scan"]["units"], "mm");
  EXPECT_EQ(d["landmarks"]["count"], 68);
  EXPECT_GT(d["timings_ms"]["total"].get<double>(), 0.0);
  EXPECT_FALSE(d["cache"]["hit"].get<bool>());
  EXPECT_EQ(d["rebuild"]["shapes"], 6);

  // A second job on the same reference skips all reference-only work.
  const Reply second = submitFit(*client, rig_id, files);
  ASSERT_EQ(second.status, 202) << second.raw;
  const nlohmann::json second_done = waitForJob(*client, second.body["id"]);
  ASSERT_EQ(second_done["status"], "succeeded") << second_done.dump();
  EXPECT_TRUE(second_done["cache_hit"].get<bool>());
  EXPECT_EQ(second_done["timings_ms"]["prepare"], 0.0);
  std::printf("fit job, cached reference: %s\n", second_done["timings_ms"].dump().c_str());
  EXPECT_EQ(get(*client, "/v1/jobs/" + second_done["id"].get<std::string>() + "/result").raw, expected);
  EXPECT_EQ(metricValue(*client, "rigport_cache_misses_total{cache=\"fit\"}"), 1.0);
  EXPECT_EQ(metricValue(*client, "rigport_cache_hits_total{cache=\"fit\"}"), 1.0);
}

// `rigport fit --server` uploads the reference, submits, waits and writes the
// service's result: the in-process bytes; --strict reaches the job's options.
TEST(FitJobs, CliWithServerWritesTheInProcessResult) {
  const auto dir = makeTempDir("fit_remote");
  const FitFiles files = writeFitFiles(dir);
  const CliRun local = runCliFit(files, dir);
  ASSERT_EQ(local.exit_code, 0) << local.log;
  const std::string expected = fileText(dir / "out.glb");

  InProcessService service(testConfig(dir / "data"));
  const std::string server = "--server http://127.0.0.1:" + std::to_string(service.port());
  const CliRun remote = runCliFit(files, dir, server);
  ASSERT_EQ(remote.exit_code, 0) << remote.log;
  EXPECT_TRUE(fileText(dir / "out.glb") == expected) << "`fit --server` wrote other bytes than the in-process fit";
  const auto d = nlohmann::json::parse(fileText(dir / "out.json"), nullptr, false);
  EXPECT_EQ(d.value("verdict", ""), "ok") << remote.log;
  EXPECT_NE(remote.log.find("fit (job "), std::string::npos) << remote.log;
  EXPECT_NE(remote.log.find("ok (landmarks alignment, scan in mm"), std::string::npos) << remote.log;

  // A head 1.6 times the reference's size: the gate warns (check the units),
  // which --strict turns into a failed job, as in-process.
  const FitFiles big = writeFitFiles(dir / "big", 120, 72, 1.6);
  const CliRun warned = runCliFit(big, dir, server);
  ASSERT_EQ(warned.exit_code, 0) << warned.log;
  EXPECT_NE(warned.log.find("warn (landmarks alignment"), std::string::npos) << warned.log;
  EXPECT_NE(warned.log.find("check the units"), std::string::npos) << warned.log;
  const CliRun strict = runCliFit(big, dir, server + " --strict");
  EXPECT_EQ(strict.exit_code, 1) << strict.log;
  EXPECT_NE(strict.log.find("quality gate (strict): the head is 1."), std::string::npos) << strict.log;
  EXPECT_FALSE(std::filesystem::exists(dir / "out.glb"));
  // The refused fit's diagnostics are written, as in-process.
  const auto refused = nlohmann::json::parse(fileText(dir / "out.json"), nullptr, false);
  EXPECT_EQ(refused.value("verdict", ""), "warn") << strict.log;
  const CliRun strict_local = runCliFit(big, dir, "--strict");
  EXPECT_EQ(strict_local.exit_code, 1) << strict_local.log;
  EXPECT_FALSE(std::filesystem::exists(dir / "out.glb"));
}

// A reference with a components document: `fit --server` uploads it with
// the reference and writes the service's rebuilt document, the same bytes as
// the in-process fit's; bindings by vertex stay as they were.
TEST(FitJobs, ComponentsUploadedWithTheReferenceComeBackRebuilt) {
  const auto dir = makeTempDir("fit_components");
  const FitFiles files = writeFitFiles(dir);
  writeText(dir / "reference.components.json",
            R"({"format": "rigport.components", "version": 1,
                "locators": [{"name": "nose", "binding": {"vertex": 120}},
                             {"name": "free", "binding": {"position": [0.01, 0.02, 0.03]}}],
                "clusters": [{"name": "lip_c", "pivot": {"face": 10, "barycentric": [0.2, 0.3, 0.5]},
                              "members": [{"vertex": 49, "weight": 1.0}, {"vertex": 38, "weight": 0.5}]}],
                "controls": [{"name": "lift", "drives": [{"cluster": "lip_c", "channel": "translate_y", "gain": 0.01}]}],
                "presets": {"lifted": {"controls": {"lift": 1}}}})");
  const std::string flags = "--reference-components " + quoted(dir / "reference.components.json") +
                            " --components-out " + quoted(dir / "out.components.json");
  const CliRun local = runCliFit(files, dir, flags);
  ASSERT_EQ(local.exit_code, 0) << local.log;
  const std::string expected = fileText(dir / "out.components.json");
  const auto doc = nlohmann::json::parse(expected, nullptr, false);
  ASSERT_TRUE(doc.is_object()) << local.log;
  EXPECT_EQ(doc["locators"][0]["binding"], nlohmann::json::parse(R"({"vertex": 120})"));
  EXPECT_EQ(doc["clusters"][0]["members"].size(), 2u);

  InProcessService service(testConfig(dir / "data"));
  std::filesystem::remove(dir / "out.components.json");
  const CliRun remote =
      runCliFit(files, dir, flags + " --server http://127.0.0.1:" + std::to_string(service.port()));
  ASSERT_EQ(remote.exit_code, 0) << remote.log;
  EXPECT_TRUE(fileText(dir / "out.components.json") == expected)
      << "`fit --server --components-out` wrote another document than the in-process fit";
}

void expectRefused(const Reply& r, int status, const std::string& slug, const std::string& detail_part) {
  EXPECT_EQ(r.status, status) << r.raw;
  EXPECT_EQ(r.content_type, "application/problem+json") << r.raw;
  EXPECT_EQ(r.body.value("type", ""), "urn:rigport:problem:" + slug) << r.raw;
  EXPECT_NE(r.body.value("detail", "").find(detail_part), std::string::npos)
      << "detail should say '" << detail_part << "': " << r.raw;
}

TEST(FitJobs, SubmissionRefusesWhatCannotBeFittedNamingTheProblem) {
  const auto dir = makeTempDir("fit_refused");
  const FitFiles files = writeFitFiles(dir);
  InProcessService service(testConfig(dir / "data"));
  auto client = service.client();
  const std::string rig_id = uploadReference(*client, files);
  const std::string scan = fileText(files.scan), landmarks = fileText(files.scan_landmarks);

  writePlyCloud(dir / "tiny.ply", randomPoints(10, 4, 0.1));
  expectRefused(postParts(*client, fitParts(rig_id, fileText(dir / "tiny.ply"), "tiny.ply", "")), 422, "invalid-mesh",
                "tiny.ply: 10 points; a head scan needs at least 100");

  Eigen::MatrixX3d points = randomPoints(500, 5, 100.0);
  points(17, 1) = std::numeric_limits<double>::quiet_NaN();
  writePlyCloud(dir / "nan.ply", points);
  expectRefused(postParts(*client, fitParts(rig_id, fileText(dir / "nan.ply"), "nan.ply", "")), 422, "invalid-mesh",
                "'nan.ply': vertex 17 has a non-finite coordinate");

  auto renamed = nlohmann::json::parse(landmarks);
  renamed["landmarks"][5]["name"] = "earlobe_left";
  expectRefused(postParts(*client, fitParts(rig_id, scan, "scan.ply", renamed.dump())), 422, "invalid-landmarks",
                "earlobe_left");

  expectRefused(postParts(*client, fitParts(rig_id, scan, "scan.ply", landmarks, {{"stifness", 3}})), 400,
                "invalid-option", "spec.options: 'stifness' is not a known option");
  expectRefused(postParts(*client, fitParts(rig_id, scan, "scan.ply", landmarks, {{"alignment", "sideways"}})), 400,
                "invalid-option", "'alignment' must be one of");
  expectRefused(postParts(*client, fitParts(rig_id, scan, "scan.ply", "", {{"alignment", "landmarks"}})), 400,
                "invalid-option", "'alignment' is \"landmarks\" but no scan_landmarks file was sent");
  // Without its scan, or without a rig, a fit is a malformed request.
  httplib::MultipartFormDataItems no_scan = fitParts(rig_id, scan, "scan.ply", landmarks);
  no_scan.erase(no_scan.begin() + 1);
  expectRefused(postParts(*client, no_scan), 400, "malformed-request", "multipart field 'scan' is required");
  expectRefused(postParts(*client, fitParts("", scan, "scan.ply", landmarks)), 400, "malformed-request", "spec.rig");

  EXPECT_TRUE(get(*client, "/v1/jobs").body["items"].empty()) << "a refused job must not be stored";
  const Reply fine = submitFit(*client, rig_id, files);
  ASSERT_EQ(fine.status, 202) << fine.raw;
  EXPECT_EQ(waitForJob(*client, fine.body["id"])["status"], "succeeded");
}

TEST(FitJobs, CancellingARunningFitStopsIt) {
  const auto dir = makeTempDir("fit_cancel");
  const FitFiles files = writeFitFiles(dir, 240, 160);  // large enough to keep the worker busy for seconds
  server::ServerConfig config = testConfig(dir / "data");
  config.workers = 1;
  InProcessService service(config);
  auto client = service.client();
  const std::string rig_id = uploadReference(*client, files);
  const Reply job = submitFit(*client, rig_id, files);
  ASSERT_EQ(job.status, 202) << job.raw;
  const std::string id = job.body["id"];
  const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(120);
  while (get(*client, "/v1/jobs/" + id).body.value("status", "") != "running") {
    ASSERT_LT(std::chrono::steady_clock::now(), give_up) << "the fit never ran";
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  const Reply cancel = post(*client, "/v1/jobs/" + id + ":cancel");
  ASSERT_EQ(cancel.status, 202) << cancel.raw;
  const nlohmann::json stopped = waitForJob(*client, id);
  EXPECT_EQ(stopped["status"], "cancelled") << stopped.dump();
  EXPECT_EQ(stopped["error"]["type"], "urn:rigport:problem:job-cancelled") << stopped.dump();
  EXPECT_EQ(get(*client, "/v1/jobs/" + id + "/result").status, 409);
}

// A sphere is no head: the search finds no pose, the gate fails the fit, and
// the job ends failed with the gate's reason (no result; its diagnostics kept).
TEST(FitJobs, AFitWhoseGateFailsEndsFailedWithTheReason) {
  const auto dir = makeTempDir("fit_gate");
  const FitFiles files = writeFitFiles(dir);
  const Icosphere sphere = unitIcosphere(4);
  std::string obj;
  char line[96];
  for (Eigen::Index v = 0; v < sphere.positions.rows(); ++v) {
    const Eigen::RowVector3d p = 100.0 * sphere.positions.row(v);  // 10 cm radius, millimetres
    std::snprintf(line, sizeof line, "v %.6g %.6g %.6g\n", p.x(), p.y(), p.z());
    obj += line;
  }
  for (Eigen::Index f = 0; f < sphere.triangles.rows(); ++f) {
    std::snprintf(line, sizeof line, "f %d %d %d\n", sphere.triangles(f, 0) + 1, sphere.triangles(f, 1) + 1,
                  sphere.triangles(f, 2) + 1);
    obj += line;
  }
  InProcessService service(testConfig(dir / "data"));
  auto client = service.client();
  const std::string rig_id = uploadReference(*client, files);
  const Reply job = postParts(*client, fitParts(rig_id, obj, "ball.obj", ""));
  ASSERT_EQ(job.status, 202) << job.raw;
  const nlohmann::json done = waitForJob(*client, job.body["id"]);
  ASSERT_EQ(done["status"], "failed") << done.dump();
  EXPECT_EQ(done["error"]["type"], "urn:rigport:problem:quality-gate") << done.dump();
  EXPECT_EQ(done["error"]["status"], 422) << done.dump();
  const std::string detail = done["error"].value("detail", "");
  EXPECT_NE(detail.find("ball.obj: the fit failed its quality gate: the alignment found no head"), std::string::npos)
      << detail;
  EXPECT_EQ(get(*client, "/v1/jobs/" + done["id"].get<std::string>() + "/result").status, 409);
  // Why, in full: the refused fit's diagnostics are kept.
  const Reply diagnostics = get(*client, "/v1/jobs/" + done["id"].get<std::string>() + "/diagnostics");
  ASSERT_EQ(diagnostics.status, 200) << diagnostics.raw;
  EXPECT_EQ(diagnostics.body.value("verdict", ""), "fail");
  ASSERT_FALSE(diagnostics.body["reasons"].empty());
  EXPECT_NE(diagnostics.body["reasons"][0].get<std::string>().find("the alignment found no head"), std::string::npos)
      << diagnostics.raw.substr(0, 400);
}

// A transfer target for the reference of writeFitFiles: the scan's identity
// (seed 3) as a mesh of its own triangulation (GLB, metres as the rig) with
// its 68 landmarks; `true_landmarks` receives where they truly are.
TransferFiles writeFitTransferFiles(const FitFiles& f, const std::filesystem::path& dir, Eigen::MatrixX3d& true_landmarks) {
  core::HeadResolution res;
  res.columns = 80;
  res.rows = 70;
  res.alternate_diagonals = true;
  res.jitter = 0.2;
  res.seed = 5;
  const core::SyntheticHead head = core::generateHead(core::randomHeadShape(3, 0.15), res);
  TransferFiles t{f.rig, f.landmarks, dir / "target.glb", dir / "target.landmarks.json", {}};
  EXPECT_TRUE(core::writeMeshGlb(head.mesh, t.target).ok());
  writeText(t.target_landmarks, core::formatLandmarks(head.landmarks));
  auto at = core::resolveLandmarks(head.landmarks, head.mesh, "target");
  EXPECT_TRUE(at.ok());
  if (at) true_landmarks = *at;
  return t;
}

// `rigport transfer` in-process on `t` (without --target-landmarks when its
// path is empty), writing out.glb and out.json in `dir`.
CliRun runCliTransferTo(const TransferFiles& t, const std::filesystem::path& dir, const std::string& flags = "") {
  std::filesystem::remove(dir / "out.glb");
  return runRigportCli("transfer --source " + quoted(t.rig) + " --source-landmarks " + quoted(t.landmarks) +
                       " --target " + quoted(t.target) +
                       (t.target_landmarks.empty() ? std::string() : " --target-landmarks " + quoted(t.target_landmarks)) +
                       " -o " + quoted(dir / "out.glb") + " --diagnostics " + quoted(dir / "out.json") + " " + flags);
}

// Transfers that fit (docs/FIT.md, "The fit as a correspondence"): through
// the fit's correspondence, and to a target without landmarks (found by the
// fit, reported). The service's bytes are the CLI's; the fit reference is
// cached for transfers as for fits.
TEST(FitJobs, TransfersThroughTheFitAndWithoutTargetLandmarksGiveTheCliBytes) {
  const auto dir = makeTempDir("fit_transfer");
  const FitFiles f = writeFitFiles(dir);
  Eigen::MatrixX3d truth;
  const TransferFiles given = writeFitTransferFiles(f, dir, truth);
  TransferFiles found = given;
  found.target_landmarks.clear();
  writeText(dir / "fit.json", R"({"correspondence": "fit"})");

  const CliRun through_fit = runCliTransferTo(given, dir, "--options " + quoted(dir / "fit.json"));
  ASSERT_EQ(through_fit.exit_code, 0) << through_fit.log;
  const std::string fit_bytes = fileText(dir / "out.glb");
  EXPECT_GLTF_VALID(dir / "out.glb");
  const auto fit_d = nlohmann::json::parse(fileText(dir / "out.json"), nullptr, false);
  EXPECT_EQ(fit_d["correspondence"]["method"], "fit") << fit_d.dump().substr(0, 400);
  EXPECT_EQ(fit_d["fit"]["verdict"], "ok");
  EXPECT_FALSE(fit_d["landmarks"]["found_by_fit"].get<bool>());
  EXPECT_TRUE(fit_d["timings_ms"].contains("fit"));
  EXPECT_EQ(fit_d["shapes"]["count"], 6);

  const CliRun without = runCliTransferTo(found, dir);
  ASSERT_EQ(without.exit_code, 0) << without.log;
  const std::string found_bytes = fileText(dir / "out.glb");
  EXPECT_GLTF_VALID(dir / "out.glb");
  EXPECT_NE(without.log.find("the target had no landmarks: the 68 used were found by a fit"), std::string::npos)
      << without.log;
  const auto found_d = nlohmann::json::parse(fileText(dir / "out.json"), nullptr, false);
  EXPECT_EQ(found_d["correspondence"]["method"], "warp");
  EXPECT_TRUE(found_d["landmarks"]["found_by_fit"].get<bool>());
  EXPECT_EQ(found_d["fit"]["alignment"]["method"], "search");
  const nlohmann::json& placed = found_d["fit"]["landmarks"]["found"];
  ASSERT_EQ(placed.size(), 68u);
  // Where they were found against where they are (the generated head's own).
  const double diagonal = found_d["mesh"]["bbox_diagonal"].get<double>();
  std::vector<double> off;
  for (std::size_t i = 0; i < placed.size(); ++i) {
    const auto& p = placed[i]["position"];
    off.push_back((Eigen::Vector3d(p[0], p[1], p[2]) - truth.row(static_cast<Eigen::Index>(i)).transpose()).norm() / diagonal);
  }
  std::sort(off.begin(), off.end());
  std::printf("landmarks found by the fit: median %.4f, worst %.4f of the diagonal off the head's own\n",
              off[off.size() / 2], off.back());
  EXPECT_LE(off[off.size() / 2], 0.01);

  InProcessService service(testConfig(dir / "data"));
  auto client = service.client();
  const Reply rig = uploadRig(*client, given);
  ASSERT_EQ(rig.status, 201) << rig.raw;
  const std::string rig_id = rig.body["id"];
  const Reply job = submitTransfer(*client, rig_id, given, "", {{"correspondence", "fit"}});
  ASSERT_EQ(job.status, 202) << job.raw;
  const nlohmann::json done = waitForJob(*client, job.body["id"]);
  ASSERT_EQ(done["status"], "succeeded") << done.dump();
  EXPECT_GT(done["timings_ms"]["fit"].get<double>(), 0.0);
  EXPECT_TRUE(get(*client, "/v1/jobs/" + done["id"].get<std::string>() + "/result").raw == fit_bytes)
      << "the service's transfer through the fit differs from the CLI's";

  const Reply no_landmarks = submitTransfer(*client, rig_id, found);
  ASSERT_EQ(no_landmarks.status, 202) << no_landmarks.raw;
  const nlohmann::json found_done = waitForJob(*client, no_landmarks.body["id"]);
  ASSERT_EQ(found_done["status"], "succeeded") << found_done.dump();
  EXPECT_EQ(found_done["files"].count("target_landmarks"), 0u) << found_done.dump();
  const std::string found_id = found_done["id"];
  EXPECT_TRUE(get(*client, "/v1/jobs/" + found_id + "/result").raw == found_bytes)
      << "the service's transfer without target landmarks differs from the CLI's";
  EXPECT_TRUE(get(*client, "/v1/jobs/" + found_id + "/diagnostics").body["landmarks"]["found_by_fit"].get<bool>());
  // One fit reference for both jobs.
  EXPECT_EQ(metricValue(*client, "rigport_cache_misses_total{cache=\"fit\"}"), 1.0);
  EXPECT_EQ(metricValue(*client, "rigport_cache_hits_total{cache=\"fit\"}"), 1.0);

  // `transfer --server` without target landmarks: the same bytes.
  const CliRun remote = runCliTransferTo(found, dir, "--server http://127.0.0.1:" + std::to_string(service.port()));
  ASSERT_EQ(remote.exit_code, 0) << remote.log;
  EXPECT_TRUE(fileText(dir / "out.glb") == found_bytes) << "`transfer --server` without landmarks differs";
  expectRefused(submitTransfer(*client, rig_id, given, "", {{"correspondence", "icp"}}), 400, "invalid-option",
                "'correspondence' must be \"warp\" or \"fit\"");
  // Without landmarks the target is fitted as a scan: one too small to be a
  // head is refused at submission, named.
  core::Mesh tiny;
  tiny.positions.resize(4, 3);
  tiny.positions << 0, 0, 0, 0.1, 0, 0, 0, 0.1, 0, 0, 0, 0.1;
  tiny.triangles.resize(4, 3);
  tiny.triangles << 0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3;
  TransferFiles small = found;
  small.target = dir / "tiny.glb";
  ASSERT_TRUE(core::writeMeshGlb(tiny, small.target).ok());
  expectRefused(submitTransfer(*client, rig_id, small), 422, "invalid-mesh", "tiny.glb: 4 points; a head scan needs at least 100");
}

// The served contract lists kind fit, its files and every fit option the
// service stores (the normalised options of core/jobs/fit_options.h).
TEST(FitJobs, TheContractDescribesFitJobs) {
  const auto dir = makeTempDir("fit_contract");
  InProcessService service(testConfig(dir / "data"));
  auto client = service.client();
  const Reply doc = get(*client, "/openapi.json");
  ASSERT_EQ(doc.status, 200) << doc.raw.substr(0, 200);
  const nlohmann::json& schemas = doc.body["components"]["schemas"];
  const nlohmann::json kinds = schemas["JobSpec"]["properties"]["kind"]["enum"];
  for (const auto& kind : api::jobKinds()) {
    EXPECT_NE(std::find(kinds.begin(), kinds.end(), api::jobKindName(kind.kind)), kinds.end()) << api::jobKindName(kind.kind);
    for (const auto* list : {&kind.required_files, &kind.optional_files}) {
      for (const std::string& field : *list) EXPECT_TRUE(schemas["JobSubmission"]["properties"].contains(field)) << field;
    }
  }
  ASSERT_TRUE(schemas.contains("FitOptions"));
  const nlohmann::json stored = nlohmann::json::parse(core::fitOptionsJson(core::FitSettings{}));
  std::set<std::string> documented, normalised;
  for (const auto& [key, value] : schemas["FitOptions"]["properties"].items()) documented.insert(key);
  for (const auto& [key, value] : stored.items()) normalised.insert(key);
  EXPECT_EQ(documented, normalised);
  for (const auto& [key, value] : schemas["FitStage"]["properties"].items()) {
    EXPECT_TRUE(stored["schedule"][0].contains(key)) << key;
  }
  EXPECT_EQ(schemas["FitStage"]["properties"].size(), stored["schedule"][0].size());
}

}  // namespace
}  // namespace rigport_test
