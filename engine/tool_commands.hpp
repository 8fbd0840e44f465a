#pragma once
/// \file tool_commands.hpp
/// The one way a tool command reaches physics, from every front end: `serve`'s DDS and CRTK
/// readers, the Python module's set_pose, and `stroma run`'s scripted tools. Each command is
/// checked against its tool's limits (haptics/tool.hpp validate_tool_command: finite values, a
/// unit quaternion, the workspace, the speed since the last accepted command), counted, and —
/// unless rejected — made the tool's newest command, which the next tick takes (read_inputs).
///
/// Threads: one producer (the thread that submits) and one consumer (the thread that ticks);
/// they may be the same thread. The hand-off is a lock-free latest-value buffer per tool (a
/// newer command replaces one the tick has not taken yet). The counters are atomics any thread
/// may read.

#include <atomic>
#include <cstdint>
#include <memory>
#include <vector>

#include "engine/triple_buffer.hpp"
#include "haptics/tool.hpp"

namespace stroma {

/// What became of the commands a port received. Invariant: every command a front end received
/// is in exactly one of accepted, clamped (then applied), rejected or superseded:
/// accepted + clamped + rejected + superseded = received.
struct CommandCounters {
  std::atomic<uint64_t> accepted{0}, clamped{0}, rejected{0};
  /// Commands a transport dropped for a newer one of the same tool before the port saw them
  /// (serve: counted from the gaps in each writer's seq; DDS.md). Never validated.
  std::atomic<uint64_t> superseded{0};
  uint64_t received() const { return accepted.load() + clamped.load() + rejected.load() + superseded.load(); }
};

/// Per-tool validation and hand-off of tool commands (see the file comment).
/// Invariants: one validation state and one latest-command buffer per tool of the model it was
/// made for; `last accepted` is the pose the speed check measures from.
class ToolCommandPort {
 public:
  /// For the tools of a model (their limits are copied: cut models keep their scenario's tools).
  /// `tick_period`: the speed check's time base for commands that carry no newer time than the
  /// last accepted one (two commands in the same tick are at least a tick apart).
  ToolCommandPort(const std::vector<ToolSpec>& tools, double tick_period);

  /// Producer: checks `pose` for tool `tool` (a valid index) and, unless rejected, makes it the
  /// tool's newest command. The speed check measures over the sender's clock
  /// (`client_time_ns`); when that does not advance, over the arrival clock (`arrival_ns`, the
  /// loop's CLOCK_MONOTONIC: tissue/clock.hpp); when neither does, over one tick period.
  ToolCheck submit(int tool, const ToolPose& pose, uint64_t seq, int64_t client_time_ns, int64_t arrival_ns);

  /// Producer: a command a transport refused before it could be checked (an unknown tool, a
  /// malformed message), counted as rejected.
  void count_rejected() { counters_.rejected.fetch_add(1, std::memory_order_relaxed); }
  /// Producer: commands a transport dropped for newer ones (CommandCounters::superseded).
  void count_superseded(uint64_t n) { counters_.superseded.fetch_add(n, std::memory_order_relaxed); }

  /// Consumer: the newest command of each tool submitted since the last take, in tool order,
  /// into `out` (room for `max` entries); returns how many. Never blocks or allocates.
  int take(ToolInput* out, int max);

  /// Producer: the speed check measures from the tools as they are in a state (their applied
  /// poses, at their last command's client time) — after a restore or reset by a front end
  /// whose client clock is the simulated time (Python, `stroma run`), so that checking a command
  /// depends on the state it is applied to and nothing else. A tool never commanded in that state
  /// has no speed limit on its next command, as a tool's first one.
  void seed(const std::vector<ToolState>& tools);

  const CommandCounters& counters() const { return counters_; }
  int tool_count() const { return static_cast<int>(tools_.size()); }
  /// The reason of the last rejected or clamped command ("" if none): for messages.
  const char* last_reason() const { return last_reason_.load(std::memory_order_relaxed); }

 private:
  std::vector<ToolSpec> tools_;
  double period_;
  std::vector<ToolPose> last_;
  std::vector<int64_t> last_client_ns_, last_arrival_ns_;
  std::vector<uint8_t> have_last_;
  std::vector<std::unique_ptr<TripleBuffer<ToolInput>>> slots_;
  CommandCounters counters_;
  std::atomic<const char*> last_reason_{""};
};

}  // namespace stroma
