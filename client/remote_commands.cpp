#include "client/remote_commands.h"

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>

#include "api/json.h"
#include "client/load_generator.h"
#include "client/local_jobs.h"
#include "client/cli_hints.h"
#include "client/remote.h"

namespace client {

namespace {

using nlohmann::json;

// --server / --api-key of one command line (only one command runs).
struct Connection {
  std::string server;
  std::string api_key;
  std::string ca_certificate;
};

void addConnectionOptions(CLI::App* cmd, Connection& c, bool server_required) {
  auto* server = cmd->add_option("--server", c.server, "Service URL, e.g. http://localhost:8080")
                     ->envname("RIGPORT_SERVER");
  if (server_required) server->required();
  cmd->add_option("--api-key", c.api_key, "API key, sent as a Bearer token")
      ->envname("RIGPORT_API_KEY");
  cmd->add_option("--ca-cert", c.ca_certificate, "https:// service: the CA (PEM) its certificate is signed by")
      ->envname("RIGPORT_CA_CERT")
      ->check(CLI::ExistingFile);
}

RemoteOptions remoteOptions(const Connection& c) {
  RemoteOptions options;
  options.server_url = c.server;
  options.api_key = c.api_key;
  options.ca_certificate_file = c.ca_certificate;
  return options;
}

int fail(const api::Problem& problem) {
  spdlog::error("{}", describeProblem(problem));
  return 1;
}

int failText(const std::string& message) {
  spdlog::error("{}", message);
  return 1;
}

void printJson(const json& j) {
  std::printf("%s\n", j.dump(2).c_str());
  std::fflush(stdout);
}

// Reads a JSON file that must hold an object; the error names the file.
api::Parsed<json> readJsonObject(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return path.string() + ": cannot read";
  auto parsed = api::parseJsonText(std::string(std::istreambuf_iterator<char>(in), {}), path.string());
  if (parsed && !parsed->is_object()) return path.string() + ": expected a JSON object";
  return parsed;
}

// Shows job progress on stderr: a redrawn bar on a terminal, otherwise a log
// line when the stage changes and at most every 5 s.
class ProgressDisplay {
 public:
  ProgressDisplay() : tty_(::isatty(::fileno(stderr)) != 0), enabled_(spdlog::should_log(spdlog::level::info)) {}
  ~ProgressDisplay() { finish(); }

  void update(const api::JobInfo& job) {
    if (!enabled_) return;
    const int percent = static_cast<int>(job.progress * 100.0 + 0.5);
    const std::string label = job.status == api::JobStatus::kRunning ? job.stage : api::jobStatusName(job.status);
    if (tty_) {
      constexpr int kWidth = 30;
      const int filled = std::clamp(percent * kWidth / 100, 0, kWidth);
      std::fprintf(stderr, "\r[%s%s] %3d%% %-24.24s", std::string(static_cast<std::size_t>(filled), '#').c_str(),
                   std::string(static_cast<std::size_t>(kWidth - filled), '.').c_str(), percent, label.c_str());
      std::fflush(stderr);
      drawn_ = true;
      return;
    }
    const auto now = std::chrono::steady_clock::now();
    if (label != last_label_ || now - last_log_ >= std::chrono::seconds(5)) {
      spdlog::info("job {}: {} {}%", job.id, label, percent);
      last_label_ = label;
      last_log_ = now;
    }
  }

  void finish() {
    if (drawn_) std::fputc('\n', stderr);
    drawn_ = false;
  }

