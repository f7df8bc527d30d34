// Every malformed-request class gets its problem+json (RFC 9457) with a stable
// type and a detail naming the field or file, and the server keeps serving.
#include <fstream>

#include <gtest/gtest.h>

#include "tests/gltf_builder.h"
#include "tests/server/service_fixture.h"
#include "tests/test_support.h"

namespace rigport_test {
namespace {

void expectProblem(const Reply& r, int status, const std::string& slug, const std::string& detail_part) {
  EXPECT_EQ(r.status, status) << r.raw;
  EXPECT_EQ(r.content_type, "application/problem+json") << r.raw;
  EXPECT_EQ(r.body.value("type", ""), "urn:rigport:problem:" + slug) << r.raw;
  EXPECT_EQ(r.body.value("status", 0), status) << r.raw;
  // A complete problem (RFC 9457): what, a title, the status, the detail, and where.
  EXPECT_FALSE(r.body.value("title", "").empty()) << r.raw;
  EXPECT_EQ(r.body.value("instance", "").rfind('/', 0), 0u) << "no instance: " << r.raw;
  EXPECT_NE(r.body.value("detail", "").find(detail_part), std::string::npos)
      << "detail should name '" << detail_part << "': " << r.raw;
}

Reply postParts(httplib::Client& client, const std::string& path, const httplib::MultipartFormDataItems& items) {
  auto res = client.Post(path.c_str(), items);
  Reply r;
  if (!res) return r;
  r.status = res->status;
  r.raw = res->body;
  r.content_type = res->get_header_value("Content-Type");
  r.body = nlohmann::json::parse(res->body, nullptr, false);
  return r;
}

std::string fileText(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

class ServiceErrors : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = makeTempDir("errors");
    files_ = writeTransferFiles(dir_);
    server::ServerConfig config = testConfig(dir_ / "data");
    config.max_vertices = 20000;
    service_ = std::make_unique<InProcessService>(config);
    client_ = service_->client();
    Reply rig = uploadRig(*client_, files_);
    ASSERT_EQ(rig.status, 201) << rig.raw;
    rig_id_ = rig.body["id"];
  }
  void TearDown() override {
    // The server still serves a healthy job after every error above.
    EXPECT_EQ(get(*client_, "/healthz").status, 200);
    Reply job = submitTransfer(*client_, rig_id_, files_);
    ASSERT_EQ(job.status, 202) << job.raw;
    EXPECT_EQ(waitForJob(*client_, job.body["id"])["status"], "succeeded");
  }
  httplib::MultipartFormDataItems jobParts(const std::string& spec) const {
    return {{"spec", spec, "spec.json", "application/json"},
            {"target", fileText(files_.target), "target_head.glb", "model/gltf-binary"},
            {"target_landmarks", fileText(files_.target_landmarks), "target.json", "application/json"}};
  }
  std::string spec(const std::string& options = "{}") const {
    return R"({"kind":"transfer","rig":")" + rig_id_ + R"(","options":)" + options + "}";
  }
  std::filesystem::path dir_;
  TransferFiles files_;
  std::unique_ptr<InProcessService> service_;
  std::unique_ptr<httplib::Client> client_;
  std::string rig_id_;
};

TEST_F(ServiceErrors, MalformedSpecsAre400NamingTheField) {
  expectProblem(postParts(*client_, "/v1/jobs", jobParts("{not json")), 400, "malformed-request", "spec");
  expectProblem(postParts(*client_, "/v1/jobs", jobParts(R"({"kind":"transfer","rig":42})")), 400, "malformed-request", "spec.rig");
  expectProblem(postParts(*client_, "/v1/jobs", jobParts(R"({"kind":"sculpt","rig":"00"})")), 400, "malformed-request", "spec.kind");
  expectProblem(postParts(*client_, "/v1/jobs", jobParts(R"({"kind":"transfer","rig":"abc"})")), 400, "malformed-request", "spec.rig");
  expectProblem(postParts(*client_, "/v1/jobs", jobParts(R"({"kind":"transfer","rig":"x","colour":1})")), 400, "malformed-request", "spec.colour");
  expectProblem(postParts(*client_, "/v1/jobs", jobParts(spec(R"({"max_influences": 99})"))), 400, "invalid-option", "max_influences");
  expectProblem(postParts(*client_, "/v1/jobs", jobParts(spec(R"({"max_infuences": 4})"))), 400, "invalid-option", "max_infuences");
  auto parts = jobParts(spec());
  parts.erase(parts.begin() + 1);  // the target (its landmarks are optional: a fit finds them)
  expectProblem(postParts(*client_, "/v1/jobs", parts), 400, "malformed-request", "multipart field 'target' is required");
  parts = jobParts(spec());
  parts.push_back({"texture", "x", "t.png", "image/png"});
  expectProblem(postParts(*client_, "/v1/jobs", parts), 400, "malformed-request", "texture");
  expectProblem(get(*client_, "/v1/jobs?status=done"), 400, "malformed-request", "status");
  expectProblem(get(*client_, "/v1/jobs?limit=0"), 400, "malformed-request", "limit");
  expectProblem(get(*client_, "/v1/jobs?limit=5abc"), 400, "malformed-request", "limit");
  expectProblem(get(*client_, "/v1/jobs?after=1e3"), 400, "malformed-request", "after");
  expectProblem(get(*client_, "/v1/jobs?limit=99999999999999999999"), 400, "malformed-request", "limit");
}

TEST_F(ServiceErrors, UnknownThingsAre404) {
  expectProblem(get(*client_, "/v1/jobs/0123456789abcdef0123456789abcdef"), 404, "not-found", "0123456789abcdef");
  expectProblem(get(*client_, "/v1/rigs/" + std::string(64, 'a')), 404, "not-found", "aaaa");
  expectProblem(get(*client_, "/v1/teapot"), 404, "not-found", "/v1/teapot");
  expectProblem(postParts(*client_, "/v1/jobs", jobParts(R"({"kind":"transfer","rig":")" + std::string(64, 'b') + "\"}")),
                404, "not-found", "spec.rig");
}

