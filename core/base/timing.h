// Stage timings for reports and diagnostics: milliseconds on the monotonic clock.
#pragma once

#include <chrono>

namespace core {

using Clock = std::chrono::steady_clock;

inline double msSince(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

}  // namespace core
