// Tests of the wire contract: api/json.cpp (round trips, errors that name the
// field), api/error_codes.cpp (the status table), api/content_id.cpp and the
// OpenAPI document api/openapi.json.
#include <fstream>
#include <iterator>
#include <set>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "api/content_id.h"
#include "api/error_codes.h"
#include "api/json.h"

#include "tests/test_support.h"

namespace {

using nlohmann::json;

template <typename T>
T valueOf(const api::Parsed<T>& parsed) {
  EXPECT_TRUE(parsed.ok()) << parsed.error();
  return parsed ? *parsed : T{};
}

template <typename T>
std::string errorOf(const api::Parsed<T>& parsed) {
  EXPECT_FALSE(parsed.ok()) << "expected a parse error";
  return parsed ? std::string() : parsed.error();
}

api::Problem sampleProblem() {
  return api::Problem{"urn:rigport:problem:invalid-mesh", "Mesh unusable", 422, "target: vertex 12 is NaN", "job-7"};
}

api::RigInfo sampleRig() {
  api::RigInfo r;
  r.id = std::string(64, 'a');
  r.name = "head.glb";
  r.size_bytes = 123456789012;
  r.vertices = 24000;
  r.joints = 12;
  r.morph_targets = 52;
  r.landmarks = 68;
  r.has_components = true;
  r.created_at = "2026-11-21T16:00:00Z";
  r.region_labels = std::vector<int>{0, 1, 2};
  return r;
}

api::JobInfo sampleJob(api::JobStatus status) {
  api::JobInfo j;
  j.id = "job-7";
  j.kind = "transfer";
  j.rig = std::string(64, 'b');
  j.status = status;
  j.stage = "weights";
  j.progress = 0.625;
  j.attempts = 2;
  j.cache_hit = true;
  j.created_at = "2026-11-21T16:00:00Z";
  j.started_at = "2026-11-21T16:00:01Z";
  j.finished_at = api::isFinal(status) ? "2026-11-21T16:00:09Z" : "";
  j.timings_ms = {{"warp", 12.5}, {"weights", 40.0}};
  j.files = {{"target", "actor_07.glb"}, {"target_landmarks", "actor_07.landmarks.json"}};
  if (status == api::JobStatus::kFailed) j.error = sampleProblem();
  return j;
}

void expectSameProblem(const api::Problem& a, const api::Problem& b) {
  EXPECT_EQ(a.type, b.type);
  EXPECT_EQ(a.title, b.title);
  EXPECT_EQ(a.status, b.status);
  EXPECT_EQ(a.detail, b.detail);
  EXPECT_EQ(a.instance, b.instance);
}

void expectSameJob(const api::JobInfo& a, const api::JobInfo& b) {
  EXPECT_EQ(a.id, b.id);
  EXPECT_EQ(a.kind, b.kind);
  EXPECT_EQ(a.rig, b.rig);
  EXPECT_EQ(a.status, b.status);
  EXPECT_EQ(a.stage, b.stage);
  EXPECT_DOUBLE_EQ(a.progress, b.progress);
  EXPECT_EQ(a.attempts, b.attempts);
  EXPECT_EQ(a.cache_hit, b.cache_hit);
  EXPECT_EQ(a.created_at, b.created_at);
  EXPECT_EQ(a.started_at, b.started_at);
  EXPECT_EQ(a.finished_at, b.finished_at);
  EXPECT_EQ(a.timings_ms, b.timings_ms);
  EXPECT_EQ(a.files, b.files);
  ASSERT_EQ(a.error.has_value(), b.error.has_value());
  if (a.error) expectSameProblem(*a.error, *b.error);
}

// ---- round trips -------------------------------------------------------------

TEST(ApiJson, Utf8IsCheckedByTheRfc3629Rules) {
  EXPECT_TRUE(api::isValidUtf8(""));
  EXPECT_TRUE(api::isValidUtf8("rig.glb"));
  EXPECT_TRUE(api::isValidUtf8("t\xC3\xAAte.glb"));          // ê
  EXPECT_TRUE(api::isValidUtf8("\xE2\x82\xAC"));             // €
  EXPECT_TRUE(api::isValidUtf8("\xF0\x9F\x98\x80"));        // U+1F600
  EXPECT_FALSE(api::isValidUtf8("rig\xFF.glb"));
  EXPECT_FALSE(api::isValidUtf8("\x80"));                     // a lone continuation byte
  EXPECT_FALSE(api::isValidUtf8("\xC0\x80"));                 // overlong NUL
  EXPECT_FALSE(api::isValidUtf8("\xED\xA0\x80"));            // a surrogate
  EXPECT_FALSE(api::isValidUtf8("\xF4\x90\x80\x80"));        // past U+10FFFF
  EXPECT_FALSE(api::isValidUtf8("\xE2\x82"));                 // truncated
}

// A stored name of a client's bytes can never make a response fail: invalid
// UTF-8 is replaced in what goes out.
TEST(ApiJson, DumpReplacesInvalidUtf8) {
  nlohmann::json j = {{"name", std::string("rig\xFF.glb")}};
  EXPECT_THROW(j.dump(), nlohmann::json::type_error);
  EXPECT_EQ(api::dumpJson(j), "{\"name\":\"rig\xEF\xBF\xBD.glb\"}");
}

// Client JSON nested past any use, or holding a number out of range.
TEST(ApiJson, ParseRefusesDeepNestingAndHugeNumbers) {
  EXPECT_TRUE(api::parseJsonText(std::string(64, '[') + std::string(64, ']'), "spec").ok());
  const auto deep = api::parseJsonText(std::string(100000, '{') , "spec");
  ASSERT_FALSE(deep.ok());
  const auto deep_arrays = api::parseJsonText(std::string(100000, '[') + std::string(100000, ']'), "spec");
  ASSERT_FALSE(deep_arrays.ok());
  EXPECT_EQ(deep_arrays.error(), "spec: JSON nested deeper than 64 levels");
  const auto huge = api::parseJsonText(R"({"a": 1e400})", "spec");
  ASSERT_FALSE(huge.ok());
  EXPECT_EQ(huge.error().rfind("spec: not valid JSON", 0), 0u);
}

TEST(ApiJson, ProblemRoundTrips) {
  const api::Problem p = sampleProblem();
  expectSameProblem(valueOf(api::problemFromJson(api::toJson(p))), p);
}

TEST(ApiJson, ProblemWithoutInstanceOmitsIt) {
  api::Problem p = sampleProblem();
  p.instance.clear();
  EXPECT_FALSE(api::toJson(p).contains("instance"));
  expectSameProblem(valueOf(api::problemFromJson(api::toJson(p))), p);
}

TEST(ApiJson, RigInfoRoundTrips) {
  const api::RigInfo r = sampleRig();
  const api::RigInfo back = valueOf(api::rigInfoFromJson(api::toJson(r)));
  EXPECT_EQ(back.id, r.id);
  EXPECT_EQ(back.name, r.name);
  EXPECT_EQ(back.size_bytes, r.size_bytes);
  EXPECT_EQ(back.vertices, r.vertices);
  EXPECT_EQ(back.joints, r.joints);
  EXPECT_EQ(back.morph_targets, r.morph_targets);
  EXPECT_EQ(back.landmarks, r.landmarks);
  EXPECT_EQ(back.has_components, r.has_components);
  EXPECT_EQ(back.created_at, r.created_at);
  EXPECT_EQ(back.region_labels, r.region_labels);
  EXPECT_EQ(api::toJson(back), api::toJson(r));
  // Unknown labels (a rig stored before they were recorded) stay unknown.
  api::RigInfo unknown = r;
  unknown.region_labels.reset();
  EXPECT_FALSE(api::toJson(unknown).contains("region_labels"));
  EXPECT_FALSE(valueOf(api::rigInfoFromJson(api::toJson(unknown))).region_labels.has_value());
}

TEST(ApiJson, JobSpecRoundTrips) {
  api::JobSpec s;
  s.kind = api::JobKind::kTransfer;
  s.rig = std::string(64, 'c');
  s.options = {{"max_influences", 4}, {"components", {{"shapes", false}}}};
  const api::JobSpec back = valueOf(api::jobSpecFromJson(api::toJson(s)));
  EXPECT_EQ(back.kind, s.kind);
  EXPECT_EQ(back.rig, s.rig);
  EXPECT_EQ(back.options, s.options);
}

TEST(ApiJson, JobSpecWithoutRigOmitsItAndRoundTrips) {
  api::JobSpec s;
  s.kind = api::JobKind::kRetarget;
  EXPECT_FALSE(api::toJson(s).contains("rig"));
  const api::JobSpec back = valueOf(api::jobSpecFromJson(api::toJson(s)));
  EXPECT_EQ(back.kind, api::JobKind::kRetarget);
  EXPECT_TRUE(back.rig.empty());
  EXPECT_EQ(back.options, json::object());
}

TEST(ApiJson, JobInfoRoundTripsInEveryStatus) {
  for (auto status : {api::JobStatus::kQueued, api::JobStatus::kRunning, api::JobStatus::kSucceeded,
                      api::JobStatus::kFailed, api::JobStatus::kCancelled}) {
    SCOPED_TRACE(api::jobStatusName(status));
    const api::JobInfo j = sampleJob(status);
    const json wire = api::toJson(j);
    EXPECT_EQ(wire["status"], api::jobStatusName(status));
    expectSameJob(valueOf(api::jobInfoFromJson(wire)), j);
  }
}

TEST(ApiJson, JobInfoEmptyTimesAndRigAreNullOnTheWire) {
  api::JobInfo j = sampleJob(api::JobStatus::kQueued);
  j.rig.clear();
  j.started_at.clear();
  const json wire = api::toJson(j);
  EXPECT_TRUE(wire["rig"].is_null());
  EXPECT_TRUE(wire["started_at"].is_null());
  EXPECT_TRUE(wire["finished_at"].is_null());
  EXPECT_TRUE(wire["error"].is_null());
  expectSameJob(valueOf(api::jobInfoFromJson(wire)), j);
}

TEST(ApiJson, JobPageRoundTripsWithAndWithoutCursor) {
  api::JobPage page;
  page.items = {sampleJob(api::JobStatus::kRunning), sampleJob(api::JobStatus::kFailed)};
  page.next = "cursor-2";
  api::JobPage back = valueOf(api::jobPageFromJson(api::toJson(page)));
  ASSERT_EQ(back.items.size(), 2u);
  expectSameJob(back.items[1], page.items[1]);
  EXPECT_EQ(back.next, "cursor-2");

  page.next.clear();
  EXPECT_TRUE(api::toJson(page)["next"].is_null());
  back = valueOf(api::jobPageFromJson(api::toJson(page)));
  EXPECT_TRUE(back.next.empty());
}

TEST(ApiJson, RigPageRoundTrips) {
  api::RigPage page;
  page.items = {sampleRig(), sampleRig()};
  page.items[1].id = std::string(64, 'd');
  const api::RigPage back = valueOf(api::rigPageFromJson(api::toJson(page)));
  ASSERT_EQ(back.items.size(), 2u);
  EXPECT_EQ(back.items[1].id, page.items[1].id);
  EXPECT_EQ(api::toJson(back), api::toJson(page));
  EXPECT_EQ(valueOf(api::rigPageFromJson(json{{"items", json::array()}})).items.size(), 0u);
}

// ---- errors name the field ---------------------------------------------------

TEST(ApiJson, JobSpecRejectsRigOfWrongTypeNamingTheField) {
  const std::string e = errorOf(api::jobSpecFromJson(json{{"kind", "transfer"}, {"rig", 42}}));
  EXPECT_NE(e.find("spec.rig"), std::string::npos) << e;
}

TEST(ApiJson, JobSpecRejectsUnknownFieldNamingIt) {
  const std::string e = errorOf(api::jobSpecFromJson(json{{"kind", "transfer"}, {"rgi", "x"}}));
  EXPECT_NE(e.find("spec.rgi"), std::string::npos) << e;
}

TEST(ApiJson, JobSpecRequiresKindAndObjectOptions) {
  EXPECT_NE(errorOf(api::jobSpecFromJson(json{{"rig", "x"}})).find("spec.kind"), std::string::npos);
  EXPECT_NE(errorOf(api::jobSpecFromJson(json{{"kind", "transfer"}, {"options", json::array()}})).find("spec.options"),
            std::string::npos);
  EXPECT_NE(errorOf(api::jobSpecFromJson(json::array())).find("spec"), std::string::npos);
}

TEST(ApiJson, JobInfoRejectsUnknownStatusAndBadFieldsNamingThem) {
  json wire = api::toJson(sampleJob(api::JobStatus::kRunning));
  wire["status"] = "sleeping";
  EXPECT_NE(errorOf(api::jobInfoFromJson(wire)).find("job.status"), std::string::npos);
  wire = api::toJson(sampleJob(api::JobStatus::kRunning));
  wire["progress"] = "half";
  EXPECT_NE(errorOf(api::jobInfoFromJson(wire)).find("job.progress"), std::string::npos);
  wire = api::toJson(sampleJob(api::JobStatus::kRunning));
  wire["error"] = {{"title", "no type"}};
  EXPECT_NE(errorOf(api::jobInfoFromJson(wire)).find("job.error"), std::string::npos);
  wire.erase("error");
  wire.erase("id");
  EXPECT_NE(errorOf(api::jobInfoFromJson(wire)).find("job.id"), std::string::npos);
}

TEST(ApiJson, RigInfoAndProblemErrorsNameTheField) {
  json rig = api::toJson(sampleRig());
  rig["vertices"] = "many";
  EXPECT_NE(errorOf(api::rigInfoFromJson(rig)).find("rig.vertices"), std::string::npos);
  rig = api::toJson(sampleRig());
  rig["has_components"] = 1;
  EXPECT_NE(errorOf(api::rigInfoFromJson(rig)).find("rig.has_components"), std::string::npos);
  rig = api::toJson(sampleRig());
  rig["region_labels"] = json::array({1, 64});
  EXPECT_NE(errorOf(api::rigInfoFromJson(rig)).find("rig.region_labels"), std::string::npos);
  EXPECT_NE(errorOf(api::problemFromJson(json{{"type", "x"}})).find("problem.status"), std::string::npos);
}

TEST(ApiJson, PagesRejectMissingItems) {
  EXPECT_FALSE(errorOf(api::jobPageFromJson(json::object())).empty());
  EXPECT_FALSE(errorOf(api::rigPageFromJson(json{{"items", 3}})).empty());
  json page = api::toJson(api::JobPage{{sampleJob(api::JobStatus::kQueued)}, ""});
  page["items"][0]["status"] = 7;
  EXPECT_NE(errorOf(api::jobPageFromJson(page)).find("job.status"), std::string::npos);
}

TEST(ApiJson, ParseJsonTextNamesTheLabelOnBadText) {
  EXPECT_EQ(valueOf(api::parseJsonText(R"({"a":1})", "spec")), (json{{"a", 1}}));
  const std::string e = errorOf(api::parseJsonText("{\"a\":", "spec"));
  EXPECT_EQ(e.rfind("spec:", 0), 0u) << e;
}

TEST(ApiTypes, JobStatusNamesRoundTripAndFinalStatesAreTheThreeEnds) {
  for (auto status : {api::JobStatus::kQueued, api::JobStatus::kRunning, api::JobStatus::kSucceeded,
                      api::JobStatus::kFailed, api::JobStatus::kCancelled}) {
    EXPECT_EQ(api::parseJobStatus(api::jobStatusName(status)), status);
  }
  EXPECT_FALSE(api::parseJobStatus("done").has_value());
  EXPECT_FALSE(api::isFinal(api::JobStatus::kQueued));
  EXPECT_FALSE(api::isFinal(api::JobStatus::kRunning));
  EXPECT_TRUE(api::isFinal(api::JobStatus::kSucceeded));
  EXPECT_TRUE(api::isFinal(api::JobStatus::kFailed));
  EXPECT_TRUE(api::isFinal(api::JobStatus::kCancelled));
}

TEST(ApiTypes, TransferKindNeedsRigAndTargetItsLandmarksOptional) {
  const api::JobKindInfo& transfer = api::jobKindInfo(api::JobKind::kTransfer);
  EXPECT_EQ(transfer.kind, api::JobKind::kTransfer);
  EXPECT_TRUE(transfer.needs_rig);
  EXPECT_EQ(transfer.required_files, (std::vector<std::string>{"target"}));
  EXPECT_EQ(transfer.optional_files, (std::vector<std::string>{"target_landmarks"}));
  EXPECT_EQ(api::parseJobKind("transfer"), api::JobKind::kTransfer);
  EXPECT_EQ(api::parseJobKind("nope"), std::nullopt);
}

// ---- error codes -----------------------------------------------------------------

TEST(ApiErrorCodes, TableMapsEveryCodeToItsContractStatus) {
  using W = api::WireError;
  const std::vector<std::pair<W, int>> expected = {
      {W::kMalformedRequest, 400}, {W::kMalformedFile, 400},   {W::kInvalidOption, 400},
      {W::kUnauthorized, 401},     {W::kNotFound, 404},        {W::kConflict, 409},
      {W::kPayloadTooLarge, 413},  {W::kUnsupportedMediaType, 415}, {W::kInvalidMesh, 422},
      {W::kInvalidLandmarks, 422}, {W::kIllConditioned, 422},  {W::kUnsupportedFeature, 422},
      {W::kQueueFull, 429},        {W::kJobCancelled, 409},    {W::kJobTimeout, 504},
      {W::kInternal, 500},         {W::kNotReady, 503},
      {W::kStorageUnavailable, 503}, {W::kRequestTimeout, 408}, {W::kLengthRequired, 411},
      {W::kTooManyUploads, 429},     {W::kAuthThrottled, 429},     {W::kHeadersTooLarge, 431}};
  std::set<std::string> slugs;
  for (const auto& [error, status] : expected) {
    SCOPED_TRACE(api::wireErrorSlug(error));
    EXPECT_EQ(api::httpStatus(error), status);
    EXPECT_TRUE(slugs.insert(api::wireErrorSlug(error)).second) << "duplicate slug";
    EXPECT_EQ(api::problemType(error), std::string("urn:rigport:problem:") + api::wireErrorSlug(error));
  }
  EXPECT_STREQ(api::wireErrorSlug(W::kInvalidMesh), "invalid-mesh");
  EXPECT_STREQ(api::wireErrorSlug(W::kQueueFull), "queue-full");
}

TEST(ApiErrorCodes, MakeProblemFillsTypeTitleStatusDetailInstance) {
  const api::Problem p = api::makeProblem(api::WireError::kNotFound, "rig abc: not found", "/v1/rigs/abc");
  EXPECT_EQ(p.type, "urn:rigport:problem:not-found");
  EXPECT_FALSE(p.title.empty());
  EXPECT_EQ(p.status, 404);
  EXPECT_EQ(p.detail, "rig abc: not found");
  EXPECT_EQ(p.instance, "/v1/rigs/abc");
  expectSameProblem(valueOf(api::problemFromJson(api::toJson(p))), p);
}

// ---- content ids -----------------------------------------------------------------

std::vector<std::uint8_t> bytes(const std::string& s) { return {s.begin(), s.end()}; }

TEST(ApiContentId, Sha256MatchesTheKnownVectors) {
  EXPECT_EQ(api::sha256Hex(std::string_view("abc")), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
  EXPECT_EQ(api::sha256Hex(std::span<const std::uint8_t>(bytes("abc"))),
            "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
  EXPECT_EQ(api::sha256Hex(std::string_view("")), "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
}

TEST(ApiContentId, RigIdIsTheDocumentedHashOfHashes) {
  const auto rig = bytes("glb bytes"), landmarks = bytes("{\"landmarks\":[]}"), components = bytes("{}");
  const std::string expected = api::sha256Hex(std::string_view(
      "rigport-rig-v1\n" + api::sha256Hex(std::span<const std::uint8_t>(rig)) + "\n" +
      api::sha256Hex(std::span<const std::uint8_t>(landmarks)) + "\n" +
      api::sha256Hex(std::span<const std::uint8_t>(components)) + "\n"));
  EXPECT_EQ(api::rigContentId(rig, landmarks, components), expected);
  EXPECT_EQ(api::rigContentId(rig, landmarks, components), api::rigContentId(rig, landmarks, components));
  EXPECT_EQ(expected.size(), 64u);
}

TEST(ApiContentId, RigIdChangesWithEachInputAndAbsentComponentsAreEmpty) {
  const auto rig = bytes("glb"), landmarks = bytes("lm"), components = bytes("c");
  const std::string base = api::rigContentId(rig, landmarks, components);
  EXPECT_NE(api::rigContentId(bytes("glB"), landmarks, components), base);
  EXPECT_NE(api::rigContentId(rig, bytes("lM"), components), base);
  EXPECT_NE(api::rigContentId(rig, landmarks, bytes("C")), base);
  EXPECT_NE(api::rigContentId(rig, landmarks), base);
  EXPECT_EQ(api::rigContentId(rig, landmarks), api::rigContentId(rig, landmarks, {}));
  // The separators keep bytes from moving between inputs unnoticed.
  EXPECT_NE(api::rigContentId(bytes("gl"), bytes("blm"), components), api::rigContentId(bytes("glb"), bytes("lm"), components));
}

// ---- the OpenAPI document ----------------------------------------------------------

json loadOpenApi() {
  std::ifstream in(std::string(RIGPORT_SOURCE_DIR) + "/api/openapi.json", std::ios::binary);
  EXPECT_TRUE(in) << "api/openapi.json not found under " << RIGPORT_SOURCE_DIR;
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  auto parsed = api::parseJsonText(text, "api/openapi.json");
  return valueOf(parsed);
}

// The contract is checked against the OpenAPI 3 schema itself, so a client
// generator or a gateway that reads it does not stop at a keyword used the
// way another version spells it.
TEST(ApiOpenApi, DocumentPassesTheOpenApiSchemaValidator) {
  const std::string script = std::string(RIGPORT_SOURCE_DIR) + "/tests/tools/validate_openapi.mjs";
  const rigport_test::CommandResult run =
      rigport_test::runCommand("node '" + script + "' '" + std::string(RIGPORT_SOURCE_DIR) + "/api/openapi.json'");
  ASSERT_NE(run.exit_code, 2) << "the OpenAPI validator did not run (docker/install-deps.sh installs it): " << run.output;
  EXPECT_EQ(run.exit_code, 0) << run.output;
  EXPECT_NE(run.output.find("\"valid\":true"), std::string::npos) << run.output;
}

TEST(ApiOpenApi, DocumentIsValidJsonOfOpenApi3) {
  const json doc = loadOpenApi();
  ASSERT_TRUE(doc.is_object());
  ASSERT_TRUE(doc.contains("openapi"));
  EXPECT_EQ(doc["openapi"].get<std::string>().rfind("3.", 0), 0u);
  EXPECT_TRUE(doc.contains("info"));
  for (const char* schema : {"RigInfo", "RigPage", "JobSpec", "JobInfo", "JobPage", "Problem", "TransferOptions"}) {
    EXPECT_TRUE(doc["components"]["schemas"].contains(schema)) << schema;
  }
  EXPECT_TRUE(doc["components"]["securitySchemes"].contains("bearer"));
}

TEST(ApiOpenApi, EveryRouteOfTheContractHasItsMethods) {
  const json doc = loadOpenApi();
  const std::vector<std::pair<std::string, std::vector<std::string>>> routes = {
      {"/v1/rigs", {"get", "post"}},
      {"/v1/rigs/{id}", {"get", "delete"}},
      {"/v1/jobs", {"get", "post"}},
      {"/v1/jobs/{id}", {"get", "delete"}},
      {"/v1/jobs/{id}:cancel", {"post"}},
      {"/v1/jobs/{id}/result", {"get"}},
      {"/v1/jobs/{id}/diagnostics", {"get"}},
      {"/healthz", {"get"}},
      {"/readyz", {"get"}},
      {"/metrics", {"get"}},
      {"/openapi.json", {"get"}},
  };
  ASSERT_TRUE(doc.contains("paths"));
  for (const auto& [path, methods] : routes) {
    ASSERT_TRUE(doc["paths"].contains(path)) << path;
    for (const auto& method : methods) {
      EXPECT_TRUE(doc["paths"][path].contains(method)) << method << " " << path;
      EXPECT_TRUE(doc["paths"][path][method].contains("responses")) << method << " " << path;
    }
  }
}

TEST(ApiOpenApi, TransferOptionsSchemaListsEveryOptionKey) {
  const json doc = loadOpenApi();
  const json& props = doc["components"]["schemas"]["TransferOptions"]["properties"];
  for (const char* key : {"components", "uvs", "max_influences", "weight_encoding", "low_confidence_distance",
                          "low_confidence_angle_deg", "adaptation", "exaggeration", "shape_exaggeration",
                          "joint_exaggeration", "diagnostic_attributes", "refine_iterations",
                          "region_matching", "rim_matching", "slide_centres", "target_pulls", "smooth_guide",
                          "rim_location"}) {
    EXPECT_TRUE(props.contains(key)) << key;
  }
}

}  // namespace
