#pragma once
/// \file physics_loop.hpp
/// The fixed-rate physics thread of `stroma serve`: one tick per time step of wall time, slept
/// to absolute deadlines (clock_nanosleep, TIMER_ABSTIME). A late tick is counted, the next one
/// starts at once and the schedule re-anchors — never a burst of catch-up ticks. Inputs arrive
/// through a lock-free queue; outputs leave through lock-free triple buffers. The loop never
/// blocks on anything but its own deadline, never allocates, locks or logs.

#include <array>
#include <atomic>
#include <cstdint>
#include <memory>
#include <vector>

#include "engine/cut_worker.hpp"
#include "engine/model.hpp"
#include "engine/simulation.hpp"
#include "engine/state.hpp"
#include "engine/tick.hpp"
#include "engine/timing_stats.hpp"
#include "engine/triple_buffer.hpp"
#include "runtime/phase_lock.hpp"
#include "runtime/session_log.hpp"
#include "runtime/spsc_queue.hpp"

namespace stroma {

/// A control command from a client (stroma_Control).
struct ControlEvent {
  enum Kind : uint8_t { Pause, Resume, Reset, Step, Shutdown } kind = Pause;
  uint32_t steps = 0;
};

/// Run state as published in SimStatus.
enum class RunState : uint8_t { Running, Paused, Stopping, Fault };

/// SCHED_FIFO priority of the multirate tissue worker (the physics thread has 80, the DDS
/// input and feedback threads 60).
inline constexpr int kTissueWorkerPriority = 50;

/// Most tools a scenario served in real time may have.
inline constexpr int kMaxTools = 8;

/// What renderers need of a tool, copied with each state frame.
struct ToolSnapshot {
  ToolPose pose;
  Vec3 center{0, 0, 0};    ///< tool_center(): where contact has the tool (proxy when coupled)
  Vec3 device_force{0, 0, 0};  ///< what its device renders (ToolFeedback::force)
  bool active = false;     ///< a client is driving it now
  bool commanded = false;  ///< it has had a command (it is somewhere in the scene)
  int contacts = 0, grasped = 0;
  int32_t holding_body = -1;  ///< the rigid body its jaws hold (−1: none)
};

/// What renderers need of a rigid body, copied with each state frame: its pose and velocities,
/// last step's contacts and a needle's insertion. Its track points are the frame's
/// track[track_begin, track_begin + track_count) (material points: weights on the frame's x).
struct RigidSnapshot {
  RigidState state;
  int32_t contacts = 0;
  Vec3 contact_force{0, 0, 0};
  NeedlePhase phase = NeedlePhase::Outside;
  int32_t tissue_body = -1;
  int32_t punctures = 0;
  double inserted_length = 0, tip_force = 0, friction_force = 0;
  int32_t track_begin = 0, track_count = 0;
};

/// A needle's puncture, exit or leaving the tissue, as the physics thread reports it (the DDS
/// stroma_NeedleEvent).
struct NeedleEventRecord {
  enum Kind : uint8_t { Puncture, Exit, Left } kind = Puncture;
  int32_t body = 0;         ///< the rigid body
  int32_t tissue_body = 0;  ///< the FEM body
  int32_t punctures = 0;    ///< the needle's count after it
  double time = 0;
  double tip_force = 0;     ///< N
  Vec3 apex{0, 0, 0};       ///< the tip's apex, world (m)
};

/// Full positions for the publisher (which extracts surfaces and stresses off the physics
/// thread). Sized once: with cutting, for the most DOFs and elements a cut model of the mesh
/// can have (stateframe_capacity). Invariants: the first 3·dofs entries of x and the first
/// `elements` of damage are the frame's; they are in the DOF and element layout of the model
/// of serial cut_serial (0: the scenario's uncut model; a cut model: CutModelRegistry).
struct StateFrame {
  uint64_t frame = 0;
  double sim_time = 0;
  std::vector<double> x;
  std::vector<float> damage;  ///< per element (empty without damage models)
  size_t dofs = 0, elements = 0;
  uint64_t cut_serial = 0;
  int32_t topology_version = 0;
  int tool_count = 0;
  std::array<ToolSnapshot, kMaxTools> tools{};
  std::vector<RigidSnapshot> rigid;  ///< one per Model::rigid_bodies
  std::vector<TrackPoint> track;     ///< the needles' track points (capacity: Σ track_capacity)
  std::vector<RodPuncture> punctures;  ///< the threads' punctures (capacity: Model::puncture_capacity)
  int32_t puncture_count = 0;
};

/// What a cut made, as the physics thread reports it when a cut model is swapped in (or a
/// Reset returns to the uncut model) — the DDS topology event.
struct TopologyEventRecord {
  int32_t topology_version = 0;
  double sim_time = 0;
  uint64_t tick = 0;
  CutStats cut;
};

/// Number of recent ticks whose times travel with each status frame (percentiles are computed
/// by the publisher, not the physics thread).
inline constexpr int kRecentTicks = 1024;

/// Live statistics for SimStatus (~10 Hz).
struct StatusFrame {
  RunState state = RunState::Running;
  double sim_time = 0, wall_time = 0, lag = 0;
  uint64_t ticks = 0, missed_deadlines = 0, controls = 0;
  double cg_iterations_mean = 0;  ///< over the last status period
  std::array<double, kStageCount> stage_ms{};  ///< mean per tick over the last status period
  uint64_t missed_window = 0;                  ///< missed deadlines in the last status period
  double budget_ms = 0;                        ///< the per-tick budget
  uint64_t over_budget = 0, degraded = 0;      ///< cumulative
  uint64_t over_budget_window = 0, degraded_window = 0;
  double residual_max = 0;                     ///< worst relative residual in the period
  double error_energy_max = 0;                 ///< J, worst energy-norm error bound in the period
  double error_position_max = 0;               ///< m, worst position error bound in the period
  double kinetic_energy = 0, elastic_energy = 0;
  int32_t topology_version = 0;  ///< the model ticking now (cutting: +1 per swapped-in model)
  CutStats cut;                  ///< what its cuts made
  int recent = 0;                               ///< valid entries below
  std::array<float, kRecentTicks> tick_us{};    ///< tick compute times (µs), recent window
  std::array<float, kRecentTicks> wake_us{};    ///< wake-up latencies (µs)
};

/// Feedback of every tool for one tick.
struct FeedbackBatch {
  int count = 0;
  std::array<ToolFeedbackFrame, kMaxTools> frames{};
};

/// Settings of the loop.
struct PhysicsLoopOptions {
  int publish_every = 17;  ///< ticks between state frames (≈ 60 Hz at 1 kHz)
  int status_every = 100;  ///< ticks between status frames (10 Hz at 1 kHz)
  bool start_paused = false;
  bool record = false;     ///< push applied inputs and controls to `record` (session log)
  /// Wake this many µs before each deadline and spin to it: trades a little CPU for wake-up
  /// latency (the kernel's timer slack and wake-up path cost tens of µs here).
  int spin_us = 0;
  /// The tick's engine work must end this long before the next deadline (s): the budget is the
  /// period minus this (or Model::time_budget if smaller), counted from the scheduled start.
  /// Multirate: the tissue worker's step has fem_every periods minus this.
  double budget_margin = 0.15e-3;
  /// Budget the ticks at all (tests that compare served and headless ticks turn it off).
  bool budget = true;
  /// The CPU the physics thread is pinned to (−1: not pinned). The multirate tissue worker
  /// then keeps off it: sharing it with the 1 kHz ticks (and their spin) slowed its steps 2–3×.
  int physics_cpu = -1;
  /// Phase-lock the schedule to the tool commands' arrival (runtime/phase_lock.hpp): a command
  /// is to arrive this long before the tick that takes it (s); 0 keeps a free-running schedule.
  double phase_lead = 0;
  /// Most the lock moves one deadline, as a fraction of the period.
  double phase_max_step = 0.02;
};

/// Final statistics after run() returns (read by the main thread after join).
struct PhysicsLoopStats {
  LatencyHistogram wake;        ///< actual wake-up − deadline
  LatencyHistogram tick;        ///< tick compute time
  /// Per taken command: its tick's scheduled start − its arrival (how long it waited for the
  /// tick; ≤ 0 counts as 0). Only commands stamped by the input thread (ToolInput::arrival_ns).
  LatencyHistogram command_wait;
  int64_t phase_shift_ns = 0;      ///< sum of the phase lock's corrections (signed)
  int64_t phase_shift_abs_ns = 0;  ///< sum of their magnitudes
  uint64_t ticks = 0, loops = 0, missed_deadlines = 0, not_converged = 0, non_finite = 0;
  uint64_t recovered = 0;  ///< ticks redone in sub-steps after a failed step
  uint64_t over_budget = 0;  ///< ticks whose engine work ended past the budget
  uint64_t degraded = 0;     ///< ticks the budget cut short (TickReport::degradation)
  /// Threads (TickReport::thread_contact): springs the continuous check after the step added (the
  /// step redone with them), and passes it skipped because no redo fitted before the deadline.
  uint64_t thread_missed = 0, thread_unchecked = 0;
  int64_t budget_ns = 0;     ///< the per-tick budget used
  uint64_t cg_iterations_total = 0;
  uint64_t record_dropped = 0;  ///< session-log events lost because the recorder fell behind
  int cg_iterations_max = 0;
  /// Multirate (Model::fem_every > 1): tissue steps the worker finished and whose models the
  /// ticks took up, and ticks at which a step was due but the worker was still busy (the next
  /// step then starts when it is done; the tools keep the last model meanwhile).
  uint64_t tissue_steps = 0, tissue_steps_late = 0;
  std::array<int64_t, kStageCount> stage_ns_total{};
  double sim_time = 0, wall_time = 0, lag = 0;
};

/// The physics thread's state and its lock-free ports. Invariants: one producer and one
/// consumer per port (controls and tool_in: the DDS-in thread → physics; the outputs: physics →
/// publisher / feedback / recorder threads); only run()'s thread touches the state, the
/// workspace and stats until finished is set.
class PhysicsLoop {
 public:
  PhysicsLoop(std::shared_ptr<const Model> model, PhysicsLoopOptions options);