 private:
  bool tty_;
  bool enabled_;
  bool drawn_ = false;
  std::string last_label_;
  std::chrono::steady_clock::time_point last_log_{};
};

// Waits for a job with the progress display; the final state (any status).
api::Result<api::JobInfo> waitWithProgress(RemoteClient& client, const std::string& id, double timeout_s) {
  ProgressDisplay display;
  auto job = client.waitJob(
      id, [&display](const api::JobInfo& j) { display.update(j); }, std::chrono::milliseconds(250),
      std::chrono::milliseconds(static_cast<long long>(timeout_s * 1000.0)));
  display.finish();
  return job;
}

// The job's own problem when it did not succeed.
int failJob(const api::JobInfo& job) {
  if (job.error) return failText("job " + job.id + " " + api::jobStatusName(job.status) + ": " + describeProblem(*job.error));
  return failText("job " + job.id + " " + api::jobStatusName(job.status));
}

// A succeeded job's outputs on disk: the GLB at `output`, the diagnostics at
// `diagnostics_file` and/or on stdout when asked. Their text is kept for the
// summary (nullopt when it could not be fetched and was not asked for).
struct JobOutputs {
  int exit_code = 0;  // non-zero: a problem, already logged
  std::int64_t bytes = 0;
  std::optional<std::string> diagnostics;
};

bool writeDiagnosticsFile(const std::filesystem::path& path, const std::string& diagnostics) {
  std::ofstream file(path, std::ios::binary | std::ios::trunc);
  file << diagnostics;
  return static_cast<bool>(file.flush());
}

JobOutputs fetchOutputs(RemoteClient& client, const std::string& id, const std::filesystem::path& output,
                        const std::filesystem::path& diagnostics_file, bool print_diagnostics,
                        const std::filesystem::path& components_file) {
  JobOutputs out;
  const auto failed = [](int exit_code) {
    JobOutputs f;
    f.exit_code = exit_code;
    return f;
  };
  auto written = client.downloadResult(id, output);
  if (!written) return failed(fail(written.error()));
  out.bytes = *written;
  if (!components_file.empty()) {
    if (auto components = client.downloadComponents(id, components_file); !components) {
      return failed(fail(components.error()));
    }
    spdlog::info("wrote {}", components_file.string());
  }
  auto diagnostics = client.fetchDiagnostics(id);
  if (!diagnostics) {
    if (!diagnostics_file.empty() || print_diagnostics) return failed(fail(diagnostics.error()));
    spdlog::warn("diagnostics: {}", describeProblem(diagnostics.error()));
    return out;
  }
  if (!diagnostics_file.empty() && !writeDiagnosticsFile(diagnostics_file, *diagnostics)) {
    return failed(failText(diagnostics_file.string() + ": cannot write"));
  }
  if (print_diagnostics) std::fputs(diagnostics->c_str(), stdout);
  out.diagnostics = std::move(*diagnostics);
  return out;
}

// A job's options: the --options file's object (empty without one), with
// "strict" set by --strict.
api::Parsed<json> jobOptions(const std::filesystem::path& file, bool strict) {
  json options = json::object();
  if (!file.empty()) {
    auto parsed = readJsonObject(file);
    if (!parsed) return parsed.error();
    options = std::move(*parsed);
  }
  if (strict) options["strict"] = true;
  return options;
}

// ---- transfer --server -------------------------------------------------------

int runRemoteTransfer(const TransferArgs& args, const Connection& connection) {
  const auto t_start = std::chrono::steady_clock::now();
  if (args.threads != 0) spdlog::warn("--threads is ignored with --server (the service sizes its workers)");
  auto read_options = jobOptions(args.options, args.strict);
  if (!read_options) return failText(read_options.error());
  const json options = std::move(*read_options);
  RemoteClient client(remoteOptions(connection));

  auto rig = client.uploadRig({args.source, args.source_landmarks, args.source_components});
  if (!rig) return fail(rig.error());
  spdlog::info("rig {} {} ({} vertices, {} joints, {} shapes)", rig->rig.id,
               rig->uploaded ? "uploaded" : "already on the service", rig->rig.vertices, rig->rig.joints,
               rig->rig.morph_targets);

  const json spec = {{"kind", "transfer"}, {"rig", rig->rig.id}, {"options", options}};
  std::map<std::string, std::filesystem::path> files = {{"target", args.target}};
  if (!args.target_landmarks.empty()) files["target_landmarks"] = args.target_landmarks;
  auto submitted = client.submitJob(spec, files);
  if (!submitted) return fail(submitted.error());
  const std::string id = submitted->job.id;
  spdlog::info("job {} {}{}", id, api::jobStatusName(submitted->job.status),
               submitted->queue_retries ? " after " + std::to_string(submitted->queue_retries) + " queue-full retries" : "");

  auto job = waitWithProgress(client, id, 0.0);
  if (!job) return fail(job.error());
  if (job->status != api::JobStatus::kSucceeded) return failJob(*job);

  const JobOutputs fetched = fetchOutputs(client, id, args.output, args.diagnostics, args.print_diagnostics, args.components_out);
  if (fetched.exit_code != 0) return fetched.exit_code;
  const std::optional<std::string>& diagnostics = fetched.diagnostics;

  // The same one-line summary as the in-process run, from the diagnostics JSON.
  const double total_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t_start).count();
  const json d = diagnostics ? json::parse(*diagnostics, nullptr, false) : json();
  if (d.is_object()) {
    const auto num = [&d](const char* section, const char* key) {
      const auto s = d.find(section);
      if (s == d.end() || !s->is_object()) return 0.0;
      const auto v = s->find(key);
      return v != s->end() && v->is_number() ? v->get<double>() : 0.0;
    };
    const double diagonal = num("mesh", "bbox_diagonal");
    const auto suspicious = d.contains("landmarks") && d["landmarks"].contains("suspicious") && d["landmarks"]["suspicious"].is_array()
                                ? d["landmarks"]["suspicious"]
                                : json::array();
    if (!suspicious.empty()) spdlog::warn("suspicious landmarks (swapped or misplaced?): {}", suspicious.dump());
    for (const char* section : {"correspondence", "transfer"}) {
      if (const auto c = d.find(section); c != d.end() && c->is_object() && c->contains("warnings") &&
                                          (*c)["warnings"].is_array()) {
        for (const json& warning : (*c)["warnings"]) {
          if (warning.is_string()) spdlog::warn("{}", warning.get<std::string>());
        }
      }
    }
    spdlog::info("transfer (job {}{}): {} joints, {} shapes, {} animations; {} vertices inpainted, {} pruned; "
                 "landmark rms {:.3g}, correspondence p95 {:.3f}% of diagonal, {} flipped; service {:.1f} ms, total {:.1f} ms",
                 id, job->cache_hit ? ", cached rig" : "", num("joints", "count"), num("shapes", "count"),
                 num("animations", "count"), num("weights", "inpainted_vertices"), num("weights", "pruned_vertices"),
                 num("landmarks", "rms_residual"),
                 diagonal > 0.0 ? 100.0 * num("correspondence", "p95_distance") / diagonal : 0.0,
                 num("correspondence", "flipped_triangles"), num("timings_ms", "total"), total_ms);
  } else {
    spdlog::info("transfer (job {}{}): total {:.1f} ms", id, job->cache_hit ? ", cached rig" : "", total_ms);
  }
  spdlog::info("wrote {} ({} bytes){}", args.output.string(), fetched.bytes,
               args.diagnostics.empty() ? "" : " and " + args.diagnostics.string());
  return 0;
}

// ---- fit --server -------------------------------------------------------------

// The number at d[section][key], 0 when absent.
double numberAt(const json& d, const char* section, const char* key) {
  const auto s = d.find(section);
  if (s == d.end() || !s->is_object()) return 0.0;
  const auto v = s->find(key);
  return v != s->end() && v->is_number() ? v->get<double>() : 0.0;
}

// Logs the strings of the array d[key] as warnings.
void warnEach(const json& d, const char* key) {
  if (const auto list = d.find(key); list != d.end() && list->is_array()) {
    for (const json& item : *list) {
      if (item.is_string()) spdlog::warn("{}", item.get<std::string>());
    }
  }
}

int runRemoteFit(const FitArgs& args, const Connection& connection) {
  const auto t_start = std::chrono::steady_clock::now();
  if (args.threads != 0) spdlog::warn("--threads is ignored with --server (the service sizes its workers)");
  auto read_options = jobOptions(args.options, args.strict);
  if (!read_options) return failText(read_options.error());
  const json options = std::move(*read_options);
  RemoteClient client(remoteOptions(connection));

  // The reference is a rig like a transfer's source: uploaded once, prepared once.
  auto rig = client.uploadRig({args.reference, args.reference_landmarks, args.reference_components});
  if (!rig) return fail(rig.error());
  spdlog::info("reference {} {} ({} vertices, {} shapes)", rig->rig.id,
               rig->uploaded ? "uploaded" : "already on the service", rig->rig.vertices, rig->rig.morph_targets);

  const json spec = {{"kind", "fit"}, {"rig", rig->rig.id}, {"options", options}};
  std::map<std::string, std::filesystem::path> files = {{"scan", args.scan}};
  if (!args.scan_landmarks.empty()) files.emplace("scan_landmarks", args.scan_landmarks);
  auto submitted = client.submitJob(spec, files);
  if (!submitted) return fail(submitted.error());
  const std::string id = submitted->job.id;
  spdlog::info("job {} {}{}", id, api::jobStatusName(submitted->job.status),
               submitted->queue_retries ? " after " + std::to_string(submitted->queue_retries) + " queue-full retries" : "");

  auto job = waitWithProgress(client, id, 0.0);
  if (!job) return fail(job.error());
  if (job->status != api::JobStatus::kSucceeded) {
    // A fit its gate refused keeps its diagnostics, written as in-process.
    if (!args.diagnostics.empty()) {
      if (auto refused = client.fetchDiagnostics(id); refused && writeDiagnosticsFile(args.diagnostics, *refused)) {
        spdlog::info("wrote {} (the refused fit's diagnostics)", args.diagnostics.string());
      }
    }
    return failJob(*job);
  }

  const JobOutputs fetched = fetchOutputs(client, id, args.output, args.diagnostics, args.print_diagnostics, args.components_out);
  if (fetched.exit_code != 0) return fetched.exit_code;
  const std::optional<std::string>& diagnostics = fetched.diagnostics;

  // The in-process run's summary line, from the diagnostics JSON.
  const double total_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t_start).count();
  const json d = diagnostics ? json::parse(*diagnostics, nullptr, false) : json();
  const std::string cached = job->cache_hit ? ", cached reference" : "";
  if (d.is_object()) {
    warnEach(d, "warnings");
    warnEach(d, "reasons");
    const auto text = [](const json& j, const char* key) {
      return j.is_object() && j.contains(key) && j[key].is_string() ? j[key].get<std::string>() : std::string("?");
    };
    const std::string units = text(d.value("scan", json()), "units");
    const json face = d.contains("distance") && d["distance"].is_object() ? d["distance"].value("face", json()) : json();
    spdlog::info("fit (job {}{}): {} ({} alignment, scan in {}, head {:.3f}x the reference); face to scan median {:.3g} / "
                 "p95 {:.3g} / max {:.3g} {}, face coverage {:.1f}%, {} flipped; service {:.1f} ms, total {:.1f} ms",
                 id, cached, text(d, "verdict"), text(d.value("alignment", json()), "method"), units,
                 numberAt(d, "scan", "size_ratio"), face.is_object() ? face.value("median", 0.0) : 0.0,
                 face.is_object() ? face.value("p95", 0.0) : 0.0, face.is_object() ? face.value("max", 0.0) : 0.0, units,
                 100.0 * numberAt(d, "coverage", "face"), numberAt(d, "folds", "flipped"),
                 numberAt(d, "timings_ms", "total"), total_ms);
  } else {
    spdlog::info("fit (job {}{}): total {:.1f} ms", id, cached, total_ms);
  }
  spdlog::info("wrote {} ({} bytes){}", args.output.string(), fetched.bytes,
               args.diagnostics.empty() ? "" : " and " + args.diagnostics.string());
  return 0;
}

}  // namespace

