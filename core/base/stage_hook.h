// StageHook: how a caller follows and stops long work. Called at each stage
// boundary with the stage about to run and the fraction done (0-1); returning
// false stops the work there with ErrorCode::kCancelled (cancellation, time
// limits). Empty = run to the end.
#pragma once

#include <functional>
#include <string_view>

namespace core {

using StageHook = std::function<bool(std::string_view stage, double fraction)>;

}  // namespace core
