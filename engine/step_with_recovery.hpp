#pragma once
/// \file step_with_recovery.hpp
/// The tick's physics step and the engine's self-defence around it: assemble → solve →
/// integrate over the time step; speculative body contacts that ended pulling are released and
/// the step redone (at most kMaxContactReleases times); a step that is not sane (non-finite, a
/// capped solve while solver.on_cg_cap is `substep`, or a node moving more than
/// Model::max_step_displacement) is rolled back and redone in 2, 4, … kMaxSubsteps sub-steps.
///
/// A step whose linear solve did not converge (capped with `on_cg_cap: continue`, or stopped by
/// the deadline) is kept only without an energy gain: TimeStepper::energy_guard takes out what
/// it added (TickReport::energy_limit, energy_removed) — where the guard applies
/// (TimeStepper::energy_guard_applies: not with QR-rotation bodies, which keep it as solved).
///
/// With a deadline (the tick's time budget) nothing here runs past it; what does not fit
/// degrades (TickReport::degradation):
///  - CG stops at the deadline and its iterate is kept if the step is sane (SolveTruncated);
///  - Newton iterations stop at the last accepted iterate (NewtonStopped);
///  - releases of pulling speculative contacts are skipped (ReleasesSkipped);
///  - the sub-step ladder stops: the sub-steps done are kept, the rest of the tick is not
///    simulated (LadderStopped) — or, when no sane step exists yet, the tissue is rolled back
///    and held still for the tick, its velocities zeroed (Held): every energy is kept or lost,
///    none gained; time advances, so a real-time loop never stalls.

#include "engine/model.hpp"
#include "engine/state.hpp"
#include "engine/tick_types.hpp"
#include "tissue/deadline.hpp"

namespace stroma {

/// Advances s.tissue by one time step with this tick's springs (w.springs), recording stage
/// times, solver statistics, sub-steps and status in r. On return the tissue state is finite:
/// advanced (Ok, SolverNotConverged, Recovered) or rolled back to the start of the tick
/// (NonFinite). Leaves the start-of-tick positions and velocities in w.backup_x / backup_v.
void step_with_recovery(const Model& m, State& s, TickWorkspace& w, TickReport& r, Deadline& deadline);

}  // namespace stroma
