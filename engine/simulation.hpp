#pragma once
/// \file simulation.hpp
/// One Simulation advances a model's state for every front end — `stroma run`, `serve`'s
/// physics thread, the Python module and the benchmarks — so that a rule around the tick is
/// written once:
///  - commands come in through its ToolCommandPort (engine/tool_commands.hpp): validated,
///    clamped or refused by the tool's policy, and counted, whichever front end sent them;
///  - the cut stage follows each tick: a tick whose blade cut edges gets the cut model built and
///    swapped in — synchronously (headless: a run is a function of its inputs) or on a worker
///    that the physics thread never waits for (`serve`) — one code path with a policy;
///  - multirate (solver.fem_every > 1): the tissue's step inside tick() (headless) or on a
///    worker thread while each tick renders the tools (`serve`: MultirateWorker) — again one
///    entry point, step(), with a policy;
///  - Reset and restore return to the scenario's model, or to the model a snapshot names.
///
/// Model vs state (MuJoCo's mjModel/mjData): the Simulation holds a pointer to an immutable
/// Model, the State that is everything the next tick depends on, and the scratch TickWorkspace.
///
/// Invariants: state() fits model() (state_fits_model) between calls; the report step() returns
/// stays valid until the next step(), reset() or restore() — a cut swapped in by cut() keeps the
/// retired workspace alive until then (synchronous policy); with the worker policy, call cut()
/// after the report has been used (its swap retires the workspace the report lives in).
/// Threads: one thread advances it (step, cut, reset, restore); one producer thread may submit
/// to commands() concurrently.

#include <cstdint>
#include <memory>
#include <vector>

#include "engine/cut_registry.hpp"
#include "engine/cut_swap.hpp"
#include "engine/model.hpp"
#include "engine/multirate_worker.hpp"
#include "engine/state.hpp"
#include "engine/tick.hpp"
#include "engine/tool_commands.hpp"
#include "engine/trajectory.hpp"

namespace stroma {

class CutWorker;

/// How cut models are built (the cut stage's policy).
enum class CutBuilds : uint8_t {
  Synchronous,  ///< built and swapped in right after the tick that cut (headless, Python, benchmarks)
  OnWorker      ///< built on a worker thread, swapped in at the first tick boundary after (serve)
};

/// What a tool does in a tick with no new command.
enum class ToolHold : uint8_t {
  Timeout,  ///< holds its last pose, goes idle after its `timeout` (a live device: serve, run)
  Repeat    ///< the pose its state holds is applied again, once commanded (a pose set from Python
            ///< stays set, across a snapshot and restore too: it is read from the state)
};

struct SimulationOptions {
  CutBuilds cut_builds = CutBuilds::Synchronous;
  ToolHold hold = ToolHold::Timeout;
  /// Real-time ticks never wait for the preconditioner's refresh worker (TimeStepper::set_realtime).
  bool realtime = false;
  /// OnWorker: every cut model built is registered here (for the readers of state frames).
  CutModelRegistry* registry = nullptr;
  /// Commands are submitted from another thread than the one that steps (serve's DDS input
  /// thread). False (one thread, its client clock the simulated time: Python, run): reset() and
  /// restore() re-seed the commands port's speed check from the state (ToolCommandPort::seed).
  bool commands_from_another_thread = false;
  /// Multirate models (solver.fem_every > 1): the tissue steps on a worker thread (MultirateWorker,
  /// `serve`) rather than inside tick() (headless: the same pipeline emulated tick by tick).
  bool multirate_on_worker = false;
};

/// What the cut stage did after a tick.
struct CutStageResult {
  bool swapped = false;      ///< a cut model was swapped in (model(), state() are its now)
  bool posted = false;       ///< OnWorker: the state's cuts were handed to the worker
  double build_ms = 0;       ///< Synchronous: the build's wall time (0 when nothing was built)
};

class Simulation {
 public:
  /// At the model's initial state (State::initial). Throws std::invalid_argument on a null model.
  explicit Simulation(std::shared_ptr<const Model> model, SimulationOptions options = {});
  ~Simulation();
  Simulation(const Simulation&) = delete;
  Simulation& operator=(const Simulation&) = delete;

  const Model& model() const { return *model_; }
  const std::shared_ptr<const Model>& model_ptr() const { return model_; }
  /// The scenario's (uncut) model: what reset() returns to.
  const std::shared_ptr<const Model>& scenario_model() const { return original_; }
  State& state() { return state_; }
  const State& state() const { return state_; }
  TickWorkspace& workspace() { return *work_; }
  const TickWorkspace& workspace() const { return *work_; }
  /// Where every front end's tool commands go (see tool_commands.hpp).
  ToolCommandPort& commands() { return port_; }
  const ToolCommandPort& commands() const { return port_; }

