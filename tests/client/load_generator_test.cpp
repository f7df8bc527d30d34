// Tests of the statistics of `rigport bench` (client/load_generator.cpp):
// percentiles, the summary and its JSON line. The network part needs the
// service and is not tested here.
#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <vector>

#include "client/load_generator.h"

namespace {

TEST(Percentile, InterpolatesLinearlyBetweenClosestRanks) {
  std::vector<double> v;
  for (int i = 1; i <= 100; ++i) v.push_back(i);
  EXPECT_DOUBLE_EQ(client::percentile(v, 0.0), 1.0);
  EXPECT_DOUBLE_EQ(client::percentile(v, 50.0), 50.5);
  EXPECT_DOUBLE_EQ(client::percentile(v, 95.0), 95.05);
  EXPECT_DOUBLE_EQ(client::percentile(v, 99.0), 99.01);
  EXPECT_DOUBLE_EQ(client::percentile(v, 100.0), 100.0);
}

TEST(Percentile, HandlesEmptySingleAndOutOfRangeP) {
  EXPECT_DOUBLE_EQ(client::percentile({}, 50.0), 0.0);
  EXPECT_DOUBLE_EQ(client::percentile({7.0}, 1.0), 7.0);
  EXPECT_DOUBLE_EQ(client::percentile({7.0}, 99.0), 7.0);
  EXPECT_DOUBLE_EQ(client::percentile({1.0, 3.0}, 50.0), 2.0);
  EXPECT_DOUBLE_EQ(client::percentile({1.0, 3.0}, -5.0), 1.0);
  EXPECT_DOUBLE_EQ(client::percentile({1.0, 3.0}, 250.0), 3.0);
}

TEST(SummarizeBench, SortsLatenciesAndComputesThroughputOverTheRun) {
  std::vector<double> latencies;
  for (int i = 1; i <= 100; ++i) latencies.push_back(10.0 * i);
  std::shuffle(latencies.begin(), latencies.end(), std::mt19937(42));
  const client::BenchSummary s = client::summarizeBench(latencies, 4.0, 100, 3, 1, {{"429", 7}, {"500", 1}});
  EXPECT_DOUBLE_EQ(s.jobs_per_s, 25.0);
  EXPECT_EQ(s.latency_count, 100u);
  EXPECT_DOUBLE_EQ(s.p50_ms, 505.0);
  EXPECT_DOUBLE_EQ(s.p95_ms, 950.5);
  EXPECT_DOUBLE_EQ(s.p99_ms, 990.1);
  EXPECT_DOUBLE_EQ(s.mean_ms, 505.0);
  EXPECT_DOUBLE_EQ(s.max_ms, 1000.0);
  EXPECT_EQ(s.succeeded, 100);
  EXPECT_EQ(s.failed, 3);
  EXPECT_EQ(s.unfinished, 1);
  EXPECT_EQ(s.errors_by_status.at("429"), 7);
}

TEST(SummarizeBench, PercentilesAreOrdered) {
  std::mt19937 rng(7);
  std::lognormal_distribution<double> dist(4.0, 0.8);
  std::vector<double> latencies(997);
  for (double& x : latencies) x = dist(rng);
  const client::BenchSummary s = client::summarizeBench(latencies, 10.0, 997, 0, 0, {});
  EXPECT_LE(s.p50_ms, s.p95_ms);
  EXPECT_LE(s.p95_ms, s.p99_ms);
  EXPECT_LE(s.p99_ms, s.max_ms);
  EXPECT_GE(s.p50_ms, *std::min_element(latencies.begin(), latencies.end()));
}

TEST(SummarizeBench, ZeroWallTimeGivesZeroThroughput) {
  EXPECT_DOUBLE_EQ(client::summarizeBench({}, 0.0, 0, 0, 0, {}).jobs_per_s, 0.0);
}

TEST(BenchSummaryJson, HasTheContractKeysWithErrorsAsAnObject) {
  const client::BenchSummary s = client::summarizeBench({100.0, 200.0, 300.0}, 2.0, 3, 1, 0, {{"429", 2}});
  const nlohmann::json j = client::benchSummaryJson(s);
  for (const char* key : {"jobs_per_s", "p50_ms", "p95_ms", "p99_ms", "succeeded", "failed", "errors_by_status"}) {
    EXPECT_TRUE(j.contains(key)) << key;
  }
  EXPECT_DOUBLE_EQ(j["jobs_per_s"].get<double>(), 1.5);
  EXPECT_DOUBLE_EQ(j["p50_ms"].get<double>(), 200.0);
  EXPECT_EQ(j["succeeded"], 3);
  EXPECT_EQ(j["failed"], 1);
  ASSERT_TRUE(j["errors_by_status"].is_object());
  EXPECT_EQ(j["errors_by_status"]["429"], 2);
  // One line: the bench prints it last on stdout.
  EXPECT_EQ(j.dump().find('\n'), std::string::npos);
}

TEST(BenchSummaryJson, LatenciesAreNullWhenNoJobSucceeded) {
  const nlohmann::json j = client::benchSummaryJson(client::summarizeBench({}, 5.0, 0, 4, 0, {{"transport", 4}}));
  EXPECT_TRUE(j["p50_ms"].is_null());
  EXPECT_TRUE(j["p99_ms"].is_null());
  EXPECT_EQ(j["failed"], 4);
  EXPECT_EQ(j["errors_by_status"]["transport"], 4);
  EXPECT_TRUE(j["errors_by_status"].is_object());
}

TEST(BenchServers, SplitsACommaSeparatedListTrimmingBlanks) {
  EXPECT_EQ(client::benchServers("http://a:1"), (std::vector<std::string>{"http://a:1"}));
  EXPECT_EQ(client::benchServers("http://a:1, http://b:2 ,,http://c:3,"),
            (std::vector<std::string>{"http://a:1", "http://b:2", "http://c:3"}));
  EXPECT_TRUE(client::benchServers(" , ").empty());
}

}  // namespace
