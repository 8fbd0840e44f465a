#include "engine/headless_runner.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>

#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include "engine/session_log.hpp"
#include "engine/state_io.hpp"
#include "engine/vtu_writer.hpp"

namespace stroma {

namespace fs = std::filesystem;

long resolve_steps(const Model& m, const RunOptions& o) {
  if (m.stepper.integrator == Integrator::Static) return 0;
  if (!o.replay.empty()) return static_cast<long>(read_session_log(o.replay).back().tick);
  if (o.steps) return *o.steps;
  if (o.duration) return std::lround(*o.duration / m.time_step);
  if (m.spec.run.steps) return *m.spec.run.steps;
  if (m.spec.run.duration) return std::lround(*m.spec.run.duration / m.time_step);
  return 1000;
}

namespace {

using Clock = std::chrono::steady_clock;

TimingSummary summarize(std::vector<double> v) {
  TimingSummary t;
  if (v.empty()) return t;
  double sum = 0;
  for (double x : v) sum += x;
  t.mean = sum / static_cast<double>(v.size());
  auto pct = [&](double q) {
    const size_t k = std::min(v.size() - 1, static_cast<size_t>(std::ceil(q * v.size())) - (q > 0 ? 1 : 0));
    std::nth_element(v.begin(), v.begin() + k, v.end());
    return v[k];
  };
  t.p50 = pct(0.5);
  t.p99 = pct(0.99);
  t.max = *std::max_element(v.begin(), v.end());
  return t;
}

/// Streams metrics.csv rows; buffered, flushed in large chunks.
class MetricsWriter {
 public:
  MetricsWriter(const std::string& path, const Model& m) : f_(std::fopen(path.c_str(), "w")) {
    if (!f_) throw std::runtime_error(fmt::format("cannot write '{}'", path));
    buf_ = "step,time,step_ms,cg_iterations,cg_residual,kinetic_energy,elastic_energy,"
           "external_potential,total_energy,status";
    for (int s = 0; s < kStageCount; ++s) buf_ += fmt::format(",{}_ms", stage_name(static_cast<Stage>(s)));
    for (const ProbeModel& p : m.probes) buf_ += fmt::format(",{0}_dx,{0}_dy,{0}_dz", p.name);
    for (const ToolSpec& t : m.tools) buf_ += fmt::format(",{0}_fx,{0}_fy,{0}_fz,{0}_contacts", t.name);
    if (m.has_damage) buf_ += ",elements_warned,elements_damaged,elements_ruptured";
    buf_ += '\n';
  }
  ~MetricsWriter() {
    flush();
    std::fclose(f_);
  }
  std::string& buf() { return buf_; }
  void maybe_flush() {
    if (buf_.size() > (1 << 20)) flush();
  }
  void flush() {
    if (!buf_.empty() && std::fwrite(buf_.data(), 1, buf_.size(), f_) != buf_.size())
      throw std::runtime_error("cannot write metrics.csv");
    buf_.clear();
  }

