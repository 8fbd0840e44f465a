#include "scene/solver_report.hpp"

#include <fmt/format.h>

namespace stroma {

namespace {
bool refreshes(const Model& m) {
  return m.stepper.preconditioner == Preconditioner::WarpedCholesky && m.stepper.integrator == Integrator::ImplicitEuler &&
         m.stepper.linear_solver == LinearSolverKind::CG;
}
}  // namespace

std::string solver_summary(const CompiledScenario& c) {
  const Model& m = *c.model;
  const SolverSpec& s = c.spec.solver;
  const StepperSettings& st = m.stepper;
  if (st.integrator == Integrator::SymplecticEuler) return "solver: symplectic Euler (no linear solve)";
  if (st.linear_solver == LinearSolverKind::Cholmod) return "solver: CHOLMOD (a direct solve each step)";
  std::string line = fmt::format("solver: CG to {:g} (cap {}), preconditioner {} ({})", st.tolerance, st.max_iterations,
                                 preconditioner_name(st.preconditioner), s.preconditioner ? "scenario" : "auto");
  if (refreshes(m)) {
    if (st.preconditioner_refresh <= 0)
      line += fmt::format(", refresh off ({})", s.preconditioner_refresh == 0 ? "scenario" : "auto");
    else if (st.refresh_follows_pace)
      line += fmt::format(", refreshed every ~{} steps as the ticks' pace allows, and on demand (auto)",
                          st.preconditioner_refresh);
    else
      line += fmt::format(", refreshed every {} steps and on demand (scenario)", st.preconditioner_refresh);
  }
  if (st.integrator == Integrator::ImplicitEuler)
    line += fmt::format(", capped steps {} ({})", m.substep_on_cg_cap ? "redone in sub-steps" : "kept",
                        s.on_cg_cap == CapPolicy::Auto ? "auto" : "scenario");
  if (c.solver_choice) line += fmt::format("; chose {} in {:.0f} ms", c.solver_choice->reason, c.solver_choice->trial_ms);
  return line;
}

std::string solver_short(const CompiledScenario& c) {
  const Model& m = *c.model;
  const StepperSettings& st = m.stepper;
  if (st.integrator == Integrator::SymplecticEuler) return "symplectic Euler";
  if (st.linear_solver == LinearSolverKind::Cholmod) return "cholmod";
  std::string s = fmt::format("{} ({})", preconditioner_name(st.preconditioner), c.spec.solver.preconditioner ? "scenario" : "auto");
  if (refreshes(m)) s += st.preconditioner_refresh > 0 ? fmt::format(", refresh {}", st.preconditioner_refresh) : ", refresh off";
  return s;
}

nlohmann::ordered_json solver_json(const CompiledScenario& c) {
  const Model& m = *c.model;
  const SolverSpec& s = c.spec.solver;
  const StepperSettings& st = m.stepper;
  nlohmann::ordered_json j;
  j["linear_solver"] = st.linear_solver == LinearSolverKind::CG ? "cg" : "cholmod";
  j["tolerance"] = st.tolerance;
  j["max_iterations"] = st.max_iterations;
  j["preconditioner"] = preconditioner_name(st.preconditioner);
  j["preconditioner_chosen_by"] = s.preconditioner ? "scenario" : "auto";
  if (refreshes(m)) {
    j["preconditioner_refresh"] = st.preconditioner_refresh > 0 ? nlohmann::ordered_json(st.preconditioner_refresh)
                                                                : nlohmann::ordered_json("off");
    j["preconditioner_refresh_chosen_by"] = s.preconditioner_refresh < 0 ? "auto" : "scenario";
    // auto: the period above is the first; the stepper re-evaluates it from its iterations.
    j["preconditioner_refresh_follows_pace"] = st.refresh_follows_pace;
  }
  if (st.integrator == Integrator::ImplicitEuler) {
    j["on_cg_cap"] = m.substep_on_cg_cap ? "substep" : "continue";
    j["on_cg_cap_chosen_by"] = s.on_cg_cap == CapPolicy::Auto ? "auto" : "scenario";
  }
  if (c.solver_choice) {
    const PreconditionerChoice& ch = *c.solver_choice;
    nlohmann::ordered_json trials = nlohmann::ordered_json::array();
    for (const PreconditionerTrial& t : ch.trials) {
      nlohmann::ordered_json o;
      o["preconditioner"] = preconditioner_name(t.preconditioner);
      if (!t.tried) {
        o["left_out"] = t.left_out;
      } else {
        o["steps"] = t.steps;
        o["converged"] = t.converged;
        o["iterations_mean"] = t.iterations_mean;
        o["iterations_max"] = t.iterations_max;
        o["residual_max"] = t.residual_max;
        o["iteration_us_model"] = t.iteration_ns * 1e-3;
        o["predicted_solve_ms"] = t.predicted_solve_ms;
        o["measured_solve_ms"] = t.measured_solve_ms;
        if (t.stopped_early) o["stopped_early"] = true;
      }
      trials.push_back(o);
    }
    j["choice"] = {{"reason", ch.reason},
                   {"trial_ms", ch.trial_ms},
                   {"factor_entries", ch.factor_entries},
                   {"factor_seconds_estimate", ch.factor_seconds_estimate},
                   {"trials", trials}};
  }
  return j;
}

}  // namespace stroma
