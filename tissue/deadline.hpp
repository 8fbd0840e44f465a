#pragma once
/// \file deadline.hpp
/// A tick's deadline as the engine's own work sees it: checked at fixed points (each CG
/// iteration, each Newton iteration, before each contact-release pass and sub-step). Live, it
/// expires once the steady clock passes `at_ns`, and records at which check it first did. In a
/// replay it expires at the recorded check instead, so a replayed tick makes exactly the cuts
/// the live tick made — a budgeted session still replays bit for bit.

#include <cstdint>

#include "tissue/clock.hpp"

namespace stroma {

/// Invariant: once past() has returned true it returns true for the rest of the tick.
struct Deadline {
  int64_t at_ns = 0;             ///< steady_now_ns() time it expires at (0: no clock deadline)
  int64_t expire_at_check = -1;  ///< ≥ 0: replay — expired from this check on, whatever the clock
  int64_t checks = 0;            ///< checks made so far
  int64_t expired_at = -1;       ///< the first check that found it expired (−1: not yet)

  bool active() const { return at_ns > 0 || expire_at_check >= 0; }
  /// One check point: true if the deadline has passed (counting this check).
  bool past() { return past_in(0); }
  /// One check point before work expected to take `ahead_ns`: true if the deadline will have
  /// passed by its end (live), or at the recorded check (replay) — counted like past(), so a
  /// replay expires at the same check whatever each check looked ahead by.
  bool past_in(int64_t ahead_ns) {
    if (!active()) return false;
    const int64_t k = checks++;
    if (expired_at >= 0) return true;
    const bool expired = expire_at_check >= 0 ? k >= expire_at_check : steady_now_ns() + ahead_ns > at_ns;
    if (expired) expired_at = k;
    return expired;
  }
};

}  // namespace stroma
