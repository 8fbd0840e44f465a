#pragma once
/// \file static_run.hpp
/// Static equilibria (solver.integrator: static) with load stepping. The engine brings the
/// tissue from one equilibrium to the next along a path of parameters — the load factor λ that
/// multiplies the constant external forces (gravity, nodal loads), the contact factor κ that
/// multiplies every contact spring (tools and bodies), and each tool's pose — and solves each
/// increment with Newton (TimeStepper::solve_static, contacts recomputed at every iterate).
///
/// Continuation rule: from the last equilibrium (parameter t_done, 0 at the start) the solver
/// tries the whole remaining increment; a Newton attempt that does not converge within
/// static_max_newton iterations, turns non-finite or grows its residual past kStaticDivergence
/// × its start is abandoned — the positions go back to the last equilibrium — and the increment
/// is halved; after a converged increment the next is twice as long (up to what remains).
/// Below kMinStaticIncrement of the path the solve fails, keeping the last equilibrium.
///
/// The first equilibrium of a run starts at rest with λ = κ = 0 (the tools in their pose at
/// t = 0, the contacts faded in with κ); each later one (a quasi-static run with --steps or
/// --duration) starts from the previous equilibrium with λ = κ = 1 and moves the tools from
/// their previous scripted pose to the current one.

#include <vector>

#include "engine/model.hpp"
#include "engine/state.hpp"
#include "engine/tick.hpp"

namespace stroma {

/// Smallest increment, as a fraction of the path, before a static solve gives up.
inline constexpr double kMinStaticIncrement = 1.0 / 1024.0;

/// Parameters of a static equilibrium (the ends of a continuation path).
struct StaticParameters {
  double load = 1.0;                ///< λ: multiplies the constant external forces
  double contact = 1.0;             ///< κ: multiplies every contact spring
  std::vector<ToolPose> tool_poses;  ///< per tool (empty: the tools keep their poses)
};

/// What reaching one equilibrium took.
struct StaticOutcome {
  bool converged = false;
  int increments = 0;           ///< converged increments (1: reached in one go)
  int attempts = 0;             ///< Newton solves tried, failed ones included
  int newton_iterations = 0;    ///< summed over the attempts
  int linear_iterations = 0;    ///< CG iterations summed (0 with CHOLMOD)
  double relative_residual = 0; ///< of the last attempt
  double reached = 0;           ///< fraction of the path reached (1 when converged)
  /// Failed because Newton stalled below kStaticRoundoffLevel: the static_tolerance asked is
  /// below what round-off allows for this problem (smaller increments would not help).
  bool roundoff_stall = false;
  double best_residual = 0;     ///< the smallest relative residual the last attempt reached
  int64_t collide_ns = 0, solve_ns = 0;  ///< wall time in contact search, and the rest
};

/// Brings `s` (an equilibrium at `from`, or the rest state) to equilibrium at `to`. Tools with a
/// shape are found in contact at every Newton iterate; on return w.report.tools holds each
/// tool's contact force at the final positions and its device feedback. On failure s holds the
/// last equilibrium reached.
StaticOutcome solve_equilibrium(const Model& m, State& s, TickWorkspace& w, const StaticParameters& from,
                                const StaticParameters& to);

}  // namespace stroma
