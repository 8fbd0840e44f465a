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
  enum Kind : uint8_t { Tool, Pause, Resume, Reset, Step, Shutdown, End, Deadline } kind = Tool;
  int64_t tick = 0;    ///< ticks executed before it took effect
  ToolInput input;     ///< Tool events
  uint32_t steps = 0;  ///< Step events
  /// Deadline events: the tick `tick` ran out of its time budget at this deadline check
  /// (tissue/deadline.hpp); the replay expires that tick's deadline at the same check.
  int64_t deadline_check = -1;
};

/// First lines of a session log (format version and column names).
extern const char* const kSessionLogHeader;

/// One line (with '\n') for `e`.
std::string format_session_event(const SessionEvent& e);

/// Reads a session log. Throws InputError with file and line on a malformed line, on ticks
/// that go backwards, and on a log without its final `end` line (an interrupted recording).
std::vector<SessionEvent> read_session_log(const std::string& path);

}  // namespace stroma
