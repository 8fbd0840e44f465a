#pragma once
/// \file solver_costs.hpp
/// What a CG solve costs on this machine, by what it streams — the cost model behind
/// `preconditioner: auto` (tissue/solver_choice.hpp) and the warped factor's refresh period
/// (auto_refresh_period, TimeStepper). Deterministic: a function of the scene's sizes and an
/// iteration count, never of a clock, so a choice made with it is the same on every run.

#include <algorithm>

#include "tissue/fem_model.hpp"
#include "tissue/options.hpp"
#include "tissue/warped_preconditioner.hpp"

namespace stroma {

/// Nanoseconds per unit, fitted 2026-12-05 on the project's 2-core VM by least squares over the
/// solve stages of 30 scenes × 6 solver configurations (`bench/defaults.py`'s runs: 294 warped
/// runs, 30 Jacobi runs at ≥ 3 iterations; docs/PERFORMANCE.md, "The engine chooses"). A solve
/// of k iterations does k + 1 matrix products (the first residual) and k preconditioner
/// applications. Measured against the model: Jacobi 0.80–1.12 (21 of 29 scenes within ±10 %),
/// warped p10–p90 0.77–1.29.
struct IterationCostModel {
  double ns_per_block = 3.79;            ///< per stored 3×3 block of the system, per product
  double ns_per_dof = 0.97;              ///< per unknown, per product (vector updates, dots)
  double block_jacobi_ns_per_dof = 0.6;  ///< block Jacobi's 3×3 products, per iteration
  double warped_ns_per_entry = 0.36;     ///< warped: per stored factor entry, per iteration
  double warped_ns_per_dof = 3.7;        ///< warped: node rotations in and out, per iteration
  /// The element pass with assembly (the assemble stage), per element: 80–130 ns over the same
  /// scenes (median 98; polar corotational, stable Neo-Hookean dearer).
  double ns_per_element = 100.0;
};

/// ns of one CG solve of `iterations` iterations with preconditioner p on `m` (`factor_entries`:
/// the warped factor's stored entries).
inline double solve_ns(Preconditioner p, const FemModel& m, double factor_entries, double iterations,
                       const IterationCostModel& c = {}) {
  const double product = c.ns_per_block * m.pattern.nnzb() + c.ns_per_dof * m.dofs();
  double per_iteration = 0;
  if (p == Preconditioner::BlockJacobi) per_iteration = c.block_jacobi_ns_per_dof * m.dofs();
  if (p == Preconditioner::WarpedCholesky)
    per_iteration = c.warped_ns_per_entry * factor_entries + c.warped_ns_per_dof * m.dofs();
  return (iterations + 1.0) * product + iterations * per_iteration;
}

/// ns of a tick's assemble stage on `m` (the element pass with assembly).
inline double assemble_ns(const FemModel& m, const IterationCostModel& c = {}) {
  return c.ns_per_element * static_cast<double>(m.elements.size());
}

/// Iterations a warped solve is taken to need where none was measured yet (an explicit
/// `warped_cholesky`, or before the first solves): what the shipped warped scenes need.
inline constexpr double kTypicalWarpedIterations = 2.0;

/// The fewest steps between two refreshes of the warped factor `auto` chooses.
inline constexpr int kMinRefreshPeriod = 10;

/// `preconditioner_refresh: auto`: the steps between refreshes of the warped factor. A refresh
/// is useful as soon as the worker can make one, so the period is the steps the factorisation
/// takes (refresh_steps_for: 40 ns per stored entry, × 1.5) at the run's own pace: one predicted
/// tick (assemble + `warped_iterations` iterations) per step — what a headless run takes, and
/// what a served one takes when its ticks do not fit the period; `real_time_step` > 0 (serve):
/// at least that per step. A headless run swaps its factors on a fixed schedule and waits for a
/// late worker, so a period counted in real time would make it wait. The time stepper
/// re-evaluates it with the running mean of its warped iterations (a deterministic count): a
/// factor that has gone stale makes ticks slow, and slow ticks leave the worker time to refresh
/// it more often. At least kMinRefreshPeriod steps.
inline int auto_refresh_period(const FemModel& model, double factor_entries, double warped_iterations,
                               double real_time_step = 0, const IterationCostModel& costs = {}) {
  const double tick_s = 1e-9 * (assemble_ns(model, costs) +
                                solve_ns(Preconditioner::WarpedCholesky, model, factor_entries, warped_iterations, costs));
  const double pace = std::max({tick_s, real_time_step, 1e-6});
  return std::max(kMinRefreshPeriod, refresh_steps_for(factor_entries, pace));
}

}  // namespace stroma
