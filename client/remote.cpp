#include "client/remote.h"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <iterator>
#include <random>
#include <regex>
#include <stdexcept>
#include <system_error>
#include <thread>

#include "api/http.h"

#include "api/content_id.h"
#include "api/json.h"

namespace client {

namespace {

using nlohmann::json;

api::Problem localProblem(const char* type, const char* title, std::string detail) {
  api::Problem p;
  p.type = type;
  p.title = title;
  p.status = 0;
  p.detail = std::move(detail);
  return p;
}

// Reads a whole local file; the problem names the path and the OS error.
api::Result<std::string> readFile(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return localProblem(kClientIoProblem, "Cannot read a local file", path.string() + ": " + std::strerror(errno));
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (in.bad()) return localProblem(kClientIoProblem, "Cannot read a local file", path.string() + ": read error");
  return bytes;
}

// Writes through `path`.part and renames, so a failed download leaves no half file.
api::Result<std::int64_t> writeFile(const std::filesystem::path& path, const std::string& bytes) {
  std::filesystem::path part = path;
  part += ".part";
  {
    std::ofstream out(part, std::ios::binary | std::ios::trunc);
    if (!out) return localProblem(kClientIoProblem, "Cannot write a local file", part.string() + ": " + std::strerror(errno));
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    if (!out.flush()) return localProblem(kClientIoProblem, "Cannot write a local file", part.string() + ": write error");
  }
  std::error_code ec;
  std::filesystem::rename(part, path, ec);
  if (ec) return localProblem(kClientIoProblem, "Cannot write a local file", path.string() + ": " + ec.message());
  return static_cast<std::int64_t>(bytes.size());
}

std::span<const std::uint8_t> asBytes(const std::string& s) {
  return {reinterpret_cast<const std::uint8_t*>(s.data()), s.size()};
}

// The media type of an uploaded file, from its extension.
std::string mediaTypeOf(const std::filesystem::path& path) {
  std::string ext = path.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (ext == ".glb") return "model/gltf-binary";
  if (ext == ".gltf") return "model/gltf+json";
  if (ext == ".json") return "application/json";
  if (ext == ".obj") return "model/obj";
  if (ext == ".trc" || ext == ".txt") return "text/plain";
  return "application/octet-stream";
}

// Percent-encodes everything but RFC 3986 unreserved characters.
std::string escape(const std::string& s) {
  static constexpr char kHex[] = "0123456789ABCDEF";
  std::string out;
  for (unsigned char c : s) {
    if (std::isalnum(c) || c == '-' || c == '_' || c == '.' || c == '~') {
      out.push_back(static_cast<char>(c));
    } else {
      out.push_back('%');
      out.push_back(kHex[c >> 4]);
      out.push_back(kHex[c & 0x0f]);
    }
  }
  return out;
}

const char* statusTitle(int status) {
  switch (status) {
    case 400: return "Bad Request";
    case 401: return "Unauthorized";
    case 403: return "Forbidden";
    case 404: return "Not Found";
    case 405: return "Method Not Allowed";
    case 409: return "Conflict";
    case 413: return "Payload Too Large";
    case 415: return "Unsupported Media Type";
    case 422: return "Unprocessable Content";
    case 429: return "Too Many Requests";
    case 500: return "Internal Server Error";
    case 502: return "Bad Gateway";
    case 503: return "Service Unavailable";
    case 504: return "Gateway Timeout";
    default: return "Unexpected HTTP status";
  }
}

bool isSuccess(int status) { return status >= 200 && status < 300; }

// Seconds of a Retry-After header (delta-seconds form; an HTTP date or a
// missing header counts as 1 s), clamped to [0, cap].
std::chrono::milliseconds retryAfter(const httplib::Response& res, std::chrono::milliseconds cap) {
  std::chrono::milliseconds wait(1000);
  const std::string value = res.get_header_value("Retry-After");
  if (!value.empty() && std::all_of(value.begin(), value.end(), [](unsigned char c) { return std::isdigit(c); }) &&
      value.size() < 9) {
    wait = std::chrono::seconds(std::stol(value));
  }
  return std::clamp(wait, std::chrono::milliseconds(0), cap);
}

}  // namespace

struct RemoteClient::Http {
  std::string base_url;              // "http://host:port", no trailing slash
  std::unique_ptr<httplib::Client> client;
  std::string invalid_reason;        // set when the URL is unusable

