#pragma once
/// \file solver_report.hpp
/// What solver a compiled scenario runs and where each setting came from — the scenario, or
/// the engine's choice (`auto`: tissue/solver_choice.hpp) — in the forms the front ends show:
/// one log line at start (`stroma run`, `check`, `serve`, the Python module), an object in
/// summary.json and in `serve --stats`, and the short form SimStatus carries.

#include <string>

#include <nlohmann/json.hpp>

#include "scene/compiled_scenario.hpp"

namespace stroma {

/// One line: the solver, its tolerance and cap, the preconditioner and its refresh, the cap
/// policy, each marked (auto) or (scenario), and for `auto` what the trial found.
std::string solver_summary(const CompiledScenario& c);

/// A few words for SimStatus: "warped_cholesky (auto), refresh 10".
std::string solver_short(const CompiledScenario& c);

/// The same as an object: {linear_solver, tolerance, max_iterations, preconditioner,
/// preconditioner_chosen_by, preconditioner_refresh, on_cg_cap, on_cg_cap_chosen_by, choice:
/// {reason, trial_ms, factor_entries, trials: [{preconditioner, iterations_mean, …}]}}.
nlohmann::ordered_json solver_json(const CompiledScenario& c);

}  // namespace stroma
