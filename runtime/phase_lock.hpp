#pragma once
/// \file phase_lock.hpp
/// Locks the phase of `serve`'s tick schedule to the arrival of tool commands, so that a
/// command from a client on its own 1 kHz clock reaches the tick a short, fixed lead before it
/// starts instead of waiting a random 0–1 period for it.
///
/// Why: a tick reads each tool's newest command at its start (the whole tick depends on the
/// tool's pose, so no later read is safe). A client commanding at the tick rate from its own
/// clock sends at an arbitrary phase of the server's period; without locking, its command waits
/// uniformly 0…1 period for the next tick, which alone puts the command → feedback round trip's
/// p99 near one period plus the tick. A haptic device's loop is clocked by the device: the
/// server follows the command stream's phase, as a phase-locked loop follows a reference.
///
/// How: after each tick that took a command, the error between the command's lead (tick
/// start − arrival) and the target lead, wrapped into half a period each way, moves the next
/// deadline by a proportional-integral correction (0.1 × error + 0.005 × the errors' sum),
/// clamped to ±max_step. The small proportional gain passes only a tenth of the arrivals'
/// jitter into the schedule; the integral removes the constant phase error a client whose clock
/// runs slightly off would otherwise leave. The rate stays the tick rate: each period
/// changes by at most max_step (2 % by default), and a client on the same clock needs one fixed
/// shift. A client whose rate differs by more than max_step per period cannot be followed; its
/// commands then slip through the period as they would without the lock. The lock changes when
/// a tick starts, never what it computes: replays are unaffected.

#include <algorithm>
#include <cstdint>

namespace stroma {

/// Proportional-integral phase controller. Invariants: period_ns > 0; 0 ≤ lead_ns < period_ns;
/// 0 ≤ max_step_ns; every correction and the integral term are within ±max_step_ns.
class PhaseLock {
 public:
  PhaseLock() = default;
  /// lead_ns = 0 disables the lock (every correction is 0).
  PhaseLock(int64_t period_ns, int64_t lead_ns, int64_t max_step_ns, double gain = 0.1, double integral_gain = 0.005)
      : period_(period_ns), lead_(lead_ns), max_step_(max_step_ns), gain_(gain), integral_gain_(integral_gain) {}

  bool enabled() const { return lead_ > 0 && period_ > 0; }

  /// A command that arrived at `arrival_ns` was taken by the tick scheduled at `tick_ns`.
  /// Returns how far to move the next deadline (ns; positive: later).
  int64_t correction(int64_t tick_ns, int64_t arrival_ns) {
    if (!enabled()) return 0;
    // Positive error: the command came later than the target lead before the tick start.
    int64_t error = lead_ - (tick_ns - arrival_ns);
    // A command that arrived just after the previous tick started shows a lead of nearly a
    // period: it was late by a little, not early by a lot.
    error %= period_;
    if (error > period_ / 2) error -= period_;
    if (error < -period_ / 2) error += period_;
    const double limit = static_cast<double>(max_step_);
    integral_ = std::clamp(integral_ + integral_gain_ * static_cast<double>(error), -limit, limit);
    const double step = gain_ * static_cast<double>(error) + integral_;
    return static_cast<int64_t>(std::clamp(step, -limit, limit));
  }

 private:
  int64_t period_ = 0, lead_ = 0, max_step_ = 0;
  double gain_ = 0.1, integral_gain_ = 0.005;
  double integral_ = 0;  ///< ns per period: the client's rate offset, once locked
};

}  // namespace stroma
