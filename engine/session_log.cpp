#include "engine/session_log.hpp"

#include <fstream>
#include <sstream>

#include <fmt/format.h>

#include "tissue/input_error.hpp"

namespace stroma {

const char* const kSessionLogHeader =
    "# stroma session log v2 (v1 + deadline events)\n"
    "tick,event,tool,seq,client_time_ns,x,y,z,qw,qx,qy,qz,jaw,buttons,steps\n";

namespace {
const char* const kNames[] = {"tool", "pause", "resume", "reset", "step", "shutdown", "end", "deadline"};
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

std::vector<SessionEvent> read_session_log(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw InputError(path, 0, "", "cannot open session log");
  std::vector<SessionEvent> out;
  std::string line;
  int ln = 0;
  bool ended = false;
  while (std::getline(in, line)) {
    ++ln;
    if (line.empty() || line[0] == '#' || line.rfind("tick,", 0) == 0) continue;
    if (ended) throw InputError(path, ln, "", "event after the 'end' line");
    std::vector<std::string> c;
    std::stringstream ss(line);
    std::string cell;
    while (std::getline(ss, cell, ',')) c.push_back(cell);
    while (c.size() < 15) c.emplace_back();
    SessionEvent e;
    int kind = -1;
    for (int k = 0; k < 8; ++k)
      if (c[1] == kNames[k]) kind = k;
    if (kind < 0) throw InputError(path, ln, "event", fmt::format("unknown event '{}'", c[1]));
    e.kind = static_cast<SessionEvent::Kind>(kind);
    try {
      size_t used = 0;
      e.tick = std::stoll(c[0], &used);
      if (used != c[0].size() || e.tick < 0) throw std::invalid_argument("tick");
      if (e.kind == SessionEvent::Tool) {
        e.input.tool = std::stoi(c[2]);
        e.input.seq = std::stoull(c[3]);
        e.input.client_time_ns = std::stoll(c[4]);
        for (int k = 0; k < 3; ++k) e.input.pose.position[k] = std::stod(c[5 + k]);
        for (int k = 0; k < 4; ++k) e.input.pose.orientation[k] = std::stod(c[8 + k]);
        e.input.pose.jaw = std::stod(c[12]);
        e.input.pose.buttons = static_cast<uint32_t>(std::stoul(c[13]));
      } else if (e.kind == SessionEvent::Step) {
        e.steps = static_cast<uint32_t>(std::stoul(c[14]));
      } else if (e.kind == SessionEvent::Deadline) {
        e.deadline_check = std::stoll(c[14]);
        if (e.deadline_check < 0) throw std::invalid_argument("deadline");
      }
    } catch (const std::exception&) {
      throw InputError(path, ln, "", fmt::format("malformed line '{}'", line));
    }
    if (!out.empty() && e.tick < out.back().tick)
      throw InputError(path, ln, "tick", fmt::format("tick {} goes backwards (previous {})", e.tick, out.back().tick));
    ended = e.kind == SessionEvent::End;
    out.push_back(e);
  }
  if (!ended)
    throw InputError(path, ln, "", "no 'end' line: the recording was interrupted, cannot replay it exactly");
  return out;
}

}  // namespace stroma