TEST_F(ServiceErrors, WrongMediaTypeIs415) {
  auto res = client_->Post("/v1/jobs", R"({"kind":"transfer"})", "application/json");
  ASSERT_TRUE(res);
  Reply r{res->status, nlohmann::json::parse(res->body, nullptr, false), res->body, res->get_header_value("Content-Type"), ""};
  expectProblem(r, 415, "unsupported-media-type", "multipart/form-data");
}

TEST_F(ServiceErrors, UnusableFilesAre400Or422NamingTheFile) {
  auto parts = jobParts(spec());
  parts[1] = {"target", "not a binary glTF at all", "broken.glb", "model/gltf-binary"};
  expectProblem(postParts(*client_, "/v1/jobs", parts), 400, "malformed-file", "broken.glb");
  parts[1] = {"target", "v 0 0 0\nv 1 0 nan\nv 0 1 0\nf 1 2 3\n", "nan.obj", "text/plain"};
  expectProblem(postParts(*client_, "/v1/jobs", parts), 422, "invalid-mesh", "nan.obj");
  parts = jobParts(spec());
  parts[2] = {"target_landmarks", R"({"landmarks":[{"name":"nose_tip","vertex":999999999}]})", "t.json", "application/json"};
  expectProblem(postParts(*client_, "/v1/jobs", parts), 422, "invalid-landmarks", "nose_tip");
  // A rig whose landmarks all sit on one vertex: ill-conditioned TPS.
  httplib::MultipartFormDataItems rig = {
      {"rig", fileText(files_.rig), "coplanar.glb", "model/gltf-binary"},
      {"landmarks", R"({"landmarks":[{"name":"a","vertex":0},{"name":"b","vertex":0},{"name":"c","vertex":0},{"name":"d","vertex":0}]})",
       "l.json", "application/json"}};
  const Reply r = postParts(*client_, "/v1/rigs", rig);
  EXPECT_EQ(r.status, 422) << r.raw;
  EXPECT_EQ(r.content_type, "application/problem+json");
}

