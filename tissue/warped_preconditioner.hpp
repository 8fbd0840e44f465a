#pragma once
/// \file warped_preconditioner.hpp
/// The warped rest-pose Cholesky preconditioner (solver.preconditioner: warped_cholesky): the
/// system matrix at rest, A₀ = (1 + h_mass·α)·M + (k_beta·β + k_const)·K(rest), factored once by
/// CHOLMOD, applied as z = R A₀⁻¹ Rᵀ r with one rotation per node (the rotation of an element
/// around it, from the last element pass). Good while rotations are what changes the tangent;
/// it degrades when the deformation itself does (docs/PERFORMANCE.md).

#include <memory>
#include <vector>

#include "tissue/cg_solver.hpp"
#include "tissue/cholmod_solver.hpp"
#include "tissue/fem_model.hpp"

namespace stroma {

/// Invariant: after factor(), op() applies R A₀⁻¹ Rᵀ with the rotations of the last
/// update_rotations(); before the first update the rotations are the identity.
class WarpedPreconditioner {
 public:
  explicit WarpedPreconditioner(const FemModel& model);
  /// Factors A₀ with these coefficients (h_mass < 0: no mass term, for static solves). Does
  /// nothing when already factored with the same ones (allocates only when it refactors).
  void factor(double h_mass, double k_beta, double k_const);
  /// Per-node rotations from the element rotations `rot` (9 per element) of the last element
  /// pass: each node takes its first element's; fixed and unused nodes keep the identity.
  void update_rotations(const double* rot);
  /// The preconditioner as CG takes it (valid while this object lives).
  const ExternalPreconditioner* op() const { return &op_; }

 private:
  static void apply(void* self, const double* r, double* z);
  const FemModel& m_;
  std::unique_ptr<CholmodSolver> factor_;
  double key_[3] = {-1, -1, -1};  // coefficients it was factored with
  std::vector<double> node_rot_, a_, b_;
  ExternalPreconditioner op_;
};

}  // namespace stroma
