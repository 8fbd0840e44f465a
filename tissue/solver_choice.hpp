#pragma once
/// \file solver_choice.hpp
/// `preconditioner: auto` (the scenario default): which conjugate-gradient preconditioner
/// reaches the requested tolerance in the least time on this scene, decided at load.
///
/// How (docs/PERFORMANCE.md, "The engine chooses"):
///  - **Trial steps of the scene itself.** Each candidate — Jacobi, block Jacobi, the warped
///    Cholesky factor of the rest pose — takes kTrialSteps implicit-Euler steps of the free
///    tissue from rest (its gravity and constant loads; no tools), with the scenario's
///    tolerance, cap and warm start. Its CG iterations over the steps after the first
///    kTrialWarmup (the warm start then extrapolates, as in a running scene) say how hard the
///    scene's systems are for it. Iteration counts depend on the arithmetic alone, so the
///    choice is the same on every run of a build: a headless run stays a function of its inputs.
///  - **A cost model of a solve**, calibrated on the project's machine (tissue/solver_costs.hpp):
///    a Jacobi-PCG iteration streams the matrix (ns per stored 3×3 block) and a few vectors (ns
///    per unknown); block Jacobi adds a 3×3 product per node; a warped iteration adds the
///    single-precision triangular solves (ns per stored factor entry) and the node rotations.
///  - **The least predicted solve time wins** among candidates that converged on every measured
///    trial step; if none did, the one with the most converged steps (then the smallest
///    residual). The warped factor must win by kWarpedMargin: it carries costs the model does
///    not see — its factorisations on the second core contend for the memory the ticking
///    thread streams (the assemble stage ~20 % slower while a refresh runs, measured), it is
///    history a snapshot does not hold, and the trial's first steps flatter it (a fresh factor
///    fits a body that has not yet deformed). Under a time budget each candidate is charged one
///    more iteration (a budget cut lands up to one iteration late: coarse iterations overshoot
///    more).
///  - **Never a factorisation that stalls**: the warped candidate is left out when the symbolic
///    analysis predicts a factorisation longer than kMaxFactorSeconds.
/// The explicit settings of a scenario are never overridden: this runs only for `auto`.

#include <cstdint>
#include <string>
#include <vector>

#include "tissue/fem_model.hpp"
#include "tissue/options.hpp"
#include "tissue/solver_costs.hpp"
#include "tissue/time_stepper.hpp"

namespace stroma {

/// The warped factor is chosen only when its predicted solve is below the best Jacobi-family
/// candidate's / this (see the file comment). 1.3: on the mass-dominated Armadillo (1 warped
/// against 5–6 Jacobi iterations, predicted within 25 % of each other) Jacobi's measured tick
/// is 0.6 ms against the factor's 0.85; everywhere the factor measured faster, it was predicted
/// more than 1.3× faster (docs/PERFORMANCE.md, "The engine chooses").
inline constexpr double kWarpedMargin = 1.3;

/// Trial steps per candidate, and how many of the first are left out of its statistics.
inline constexpr int kTrialSteps = 12;
inline constexpr int kTrialWarmup = 2;
/// A warped factor whose numeric factorisation the symbolic analysis predicts to take longer
/// than this (s, at kFactorNsPerEntry or kFactorFlopsPerSecond, whichever is slower) is no
/// candidate: it would stall the load and no refresh could keep up with the scene.
inline constexpr double kMaxFactorSeconds = 2.0;
inline constexpr double kFactorNsPerEntry = 40.0;       ///< as auto_refresh_period()
inline constexpr double kFactorFlopsPerSecond = 2.0e9;  ///< CHOLMOD here on small supernodes

/// One candidate's trial.
struct PreconditionerTrial {
  Preconditioner preconditioner = Preconditioner::Jacobi;
  bool tried = false;            ///< false: left out (`left_out` says why)
  std::string left_out;          ///< why it was not tried (empty when tried)
  int steps = 0;                 ///< measured steps (after the warm-up)
  int converged = 0;             ///< of them, converged within the cap
  double iterations_mean = 0;    ///< CG iterations per measured step
  int iterations_max = 0;
  double residual_max = 0;       ///< largest relative residual at exit of a measured step
  double iteration_ns = 0;       ///< the cost model's time of one more iteration
  double predicted_solve_ms = 0; ///< solve_ns at iterations_mean (+1 iteration under a budget)
  double measured_solve_ms = 0;  ///< median wall time of its measured solves (reported only)
  bool stopped_early = false;    ///< its predicted cost passed 3× the best's: trial cut short
};

/// The choice and the evidence behind it.
struct PreconditionerChoice {
  Preconditioner preconditioner = Preconditioner::Jacobi;
  std::vector<PreconditionerTrial> trials;  ///< every candidate, in the order tried
  std::string reason;                       ///< one line: why this one
  double factor_entries = 0;                ///< the warped factor's size (0: not analysed)
  double factor_seconds_estimate = 0;       ///< its predicted factorisation time
  double trial_ms = 0;                      ///< wall time of the whole choice
};

/// What the choice takes besides the model.
struct ChoiceOptions {
  bool budgeted = false;  ///< ticks run under a time budget: each candidate is charged one more iteration
  double max_factor_seconds = kMaxFactorSeconds;  ///< a longer predicted factorisation leaves warped out
  IterationCostModel costs;
};

/// Chooses the preconditioner for CG on `model` with `settings` (whose preconditioner is
/// ignored) at step h. Implicit Euler runs the trial; a static solve takes the warped factor of
/// the rest tangent when it is feasible (Newton's tangents stay near it) and Jacobi otherwise;
/// symplectic Euler and CHOLMOD solve with no preconditioner (Jacobi, unused). Allocates; load
/// time only.
PreconditionerChoice choose_preconditioner(const FemModel& model, const StepperSettings& settings, double h,
                                           const ChoiceOptions& options = {});

/// The warped candidate's mean iterations in the trial (kTypicalWarpedIterations when it was
/// not tried).
double warped_trial_iterations(const PreconditionerChoice& c);

/// The name a scenario writes for a preconditioner (`jacobi`, `block_jacobi`, `none`,
/// `warped_cholesky`).
const char* preconditioner_name(Preconditioner p);

/// Whether TimeStepper::energy_guard() means anything for this model (its elastic forces are
/// the gradient of the energy it measures): false when any free element range uses the QR
/// rotation (SOFA's "large").
bool energy_guard_applies(const FemModel& model);

}  // namespace stroma
