#include "tissue/solver_choice.hpp"

#include <algorithm>
#include <cmath>
#include <memory>

#include <fmt/format.h>

#include "tissue/bounding_box.hpp"
#include "tissue/clock.hpp"
#include "tissue/cholmod_solver.hpp"

namespace stroma {

const char* preconditioner_name(Preconditioner p) {
  switch (p) {
    case Preconditioner::Jacobi: return "jacobi";
    case Preconditioner::BlockJacobi: return "block_jacobi";
    case Preconditioner::None: return "none";
    case Preconditioner::WarpedCholesky: return "warped_cholesky";
  }
  return "?";
}

bool energy_guard_applies(const FemModel& model) {
  for (const ElementRange& r : model.ranges)
    if (!r.fixed && r.kernel == ElementKernel::CorotationalQR) return false;
  return true;
}

namespace {

bool any_load(const FemModel& m) {
  for (double f : m.f_ext)
    if (f != 0.0) return true;
  return false;
}

/// A copy of `m` loaded by a shearing body force, for a scene with no gravity and no constant
/// load (its trial systems would be zero): each node's mass × 9.81 m/s² × (its coordinate along
/// the longest extent, from the centre, over that extent) along the next-longest axis. A
/// uniform field would only translate a free body; this one also bends and shears it.
FemModel sheared_copy(const FemModel& m) {
  FemModel c = m;
  const BoundingBox box = bounding_box(m.rest.data(), m.rest.size() / 3);
  int a = 0, b = 1;
  double ext[3];
  for (int k = 0; k < 3; ++k) ext[k] = box.hi[k] - box.lo[k];
  int order[3] = {0, 1, 2};
  std::sort(order, order + 3, [&](int i, int j) { return ext[i] > ext[j]; });
  a = order[0];
  b = order[1];
  const double centre = 0.5 * (box.hi[a] + box.lo[a]), len = std::max(ext[a], 1e-300);
  for (int32_t i = 0; i < m.num_nodes; ++i) {
    if (m.constrained[i] >> b & 1) continue;
    c.f_ext[3 * i + b] = m.mass[i] * 9.81 * (m.rest[3 * i + a] - centre) / len;
  }
  return c;
}

/// One candidate's trial steps (see the file comment) on `m` (maybe the loaded copy), costed on
/// `costed` (the scene's model). `stop_ms`: its trial ends once its predicted solve time per
/// measured step so far passes this (3× the best's).
PreconditionerTrial run_trial(const FemModel& m, const FemModel& costed, double factor_entries, StepperSettings s,
                              double h, Preconditioner p, const IterationCostModel& costs, bool budgeted,
                              double stop_ms) {
  PreconditionerTrial t;
  t.preconditioner = p;
  t.tried = true;
  t.iteration_ns = solve_ns(p, costed, factor_entries, 1.0, costs) - solve_ns(p, costed, factor_entries, 0.0, costs);
  s.preconditioner = p;
  s.preconditioner_refresh = 0;  // the rest factor: what the trial measures is the scene
  s.newton_iterations = 1;
  TimeStepper stepper(m, s);
  stepper.prepare(h);
  TissueState st = TissueState::at_rest(m);
  std::vector<double> solve_ms;
  double iterations = 0;
  for (int k = 0; k < kTrialSteps; ++k) {
    stepper.assemble(st, h, StepInputs{});
    const int64_t t0 = steady_now_ns();
    const SolveStats r = stepper.solve(st);
    const int64_t t1 = steady_now_ns();
    stepper.integrate(st, h);
    bool finite = std::isfinite(r.relative_residual);
    for (double v : st.x) finite = finite && std::isfinite(v);
    if (!finite) {  // diverged: counts as never converging from here on
      t.steps = kTrialSteps - kTrialWarmup;
      t.residual_max = HUGE_VAL;
      break;
    }
    if (k < kTrialWarmup) continue;
    ++t.steps;
    t.converged += r.converged;
    iterations += r.iterations;
    t.iterations_max = std::max(t.iterations_max, r.iterations);
    t.residual_max = std::max(t.residual_max, r.relative_residual);
    solve_ms.push_back((t1 - t0) * 1e-6);
    if (1e-6 * solve_ns(p, costed, factor_entries, iterations / t.steps, costs) > stop_ms && k + 1 < kTrialSteps) {
      t.stopped_early = true;
      break;
    }
  }
  t.iterations_mean = t.steps > 0 ? iterations / t.steps : 0.0;
  t.predicted_solve_ms = 1e-6 * solve_ns(p, costed, factor_entries, t.iterations_mean + (budgeted ? 1.0 : 0.0), costs);
  if (!solve_ms.empty()) {
    std::nth_element(solve_ms.begin(), solve_ms.begin() + solve_ms.size() / 2, solve_ms.end());
    t.measured_solve_ms = solve_ms[solve_ms.size() / 2];
  }
  return t;
}

/// The predicted time a candidate is ranked by: the warped factor's × kWarpedMargin.
double ranked_ms(const PreconditionerTrial& t) {
  return t.predicted_solve_ms * (t.preconditioner == Preconditioner::WarpedCholesky ? kWarpedMargin : 1.0);
}

/// Better: converged on more measured steps (all of them first), then the least ranked time,
/// then the smaller residual.
bool better(const PreconditionerTrial& a, const PreconditionerTrial& b) {
  const bool a_all = a.steps > 0 && a.converged == a.steps, b_all = b.steps > 0 && b.converged == b.steps;
  if (a_all != b_all) return a_all;
  if (!a_all && a.converged != b.converged) return a.converged > b.converged;
  if (ranked_ms(a) != ranked_ms(b)) return ranked_ms(a) < ranked_ms(b);
  return a.residual_max < b.residual_max;
}

}  // namespace

double warped_trial_iterations(const PreconditionerChoice& c) {
  for (const PreconditionerTrial& t : c.trials)
    if (t.preconditioner == Preconditioner::WarpedCholesky && t.tried && t.steps > 0) return t.iterations_mean;
  return kTypicalWarpedIterations;
}

PreconditionerChoice choose_preconditioner(const FemModel& model, const StepperSettings& settings, double h,
                                           const ChoiceOptions& options) {
  const IterationCostModel& costs = options.costs;
  const bool budgeted = options.budgeted;
  const int64_t start = steady_now_ns();
  PreconditionerChoice c;
  if (settings.linear_solver != LinearSolverKind::CG || settings.integrator == Integrator::SymplecticEuler ||
      model.elements.empty()) {
    c.preconditioner = Preconditioner::Jacobi;
    c.reason = settings.linear_solver != LinearSolverKind::CG ? "a direct solve: no preconditioner"
                                                              : "no linear solve: no preconditioner";
    return c;
  }
  // The warped factor's size and cost from CHOLMOD's symbolic analysis (no numeric work).
  {
    CholmodSolver analysis(model.pattern);
    c.factor_entries = analysis.factor_entries();
    c.factor_seconds_estimate =
        std::max(kFactorNsPerEntry * 1e-9 * c.factor_entries, analysis.factor_flops() / kFactorFlopsPerSecond);
  }
  const bool factor_ok = c.factor_seconds_estimate <= options.max_factor_seconds;
  const std::string factor_too_big = fmt::format(
      "its factorisation is predicted to take {:.2g} s ({:.3g} M stored entries), over the {:.3g} s limit",
      c.factor_seconds_estimate, c.factor_entries * 1e-6, options.max_factor_seconds);

  if (settings.integrator == Integrator::Static) {
    c.preconditioner = factor_ok ? Preconditioner::WarpedCholesky : Preconditioner::Jacobi;
    c.reason = factor_ok ? "a static solve: the factor of the rest tangent, which Newton's tangents stay near"
                         : "a static solve, Jacobi: the warped factor " + factor_too_big;
    c.trial_ms = (steady_now_ns() - start) * 1e-6;
    return c;
  }

  // Trials: the warped factor first (when it may be made), so that the cheap-per-iteration
  // candidates that need many more iterations stop early against it.
  const FemModel* trial_model = &model;
  std::unique_ptr<FemModel> loaded;
  if (!any_load(model)) {
    loaded = std::make_unique<FemModel>(sheared_copy(model));
    trial_model = loaded.get();
  }
  const Preconditioner order[] = {Preconditioner::WarpedCholesky, Preconditioner::Jacobi, Preconditioner::BlockJacobi};
  double best_ms = HUGE_VAL;
  for (Preconditioner p : order) {
    if (p == Preconditioner::WarpedCholesky && !factor_ok) {
      PreconditionerTrial t;
      t.preconditioner = p;
      t.left_out = factor_too_big;
      c.trials.push_back(t);
      continue;
    }
    const double stop_ms = std::isfinite(best_ms)
                               ? 3.0 * std::max(best_ms, 1e-6 * solve_ns(p, model, c.factor_entries, 1.0, costs))
                               : HUGE_VAL;
    PreconditionerTrial t = run_trial(*trial_model, model, c.factor_entries, settings, h, p, costs, budgeted, stop_ms);
    if (t.steps > 0 && t.converged == t.steps) best_ms = std::min(best_ms, t.predicted_solve_ms);
    c.trials.push_back(t);
  }
  const PreconditionerTrial* best = nullptr;
  for (const PreconditionerTrial& t : c.trials)
    if (t.tried && (!best || better(t, *best))) best = &t;
  c.preconditioner = best ? best->preconditioner : Preconditioner::Jacobi;
  if (best) {
    const bool all = best->converged == best->steps;
    const PreconditionerTrial* next = nullptr;
    for (const PreconditionerTrial& t : c.trials)
      if (t.tried && &t != best && (!next || better(t, *next))) next = &t;
    std::string runner_up;
    if (next)
      runner_up = fmt::format("; next {}: {:.1f} iterations{}, {:.3f} ms", preconditioner_name(next->preconditioner),
                              next->iterations_mean,
                              next->converged == next->steps ? ""
                                                             : fmt::format(" ({} of {} converged)", next->converged,
                                                                           next->steps),
                              next->predicted_solve_ms);
    c.reason = fmt::format("{}: {:.1f} iterations per step{}, predicted {:.3f} ms per solve{}{}",
                           preconditioner_name(best->preconditioner), best->iterations_mean,
                           all ? " to the tolerance" : fmt::format(" ({} of {} steps converged)", best->converged,
                                                                   best->steps),
                           best->predicted_solve_ms, runner_up,
                           loaded ? " (trial under a shearing body load: no gravity)" : "");
  }
  c.trial_ms = (steady_now_ns() - start) * 1e-6;
  return c;
}

}  // namespace stroma
