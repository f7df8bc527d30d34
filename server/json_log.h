// Structured logs: one JSON object per line ({"ts","level","event", ...fields}
// with job id and tenant where there is one), through an explicit spdlog
// logger passed from main (no process-global logger in the server library).
#pragma once

#include <memory>
#include <string_view>

#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

namespace server {

class JsonLog {
 public:
  // nullptr: a logger that drops everything (tests).
  explicit JsonLog(std::shared_ptr<spdlog::logger> logger) : logger_(std::move(logger)) {}
  void info(std::string_view event, nlohmann::json fields = nlohmann::json::object()) const {
    write(spdlog::level::info, event, std::move(fields));
  }
  void warn(std::string_view event, nlohmann::json fields = nlohmann::json::object()) const {
    write(spdlog::level::warn, event, std::move(fields));
  }
  void error(std::string_view event, nlohmann::json fields = nlohmann::json::object()) const {
    write(spdlog::level::err, event, std::move(fields));
  }

 private:
  void write(spdlog::level::level_enum level, std::string_view event, nlohmann::json fields) const;
  std::shared_ptr<spdlog::logger> logger_;
};

// A logger writing bare lines to stderr with the JSON above.
std::shared_ptr<spdlog::logger> makeJsonStderrLogger(const std::string& name);

}  // namespace server
