#pragma once
/// \file multirate_worker.hpp
/// The served multirate pipeline (solver.fem_every = N > 1 under `stroma serve`): the tissue
/// steps by N·time_step on a worker thread, taking N ticks, while every tick of the calling
/// (physics) thread reads the tools' commands and renders their forces from the last finished
/// step's haptic models (engine/multirate.hpp). A headless run emulates the same pipeline inside
/// tick(): the model of the step started at tick kN is rendered from tick (k+1)N on.
///
/// Simulation owns one when its options ask for the worker policy on a multirate model
/// (SimulationOptions::multirate_on_worker); the physics loop drives it through
/// Simulation::step_multirate, which hands each finished step to the loop's callback (state
/// frames, damage events, statistics) before the next one starts.
///
/// Ownership: while the worker is idle (done == posted) the calling thread owns tissue_state()
/// and the workspace; after it posts (release) the worker owns them until it stores done
/// (release). The tools' poses reach the worker inside the tissue state; its results come back
/// in the tissue state, the workspace's report and the step's kinetic energy.

#include <atomic>
#include <cstdint>
#include <functional>
#include <thread>

#include "engine/model.hpp"
#include "engine/state.hpp"
#include "engine/tick.hpp"
#include "engine/tick_types.hpp"

namespace stroma {

class MultirateWorker {
 public:
  /// Steps m's tissue with workspace w (which must outlive it), from `initial`, which a reset
  /// also returns the tissue to. Invariant: m.fem_every > 1 and m has no cutting tool (compile
  /// refuses cutting with multirate: the workspace never changes).
  MultirateWorker(const Model& m, TickWorkspace& w, const State& initial);
  ~MultirateWorker();  ///< stops and joins the thread
  MultirateWorker(const MultirateWorker&) = delete;
  MultirateWorker& operator=(const MultirateWorker&) = delete;

  /// Starts the worker thread; `on_start` runs first on it (its priority and CPU:
  /// runtime/realtime.hpp's setup_worker_thread under `serve`).
  void start(std::function<void()> on_start = {});
  /// Stops and joins the thread (a posted step runs to its end first, so done == posted after:
  /// start() again goes on where it stopped). Idempotent.
  void stop();

  /// One haptic-rate tick on the calling thread: the tools' commands into s (read_inputs), and
  /// every fem_every ticks — or as soon as a late worker is done — the worker's finished step
  /// taken up (each tool's haptic model from it; `on_step(step_report, tissue_state, ticks,
  /// tick_report)` called with the step's report, state and the ticks it spanned, and this
  /// tick's report so far — the tools' contacts of the step, last tick's rendered forces —
  /// before the next step starts) and
  /// the next step posted with the tools as they are now, due at `step_deadline_ns` (steady
  /// clock; 0: none). Then s advances one tick and each tool is rendered from its model.
  /// Never waits, locks or allocates.
  template <class OnStep>
  const TickReport& tick(State& s, const ToolInput* inputs, int n, int64_t step_deadline_ns, OnStep&& on_step) {
    const int64_t t0 = begin_tick(s, inputs, n);
    if (step_due()) {
      if (take_up_step(s))
        on_step(static_cast<const TickReport&>(w_.report), static_cast<const State&>(tissue_), ticks_since_post_,
                static_cast<const TickReport&>(report_));
      post_step(s, step_deadline_ns);
    }
    return end_tick(s, t0);
  }

  /// The tissue returns to the initial state at the next post (the worker may be mid-step now).
  void reset() { reset_pending_ = true; }

  /// The worker's tissue state (read while it is idle, or after stop()).
  const State& tissue_state() const { return tissue_; }
  /// Kinetic energy after the last step taken up (the worker's figure, for status frames).
  double kinetic_energy() const { return kinetic_taken_; }
  uint64_t steps() const { return steps_; }            ///< steps taken up
  uint64_t steps_late() const { return steps_late_; }  ///< due ticks at which the worker was still running

 private:
  int64_t begin_tick(State& s, const ToolInput* inputs, int n);
  bool step_due();
  bool take_up_step(State& s);
  void post_step(const State& s, int64_t deadline_ns);
  const TickReport& end_tick(State& s, int64_t t0);
  void run();
  void run_step(uint64_t posted);

  const Model& m_;
  TickWorkspace& w_;
  State tissue_;         ///< the worker's state
  const State initial_;  ///< what a reset returns the tissue to
  TickReport report_;    ///< the calling thread's tick report
  std::thread thread_;
  std::atomic<uint64_t> posted_{0}, done_{0};
  std::atomic<uint64_t> bell_{0};  ///< rung by every post and by stop(): what the worker waits on
  std::atomic<bool> stop_{false};
  int64_t deadline_ns_ = 0;  ///< the posted step's deadline (0: none)
  int64_t ticks_since_post_;
  bool reset_pending_ = false;
  double kinetic_step_ = 0;   ///< the worker's: kinetic energy after its step
  double kinetic_taken_ = 0;  ///< the calling thread's copy
  uint64_t steps_ = 0, steps_late_ = 0;
};

}  // namespace stroma
