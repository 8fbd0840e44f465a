#pragma once
/// \file headless_runner.hpp
/// `stroma run`: ticks a model as fast as it can and writes summary.json, metrics.csv,
/// final.vtu (+ a .pvd series) and final_state.csv into an output directory. Static scenarios
/// solve equilibria with load stepping (engine/static_run.hpp) through the same collide stage
/// and time stepper. A failed run (a tick that could not advance, a static solve that did not
/// converge) writes summary.json with "status": "failed" and its reason, its metrics, and no
/// final state: final.vtu and final_state.csv are not written (and stale ones removed).

#include <functional>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "engine/model.hpp"
#include "engine/state.hpp"
#include "engine/tick.hpp"
#include "engine/timing_stats.hpp"
#include "scene/compiled_scenario.hpp"

namespace stroma {

/// Options of a headless run (command-line values override the scenario's `run:`).
struct RunOptions {
  std::optional<long> steps;        ///< ticks to run (static: further equilibria after t = 0)
  std::optional<double> duration;   ///< simulated seconds to run
  std::string out_dir;              ///< empty: write nothing
  int vtu_every = 0;                ///< > 0: also write a .vtu every K ticks and a .pvd
  bool progress = true;             ///< log progress for runs longer than a few seconds
  bool metrics = true;              ///< per-tick metrics (costs an energy pass per tick)
  std::string replay;               ///< session log to re-execute (overrides steps/duration)
};

/// What a headless run produced (also written to summary.json).
struct RunResult {
  State final_state;
  std::vector<ToolOutput> final_tools;  ///< each tool's output of the last tick (or equilibrium)
  std::vector<RigidContactOutput> final_rigid;  ///< each rigid body's contacts of the last tick
  bool ok = true;                       ///< false: the run failed (see failure)
  std::string failure;                  ///< why, when !ok
  long steps = 0;                       ///< ticks (static: equilibria after the first)
  double sim_time = 0;
  double wall_seconds = 0;
  TimingSummary step_ms;
  /// The same ticks less their waits for a late preconditioner refresh (TickReport::
  /// refresh_wait_ns): what they cost as `serve` runs them. Those waits: ticks, total and longest.
  TimingSummary step_ms_without_refresh_waits;
  long refresh_wait_ticks = 0;
  double refresh_wait_ms_total = 0, refresh_wait_ms_max = 0;
  double cg_iterations_mean = 0;
  int cg_iterations_max = 0;
  long ticks_not_converged = 0;
  long ticks_non_finite = 0;
  long ticks_recovered = 0;  ///< ticks redone in sub-steps after a failed step (TickStatus::Recovered)
  int max_substeps = 1;       ///< most sub-steps any tick needed
  long ticks_over_budget = 0;  ///< ticks that ended past solver.time_budget
  long ticks_degraded = 0;     ///< ticks the budget cut short (TickReport::degradation)
  /// Threads: springs the continuous check after the step added, and passes it skipped (no redo
  /// fitted before the deadline; headless only under a time budget).
  long thread_missed = 0, thread_unchecked = 0;
  /// Warped Cholesky: solves Jacobi-PCG finished (SolveStats::preconditioner_fallback), and
  /// refreshed factors swapped in (`preconditioner_refresh`).
  long preconditioner_fallbacks = 0;
  int64_t preconditioner_refreshes = 0;
  /// The refresh worker's time per factor of the last model's workspace (ms): mean and longest.
  double refresh_factor_ms_mean = 0, refresh_factor_ms_max = 0;
  /// Tool commands of the scripts (checked as a client's: engine/tool_commands.hpp) — a
  /// replayed session's were checked when recorded and are not counted again.
  uint64_t commands_accepted = 0, commands_clamped = 0, commands_rejected = 0;
  double residual_max = 0;     ///< worst relative residual of a tick's linear solve
  double error_energy_max = 0;   ///< J: worst energy-norm error bound of a tick's solve
  double error_position_max = 0; ///< m: worst mass-weighted RMS position error bound
  long ticks_energy_limited = 0; ///< inexact ticks whose energy gain the guard took out
  double energy_removed = 0;     ///< J, by the energy guard over the run
  std::map<std::string, double> stage_ms_total;  ///< per stage, summed over the run
  double io_ms_total = 0;                        ///< metrics, VTU and summary writing
  /// Static runs: Newton iterations (all equilibria), final relative residual, load increments.
  int newton_iterations = 0;
  double static_residual = 0;
  bool static_converged = true;
  int static_increments = 0;
  /// Cutting: the model the run ended on (the scenario's, or the last cut model swapped in),
  /// cut models swapped in, and their builds' wall time (ms; synchronous in a headless run).
  std::shared_ptr<const Model> final_model;
  int topology_swaps = 0;
  double cut_build_ms_total = 0, cut_build_ms_max = 0;
};

/// Number of ticks a run makes: options first, then the scenario's `run:`. Dynamic default
/// 1000; static default 0 (one equilibrium at t = 0).
long resolve_steps(const CompiledScenario& sc, const RunOptions& o);

/// Runs the scenario from its initial state. Throws std::runtime_error on I/O failure.
RunResult run_headless(const CompiledScenario& sc, const RunOptions& o);

}  // namespace stroma
