#include "runtime/physics_loop.hpp"

#include <time.h>

#include <algorithm>
#include <cmath>
#include <thread>

#include "engine/stage_timer.hpp"
#include "haptics/tool_shape.hpp"
#include "runtime/realtime.hpp"
#include "tissue/clock.hpp"

namespace stroma {

namespace {

constexpr int64_t kNs = 1000000000LL;

inline void sleep_until(int64_t t) {
  timespec ts{static_cast<time_t>(t / kNs), static_cast<long>(t % kNs)};
  while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) != 0) {
  }
}

/// A state frame sized for every model the loop may tick: the scenario's, and with cutting any
/// cut model of its mesh — a tetrahedron has at most four copies (one per node component) and
/// each copy four DOFs, so at most 16 DOFs per tetrahedron beyond the nodes.
StateFrame frame_for(const Model& m) {
  StateFrame f;
  const size_t tets = m.fem.elements.size();
  const size_t nodes = static_cast<size_t>(m.fem.num_nodes);
  const size_t dofs = m.cutting ? nodes + 16 * tets : nodes;
  f.x.assign(3 * dofs, 0.0);
  const std::vector<double>& x0 = m.initial_x.empty() ? m.fem.rest : m.initial_x;
  std::copy(x0.begin(), x0.end(), f.x.begin());
  f.dofs = nodes;
  if (m.has_damage) f.damage.assign(m.cutting ? 4 * tets : tets, 0.0f);
  f.elements = m.has_damage ? tets : 0;
  f.rigid.resize(m.rigid_bodies.size());
  size_t track = 0;
  for (const RigidBodyModel& b : m.rigid_bodies) track += static_cast<size_t>(b.track_capacity);
  f.track.resize(track);
  f.punctures.resize(size_t(m.puncture_capacity));
  return f;
}

}  // namespace

PhysicsLoop::PhysicsLoop(std::shared_ptr<const Model> model, PhysicsLoopOptions options)
    : state_out(frame_for(*model)),
      opt_(options),
      // Served ticks never wait for the preconditioner's worker (TimeStepper::set_realtime); cut
      // models are built on a worker (compile refuses cutting with multirate).
      // The tissue of a multirate model steps on the Simulation's worker (MultirateWorker).
      sim_(std::move(model), SimulationOptions{CutBuilds::OnWorker, ToolHold::Timeout, true, &cut_models, true, true}) {
  multirate_ = sim_.multirate() != nullptr;
  idle_report_.tools.resize(sim_.model().tools.size());
}

void PhysicsLoop::handle_controls(RunState& rs, uint32_t& steps_pending, bool& shutdown) {
  ControlEvent ev;
  while (controls.pop(ev)) {
    SessionEvent se;
    se.tick = static_cast<int64_t>(stats_.ticks);
    se.kind = static_cast<SessionEvent::Kind>(static_cast<int>(ev.kind) + 1);  // Pause..Shutdown
    se.steps = ev.steps;
    // (A Reset is logged where it takes effect: it may wait a few ticks for the uncut workspace.)
    if (ev.kind != ControlEvent::Reset) log(se);
    switch (ev.kind) {
      case ControlEvent::Pause: rs = RunState::Paused; break;
      case ControlEvent::Resume: rs = RunState::Running; steps_pending = 0; break;
      case ControlEvent::Reset: {
        const int32_t version = sim_.model().topology_version;
        if (!sim_.reset()) {  // (a copy of the initial state into the state's arrays: no allocation)
          reset_pending_ = true;  // the uncut workspace is still being made: at the next tick
          break;
        }
        if (version != sim_.model().topology_version) publish_topology_event();
        frame_due_ = true;
        log(se);
        break;
      }
      case ControlEvent::Step:
        rs = RunState::Paused;
        steps_pending += ev.steps;
        break;
      case ControlEvent::Shutdown: shutdown = true; break;
    }
  }
}

