#pragma once
/// \file step_with_recovery.hpp
/// The tick's physics step and the engine's self-defence around it: assemble → solve →
/// integrate over the time step; speculative body contacts that ended pulling are released and
/// the step redone (at most kMaxContactReleases times); a step that is not sane (non-finite, a
/// capped solve while solver.on_cg_cap is `substep`, or a node moving more than
/// Model::max_step_displacement) is rolled back and redone in 2, 4, … kMaxSubsteps sub-steps.

#include "engine/model.hpp"
#include "engine/state.hpp"
#include "engine/tick.hpp"

namespace stroma {

/// Advances s.tissue by one time step with this tick's springs (w.springs), recording stage
/// times, solver statistics, sub-steps and status in r. On return the tissue state is finite:
/// advanced (Ok, SolverNotConverged, Recovered) or rolled back to the start of the tick
/// (NonFinite). Leaves the start-of-tick positions and velocities in w.backup_x / backup_v.
void step_with_recovery(const Model& m, State& s, TickWorkspace& w, TickReport& r);

}  // namespace stroma