// A rig's components document is read and checked at upload: a document the
// rig cannot use is refused naming the component and field; a good one stored.
TEST_F(ServiceErrors, RigComponentsAreCheckedAtUploadNamingTheField) {
  auto rigParts = [&](const std::string& components) {
    return httplib::MultipartFormDataItems{{"rig", fileText(files_.rig), "rig.glb", "model/gltf-binary"},
                                           {"landmarks", fileText(files_.landmarks), "l.json", "application/json"},
                                           {"components", components, "c.json", "application/json"}};
  };
  const std::string header = R"("format": "rigport.components", "version": 1)";
  Reply r = postParts(*client_, "/v1/rigs",
                      rigParts("{" + header + R"(, "wires": [{"name": "upper_lip", "base_curve": "a", "curve": "a", "dropoff_distance": -1}]})"));
  EXPECT_EQ(r.status, 400) << r.raw;
  EXPECT_NE(r.raw.find("upper_lip"), std::string::npos) << r.raw;
  r = postParts(*client_, "/v1/rigs", rigParts("{" + header + R"(, "locators": [{"name": "tip", "binding": {"vertex": 99999999}}]})"));
  EXPECT_EQ(r.status, 400) << r.raw;
  EXPECT_EQ(r.body.value("type", ""), "urn:rigport:problem:malformed-file") << r.raw;
  EXPECT_NE(r.raw.find("tip"), std::string::npos) << r.raw;
  r = postParts(*client_, "/v1/rigs", rigParts("{" + header + R"(, "locators": [{"name": "tip", "binding": {"vertex": 3}}]})"));
  EXPECT_EQ(r.status, 201) << r.raw;
  EXPECT_EQ(r.body.value("has_components", false), true) << r.raw;
}

// What a job would refuse is answered at submission (422), never accepted and
// failed later: a target with no surface, landmarks sharing fewer than 4 names
// with the rig, shared landmarks that do not span 3D. Nothing is stored.
TEST_F(ServiceErrors, UnusableInputsAre422AtSubmissionNotFailedLater) {
  const nlohmann::json target_landmarks = nlohmann::json::parse(fileText(files_.target_landmarks));
  std::vector<std::string> names;
  for (const auto& lm : target_landmarks["landmarks"]) names.push_back(lm["name"]);
  ASSERT_GE(names.size(), 4u);

  nlohmann::json on_line = {{"landmarks", nlohmann::json::array()}};
  for (int i = 0; i < 4; ++i) on_line["landmarks"].push_back({{"name", names[static_cast<std::size_t>(i)]}, {"position", {i, 0, 0}}});
  auto parts = jobParts(spec());
  parts[1] = {"target", "v 0 0 0\nv 1 0 0\nv 2 0 0\nv 3 0 0\nf 1 2 3\nf 2 3 4\n", "line.obj", "text/plain"};
  parts[2] = {"target_landmarks", on_line.dump(), "line.json", "application/json"};
  const Reply flat = postParts(*client_, "/v1/jobs", parts);
  expectProblem(flat, 422, "invalid-mesh", "line.obj: all 2 triangles have zero area");

  nlohmann::json three = target_landmarks;
  three["landmarks"].erase(three["landmarks"].begin() + 3, three["landmarks"].end());
  parts = jobParts(spec());
  parts[2] = {"target_landmarks", three.dump(), "three.json", "application/json"};
  expectProblem(postParts(*client_, "/v1/jobs", parts), 422, "invalid-landmarks",
                "only 3 landmark name(s) shared with the rig");

  nlohmann::json one_point = {{"landmarks", nlohmann::json::array()}};
  for (int i = 0; i < 4; ++i) one_point["landmarks"].push_back({{"name", names[static_cast<std::size_t>(i)]}, {"vertex", 7}});
  parts = jobParts(spec());
  parts[2] = {"target_landmarks", one_point.dump(), "one_point.json", "application/json"};
  expectProblem(postParts(*client_, "/v1/jobs", parts), 422, "ill-conditioned",
                "target_head.glb: all landmarks are at the same position");

  EXPECT_TRUE(get(*client_, "/v1/jobs").body["items"].empty()) << "a refused job was stored";
}

