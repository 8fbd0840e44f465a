#pragma once
/// \file realtime.hpp
/// Real-time set-up of the calling thread: SCHED_FIFO, locked and pre-faulted memory, CPU pin.

#include <string>

namespace stroma {

/// --realtime: auto (try, warn once and go on if denied), fifo (required), off.
enum class RealtimeMode { Auto, Fifo, Off };

/// What was obtained.
struct RealtimeResult {
  bool fifo = false;
  bool memory_locked = false;
  bool pinned = false;
  int cpu = -1;  ///< the CPU pinned to (−1: none)
  std::string problems;  ///< empty when everything asked for was granted
};

/// Applies `mode` to the calling thread (priority `priority` for SCHED_FIFO) and pins it to
/// `cpu` if cpu ≥ 0. Unless `lock_memory` is false, locks all current and future memory of the
/// process and pre-faults `stack_bytes` of stack so the first ticks do not page-fault (a client
/// leaves memory unlocked: faulting in its whole address space at real-time priority stalls
/// whatever shares its core). Never throws; the caller decides what a problem means.
RealtimeResult setup_realtime_thread(RealtimeMode mode, int cpu, int priority = 80,
                                     size_t stack_bytes = 512 * 1024, bool lock_memory = true);

/// For a worker thread created by a real-time thread: SCHED_FIFO at `priority` if its creator
/// ran under SCHED_FIFO (it inherited the class), normal priority otherwise; and, if
/// avoid_cpu ≥ 0, every CPU but that one. Never throws.
void setup_worker_thread(int priority, int avoid_cpu);

/// True if this process may run threads under SCHED_FIFO at `priority` (tried on a short-lived
/// thread; nothing else changes). Used before asking a library, such as the DDS receive threads'
/// configuration, for a real-time class it would otherwise fail to start without.
bool fifo_permitted(int priority);

}  // namespace stroma
