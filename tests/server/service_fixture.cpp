#include "tests/server/service_fixture.h"

#include <sys/wait.h>

#include <chrono>
#include <cstdlib>

#include "core/io/landmarks.h"
#include "core/io/mesh_io.h"
#include "core/io/rig_io.h"
#include "core/synthetic/synthetic_head.h"
#include "core/synthetic/synthetic_rig.h"
#include "tests/test_support.h"

namespace rigport_test {

namespace {

std::string readText(const std::filesystem::path& path) {
  auto bytes = core::readFileBytes(path);
  EXPECT_TRUE(bytes.ok()) << path;
  return bytes ? std::string(bytes->begin(), bytes->end()) : std::string();
}

void writeText(const std::filesystem::path& path, const std::string& text) {
  auto ok = core::writeFileBytes(path, std::span(reinterpret_cast<const std::uint8_t*>(text.data()), text.size()));
  ASSERT_TRUE(ok.ok()) << path;
}

Reply toReply(const httplib::Result& res) {
  Reply reply;
  if (!res) return reply;
  reply.status = res->status;
  reply.raw = res->body;
  reply.content_type = res->get_header_value("Content-Type");
  reply.retry_after = res->get_header_value("Retry-After");
  if (reply.content_type.find("json") != std::string::npos) {
    reply.body = nlohmann::json::parse(res->body, nullptr, false);
  }
  return reply;
}

}  // namespace

CliRun runRigportCli(const std::string& arguments) {
  const auto dir = makeTempDir("cli_run");
  const auto out = dir / "stdout.txt", err = dir / "stderr.txt";
  const std::string cmd = std::string("'") + RIGPORT_CLI_PATH + "' " + arguments + " > '" + out.string() + "' 2> '" +
                          err.string() + "'";
  const int status = std::system(cmd.c_str());
  CliRun run;
  run.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  run.out = readText(out);
  run.log = readText(err) + run.out;
  return run;
}

TransferFiles writeTransferFiles(const std::filesystem::path& dir, int target_cells) {
  std::filesystem::create_directories(dir);
  TransferFiles f{dir / "source_rig.glb", dir / "source_rig.landmarks.json", dir / "target_head.glb",
                  dir / "target_head.landmarks.json", {}};
  core::HeadResolution source_res;
  source_res.columns = 48;
  source_res.rows = 40;
  const core::SyntheticRig rig = core::generateRig({}, source_res);
  EXPECT_TRUE(core::writeRigGlb(rig.rig, f.rig).ok());
  writeText(f.landmarks, core::formatLandmarks(rig.landmarks));
  core::HeadResolution target_res;
  target_res.columns = target_cells;
  target_res.rows = target_cells * 9 / 10;
  target_res.alternate_diagonals = true;
  target_res.jitter = 0.2;
  target_res.seed = 3;
  // Generated heads carry lip and lid labels like the rig's, so every
  // service job also runs region-constrained matching.
  const core::SyntheticHead head = core::generateHead(core::randomHeadShape(3, 0.15), target_res);
  EXPECT_TRUE(core::writeMeshGlb(head.mesh, f.target).ok());
  writeText(f.target_landmarks, core::formatLandmarks(head.landmarks));
  return f;
}

std::vector<std::uint8_t> runCliTransfer(const TransferFiles& files, const std::filesystem::path& out_dir) {
  const std::filesystem::path out = out_dir / "cli_out.glb";
  const std::string cmd = std::string("'") + RIGPORT_CLI_PATH + "' -q transfer --source '" + files.rig.string() +
                          "' --source-landmarks '" + files.landmarks.string() + "' --target '" + files.target.string() +
                          "' --target-landmarks '" + files.target_landmarks.string() + "' -o '" + out.string() + "'" +
                          (files.components.empty() ? std::string()
                                                    : " --source-components '" + files.components.string() +
                                                          "' --components-out '" +
                                                          (out_dir / "cli_components.json").string() + "'");
  EXPECT_EQ(std::system(cmd.c_str()), 0) << cmd;
  auto bytes = core::readFileBytes(out);
  EXPECT_TRUE(bytes.ok());
  return bytes ? *bytes : std::vector<std::uint8_t>{};
}

server::ServerConfig testConfig(const std::filesystem::path& dir) {
  server::ServerConfig config;
  config.port = 0;
  config.data_dir = dir;
  config.workers = 2;
  return config;
}

TlsFiles writeSelfSignedCertificate(const std::filesystem::path& dir) {
  std::filesystem::create_directories(dir);
  const TlsFiles files{dir / "service.crt", dir / "service.key"};
  const CommandResult made = runCommand(
      "openssl req -x509 -newkey ec -pkeyopt ec_paramgen_curve:prime256v1 -nodes -days 2 -subj /CN=localhost "
      "-addext subjectAltName=DNS:localhost,IP:127.0.0.1 -keyout '" +
      files.private_key.string() + "' -out '" + files.certificate.string() + "'");
  EXPECT_EQ(made.exit_code, 0) << "openssl req: " << made.output;
  return files;
}

InProcessService::InProcessService(server::ServerConfig config, server::ApiKeys keys)
    : tls_certificate_(config.tls_certificate_file) {
  auto service = server::Service::create(config, std::move(keys), nullptr);
  if (!service) {
    ADD_FAILURE() << service.error().message;
    return;
  }
  service_ = std::move(*service);
  auto port = service_->start();
  if (!port) {
    ADD_FAILURE() << port.error().message;
    return;
  }
  port_ = *port;
  thread_ = std::thread([this] { service_->serve(); });
}

InProcessService::~InProcessService() { stop(10.0); }

void InProcessService::stop(double grace_s) {
  if (service_) service_->stop(grace_s);
  if (thread_.joinable()) thread_.join();
}

std::unique_ptr<httplib::Client> InProcessService::client(const std::string& api_key) const {
  auto client = tls_certificate_.empty()
                    ? std::make_unique<httplib::Client>("127.0.0.1", port_)
                    : std::make_unique<httplib::Client>("https://127.0.0.1:" + std::to_string(port_));
  if (!tls_certificate_.empty()) client->set_ca_cert_path(tls_certificate_.string());
  client->set_connection_timeout(5, 0);
  client->set_read_timeout(60, 0);
  client->set_write_timeout(60, 0);
  if (!api_key.empty()) client->set_bearer_token_auth(api_key);
  return client;
}

Reply uploadRig(httplib::Client& client, const TransferFiles& f) {
  httplib::MultipartFormDataItems items = {
      {"rig", readText(f.rig), f.rig.filename().string(), "model/gltf-binary"},
      {"landmarks", readText(f.landmarks), f.landmarks.filename().string(), "application/json"},
  };
  if (!f.components.empty()) {
    items.push_back({"components", readText(f.components), f.components.filename().string(), "application/json"});
  }
  return toReply(client.Post("/v1/rigs", items));
}

Reply submitTransfer(httplib::Client& client, const std::string& rig_id, const TransferFiles& f,
                     const std::string& idempotency_key, const nlohmann::json& options) {
  const nlohmann::json spec = {{"kind", "transfer"}, {"rig", rig_id}, {"options", options}};
  httplib::MultipartFormDataItems items = {
      {"spec", spec.dump(), "spec.json", "application/json"},
      {"target", readText(f.target), f.target.filename().string(), "model/gltf-binary"},
  };
  if (!f.target_landmarks.empty()) {
    items.push_back({"target_landmarks", readText(f.target_landmarks), f.target_landmarks.filename().string(),
                     "application/json"});
  }
  httplib::Headers headers;
  if (!idempotency_key.empty()) headers.emplace("Idempotency-Key", idempotency_key);
  return toReply(client.Post("/v1/jobs", headers, items));
}

Reply get(httplib::Client& client, const std::string& path) { return toReply(client.Get(path)); }
Reply post(httplib::Client& client, const std::string& path) { return toReply(client.Post(path, "", "text/plain")); }
Reply del(httplib::Client& client, const std::string& path) { return toReply(client.Delete(path)); }

nlohmann::json waitForJob(httplib::Client& client, const std::string& id) {
  const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(300);
  while (std::chrono::steady_clock::now() < give_up) {
    Reply r = get(client, "/v1/jobs/" + id);
    if (r.status != 200) {
      ADD_FAILURE() << "GET /v1/jobs/" << id << " -> " << r.status << " " << r.raw;
      return {};
    }
    const std::string status = r.body.value("status", "");
    if (status == "succeeded" || status == "failed" || status == "cancelled") return r.body;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  ADD_FAILURE() << "job " << id << " not final after 300 s";
  return {};
}

double metricValue(httplib::Client& client, const std::string& prefix) {
  Reply r = get(client, "/metrics");
  std::istringstream lines(r.raw);
  std::string line;
  while (std::getline(lines, line)) {
    if (line.rfind(prefix + " ", 0) == 0) return std::stod(line.substr(prefix.size() + 1));
  }
  return -1.0;
}

}  // namespace rigport_test