// Nesting that would overflow a thread's stack in a recursive copy or
// conversion (spec.options 100,000 deep; glTF extras 20,000 deep), and
// numbers out of range, are refused naming the part and the depth; the
// server keeps serving (TearDown).
TEST_F(ServiceErrors, DeepJsonAndHugeNumbersAre400NamingThePart) {
  const std::string deep_options = std::string(100000, '[') + std::string(100000, ']');
  expectProblem(postParts(*client_, "/v1/jobs", jobParts(spec(deep_options))), 400, "malformed-request",
                "spec: JSON nested deeper than 64 levels");
  expectProblem(postParts(*client_, "/v1/jobs", jobParts(spec(R"({"exaggeration": 1e400})"))), 400, "malformed-request",
                "spec: not valid JSON");
  auto parts = jobParts(spec());
  parts[2] = {"target_landmarks", R"({"landmarks":[{"name":"nose_tip","position":[1e400,0,0]}]})", "huge.json",
              "application/json"};
  expectProblem(postParts(*client_, "/v1/jobs", parts), 400, "malformed-file", "target_landmarks: not valid JSON");
  parts = jobParts(spec());
  parts[2] = {"target_landmarks", std::string(20000, '[') + std::string(20000, ']'), "deep.json", "application/json"};
  expectProblem(postParts(*client_, "/v1/jobs", parts), 400, "malformed-file",
                "target_landmarks: JSON nested deeper than 64 levels");
  // A target GLB whose glTF JSON nests extras 20,000 deep.
  const std::string glb = fileText(files_.target);
  auto split = gltf::splitGlb(gltf::ByteVector(glb.begin(), glb.end()));
  std::string text = split.first.dump();
  text.insert(text.size() - 1, std::string(R"(,"extras":)") + std::string(20000, '[') + std::string(20000, ']'));
  const gltf::ByteVector deep_glb = gltf::makeGlbFromText(text, split.second);
  parts = jobParts(spec());
  parts[1] = {"target", std::string(deep_glb.begin(), deep_glb.end()), "deep.glb", "model/gltf-binary"};
  expectProblem(postParts(*client_, "/v1/jobs", parts), 400, "malformed-file", "target 'deep.glb': glTF JSON nested deeper than 64 levels");
  httplib::MultipartFormDataItems rig = {
      {"rig", std::string(deep_glb.begin(), deep_glb.end()), "deep_rig.glb", "model/gltf-binary"},
      {"landmarks", fileText(files_.landmarks), "l.json", "application/json"}};
  expectProblem(postParts(*client_, "/v1/rigs", rig), 400, "malformed-file", "deep_rig.glb");
}

// A client's bytes that are not UTF-8 (a file name, a landmark name): 400
// naming the field, nothing stored, and the tenant's listings keep working.
TEST_F(ServiceErrors, NonUtf8NamesAre400AndListingsKeepWorking) {
  httplib::MultipartFormDataItems rig = {{"rig", fileText(files_.rig), "rig\xFF.glb", "model/gltf-binary"},
                                         {"landmarks", fileText(files_.landmarks), "l.json", "application/json"}};
  expectProblem(postParts(*client_, "/v1/rigs", rig), 400, "malformed-request",
                "the file name of multipart field 'rig' is not valid UTF-8");
  auto parts = jobParts(spec());
  parts[1].filename = "target\xC0\x80.glb";
  expectProblem(postParts(*client_, "/v1/jobs", parts), 400, "malformed-request",
                "the file name of multipart field 'target' is not valid UTF-8");
  parts = jobParts(spec());
  parts[2] = {"target_landmarks", "{\"landmarks\":[{\"name\":\"nose\xFF\",\"vertex\":1}]}", "t.json", "application/json"};
  expectProblem(postParts(*client_, "/v1/jobs", parts), 400, "malformed-file", "target_landmarks: not valid JSON");
  const Reply rigs = get(*client_, "/v1/rigs");
  EXPECT_EQ(rigs.status, 200) << rigs.raw;
  EXPECT_EQ(rigs.body["items"].size(), 1u) << rigs.raw;  // the fixture's rig only
  EXPECT_EQ(get(*client_, "/v1/jobs").status, 200);
}

