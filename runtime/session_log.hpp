#pragma once
/// \file session_log.hpp
/// Record of a live session: every accepted tool command and control, stamped with the tick
/// (count of ticks executed since the server started) at which it took effect. `stroma serve
/// --record FILE` writes it; `stroma run SCENARIO --replay FILE` re-executes it headless and
/// reaches a final state bit-for-bit identical to the server's. A recorded session is then a
/// regression scenario. Text, one event per line, doubles at 17 significant digits.

#include <cstdint>
#include <string>
#include <vector>

#include "haptics/tool.hpp"

namespace stroma {

/// One recorded event.
struct SessionEvent {
  /// Mark: a checkpoint — `tick` ticks had executed and every event before them is above it in
  /// the log (the server writes one at least every kRecordMarkTicks; a log cut short by a crash
  /// replays to its last mark).
  /// CutSnapshot: after `tick` ticks the state's edge cuts were handed to the cut-model builder;
  /// Topology: after `tick` ticks the cut model built from the last snapshot was swapped in (a
  /// replay builds it from the same snapshot and swaps it at the same tick: engine/cut_swap.hpp).
  enum Kind : uint8_t { Tool, Pause, Resume, Reset, Step, Shutdown, End, Deadline, Mark, CutSnapshot, Topology } kind =
      Tool;
  int64_t tick = 0;    ///< ticks executed before it took effect
  ToolInput input;     ///< Tool events
  uint32_t steps = 0;  ///< Step events
  /// Deadline events: the tick `tick` ran out of its time budget at this deadline check
  /// (tissue/deadline.hpp); the replay expires that tick's deadline at the same check.
  int64_t deadline_check = -1;
  int line = 0;        ///< its line in the log (read_session_log), for messages
};

/// Ticks between the checkpoints (Mark events) a server writes into its session log.
inline constexpr int64_t kRecordMarkTicks = 10;

/// First lines of a session log (format version and column names).
extern const char* const kSessionLogHeader;

/// One line (with '\n') for `e`.
std::string format_session_event(const SessionEvent& e);

/// Reads a session log for a scenario with `tool_count` tools. Throws InputError with file, line
/// and column on a malformed value (not a number, not finite, not a unit quaternion), on a tool
/// index outside [0, tool_count) — the replay indexes the scenario's tools with it — and on
/// ticks that go backwards. The result ends with an End event. A log without its `end` line (the
/// server was killed) is cut at its last Mark: the events before it and an End at its tick, with
/// `*interrupted` set; without any Mark it is an error. Marks are not returned.
std::vector<SessionEvent> read_session_log(const std::string& path, int tool_count, bool* interrupted = nullptr);

/// The comment line a server writes into its log when it compiled the scenario with
/// `--converge` (the engine's converging solver in place of a SOFA scene's settings): a replay
/// compiles the same way, or it would not reach the same states.
extern const char* const kSessionLogConvergeLine;

/// Whether the log at `path` was recorded by a server that compiled with `--converge` (its
/// comment lines hold kSessionLogConvergeLine). Throws InputError if it cannot be opened.
bool session_log_converged(const std::string& path);

}  // namespace stroma
