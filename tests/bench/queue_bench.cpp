// The job queue's cost in the store (server/jobs.h, MetadataStore): claiming
// and completing one empty job, on the embedded SQLite store and on
// PostgreSQL; and 64 workers (one connection each, as 64 one-worker replicas)
// claiming 10,000 empty jobs, with the claims counted per job (a double claim
// is a bug, reported as a counter). PostgreSQL: RIGPORT_TEST_POSTGRES_URL
// (scripts/postgres.sh start DIR prints one); without it those runs are
// skipped with that message. Each run gets a fresh schema or file.
#include <benchmark/benchmark.h>
#include <libpq-fe.h>

#include <atomic>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "server/store.h"
#include "tests/test_support.h"

namespace {

std::string postgresUrl() {
  const char* url = std::getenv("RIGPORT_TEST_POSTGRES_URL");
  return url ? url : "";
}

// A new store location: a schema of its own on PostgreSQL, a new file otherwise.
std::string freshLocation(bool postgres) {
  static std::atomic<int> counter{0};
  const std::string tag = std::to_string(::getpid()) + "_" + std::to_string(counter++);
  if (!postgres) return (rigport_test::makeTempDir("queue_bench") / ("meta" + tag + ".db")).string();
  const std::string schema = "queue_bench_" + tag;
  PGconn* conn = PQconnectdb(postgresUrl().c_str());
  PQclear(PQexec(conn, ("CREATE SCHEMA " + schema).c_str()));
  PQfinish(conn);
  const std::string base = postgresUrl();
  return base + (base.find('?') == std::string::npos ? "?" : "&") + "options=-csearch_path%3D" + schema;
}

server::JobRecord emptyJob(int i) {
  server::JobRecord job;
  job.tenant = "bench";
  job.id = "job-" + std::to_string(i);
  job.rig = "rig";
  job.spec_json = "{}";
  return job;
}

bool skipWithoutPostgres(benchmark::State& state, bool postgres) {
  if (postgres && postgresUrl().empty()) {
    state.SkipWithError("RIGPORT_TEST_POSTGRES_URL is not set (bash scripts/postgres.sh start DIR prints one)");
    return true;
  }
  return false;
}

// One job claimed and completed (inserted outside the timing).
void BM_ClaimAndCompleteEmptyJob(benchmark::State& state) {
  const bool postgres = state.range(0) == 1;
  if (skipWithoutPostgres(state, postgres)) return;
  auto store = server::MetadataStore::open(freshLocation(postgres));
  if (!store) return state.SkipWithError(store.error().message.c_str());
  int i = 0;
  for (auto _ : state) {
    state.PauseTiming();
    if (!(*store)->insertJob(emptyJob(i++))) return state.SkipWithError("insert failed");
    state.ResumeTiming();
    auto claimed = (*store)->claimNextJob("bench", 30'000);
    if (!claimed || !*claimed) return state.SkipWithError("claim failed");
    server::JobRecord done = **claimed;
    done.status = api::JobStatus::kSucceeded;
    done.stage = "done";
    if (!(*store)->markFinished(done, done.attempts)) return state.SkipWithError("complete failed");
  }
  state.SetLabel(postgres ? "postgresql" : "sqlite");
}
BENCHMARK(BM_ClaimAndCompleteEmptyJob)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

// 64 workers drain 10,000 queued jobs; every job must be claimed exactly once.
void BM_WorkersClaimTenThousandJobs(benchmark::State& state) {
  const bool postgres = state.range(0) == 1;
  if (skipWithoutPostgres(state, postgres)) return;
  constexpr int kWorkers = 64, kJobs = 10'000;
  for (auto _ : state) {
    state.PauseTiming();
    const std::string location = freshLocation(postgres);
    std::vector<std::unique_ptr<server::MetadataStore>> stores;
    for (int w = 0; w < kWorkers; ++w) {
      auto store = server::MetadataStore::open(location);
      if (!store) return state.SkipWithError(store.error().message.c_str());
      stores.push_back(std::move(*store));
    }
    for (int i = 0; i < kJobs; ++i) {
      if (!stores[0]->insertJob(emptyJob(i))) return state.SkipWithError("insert failed");
    }
    std::mutex mutex;
    std::map<std::string, int> claims;
    std::atomic<int> errors{0};
    state.ResumeTiming();
    std::vector<std::thread> workers;
    for (int w = 0; w < kWorkers; ++w) {
      workers.emplace_back([&, w] {
        std::vector<std::string> mine;
        for (;;) {
          auto claimed = stores[w]->claimNextJob("worker-" + std::to_string(w), 30'000);
          if (!claimed) {
            ++errors;  // SQLite: a writer busy past its timeout
            continue;
          }
          if (!*claimed) break;
          mine.push_back((*claimed)->id);
        }
        std::lock_guard lock(mutex);
        for (const auto& id : mine) ++claims[id];
      });
    }
    for (auto& t : workers) t.join();
    state.PauseTiming();
    int doubles = 0;
    for (const auto& [id, n] : claims) doubles += n > 1 ? n - 1 : 0;
    state.counters["claimed_jobs"] = static_cast<double>(claims.size());
    state.counters["double_claims"] = doubles;
    state.counters["claim_errors"] = errors.load();
    state.counters["claims_per_s"] = benchmark::Counter(kJobs, benchmark::Counter::kIsRate);
    stores.clear();
    state.ResumeTiming();
  }
  state.SetLabel(postgres ? "postgresql" : "sqlite");
}
BENCHMARK(BM_WorkersClaimTenThousandJobs)->Arg(0)->Arg(1)->Iterations(1)->UseRealTime()->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
