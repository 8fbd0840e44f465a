#include "runtime/realtime.hpp"

#include <pthread.h>
#include <sched.h>
#include <sys/mman.h>

#include <cerrno>
#include <cstring>
#include <thread>

#include <fmt/format.h>

namespace stroma {

namespace {
void prefault_stack(size_t bytes) {
  volatile char* buf = static_cast<volatile char*>(__builtin_alloca(bytes));
  for (size_t i = 0; i < bytes; i += 4096) buf[i] = 0;
}
}  // namespace

RealtimeResult setup_realtime_thread(RealtimeMode mode, int cpu, int priority, size_t stack_bytes, bool lock_memory) {
  RealtimeResult r;
  if (cpu >= 0) {
    cpu_set_t set;
    CPU_ZERO(&set);
    CPU_SET(cpu, &set);
    const int rc = pthread_setaffinity_np(pthread_self(), sizeof(set), &set);
    r.pinned = rc == 0;
    if (r.pinned) r.cpu = cpu;
    if (rc != 0) r.problems += fmt::format("cannot pin to CPU {} ({}); ", cpu, std::strerror(rc));
  }
  if (mode == RealtimeMode::Off) return r;
  sched_param sp{};
  sp.sched_priority = priority;
  const int rc = pthread_setschedparam(pthread_self(), SCHED_FIFO, &sp);
  r.fifo = rc == 0;
  if (rc != 0) r.problems += fmt::format("SCHED_FIFO denied ({}); ", std::strerror(rc));
  if (!lock_memory) return r;
  if (mlockall(MCL_CURRENT | MCL_FUTURE) == 0) {
    r.memory_locked = true;
  } else {
    r.problems += fmt::format("mlockall denied ({}); ", std::strerror(errno));
  }
  prefault_stack(stack_bytes);
  return r;
}

void setup_worker_thread(int priority, int avoid_cpu) {
  int policy = SCHED_OTHER;
  sched_param sp{};
  pthread_getschedparam(pthread_self(), &policy, &sp);
  const bool fifo = policy == SCHED_FIFO;
  sp.sched_priority = fifo ? priority : 0;
  pthread_setschedparam(pthread_self(), fifo ? SCHED_FIFO : SCHED_OTHER, &sp);
  if (avoid_cpu < 0) return;
  cpu_set_t set;
  CPU_ZERO(&set);
  const int n = static_cast<int>(std::thread::hardware_concurrency());
  for (int c = 0; c < n; ++c)
    if (c != avoid_cpu) CPU_SET(c, &set);
  if (CPU_COUNT(&set) > 0) pthread_setaffinity_np(pthread_self(), sizeof(set), &set);
}

bool fifo_permitted(int priority) {
  bool ok = false;
  std::thread probe([&] {
    sched_param sp{};
    sp.sched_priority = priority;
    ok = pthread_setschedparam(pthread_self(), SCHED_FIFO, &sp) == 0;
  });
  probe.join();
  return ok;
}

}  // namespace stroma
