/// \file bench_ticks.cpp
/// Whole-tick timing of scenarios over repeated runs: for each run, ticks from the initial
/// state and records every tick's wall time; reports the median over runs of the per-run p50,
/// p99 and max, the spread (min–max of the per-run p50/p99), CG iterations, and the stage split.
///
/// Usage: stroma_bench_ticks SCENARIO [--mesh FILE] [--runs R] [--steps N] [--tolerance T]
///                          [--preconditioner P]
///                          [--label TEXT] [--markdown]
/// The machine is shared and noisy: report medians over many runs, never one run.

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include "bench/bench_stats.hpp"
#include "engine/model.hpp"
#include "engine/simulation.hpp"
#include "engine/state.hpp"
#include "engine/tick.hpp"
#include "scene/compiled_scenario.hpp"
#include "scene/scenario_spec.hpp"

using namespace stroma;

using bench::median;
using bench::percentile;

int main(int argc, char** argv) {
  CLI::App app{"Tick timing of a scenario over repeated runs (median of per-run percentiles)"};
  std::string scenario, mesh, label;
  int runs = 10;
  long steps = 1000;
  double tolerance = -1;
  bool markdown = false;
  std::string pc;
  double poisson = -1, locking_free = -1, budget = -1;
  int max_iterations = -1, patch = 0;
  app.add_option("scenario", scenario, "Scenario YAML")->required()->check(CLI::ExistingFile);
  app.add_option("--mesh", mesh, "Replace the first body's mesh")->check(CLI::ExistingFile);
  app.add_option("--runs", runs, "Repetitions")->capture_default_str();
  app.add_option("--steps", steps, "Ticks per run")->capture_default_str();
  app.add_option("--tolerance", tolerance, "Override the CG tolerance");
  app.add_option("--label", label, "Row label");
  app.add_flag("--markdown", markdown, "Print a markdown table row");
  app.add_option("--preconditioner", pc, "Override the CG preconditioner")
      ->check(CLI::IsMember({"jacobi", "block_jacobi", "none", "warped_cholesky"}));
  app.add_option("--poisson", poisson, "Override the first body's Poisson ratio")->check(CLI::Range(0.0, 0.4999));
  app.add_option("--locking-free", locking_free,
                 "Make the first body locking-free (node smoothing) with this stabilisation share")
      ->check(CLI::Range(0.0, 1.0));
  app.add_option("--patch", patch,
                 "With --locking-free B: element patches of at least this many tetrahedra (F-bar-patch) "
                 "instead of node domains, the elements keeping the share B of the bulk modulus")
      ->check(CLI::Range(2, 64));
  app.add_option("--max-iterations", max_iterations, "Override the CG iteration cap")->check(CLI::PositiveNumber);
  app.add_option("--time-budget", budget, "Override solver.time_budget (s; 0: none)")->check(CLI::NonNegativeNumber);
  CLI11_PARSE(app, argc, argv);

  ScenarioSpec spec = load_scenario(scenario);
  if (!mesh.empty()) spec.bodies.at(0).mesh_path = mesh;
  if (tolerance > 0) spec.solver.tolerance = tolerance;
  if (poisson >= 0) spec.bodies.at(0).material.poisson_ratio = poisson;
  if (locking_free >= 0) {
    LockingFreeSpec l{"node_smoothing", locking_free, {}};
    if (patch > 0) {  // (--locking-free's value is then the share of the bulk on the elements)
      l = LockingFreeSpec::element_patches();
      l.patch_elements = patch;
      l.element_bulk = std::min(locking_free, 0.99);
    }
    spec.bodies.at(0).material.locking_free = l;
  }
  if (max_iterations > 0) spec.solver.max_iterations = max_iterations;
  if (budget >= 0) spec.solver.time_budget = budget;
  if (pc == "jacobi") spec.solver.preconditioner = Preconditioner::Jacobi;
  if (pc == "block_jacobi") spec.solver.preconditioner = Preconditioner::BlockJacobi;
  if (pc == "none") spec.solver.preconditioner = Preconditioner::None;
  if (pc == "warped_cholesky") spec.solver.preconditioner = Preconditioner::WarpedCholesky;
  auto m = compile_model(spec);
  std::vector<double> p50s, p99s, maxs, cgs, asm_ms, solve_ms;
  int cg_max = 0;
  for (int r = 0; r < runs; ++r) {
    Simulation sim(m);  // as every front end drives the engine (engine/simulation.hpp)
    std::vector<double> t;
    t.reserve(steps);
    double cg = 0, as = 0, so = 0;
    for (long k = 0; k < steps; ++k) {
      const TickReport& rep = sim.advance();
      t.push_back(static_cast<double>(rep.total_ns) * 1e-6);
      cg += rep.solve.iterations;
      cg_max = std::max(cg_max, rep.solve.iterations);
      as += static_cast<double>(rep.stage_ns[static_cast<int>(Stage::Assemble)]) * 1e-6;
      so += static_cast<double>(rep.stage_ns[static_cast<int>(Stage::Solve)]) * 1e-6;
    }
    p50s.push_back(percentile(t, 0.5));
    p99s.push_back(percentile(t, 0.99));
    maxs.push_back(*std::max_element(t.begin(), t.end()));
    cgs.push_back(cg / static_cast<double>(steps));
    asm_ms.push_back(as / static_cast<double>(steps));
    solve_ms.push_back(so / static_cast<double>(steps));
  }
  const std::string name = label.empty() ? spec.name : label;
  if (markdown) {
    fmt::print("| {} | {} | {} | {:.3f} ({:.3f}–{:.3f}) | {:.3f} ({:.3f}–{:.3f}) | {:.3f} | {:.1f} / {} | {:.3f} / {:.3f} |\n",
               name, m->fem.num_nodes, m->fem.elements.size(), median(p50s),
               *std::min_element(p50s.begin(), p50s.end()), *std::max_element(p50s.begin(), p50s.end()),
               median(p99s), *std::min_element(p99s.begin(), p99s.end()), *std::max_element(p99s.begin(), p99s.end()),
               median(maxs), median(cgs), cg_max, median(asm_ms), median(solve_ms));
  } else {
    fmt::print("{}: {} nodes, {} tets, {} runs x {} ticks\n", name, m->fem.num_nodes, m->fem.elements.size(), runs, steps);
    fmt::print("  tick ms  p50 {:.4f} (runs {:.4f}-{:.4f})  p99 {:.4f} (runs {:.4f}-{:.4f})  max {:.4f}\n",
               median(p50s), *std::min_element(p50s.begin(), p50s.end()), *std::max_element(p50s.begin(), p50s.end()),
               median(p99s), *std::min_element(p99s.begin(), p99s.end()), *std::max_element(p99s.begin(), p99s.end()),
               median(maxs));
    fmt::print("  CG iterations mean {:.1f} max {}; assemble {:.4f} ms, solve {:.4f} ms per tick\n", median(cgs),
               cg_max, median(asm_ms), median(solve_ms));
  }
  return 0;
}
