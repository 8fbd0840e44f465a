#pragma once
/// \file constraints.hpp
/// Projection of Dirichlet constraints (fixed degrees of freedom, per axis) onto an assembled
/// BSR system: rows and columns of constrained DOFs are zeroed and their diagonal entry set, so
/// the solution there is exactly zero (the right-hand side is zeroed by the caller).

#include "tissue/fem_model.hpp"

namespace stroma {

/// True if DOF `axis` (0..2) of node i is constrained.
inline bool dof_constrained(const FemModel& m, int32_t node, int axis) {
  return (m.constrained[node] >> axis) & 1;
}

/// Projects the constraints of `m` onto BSR values `A`: constrained rows/columns zeroed, the
/// diagonal of a constrained DOF of node i set to diag_scale·mass_i (diag_scale if the node
/// has no mass).
void project_constraints(const FemModel& m, double* A, double diag_scale, bool scale_by_mass);

}  // namespace stroma
