// Timers of the evaluation and of the benchmarks (`lboost-bench`): wall milliseconds since a
// steady-clock point, and the calling thread's CPU milliseconds (the cross-check on a busy machine,
// where wall time includes waiting for a core).
#pragma once

#include <chrono>
#include <ctime>

namespace lmb {

using Clock = std::chrono::steady_clock;

inline double ms_since(Clock::time_point t) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t).count();
}

inline double thread_cpu_ms() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return 1e3 * static_cast<double>(ts.tv_sec) + 1e-6 * static_cast<double>(ts.tv_nsec);
}

}  // namespace lmb