  /// Runs until `stop` becomes true or a Shutdown control arrives. Call from the physics thread.
  void run(const std::atomic<bool>& stop);

  // ---- ports (lock-free) ----
  SpscQueue<ControlEvent, 64> controls;      ///< DDS-in thread → physics
  /// Tool commands: the DDS-in thread submits (checked and counted there), physics takes the
  /// newest of each tool (engine/tool_commands.hpp; the one port of every front end).
  ToolCommandPort& commands() { return sim_.commands(); }
  const ToolCommandPort& commands() const { return sim_.commands(); }
  TripleBuffer<StateFrame> state_out;        ///< physics → publisher
  TripleBuffer<StatusFrame> status_out;      ///< physics → publisher
  std::atomic<bool> state_wanted{false};     ///< publisher: a renderer is listening
  std::atomic<uint64_t> outputs_published{0};  ///< bumped (and notified) on every hand-off
  std::atomic<bool> finished{false};         ///< set when run() returns
  TripleBuffer<FeedbackBatch> feedback_out;  ///< physics → feedback writer, every tick
  std::atomic<uint64_t> feedback_published{0};
  SpscQueue<SessionEvent, 8192> record;      ///< physics → recorder thread
  SpscQueue<DamageEventRecord, 4096> damage_out;  ///< physics → publisher (reliable events)
  SpscQueue<TopologyEventRecord, 256> topology_out;  ///< physics → publisher (reliable events)
  SpscQueue<NeedleEventRecord, 256> needle_out;      ///< physics → publisher (reliable events)
  std::atomic<uint64_t> needle_dropped{0};  ///< events lost because the publisher fell behind
  std::atomic<uint64_t> topology_dropped{0};  ///< events lost because the publisher fell behind
  /// Cut models built for this loop (by its cut worker), for the readers of its state frames.
  CutModelRegistry cut_models;
  std::atomic<uint64_t> damage_dropped{0};   ///< events lost because the publisher fell behind