// ---- the CLI wiring --------------------------------------------------------------

struct RemoteCommands::State {
  // One per command: options bound to one shared variable would let another
  // command's env default (RIGPORT_SERVER) overwrite the parsed flag.
  std::map<const CLI::App*, Connection> connections;
  Connection connection;  // the chosen command's, copied in run()
  CLI::App* transfer = nullptr;
  CLI::App* fit = nullptr;

  CLI::App* rigs_upload = nullptr;
  CLI::App* rigs_list = nullptr;
  CLI::App* rigs_get = nullptr;
  CLI::App* rigs_delete = nullptr;
  RigFiles rig_files;
  std::string rig_id;

  CLI::App* jobs_submit = nullptr;
  CLI::App* jobs_get = nullptr;
  CLI::App* jobs_wait = nullptr;
  CLI::App* jobs_list = nullptr;
  CLI::App* jobs_cancel = nullptr;
  CLI::App* jobs_result = nullptr;
  CLI::App* jobs_delete = nullptr;
  std::string job_id;
  std::filesystem::path spec_file;
  std::vector<std::string> file_fields;  // "field=path"
  std::string idempotency_key;
  JobQuery query;
  double wait_timeout_s = 0.0;
  std::filesystem::path result_output, result_diagnostics, result_components;

  CLI::App* bench = nullptr;
  BenchArgs bench_args;

