#include "server/serve.hpp"

#include <pthread.h>
#include <signal.h>
#include <time.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <fstream>
#include <thread>

#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include "engine/model.hpp"
#include "runtime/option_error.hpp"
#include "runtime/physics_loop.hpp"
#include "runtime/realtime.hpp"
#include "runtime/state_io.hpp"
#include "scene/compiled_scenario.hpp"
#include "scene/scenario_spec.hpp"
#include "scene/solver_report.hpp"
#include "server/crtk_bridge.hpp"
#include "server/serve_dds.hpp"
#include "server/serve_record.hpp"
#include "server/serve_stats.hpp"
#include "tissue/input_error.hpp"

namespace stroma {

namespace {

/// Loads and compiles the scenario to serve; a static scenario is refused (file:line:field).
CompiledScenario load_servable(const ServeOptions& o) {
  const std::string& path = o.scenario;
  const ScenarioSpec spec = load_scenario(path);
  if (spec.solver.integrator == Integrator::Static) {
    // A static scenario solves equilibria, not time steps: there is nothing to tick at 1 kHz.
    const SourceLocation& at = spec.solver.integrator_where;
    throw InputError(at.file.empty() ? spec.file : at.file, at.line, "solver.integrator",
                     "integrator 'static' cannot be served in real time: `stroma serve` ticks time steps; use "
                     "implicit_euler (or symplectic_euler) to serve this scenario, or `stroma run` for its static "
                     "equilibrium");
  }
  // The budget must fit in the period: a longer one could never be kept at the tick rate (with
  // fem_every > 1 the tissue steps on a worker, once per fem_every ticks: that is its period).
  if (spec.solver.time_budget > spec.time_step * spec.solver.fem_every) {
    const SourceLocation& at = spec.solver.time_budget_where;
    throw InputError(at.file.empty() ? spec.file : at.file, at.line, "solver.time_budget",
                     fmt::format("time_budget {:g} s is longer than the period (time_step {:g} s): a served tick "
                                 "must fit in one period; use at most {:g} s, or none (the period minus "
                                 "--budget-margin-ms)",
                                 spec.solver.time_budget, spec.time_step * spec.solver.fem_every,
                                 spec.time_step * spec.solver.fem_every));
  }
  const ServeTimingOptions& t = o.timing;
  if (t.budget_margin_ms < 0 || t.budget_margin_ms * 1e-3 >= spec.time_step)
    throw OptionError("--budget-margin-ms",
                      fmt::format("{:g} ms leaves no budget: it must be >= 0 and below the period ({:g} ms)",
                                  t.budget_margin_ms, spec.time_step * 1e3));
  if (t.phase_lead_us < 0 || t.phase_lead_us * 1e-6 >= spec.time_step)
    throw OptionError("--phase-lead-us",
                      fmt::format("{:g} us: the lead must be >= 0 (0: no phase lock) and below the period ({:g} us)",
                                  t.phase_lead_us, spec.time_step * 1e6));
  CompileOptions co;
  co.budgeted = true;  // every served tick has a deadline (tissue/solver_choice.hpp)
  co.converge = o.converge;
  CompiledScenario sc = compile_scenario(spec, co);
  for (const auto& n : sc.notes) spdlog::warn("{}", n);
  if (sc.model->tools.size() > static_cast<size_t>(kMaxTools))
    throw std::runtime_error(fmt::format("at most {} tools are supported", kMaxTools));
  return sc;
}

/// Blocks until the loop finishes, SIGINT/SIGTERM arrives (signals go to this thread only) or
/// --duration has passed.
void wait_for_stop(const ServeOptions& o, const sigset_t& sigs, const PhysicsLoop& loop) {
  const auto start = std::chrono::steady_clock::now();
  const timespec poll{0, 100 * 1000 * 1000};
  while (!loop.finished.load()) {
    const int sig = sigtimedwait(&sigs, nullptr, &poll);
    if (sig == SIGINT || sig == SIGTERM) {
      spdlog::info("signal {}: shutting down", sig == SIGINT ? "SIGINT" : "SIGTERM");
      return;
    }
    if (o.timing.duration > 0 &&
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count() >= o.timing.duration)
      return;
  }
}

/// The physics thread: real-time setup (FIFO, mlockall, pinning: runtime/realtime.hpp), then the
/// loop until `stop`. ok() is false when --realtime fifo was asked for and refused.
class PhysicsThread {
 public:
  PhysicsThread(PhysicsLoop& loop, RealtimeMode mode, int cpu, std::atomic<bool>& stop) : stop_(stop) {
    std::atomic<bool> ready{false};
    thread_ = std::thread([&, mode, cpu] {
      rt_ = setup_realtime_thread(mode, cpu);
      failed_ = mode == RealtimeMode::Fifo && !rt_.fifo;
      ready = true;
      ready.notify_all();
      if (!failed_) loop.run(stop);
      loop.finished = true;
      loop.outputs_published.fetch_add(1);
      loop.outputs_published.notify_all();
    });
    ready.wait(false);
    if (!rt_.problems.empty()) {
      if (mode == RealtimeMode::Fifo) spdlog::error("--realtime fifo: {}", rt_.problems);
      else if (mode == RealtimeMode::Auto) spdlog::warn("real time not fully available, running best effort: {}", rt_.problems);
    }
  }
  /// Stops the loop (on an exception's path too) and joins.
  ~PhysicsThread() {
    stop_ = true;
    join();
  }
  void join() {
    if (thread_.joinable()) thread_.join();
  }
  bool ok() const { return !failed_; }
  const RealtimeResult& realtime() const { return rt_; }