  const PhysicsLoopStats& stats() const { return stats_; }
  /// The simulation state (multirate: the tissue worker's, whose tools carry its own copies of
  /// the poses). Read after run() has returned.
  const State& state() const { return sim_.tissue_state(); }
  const Model& model() const { return sim_.model(); }
  /// Cutting statistics (null without a cutting tool). Read after run() has returned.
  const CutWorker* cutter() const { return sim_.cutter(); }

 private:
  /// What the status frame averages over its period (reset at each status frame).
  struct StatusWindow {
    uint64_t cg_iterations = 0, ticks = 0, missed_at_start = 0;
    std::array<int64_t, kStageCount> stage_ns{};
    double elastic_energy = 0;
    int recent = 0;  ///< entries of the recent tick/wake-up arrays filled
    uint64_t over_budget = 0, degraded = 0;
    double residual_max = 0, error_energy_max = 0, error_position_max = 0;
  };
  void handle_controls(RunState& rs, uint32_t& steps_pending, bool& shutdown);
  /// Logs the commands the tick took (sim_.inputs()) for the replay.
  void log_inputs();
  /// Records how long this tick's commands waited for it and returns the phase lock's move of
  /// the next deadline.
  int64_t follow_commands(PhaseLock& lock, const std::vector<ToolInput>& inputs, int64_t tick_start);
  /// Statistics of one tick (`tick`: count it as a tick; false for a multirate tissue step,
  /// whose ticks are counted by the physics thread); a non-finite step faults the run.
  void account_tick(const TickReport& r, RunState& rs, StatusWindow& win, bool tick = true);
  void publish_feedback(const TickReport& r);
  /// A state frame of `tissue` (its positions, rigid bodies and needles; `body_report`: the
  /// report of the step that moved them) with the tools of tick report r.
  void publish_state_frame(const TickReport& r, const State& tissue, const TickReport& body_report, uint64_t frame);
  /// Multirate: a tissue step the Simulation's worker finished, taken up at this tick — its
  /// statistics, damage events and (every publish_every ticks) a state frame of its state.
  void multirate_step_done(const TickReport& step, const State& tissue, int64_t ticks, const TickReport& tick_report,
                           RunState& rs, StatusWindow& win, uint64_t& frame);
  void publish_damage_events(const TickReport& r);
  /// The needles' punctures, exits and leavings of the step that made `tissue` (report r).
  void publish_needle_events(const TickReport& r, const State& tissue);
  void publish_topology_event();
  /// Cutting, at the end of a tick (or of a paused loop's turn): a pending Reset, a finished cut
  /// model swapped in, this tick's cuts handed to the worker — each logged for the replay.
  void service_cuts(int cut_edges);
  void publish_status(StatusFrame*& status, RunState rs, StatusWindow& win, double wall, double running_wall,
                      uint64_t controls_seen);
  void log(const SessionEvent& e) {
    if (opt_.record && !record.push(e)) {
      ++stats_.record_dropped;
      record_lost_ = true;  // no checkpoint after a lost event: the log replays only up to it
    }
  }
  bool record_lost_ = false;
  PhysicsLoopOptions opt_;
  /// The model ticking now (a cut model once cut), its state and workspace, the commands port
  /// and the cut stage (cut models built on its worker, swapped in at tick boundaries).
  Simulation sim_;
  /// A Reset that must wait for the cut worker's spare workspace is retried each tick.
  bool reset_pending_ = false;
  PhysicsLoopStats stats_;
  // Multirate (Model::fem_every > 1): the tissue steps on the Simulation's worker thread
  // (engine/multirate_worker.hpp); the physics thread renders the tools every tick.
  bool multirate_ = false;
  uint64_t ticks_since_frame_ = 0;  ///< ticks since the last state frame of a finished step
  /// The state changed since the last state frame (at start, after ticks, after a Reset): a
  /// paused loop publishes it once to a subscriber, so a paused server's state — its initial
  /// state (a prestretched body's mesh, not its rest shape), or where a Reset or steps left it —
  /// is seen without a tick.
  bool frame_due_ = true;
  /// The report a paused loop's state frame carries (no tick ran: no contacts, zero feedback),
  /// sized for the model's tools at construction so publishing it never allocates.
  TickReport idle_report_;
};

}  // namespace stroma