  int runRigs() const;
  int runJobs() const;
};

RemoteCommands::RemoteCommands(CLI::App& app, CLI::App& transfer, CLI::App& fit) : state_(std::make_unique<State>()) {
  State& s = *state_;
  s.transfer = &transfer;
  s.fit = &fit;
  addConnectionOptions(&transfer, s.connections[&transfer], false);
  addConnectionOptions(&fit, s.connections[&fit], false);

  auto* rigs = app.add_subcommand("rigs", "Rigs on the service: upload, list, get, delete");
  rigs->require_subcommand(1);
  s.rigs_upload = rigs->add_subcommand("upload", "Upload a rig (skipped when the service already has its content id)");
  s.rigs_upload->add_option("--rig", s.rig_files.rig, "Rig GLB")->required()->check(CLI::ExistingFile);
  s.rigs_upload->add_option("--landmarks", s.rig_files.landmarks, "Rig landmarks JSON")->required()->check(CLI::ExistingFile);
  s.rigs_upload->add_option("--components", s.rig_files.components, "Components JSON")->check(CLI::ExistingFile);
  s.rigs_list = rigs->add_subcommand("list", "List this tenant's rigs");
  s.rigs_get = rigs->add_subcommand("get", "Show one rig");
  s.rigs_get->add_option("id", s.rig_id, "Rig id")->required();
  s.rigs_delete = rigs->add_subcommand("delete", "Delete one rig");
  s.rigs_delete->add_option("id", s.rig_id, "Rig id")->required();
  for (auto* cmd : {s.rigs_upload, s.rigs_list, s.rigs_get, s.rigs_delete}) {
    addConnectionOptions(cmd, s.connections[cmd], true);
  }

  auto* jobs = app.add_subcommand("jobs", "Jobs on the service: submit, get, wait, list, cancel, result, delete");
  jobs->require_subcommand(1);
  s.jobs_submit = jobs->add_subcommand("submit", "Submit a job: a spec JSON plus named files (any kind)");
  s.jobs_submit->add_option("--spec", s.spec_file, "Job spec JSON {\"kind\":...,\"rig\":...,\"options\":{...}}")
      ->required()->check(CLI::ExistingFile);
  s.jobs_submit->add_option("--file", s.file_fields, "A multipart file: field=path (repeat), e.g. target=head.glb");
  s.jobs_submit->add_option("--idempotency-key", s.idempotency_key, "Same key = the same job, not a new one");
  s.jobs_get = jobs->add_subcommand("get", "Show one job");
  s.jobs_get->add_option("id", s.job_id, "Job id")->required();
  s.jobs_wait = jobs->add_subcommand("wait", "Wait until a job is final (exit 1 unless it succeeded)");
  s.jobs_wait->add_option("id", s.job_id, "Job id")->required();
  s.jobs_wait->add_option("--timeout", s.wait_timeout_s, "Give up after this many seconds (0 = never)")
      ->check(CLI::NonNegativeNumber);
  s.jobs_list = jobs->add_subcommand("list", "List this tenant's jobs (one page)");
  s.jobs_list->add_option("--status", s.query.status, "Only this status")
      ->check(CLI::IsMember({"queued", "running", "succeeded", "failed", "cancelled"}));
  s.jobs_list->add_option("--limit", s.query.limit, "Page size")->check(CLI::Range(1, 1000));
  s.jobs_list->add_option("--after", s.query.after, "Cursor: the `next` of the previous page");
  s.jobs_cancel = jobs->add_subcommand("cancel", "Cancel a queued or running job");
  s.jobs_cancel->add_option("id", s.job_id, "Job id")->required();
  s.jobs_result = jobs->add_subcommand("result", "Download a succeeded job's GLB (and diagnostics)");
  s.jobs_result->add_option("id", s.job_id, "Job id")->required();
  s.jobs_result->add_option("-o,--output", s.result_output, "GLB to write")->required()->check(kGlbPath);
  s.jobs_result->add_option("--diagnostics", s.result_diagnostics, "Diagnostics JSON to write");
  s.jobs_result->add_option("--components", s.result_components,
                            "The result's components JSON to write (a job whose rig has a components document)");
  s.jobs_delete = jobs->add_subcommand("delete", "Delete a finished job: its result, diagnostics and the inputs only it used");
  s.jobs_delete->add_option("id", s.job_id, "Job id")->required();
  for (auto* cmd : {s.jobs_submit, s.jobs_get, s.jobs_wait, s.jobs_list, s.jobs_cancel, s.jobs_result, s.jobs_delete}) {
    addConnectionOptions(cmd, s.connections[cmd], true);
  }

  BenchArgs& b = s.bench_args;
  s.bench = app.add_subcommand("bench", "Load the service: C client threads run N transfer jobs; JSON summary last on stdout");
  addConnectionOptions(s.bench, s.connections[s.bench], true);
  s.bench->add_option("--concurrency", b.concurrency, "Client threads; the jobs are split evenly among them, the threads round-robin over the --server URLs")->check(CLI::Range(1, 1024))->capture_default_str();
  s.bench->add_option("--jobs", b.jobs, "Jobs in total")->check(CLI::Range(1, 1'000'000))->capture_default_str();
  s.bench->add_option("--source", b.source, "Source rig (GLB)")->required()->check(CLI::ExistingFile);
  s.bench->add_option("--source-landmarks", b.source_landmarks, "Source landmarks JSON")->required()->check(CLI::ExistingFile);
  s.bench->add_option("--target", b.target, "Target mesh (GLB/OBJ/PLY)")->required()->check(CLI::ExistingFile);
  s.bench->add_option("--target-landmarks", b.target_landmarks, "Target landmarks JSON")->required()->check(CLI::ExistingFile);
  s.bench->add_option("--options", b.options, "Transfer options JSON (spec.options)")->check(CLI::ExistingFile);
  s.bench->add_option("--timeout", b.timeout_s, "Stop after this many seconds")->check(CLI::PositiveNumber)->capture_default_str();
  s.bench->add_option("--poll-ms", b.poll_ms, "Job status poll interval, ms")->check(CLI::Range(1, 10'000))->capture_default_str();
}

RemoteCommands::~RemoteCommands() = default;

std::optional<int> RemoteCommands::run(const TransferArgs& transfer, const FitArgs& fit) const {
  State& s = *state_;
  for (const auto& [cmd, connection] : s.connections) {
    if (*cmd) s.connection = connection;
  }
  if (*s.transfer) {
    if (s.connection.server.empty()) return std::nullopt;  // in-process transfer
    return runRemoteTransfer(transfer, s.connection);
  }
  if (*s.fit) {
    if (s.connection.server.empty()) return std::nullopt;  // in-process fit
    return runRemoteFit(fit, s.connection);
  }
  if (*s.rigs_upload || *s.rigs_list || *s.rigs_get || *s.rigs_delete) return s.runRigs();
  if (*s.jobs_submit || *s.jobs_get || *s.jobs_wait || *s.jobs_list || *s.jobs_cancel || *s.jobs_result || *s.jobs_delete) {
    return s.runJobs();
  }
  if (*s.bench) {
    BenchArgs args = s.bench_args;
    args.server = s.connection.server;
    args.api_key = s.connection.api_key;
    args.ca_certificate = s.connection.ca_certificate;
    return runBench(args);
  }
  return std::nullopt;
}

int RemoteCommands::State::runRigs() const {
  RemoteClient client(remoteOptions(connection));
  if (*rigs_upload) {
    auto rig = client.uploadRig(rig_files);
    if (!rig) return fail(rig.error());
    spdlog::info("rig {} {}", rig->rig.id, rig->uploaded ? "uploaded" : "already on the service (upload skipped)");
    printJson(api::toJson(rig->rig));
    return 0;
  }
  if (*rigs_list) {
    auto page = client.listRigs();
    if (!page) return fail(page.error());
    printJson(api::toJson(*page));
    return 0;
  }
  if (*rigs_get) {
    auto rig = client.getRig(rig_id);
    if (!rig) return fail(rig.error());
    printJson(api::toJson(*rig));
    return 0;
  }
  auto deleted = client.deleteRig(rig_id);
  if (!deleted) return fail(deleted.error());
  printJson({{"id", rig_id}, {"deleted", true}});
  return 0;
}

int RemoteCommands::State::runJobs() const {
  RemoteClient client(remoteOptions(connection));
  if (*jobs_submit) {
    auto spec = readJsonObject(spec_file);
    if (!spec) return failText(spec.error());
    std::map<std::string, std::filesystem::path> files;
    for (const std::string& field : file_fields) {
      const auto eq = field.find('=');
      if (eq == std::string::npos || eq == 0 || eq + 1 == field.size()) {
        return failText("--file " + field + ": expected field=path");
      }
      const std::filesystem::path path = field.substr(eq + 1);
      if (!std::filesystem::is_regular_file(path)) return failText("--file " + field + ": no such file");
      if (!files.emplace(field.substr(0, eq), path).second) return failText("--file " + field + ": field given twice");
    }
    auto submitted = client.submitJob(*spec, files, idempotency_key);
    if (!submitted) return fail(submitted.error());
    if (!submitted->created) spdlog::info("job {}: existing job for this Idempotency-Key", submitted->job.id);
    printJson(api::toJson(submitted->job));
    return 0;
  }
  if (*jobs_get) {
    auto job = client.getJob(job_id);
    if (!job) return fail(job.error());
    printJson(api::toJson(*job));
    return 0;
  }
  if (*jobs_wait) {
    auto job = waitWithProgress(client, job_id, wait_timeout_s);
    if (!job) return fail(job.error());
    printJson(api::toJson(*job));
    return job->status == api::JobStatus::kSucceeded ? 0 : failJob(*job);
  }
  if (*jobs_list) {
    auto page = client.listJobs(query);
    if (!page) return fail(page.error());
    printJson(api::toJson(*page));
    return 0;
  }
  if (*jobs_cancel) {
    auto job = client.cancelJob(job_id);
    if (!job) return fail(job.error());
    printJson(api::toJson(*job));
    return 0;
  }
  if (*jobs_delete) {
    auto deleted = client.deleteJob(job_id);
    if (!deleted) return fail(deleted.error());
    printJson({{"id", job_id}, {"deleted", true}});
    return 0;
  }
  auto bytes = client.downloadResult(job_id, result_output);
  if (!bytes) return fail(bytes.error());
  json out = {{"id", job_id}, {"result", result_output.string()}, {"bytes", *bytes}};
  if (!result_diagnostics.empty()) {
    auto diagnostics = client.downloadDiagnostics(job_id, result_diagnostics);
    if (!diagnostics) return fail(diagnostics.error());
    out["diagnostics"] = result_diagnostics.string();
  }
  if (!result_components.empty()) {
    auto components = client.downloadComponents(job_id, result_components);
    if (!components) return fail(components.error());
    out["components"] = result_components.string();
  }
  printJson(out);
  return 0;
}

}  // namespace client
