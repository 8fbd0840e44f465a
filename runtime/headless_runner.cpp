#include "runtime/headless_runner.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <memory>

#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include "engine/cut_swap.hpp"
#include "engine/simulation.hpp"
#include "engine/static_run.hpp"
#include "runtime/session_log.hpp"
#include "runtime/state_io.hpp"
#include "runtime/vtu_writer.hpp"
#include "scene/solver_report.hpp"

namespace stroma {

namespace fs = std::filesystem;

long resolve_steps(const CompiledScenario& sc, const RunOptions& o) {
  const Model& m = *sc.model;
  if (!o.replay.empty()) return static_cast<long>(read_session_log(o.replay, static_cast<int>(m.tools.size())).back().tick);
  if (o.steps) return *o.steps;
  if (o.duration) return std::lround(*o.duration / m.time_step);
  if (sc.spec.run.steps) return *sc.spec.run.steps;
  if (sc.spec.run.duration) return std::lround(*sc.spec.run.duration / m.time_step);
  return m.stepper.integrator == Integrator::Static ? 0 : 1000;
}

namespace {

using Clock = std::chrono::steady_clock;


/// Streams metrics.csv rows; buffered, flushed in large chunks.
class MetricsWriter {
 public:
  MetricsWriter(const std::string& path, const Model& m) : m_(&m), f_(std::fopen(path.c_str(), "w")) {
    if (!f_) throw std::runtime_error(fmt::format("cannot write '{}'", path));
    buf_ = "step,time,step_ms,cg_iterations,cg_residual,kinetic_energy,elastic_energy,"
           "external_potential,total_energy,status";
    for (int s = 0; s < kStageCount; ++s) buf_ += fmt::format(",{}_ms", stage_name(static_cast<Stage>(s)));
    for (const ProbeModel& p : m.probes) buf_ += fmt::format(",{0}_dx,{0}_dy,{0}_dz", p.name);
    for (const ToolSpec& t : m.tools)
      buf_ += fmt::format(",{0}_fx,{0}_fy,{0}_fz,{0}_contacts,{0}_feedback_fx,{0}_feedback_fy,{0}_feedback_fz", t.name);
    if (m.has_damage) buf_ += ",elements_warned,elements_damaged,elements_ruptured";
    for (const RigidBodyModel& b : m.rigid_bodies) {
      buf_ += fmt::format(",{0}_x,{0}_y,{0}_z,{0}_qw,{0}_qx,{0}_qy,{0}_qz,{0}_vx,{0}_vy,{0}_vz,{0}_contacts,{0}_fx,{0}_fy,{0}_fz",
                          b.name);
      if (b.shape == RigidShape::Needle)  // its insertion (rigid/needle_track.hpp)
        buf_ += fmt::format(",{0}_phase,{0}_inserted_length,{0}_track_points,{0}_tip_force,{0}_friction_force,{0}_punctures",
                            b.name);
    }
    buf_ += ",over_budget,degradation,error_energy,error_position,energy_removed";
    if (m.cutting) buf_ += ",cut_edges,topology_version,elements_split,nodes_created,faces_created,cut_area";
    buf_ += '\n';
  }
  /// The model rows are written against from now on (a cut model swapped in: same columns).
  void set_model(const Model& m) { m_ = &m; }
  ~MetricsWriter() {
    flush();
    std::fclose(f_);
  }
  /// One row: the state after a tick (or an equilibrium) and what the tick reported.
  void row(const State& s, TimeStepper& stepper, double ms, int iterations, double residual, int status,
           const TickReport& r) {
    const double ke = stepper.kinetic_energy(s.tissue);
    const double ee = stepper.elastic_energy(s.tissue);
    const double pe = stepper.external_potential(s.tissue);
    auto out = std::back_inserter(buf_);
    fmt::format_to(out, "{},{:.9g},{:.6f},{},{:.3e},{:.9e},{:.9e},{:.9e},{:.9e},{}", s.step, s.time, ms, iterations,
                   residual, ke, ee, pe, ke + ee + pe, status);
    for (int st = 0; st < kStageCount; ++st) fmt::format_to(out, ",{:.6f}", static_cast<double>(r.stage_ns[st]) * 1e-6);
    for (const ProbeModel& p : m_->probes) {
      const Vec3 d = probe_displacement(*m_, s, p);
      fmt::format_to(out, ",{:.12e},{:.12e},{:.12e}", d[0], d[1], d[2]);
    }
    for (const ToolOutput& t : r.tools)
      fmt::format_to(out, ",{:.9e},{:.9e},{:.9e},{},{:.9e},{:.9e},{:.9e}", t.force[0], t.force[1], t.force[2], t.contacts,
                     t.feedback.force[0], t.feedback.force[1], t.feedback.force[2]);
    if (m_->has_damage) fmt::format_to(out, ",{},{},{}", s.damage_count[1], s.damage_count[2], s.damage_count[3]);
    for (size_t k = 0; k < s.rigid.size(); ++k) {
      const RigidState& b = s.rigid[k];
      const RigidContactOutput c = k < r.rigid_contact.size() ? r.rigid_contact[k] : RigidContactOutput{};
      fmt::format_to(out, ",{:.12e},{:.12e},{:.12e},{:.12e},{:.12e},{:.12e},{:.12e},{:.9e},{:.9e},{:.9e},{},{:.9e},{:.9e},{:.9e}",
                     b.x[0], b.x[1], b.x[2], b.q[0], b.q[1], b.q[2], b.q[3], b.v[0], b.v[1], b.v[2], c.contacts,
                     c.force[0], c.force[1], c.force[2]);
      if (m_->rigid_bodies[k].shape == RigidShape::Needle) {
        const NeedleOutput n = k < r.needles.size() ? r.needles[k] : NeedleOutput{};
        fmt::format_to(out, ",{},{:.9e},{},{:.9e},{:.9e},{}", needle_phase_name(s.needles[k].phase), n.inserted_length,
                       s.needles[k].count, n.tip_force, n.friction_force, s.needles[k].punctures);
      }
    }
    fmt::format_to(out, ",{},{},{:.3e},{:.3e},{:.3e}", r.over_budget ? 1 : 0, degradation_name(r.degradation),
                   r.solve.error_energy, r.solve.error_position, r.energy_removed);
    if (m_->cutting) {
      const CutStats& c = m_->cut_stats;
      fmt::format_to(out, ",{},{},{},{},{},{:.6e}", r.cut_edges, m_->topology_version, c.elements_split,
                     c.nodes_created, c.faces_created, c.cut_area);
    }
    buf_ += '\n';
    if (buf_.size() > (1 << 20)) flush();
  }
  void flush() {
    if (!buf_.empty() && std::fwrite(buf_.data(), 1, buf_.size(), f_) != buf_.size())
      throw std::runtime_error("cannot write metrics.csv");
    buf_.clear();
  }

