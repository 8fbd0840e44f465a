#pragma once
/// \file clock.hpp
/// The one clock the engine times and budgets with: CLOCK_MONOTONIC in nanoseconds, the clock
/// the real-time loop also sleeps on (clock_nanosleep), so stage times, tick deadlines and the
/// loop's schedule are all comparable. A vDSO call (~20 ns), safe in the 1 kHz tick.

#include <time.h>

#include <cstdint>

namespace stroma {

inline int64_t steady_now_ns() {
  timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<int64_t>(ts.tv_sec) * 1000000000LL + ts.tv_nsec;
}

}  // namespace stroma
