// MetadataStore: which implementation a location opens (server/store.h).
#include "server/store_sql.h"

namespace server {

bool isPostgresUrl(const std::string& location) {
  return location.rfind("postgresql://", 0) == 0 || location.rfind("postgres://", 0) == 0;
}

core::Result<std::unique_ptr<MetadataStore>> MetadataStore::open(const std::string& location) {
  if (isPostgresUrl(location)) return openPostgresStore(location);
  return openSqliteStore(location);
}

void MetadataStore::setErrorReporter(std::function<void(const std::string&)> report) {
  std::lock_guard lock(reporter_mutex_);
  report_error_ = std::move(report);
}

}  // namespace server
