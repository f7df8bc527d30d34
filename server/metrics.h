// Prometheus text exposition (format 0.0.4) of the service's counters and
// histograms. Counters are recorded as events happen; gauges (jobs by state,
// queue depth, cache) are read when /metrics is scraped. Thread-safe.
#pragma once

#include <array>
#include <cstdint>
#include <map>
#include <mutex>
#include <string>
#include <utility>

namespace server {

struct CacheStats {
  std::int64_t bytes = 0, capacity_bytes = 0, entries = 0;
  std::int64_t hits = 0, misses = 0, evictions = 0;
};

struct GaugeSnapshot {
  std::map<std::string, std::int64_t> jobs_by_state;  // state name -> count (store)
  std::int64_t queue_depth = 0;
  std::int64_t running_jobs = 0;
  std::map<std::string, CacheStats> caches;           // "rig", "fit", "distances"
  bool storage_ok = true;                              // StorageHealth
  std::int64_t storage_faults = 0;
};

class Metrics {
 public:
  // `route` is the route pattern ("/v1/jobs/{id}"), never a raw path, so the
  // label set stays bounded.
  void countRequest(const std::string& method, const std::string& route, int status);
  void observeStage(const std::string& stage, double seconds);
  void countJobOutcome(const std::string& status);
  void countJobDeleted(const std::string& reason);    // "request" or "retention"
  // The job queue's lease events (server/jobs.h), as seen by this replica.
  enum class LeaseEvent {
    kRescued,          // claimed a job an earlier attempt left unfinished
    kExpired,          // found a lease ended and put its job back in the queue
    kFencingRejected,  // a heartbeat or result write refused: the lease had moved on
  };
  void countLeaseEvent(LeaseEvent event);
  std::string render(const GaugeSnapshot& gauges) const;

 private:
  static constexpr std::array<double, 12> kBuckets = {0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1, 2.5, 5, 10, 30};
  struct Histogram {
    std::array<std::uint64_t, kBuckets.size()> buckets{};  // cumulative at render time
    std::uint64_t count = 0;
    double sum = 0.0;
  };
  mutable std::mutex mutex_;
  std::map<std::pair<std::string, std::pair<std::string, int>>, std::uint64_t> requests_;  // (method, (route, status))
  std::map<std::string, Histogram> stages_;
  std::map<std::string, std::uint64_t> outcomes_;
  std::map<std::string, std::uint64_t> deleted_;
  std::uint64_t rescued_ = 0, lease_expiries_ = 0, fencing_rejections_ = 0;
};

// The route pattern of a request path: hex ids become {id} ("/v1/jobs/{id}/result").
std::string routePattern(const std::string& path);

}  // namespace server