void PhysicsLoop::publish_feedback(const TickReport& r) {
  FeedbackBatch& fb = feedback_out.write_slot();
  fb.count = 0;
  for (size_t t = 0; t < sim_.state().tools.size() && fb.count < kMaxTools; ++t) {
    const ToolState& ts = sim_.state().tools[t];
    const ToolOutput& out = r.tools[t];
    ToolFeedbackFrame& f = fb.frames[fb.count++];
    f = ToolFeedbackFrame{};
    f.tool = static_cast<int32_t>(t);
    f.seq = ts.seq;
    f.client_time_ns = ts.client_time_ns;
    f.server_time_ns = steady_now_ns();
    f.sim_time = sim_.state().time;
    f.active = ts.active;
    f.force = out.feedback.force;  // computed once, by the tick's hand_off (haptics/feedback.hpp)
    f.torque = out.feedback.torque;
    f.stiffness = out.feedback.stiffness;
    f.in_contact = out.contacts > 0;
    f.pose = ts.pose;
  }
  feedback_out.publish();
  feedback_published.fetch_add(1, std::memory_order_release);
  feedback_published.notify_one();
}

void PhysicsLoop::publish_state_frame(const TickReport& r, const State& tissue, const TickReport& body_report,
                                      uint64_t frame) {
  StateFrame& f = state_out.write_slot();
  frame_due_ = false;
  f.frame = frame;
  f.sim_time = tissue.time;
  // The positions and damage in the ticking model's layout (a cut model's DOFs and element
  // copies), named by its serial: the publisher finds the model in cut_models. The frame is
  // sized for the largest cut model (frame_for), so this never allocates.
  const size_t nx = std::min(tissue.tissue.x.size(), f.x.size());
  const size_t nd = std::min(tissue.damage.size(), f.damage.size());
  std::copy_n(tissue.tissue.x.begin(), nx, f.x.begin());
  std::copy_n(tissue.damage.begin(), nd, f.damage.begin());
  f.dofs = nx / 3;
  f.elements = nd;
  f.cut_serial = sim_.model().cut_serial;
  f.topology_version = sim_.model().topology_version;
  f.tool_count = static_cast<int>(std::min<size_t>(sim_.state().tools.size(), kMaxTools));
  for (int t = 0; t < f.tool_count; ++t) {
    const ToolState& ts = sim_.state().tools[t];
    f.tools[t] = ToolSnapshot{ts.pose,      tool_center(sim_.model().tools[t], ts), r.tools[t].feedback.force, ts.active,
                              ts.last_command_time >= 0, r.tools[t].contacts, ts.grasped, ts.grasped_body};
  }
  // The rigid bodies and the needles' tracks (the frame is sized for every track's capacity).
  int32_t track = 0;
  for (size_t k = 0; k < f.rigid.size() && k < tissue.rigid.size(); ++k) {
    RigidSnapshot& b = f.rigid[k];
    b = RigidSnapshot{};
    b.state = tissue.rigid[k];
    if (k < body_report.rigid_contact.size()) {
      b.contacts = body_report.rigid_contact[k].contacts;
      b.contact_force = body_report.rigid_contact[k].force;
    }
    b.track_begin = track;
    if (k < tissue.needles.size()) {
      const NeedleState& n = tissue.needles[k];
      b.phase = n.phase;
      b.tissue_body = n.tissue_body;
      b.punctures = n.punctures;
      b.track_count = std::clamp<int32_t>(n.count, 0, static_cast<int32_t>(f.track.size()) - track);
      std::copy_n(n.track.begin(), b.track_count, f.track.begin() + track);
      track += b.track_count;
    }
    if (k < body_report.needles.size()) {
      const NeedleOutput& o = body_report.needles[k];
      b.inserted_length = o.inserted_length;
      b.tip_force = o.tip_force;
      b.friction_force = o.friction_force;
    }
  }
  // The threads' punctures (the frame is sized for their capacity).
  f.puncture_count = std::clamp<int32_t>(tissue.puncture_count, 0, static_cast<int32_t>(f.punctures.size()));
  std::copy_n(tissue.punctures.begin(), f.puncture_count, f.punctures.begin());
  state_out.publish();
  outputs_published.fetch_add(1, std::memory_order_release);
  outputs_published.notify_one();
}

