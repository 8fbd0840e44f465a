#include "scene/solver_comparison.hpp"

#include <algorithm>
#include <cmath>

#include "engine/state.hpp"
#include "engine/tick.hpp"
#include "scene/compiled_scenario.hpp"
#include "scene/solver_report.hpp"
#include "tissue/clock.hpp"

namespace stroma {

void converge_solver(SolverSpec& s) {
  s.preconditioner.reset();
  s.preconditioner_refresh = -1;
  s.on_cg_cap = CapPolicy::Auto;
  s.warm_start = WarmStart::Extrapolate;
  s.max_iterations = std::max(s.max_iterations, kConvergeMinIterations);
}

namespace {

/// One side of the comparison: its compiled scenario, state, workspace and tallies.
struct Side {
  CompiledScenario sc;
  State s;
  std::unique_ptr<TickWorkspace> w;
  std::vector<double> tick_ms;
  double iterations = 0;
  SolverRun out;
  explicit Side(const ScenarioSpec& spec) : sc(compile_scenario(spec)) {
    s = State::initial(*sc.model);
    w = std::make_unique<TickWorkspace>(*sc.model);
    out.solver = solver_short(sc);
  }
  void tick_once() {
    std::vector<ToolInput> inputs;
    for (size_t t = 0; t < sc.model->tools.size(); ++t)
      if (!sc.tool_scripts[t].keys.empty())
        inputs.push_back(ToolInput{static_cast<int32_t>(t), static_cast<uint64_t>(s.step + 1), 0,
                                   sc.tool_scripts[t].sample(s.time)});
    const int64_t t0 = steady_now_ns();
    const TickReport& r = tick(*sc.model, s, *w, inputs.data(), static_cast<int>(inputs.size()));
    tick_ms.push_back((steady_now_ns() - t0) * 1e-6);
    iterations += r.solve.iterations;
    out.ticks_converged += r.solve.converged;
  }
};

}  // namespace

SolverComparison compare_with_converged(const ScenarioSpec& spec, long ticks) {
  ScenarioSpec conv = spec;
  converge_solver(conv.solver);
  Side a(spec), b(conv);
  SolverComparison c;
  const std::vector<double>& rest = b.sc.model->fem.rest;
  for (long k = 0; k < ticks; ++k) {
    a.tick_once();
    b.tick_once();
    // Same topology on both sides (no cutting here): compare node by node.
    if (a.s.tissue.x.size() != b.s.tissue.x.size()) break;
    for (size_t i = 0; i + 2 < b.s.tissue.x.size(); i += 3) {
      double d2 = 0, u2 = 0, w2 = 0;
      for (int j = 0; j < 3; ++j) {
        const double d = a.s.tissue.x[i + j] - b.s.tissue.x[i + j];
        const double u = b.s.tissue.x[i + j] - rest[i + j], w = a.s.tissue.x[i + j] - rest[i + j];
        d2 += d * d;
        u2 += u * u;
        w2 += w * w;
      }
      c.difference_max = std::max(c.difference_max, std::sqrt(d2));
      b.out.max_displacement = std::max(b.out.max_displacement, std::sqrt(u2));
      a.out.max_displacement = std::max(a.out.max_displacement, std::sqrt(w2));
    }
    ++c.ticks;
  }
  for (Side* s : {&a, &b}) {
    s->out.tick_ms = summarize(s->tick_ms);
    s->out.iterations_mean = c.ticks ? s->iterations / static_cast<double>(c.ticks) : 0.0;
  }
  c.as_written = a.out;
  c.converged = b.out;
  c.difference_relative = b.out.max_displacement > 0 ? c.difference_max / b.out.max_displacement : 0.0;
  return c;
}

}  // namespace stroma
