// Integration-test helpers: the real service in-process on an ephemeral
// loopback port (or the rigport-server binary, for crash tests), generated
// rig and target files, and contract-level requests with httplib::Client.
#pragma once

#include <filesystem>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <thread>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "api/http.h"
#include "server/service.h"

namespace rigport_test {

// A generated source rig and a target head of other proportions and
// triangulation (with the rig's _REGION labels), small enough that a job takes
// tens of milliseconds.
struct TransferFiles {
  std::filesystem::path rig, landmarks, target, target_landmarks;
  std::filesystem::path components;  // the rig's components JSON; empty = none (writeTransferFiles writes none)
};
// `target_cells` sets the target's grid (columns; rows follow): larger = slower jobs.
TransferFiles writeTransferFiles(const std::filesystem::path& dir, int target_cells = 40);

// The rigport CLI binary run with `arguments` (shell words, quoted by the
// caller); `log` is stderr then stdout, `out` stdout alone (the JSON commands print).
struct CliRun {
  int exit_code = -1;
  std::string log, out;
};
CliRun runRigportCli(const std::string& arguments);

// The rigport CLI's in-process transfer of `files` (the reference bytes).
// With `files.components` the CLI also writes out_dir/cli_components.json.
std::vector<std::uint8_t> runCliTransfer(const TransferFiles& files, const std::filesystem::path& out_dir);

// A self-signed certificate for 127.0.0.1 and localhost, and its private
// key (PEM, written with the openssl command; the test fails without it).
struct TlsFiles {
  std::filesystem::path certificate, private_key;
};
TlsFiles writeSelfSignedCertificate(const std::filesystem::path& dir);

// The service in this process on 127.0.0.1:<any free port> (HTTPS when the
// config names a certificate: client() then trusts it).
class InProcessService {
 public:
  explicit InProcessService(server::ServerConfig config, server::ApiKeys keys = server::ApiKeys::disabled());
  ~InProcessService();
  int port() const { return port_; }
  std::unique_ptr<httplib::Client> client(const std::string& api_key = "") const;
  void stop(double grace_s = 10.0);

 private:
  std::unique_ptr<server::Service> service_;
  std::thread thread_;
  int port_ = 0;
  std::filesystem::path tls_certificate_;
};

// A config for tests: data in `dir`, 2 workers, ephemeral port.
server::ServerConfig testConfig(const std::filesystem::path& dir);

struct Reply {
  int status = 0;                         // 0: transport error
  nlohmann::json body;                    // parsed when JSON, else null
  std::string raw;
  std::string content_type;
  std::string retry_after;
};

Reply uploadRig(httplib::Client& client, const TransferFiles& files);
// Without `files.target_landmarks` (empty) the job finds them by a fit.
Reply submitTransfer(httplib::Client& client, const std::string& rig_id, const TransferFiles& files,
                     const std::string& idempotency_key = "", const nlohmann::json& options = nlohmann::json::object());
Reply get(httplib::Client& client, const std::string& path);
Reply post(httplib::Client& client, const std::string& path);
Reply del(httplib::Client& client, const std::string& path);
// Polls GET /v1/jobs/{id} until the job is final (fails the test after 300 s).
nlohmann::json waitForJob(httplib::Client& client, const std::string& id);
// A value from /metrics ("rigport_cache_misses_total"), -1 when absent.
double metricValue(httplib::Client& client, const std::string& line_prefix);

}  // namespace rigport_test