 private:
  std::atomic<bool>& stop_;
  std::thread thread_;
  RealtimeResult rt_;
  bool failed_ = false;
};

/// The physics loop's options from serve's: rates from the model's time step, the schedule's
/// from --spin-us, --budget-margin-ms, --phase-lead-us, --cpu.
PhysicsLoopOptions loop_options(const ServeOptions& o, const Model& model) {
  PhysicsLoopOptions lo;
  lo.publish_every = std::max(1, static_cast<int>(std::lround(1.0 / (o.dds.publish_hz * model.time_step))));
  lo.status_every = std::max(1, static_cast<int>(std::lround(0.1 / model.time_step)));
  lo.start_paused = o.timing.start_paused;
  lo.record = !o.outputs.record_file.empty();
  lo.spin_us = o.timing.spin_us;
  lo.budget_margin = o.timing.budget_margin_ms * 1e-3;
  lo.phase_lead = o.timing.phase_lead_us * 1e-6;
  // Multirate: the tissue worker needs a core of its own; the physics thread takes the last
  // CPU unless --cpu says otherwise, and the worker keeps off it.
  const unsigned ncpu = std::thread::hardware_concurrency();
  lo.physics_cpu = o.timing.cpu >= 0 ? o.timing.cpu : model.fem_every > 1 && ncpu > 1 ? static_cast<int>(ncpu) - 1 : -1;
  return lo;
}

/// The end-of-session line in the log.
void log_session(const PhysicsLoopStats& st) {
  spdlog::info("{} ticks in {:.2f} s wall; missed deadlines {} ({:.3f} %); wake p99 {:.0f} us; tick p99 {:.3f} ms; lag {:.4f} s; "
               "budget {:.3f} ms: {} ticks over it, {} degraded",
               st.ticks, st.wall_time, st.missed_deadlines,
               st.loops ? 100.0 * static_cast<double>(st.missed_deadlines) / static_cast<double>(st.loops) : 0.0,
               st.wake.percentile_us(0.99), st.tick.percentile_us(0.99) * 1e-3, st.lag,
               static_cast<double>(st.budget_ns) * 1e-6, st.over_budget, st.degraded);
}

}  // namespace

int run_serve(const ServeOptions& o) {
  const CompiledScenario scenario = load_servable(o);
  const Model& model = *scenario.model;
  spdlog::info("{}", solver_summary(scenario));
  const RealtimeMode rt_mode = o.timing.realtime == "fifo"  ? RealtimeMode::Fifo
                               : o.timing.realtime == "off" ? RealtimeMode::Off
                                                            : RealtimeMode::Auto;
  // Signals go to the main thread only (sigtimedwait), never to the physics thread.
  sigset_t sigs;
  sigemptyset(&sigs);
  sigaddset(&sigs, SIGINT);
  sigaddset(&sigs, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &sigs, nullptr);

  // The parts, each with its options. Cyclone's receive threads deliver every tool command:
  // real-time like the input thread that takes them (priority 60, below the physics thread's
  // 80), best effort if denied.
  // Declared so that they end in reverse: the physics thread stops first (on an exception's
  // path too), then the DDS and recorder threads, which read the loop, then the loop.
  std::atomic<bool> stop{false};
  const PhysicsLoopOptions lo = loop_options(o, model);
  PhysicsLoop loop(scenario.model, lo);
  SessionRecorder recorder(o.outputs, o.scenario, o.converge);
  ServeDds dds(o.dds, rt_mode == RealtimeMode::Off ? 0 : 60, scenario);
  PhysicsThread physics(loop, rt_mode, lo.physics_cpu, stop);
  dds.start(loop, stop, solver_short(scenario), rt_mode != RealtimeMode::Off);
  recorder.start(loop);
  spdlog::info("serving '{}' at {:.0f} Hz ({} nodes, {} tets); Ctrl-C to stop", model.name, 1.0 / model.time_step,
               model.fem.num_nodes, model.fem.elements.size());
  if (model.fem_every > 1)
    spdlog::info("multirate: the tissue steps every {} ticks ({:.0f} Hz) on a worker thread; tools are rendered "
                 "every tick from the last finished step ({})",
                 model.fem_every, 1.0 / model.fem_step, model.haptic_secant ? "secant" : "hold");

  wait_for_stop(o, sigs, loop);
  stop = true;
  physics.join();
  dds.join();
  int exit_code = 0;
  if (!recorder.finish(loop)) exit_code = 1;
  if (!o.outputs.final_state_file.empty()) write_state_csv(o.outputs.final_state_file, loop.state());
  if (!physics.ok()) exit_code = 1;
  log_session(loop.stats());
  if (!o.outputs.stats_file.empty()) {
    std::ofstream f(o.outputs.stats_file);
    nlohmann::ordered_json j = stats_json(o, model, loop, physics.realtime(), dds.participant(), dds.counters(),
                                          dds.status_sent(), recorder.status());
    j["solver"] = solver_json(scenario);
    if (dds.crtk()) j["crtk"] = dds.crtk()->stats_json();
    f << j.dump(2) << '\n';
    if (!f) {
      spdlog::error("cannot write --stats file '{}'", o.outputs.stats_file);
      exit_code = 1;
    } else {
      spdlog::info("statistics written to {}", o.outputs.stats_file);
    }
  }
  if (loop.stats().non_finite) exit_code = 1;
  return exit_code;
}

}  // namespace stroma
