#include "runtime/session_log.hpp"

#include <cmath>
#include <fstream>
#include <sstream>

#include <fmt/format.h>

#include "io/text_scan.hpp"
#include "tissue/input_error.hpp"

namespace stroma {

const char* const kSessionLogHeader =
    "# stroma session log v4 (v3 + cut_snapshot, topology: when a cut model was built from and swapped in)\n"
    "tick,event,tool,seq,client_time_ns,x,y,z,qw,qx,qy,qz,jaw,buttons,steps\n";

const char* const kSessionLogConvergeLine = "# compiled: --converge";

bool session_log_converged(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, 0, "", "cannot open session log");
  std::string line;
  while (std::getline(in, line)) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line == kSessionLogConvergeLine) return true;
    if (!line.empty() && line[0] != '#' && line.rfind("tick,", 0) != 0) return false;  // the events began
  }
  return false;
}

namespace {
const char* const kNames[] = {"tool", "pause",    "resume", "reset",        "step",    "shutdown",
                              "end",  "deadline", "mark",   "cut_snapshot", "topology"};
constexpr int kKinds = 11;
}

std::string format_session_event(const SessionEvent& e) {
  if (e.kind == SessionEvent::Tool) {
    const ToolInput& in = e.input;
    const ToolPose& p = in.pose;
    return fmt::format("{},tool,{},{},{},{:.17g},{:.17g},{:.17g},{:.17g},{:.17g},{:.17g},{:.17g},{:.17g},{},0\n",
                       e.tick, in.tool, in.seq, in.client_time_ns, p.position[0], p.position[1],
                       p.position[2], p.orientation[0], p.orientation[1], p.orientation[2],
                       p.orientation[3], p.jaw, p.buttons);
  }
  if (e.kind == SessionEvent::Deadline) return fmt::format("{},deadline,,,,,,,,,,,,,{}\n", e.tick, e.deadline_check);
  return fmt::format("{},{},,,,,,,,,,,,,{}\n", e.tick, kNames[e.kind], e.steps);
}

namespace {

/// Column names, for errors that say which field of a line is wrong.
const char* const kColumns[] = {"tick", "event", "tool", "seq", "client_time_ns", "x", "y", "z", "qw", "qx",
                                "qy", "qz", "jaw", "buttons", "steps"};

/// A whole cell as a number of type T, or an InputError naming the line and the column.
template <class T>
T cell_value(const std::vector<std::string>& c, int col, const std::string& path, int ln) {
  T v{};
  if (!text::parse_number(c[col], v))
    throw InputError(path, ln, kColumns[col],
                     fmt::format("'{}' is not {}", text::clip(c[col]),
                                 std::is_floating_point_v<T> ? "a number"
                                 : std::is_signed_v<T>       ? "an integer"
                                                             : "a non-negative integer"));
  if constexpr (std::is_floating_point_v<T>)
    if (!std::isfinite(v)) throw InputError(path, ln, kColumns[col], fmt::format("'{}' is not finite", text::clip(c[col])));
  return v;
}

}  // namespace