void PhysicsLoop::publish_damage_events(const TickReport& r) {
  for (DamageEventRecord ev : r.damage_records) {
    // Events name the scenario's tetrahedra (file order): a cut model's element is a copy.
    if (sim_.model().topology_version > 0) ev.element = sim_.model().topology->copies[ev.element].tet;
    if (!damage_out.push(ev)) damage_dropped.fetch_add(1, std::memory_order_relaxed);
  }
  outputs_published.fetch_add(1, std::memory_order_release);
  outputs_published.notify_one();
}

void PhysicsLoop::publish_needle_events(const TickReport& r, const State& tissue) {
  const Model& m = sim_.model();
  bool pushed = false;
  for (size_t k = 0; k < r.needles.size() && k < tissue.needles.size(); ++k) {
    const NeedleOutput& o = r.needles[k];
    if (!o.punctured && !o.exited && !o.left) continue;
    const RigidBodyModel& b = m.rigid_bodies[k];
    NeedleEventRecord ev;
    ev.body = static_cast<int32_t>(k);
    ev.tissue_body = o.tissue_body;
    ev.punctures = tissue.needles[k].punctures;
    ev.time = tissue.time;
    ev.tip_force = o.tip_force;
    double t[3], arm[3];
    needle_world_point(b, tissue.rigid[k], b.needle.length + b.needle.wire_radius, ev.apex.data(), t, arm);
    // In the order they happened: an exit or a leaving ends an insertion a puncture began.
    for (const auto& [happened, kind] : {std::pair{o.punctured, NeedleEventRecord::Puncture},
                                        std::pair{o.exited, NeedleEventRecord::Exit}, std::pair{o.left, NeedleEventRecord::Left}})
      if (happened) {
        ev.kind = kind;
        if (!needle_out.push(ev)) needle_dropped.fetch_add(1, std::memory_order_relaxed);
        pushed = true;
      }
  }
  if (!pushed) return;
  outputs_published.fetch_add(1, std::memory_order_release);
  outputs_published.notify_one();
}

void PhysicsLoop::publish_topology_event() {
  TopologyEventRecord ev;
  ev.topology_version = sim_.model().topology_version;
  ev.sim_time = sim_.state().time;
  ev.tick = stats_.ticks;
  ev.cut = sim_.model().cut_stats;
  if (!topology_out.push(ev)) topology_dropped.fetch_add(1, std::memory_order_relaxed);
  outputs_published.fetch_add(1, std::memory_order_release);
  outputs_published.notify_one();
}

void PhysicsLoop::account_tick(const TickReport& r, RunState& rs, StatusWindow& win, bool tick) {
  if (tick) {
    ++stats_.ticks;
    ++win.ticks;
    if (opt_.record && !record_lost_ && stats_.ticks % kRecordMarkTicks == 0) {
      // A checkpoint in the session log: a log cut short (the server killed) replays to it.
      SessionEvent mark;
      mark.kind = SessionEvent::Mark;
      mark.tick = static_cast<int64_t>(stats_.ticks);
      log(mark);
    }
  }
  stats_.cg_iterations_total += static_cast<uint64_t>(r.solve.iterations);
  stats_.cg_iterations_max = std::max(stats_.cg_iterations_max, r.solve.iterations);
  for (int s = 0; s < kStageCount; ++s) {
    stats_.stage_ns_total[s] += r.stage_ns[s];
    win.stage_ns[s] += r.stage_ns[s];
  }
  if (r.status == TickStatus::SolverNotConverged) ++stats_.not_converged;
  if (r.status == TickStatus::Recovered) ++stats_.recovered;
  stats_.thread_missed += static_cast<uint64_t>(r.thread_contact.missed);
  stats_.thread_unchecked += static_cast<uint64_t>(r.thread_contact.unchecked);
  if (r.over_budget) {
    ++stats_.over_budget;
    ++win.over_budget;
  }
  if (r.degradation != Degradation::None) {
    ++stats_.degraded;
    ++win.degraded;
  }
  win.residual_max = std::max(win.residual_max, r.solve.relative_residual);
  win.error_energy_max = std::max(win.error_energy_max, r.solve.error_energy);
  win.error_position_max = std::max(win.error_position_max, r.solve.error_position);
  if (r.status == TickStatus::NonFinite) {
    ++stats_.non_finite;
    rs = RunState::Fault;  // state kept finite (not advanced); clients see FAULT
  }
  if (r.tissue_stepped) win.elastic_energy = r.elastic_energy;
  win.cg_iterations += static_cast<uint64_t>(r.solve.iterations);
}

