#pragma once
/// \file warped_preconditioner.hpp
/// The warped Cholesky preconditioner (solver.preconditioner: warped_cholesky): a CHOLMOD factor
/// of a system matrix A_f, applied in each node's frame rotated since A_f was assembled:
/// z = R_Δ A_f⁻¹ R_Δᵀ r, R_Δ = R·R_fᵀ per node (the rotation of an element around the node, from
/// the last element pass, against the one when A_f was assembled).
///
/// A_f starts as the system at rest, A₀ = (1 + h_mass·α)·M + (k_beta·β + k_const)·K(rest),
/// factored once (R_f = I). Warping keeps it good while rotations are what changes the tangent;
/// it degrades when the deformation itself does, and it never contains contact stiffness. With
/// a refresh (enable_refresh) a worker thread factors the system of a recent step and the
/// physics thread swaps it in (tissue/cholesky_refresh.hpp): the factor then lags the tangent
/// by the refresh period and sees contacts, large strain and damage (docs/PERFORMANCE.md).

#include <cstdint>
#include <memory>
#include <vector>

#include "tissue/cg_solver.hpp"
#include "tissue/cholesky_refresh.hpp"
#include "tissue/cholmod_solver.hpp"
#include "tissue/fem_model.hpp"
#include "tissue/tissue_state.hpp"

namespace stroma {

/// Steps of length h that 1.5 × a factorisation of `factor_entries` stored entries takes, at
/// 40 ns per entry (what CHOLMOD takes here in wall time, docs/PERFORMANCE.md); 1 … 10⁶.
inline int refresh_steps_for(double factor_entries, double h) {
  const double steps = 1.5 * 40e-9 * factor_entries / h;
  return steps < 1 ? 1 : steps > 1.0e6 ? 1000000 : static_cast<int>(steps + 0.999);
}

/// A refresh id not used before in this process (SolverHistory names its factors by them).
uint64_t new_refresh_id();

/// Invariant: after factor(), op() applies R_Δ A_f⁻¹ R_Δᵀ with the rotations of the last
/// update_rotations() (identity before the first one), A_f the rest-pose system or — with a
/// refresh — the system of the refresh the state's SolverHistory names (factor_id). The schedule
/// of the refreshes lives in that history, not here: a copy of the state is a copy of it.
class WarpedPreconditioner {
 public:
  explicit WarpedPreconditioner(const FemModel& model);
  /// Factors the rest-pose system A₀ with these coefficients (h_mass < 0: no mass term, for
  /// static solves). Does nothing when the rest factor already has them (allocates only when it
  /// factors).
  void factor(double h_mass, double k_beta, double k_const);
  /// Per-node rotations from the element rotations `rot` (9 per element) of the last element
  /// pass: each node takes its first element's; fixed and unused nodes keep the identity.
  void update_rotations(const double* rot);
  /// The preconditioner as CG takes it (valid while this object lives).
  const ExternalPreconditioner* op() const { return &op_; }

  /// Starts asynchronous refreshes (a worker thread; implicit Euler only): every history period
  /// steps a step's system goes to the worker, and at the next step after request_refresh()
  /// when the worker is idle. `deterministic`: the step's own system is handed over (a copy of it
  /// kept in the state's history) and its factor is swapped in exactly `lag` (= the period) steps later,
  /// waiting for the worker if it is late — results then depend on nothing but the inputs and
  /// the state (headless runs, replays, restored snapshots). Otherwise (real time) the last
  /// step's system goes over by swapping buffers (no copy), a finished factor is swapped in at
  /// the next step and the physics thread never waits; a late worker only means the older factor
  /// stays in use.
  void enable_refresh(bool deterministic);
  /// Start of a step's assembly. First aligns the factors with the state's history `h` (after a
  /// restore the history may name a refresh this object does not hold: its factor is remade
  /// from the system stored in `h`, synchronously, and a pending one is handed over again —
  /// `carrier`, a buffer of the system's size the caller refills anyway, takes it). Then, in
  /// real time: swaps in a finished factor, and hands `last_system` (the previous step's
  /// projected system, assembled for step `h_last`, by buffer swap) to the worker when due.
  /// Deterministic: swaps in the pending factor when its lag has passed. `h_now`: this step's
  /// h; only full steps (the rest factor's h) count in the schedule, and only their systems are
  /// handed over (a sub-step's is not).
  void begin_step(std::vector<double>& last_system, double h_last, double h_now, SolverHistory& h);
  /// End of a step's assembly, deterministic mode: hands this step's `system` over (a copy)
  /// when due, with a copy in `h`.
  void end_assembly(const std::vector<double>& system, double h_step, SolverHistory& h);
  /// True once a factor exists (factor()).
  bool factored() const { return rest_ != nullptr && key_[0] != -1; }

