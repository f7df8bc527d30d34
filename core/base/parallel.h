// parallelFor: split [0, n) into contiguous chunks run on std::threads.
// Chunks are contiguous and results are written by index, so outputs do not
// depend on the thread count (determinism).
//
// How many threads is one execution setting, not an option of every stage:
// whoever runs a job (the job bodies, core/jobs/job.h JobRun::threads; a CLI
// command; a test) sets it for the calling thread with a ScopedThreadCount,
// and every parallel loop below it reads it; the loops' own threads inherit it.
#pragma once

#include <algorithm>
#include <cstddef>
#include <thread>
#include <vector>

namespace core {

// The calling thread's thread count for parallel loops while it lives (0, the
// default: hardware threads); the previous setting returns when it ends.
class ScopedThreadCount {
 public:
  explicit ScopedThreadCount(int threads) : previous_(setting()) { setting() = threads; }
  ~ScopedThreadCount() { setting() = previous_; }
  ScopedThreadCount(const ScopedThreadCount&) = delete;
  ScopedThreadCount& operator=(const ScopedThreadCount&) = delete;

  static int current() { return setting(); }  // as set (0 = hardware threads)
  static int resolved() {                      // the number of threads it means
    return setting() > 0 ? setting() : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  }

 private:
  static int& setting() {
    thread_local int threads = 0;
    return threads;
  }
  int previous_;
};

// `fn(begin, end)` is called once per chunk, on up to
// ScopedThreadCount::resolved() threads; it must only write to its own index range.
template <typename Fn>
void parallelFor(std::ptrdiff_t n, Fn&& fn, std::ptrdiff_t min_chunk = 256) {
  if (n <= 0) return;
  int t = ScopedThreadCount::resolved();
  t = static_cast<int>(std::min<std::ptrdiff_t>(t, (n + min_chunk - 1) / min_chunk));
  if (t <= 1) {
    fn(std::ptrdiff_t{0}, n);
    return;
  }
  const int setting = ScopedThreadCount::current();
  std::vector<std::thread> pool;
  pool.reserve(t - 1);
  const std::ptrdiff_t chunk = (n + t - 1) / t;
  for (int i = 1; i < t; ++i) {
    const std::ptrdiff_t begin = i * chunk;
    const std::ptrdiff_t end = std::min(n, begin + chunk);
    if (begin >= end) break;
    pool.emplace_back([&fn, begin, end, setting] {
      const ScopedThreadCount inherited(setting);
      fn(begin, end);
    });
  }
  fn(std::ptrdiff_t{0}, std::min(n, chunk));
  for (auto& th : pool) th.join();
}

}  // namespace core
