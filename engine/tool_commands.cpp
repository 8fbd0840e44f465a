#include "engine/tool_commands.hpp"

#include <algorithm>

namespace stroma {

ToolCommandPort::ToolCommandPort(const std::vector<ToolSpec>& tools, double tick_period)
    : tools_(tools), period_(tick_period) {
  const size_t n = tools.size();
  last_.resize(n);
  last_client_ns_.assign(n, 0);
  last_arrival_ns_.assign(n, 0);
  have_last_.assign(n, 0);
  for (size_t t = 0; t < n; ++t) slots_.push_back(std::make_unique<TripleBuffer<ToolInput>>());
}

ToolCheck ToolCommandPort::submit(int tool, const ToolPose& pose, uint64_t seq, int64_t client_time_ns,
                                  int64_t arrival_ns) {
  // The speed check's interval: the sender's clock (arrival times bunch up under network
  // jitter), else the arrival clock, else one tick (the command takes effect a tick later at
  // the earliest). dt ≤ 0 would skip the check: a jump must never pass for lack of a clock.
  double dt = 0.0;
  if (have_last_[tool]) {
    const int64_t dc = client_time_ns - last_client_ns_[tool];
    const int64_t da = arrival_ns - last_arrival_ns_[tool];
    dt = dc > 0 ? static_cast<double>(dc) * 1e-9 : da > 0 ? static_cast<double>(da) * 1e-9 : period_;
  }
  const ToolCheck chk = validate_tool_command(tools_[tool], last_[tool], dt, pose);
  if (chk.result != ToolCheck::Accepted) last_reason_.store(chk.reason, std::memory_order_relaxed);
  if (chk.result == ToolCheck::Rejected) {
    counters_.rejected.fetch_add(1, std::memory_order_relaxed);
    return chk;
  }
  (chk.result == ToolCheck::Clamped ? counters_.clamped : counters_.accepted).fetch_add(1, std::memory_order_relaxed);
  last_[tool] = chk.pose;
  last_client_ns_[tool] = client_time_ns;
  last_arrival_ns_[tool] = arrival_ns;
  have_last_[tool] = 1;
  ToolInput& slot = slots_[tool]->write_slot();
  slot.tool = tool;
  slot.seq = seq;
  slot.client_time_ns = client_time_ns;
  slot.pose = chk.pose;
  slot.arrival_ns = arrival_ns;
  slots_[tool]->publish();
  return chk;
}

int ToolCommandPort::take(ToolInput* out, int max) {
  int n = 0;
  for (size_t t = 0; t < slots_.size() && n < max; ++t)
    if (slots_[t]->update()) out[n++] = slots_[t]->read_slot();
  return n;
}

void ToolCommandPort::seed(const std::vector<ToolState>& tools) {
  for (size_t t = 0; t < last_.size(); ++t) {
    have_last_[t] = t < tools.size() && tools[t].last_command_time >= 0;
    if (!have_last_[t]) continue;
    last_[t] = tools[t].pose;
    last_client_ns_[t] = tools[t].client_time_ns;
    last_arrival_ns_[t] = tools[t].client_time_ns;
  }
}

}  // namespace stroma