void PhysicsLoop::publish_status(StatusFrame*& status, RunState rs, StatusWindow& win, double wall, double running_wall,
                                 uint64_t controls_seen) {
  status->state = rs;
  status->sim_time = sim_.state().time;
  status->wall_time = wall;
  status->lag = running_wall - sim_.state().time;
  status->ticks = stats_.ticks;
  status->missed_deadlines = stats_.missed_deadlines;
  status->controls = controls_seen;
  status->cg_iterations_mean = win.ticks ? static_cast<double>(win.cg_iterations) / static_cast<double>(win.ticks) : 0.0;
  // (multirate: the worker's last finished step; its state may be in use)
  status->kinetic_energy = multirate_ ? sim_.multirate()->kinetic_energy() : sim_.workspace().stepper().kinetic_energy(sim_.state().tissue);
  for (int st = 0; st < kStageCount; ++st)
    status->stage_ms[st] = win.ticks ? static_cast<double>(win.stage_ns[st]) * 1e-6 / static_cast<double>(win.ticks) : 0.0;
  status->missed_window = stats_.missed_deadlines - win.missed_at_start;
  status->elastic_energy = win.elastic_energy;
  status->recent = win.recent;
  status->budget_ms = static_cast<double>(stats_.budget_ns) * 1e-6;
  status->over_budget = stats_.over_budget;
  status->degraded = stats_.degraded;
  status->over_budget_window = win.over_budget;
  status->degraded_window = win.degraded;
  status->residual_max = win.residual_max;
  status->error_energy_max = win.error_energy_max;
  status->error_position_max = win.error_position_max;
  status->topology_version = sim_.model().topology_version;
  status->cut = sim_.model().cut_stats;
  status_out.publish();
  outputs_published.fetch_add(1, std::memory_order_release);
  outputs_published.notify_one();
  status = &status_out.write_slot();
  const double elastic = win.elastic_energy;
  win = StatusWindow{};
  win.elastic_energy = elastic;
  win.missed_at_start = stats_.missed_deadlines;
}

void PhysicsLoop::log_inputs() {
  for (const ToolInput& in : sim_.inputs()) {
    SessionEvent se;
    se.tick = static_cast<int64_t>(stats_.ticks);
    se.kind = SessionEvent::Tool;
    se.input = in;
    log(se);
  }
}

int64_t PhysicsLoop::follow_commands(PhaseLock& lock, const std::vector<ToolInput>& inputs, int64_t tick_start) {
  // The latest-arriving command of this tick is the one the schedule must wait for.
  int64_t latest = 0;
  for (size_t i = 0; i < inputs.size(); ++i) {
    if (inputs[i].arrival_ns <= 0) continue;
    stats_.command_wait.record(tick_start - inputs[i].arrival_ns);
    latest = std::max(latest, inputs[i].arrival_ns);
  }
  if (latest == 0) return 0;
  const int64_t shift = lock.correction(tick_start, latest);
  stats_.phase_shift_ns += shift;
  stats_.phase_shift_abs_ns += shift < 0 ? -shift : shift;
  return shift;
}

