#pragma once
/// \file tissue_state.hpp
/// The small mutable state of the deformable bodies. Snapshot and restore are plain copies.

#include <vector>

#include "tissue/fem_model.hpp"

namespace stroma {

/// What the time stepper's next solves depend on besides positions and velocities
/// (TimeStepper): whether the last solves converged (the warm start extrapolates only from two
/// converged increments) and, with a warped Cholesky factor refreshed on a worker thread, the
/// systems its factor in use and the one being made were assembled from, and the schedule
/// between them. Copying a state copies the solver's history, so a restored snapshot replays bit
/// for bit: a stepper that finds another history than its own (ids differ) remakes the factor
/// from the stored system at its next step (WarpedPreconditioner::sync). Invariant: the
/// matrices are empty unless the model refreshes its factor (then 9 per stored block, sized by
/// State::initial, and filled only in deterministic — headless — mode); ids are unique in the
/// process (0: the rest-pose factor, or none handed over).
struct SolverHistory {
  int32_t converged_in_a_row = 2;    ///< solves converged in a row (the rest state counts as two)
  uint64_t factor_id = 0;            ///< the refresh in use; 0: the rest-pose factor
  double factor_key = 0;             ///< the step h its system was assembled for
  std::vector<double> factor_matrix; ///< its system (BSR values)
  std::vector<double> factor_rot;    ///< the node rotations it was assembled in (9 per node)
  uint64_t pending_id = 0;           ///< the refresh being made; 0: none
  double pending_key = 0;
  std::vector<double> pending_matrix, pending_rot;
  int32_t steps_since_offer = 0;     ///< steps since the last hand-over
  int32_t period = 0;                ///< steps between hand-overs (`auto`: re-evaluated)
  int32_t lag = 0;                   ///< steps from the pending hand-over to its swap
  bool demand = false;               ///< a solve asked for a refresh at the next step
  double pace_iterations = 2;        ///< running mean (1/16) of every warped solve's iterations
  double typical_iterations = 0;     ///< running mean of the converged warped solves' iterations
  int64_t warped_solves = 0;         ///< converged warped solves so far
  /// `solver.stiffness_every: N` > 1 (StepperSettings): the elements' stiffness blocks
  /// h(β + h)·R·Ke·Rᵀ the steps solve with (BSR values of the model's pattern), the ones being
  /// made — a 1/N share of the element batches each step, those of `element_blocks_phase` —,
  /// which replace them once complete, the phase (−1: none yet, the next step makes them all)
  /// and the step h they are for. State, not scratch: the next steps solve with them, so a
  /// snapshot replays bit for bit only with them.
  std::vector<double> element_blocks, element_blocks_next;
  double element_blocks_key = 0;
  int32_t element_blocks_phase = -1;
};

/// Positions, velocities, the solver's warm start and history. Everything else is either in
/// the immutable FemModel or scratch space that need not survive a tick. Invariants: the four
/// arrays have 3·num_nodes entries; fixed DOFs keep their rest (or driven) position and zero
/// velocity; after any tick every entry is finite (a tick that cannot keep them so is rolled
/// back).
struct TissueState {
  std::vector<double> x;   ///< 3n positions (m)
  std::vector<double> v;   ///< 3n velocities (m/s)
  std::vector<double> dv;  ///< 3n last velocity increment: CG warm start (implicit Euler)
  std::vector<double> dv_prev;  ///< 3n velocity increment of the tick before (extrapolation)
  /// Visco-elastic internal variables (viscoelastic.hpp; empty without visco-elastic bodies):
  /// each branch's overstress Qᵢ and the instantaneous stress σ₀ at the positions x, per element
  /// in its rotated frame (6 values: xx yy zz xy xz yz; FemModel sizes and ElementRange offsets).
  std::vector<double> visco_q, visco_s0;
  SolverHistory solver;  ///< see SolverHistory

  /// State at rest: x = rest positions, v = 0.
  static TissueState at_rest(const FemModel& m) {
    TissueState s;
    s.x = m.rest;
    s.v.assign(m.rest.size(), 0.0);
    s.dv.assign(m.rest.size(), 0.0);
    s.dv_prev.assign(m.rest.size(), 0.0);
    s.visco_q.assign(static_cast<size_t>(m.visco_q_size), 0.0);
    s.visco_s0.assign(static_cast<size_t>(m.visco_s0_size), 0.0);
    return s;
  }
};

}  // namespace stroma