  /// What one application costs against one Jacobi-PCG iteration, from the memory each streams:
  /// the factor twice (forward and backward) in float, 8 bytes per stored entry, against the
  /// matrix's 72 bytes per stored block: 1 + 8·entries(L) / (72·blocks). Since the blocked
  /// solves (2026-12-04) the factor streams at about the SpMV's rate; measured per iteration,
  /// warped against Jacobi: liver 13.4 against 4.0 µs (3.3; this estimate 3.5), 0.2 m Armadillo
  /// ~4.3 (5.3). (Before them it streamed at half that rate and the estimate's constant was 16.)
  /// Deterministic, so the fallback it sets (TimeStepper::solve) is too.
  double relative_cost() const {
    return rest_ ? 1.0 + 8.0 * rest_->factor_entries() / (72.0 * m_.pattern.nnzb()) : 1.0;
  }
  /// Stored entries of the factor (after factor()).
  double factor_entries() const { return rest_ ? rest_->factor_entries() : 0.0; }
  int64_t refreshes() const { return refreshes_; }  ///< refreshed factors swapped in
  /// Factors remade synchronously from a restored history (sync).
  int64_t remade() const { return remade_; }
  /// The worker's time for the factors swapped in (CholeskyRefresher::factor_ns_total/max).
  int64_t refresh_factor_ns_total() const { return refresh_ ? refresh_->factor_ns_total() : 0; }
  int64_t refresh_factor_ns_max() const { return refresh_ ? refresh_->factor_ns_max() : 0; }
  /// Time the last begin_step() waited for a late worker (deterministic swap only; 0 in real
  /// time, which never waits). A served tick would not have spent it.
  int64_t last_wait_ns() const { return last_wait_ns_; }
  int64_t rest_factorizations() const { return rest_factorizations_; }  ///< factor() calls that factored
  bool refreshing() const { return refresh_ != nullptr; }
  bool deterministic() const { return deterministic_; }

 private:
  static void apply(void* self, const double* r, double* z);
  /// Makes the factors agree with `h` (see begin_step).
  void sync(SolverHistory& h, std::vector<double>& carrier);
  /// Takes the worker's finished factor (waiting for it with `wait`) into `h`.
  void adopt(SolverHistory& h, bool wait);
  /// Hands `system` to the worker as refresh `id` (copied with `copy`, else by buffer swap).
  bool hand_over(std::vector<double>& system, const double* node_rot, double key, uint64_t id, bool copy);
  const FemModel& m_;
  std::unique_ptr<CholmodSolver> rest_;       ///< the rest-pose factor (factor())
  std::unique_ptr<CholmodSolver> refreshed_;  ///< the refreshed factor in use, if any
  const CholmodSolver* active_ = nullptr;     ///< rest_ or refreshed_
  uint64_t refreshed_id_ = 0;                 ///< the refresh refreshed_ holds (0: none)
  uint64_t job_id_ = 0;                       ///< the refresh handed to the worker (0: none)
  /// Real time: the worker is factoring a job no history wants (a reset or restored state
  /// dropped it); its result is dropped once it is finished, never waited for.
  bool orphan_job_ = false;
  double key_[3] = {-1, -1, -1};  // coefficients the rest factor was built with
  std::vector<double> node_abs_;   // per-node rotation from the last update (9 per node)
  std::vector<double> factor_rot_; // per-node rotation when A_f was assembled (identity: rest)
  std::vector<double> node_rot_;   // R_Δ = R·R_fᵀ, what apply() uses
  std::vector<double> a_, b_, offer_;  // offer_: the worker's copy, deterministic mode
  ExternalPreconditioner op_;
  std::unique_ptr<CholeskyRefresher> refresh_;
  bool deterministic_ = true;
  int64_t refreshes_ = 0, remade_ = 0;
  int64_t rest_factorizations_ = 0;
  int64_t last_wait_ns_ = 0;
};

}  // namespace stroma
