// Built-in TLS (--tls-cert / --tls-key): a job over HTTPS gives the bytes it
// gives over HTTP, kept-alive connections carry request after request, the
// client verifies the certificate (and fails without the CA), the CLI talks
// to an https:// service with --ca-cert, and a bad key or certificate stops
// the service at start with the file named.
#include <filesystem>
#include <fstream>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "tests/server/service_fixture.h"
#include "tests/test_support.h"

namespace rigport_test {
namespace {

server::ServerConfig tlsConfig(const std::filesystem::path& dir, const TlsFiles& tls) {
  server::ServerConfig config = testConfig(dir / "data");
  config.tls_certificate_file = tls.certificate;
  config.tls_private_key_file = tls.private_key;
  return config;
}

std::string quoted(const std::filesystem::path& path) { return "'" + path.string() + "'"; }

TEST(Tls, AJobOverHttpsGivesTheCliBytesOnKeptAliveConnections) {
  const auto dir = makeTempDir("tls_job");
  const TransferFiles files = writeTransferFiles(dir);
  const TlsFiles tls = writeSelfSignedCertificate(dir / "tls");
  const std::vector<std::uint8_t> cli = runCliTransfer(files, dir);
  ASSERT_FALSE(cli.empty());

  InProcessService service(tlsConfig(dir, tls));
  auto client = service.client();
  client->set_keep_alive(true);  // every request below on one connection, back through the gate each time
  EXPECT_EQ(get(*client, "/healthz").status, 200);
  const Reply rig = uploadRig(*client, files);
  ASSERT_EQ(rig.status, 201) << rig.raw;
  const Reply job = submitTransfer(*client, rig.body["id"], files);
  ASSERT_EQ(job.status, 202) << job.raw;
  const std::string id = job.body["id"];
  ASSERT_EQ(waitForJob(*client, id)["status"], "succeeded");
  const Reply result = get(*client, "/v1/jobs/" + id + "/result");
  ASSERT_EQ(result.status, 200);
  EXPECT_TRUE(result.raw == std::string(cli.begin(), cli.end()))
      << "HTTPS result differs from the in-process CLI (" << result.raw.size() << " vs " << cli.size() << " bytes)";

  // Without the CA the client refuses the service: the certificate is checked.
  httplib::Client untrusting("https://127.0.0.1:" + std::to_string(service.port()));
  const auto refused = untrusting.Get("/healthz");
  EXPECT_FALSE(refused) << "a client without the CA accepted the self-signed certificate";
  EXPECT_EQ(refused.error(), httplib::Error::SSLServerVerification) << httplib::to_string(refused.error());

  // Plain HTTP to the HTTPS port gets no HTTP answer, and takes nothing from anybody.
  httplib::Client plain("127.0.0.1", service.port());
  plain.set_read_timeout(5, 0);
  const auto plain_reply = plain.Get("/healthz");
  EXPECT_FALSE(plain_reply) << "plain HTTP was answered on the HTTPS port";
  EXPECT_EQ(get(*service.client(), "/healthz").status, 200);
}

TEST(Tls, TheCliReachesAnHttpsServiceWithItsCa) {
  const auto dir = makeTempDir("tls_cli");
  const TransferFiles files = writeTransferFiles(dir);
  const TlsFiles tls = writeSelfSignedCertificate(dir / "tls");
  InProcessService service(tlsConfig(dir, tls));
  const std::string server = " --server https://127.0.0.1:" + std::to_string(service.port());

  const CliRun upload = runRigportCli("-q rigs upload" + server + " --ca-cert " + quoted(tls.certificate) + " --rig " +
                                      quoted(files.rig) + " --landmarks " + quoted(files.landmarks));
  ASSERT_EQ(upload.exit_code, 0) << upload.log;
  const CliRun listed = runRigportCli("-q rigs list" + server + " --ca-cert " + quoted(tls.certificate));
  ASSERT_EQ(listed.exit_code, 0) << listed.log;
  EXPECT_EQ(nlohmann::json::parse(listed.out, nullptr, false)["items"].size(), 1u) << listed.out;

  const CliRun untrusted = runRigportCli("-q rigs list" + server);
  EXPECT_NE(untrusted.exit_code, 0) << untrusted.log;
  EXPECT_NE(untrusted.log.find("certificate"), std::string::npos) << untrusted.log;
}

TEST(Tls, ABadCertificateOrKeyStopsTheStartNamingTheFile) {
  const auto dir = makeTempDir("tls_bad");
  const TlsFiles tls = writeSelfSignedCertificate(dir / "tls");
  const TlsFiles other = writeSelfSignedCertificate(dir / "other");

  server::ServerConfig mismatched = tlsConfig(dir, tls);
  mismatched.tls_private_key_file = other.private_key;
  auto service = server::Service::create(mismatched, server::ApiKeys::disabled(), nullptr);
  ASSERT_FALSE(service);
  EXPECT_NE(service.error().message.find(other.private_key.string()), std::string::npos) << service.error().message;
  EXPECT_NE(service.error().message.find("does not belong"), std::string::npos) << service.error().message;

  server::ServerConfig not_pem = tlsConfig(dir, tls);
  not_pem.tls_certificate_file = dir / "tls" / "not_a_certificate.crt";
  std::ofstream(not_pem.tls_certificate_file) << "this is not PEM\n";
  service = server::Service::create(not_pem, server::ApiKeys::disabled(), nullptr);
  ASSERT_FALSE(service);
  EXPECT_NE(service.error().message.find("not_a_certificate.crt"), std::string::npos) << service.error().message;

  server::ServerConfig half = tlsConfig(dir, tls);
  half.tls_private_key_file.clear();
  service = server::Service::create(half, server::ApiKeys::disabled(), nullptr);
  ASSERT_FALSE(service);
  EXPECT_NE(service.error().message.find("--tls-key"), std::string::npos) << service.error().message;

  // The server binary says so and exits non-zero.
  const CommandResult run = runCommand(std::string("'") + RIGPORT_SERVER_PATH + "' --no-auth --listen 127.0.0.1:0 --data-dir " +
                                       quoted(dir / "data_bin") + " --tls-cert " + quoted(tls.certificate) +
                                       " --tls-key " + quoted(other.private_key));
  EXPECT_NE(run.exit_code, 0) << run.output;
  EXPECT_NE(run.output.find("does not belong"), std::string::npos) << run.output;
}

}  // namespace
}  // namespace rigport_test
