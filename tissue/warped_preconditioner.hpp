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

namespace stroma {

/// Steps of length h that 1.5 × a factorisation of `factor_entries` stored entries takes, at
/// 40 ns per entry (what CHOLMOD takes here in wall time, docs/PERFORMANCE.md); 1 … 10⁶.
inline int refresh_steps_for(double factor_entries, double h) {
  const double steps = 1.5 * 40e-9 * factor_entries / h;
  return steps < 1 ? 1 : steps > 1.0e6 ? 1000000 : static_cast<int>(steps + 0.999);
}

/// Invariant: after factor(), op() applies R_Δ A_f⁻¹ R_Δᵀ with the rotations of the last
/// update_rotations() (identity before the first one). factor_key() is the step h A_f was
/// assembled for (h_mass of the rest factor).
class WarpedPreconditioner {
 public:
  explicit WarpedPreconditioner(const FemModel& model);
  /// Factors A₀ with these coefficients (h_mass < 0: no mass term, for static solves). Does
  /// nothing when the current factor already has them — the rest factor with the same ones, or
  /// a refreshed factor of a step with h_mass = k_beta = h, k_const = h² (allocates only when
  /// it refactors).
  void factor(double h_mass, double k_beta, double k_const);
  /// Per-node rotations from the element rotations `rot` (9 per element) of the last element
  /// pass: each node takes its first element's; fixed and unused nodes keep the identity.
  void update_rotations(const double* rot);
  /// The preconditioner as CG takes it (valid while this object lives).
  const ExternalPreconditioner* op() const { return &op_; }

  /// Starts asynchronous refreshes (a worker thread; implicit Euler only): every `period`
  /// steps the last step's system goes to the worker, and at the next step after
  /// request_refresh() when the worker is idle. `deterministic`: the factor is swapped in
  /// exactly refresh_lag() steps after its matrix was handed over, waiting for the worker if it
  /// is late — results then depend on nothing but the inputs (headless runs, replays).
  /// Otherwise (real time) a finished factor is swapped in at the next step and the physics
  /// thread never waits; a late worker only means the older factor stays in use.
  void enable_refresh(int period, bool deterministic);
  /// Asks for a refresh at the next step (the factor fits this system badly: TimeStepper::solve
  /// saw a solve far above its usual iterations, or gave up on it). No effect without
  /// enable_refresh() or while a refresh is under way.
  void request_refresh() { demand_ = true; }
  /// A new refresh period (≥ 1) from the next hand-over on (`auto` re-evaluates it as the ticks
  /// go: TimeStepper). A hand-over already made keeps the period it was made with.
  void set_period(int period) { period_ = period < 1 ? 1 : period; }
  int period() const { return period_; }
  /// Steps between the last hand-over and its swap in deterministic mode: the period at the
  /// hand-over.
  int refresh_lag() const { return lag_; }
  /// Start of a step's assembly: `last_system` holds the previous step's projected system
  /// matrix, assembled for step `h_last` (0: none) in the frame of the last update_rotations().
  /// When a refresh is due it is handed to the worker by swapping buffers (no copy) — the
  /// caller refills `last_system` anyway. Only systems of the current factor's step are handed
  /// over (a sub-step's is not).
  void begin_step(std::vector<double>& last_system, double h_last);
  /// After this step's element pass, before update_rotations(): in real-time mode swaps in a
  /// factor the worker has finished.
  void poll();
  /// True once a factor exists (factor() or a refresh).
  bool factored() const { return factor_ != nullptr && key_[0] != -1; }

  /// What one application costs against one Jacobi-PCG iteration, from the memory each streams:
  /// the factor twice (forward and backward) in float, 8 bytes per stored entry, against the
  /// matrix's 72 bytes per stored block: 1 + 8·entries(L) / (72·blocks). Since the blocked
  /// solves (2026-12-04) the factor streams at about the SpMV's rate; measured per iteration,
  /// warped against Jacobi: liver 13.4 against 4.0 µs (3.3; this estimate 3.5), 0.2 m Armadillo
  /// ~4.3 (5.3). (Before them it streamed at half that rate and the estimate's constant was 16.)
  /// Deterministic, so the fallback it sets (TimeStepper::solve) is too.
  double relative_cost() const {
    return factor_ ? 1.0 + 8.0 * factor_->factor_entries() / (72.0 * m_.pattern.nnzb()) : 1.0;
  }
  /// Stored entries of the factor (after factor()).
  double factor_entries() const { return factor_ ? factor_->factor_entries() : 0.0; }
  int64_t refreshes() const { return refreshes_; }  ///< refreshed factors swapped in
  /// The worker's time for the factors swapped in (CholeskyRefresher::factor_ns_total/max).
  int64_t refresh_factor_ns_total() const { return refresh_ ? refresh_->factor_ns_total() : 0; }
  int64_t refresh_factor_ns_max() const { return refresh_ ? refresh_->factor_ns_max() : 0; }
  /// Time the last begin_step() waited for a late worker (deterministic swap only; 0 in real
  /// time, which never waits). A served tick would not have spent it.
  int64_t last_wait_ns() const { return last_wait_ns_; }
  int64_t rest_factorizations() const { return rest_factorizations_; }  ///< factor() calls that factored
  bool refreshing() const { return refresh_ != nullptr; }

 private:
  static void apply(void* self, const double* r, double* z);
  void adopt(bool wait);
  const FemModel& m_;
  std::unique_ptr<CholmodSolver> factor_;
  double key_[3] = {-1, -1, -1};  // coefficients the current factor was built with
  std::vector<double> node_abs_;   // per-node rotation from the last update (9 per node)
  std::vector<double> factor_rot_; // per-node rotation when A_f was assembled (identity: rest)
  std::vector<double> node_rot_;   // R_Δ = R·R_fᵀ, what apply() uses
  std::vector<double> a_, b_;
  ExternalPreconditioner op_;
  std::unique_ptr<CholeskyRefresher> refresh_;
  int period_ = 0;
  int lag_ = 0;
  bool demand_ = false;
  bool deterministic_ = true;
  int steps_since_offer_ = 0;
  int64_t refreshes_ = 0;
  int64_t rest_factorizations_ = 0;
  int64_t last_wait_ns_ = 0;
};

}  // namespace stroma
