#include "server/serve_stats.hpp"

#include <string>

#include "engine/cut_worker.hpp"
#include "engine/tick_types.hpp"

namespace stroma {

namespace {

nlohmann::ordered_json histogram_json(const LatencyHistogram& h) {
  static constexpr int kEdges[] = {0, 10, 20, 50, 100, 200, 500, 1000, 2000, 5000, 10000, 20000};
  nlohmann::ordered_json bins = nlohmann::ordered_json::array();
  h.for_each_bin(kEdges, static_cast<int>(std::size(kEdges)), [&](int lo, int64_t c) {
    bins.push_back({{"from_us", lo}, {"count", c}});
  });
  return {{"count", h.count()},      {"p50_us", h.percentile_us(0.5)},
          {"p99_us", h.percentile_us(0.99)}, {"p999_us", h.percentile_us(0.999)},
          {"max_us", h.max_us()},    {"mean_us", h.mean_us()},
          {"histogram", bins}};
}

}  // namespace

nlohmann::ordered_json stats_json(const ServeOptions& o, const Model& model, const PhysicsLoop& loop,
                                  const RealtimeResult& rt, const DdsParticipant& pp, const InputCounters& counters,
                                  uint64_t status_sent, const RecordStatus& record) {
  const PhysicsLoopStats& st = loop.stats();
  nlohmann::ordered_json j;
  j["scenario"] = model.name;
  j["time_step"] = model.time_step;
  j["realtime"] = {{"mode", o.timing.realtime}, {"fifo", rt.fifo}, {"memory_locked", rt.memory_locked},
                   {"pinned_cpu", rt.cpu}, {"problems", rt.problems}};
  j["dds"] = {{"domain", o.dds.domain}, {"config", pp.config_source}};
  j["loops"] = st.loops;
  j["ticks"] = st.ticks;
  j["missed_deadlines"] = st.missed_deadlines;
  j["missed_ratio"] = st.loops ? static_cast<double>(st.missed_deadlines) / static_cast<double>(st.loops) : 0.0;
  j["sim_time"] = st.sim_time;
  j["wall_time"] = st.wall_time;
  j["lag"] = st.lag;
  j["wake_latency"] = histogram_json(st.wake);
  j["phase_lock"] = {{"lead_us", o.timing.phase_lead_us},
                     {"shift_ms_total", static_cast<double>(st.phase_shift_ns) * 1e-6},
                     {"shift_ms_abs_total", static_cast<double>(st.phase_shift_abs_ns) * 1e-6}};
  j["command_wait"] = histogram_json(st.command_wait);
  j["tick_time"] = histogram_json(st.tick);
  j["cg_iterations"] = {{"mean", st.ticks ? static_cast<double>(st.cg_iterations_total) / static_cast<double>(st.ticks) : 0.0},
                        {"max", st.cg_iterations_max}};
  nlohmann::ordered_json stages;
  for (int s = 0; s < kStageCount; ++s)
    stages[std::string(stage_name(static_cast<Stage>(s)))] =
        st.ticks ? static_cast<double>(st.stage_ns_total[s]) * 1e-6 / static_cast<double>(st.ticks) : 0.0;
  j["stage_ms_mean"] = stages;
  j["ticks_not_converged"] = st.not_converged;
  j["ticks_non_finite"] = st.non_finite;
  j["ticks_recovered"] = st.recovered;
  j["budget_ms"] = static_cast<double>(st.budget_ns) * 1e-6;
  j["ticks_over_budget"] = st.over_budget;
  if (model.fem_every > 1)
    j["multirate"] = {{"fem_every", model.fem_every}, {"tissue_steps", st.tissue_steps},
                      {"tissue_steps_late", st.tissue_steps_late},
                      {"haptic_model", model.haptic_secant ? "secant" : "hold"}};
  j["ticks_degraded"] = st.degraded;
  if (!model.fem.rods.empty())  // docs/THREAD.md, "Contact": the continuous check after the step
    j["thread_contact"] = {{"missed_springs_added", st.thread_missed}, {"checks_skipped", st.thread_unchecked}};
  j["controls"] = {{"received", counters.controls.load()}, {"dropped", counters.controls_dropped.load()}};
  {
    const CommandCounters& cc = loop.commands().counters();
    const uint64_t a = cc.accepted.load(), c = cc.clamped.load(), r = cc.rejected.load(), s = cc.superseded.load();
    j["tool_commands"] = {{"received", a + c + r + s}, {"accepted", a}, {"clamped", c}, {"rejected", r},
                          {"superseded", s}};
  }
  j["status_messages"] = status_sent;
  if (!o.outputs.record_file.empty())
    j["record"] = {{"file", o.outputs.record_file},
                   {"ok", !record.failed && loop.stats().record_dropped == 0},
                   {"lines_written", record.lines_written},
                   {"events_dropped", loop.stats().record_dropped},
                   {"error", record.error},
                   {"stopped_at_tick", record.failed ? record.stopped_at_tick : -1}};
  if (const CutWorker* cw = loop.cutter()) {
    const CutWorker::Stats& cs = cw->stats();
    const CutStats& c = loop.model().cut_stats;  // the model the session ended on
    j["cutting"] = {{"edges_cut", c.edges_cut},
                    {"elements_split", c.elements_split},
                    {"nodes_created", c.nodes_created},
                    {"faces_created", c.faces_created},
                    {"cut_area", c.cut_area},
                    {"topology_version", loop.model().topology_version},
                    {"topology_swaps", cs.swapped},
                    {"builds", {{"posted", cs.posted}, {"unchanged", cs.unchanged}, {"failed", cs.failed}}},
                    {"build_ms_max", cs.build_ms_max},
                    {"swap_ms_max", static_cast<double>(cs.swap_ns_max) * 1e-6},
                    {"lag_ticks_max", cs.lag_ticks_max}};
  }
  if (model.has_damage) {
    const State& fs = loop.state();
    j["damage"] = {{"elements_warned", fs.damage_count[1]}, {"elements_damaged", fs.damage_count[2]},
                   {"elements_ruptured", fs.damage_count[3]}, {"first_onset_time", fs.first_damage_time},
                   {"events_dropped", loop.damage_dropped.load()}};
  }
  return j;
}


}  // namespace stroma
