#pragma once
/// \file headless_runner.hpp
/// `stroma run`: ticks a model as fast as it can and writes summary.json, metrics.csv,
/// final.vtu (+ a .pvd series) and final_state.csv into an output directory.

#include <functional>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "engine/model.hpp"
#include "engine/state.hpp"
#include "engine/tick.hpp"

namespace stroma {

/// Options of a headless run (command-line values override the scenario's `run:`).
struct RunOptions {
  std::optional<long> steps;        ///< ticks to run
  std::optional<double> duration;   ///< simulated seconds to run
  std::string out_dir;              ///< empty: write nothing
  int vtu_every = 0;                ///< > 0: also write a .vtu every K ticks and a .pvd
  bool progress = true;             ///< log progress for runs longer than a few seconds
  bool metrics = true;              ///< per-tick metrics (costs an energy pass per tick)
  std::string replay;               ///< session log to re-execute (overrides steps/duration)
};

/// Percentiles of a sample (milliseconds).
struct TimingSummary {
  double p50 = 0, p99 = 0, max = 0, mean = 0;
};

/// What a headless run produced (also written to summary.json).
struct RunResult {
  State final_state;
  long steps = 0;
  double sim_time = 0;
  double wall_seconds = 0;
  TimingSummary step_ms;
  double cg_iterations_mean = 0;
  int cg_iterations_max = 0;
  long ticks_not_converged = 0;
  long ticks_non_finite = 0;
  long ticks_recovered = 0;  ///< ticks redone in sub-steps after a failed step (TickStatus::Recovered)
  int max_substeps = 1;       ///< most sub-steps any tick needed
  std::map<std::string, double> stage_ms_total;  ///< per stage, summed over the run
  double io_ms_total = 0;                        ///< metrics, VTU and summary writing
  /// Static runs: Newton iterations and final relative residual.
  int newton_iterations = 0;
  double static_residual = 0;
  bool static_converged = true;
};

/// Number of ticks a run makes: options first, then the scenario's `run:` (0 for static).
long resolve_steps(const Model& m, const RunOptions& o);

/// Runs the model from its initial state. Throws std::runtime_error on I/O failure.
RunResult run_headless(const Model& m, const RunOptions& o);

}  // namespace stroma
