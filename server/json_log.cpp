#include "server/json_log.h"

#include <spdlog/sinks/stdout_sinks.h>

#include "server/timestamps.h"

namespace server {

void JsonLog::write(spdlog::level::level_enum level, std::string_view event, nlohmann::json fields) const {
  if (!logger_ || !logger_->should_log(level)) return;
  const auto level_name = spdlog::level::to_string_view(level);
  nlohmann::json line = {{"ts", formatTimestamp(nowMs())}, {"level", std::string(level_name.data(), level_name.size())}, {"event", event}};
  for (auto& [key, value] : fields.items()) line[key] = std::move(value);
  // Replacement of invalid UTF-8 (file names from clients) keeps every line valid JSON.
  logger_->log(level, "{}", line.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace));
}

std::shared_ptr<spdlog::logger> makeJsonStderrLogger(const std::string& name) {
  auto logger = std::make_shared<spdlog::logger>(name, std::make_shared<spdlog::sinks::stderr_sink_mt>());
  logger->set_pattern("%v");
  logger->flush_on(spdlog::level::info);
  return logger;
}

}  // namespace server
