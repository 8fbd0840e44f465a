#pragma once
/// \file options.hpp
/// Choices of element model, rotation extraction, integrator and linear solver. Plain enums
/// shared by the tissue layer and the scenario spec (engine/) that selects them.

namespace stroma {

/// Time integration scheme.
enum class Integrator {
  ImplicitEuler,    ///< linearised backward Euler, one Newton step per tick
  SymplecticEuler,  ///< explicit, conditionally stable (for comparison)
  Static            ///< Newton iterations to equilibrium (CHOLMOD or CG per iteration)
};
/// Linear solver for the implicit/static systems.
enum class LinearSolverKind { CG, Cholmod };
/// Preconditioner of the conjugate gradient.
enum class Preconditioner {
  Jacobi,       ///< inverse of the scalar diagonal
  BlockJacobi,  ///< inverse of each node's 3×3 diagonal block
  None,
  /// CHOLMOD factor of the rest-pose system, applied in each node's rotated frame:
  /// z = R·A₀⁻¹·Rᵀ·r (SOFA's WarpPreconditioner; Courtecuisse et al.). Factored once; strong
  /// for stiff bodies where Jacobi needs hundreds of iterations.
  WarpedCholesky
};
/// Initial guess of the iterative solve each tick.
enum class WarmStart {
  Off,          ///< start from zero
  Previous,     ///< start from the previous tick's Δv
  Extrapolate   ///< start from 2·Δv(n−1) − Δv(n−2): velocity increments vary smoothly in time
};
/// Element formulation.
enum class ElementModel {
  Corotational,  ///< small strain in a per-element rotated frame (large rotations)
  Linear,        ///< small strain, small rotation (fails under rotation: for comparison)
  StableNeoHookean,  ///< hyperelastic, inversion-robust (tissue/stable_neo_hookean.hpp): large strain
  /// hyperelastic in the Green strain (tissue/st_venant_kirchhoff.hpp): large rotation, moderate
  /// strain; collapses under strong compression (its known failure)
  StVenantKirchhoff
};
/// How the corotational element rotation is extracted.
enum class RotationMethod {
  Polar,  ///< polar decomposition via SVD, inversion-safe
  QR      ///< SOFA's edge frame ("large")
};

}  // namespace stroma
