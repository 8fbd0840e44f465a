#pragma once
/// \file spsc_queue.hpp
/// Bounded lock-free single-producer / single-consumer queue for events that must not be lost
/// (control commands: a "step 10" must arrive even if a "pause" follows). Fixed capacity,
/// allocation-free; push fails (returns false) when full rather than blocking.

#include <array>
#include <atomic>
#include <cstddef>

namespace stroma {

template <class T, size_t N>
class SpscQueue {
  static_assert((N & (N - 1)) == 0, "capacity must be a power of two");

 public:
  /// Producer: false if the queue is full (the event is dropped and the caller counts it).
  bool push(const T& v) {
    const size_t h = head_.load(std::memory_order_relaxed);
    if (h - tail_.load(std::memory_order_acquire) == N) return false;
    buf_[h & (N - 1)] = v;
    head_.store(h + 1, std::memory_order_release);
    return true;
  }
  /// Consumer: false if empty.
  bool pop(T& out) {
    const size_t t = tail_.load(std::memory_order_relaxed);
    if (t == head_.load(std::memory_order_acquire)) return false;
    out = buf_[t & (N - 1)];
    tail_.store(t + 1, std::memory_order_release);
    return true;
  }

 private:
  std::array<T, N> buf_{};
  alignas(64) std::atomic<size_t> head_{0};
  alignas(64) std::atomic<size_t> tail_{0};
};

}  // namespace stroma