void PhysicsLoop::multirate_step_done(const TickReport& step, const State& tissue, int64_t ticks,
                                      const TickReport& tick_report, RunState& rs, StatusWindow& win, uint64_t& frame) {
  ++stats_.tissue_steps;
  account_tick(step, rs, win, false);
  if (step.damage_events > 0) publish_damage_events(step);
  if (sim_.model().has_needles) publish_needle_events(step, tissue);
  if (state_wanted.load(std::memory_order_relaxed) &&
      (ticks_since_frame_ += static_cast<uint64_t>(ticks)) >= static_cast<uint64_t>(opt_.publish_every)) {
    ticks_since_frame_ = 0;
    publish_state_frame(tick_report, tissue, step, ++frame);
  }
}

void PhysicsLoop::service_cuts(int cut_edges) {
  if (reset_pending_ && sim_.reset()) {
    reset_pending_ = false;
    frame_due_ = true;
    publish_topology_event();  // (pending only when a cut model was ticking)
    SessionEvent se;  // the Reset takes effect now: the log says so at this tick
    se.kind = SessionEvent::Reset;
    se.tick = static_cast<int64_t>(stats_.ticks);
    log(se);
  }
  if (reset_pending_) return;  // no cut model while a Reset waits for the uncut workspace
  const int64_t ticks = static_cast<int64_t>(stats_.ticks);
  const CutStageResult c = sim_.cut(cut_edges);
  if (c.swapped) {
    publish_topology_event();
    SessionEvent se;
    se.kind = SessionEvent::Topology;
    se.tick = ticks;
    log(se);
  }
  if (c.posted) {
    SessionEvent se;
    se.kind = SessionEvent::CutSnapshot;
    se.tick = ticks;
    log(se);
  }
}