  api::Problem transportProblem(const std::string& method, const std::string& path, httplib::Error error) const {
    std::string what = httplib::to_string(error);
    switch (error) {
      case httplib::Error::Connection: what += " (could not connect)"; break;
      case httplib::Error::ConnectionTimeout: what += " (connect timed out)"; break;
      case httplib::Error::Read: what += " (reading the response failed or timed out)"; break;
      case httplib::Error::Write: what += " (sending the request failed or timed out)"; break;
      case httplib::Error::SSLConnection: what += " (TLS handshake failed: is the service serving https?)"; break;
      case httplib::Error::SSLServerVerification:
        what += " (the service's certificate is not trusted: give its CA with --ca-cert)";
        break;
      default: break;
    }
    return localProblem(kTransportProblem, "No response from the service", method + " " + base_url + path + ": " + what);
  }

  // The problem of a non-2xx answer: its problem+json body, else one made from
  // the status and the first bytes of the body.
  api::Problem responseProblem(const std::string& method, const std::string& path, const httplib::Response& res) const {
    if (auto parsed = api::parseJsonText(res.body, "problem"); parsed) {
      auto problem = api::problemFromJson(*parsed);
      if (problem) {
        api::Problem p = std::move(*problem);
        if (p.status == 0) p.status = res.status;
        if (p.detail.empty()) p.detail = method + " " + path + ": " + p.title;
        return p;
      }
    }
    api::Problem p;
    p.type = "about:blank";
    p.title = statusTitle(res.status);
    p.status = res.status;
    std::string excerpt = res.body.substr(0, 200);
    std::replace(excerpt.begin(), excerpt.end(), '\n', ' ');
    p.detail = method + " " + base_url + path + ": HTTP " + std::to_string(res.status) +
               (excerpt.empty() ? std::string() : ": " + excerpt);
    p.instance = path;
    return p;
  }

