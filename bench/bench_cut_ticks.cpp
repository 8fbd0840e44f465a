/// \file bench_cut_ticks.cpp
/// The ticks of an incision as `stroma serve` runs them: the scenario's scripted scalpel, every
/// tick the real tick() (the blade's sweep, contact on the cut surface, the implicit step at the
/// scenario's solver settings and time budget), each cut model built on the CutWorker's thread
/// and swapped in at the first tick boundary after it is ready. Reports the tick's p50 / p99 /
/// max with the swap inside it (what a 1 kHz deadline sees), the swap alone, the builds (off the
/// tick) and how many ticks the topology lagged the blade; then the same ticks with no tool (the
/// organ alone under gravity): the difference is what cutting costs a tick. Ticks are paced at
/// the scenario's rate (absolute deadlines), as serve paces them, so the worker's builds take
/// the ticks they would take live.
///
/// Usage: stroma_bench_cut_ticks SCENARIO [--runs R] [--markdown]
/// Medians over runs of the per-run figures (the machine is shared and noisy).

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "bench/bench_stats.hpp"
#include "engine/cut_worker.hpp"
#include "engine/simulation.hpp"
#include "engine/tick.hpp"
#include "scene/compiled_scenario.hpp"
#include "tissue/clock.hpp"

using namespace stroma;
using bench::median;
using bench::percentile;

namespace {

void sleep_until_ns(int64_t t) {
  const timespec ts{static_cast<time_t>(t / 1000000000LL), static_cast<long>(t % 1000000000LL)};
  while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) != 0) {
  }
}

struct RunFigures {
  double p50 = 0, p99 = 0, max = 0, over_1ms = 0;
  double swap_max_ms = 0, build_max_ms = 0;
  int64_t swaps = 0, lag_max = 0, split = 0, dofs = 0;
  double cut_area = 0;
};

RunFigures run_once(const CompiledScenario& sc, long ticks, bool cutting) {
  // As served: the engine's Simulation with cut models built on its worker, ticks that never
  // wait for the preconditioner's worker.
  SimulationOptions so;
  so.cut_builds = CutBuilds::OnWorker;
  so.realtime = true;
  Simulation sim(sc.model, so);
  std::vector<double> ms;
  ms.reserve(static_cast<size_t>(ticks));
  const int64_t period = static_cast<int64_t>(sc.model->time_step * 1e9);
  int64_t deadline = steady_now_ns();
  for (long k = 0; k < ticks; ++k) {
    deadline += period;
    sleep_until_ns(deadline);
    if (cutting) sim.submit_scripts(sc.tool_scripts);
    const auto t0 = std::chrono::steady_clock::now();
    const TickReport& r = sim.step();
    sim.cut(r.cut_edges);  // the swap counts in the tick's time
    ms.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
  }
  const Model* m = &sim.model();
  const CutWorker& worker = *sim.cutter();
  RunFigures f;
  f.p50 = percentile(ms, 0.5);
  f.p99 = percentile(ms, 0.99);
  f.max = *std::max_element(ms.begin(), ms.end());
  f.over_1ms = static_cast<double>(std::count_if(ms.begin(), ms.end(), [](double v) { return v > 1.0; }));
  const CutWorker::Stats& st = worker.stats();
  f.swap_max_ms = static_cast<double>(st.swap_ns_max) * 1e-6;
  f.build_max_ms = st.build_ms_max;
  f.swaps = static_cast<int64_t>(st.swapped);
  f.lag_max = st.lag_ticks_max;
  f.split = m->cut_stats.elements_split;
  f.dofs = m->fem.num_nodes;
  f.cut_area = m->cut_stats.cut_area;
  return f;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"The ticks of an incision as serve runs them: tick p50/p99 with the cut models swapped in"};
  std::string scenario;
  int runs = 5;
  bool markdown = false;
  app.add_option("scenario", scenario, "scenario YAML with a cutting tool and its script")->required();
  app.add_option("--runs", runs, "repetitions (medians reported)")->check(CLI::Range(1, 1000));
  app.add_flag("--markdown", markdown, "print a Markdown table row");
  CLI11_PARSE(app, argc, argv);
  const CompiledScenario sc = compile_scenario(load_scenario(scenario));
  if (!sc.model->cutting) {
    std::fprintf(stderr, "%s: no tool cuts (give a blade a cut: section)\n", scenario.c_str());
    return 2;
  }
  const long ticks = sc.spec.run.duration ? std::lround(*sc.spec.run.duration / sc.model->time_step)
                                          : (sc.spec.run.steps ? *sc.spec.run.steps : 1000);
  std::vector<double> p50, p99, mx, over, swap, build, lag, u50, u99, umx;
  RunFigures last;
  for (int r = 0; r < runs; ++r) {
    last = run_once(sc, ticks, true);
    p50.push_back(last.p50);
    p99.push_back(last.p99);
    mx.push_back(last.max);
    over.push_back(last.over_1ms);
    swap.push_back(last.swap_max_ms);
    build.push_back(last.build_max_ms);
    lag.push_back(static_cast<double>(last.lag_max));
    const RunFigures u = run_once(sc, ticks, false);
    u50.push_back(u.p50);
    u99.push_back(u.p99);
    umx.push_back(u.max);
  }
  std::printf("%s: %d nodes, %zu tets, %ld ticks, %d runs; at the end %lld tets split, %lld DOFs, cut area %.3g cm^2, "
              "%lld swaps\n",
              sc.model->name.c_str(), sc.model->fem.num_nodes, sc.model->fem.elements.size(), ticks, runs,
              static_cast<long long>(last.split), static_cast<long long>(last.dofs), last.cut_area * 1e4,
              static_cast<long long>(last.swaps));
  std::printf("cutting:      tick p50 %.3f  p99 %.3f  max %.3f ms; ticks > 1 ms: %.0f; swap max %.3f ms; build max "
              "%.2f ms (worker); lag max %.0f ticks (1 kHz)\n",
              median(p50), median(p99), median(mx), median(over), median(swap), median(build), median(lag));
  std::printf("no tool:      tick p50 %.3f  p99 %.3f  max %.3f ms (the organ alone, same ticks)\n", median(u50),
              median(u99), median(umx));
  if (markdown)
    std::printf("| %s | %zu | %lld | %.3f / %.3f / %.3f | %.0f | %.3f | %.2f | %.0f | %.3f / %.3f / %.3f |\n",
                sc.model->name.c_str(), sc.model->fem.elements.size(), static_cast<long long>(last.split), median(p50),
                median(p99), median(mx), median(over), median(swap), median(build), median(lag), median(u50),
                median(u99), median(umx));
  return 0;
}
