// parallelFor: split [0, n) into contiguous chunks run on std::threads.
// Chunks are contiguous and results are written by index, so outputs do not
// depend on the thread count (determinism).
#pragma once

#include <algorithm>
#include <cstddef>
#include <thread>
#include <vector>

namespace core {

// threads <= 0 means std::thread::hardware_concurrency(). `fn(begin, end)` is
// called once per chunk; it must only write to its own index range.
template <typename Fn>
void parallelFor(std::ptrdiff_t n, int threads, Fn&& fn, std::ptrdiff_t min_chunk = 256) {
  if (n <= 0) return;
  int t = threads > 0 ? threads : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  t = static_cast<int>(std::min<std::ptrdiff_t>(t, (n + min_chunk - 1) / min_chunk));
  if (t <= 1) {
    fn(std::ptrdiff_t{0}, n);
    return;
  }
  std::vector<std::thread> pool;
  pool.reserve(t - 1);
  const std::ptrdiff_t chunk = (n + t - 1) / t;
  for (int i = 1; i < t; ++i) {
    const std::ptrdiff_t begin = i * chunk;
    const std::ptrdiff_t end = std::min(n, begin + chunk);
    if (begin >= end) break;
    pool.emplace_back([&fn, begin, end] { fn(begin, end); });
  }
  fn(std::ptrdiff_t{0}, std::min(n, chunk));
  for (auto& th : pool) th.join();
}

}  // namespace core
