#pragma once
/// \file cg_solver.hpp
/// Preconditioned conjugate gradient on a BSR matrix, allocation-free after construction.
/// The stopping test is relative, ‖r‖ ≤ tol·‖b‖, so a small but non-zero system is solved like
/// any other: an absolute threshold (as SOFA's `threshold`) silently returns the initial guess
/// on small-valued SI systems. Zero iterations happen only when the warm start already meets
/// the relative test (or b = 0).

#include <array>
#include <cstdint>
#include <vector>

#include "tissue/bsr_matrix.hpp"
#include "tissue/deadline.hpp"
#include "tissue/options.hpp"
#include "tissue/rod.hpp"

namespace stroma {

/// Outcome of one linear solve.
struct SolveStats {
  int iterations = 0;             ///< CG iterations (Newton iterations summed for static)
  double relative_residual = 0;   ///< ‖b − A x‖ / ‖b‖ at exit (0 when b = 0)
  bool converged = true;          ///< false: hit the iteration cap, the deadline, or broke down
  bool budget_stopped = false;    ///< stopped by the deadline (converged is then false)
  bool started_from_zero = false; ///< the initial guess was worse than zero and was dropped
  /// Warped Cholesky: the solve spent its warped share (TimeStepper) without converging and
  /// Jacobi-PCG continued from its iterate (`iterations` counts both).
  bool preconditioner_fallback = false;
  /// Stopped by the progress test (CgSolver::solve's `progress_from`): at its mean rate since
  /// the start it would not have converged within its cap.
  bool stalled = false;
  /// Bound on the solve's error in the system's energy norm: ½‖x − x*‖²_A ≤ ½ rᵀM⁻¹r with M
  /// the mass part of A (A ≥ M: stiffness, damping and contact terms are PSD). It is exactly
  /// how far the step's quadratic incremental potential is above its minimum (J). Filled by
  /// the time stepper (0 for direct solves).
  double error_energy = 0;
  /// Mass-weighted RMS bound on the position error of the step it implies (m): h·√(rᵀM⁻¹r / Σm).
  double error_position = 0;
};

/// A preconditioner supplied by the caller (used for Preconditioner::WarpedCholesky):
/// z = M⁻¹ r. A plain function pointer: one indirect call per CG iteration, none per element.
struct ExternalPreconditioner {
  void (*apply)(void* context, const double* r, double* z) = nullptr;
  void* context = nullptr;
};

/// A further, matrix-free part of the system supplied by the caller: A = A_bsr + A_x, with
/// apply(context, x, y) adding A_x·x to y and `diag` (9 per node, may be null) A_x's diagonal
/// blocks for the Jacobi preconditioners (the locking-free node domains, nodal_smoothing.hpp).
struct ExtraOperator {
  void (*apply)(void* context, const double* x, double* y) = nullptr;
  void* context = nullptr;
  const double* diag = nullptr;
};

/// Reusable PCG workspace for one system size. Invariant: every vector holds 3n entries (9n for
/// the block-Jacobi inverse) from resize() on; solve() allocates nothing.
class CgSolver {
 public:
  /// Allocates work vectors for a system of `n` nodes (3n unknowns).
  explicit CgSolver(int32_t n = 0) { resize(n); }
  void resize(int32_t n);
  /// Solves A x = b; `x` holds the initial guess on entry (warm start) and the solution on exit.
  /// `deadline` (null: none) is checked after every iteration: iterations stop once it has
  /// passed (the iterate is kept: CG's iterates lower the quadratic ½xᵀAx − bᵀx monotonically). `safe_start`: if the
  /// initial guess is worse than zero in that quadratic (−½x₀ᵀ(b + r₀) > 0, free from r₀), start
  /// from zero instead — so a truncated solve is never worse than no correction at all.
  /// `progress_from` (0: off): from that iteration on, the solve stops (SolveStats::stalled)
  /// once the iterations it would need at its mean residual reduction per iteration so far,
  /// (‖r_k‖/‖r_0‖)^(1/k), exceed `progress_limit` (≤ max_iterations) — a preconditioner that
  /// fits this system badly is given up, one that is about to converge runs on
  /// (TimeStepper::solve's fallback). `look_ahead`: with a deadline, the solve also stops
  /// before an iteration that would end past it (at the duration of the last one) — for
  /// preconditioners whose iterations are coarse (the warped factor's triangular solves, ~0.2 ms
  /// at 4k nodes), which would otherwise overrun a budget by up to a whole iteration.
  SolveStats solve(const BsrPattern& p, const double* A, const double* b, double* x,
                   Preconditioner prec, int max_iterations, double tolerance,
                   const ExternalPreconditioner* external = nullptr, Deadline* deadline = nullptr,
                   bool safe_start = false, const ExtraOperator* extra = nullptr, int progress_from = 0,
                   int progress_limit = 0, bool look_ahead = false);
  /// The residual b − A x of the last solve (3n).
  const double* residual() const { return r_.data(); }
  /// Rods (tissue/rod.hpp) of the system: under Jacobi and block Jacobi (and none), each rod's
  /// rows are preconditioned by the exact inverse of the rod's own sub-matrix — banded (its
  /// stretching and bending stencils couple nodes i..i+2: 8 scalar diagonals), factored by
  /// LAPACK's banded Cholesky at each solve in O(nodes) — instead of its diagonal blocks: a
  /// suture's stretching is 10³..10⁶ times its nodes' mass at a 1 ms step, and a chain of such
  /// springs under Jacobi needs iterations in proportion to its length (a 60-segment thread
  /// capped CG at 200). The preconditioner stays symmetric positive definite (block diagonal:
  /// the tissue's blocks, the rods' bands). Load time: sizes the factor's storage (no
  /// allocation in solve()). `p` is the system's pattern.
  void set_rods(const BsrPattern& p, const std::vector<RodRange>& rods);

 private:
  void build_preconditioner(const BsrPattern& p, const double* A, Preconditioner prec, const double* extra_diag);
  void apply_preconditioner(Preconditioner prec, const double* r, double* z) const;
  void factor_rod_bands(const double* A, const double* extra_diag);
  void solve_rod_bands(const double* r, double* z) const;
  /// Per rod: its first node, node count and offset into rod_band_; per rod node (rods in
  /// order) the slots of its blocks (i, i), (i, i+1), (i, i+2) (−1 past the rod's end); the
  /// rods' factors in LAPACK band storage (9 × 3·nodes each); whether each factored.
  std::vector<std::array<int32_t, 3>> rods_;
  std::vector<std::array<int32_t, 3>> rod_slot_;
  std::vector<double> rod_band_;
  std::vector<uint8_t> rod_ok_;
  const ExternalPreconditioner* external_ = nullptr;
  int32_t n_ = 0;
  std::vector<double> r_, z_, p_, q_, inv_diag_;  // inv_diag_: 3n (Jacobi) or 9n (block)
};

}  // namespace stroma