 private:
  const Model* m_;
  std::FILE* f_;
  std::string buf_;
};

/// What a run accumulates while it goes.
struct RunLog {
  std::vector<double> step_ms;
  std::vector<double> step_ms_without_refresh_waits;
  std::array<double, kStageCount> stage_total{};
  long cg_sum = 0;
  double io_ms = 0;
  std::vector<std::pair<double, std::string>> series;  ///< (time, file) of --vtu-every frames
  /// The last tick cut and swapped the model in: its tool outputs were kept (RunResult) before
  /// its workspace was retired.
  bool last_tick_swapped = false;
  void add_stages(const TickReport& r) {
    for (int st = 0; st < kStageCount; ++st) stage_total[st] += static_cast<double>(r.stage_ns[st]) * 1e-6;
  }
};

double ms_since(Clock::time_point t0) { return std::chrono::duration<double, std::milli>(Clock::now() - t0).count(); }

/// Everything a run writes, in one place.
class RunOutputs {
 public:
  RunOutputs(const CompiledScenario& sc, const RunOptions& o, RunLog& log)
      : sc_(sc), o_(o), log_(log), model_(sc.model.get()) {
    if (o.out_dir.empty()) return;
    const auto t0 = Clock::now();
    fs::create_directories(o.out_dir);
    if (o.metrics) metrics = std::make_unique<MetricsWriter>((fs::path(o.out_dir) / "metrics.csv").string(), *sc.model);
    log_.io_ms += ms_since(t0);
  }
  std::unique_ptr<MetricsWriter> metrics;
  bool writing() const { return !o_.out_dir.empty(); }
  /// Outputs follow the model the run is on (a cut model swapped in).
  void set_model(const Model& m) {
    model_ = &m;
    if (metrics) metrics->set_model(m);
  }
  void frame(const State& s, long k) {
    if (!writing() || o_.vtu_every <= 0 || k % o_.vtu_every != 0) return;
    const auto t0 = Clock::now();
    const std::string name = fmt::format("state_{:06d}.vtu", k);
    write_vtu((fs::path(o_.out_dir) / name).string(), *model_, s);
    log_.series.emplace_back(s.time, name);
    log_.io_ms += ms_since(t0);
  }
  /// Final files and summary.json. A failed run gets no final state (stale ones are removed).
  void finish(RunResult& res);

