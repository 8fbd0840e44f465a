#pragma once
/// \file cg_solver.hpp
/// Preconditioned conjugate gradient on a BSR matrix, allocation-free after construction.
/// The stopping test is relative, ‖r‖ ≤ tol·‖b‖, so a small but non-zero system is solved like
/// any other: an absolute threshold (as SOFA's `threshold`) silently returns the initial guess
/// on small-valued SI systems. Zero iterations happen only when the warm start already meets
/// the relative test (or b = 0).

#include <vector>

#include "tissue/bsr_matrix.hpp"
#include "tissue/options.hpp"

namespace stroma {

/// Outcome of one linear solve.
struct SolveStats {
  int iterations = 0;             ///< CG iterations (Newton iterations summed for static)
  double relative_residual = 0;   ///< ‖b − A x‖ / ‖b‖ at exit (0 when b = 0)
  bool converged = true;          ///< false: hit the iteration cap or broke down
};

/// A preconditioner supplied by the caller (used for Preconditioner::WarpedCholesky):
/// z = M⁻¹ r. A plain function pointer: one indirect call per CG iteration, none per element.
struct ExternalPreconditioner {
  void (*apply)(void* context, const double* r, double* z) = nullptr;
  void* context = nullptr;
};

/// Reusable PCG workspace for one system size.
class CgSolver {
 public:
  /// Allocates work vectors for a system of `n` nodes (3n unknowns).
  explicit CgSolver(int32_t n = 0) { resize(n); }
  void resize(int32_t n);
  /// Solves A x = b; `x` holds the initial guess on entry (warm start) and the solution on exit.
  SolveStats solve(const BsrPattern& p, const double* A, const double* b, double* x,
                   Preconditioner prec, int max_iterations, double tolerance,
                   const ExternalPreconditioner* external = nullptr);

 private:
  void build_preconditioner(const BsrPattern& p, const double* A, Preconditioner prec);
  void apply_preconditioner(Preconditioner prec, const double* r, double* z) const;
  const ExternalPreconditioner* external_ = nullptr;
  int32_t n_ = 0;
  std::vector<double> r_, z_, p_, q_, inv_diag_;  // inv_diag_: 3n (Jacobi) or 9n (block)
};

}  // namespace stroma
