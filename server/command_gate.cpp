#include "server/command_gate.hpp"

#include <time.h>

namespace stroma {

int64_t monotonic_ns() {
  timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<int64_t>(ts.tv_sec) * 1000000000LL + ts.tv_nsec;
}

CommandGate::CommandGate(PhysicsLoop& loop, InputCounters& counters)
    : loop_(loop), cnt_(counters) {
  const size_t n = loop.model().tools.size();
  last_.resize(n);
  last_time_.resize(n);
  last_client_ns_.assign(n, 0);
  have_last_.assign(n, false);
}

ToolCheck CommandGate::submit(int tool, const ToolPose& pose, uint64_t seq, int64_t client_time_ns) {
  const Model& m = loop_.model();
  // Speed check over the client's own clock (arrival times bunch up under network jitter);
  // the arrival clock only when the client's timestamps do not advance.
  const auto now = std::chrono::steady_clock::now();
  double dt = 0.0;
  if (have_last_[tool]) {
    const int64_t dc = client_time_ns - last_client_ns_[tool];
    dt = dc > 0 ? static_cast<double>(dc) * 1e-9 : std::chrono::duration<double>(now - last_time_[tool]).count();
  }
  const ToolCheck chk = validate_tool_command(m.tools[tool], last_[tool], dt, pose);
  if (chk.result == ToolCheck::Rejected) {
    cnt_.rejected.fetch_add(1);
    return chk;
  }
  (chk.result == ToolCheck::Clamped ? cnt_.clamped : cnt_.accepted).fetch_add(1);
  last_[tool] = chk.pose;
  last_time_[tool] = now;
  last_client_ns_[tool] = client_time_ns;
  have_last_[tool] = true;
  ToolInput& slot = loop_.tool_in[tool]->write_slot();
  slot.tool = tool;
  slot.seq = seq;
  slot.client_time_ns = client_time_ns;
  slot.pose = chk.pose;
  slot.arrival_ns = monotonic_ns();  // the loop's clock (CLOCK_MONOTONIC)
  loop_.tool_in[tool]->publish();
  return chk;
}

}  // namespace stroma
