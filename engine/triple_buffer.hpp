#pragma once
/// \file triple_buffer.hpp
/// Lock-free single-producer / single-consumer "latest value" hand-off.
///
/// Three slots: the producer owns one (writes into it), the consumer owns one (reads it), and
/// the third is the "middle" exchanged through one atomic word together with a "fresh" bit.
/// Neither side ever waits for the other: the producer publishes by swapping its slot with the
/// middle; the consumer picks up by swapping its slot with the middle if the fresh bit is set.
/// Values the consumer was too slow to read are overwritten (latest wins), which is what state
/// publishing and tool commands want. Slots are pre-allocated; T's copy/assignment happens in
/// the caller's thread into its own slot, so large T (vectors sized once) never allocate.

#include <atomic>
#include <cstdint>

namespace stroma {

template <class T>
class TripleBuffer {
 public:
  TripleBuffer() = default;
  /// Initialises all three slots to `init` (so buffers sized here never reallocate).
  explicit TripleBuffer(const T& init) : slots_{init, init, init} {}

  // ---- producer side ----
  /// The slot the producer may fill. Valid until publish().
  T& write_slot() { return slots_[write_]; }
  /// Makes the write slot the newest value; the producer gets a fresh slot to write.
  void publish() {
    const uint8_t prev = middle_.exchange(static_cast<uint8_t>(write_ | kFresh), std::memory_order_acq_rel);
    write_ = prev & kIndex;
  }

  // ---- consumer side ----
  /// If a newer value was published since the last call, makes it the read slot and returns
  /// true. Never blocks.
  bool update() {
    if (!(middle_.load(std::memory_order_relaxed) & kFresh)) return false;
    const uint8_t prev = middle_.exchange(read_, std::memory_order_acq_rel);
    read_ = prev & kIndex;
    return true;
  }
  /// The consumer's current value (the newest seen by update()).
  const T& read_slot() const { return slots_[read_]; }
  T& read_slot_mutable() { return slots_[read_]; }

 private:
  static constexpr uint8_t kIndex = 0x3;
  static constexpr uint8_t kFresh = 0x4;
  T slots_[3]{};
  uint8_t write_ = 0;                 // producer-owned
  uint8_t read_ = 1;                  // consumer-owned
  alignas(64) std::atomic<uint8_t> middle_{2};
};

}  // namespace stroma