 private:
  const CompiledScenario& sc_;
  const RunOptions& o_;
  RunLog& log_;
  const Model* model_;
};

void RunOutputs::finish(RunResult& res) {
  if (!writing()) return;
  const Model& m = *model_;
  const fs::path dir(o_.out_dir);
  const auto t0 = Clock::now();
  metrics.reset();
  const State& s = res.final_state;
  for (const char* name : {"final.vtu", "final_state.csv"}) fs::remove(dir / name);
  if (res.ok) {
    write_vtu((dir / "final.vtu").string(), m, s);
    write_state_csv((dir / "final_state.csv").string(), s);
  }
  if (!log_.series.empty()) write_pvd((dir / "series.pvd").string(), log_.series);
  log_.io_ms += ms_since(t0);
  res.io_ms_total = log_.io_ms;

  nlohmann::ordered_json j;
  j["scenario"] = sc_.spec.name;
  j["scenario_file"] = sc_.spec.file;
  j["status"] = res.ok ? "ok" : "failed";
  if (!res.ok) j["failure"] = res.failure;
  j["steps"] = res.steps;
  j["time_step"] = m.time_step;
  j["sim_time"] = res.sim_time;
  j["wall_seconds"] = res.wall_seconds;
  j["nodes"] = m.fem.num_nodes;
  j["elements"] = m.fem.elements.size();
  j["step_ms"] = {{"p50", res.step_ms.p50}, {"p99", res.step_ms.p99}, {"max", res.step_ms.max}, {"mean", res.step_ms.mean}};
  j["cg_iterations"] = {{"mean", res.cg_iterations_mean}, {"max", res.cg_iterations_max}};
  j["solver"] = solver_json(sc_);
  if (m.stepper.integrator == Integrator::ImplicitEuler && m.stepper.linear_solver == LinearSolverKind::CG)
    // The requested accuracy, and where it was not reached (capped or budget-cut solves).
    j["solver"]["tolerance_reached"] = {{"ticks", res.steps - res.ticks_not_converged},
                                        {"of", res.steps},
                                        {"residual_max", res.residual_max}};
  j["ticks_not_converged"] = res.ticks_not_converged;
  j["ticks_non_finite"] = res.ticks_non_finite;
  j["ticks_recovered"] = res.ticks_recovered;
  j["max_substeps"] = res.max_substeps;
  j["time_budget"] = m.time_budget > 0 ? nlohmann::ordered_json(m.time_budget) : nlohmann::ordered_json("none");
  j["ticks_over_budget"] = res.ticks_over_budget;
  j["ticks_degraded"] = res.ticks_degraded;
  if (!m.fem.rods.empty())  // docs/THREAD.md, "Contact": the continuous check after the step
    j["thread_contact"] = {{"missed_springs_added", res.thread_missed}, {"checks_skipped", res.thread_unchecked}};
  if (m.stepper.preconditioner == Preconditioner::WarpedCholesky) {
    j["warped_preconditioner"] = {{"fallbacks", res.preconditioner_fallbacks},
                                  {"refreshes", res.preconditioner_refreshes}};
    // Headless swaps refreshed factors on a fixed schedule and waits for a late worker (serve
    // never waits): the ticks' times without those waits are what serve would see.
    if (res.preconditioner_refreshes > 0) {
      const TimingSummary& t = res.step_ms_without_refresh_waits;
      j["warped_preconditioner"]["refresh_factor_ms"] = {{"mean", res.refresh_factor_ms_mean},
                                                         {"max", res.refresh_factor_ms_max}};
      j["warped_preconditioner"]["refresh_waits"] = {
          {"ticks", res.refresh_wait_ticks}, {"total_ms", res.refresh_wait_ms_total}, {"max_ms", res.refresh_wait_ms_max}};
      j["warped_preconditioner"]["step_ms_without_refresh_waits"] = {{"p50", t.p50}, {"p99", t.p99}, {"max", t.max}, {"mean", t.mean}};
    }
  }
  if (!m.tools.empty())  // every scripted command, checked as a client's (engine/tool_commands.hpp)
    j["commands"] = {{"accepted", res.commands_accepted}, {"clamped", res.commands_clamped},
                     {"rejected", res.commands_rejected}};
  j["energy_guard"] = {{"ticks_limited", res.ticks_energy_limited}, {"energy_removed", res.energy_removed}};
  j["solve_error"] = {{"residual_max", res.residual_max},
                      {"energy_max", res.error_energy_max},
                      {"position_max", res.error_position_max}};
  if (m.stepper.integrator == Integrator::Static)
    j["static"] = {{"newton_iterations", res.newton_iterations},
                   {"relative_residual", res.static_residual},
                   {"converged", res.static_converged},
                   {"load_increments", res.static_increments}};
  nlohmann::ordered_json stages;
  const double n = static_cast<double>(std::max<size_t>(log_.step_ms.size(), 1));
  for (int st = 0; st < kStageCount; ++st)
    stages[std::string(stage_name(static_cast<Stage>(st)))] = {{"total_ms", log_.stage_total[st]},
                                                              {"per_step_ms", log_.stage_total[st] / n}};
  stages["io"] = {{"total_ms", log_.io_ms}};
  j["stages"] = stages;
  nlohmann::ordered_json probes = nlohmann::ordered_json::object();
  for (const ProbeModel& p : m.probes) {
    const Vec3 pos = probe_position(m, s, p);
    const Vec3 d = probe_displacement(m, s, p);
    probes[p.name] = {{"position", {pos[0], pos[1], pos[2]}}, {"displacement", {d[0], d[1], d[2]}}};
  }
  j["probes"] = probes;
  nlohmann::ordered_json tools = nlohmann::ordered_json::object();
  for (size_t t = 0; t < m.tools.size() && t < res.final_tools.size(); ++t) {
    const ToolOutput& o = res.final_tools[t];
    const ToolFeedback& fb = o.feedback;
    tools[m.tools[t].name] = {{"force", {o.force[0], o.force[1], o.force[2]}},
                              {"torque", {o.torque[0], o.torque[1], o.torque[2]}},
                              {"contacts", o.contacts},
                              {"feedback_force", {fb.force[0], fb.force[1], fb.force[2]}},
                              {"feedback_clamped", fb.clamped}};
  }
  j["tools"] = tools;
  if (!m.rigid_bodies.empty()) {
    nlohmann::ordered_json rigid = nlohmann::ordered_json::object();
    for (size_t k = 0; k < m.rigid_bodies.size(); ++k) {
      const RigidState& r = s.rigid[k];
      nlohmann::ordered_json b = {{"position", {r.x[0], r.x[1], r.x[2]}},
                                  {"orientation", {r.q[0], r.q[1], r.q[2], r.q[3]}},
                                  {"velocity", {r.v[0], r.v[1], r.v[2]}},
                                  {"angular_velocity", {r.w[0], r.w[1], r.w[2]}}};
      if (k < res.final_rigid.size()) {
        const RigidContactOutput& c = res.final_rigid[k];
        b["contacts"] = c.contacts;
        b["contact_force"] = {c.force[0], c.force[1], c.force[2]};
      }
      if (m.rigid_bodies[k].shape == RigidShape::Needle) {
        const NeedleState& n = s.needles[k];
        double inserted = 0;
        for (int32_t i = 0; i + 1 < n.count; ++i) inserted += n.track[size_t(i + 1)].s - n.track[size_t(i)].s;
        b["needle"] = {{"phase", std::string(needle_phase_name(n.phase))},
                       {"track_points", n.count},
                       {"punctures", n.punctures},
                       {"track_length", inserted}};
      }
      rigid[m.rigid_bodies[k].name] = b;
    }
    j["rigid_bodies"] = rigid;
  }
  if (m.cutting) {
    const CutStats& c = m.cut_stats;
    j["cutting"] = {{"edges_cut", c.edges_cut},
                    {"elements_split", c.elements_split},
                    {"nodes_created", c.nodes_created},
                    {"faces_created", c.faces_created},
                    {"cut_area", c.cut_area},
                    {"topology_version", m.topology_version},
                    {"topology_swaps", res.topology_swaps},
                    {"build_ms", {{"total", res.cut_build_ms_total}, {"max", res.cut_build_ms_max}}}};
  }
  if (m.has_damage)
    j["damage"] = {{"elements_warned", s.damage_count[1]},
                   {"elements_damaged", s.damage_count[2]},
                   {"elements_ruptured", s.damage_count[3]},
                   {"first_onset_time", s.first_damage_time}};
  std::ofstream f(dir / "summary.json");
  f << j.dump(2) << '\n';
  if (!f) throw std::runtime_error(fmt::format("cannot write '{}'", (dir / "summary.json").string()));
}

/// Each scripted tool's pose at time t through the commands port, as a dynamic run's (checked
/// against the tool's limits, clamped or refused by its on_invalid, counted): `poses` gets each
/// accepted (or clamped) command; a refused one, or a tool without a script, keeps its pose.
void scripted_poses(const CompiledScenario& sc, Simulation& sim, double t, std::vector<ToolPose>& poses) {
  sim.submit_scripts(sc.tool_scripts, t);
  sim.take_commands();
  for (const ToolInput& in : sim.inputs()) poses[static_cast<size_t>(in.tool)] = in.pose;
}

/// Static run: the equilibrium at t = 0 from rest, then (quasi-static) one per tick time.
void run_static(const CompiledScenario& sc, const RunOptions& o, long steps, Simulation& sim, RunOutputs& out,
                RunLog& log, RunResult& res) {
  const Model& m = *sc.model;
  State& s = sim.state();
  TickWorkspace& w = sim.workspace();
  for (size_t t = 0; t < m.tools.size(); ++t)
    if (!sc.tool_scripts[t].keys.empty()) {
      s.tools[t].last_command_time = 0;
      s.tools[t].active = true;
    }
  std::vector<ToolPose> poses(s.tools.size());
  for (size_t t = 0; t < poses.size(); ++t) poses[t] = s.tools[t].pose;
  scripted_poses(sc, sim, 0.0, poses);
  StaticParameters from{0.0, 0.0, poses};
  StaticParameters to{1.0, 1.0, from.tool_poses};
  res.static_converged = true;
  for (long k = 0; k <= steps; ++k) {
    if (k > 0) {
      from = to;
      scripted_poses(sc, sim, static_cast<double>(k) * m.time_step, to.tool_poses);
    }
    const auto t0 = Clock::now();
    const StaticOutcome so = solve_equilibrium(m, s, w, from, to);
    const double ms = ms_since(t0);
    TickReport& r = w.report;
    r.stage_ns.fill(0);
    r.stage_ns[static_cast<int>(Stage::Collide)] = so.collide_ns;
    r.stage_ns[static_cast<int>(Stage::Solve)] = so.solve_ns;
    log.step_ms.push_back(ms);
    log.step_ms_without_refresh_waits.push_back(ms);
    log.add_stages(r);
    log.cg_sum += so.linear_iterations;
    res.cg_iterations_max = std::max(res.cg_iterations_max, so.linear_iterations);
    res.newton_iterations += so.newton_iterations;
    res.static_residual = so.relative_residual;
    res.static_increments += so.increments;
    if (k > 0) {
      s.step = k;
      s.time = static_cast<double>(k) * m.time_step;
    }
    if (out.metrics) {
      const auto t1 = Clock::now();
      out.metrics->row(s, w.stepper(), ms, so.linear_iterations, so.relative_residual, so.converged ? 0 : 1, r);
      log.io_ms += ms_since(t1);
    }
    if (!so.converged) {
      res.static_converged = false;
      res.ok = false;
      if (so.roundoff_stall)
        res.failure = fmt::format(
            "static solve did not converge at t = {:g} s: Newton stalled at relative residual {:.3g} (best reached; "
            "{} iterations without halving it) — static_tolerance {:.3g} is below what round-off allows for this "
            "problem (stiffness, near-incompressibility, mesh): set static_tolerance to about {:.1g} or more",
            static_cast<double>(k) * m.time_step, so.best_residual, kStaticStallIterations,
            m.stepper.static_tolerance, 10.0 * so.best_residual);
      else
        res.failure = fmt::format(
            "static solve did not converge at t = {:g} s: reached {:.4g} of the load/tool path in {} increments "
            "(smallest tried {:.3g}); relative residual {:.3g} after {} Newton iterations",
            static_cast<double>(k) * m.time_step, so.reached, so.increments, kMinStaticIncrement, so.relative_residual,
            so.newton_iterations);
      spdlog::error("{}", res.failure);
      break;
    }
    if (so.increments > 1)
      spdlog::debug("equilibrium {} reached in {} load increments ({} attempts)", k, so.increments, so.attempts);
    out.frame(s, k);
  }
  res.steps = s.step;
}

/// Dynamic run: ticks with the tools' scripted (or replayed) commands, through the one
/// Simulation every front end drives (engine/simulation.hpp): scripted poses are submitted as a
/// client's would be (checked and counted), a replayed session's are applied as recorded.
void run_dynamic(const CompiledScenario& sc, const RunOptions& o, long steps, Simulation& sim, RunOutputs& out,
                 RunLog& log, RunResult& res) {
  const Model& m = *sc.model;  // the scenario's (cut models keep its tools and time step)
  State& s = sim.state();
  // Tool inputs: a replayed session, else each scripted tool sampled at the tick's start time.
  std::vector<SessionEvent> replay;
  if (!o.replay.empty()) {
    bool interrupted = false;
    replay = read_session_log(o.replay, static_cast<int>(m.tools.size()), &interrupted);
    if (interrupted)
      spdlog::warn("{}: no 'end' line (the server was stopped without closing its log): replaying to its last "
                   "checkpoint, tick {}",
                   o.replay, replay.back().tick);
  }
  size_t next_event = 0;
  std::vector<double> cut_snapshot;  // replay: the edge cuts of the last recorded snapshot
  std::vector<ToolInput> recorded;   // replay: this tick's commands as the server applied them
  recorded.reserve(m.tools.size() + 16);
  const auto wall0 = Clock::now();
  auto last_progress = wall0;
  out.frame(s, 0);
  for (long k = 0; k < steps; ++k) {
    recorded.clear();
    Deadline deadline;  // none given: the scenario's time_budget, if any
    if (!o.replay.empty()) {
      deadline.expire_at_check = std::numeric_limits<int64_t>::max();  // the live ticks' cuts only
      for (; next_event < replay.size() && replay[next_event].tick == k; ++next_event) {
        const SessionEvent& e = replay[next_event];
        if (e.kind == SessionEvent::Reset) {
          const bool was_cut = sim.model_ptr() != sim.scenario_model();
          sim.reset();  // back to the uncut scenario
          if (was_cut) out.set_model(sim.model());
          recorded.clear();  // commands before a reset in the same tick were overwritten
        } else if (e.kind == SessionEvent::Tool) {
          recorded.push_back(e.input);
        } else if (e.kind == SessionEvent::Deadline) {
          deadline.expire_at_check = e.deadline_check;
        } else if (e.kind == SessionEvent::CutSnapshot) {
          cut_snapshot = s.edge_cut;  // what the live server's builder was handed at this tick
        } else if (e.kind == SessionEvent::Topology) {
          // The live server swapped in the model built from the last snapshot here: so does the
          // replay (built now, synchronously — the same pure function of the same edge cuts).
          if (sim.swap_recorded(cut_snapshot)) {
            out.set_model(sim.model());
          } else {
            spdlog::warn("{}: line {}: the recorded topology swap changed nothing here (was the session recorded "
                         "with this scenario?)",
                         o.replay, e.line);
          }
        }
      }
    } else {
      sim.submit_scripts(sc.tool_scripts);
    }
    log.last_tick_swapped = false;
    const TickReport& r = sim.step(deadline, recorded.data(), static_cast<int>(recorded.size()));
    TickWorkspace& w = sim.workspace();
    const double ms = static_cast<double>(r.total_ns) * 1e-6;
    log.step_ms.push_back(ms);
    const double waited_ms = static_cast<double>(r.refresh_wait_ns) * 1e-6;
    log.step_ms_without_refresh_waits.push_back(ms - waited_ms);
    if (r.refresh_wait_ns > 0) {
      ++res.refresh_wait_ticks;
      res.refresh_wait_ms_total += waited_ms;
      res.refresh_wait_ms_max = std::max(res.refresh_wait_ms_max, waited_ms);
    }
    log.add_stages(r);
    log.cg_sum += r.solve.iterations;
    res.cg_iterations_max = std::max(res.cg_iterations_max, r.solve.iterations);
    if (r.status == TickStatus::SolverNotConverged) ++res.ticks_not_converged;
    if (r.status == TickStatus::Recovered) ++res.ticks_recovered;
    res.max_substeps = std::max(res.max_substeps, r.substeps);
    res.ticks_over_budget += r.over_budget;
    res.ticks_degraded += r.degradation != Degradation::None;
    res.thread_missed += r.thread_contact.missed;
    res.thread_unchecked += r.thread_contact.unchecked;
    res.preconditioner_fallbacks += r.solve.preconditioner_fallback;
    res.residual_max = std::max(res.residual_max, r.solve.relative_residual);
    res.error_energy_max = std::max(res.error_energy_max, r.solve.error_energy);
    res.error_position_max = std::max(res.error_position_max, r.solve.error_position);
    res.ticks_energy_limited += r.energy_limit != EnergyLimit::None;
    res.energy_removed += r.energy_removed;
    if (r.status == TickStatus::NonFinite) {
      ++res.ticks_non_finite;
      res.ok = false;
      res.failure = fmt::format("tick {} (t = {:g} s) could not advance: non-finite or diverging in every sub-step "
                                "division down to {}; the run stopped there",
                                k, s.time, kMaxSubsteps);
      spdlog::error("{}", res.failure);
      break;
    }
    if (out.metrics) {
      const auto t0 = Clock::now();
      out.metrics->row(s, w.stepper(), ms, r.solve.iterations, r.solve.relative_residual, static_cast<int>(r.status), r);
      log.io_ms += ms_since(t0);
    }
    if (r.cut_edges > 0 && o.replay.empty()) {
      // The blade cut edges: the cut stage swaps the topology in before the next tick (headless:
      // built synchronously, so a run is a function of its inputs; `serve` builds off the thread,
      // and its recorded swaps are replayed where they happened, above).
      const CutStageResult c = sim.cut(r.cut_edges);
      if (c.swapped) {
        res.final_tools = r.tools;  // (r stays readable until the next step)
        res.final_rigid = r.rigid_contact;
        log.last_tick_swapped = true;
        out.set_model(sim.model());
        spdlog::debug("tick {}: topology {} swapped in ({} elements split, {} nodes created, cut area {:.3g} m^2; "
                      "built in {:.2f} ms)",
                      k, sim.model().topology_version, sim.model().cut_stats.elements_split,
                      sim.model().cut_stats.nodes_created, sim.model().cut_stats.cut_area, c.build_ms);
      }
    }
    out.frame(s, k + 1);
    const auto now = Clock::now();
    if (o.progress && now - last_progress > std::chrono::seconds(2)) {
      last_progress = now;
      const double el = std::chrono::duration<double>(now - wall0).count();
      const double eta = el / static_cast<double>(k + 1) * static_cast<double>(steps - k - 1);
      spdlog::info("step {}/{} ({:.0f}%), sim time {:.4g} s, {:.3f} ms/step, ETA {:.0f} s", k + 1, steps,
                   100.0 * (k + 1) / steps, s.time, el * 1e3 / (k + 1), eta);
    }
  }
  res.preconditioner_refreshes += sim.retired_refreshes();
  res.topology_swaps = sim.topology_swaps();
  res.cut_build_ms_total = sim.cut_build_ms_total();
  res.cut_build_ms_max = sim.cut_build_ms_max();
  res.steps = s.step;
}

}  // namespace

RunResult run_headless(const CompiledScenario& sc, const RunOptions& o) {
  const Model& m = *sc.model;
  RunResult res;
  Simulation sim(sc.model);  // the model the run is on (cut models swap in), its state and workspace
  State& s = sim.state();
  const long steps = resolve_steps(sc, o);
  RunLog log;
  log.step_ms.reserve(static_cast<size_t>(std::max(0L, steps)) + 1);
  log.step_ms_without_refresh_waits.reserve(log.step_ms.capacity());
  RunOutputs out(sc, o, log);
  const auto wall0 = Clock::now();
  if (m.stepper.integrator == Integrator::Static) run_static(sc, o, steps, sim, out, log, res);
  else run_dynamic(sc, o, steps, sim, out, log, res);
  // Every scripted command of either kind of run, checked as a client's (engine/tool_commands.hpp).
  const CommandCounters& c = sim.commands().counters();
  res.commands_accepted = c.accepted.load();
  res.commands_clamped = c.clamped.load();
  res.commands_rejected = c.rejected.load();
  TickWorkspace& w = sim.workspace();
  res.final_model = sim.model_ptr();
  res.wall_seconds = std::chrono::duration<double>(Clock::now() - wall0).count();
  res.sim_time = s.time;
  res.step_ms = summarize(log.step_ms);
  res.step_ms_without_refresh_waits = summarize(log.step_ms_without_refresh_waits);
  res.cg_iterations_mean =
      log.step_ms.empty() ? 0.0 : static_cast<double>(log.cg_sum) / static_cast<double>(log.step_ms.size());
  for (int st = 0; st < kStageCount; ++st)
    res.stage_ms_total[std::string(stage_name(static_cast<Stage>(st)))] = log.stage_total[st];
  res.preconditioner_refreshes += w.stepper().preconditioner_refreshes();  // (+ the retired workspaces')
  if (const int64_t k = w.stepper().preconditioner_refreshes(); k > 0) {
    res.refresh_factor_ms_mean = 1e-6 * static_cast<double>(w.stepper().preconditioner_refresh_ns_total()) / static_cast<double>(k);
    res.refresh_factor_ms_max = 1e-6 * static_cast<double>(w.stepper().preconditioner_refresh_ns_max());
  }
  // The last tick's tool outputs: its workspace's, unless the tick that ended the run swapped
  // the model (then they were kept before the swap).
  if (!log.last_tick_swapped) res.final_tools = w.report.tools, res.final_rigid = w.report.rigid_contact;
  res.final_state = std::move(s);
  out.finish(res);
  return res;
}

}  // namespace stroma
