#include "server/metrics.h"

#include <cctype>
#include <sstream>

namespace server {

void Metrics::countRequest(const std::string& method, const std::string& route, int status) {
  std::lock_guard lock(mutex_);
  ++requests_[{method, {route, status}}];
}

void Metrics::observeStage(const std::string& stage, double seconds) {
  std::lock_guard lock(mutex_);
  Histogram& h = stages_[stage];
  for (std::size_t i = 0; i < kBuckets.size(); ++i) {
    if (seconds <= kBuckets[i]) {
      ++h.buckets[i];
      break;
    }
  }
  ++h.count;
  h.sum += seconds;
}

void Metrics::countJobOutcome(const std::string& status) {
  std::lock_guard lock(mutex_);
  ++outcomes_[status];
}

void Metrics::countJobDeleted(const std::string& reason) {
  std::lock_guard lock(mutex_);
  ++deleted_[reason];
}

void Metrics::countLeaseEvent(LeaseEvent event) {
  std::lock_guard lock(mutex_);
  switch (event) {
    case LeaseEvent::kRescued: ++rescued_; break;
    case LeaseEvent::kExpired: ++lease_expiries_; break;
    case LeaseEvent::kFencingRejected: ++fencing_rejections_; break;
  }
}

std::string Metrics::render(const GaugeSnapshot& g) const {
  std::ostringstream out;
  out.precision(10);
  out << "# HELP rigport_jobs Jobs in the store by state.\n# TYPE rigport_jobs gauge\n";
  for (const auto& [state, n] : g.jobs_by_state) out << "rigport_jobs{state=\"" << state << "\"} " << n << "\n";
  out << "# HELP rigport_queue_depth Jobs waiting for a worker.\n# TYPE rigport_queue_depth gauge\n"
      << "rigport_queue_depth " << g.queue_depth << "\n"
      << "# HELP rigport_running_jobs Jobs on a worker now.\n# TYPE rigport_running_jobs gauge\n"
      << "rigport_running_jobs " << g.running_jobs << "\n"
      << "# HELP rigport_storage_ok 1 while the data directory takes writes, 0 after a fault until a probe passes.\n"
      << "# TYPE rigport_storage_ok gauge\nrigport_storage_ok " << (g.storage_ok ? 1 : 0) << "\n"
      << "# HELP rigport_storage_faults_total Failed store or blob reads and writes since start.\n"
      << "# TYPE rigport_storage_faults_total counter\nrigport_storage_faults_total " << g.storage_faults << "\n";
  // One family per statistic, one series per cache ("rig", "fit", "distances").
  const std::pair<const char*, std::int64_t CacheStats::*> families[] = {
      {"bytes", &CacheStats::bytes},   {"capacity_bytes", &CacheStats::capacity_bytes},
      {"entries", &CacheStats::entries}, {"hits_total", &CacheStats::hits},
      {"misses_total", &CacheStats::misses}, {"evictions_total", &CacheStats::evictions}};
  for (const auto& [name, field] : families) {
    const std::string family = std::string("rigport_cache_") + name;
    const bool counter = family.size() > 6 && family.compare(family.size() - 6, 6, "_total") == 0;
    out << "# HELP " << family << " Prepared-product cache (rig: prepared rigs; fit: fit references; distances: marker distance fields).\n"
        << "# TYPE " << family << (counter ? " counter\n" : " gauge\n");
    for (const auto& [cache, stats] : g.caches) out << family << "{cache=\"" << cache << "\"} " << stats.*field << "\n";
  }
  std::lock_guard lock(mutex_);
  out << "# HELP rigport_job_outcomes_total Jobs finished since start, by final state.\n# TYPE rigport_job_outcomes_total counter\n";
  for (const auto& [status, n] : outcomes_) out << "rigport_job_outcomes_total{status=\"" << status << "\"} " << n << "\n";
  out << "# HELP rigport_jobs_deleted_total Jobs deleted since start (with the blobs only they used), by reason.\n"
         "# TYPE rigport_jobs_deleted_total counter\n";
  for (const auto& [reason, n] : deleted_) out << "rigport_jobs_deleted_total{reason=\"" << reason << "\"} " << n << "\n";
  out << "# HELP rigport_jobs_rescued_total Jobs this replica claimed that an earlier attempt left unfinished.\n"
         "# TYPE rigport_jobs_rescued_total counter\nrigport_jobs_rescued_total " << rescued_ << "\n"
      << "# HELP rigport_lease_expiries_total Expired leases this replica found and put back in the queue.\n"
         "# TYPE rigport_lease_expiries_total counter\nrigport_lease_expiries_total " << lease_expiries_ << "\n"
      << "# HELP rigport_fencing_rejections_total Heartbeats and result writes of this replica refused because its "
         "lease had moved on.\n# TYPE rigport_fencing_rejections_total counter\nrigport_fencing_rejections_total "
      << fencing_rejections_ << "\n";
  out << "# HELP rigport_http_requests_total HTTP requests by method, route and status.\n# TYPE rigport_http_requests_total counter\n";
  for (const auto& [key, n] : requests_) {
    out << "rigport_http_requests_total{method=\"" << key.first << "\",route=\"" << key.second.first << "\",status=\""
        << key.second.second << "\"} " << n << "\n";
  }
  out << "# HELP rigport_stage_seconds Job stage latency.\n# TYPE rigport_stage_seconds histogram\n";
  for (const auto& [stage, h] : stages_) {
    std::uint64_t cumulative = 0;
    for (std::size_t i = 0; i < kBuckets.size(); ++i) {
      cumulative += h.buckets[i];
      out << "rigport_stage_seconds_bucket{stage=\"" << stage << "\",le=\"" << kBuckets[i] << "\"} " << cumulative << "\n";
    }
    out << "rigport_stage_seconds_bucket{stage=\"" << stage << "\",le=\"+Inf\"} " << h.count << "\n"
        << "rigport_stage_seconds_sum{stage=\"" << stage << "\"} " << h.sum << "\n"
        << "rigport_stage_seconds_count{stage=\"" << stage << "\"} " << h.count << "\n";
  }
  return out.str();
}

std::string routePattern(const std::string& path) {
  std::string out;
  std::size_t i = 0;
  while (i < path.size()) {
    const std::size_t slash = path.find('/', i + 1);
    const std::size_t end = slash == std::string::npos ? path.size() : slash;
    std::string segment = path.substr(i, end - i);  // starts with '/'
    // An id segment: 16+ hex digits, optionally followed by ":verb".
    const std::size_t colon = segment.find(':');
    const std::string head = segment.substr(1, colon == std::string::npos ? std::string::npos : colon - 1);
    bool hex = head.size() >= 16;
    for (char c : head) hex = hex && std::isxdigit(static_cast<unsigned char>(c));
    if (hex) segment = "/{id}" + (colon == std::string::npos ? std::string() : segment.substr(colon));
    out += segment;
    i = end;
  }
  return out.empty() ? "/" : out;
}

}  // namespace server