 private:
  std::FILE* f_;
  std::string buf_;
};

}  // namespace

RunResult run_headless(const Model& m, const RunOptions& o) {
  RunResult res;
  State s = State::initial(m);
  TickWorkspace w(m);
  TimeStepper& stepper = w.stepper();
  const bool write = !o.out_dir.empty();
  const long steps = resolve_steps(m, o);
  // Tool inputs: a replayed session, else each scripted tool sampled at the tick's start time.
  std::vector<SessionEvent> replay;
  if (!o.replay.empty()) replay = read_session_log(o.replay);
  size_t next_event = 0;
  std::vector<ToolInput> inputs;
  inputs.reserve(m.tools.size() + 16);
  std::unique_ptr<MetricsWriter> metrics;
  std::vector<std::pair<double, std::string>> series;
  double io_ms = 0;
  auto io_begin = Clock::now();
  if (write) {
    fs::create_directories(o.out_dir);
    if (o.metrics) metrics = std::make_unique<MetricsWriter>((fs::path(o.out_dir) / "metrics.csv").string(), m);
  }
  auto add_io = [&](Clock::time_point t0) {
    io_ms += std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
  };
  add_io(io_begin);
  auto write_frame = [&](long k) {
    const auto t0 = Clock::now();
    const std::string name = fmt::format("state_{:06d}.vtu", k);
    write_vtu((fs::path(o.out_dir) / name).string(), m, s);
    series.emplace_back(s.time, name);
    add_io(t0);
  };

  std::vector<double> step_ms;
  step_ms.reserve(static_cast<size_t>(std::max(0L, steps)));
  std::array<double, kStageCount> stage_total{};
  long cg_sum = 0;
  const auto wall0 = Clock::now();
  auto last_progress = wall0;

  if (m.stepper.integrator == Integrator::Static) {
    const auto t0 = Clock::now();
    // Tools hold their scripted pose at t = 0; contacts are recomputed every Newton iteration.
    for (size_t t = 0; t < m.tools.size(); ++t)
      if (!m.tool_scripts[t].keys.empty()) {
        s.tools[t].pose = m.tool_scripts[t].sample(0.0);
        s.tools[t].last_command_time = 0;
        s.tools[t].active = true;
      }
    std::function<void(const TissueState&)> contacts;
    if (m.has_contact) contacts = [&](const TissueState&) { collide(m, s, w); };
    const StaticResult sr = stepper.solve_static(s.tissue, contacts);
    const double ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
    step_ms.push_back(ms);
    stage_total[static_cast<int>(Stage::Solve)] = ms;
    res.newton_iterations = sr.newton_iterations;
    res.static_residual = sr.relative_residual;
    res.static_converged = sr.converged;
    cg_sum = sr.linear_iterations;
    res.cg_iterations_max = sr.linear_iterations;
    if (!sr.converged)
      spdlog::warn("static solve did not converge: relative residual {:.3g} after {} Newton iterations",
                   sr.relative_residual, sr.newton_iterations);
  } else {
    if (write && o.vtu_every > 0) write_frame(0);
    for (long k = 0; k < steps; ++k) {
      inputs.clear();
      if (!o.replay.empty()) {
        for (; next_event < replay.size() && replay[next_event].tick == k; ++next_event) {
          const SessionEvent& e = replay[next_event];
          if (e.kind == SessionEvent::Reset) {
            const State init = State::initial(m);
            s = init;
            inputs.clear();  // commands before a reset in the same tick were overwritten
          } else if (e.kind == SessionEvent::Tool) {
            inputs.push_back(e.input);
          }
        }
      } else {
        for (size_t t = 0; t < m.tools.size(); ++t)
          if (!m.tool_scripts[t].keys.empty())
            inputs.push_back(ToolInput{static_cast<int32_t>(t), static_cast<uint64_t>(k + 1), 0,
                                       m.tool_scripts[t].sample(s.time)});
      }
      const TickReport r = tick(m, s, w, inputs.data(), static_cast<int>(inputs.size()));
      const double ms = static_cast<double>(r.total_ns) * 1e-6;
      step_ms.push_back(ms);
      for (int st = 0; st < kStageCount; ++st) stage_total[st] += static_cast<double>(r.stage_ns[st]) * 1e-6;
      cg_sum += r.solve.iterations;
      res.cg_iterations_max = std::max(res.cg_iterations_max, r.solve.iterations);
      if (r.status == TickStatus::SolverNotConverged) ++res.ticks_not_converged;
      if (r.status == TickStatus::Recovered) ++res.ticks_recovered;
      res.max_substeps = std::max(res.max_substeps, r.substeps);
      if (r.status == TickStatus::NonFinite) {
        ++res.ticks_non_finite;
        spdlog::error("tick {}: non-finite values in the solve; stopping the run", k);
        break;
      }
      if (metrics) {
        const auto t0 = Clock::now();
        const double ke = stepper.kinetic_energy(s.tissue);
        const double ee = stepper.elastic_energy(s.tissue);
        const double pe = stepper.external_potential(s.tissue);
        auto& b = metrics->buf();
        fmt::format_to(std::back_inserter(b), "{},{:.9g},{:.6f},{},{:.3e},{:.9e},{:.9e},{:.9e},{:.9e},{}",
                       s.step, s.time, ms, r.solve.iterations, r.solve.relative_residual, ke, ee, pe,
                       ke + ee + pe, static_cast<int>(r.status));
        for (int st = 0; st < kStageCount; ++st)
          fmt::format_to(std::back_inserter(b), ",{:.6f}", static_cast<double>(r.stage_ns[st]) * 1e-6);
        for (const ProbeModel& p : m.probes) {
          const Vec3 d = probe_displacement(m, s, p);
          fmt::format_to(std::back_inserter(b), ",{:.12e},{:.12e},{:.12e}", d[0], d[1], d[2]);
        }
        for (const ToolState& t : s.tools)
          fmt::format_to(std::back_inserter(b), ",{:.9e},{:.9e},{:.9e},{}", t.force[0], t.force[1], t.force[2], t.contacts);
        if (m.has_damage)
          fmt::format_to(std::back_inserter(b), ",{},{},{}", s.damage_count[1], s.damage_count[2], s.damage_count[3]);
        b += '\n';
        metrics->maybe_flush();
        add_io(t0);
      }
      if (write && o.vtu_every > 0 && (k + 1) % o.vtu_every == 0) write_frame(k + 1);
      const auto now = Clock::now();
      if (o.progress && now - last_progress > std::chrono::seconds(2)) {
        last_progress = now;
        const double el = std::chrono::duration<double>(now - wall0).count();
        const double eta = el / static_cast<double>(k + 1) * static_cast<double>(steps - k - 1);
        spdlog::info("step {}/{} ({:.0f}%), sim time {:.4g} s, {:.3f} ms/step, ETA {:.0f} s", k + 1,
                     steps, 100.0 * (k + 1) / steps, s.time, el * 1e3 / (k + 1), eta);
      }
    }
  }
  res.wall_seconds = std::chrono::duration<double>(Clock::now() - wall0).count();
  res.steps = static_cast<long>(m.stepper.integrator == Integrator::Static ? 0 : s.step);
  res.sim_time = s.time;
  res.step_ms = summarize(step_ms);
  res.cg_iterations_mean = step_ms.empty() ? 0.0 : static_cast<double>(cg_sum) / static_cast<double>(step_ms.size());
  for (int st = 0; st < kStageCount; ++st)
    res.stage_ms_total[std::string(stage_name(static_cast<Stage>(st)))] = stage_total[st];

  if (write) {
    const auto t0 = Clock::now();
    metrics.reset();
    write_vtu((fs::path(o.out_dir) / "final.vtu").string(), m, s);
    write_state_csv((fs::path(o.out_dir) / "final_state.csv").string(), s);
    if (!series.empty()) write_pvd((fs::path(o.out_dir) / "series.pvd").string(), series);
    add_io(t0);
    res.io_ms_total = io_ms;

    nlohmann::ordered_json j;
    j["scenario"] = m.spec.name;
    j["scenario_file"] = m.spec.file;
    j["steps"] = res.steps;
    j["time_step"] = m.time_step;
    j["sim_time"] = res.sim_time;
    j["wall_seconds"] = res.wall_seconds;
    j["nodes"] = m.fem.num_nodes;
    j["elements"] = m.fem.elements.size();
    j["step_ms"] = {{"p50", res.step_ms.p50}, {"p99", res.step_ms.p99}, {"max", res.step_ms.max}, {"mean", res.step_ms.mean}};
    j["cg_iterations"] = {{"mean", res.cg_iterations_mean}, {"max", res.cg_iterations_max}};
    j["ticks_not_converged"] = res.ticks_not_converged;
    j["ticks_non_finite"] = res.ticks_non_finite;
    j["ticks_recovered"] = res.ticks_recovered;
    j["max_substeps"] = res.max_substeps;
    if (m.stepper.integrator == Integrator::Static)
      j["static"] = {{"newton_iterations", res.newton_iterations},
                     {"relative_residual", res.static_residual},
                     {"converged", res.static_converged}};
    nlohmann::ordered_json stages;
    for (int st = 0; st < kStageCount; ++st) {
      const std::string name(stage_name(static_cast<Stage>(st)));
      stages[name] = {{"total_ms", stage_total[st]},
                      {"per_step_ms", step_ms.empty() ? 0.0 : stage_total[st] / static_cast<double>(step_ms.size())}};
    }
    stages["io"] = {{"total_ms", io_ms}};
    j["stages"] = stages;
    nlohmann::ordered_json probes = nlohmann::ordered_json::object();
    for (const ProbeModel& p : m.probes) {
      const Vec3 pos = probe_position(m, s, p);
      const Vec3 d = probe_displacement(m, s, p);
      probes[p.name] = {{"position", {pos[0], pos[1], pos[2]}}, {"displacement", {d[0], d[1], d[2]}}};
    }
    j["probes"] = probes;
    if (m.has_damage)
      j["damage"] = {{"elements_warned", s.damage_count[1]},
                     {"elements_damaged", s.damage_count[2]},
                     {"elements_ruptured", s.damage_count[3]},
                     {"first_onset_time", s.first_damage_time}};
    std::ofstream f(fs::path(o.out_dir) / "summary.json");
    f << j.dump(2) << '\n';
    if (!f) throw std::runtime_error(fmt::format("cannot write '{}'", (fs::path(o.out_dir) / "summary.json").string()));
  }
  res.final_state = std::move(s);
  return res;
}

}  // namespace stroma