/// One event line (not a comment or header), or an InputError naming its line and field.
static SessionEvent parse_event(const std::string& line, const std::string& path, int ln, int tool_count) {
  std::vector<std::string> c;
  std::stringstream ss(line);
  std::string cell;
  while (std::getline(ss, cell, ',')) c.push_back(cell);
  if (c.size() > 15)
    throw InputError(path, ln, "", fmt::format("{} columns, expected at most 15 ({})", c.size(), text::clip(line)));
  while (c.size() < 15) c.emplace_back();
  SessionEvent e;
  e.line = ln;
  int kind = -1;
  for (int k = 0; k < kKinds; ++k)
    if (c[1] == kNames[k]) kind = k;
  if (kind < 0)
    throw InputError(path, ln, "event",
                     fmt::format("unknown event '{}' (expected tool, pause, resume, reset, step, shutdown, "
                                 "deadline, mark, cut_snapshot, topology or end)",
                                 text::clip(c[1])));
  e.kind = static_cast<SessionEvent::Kind>(kind);
  e.tick = cell_value<int64_t>(c, 0, path, ln);
  if (e.tick < 0) throw InputError(path, ln, "tick", fmt::format("tick {} is negative", e.tick));
  if (e.kind == SessionEvent::Tool) {
    e.input.tool = cell_value<int32_t>(c, 2, path, ln);
    if (e.input.tool < 0 || e.input.tool >= tool_count)
      throw InputError(path, ln, "tool",
                       fmt::format("tool index {} but the scenario has {} tool{} (indices 0..{}): was the "
                                   "session recorded with another scenario?",
                                   e.input.tool, tool_count, tool_count == 1 ? "" : "s", tool_count - 1));
    e.input.seq = cell_value<uint64_t>(c, 3, path, ln);
    e.input.client_time_ns = cell_value<int64_t>(c, 4, path, ln);
    for (int k = 0; k < 3; ++k) e.input.pose.position[k] = cell_value<double>(c, 5 + k, path, ln);
    for (int k = 0; k < 4; ++k) e.input.pose.orientation[k] = cell_value<double>(c, 8 + k, path, ln);
    const auto& q = e.input.pose.orientation;
    const double qn = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    if (!(std::fabs(qn - 1.0) <= 1e-3))
      throw InputError(path, ln, "qw,qx,qy,qz", fmt::format("|q| = {:.6g} is not a unit quaternion", qn));
    e.input.pose.jaw = cell_value<double>(c, 12, path, ln);
    e.input.pose.buttons = cell_value<uint32_t>(c, 13, path, ln);
  } else if (e.kind == SessionEvent::Step) {
    e.steps = cell_value<uint32_t>(c, 14, path, ln);
  } else if (e.kind == SessionEvent::Deadline) {
    e.deadline_check = cell_value<int64_t>(c, 14, path, ln);
    if (e.deadline_check < 0)
      throw InputError(path, ln, "steps", fmt::format("deadline check {} is negative", e.deadline_check));
  }
  return e;
}

std::vector<SessionEvent> read_session_log(const std::string& path, int tool_count, bool* interrupted) {
  if (interrupted) *interrupted = false;
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, 0, "", "cannot open session log");
  std::vector<SessionEvent> out;
  std::string line;
  int ln = 0;
  bool ended = false;
  bool have_mark = false;
  int64_t last_mark = 0;
  size_t events_before_mark = 0;
  while (std::getline(in, line)) {
    ++ln;
    if (!line.empty() && line.back() == '\r') line.pop_back();  // written on Windows
    if (line.empty() || line[0] == '#' || line.rfind("tick,", 0) == 0) continue;
    if (ended) throw InputError(path, ln, "", "event after the 'end' line");
    // A last line without its newline is a write the server's death cut short: dropped when
    // the log has no 'end' (it is then cut at its last mark anyway).
    const bool cut = in.eof();
    SessionEvent e;
    try {
      e = parse_event(line, path, ln, tool_count);
    } catch (const InputError&) {
      if (cut) break;
      throw;
    }
    if (!out.empty() && e.tick < out.back().tick)
      throw InputError(path, ln, "tick", fmt::format("tick {} goes backwards (previous {})", e.tick, out.back().tick));
    ended = e.kind == SessionEvent::End;
    if (e.kind == SessionEvent::Mark) {
      last_mark = e.tick;
      events_before_mark = out.size();
      have_mark = true;
      continue;
    }
    out.push_back(e);
  }
  if (ended) return out;
  // No 'end': the server stopped without closing the log (killed). Everything up to its last
  // checkpoint was written in order; events at or after it may be incomplete.
  if (!have_mark)
    throw InputError(path, ln, "",
                     "no 'end' line and no 'mark' checkpoint: the recording was interrupted before its first "
                     "checkpoint, there is nothing to replay");
  out.resize(events_before_mark);
  while (!out.empty() && out.back().tick >= last_mark) out.pop_back();
  SessionEvent end;
  end.kind = SessionEvent::End;
  end.tick = last_mark;
  end.line = ln;
  out.push_back(end);
  if (interrupted) *interrupted = true;
  return out;
}

}  // namespace stroma