  // Parses a 2xx JSON body with one of the api/json.h readers.
  template <typename T, typename Reader>
  api::Result<T> parseBody(const std::string& method, const std::string& path, const httplib::Response& res,
                            Reader reader) const {
    auto parsed = api::parseJsonText(res.body, method + " " + path + " response");
    if (!parsed) {
      api::Problem p = localProblem(kBadResponseProblem, "Unexpected response body", parsed.error());
      p.status = res.status;
      return p;
    }
    auto value = reader(*parsed);
    if (!value) {
      api::Problem p = localProblem(kBadResponseProblem, "Unexpected response body",
                                    method + " " + path + " response: " + value.error());
      p.status = res.status;
      return p;
    }
    return std::move(*value);
  }
};

RemoteClient::RemoteClient(RemoteOptions options) : options_(std::move(options)), http_(std::make_unique<Http>()) {
  std::string url = options_.server_url;
  while (!url.empty() && url.back() == '/') url.pop_back();
  http_->base_url = url;
  static const std::regex kUrl(R"(^https?://(\[[0-9A-Fa-f:.]+\]|[^/:?#\[\]]+)(:[0-9]{1,5})?$)");
  if (!std::regex_match(url, kUrl)) {
    http_->invalid_reason = "'" + options_.server_url + "' is not a service URL (expected http://host:port)";
    return;
  }
  try {
    http_->client = std::make_unique<httplib::Client>(url);
  } catch (const std::exception& e) {
    http_->invalid_reason = "'" + options_.server_url + "': " + e.what();
    return;
  }
  if (!http_->client->is_valid()) {
    http_->invalid_reason = "'" + options_.server_url + "': cannot create an HTTP client for it";
    http_->client.reset();
    return;
  }
  auto& c = *http_->client;
  c.set_connection_timeout(options_.connect_timeout);
  c.set_read_timeout(options_.read_timeout);
  c.set_write_timeout(options_.write_timeout);
  c.set_keep_alive(true);
  c.set_follow_location(false);
  if (!options_.api_key.empty()) c.set_bearer_token_auth(options_.api_key);
  if (!options_.ca_certificate_file.empty()) c.set_ca_cert_path(options_.ca_certificate_file.string());
  // No default Accept: /result answers model/gltf-binary, the rest JSON.
  c.set_default_headers({{"User-Agent", "rigport-cli/0.1"}});
}

RemoteClient::~RemoteClient() = default;

namespace {

// A GET with bounded retries on transport errors (GET is safe to repeat).
httplib::Result getWithRetries(httplib::Client& client, const RemoteOptions& options, const std::string& path) {
  auto delay = options.get_retry_delay;
  for (int attempt = 0;; ++attempt) {
    httplib::Result res = client.Get(path);
    if (options.on_response) options.on_response(res ? res->status : 0);
    if (res || attempt >= options.max_get_retries) return res;
    std::this_thread::sleep_for(delay);
    delay *= 2;
  }
}

}  // namespace

#define RIGPORT_REQUIRE_CLIENT()                                                                      \
  if (!http_->client) return localProblem(kTransportProblem, "Invalid service URL", http_->invalid_reason)

api::Result<api::RigInfo> RemoteClient::getRig(const std::string& id) {
  RIGPORT_REQUIRE_CLIENT();
  const std::string path = "/v1/rigs/" + escape(id);
  auto res = getWithRetries(*http_->client, options_, path);
  if (!res) return http_->transportProblem("GET", path, res.error());
  if (!isSuccess(res->status)) return http_->responseProblem("GET", path, *res);
  return http_->parseBody<api::RigInfo>("GET", path, *res, api::rigInfoFromJson);
}

api::Result<api::RigPage> RemoteClient::listRigs() {
  RIGPORT_REQUIRE_CLIENT();
  const std::string path = "/v1/rigs";
  auto res = getWithRetries(*http_->client, options_, path);
  if (!res) return http_->transportProblem("GET", path, res.error());
  if (!isSuccess(res->status)) return http_->responseProblem("GET", path, *res);
  return http_->parseBody<api::RigPage>("GET", path, *res, api::rigPageFromJson);
}

api::Result<UploadedRig> RemoteClient::uploadRig(const RigFiles& files) {
  RIGPORT_REQUIRE_CLIENT();
  auto rig = readFile(files.rig);
  if (!rig) return rig.error();
  auto landmarks = readFile(files.landmarks);
  if (!landmarks) return landmarks.error();
  std::string components_bytes;
  if (!files.components.empty()) {
    auto components = readFile(files.components);
    if (!components) return components.error();
    components_bytes = std::move(*components);
  }
  const std::string id = api::rigContentId(asBytes(*rig), asBytes(*landmarks), asBytes(components_bytes));

  // Already there? Then the upload is skipped (the id is content-derived).
  auto existing = getRig(id);
  if (existing) return UploadedRig{std::move(*existing), false};
  if (existing.error().status != 404) return existing.error();

  httplib::MultipartFormDataItems items = {
      {"rig", std::move(*rig), files.rig.filename().string(), mediaTypeOf(files.rig)},
      {"landmarks", std::move(*landmarks), files.landmarks.filename().string(), "application/json"},
  };
  if (!files.components.empty()) {
    items.push_back({"components", std::move(components_bytes), files.components.filename().string(), "application/json"});
  }
  const std::string path = "/v1/rigs";
  auto res = http_->client->Post(path, items);
  if (options_.on_response) options_.on_response(res ? res->status : 0);
  if (!res) return http_->transportProblem("POST", path, res.error());
  if (!isSuccess(res->status)) return http_->responseProblem("POST", path, *res);
  auto info = http_->parseBody<api::RigInfo>("POST", path, *res, api::rigInfoFromJson);
  if (!info) return info.error();
  return UploadedRig{std::move(*info), res->status == 201};
}

api::Result<Done> RemoteClient::deleteRig(const std::string& id) { return deleteAt("/v1/rigs/" + escape(id)); }

api::Result<Done> RemoteClient::deleteJob(const std::string& id) { return deleteAt("/v1/jobs/" + escape(id)); }

api::Result<Done> RemoteClient::deleteAt(const std::string& path) {
  RIGPORT_REQUIRE_CLIENT();
  auto res = http_->client->Delete(path);
  if (options_.on_response) options_.on_response(res ? res->status : 0);
  if (!res) return http_->transportProblem("DELETE", path, res.error());
  if (!isSuccess(res->status)) return http_->responseProblem("DELETE", path, *res);
  return Done{};
}

namespace {

std::string randomIdempotencyKey() {
  thread_local std::mt19937_64 rng{std::random_device{}()};
  char buf[64];
  std::snprintf(buf, sizeof(buf), "rigport-%016llx%016llx", static_cast<unsigned long long>(rng()),
                static_cast<unsigned long long>(rng()));
  return buf;
}

}  // namespace

api::Result<SubmittedJob> RemoteClient::submitJob(const nlohmann::json& spec,
                                                   const std::map<std::string, std::filesystem::path>& files,
                                                   const std::string& idempotency_key) {
  RIGPORT_REQUIRE_CLIENT();
  httplib::MultipartFormDataItems items = {{"spec", spec.dump(), "", "application/json"}};
  for (const auto& [field, file] : files) {
    auto bytes = readFile(file);
    if (!bytes) return bytes.error();
    items.push_back({field, std::move(*bytes), file.filename().string(), mediaTypeOf(file)});
  }
  // Every submission carries an Idempotency-Key (the caller's, or a random
  // one), so a POST whose answer was lost (a keep-alive connection closed by
  // the server, a reset) can be sent again without creating a second job.
  httplib::Headers headers;
  headers.emplace("Idempotency-Key", idempotency_key.empty() ? randomIdempotencyKey() : idempotency_key);
  // For a load balancer with rig-affinity (docker/nginx.conf): jobs of one
  // rig go to the replica whose prepared-rig cache holds it. The spec, in the
  // body, stays what the service reads.
  if (spec.contains("rig") && spec["rig"].is_string()) headers.emplace("X-Rigport-Rig", spec["rig"].get<std::string>());

  const std::string path = "/v1/jobs";
  int transport_retries = 0;
  for (int retries = 0;; ++retries) {
    auto res = http_->client->Post(path, headers, items);
    if (options_.on_response) options_.on_response(res ? res->status : 0);
    if (!res && transport_retries < options_.max_get_retries) {
      std::this_thread::sleep_for(options_.get_retry_delay * (1 << transport_retries));
      ++transport_retries;
      continue;
    }
    if (!res) return http_->transportProblem("POST", path, res.error());
    if (res->status == 429 && retries < options_.max_queue_retries) {
      const auto wait = retryAfter(*res, options_.max_retry_after);
      if (std::chrono::steady_clock::now() + wait < options_.retry_deadline) {
        std::this_thread::sleep_for(wait);
        continue;
      }
    }
    if (!isSuccess(res->status)) return http_->responseProblem("POST", path, *res);
    auto job = http_->parseBody<api::JobInfo>("POST", path, *res, api::jobInfoFromJson);
    if (!job) return job.error();
    return SubmittedJob{std::move(*job), res->status != 200, retries};
  }
}

api::Result<api::JobInfo> RemoteClient::getJob(const std::string& id, std::chrono::milliseconds wait) {
  RIGPORT_REQUIRE_CLIENT();
  std::string path = "/v1/jobs/" + escape(id);
  if (wait.count() > 0) path += "?wait_ms=" + std::to_string(wait.count());
  auto res = getWithRetries(*http_->client, options_, path);
  if (!res) return http_->transportProblem("GET", path, res.error());
  if (!isSuccess(res->status)) return http_->responseProblem("GET", path, *res);
  return http_->parseBody<api::JobInfo>("GET", path, *res, api::jobInfoFromJson);
}

api::Result<api::JobPage> RemoteClient::listJobs(const JobQuery& query) {
  RIGPORT_REQUIRE_CLIENT();
  std::string path = "/v1/jobs";
  char sep = '?';
  auto add = [&](const char* key, const std::string& value) {
    path += sep;
    path += key;
    path += '=';
    path += escape(value);
    sep = '&';
  };
  if (!query.status.empty()) add("status", query.status);
  if (query.limit > 0) add("limit", std::to_string(query.limit));
  if (!query.after.empty()) add("after", query.after);
  auto res = getWithRetries(*http_->client, options_, path);
  if (!res) return http_->transportProblem("GET", path, res.error());
  if (!isSuccess(res->status)) return http_->responseProblem("GET", path, *res);
  return http_->parseBody<api::JobPage>("GET", path, *res, api::jobPageFromJson);
}

api::Result<api::JobInfo> RemoteClient::cancelJob(const std::string& id) {
  RIGPORT_REQUIRE_CLIENT();
  const std::string path = "/v1/jobs/" + escape(id) + ":cancel";
  auto res = http_->client->Post(path);
  if (options_.on_response) options_.on_response(res ? res->status : 0);
  if (!res) return http_->transportProblem("POST", path, res.error());
  if (!isSuccess(res->status)) return http_->responseProblem("POST", path, *res);
  return http_->parseBody<api::JobInfo>("POST", path, *res, api::jobInfoFromJson);
}

// GET /v1/jobs/{id}/<file>: result, diagnostics or components.
api::Result<std::string> RemoteClient::fetchJobFile(const std::string& id, const char* file) {
  RIGPORT_REQUIRE_CLIENT();
  const std::string path = "/v1/jobs/" + escape(id) + "/" + file;
  auto res = getWithRetries(*http_->client, options_, path);
  if (!res) return http_->transportProblem("GET", path, res.error());
  if (!isSuccess(res->status)) return http_->responseProblem("GET", path, *res);
  return std::move(res->body);
}

api::Result<std::string> RemoteClient::fetchDiagnostics(const std::string& id) { return fetchJobFile(id, "diagnostics"); }
api::Result<std::string> RemoteClient::fetchResult(const std::string& id) { return fetchJobFile(id, "result"); }
api::Result<std::string> RemoteClient::fetchComponents(const std::string& id) { return fetchJobFile(id, "components"); }

api::Result<std::int64_t> RemoteClient::downloadResult(const std::string& id, const std::filesystem::path& file) {
  auto bytes = fetchResult(id);
  if (!bytes) return bytes.error();
  return writeFile(file, *bytes);
}

api::Result<std::int64_t> RemoteClient::downloadDiagnostics(const std::string& id, const std::filesystem::path& file) {
  auto text = fetchDiagnostics(id);
  if (!text) return text.error();
  return writeFile(file, *text);
}

api::Result<std::int64_t> RemoteClient::downloadComponents(const std::string& id, const std::filesystem::path& file) {
  auto text = fetchComponents(id);
  if (!text) return text.error();
  return writeFile(file, *text);
}

api::Result<api::JobInfo> RemoteClient::waitJob(const std::string& id, const JobProgressCallback& on_progress,
                                                 std::chrono::milliseconds poll_interval,
                                                 std::chrono::milliseconds timeout) {
  using namespace std::chrono;
  const auto start = steady_clock::now();
  // Long polls stay well inside the read timeout (and the server's 60 s cap).
  const milliseconds longest_wait = std::min<milliseconds>(seconds(10), options_.read_timeout / 2);
  for (;;) {
    const auto asked = steady_clock::now();
    milliseconds wait{0};
    if (!on_progress) {
      wait = longest_wait;
      if (timeout.count() > 0) wait = std::min(wait, duration_cast<milliseconds>(timeout - (asked - start)));
    }
    auto job = getJob(id, std::max(wait, milliseconds(0)));
    if (!job) return job.error();
    if (on_progress) on_progress(*job);
    if (api::isFinal(job->status)) return job;
    if (timeout.count() > 0 && steady_clock::now() - start + poll_interval > timeout) {
      return localProblem(kWaitTimeoutProblem, "Gave up waiting",
                          "job " + id + " still " + api::jobStatusName(job->status) + " after " +
                              std::to_string(timeout.count() / 1000) + " s");
    }
    // A server that did not wait (too many waiters, or an older server)
    // still gets no more than one request per poll interval.
    const auto spent = steady_clock::now() - asked;
    if (spent < poll_interval) std::this_thread::sleep_for(poll_interval - spent);
  }
}

std::string describeProblem(const api::Problem& problem) {
  std::string line = problem.title.empty() ? problem.type : problem.title;
  if (problem.status > 0) line += " (HTTP " + std::to_string(problem.status) + ")";
  if (!problem.detail.empty()) line += ": " + problem.detail;
  return line;
}

}  // namespace client