TEST_F(ServiceErrors, OversizedMeshesAre413) {
  auto parts = jobParts(spec());
  // 150 x 135 cells: over the 20000-vertex limit of this server.
  const auto big = writeTransferFiles(dir_ / "big", 150);
  parts[1] = {"target", fileText(big.target), "big.glb", "model/gltf-binary"};
  parts[2] = {"target_landmarks", fileText(big.target_landmarks), "big.json", "application/json"};
  expectProblem(postParts(*client_, "/v1/jobs", parts), 413, "payload-too-large", "vertices");
}

// Inputs are checked at submission, so a job fails on the worker only for
// what cannot be known before it runs: here its time limit.
TEST(ServiceJobFailures, AJobThatFailsCarriesItsProblemAndHasNoResult) {
  const auto dir = makeTempDir("failing_job");
  const TransferFiles files = writeTransferFiles(dir);
  server::ServerConfig config = testConfig(dir / "data");
  config.job_time_limit_s = 1e-9;
  InProcessService service(config);
  auto client = service.client();
  const std::string rig_id = uploadRig(*client, files).body["id"];
  Reply job = submitTransfer(*client, rig_id, files);
  ASSERT_EQ(job.status, 202) << job.raw;
  const nlohmann::json done = waitForJob(*client, job.body["id"]);
  EXPECT_EQ(done["status"], "failed");
  EXPECT_EQ(done["error"]["type"], "urn:rigport:problem:job-timeout") << done.dump();
  EXPECT_NE(done["error"]["detail"].get<std::string>().find("exceeded the time limit"), std::string::npos) << done.dump();
  expectProblem(get(*client, "/v1/jobs/" + done["id"].get<std::string>() + "/result"), 409, "conflict", "failed");
  expectProblem(post(*client, "/v1/jobs/" + done["id"].get<std::string>() + ":cancel"), 409, "conflict", "already failed");
}

TEST(ServiceLimits, BodiesOverTheLimitAre413) {
  const auto dir = makeTempDir("body_limit");
  const TransferFiles files = writeTransferFiles(dir);
  server::ServerConfig config = testConfig(dir / "data");
  config.max_body_bytes = 64 * 1024;
  InProcessService service(config);
  auto client = service.client();
  Reply r = uploadRig(*client, files);
  EXPECT_EQ(r.status, 413) << r.raw;
  EXPECT_EQ(r.content_type, "application/problem+json");
  EXPECT_EQ(get(*client, "/healthz").status, 200);
}


// A JSON part has its own limit, below the body's: it is read and parsed
// whole. Checked on the spooled size, naming the field; a mesh part may use
// the whole body limit.
TEST(ServiceLimits, JsonPartsOverTheirLimitAre413NamingTheField) {
  const auto dir = makeTempDir("part_limit");
  const TransferFiles files = writeTransferFiles(dir);
  server::ServerConfig config = testConfig(dir / "data");
  config.max_document_part_bytes = 12000;  // the generated landmarks are ~10 KB, the rig ~220 KB
  InProcessService service(config);
  auto client = service.client();
  const std::string landmarks = fileText(files.landmarks);
  ASSERT_LT(landmarks.size(), 12000u);
  const std::string padded = landmarks + std::string(5000, ' ');  // still valid JSON, over the part limit
  const httplib::MultipartFormDataItems items = {
      {"rig", fileText(files.rig), "rig.glb", "model/gltf-binary"},
      {"landmarks", padded, "rig.landmarks.json", "application/json"},
  };
  const Reply r = postParts(*client, "/v1/rigs", items);
  EXPECT_EQ(r.status, 413) << r.raw;
  EXPECT_NE(r.body.value("detail", "").find("'landmarks'"), std::string::npos) << r.raw;
  const Reply fits = uploadRig(*client, files);  // the rig GLB is far over 12000 bytes: bulk parts are not limited
  EXPECT_EQ(fits.status, 201) << fits.raw;
}

}  // namespace
}  // namespace rigport_test