void PhysicsLoop::run(const std::atomic<bool>& stop) {
  const Model& m = sim_.model();
  const int64_t period = static_cast<int64_t>(m.time_step * 1e9 + 0.5);
  // The tissue step's budget: its period (a tick's, or fem_every ticks' on the multirate worker)
  // minus the margin, or the scenario's time_budget if smaller.
  int64_t budget = period * m.fem_every - static_cast<int64_t>(opt_.budget_margin * 1e9);
  if (m.time_budget > 0) budget = std::min(budget, static_cast<int64_t>(m.time_budget * 1e9));
  stats_.budget_ns = std::max<int64_t>(budget, 1);
  RunState rs = opt_.start_paused ? RunState::Paused : RunState::Running;
  uint32_t steps_pending = 0;
  bool shutdown = false;
  uint64_t frame = 0, controls_seen = 0;
  double running_wall = 0;  // wall time spent in the Running state (for the lag)
  StatusWindow win;
  StatusFrame* status = &status_out.write_slot();

  PhaseLock lock(opt_.phase_lead > 0 ? period : 0, static_cast<int64_t>(opt_.phase_lead * 1e9),
                       static_cast<int64_t>(opt_.phase_max_step * static_cast<double>(period)));

  // The multirate tissue worker: below the physics thread (SCHED_FIFO 80: its 1 kHz ticks preempt
  // a step of several ms) and the DDS threads (60), above everything else — a busy machine must
  // not halve the tissue's rate — and off the physics thread's CPU (sharing it slowed the steps
  // 2–3×).
  if (multirate_) sim_.multirate()->start([cpu = opt_.physics_cpu] { setup_worker_thread(kTissueWorkerPriority, cpu); });

  const int64_t t0 = steady_now_ns();
  int64_t deadline = t0 + period;
  int64_t last_done = t0;
  while (!stop.load(std::memory_order_relaxed) && !shutdown) {
    if (opt_.spin_us > 0) {
      sleep_until(deadline - 1000LL * opt_.spin_us);
      while (steady_now_ns() < deadline) __builtin_ia32_pause();
    } else {
      sleep_until(deadline);
    }
    const int64_t wake = steady_now_ns();
    stats_.wake.record(wake - deadline);
    ++stats_.loops;

    const RunState before = rs;
    handle_controls(rs, steps_pending, shutdown);
    controls_seen += (rs != before);
    const bool do_tick = rs == RunState::Running || steps_pending > 0;
    int64_t shift = 0;  // the phase lock's move of the next deadline
    if (do_tick) {
      if (rs != RunState::Running) --steps_pending;
      frame_due_ = true;  // (a frame published below clears it)
      // The engine's work must end a margin before the next deadline, counted from this tick's
      // scheduled start (a late wake-up eats into it).
      Deadline budget;
      budget.at_ns = opt_.budget ? deadline + stats_.budget_ns : 0;
      // The newest accepted command of each tool (checked by the DDS thread as it submitted it),
      // then the tick — with the multirate worker, each finished tissue step handed off here.
      const TickReport& r =
          multirate_ ? sim_.step_multirate(budget,
                                           [&](const TickReport& step, const State& tissue, int64_t ticks,
                                               const TickReport& tick_report) {
                                             multirate_step_done(step, tissue, ticks, tick_report, rs, win, frame);
                                           })
                     : sim_.step(budget);
      if (multirate_) stats_.tissue_steps_late = sim_.multirate()->steps_late();
      log_inputs();
      shift = follow_commands(lock, sim_.inputs(), deadline);
      if (r.deadline_check >= 0) {  // the cut this tick made, so that a replay makes it too
        SessionEvent se;
        se.tick = static_cast<int64_t>(stats_.ticks);
        se.kind = SessionEvent::Deadline;
        se.deadline_check = r.deadline_check;
        log(se);
      }
      account_tick(r, rs, win);
      // Hand-off to the server's threads, timed under the hand_off stage.
      const int64_t h0 = steady_now_ns();
      if (r.damage_events > 0) publish_damage_events(r);
      if (!multirate_ && m.has_needles) publish_needle_events(r, sim_.state());
      if (!sim_.state().tools.empty()) publish_feedback(r);
      if (!multirate_ && state_wanted.load(std::memory_order_relaxed) && sim_.state().step % opt_.publish_every == 0)
        publish_state_frame(r, sim_.state(), r, ++frame);
      if (sim_.cutter()) service_cuts(r.cut_edges);  // last: a swap retires the workspace r is in
      const int64_t handoff = steady_now_ns() - h0;
      stats_.stage_ns_total[static_cast<int>(Stage::HandOff)] += handoff;
      win.stage_ns[static_cast<int>(Stage::HandOff)] += handoff;
    } else {
      if (sim_.cutter()) service_cuts(0);  // paused: a finished build is still swapped in, a pending Reset done
      // Paused: the state as it is, once, to a subscriber (the multirate worker's tissue state
      // is published by its finished steps only).
      if (frame_due_ && !multirate_ && !reset_pending_ && state_wanted.load(std::memory_order_relaxed))
        publish_state_frame(idle_report_, sim_.state(), idle_report_, ++frame);
    }
    const int64_t done = steady_now_ns();
    const int64_t busy = done - wake;
    stats_.tick.record(busy);
    if (rs == RunState::Running) running_wall += static_cast<double>(done - last_done) * 1e-9;
    last_done = done;

    if (win.recent < kRecentTicks) {
      status->tick_us[win.recent] = static_cast<float>(busy * 1e-3);
      status->wake_us[win.recent] = static_cast<float>((wake - deadline) * 1e-3);
      ++win.recent;
    }
    if (stats_.loops % opt_.status_every == 0)
      publish_status(status, rs, win, static_cast<double>(done - t0) * 1e-9, running_wall, controls_seen);

    // Next deadline: on time → one period later (moved by the phase lock); late → start at once
    // and re-anchor.
    deadline += period + shift;
    if (done > deadline) {
      ++stats_.missed_deadlines;
      deadline = done;
    }
  }
  if (multirate_) sim_.multirate()->stop();
  SessionEvent end;
  end.kind = SessionEvent::End;
  end.tick = static_cast<int64_t>(stats_.ticks);
  log(end);
  stats_.sim_time = sim_.state().time;
  stats_.wall_time = static_cast<double>(steady_now_ns() - t0) * 1e-9;
  stats_.lag = running_wall - sim_.state().time;
  finished.store(true);
  outputs_published.fetch_add(1, std::memory_order_release);
  outputs_published.notify_all();
  feedback_published.fetch_add(1, std::memory_order_release);
  feedback_published.notify_all();
}

}  // namespace stroma
