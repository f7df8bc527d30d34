// API keys and tenants: a tenant never sees another's rigs or jobs (404, not
// 403), uploads are idempotent by content, Idempotency-Key replays a job.
#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>

#include "core/jobs/transfer_options.h"
#include "tests/server/service_fixture.h"
#include "tests/test_support.h"

namespace rigport_test {
namespace {

server::ApiKeys twoTenants() {
  auto keys = server::ApiKeys::load({}, "key-alice:alice,key-bob:bob");
  EXPECT_TRUE(keys.ok());
  return *keys;
}

TEST(Tenancy, RequestsWithoutAKnownKeyGet401) {
  const auto dir = makeTempDir("auth");
  InProcessService service(testConfig(dir / "data"), twoTenants());
  auto anonymous = service.client();
  Reply r = get(*anonymous, "/v1/rigs");
  EXPECT_EQ(r.status, 401);
  EXPECT_EQ(r.content_type, "application/problem+json");
  EXPECT_EQ(r.body["type"], "urn:rigport:problem:unauthorized");
  auto wrong = service.client("key-mallory");
  EXPECT_EQ(get(*wrong, "/v1/jobs").status, 401);
  // The scheme in any case, one or more spaces before the key (RFC 9110);
  // a key that only starts like one, another scheme, or no key: 401.
  auto withAuthorization = [&](const std::string& value) {
    auto client = service.client();
    client->set_default_headers({{"Authorization", value}});
    return get(*client, "/v1/jobs").status;
  };
  EXPECT_EQ(withAuthorization("bearer key-alice"), 200);
  EXPECT_EQ(withAuthorization("BEARER   key-alice"), 200);
  EXPECT_EQ(withAuthorization("Bearer key-alic"), 401);
  EXPECT_EQ(withAuthorization("Bearer key-alicex"), 401);
  EXPECT_EQ(withAuthorization("Basic key-alice"), 401);
  EXPECT_EQ(withAuthorization("Bearer "), 401);
  EXPECT_EQ(withAuthorization("Bearerkey-alice"), 401);
  const Reply health = get(*anonymous, "/healthz");  // probes need no key
  EXPECT_EQ(health.status, 200);
  EXPECT_EQ(health.raw.rfind("ok rigport ", 0), 0u) << health.raw;  // and say the server's version
  EXPECT_EQ(get(*anonymous, "/readyz").status, 200);
  Reply spec = get(*anonymous, "/openapi.json");
  ASSERT_EQ(spec.status, 200);
  EXPECT_EQ(spec.body.value("openapi", "").substr(0, 2), "3.");
  EXPECT_TRUE(spec.body["paths"].contains("/v1/jobs/{id}/result"));
  Reply metrics = get(*service.client("key-alice"), "/metrics");  // with keys on, metrics need one
  ASSERT_EQ(metrics.status, 200);
  EXPECT_NE(metrics.raw.find("rigport_http_requests_total{method=\"GET\",route=\"/v1/rigs\",status=\"401\"} 1"),
            std::string::npos) << metrics.raw;
  EXPECT_NE(metrics.raw.find("rigport_queue_depth 0"), std::string::npos);
}

TEST(Tenancy, ATenantCannotSeeFetchCancelOrDeleteAnothersRigsAndJobs) {
  const auto dir = makeTempDir("isolation");
  const TransferFiles files = writeTransferFiles(dir);
  InProcessService service(testConfig(dir / "data"), twoTenants());
  auto alice = service.client("key-alice");
  auto bob = service.client("key-bob");
  Reply rig = uploadRig(*alice, files);
  ASSERT_EQ(rig.status, 201) << rig.raw;
  const std::string rig_id = rig.body["id"];
  Reply job = submitTransfer(*alice, rig_id, files);
  ASSERT_EQ(job.status, 202) << job.raw;
  const std::string job_id = job.body["id"];
  waitForJob(*alice, job_id);

  EXPECT_EQ(get(*bob, "/v1/rigs/" + rig_id).status, 404);
  EXPECT_TRUE(get(*bob, "/v1/rigs").body["items"].empty());
  EXPECT_EQ(get(*bob, "/v1/jobs/" + job_id).status, 404);
  EXPECT_EQ(get(*bob, "/v1/jobs/" + job_id + "/result").status, 404);
  EXPECT_EQ(get(*bob, "/v1/jobs/" + job_id + "/diagnostics").status, 404);
  EXPECT_EQ(post(*bob, "/v1/jobs/" + job_id + ":cancel").status, 404);
  EXPECT_EQ(del(*bob, "/v1/rigs/" + rig_id).status, 404);
  EXPECT_EQ(del(*bob, "/v1/jobs/" + job_id).status, 404);
  EXPECT_TRUE(get(*bob, "/v1/jobs").body["items"].empty());
  Reply bob_job = submitTransfer(*bob, rig_id, files);  // bob cannot use alice's rig either
  EXPECT_EQ(bob_job.status, 404) << bob_job.raw;

  // Alice still has everything.
  EXPECT_EQ(get(*alice, "/v1/rigs/" + rig_id).status, 200);
  EXPECT_EQ(get(*alice, "/v1/jobs/" + job_id + "/result").status, 200);
  EXPECT_EQ(get(*alice, "/v1/jobs").body["items"].size(), 1u);
}

TEST(Tenancy, UploadingTheSameRigTwiceIsIdempotent) {
  const auto dir = makeTempDir("idempotent_upload");
  const TransferFiles files = writeTransferFiles(dir);
  InProcessService service(testConfig(dir / "data"), twoTenants());
  auto alice = service.client("key-alice");
  Reply first = uploadRig(*alice, files);
  Reply second = uploadRig(*alice, files);
  ASSERT_EQ(first.status, 201) << first.raw;
  EXPECT_EQ(second.status, 200) << second.raw;
  EXPECT_EQ(first.body["id"], second.body["id"]);
  EXPECT_EQ(get(*alice, "/v1/rigs").body["items"].size(), 1u);
  // Another tenant uploading the same bytes gets its own rig under the same id.
  auto bob = service.client("key-bob");
  EXPECT_EQ(uploadRig(*bob, files).status, 201);
  // Deleting is per tenant.
  EXPECT_EQ(del(*alice, "/v1/rigs/" + first.body["id"].get<std::string>()).status, 204);
  EXPECT_EQ(get(*alice, "/v1/rigs/" + first.body["id"].get<std::string>()).status, 404);
  EXPECT_EQ(get(*bob, "/v1/rigs/" + first.body["id"].get<std::string>()).status, 200);
}

TEST(Tenancy, IdempotencyKeyReturnsTheSameJob) {
  const auto dir = makeTempDir("idempotency_key");
  const TransferFiles files = writeTransferFiles(dir);
  InProcessService service(testConfig(dir / "data"), twoTenants());
  auto alice = service.client("key-alice");
  auto bob = service.client("key-bob");
  const std::string rig_id = uploadRig(*alice, files).body["id"];
  ASSERT_EQ(uploadRig(*bob, files).status, 201);
  Reply first = submitTransfer(*alice, rig_id, files, "batch-7/head-12");
  Reply again = submitTransfer(*alice, rig_id, files, "batch-7/head-12");
  ASSERT_EQ(first.status, 202) << first.raw;
  EXPECT_EQ(again.status, 200) << again.raw;
  EXPECT_EQ(first.body["id"], again.body["id"]);
  // Options are stored normalised: the defaults written out are the same request.
  Reply spelled_out = submitTransfer(*alice, rig_id, files, "batch-7/head-12",
                                     nlohmann::json::parse(core::transferOptionsJson(core::TransferSettings{})));
  EXPECT_EQ(spelled_out.status, 200) << spelled_out.raw;
  EXPECT_EQ(spelled_out.body["id"], first.body["id"]);
  Reply other_key = submitTransfer(*alice, rig_id, files, "batch-7/head-13");
  EXPECT_NE(other_key.body["id"], first.body["id"]);
  Reply other_tenant = submitTransfer(*bob, rig_id, files, "batch-7/head-12");  // keys are per tenant
  ASSERT_EQ(other_tenant.status, 202);
  EXPECT_NE(other_tenant.body["id"], first.body["id"]);
  waitForJob(*alice, first.body["id"]);
  waitForJob(*alice, other_key.body["id"]);
  waitForJob(*bob, other_tenant.body["id"]);
  EXPECT_EQ(get(*alice, "/v1/jobs").body["items"].size(), 2u);

  // The key reused with another request (other options; other target bytes):
  // 409 naming the job it belongs to, and nothing of it left on disk.
  auto blobFiles = [&] {
    std::size_t n = 0;
    for (const auto& entry : std::filesystem::recursive_directory_iterator(dir / "data")) n += entry.is_regular_file();
    return n;
  };
  const std::size_t before = blobFiles();
  Reply other_options = submitTransfer(*alice, rig_id, files, "batch-7/head-12", {{"max_influences", 3}});
  EXPECT_EQ(other_options.status, 409) << other_options.raw;
  EXPECT_EQ(other_options.body.value("type", ""), "urn:rigport:problem:conflict");
  EXPECT_NE(other_options.body.value("detail", "").find(first.body["id"].get<std::string>()), std::string::npos)
      << other_options.raw;
  TransferFiles other_target = files;
  other_target.target = dir / "other_target.glb";
  {
    std::ifstream in(files.target, std::ios::binary);
    std::ofstream out(other_target.target, std::ios::binary);
    out << in.rdbuf() << "    ";  // other bytes (a GLB padded past its length is still read)
  }
  Reply other_bytes = submitTransfer(*alice, rig_id, other_target, "batch-7/head-12");
  EXPECT_EQ(other_bytes.status, 409) << other_bytes.raw;
  EXPECT_EQ(blobFiles(), before);
  EXPECT_EQ(get(*alice, "/v1/jobs").body["items"].size(), 2u);
}


// Failed authentications are counted per client address: past the limit the
// address is refused (429 with Retry-After) for a minute, a good key included.
TEST(Tenancy, RepeatedFailedAuthenticationsAreThrottled) {
  const auto dir = makeTempDir("auth_throttle");
  server::ServerConfig config = testConfig(dir / "data");
  config.max_auth_failures_per_minute = 5;
  InProcessService service(config, twoTenants());
  auto alice = service.client("key-alice");
  EXPECT_EQ(get(*alice, "/v1/rigs").status, 200);
  auto guesser = service.client("key-guess");
  for (int i = 0; i < 5; ++i) EXPECT_EQ(get(*guesser, "/v1/rigs").status, 401) << "failure " << i + 1;
  const Reply sixth = get(*guesser, "/v1/rigs");  // over the limit: starts the block
  EXPECT_EQ(sixth.status, 401) << sixth.raw;
  const Reply blocked = get(*guesser, "/v1/jobs");
  EXPECT_EQ(blocked.status, 429) << blocked.raw;
  EXPECT_EQ(blocked.body["type"], "urn:rigport:problem:auth-throttled");
  const int retry_after = std::stoi(blocked.retry_after);
  EXPECT_GT(retry_after, 0);
  EXPECT_LE(retry_after, 60);
  EXPECT_EQ(get(*alice, "/v1/rigs").status, 429) << "the address is refused, whatever key it sends";
  EXPECT_EQ(get(*alice, "/healthz").status, 200) << "probes need no key and are never refused";
}

// Behind a trusted load balancer the limit is per client it names in
// X-Forwarded-For: one guessing client is refused, another through the same
// balancer is not. From a peer not trusted, the header is ignored: a guesser
// cannot dodge the limit by naming a new address each time.
TEST(Tenancy, AuthFailuresAreCountedPerClientBehindATrustedProxy) {
  const auto dir = makeTempDir("auth_proxy");
  server::ServerConfig config = testConfig(dir / "data");
  config.max_auth_failures_per_minute = 3;
  auto behind = [](InProcessService& service, const std::string& key, const std::string& forwarded_for) {
    auto client = service.client(key);
    client->set_default_headers({{"X-Forwarded-For", forwarded_for}});
    return client;
  };
  {
    config.trusted_proxies = {"10.0.0.0/8", "127.0.0.1"};
    InProcessService service(config, twoTenants());
    // The guesser wrote an address of its own to the left of the one the proxies appended.
    auto guesser = behind(service, "key-guess", "198.51.100.7, 203.0.113.5, 10.1.2.3");
    for (int i = 0; i < 4; ++i) EXPECT_EQ(get(*guesser, "/v1/rigs").status, 401) << "failure " << i + 1;
    EXPECT_EQ(get(*guesser, "/v1/rigs").status, 429);
    EXPECT_EQ(get(*behind(service, "key-alice", "203.0.113.5"), "/v1/rigs").status, 429) << "the guesser's address";
    EXPECT_EQ(get(*behind(service, "key-alice", "198.51.100.7"), "/v1/rigs").status, 200)
        << "the address the guesser wrote itself is not the one counted";
    EXPECT_EQ(get(*behind(service, "key-alice", "203.0.113.6"), "/v1/rigs").status, 200) << "another client";
  }
  config.trusted_proxies.clear();
  InProcessService service(config, twoTenants());
  for (int i = 0; i < 4; ++i) {
    EXPECT_EQ(get(*behind(service, "key-guess", "203.0.113." + std::to_string(i)), "/v1/rigs").status, 401) << i;
  }
  EXPECT_EQ(get(*behind(service, "key-alice", "203.0.113.9"), "/v1/rigs").status, 429);
}

// A trusted proxy that is not an address is refused at start, named.
TEST(Tenancy, AMalformedTrustedProxyIsRefusedAtStart) {
  const auto dir = makeTempDir("auth_proxy_bad");
  server::ServerConfig config = testConfig(dir / "data");
  config.trusted_proxies = {"10.0.0.0/8", "nginx.local"};
  auto service = server::Service::create(config, twoTenants(), nullptr);
  ASSERT_FALSE(service.ok());
  EXPECT_NE(service.error().message.find("--trusted-proxy \"nginx.local\": not an IPv4 or IPv6 address"),
            std::string::npos) << service.error().message;
}

// With keys on, /metrics needs one (any tenant's) unless made public.
TEST(Tenancy, MetricsNeedAKeyUnlessPublic) {
  const auto dir = makeTempDir("metrics_key");
  {
    InProcessService service(testConfig(dir / "data"), twoTenants());
    EXPECT_EQ(get(*service.client(), "/metrics").status, 401);
    const Reply with_key = get(*service.client("key-bob"), "/metrics");
    EXPECT_EQ(with_key.status, 200);
    EXPECT_NE(with_key.raw.find("rigport_queue_depth"), std::string::npos) << with_key.raw.substr(0, 300);
  }
  server::ServerConfig config = testConfig(dir / "data");
  config.public_metrics = true;
  InProcessService service(config, twoTenants());
  EXPECT_EQ(get(*service.client(), "/metrics").status, 200);
}

// The data directory and everything the service writes in it are its user's
// alone (studio assets on a shared machine); every response names its
// request for the access log.
TEST(Tenancy, StoredFilesArePrivateAndResponsesCarryARequestId) {
  const auto dir = makeTempDir("file_modes");
  const TransferFiles files = writeTransferFiles(dir);
  InProcessService service(testConfig(dir / "data"), twoTenants());
  auto alice = service.client("key-alice");
  const Reply rig = uploadRig(*alice, files);
  ASSERT_EQ(rig.status, 201) << rig.raw;
  const Reply job = submitTransfer(*alice, rig.body["id"], files);
  ASSERT_EQ(job.status, 202) << job.raw;
  EXPECT_EQ(waitForJob(*alice, job.body["id"])["status"], "succeeded");
  int checked = 0;
  for (const auto& entry : std::filesystem::recursive_directory_iterator(dir / "data")) {
    const auto perms = entry.status().permissions();
    const auto others = std::filesystem::perms::group_all | std::filesystem::perms::others_all;
    EXPECT_EQ(perms & others, std::filesystem::perms::none) << entry.path() << " is open to other users";
    ++checked;
  }
  EXPECT_GT(checked, 5);
  EXPECT_EQ((std::filesystem::status(dir / "data").permissions() & std::filesystem::perms::others_all),
            std::filesystem::perms::none);

  const auto first = alice->Get("/healthz"), second = alice->Get("/v1/rigs");
  ASSERT_TRUE(first && second);
  const std::string id1 = first->get_header_value("X-Request-Id"), id2 = second->get_header_value("X-Request-Id");
  EXPECT_EQ(id1.size(), 16u);
  EXPECT_NE(id1, id2);
  // A proxy's plain id is kept; anything else is replaced.
  const auto proxied = alice->Get("/healthz", {{"X-Request-Id", "edge-42.a_b"}});
  ASSERT_TRUE(proxied);
  EXPECT_EQ(proxied->get_header_value("X-Request-Id"), "edge-42.a_b");
  const auto odd = alice->Get("/healthz", {{"X-Request-Id", "a b;c"}});
  ASSERT_TRUE(odd);
  EXPECT_EQ(odd->get_header_value("X-Request-Id").size(), 16u);
}


// The prepared-rig cache is per tenant: the same rig bytes uploaded by two
// tenants are prepared for each (a cache hit never reveals another tenant's
// upload), and one tenant deleting its copy leaves the other's prepared rig.
TEST(Tenancy, CacheHitsAreReportedPerTenantAndADeleteEvictsOnlyItsOwn) {
  const auto dir = makeTempDir("tenant_cache");
  const TransferFiles files = writeTransferFiles(dir);
  InProcessService service(testConfig(dir / "data"), twoTenants());
  auto alice = service.client("key-alice");
  auto bob = service.client("key-bob");
  const auto runJob = [&](httplib::Client& client, const std::string& rig) {
    const Reply job = submitTransfer(client, rig, files);
    EXPECT_EQ(job.status, 202) << job.raw;
    const nlohmann::json done = waitForJob(client, job.body["id"]);
    EXPECT_EQ(done["status"], "succeeded") << done.dump();
    return done["cache_hit"].get<bool>();
  };
  const std::string rig = uploadRig(*alice, files).body["id"];
  ASSERT_EQ(uploadRig(*bob, files).body["id"], rig) << "the same bytes, the same rig id";
  EXPECT_FALSE(runJob(*alice, rig));
  EXPECT_FALSE(runJob(*bob, rig)) << "bob's first job must not learn that alice used these bytes";
  EXPECT_TRUE(runJob(*alice, rig));
  EXPECT_EQ(del(*bob, "/v1/rigs/" + rig).status, 204);
  EXPECT_TRUE(runJob(*alice, rig)) << "bob's delete must not evict alice's prepared rig";
}

}  // namespace
}  // namespace rigport_test
