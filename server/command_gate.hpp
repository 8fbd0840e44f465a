#pragma once
/// \file command_gate.hpp
/// The one way a tool command reaches physics in `serve`, whichever topic it came on (Stroma's
/// ToolCommand, or CRTK's servo_cp with --crtk): checked against the tool's limits (finite,
/// unit quaternion, workspace, speed over the client's own clock; haptics/tool.hpp) and, if it
/// passes, written to the tool's latest-command slot of the physics loop. Used by the input
/// thread only (not thread-safe); the counters are atomics read by the publishers.

#include <atomic>
#include <chrono>
#include <cstdint>
#include <vector>

#include "engine/physics_loop.hpp"
#include "haptics/tool.hpp"

namespace stroma {

/// Counters of the input thread, published in SimStatus.
/// Every command received is accepted, clamped (then applied), rejected or superseded:
/// accepted + clamped + rejected + superseded = received.
struct InputCounters {
  std::atomic<uint64_t> accepted{0}, clamped{0}, rejected{0}, controls{0}, controls_dropped{0};
  /// Commands the reader's keep-last history replaced by a newer one of the same tool before
  /// this thread took them: counted from the gaps in each writer's seq (DDS.md: a client's seq
  /// increases by one per command), so never seen, neither accepted nor rejected.
  std::atomic<uint64_t> superseded{0};
};

class CommandGate {
 public:
  CommandGate(PhysicsLoop& loop, InputCounters& counters);

  /// Checks `pose` for tool `tool` (a valid index) and hands it to physics unless rejected;
  /// counts it in accepted, clamped or rejected. `client_time_ns`: the sender's clock (the
  /// speed check's time base; the arrival clock when it does not advance).
  ToolCheck submit(int tool, const ToolPose& pose, uint64_t seq, int64_t client_time_ns);

 private:
  PhysicsLoop& loop_;
  InputCounters& cnt_;
  std::vector<ToolPose> last_;
  std::vector<std::chrono::steady_clock::time_point> last_time_;
  std::vector<int64_t> last_client_ns_;
  std::vector<bool> have_last_;
};

/// CLOCK_MONOTONIC in ns: the physics loop's clock.
int64_t monotonic_ns();

}  // namespace stroma
