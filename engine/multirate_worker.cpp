#include "engine/multirate_worker.hpp"

#include "engine/multirate.hpp"
#include "engine/stage_timer.hpp"
#include "tissue/clock.hpp"
#include "tissue/demand.hpp"

namespace stroma {

MultirateWorker::MultirateWorker(const Model& m, TickWorkspace& w, const State& initial)
    : m_(m), w_(w), tissue_(initial), initial_(initial), ticks_since_post_(m.fem_every) {
  STROMA_DEMAND(m.fem_every > 1 && !m.cutting, "MultirateWorker: a multirate model without cutting");
  report_.tools.resize(m.tools.size());
}

MultirateWorker::~MultirateWorker() { stop(); }

void MultirateWorker::start(std::function<void()> on_start) {
  if (thread_.joinable()) return;
  stop_.store(false);
  thread_ = std::thread([this, on_start = std::move(on_start)] {
    if (on_start) on_start();
    run();
  });
}

void MultirateWorker::stop() {
  if (!thread_.joinable()) return;
  stop_.store(true);
  bell_.fetch_add(1, std::memory_order_release);
  bell_.notify_one();
  thread_.join();  // (a posted step runs first: done == posted after)
}

void MultirateWorker::run() {
  uint64_t rang = 0;
  for (;;) {
    bell_.wait(rang, std::memory_order_acquire);
    rang = bell_.load(std::memory_order_acquire);
    const uint64_t posted = posted_.load(std::memory_order_acquire);
    if (done_.load(std::memory_order_relaxed) != posted) run_step(posted);
    if (stop_.load()) return;
  }
}

void MultirateWorker::run_step(uint64_t posted) {
  TickReport& r = w_.report;
  begin_report(r);
  const int64_t t0 = steady_now_ns();
  Deadline d;
  d.at_ns = deadline_ns_;
  r.budget_ns = d.at_ns > 0 ? d.at_ns - t0 : 0;
  step_tissue(m_, tissue_, w_, d, m_.fem_every);
  close_report(r, t0, deadline_ns_);  // the tick's accounting (engine/tick_types.hpp)
  kinetic_step_ = w_.stepper().kinetic_energy(tissue_.tissue);  // O(n): here, not in a tick
  done_.store(posted, std::memory_order_release);
}

int64_t MultirateWorker::begin_tick(State& s, const ToolInput* inputs, int n) {
  const int64_t t0 = steady_now_ns();
  begin_report(report_);
  report_.budget_ns = 0;
  apply_tool_inputs(m_, s, report_, inputs, n);
  ++ticks_since_post_;
  return t0;
}

bool MultirateWorker::step_due() {
  const uint64_t posted = posted_.load(std::memory_order_relaxed);
  const bool idle = done_.load(std::memory_order_acquire) == posted;
  if (!idle && ticks_since_post_ == m_.fem_every) ++steps_late_;  // due, still running
  return idle && ticks_since_post_ >= m_.fem_every;
}

bool MultirateWorker::take_up_step(State& s) {
  // The worker's step is done: its models take over (as in a headless multirate run, at the
  // tick fem_every after the step started). Not after a reset, nor before the first step.
  if (posted_.load(std::memory_order_relaxed) == 0 || reset_pending_) return false;
  const TickReport& fr = w_.report;
  for (size_t k = 0; k < m_.tools.size(); ++k) {
    s.tools[k].haptic = tissue_.tools[k].haptic_next;
    report_.tools[k].contacts = fr.tools[k].contacts;
  }
  ++steps_;
  kinetic_taken_ = kinetic_step_;
  return true;
}

void MultirateWorker::post_step(const State& s, int64_t deadline_ns) {
  if (reset_pending_) {
    tissue_ = initial_;  // a copy into arrays of the same size: no allocation
    reset_pending_ = false;
  }
  for (size_t k = 0; k < m_.tools.size(); ++k) {  // the step is solved with the tools as they are now
    ToolState& to = tissue_.tools[k];
    const ToolState& from = s.tools[k];
    to.pose = from.pose;
    to.seq = from.seq;
    to.client_time_ns = from.client_time_ns;
    to.last_command_time = from.last_command_time;
    to.active = from.active;
  }
  deadline_ns_ = deadline_ns;
  ticks_since_post_ = 0;
  posted_.fetch_add(1, std::memory_order_release);
  bell_.fetch_add(1, std::memory_order_release);  // (the worker waits on the bell: posts and stop ring it)
  bell_.notify_one();
}

const TickReport& MultirateWorker::end_tick(State& s, int64_t t0) {
  s.time = static_cast<double>(s.step + 1) * m_.time_step;
  ++s.step;
  if (!m_.tools.empty()) {
    StageTimer t(report_, Stage::HandOff);
    render_haptic_models(m_, s, report_.tools);
  }
  report_.total_ns = steady_now_ns() - t0;
  return report_;
}

}  // namespace stroma