  /// Submits each scripted tool's pose at the next tick's start time (sampled from its
  /// keyframes) through commands(), as a client would send it — except for tools the state says
  /// a front end posed directly (ToolState::posed: Python's set_pose overrides the script, and a
  /// restored snapshot keeps that). `at` ≥ 0: sample and stamp at that time instead (a static
  /// run's next equilibrium). Returns how many were submitted.
  int submit_scripts(const std::vector<Trajectory>& scripts, double at = -1);

  /// Takes the port's newest commands (and, with ToolHold::Repeat, the last accepted ones of the
  /// tools without a new one) into inputs(): what the next tick applies. step() calls it; the
  /// multirate physics thread, which ticks the tools itself, calls it directly.
  int take_commands();
  /// The commands the last take_commands() took, in tool order (valid until the next take).
  const std::vector<ToolInput>& inputs() const { return inputs_; }

  /// One tick: the port's newest commands, then `trusted` inputs (a replayed session's, already
  /// checked when recorded; applied after, so they win), then tick() — or, with the multirate
  /// worker, its tick (step_multirate, finished steps not handed to anyone). `deadline`: see
  /// tick(); with the worker, the deadline of a tissue step started at this tick.
  /// The cut stage is not run: call cut() (advance() does both).
  const TickReport& step(Deadline deadline = {}, const ToolInput* trusted = nullptr, int trusted_count = 0);
  /// With the multirate worker (multirate() not null): one tick of the physics thread — the
  /// port's newest commands, then MultirateWorker::tick, which calls `on_step(step_report,
  /// tissue_state, ticks, tick_report)` for each finished tissue step before the next starts.
  template <class OnStep>
  const TickReport& step_multirate(Deadline deadline, OnStep&& on_step) {
    take_commands();
    return multirate_->tick(state_, inputs_.data(), static_cast<int>(inputs_.size()), deadline.at_ns, on_step);
  }
  /// The multirate worker (null unless multirate_on_worker and the model's fem_every > 1).
  MultirateWorker* multirate() { return multirate_.get(); }
  const MultirateWorker* multirate() const { return multirate_.get(); }
  /// The tissue's state: state(), or with the multirate worker its state (the tools in it are
  /// the worker's copies; read it while the worker is idle or stopped).
  const State& tissue_state() const { return multirate_ ? multirate_->tissue_state() : state_; }
  /// The cut stage after a tick whose report cut `cut_edges` edges (and, OnWorker, every tick:
  /// a finished build is swapped in, pending cuts posted). Never waits, locks or allocates on
  /// the worker policy.
  CutStageResult cut(int cut_edges);
  /// step() then cut(): what a synchronous front end does per tick.
  const TickReport& advance(Deadline deadline = {});

  /// Back to the scenario's model and initial state (and, see commands_from_another_thread, the
  /// commands port's speed check with them; the multirate worker's tissue at its next step). Synchronous: always; OnWorker: false,
  /// changing nothing, while the uncut workspace is still being made (retry at the next tick).
  bool reset();
  /// A snapshot's model and state (Synchronous only: may allocate a workspace for `m`), the
  /// commands port's speed check re-seeded from it. The caller has checked that `s` fits `m`
  /// (state_fits_model) and `m` is of this scenario (snapshot fingerprints).
  void restore(std::shared_ptr<const Model> m, const State& s);
  /// Replay of a served session: the cut model built from `edge_cut` (the snapshot the server's
  /// worker was handed) swapped in now. Returns false when it changes nothing.
  bool swap_recorded(const std::vector<double>& edge_cut, double* build_ms = nullptr);

  /// Cut models swapped in, and the preconditioner refreshes of the workspaces they retired
  /// (TimeStepper::preconditioner_refreshes counts per workspace).
  int topology_swaps() const { return topology_swaps_; }
  int64_t retired_refreshes() const { return retired_refreshes_; }
  double cut_build_ms_total() const { return build_ms_total_; }
  double cut_build_ms_max() const { return build_ms_max_; }
  /// OnWorker: the cut worker (null without a cutting tool or with the synchronous policy).
  const CutWorker* cutter() const { return cutter_.get(); }

 private:
  bool apply_build(CutBuild& b);
  SimulationOptions opt_;
  std::shared_ptr<const Model> model_, original_;
  State state_;
  State initial_;  ///< the scenario's initial state: a Reset copies it into the state's arrays
  std::unique_ptr<TickWorkspace> work_;
  ToolCommandPort port_;
  std::vector<ToolInput> inputs_;   ///< capacity: every tool, twice (held + trusted)
  std::vector<ToolInput> held_;     ///< ToolHold::Repeat: this tick's inputs (capacity: every tool)
  CutBuild retired_;                ///< Synchronous: the last swap's old model, workspace and state
  std::unique_ptr<CutWorker> cutter_;
  std::unique_ptr<MultirateWorker> multirate_;  ///< after work_ and state_: it refers to them
  int topology_swaps_ = 0;
  int64_t retired_refreshes_ = 0;
  double build_ms_total_ = 0, build_ms_max_ = 0;
};

}  // namespace stroma
