#pragma once
/// \file solver_comparison.hpp
/// What converging a scenario's solves would cost and gain (`stroma run SCENE --explain`,
/// `--converge`). SOFA scenes through the importer reproduce SOFA's algorithm — unpreconditioned
/// CG kept at its cap — and with it SOFA's error (beam k6: the tip 37 % short at 25 iterations);
/// `--converge` runs them with the engine's own choice instead, at the scene's tolerance.

#include <string>

#include "engine/timing_stats.hpp"
#include "scene/scenario_spec.hpp"

namespace stroma {

/// The cap `--converge` gives CG at least (every solve of the shipped scenes converges well
/// within it with the engine's preconditioner).
inline constexpr int kConvergeMinIterations = 1000;

/// The scenario's solver left to the engine (`--converge`): preconditioner, its refresh and the
/// cap policy `auto`, the warm start extrapolated, the cap raised to kConvergeMinIterations;
/// the integrator, linear solver, tolerance, Newton settings and time budget are kept.
void converge_solver(SolverSpec& s);

/// One run's figures in a comparison.
struct SolverRun {
  std::string solver;             ///< solver_short() of its model
  TimingSummary tick_ms;          ///< wall time per tick
  double iterations_mean = 0;     ///< CG iterations per tick
  long ticks_converged = 0;       ///< ticks whose solve reached the tolerance
  double max_displacement = 0;    ///< m: largest nodal displacement over the run
};

/// The scenario as written against converge_solver() of it, ticked alternately from the same
/// initial state (the same scripted tool poses; timings in one run), `ticks` each.
struct SolverComparison {
  SolverRun as_written, converged;
  long ticks = 0;
  /// The largest nodal distance between the two runs over all ticks (m), and relative to the
  /// converged run's largest displacement: the error of the solve as written.
  double difference_max = 0, difference_relative = 0;
};

/// Runs the comparison (compiles both; allocates; seconds for large scenes). Throws InputError
/// as compile_scenario does.
SolverComparison compare_with_converged(const ScenarioSpec& spec, long ticks);

}  // namespace stroma
