#pragma once
/// \file stable_neo_hookean.hpp
/// Stable Neo-Hookean elements (Smith, de Goes & Kim, "Stable Neo-Hookean Flesh Simulation",
/// 2018), the inversion-robust material for soft tissue at large strain:
///
///   Ψ(F) = μ/2 (‖F‖² − 3) + λ'/2 (J − α)² − Ψ₀,   J = det F,  λ' = λ + μ,  α = 1 + μ/λ',
///
/// without the paper's log term (its rest stability comes from α instead). λ' = λ + μ makes the
/// small-strain response exactly linear elasticity with the scenario's (λ, μ), so E and ν mean
/// what they mean for the other models; Ψ₀ = μ²/(2λ') makes the rest energy zero.
///
/// Why it matters: the corotational model's energy stays finite through zero volume, so an
/// element squeezed flat by a load larger than its stiffness can pass through and stay inverted
/// (measured: soft beams at 1–10 kPa under their own weight end with inverted elements). Here
/// the volume term λ'(J − α)² grows through inversion and drives J back up, for any F
/// (defined and smooth through J ≤ 0; no SVD sign fix-ups).
///
/// The tangent ∂²Ψ/∂F² = μI + λ' vec(cof F) vec(cof F)ᵀ + λ'(J − α) ∂²J/∂F² is indefinite
/// away from rest; it is projected to the nearest positive semi-definite matrix (9×9
/// eigen-decomposition, negative eigenvalues set to 0) so implicit Euler and CG see a
/// symmetric PSD system. Cost: a scalar 9×9 eigensolve per element per assembly — several
/// times the corotational kernel (docs/PERFORMANCE.md).

#include <cstdint>

#include "tissue/fem_forces.hpp"

namespace stroma {

/// The elastic pass (fem_forces.hpp) over elements [begin, end) with the stable Neo-Hookean
/// material; returns their energy. `rotations` (when requested, for the warped preconditioner)
/// are the polar rotations of F.
double stable_neo_hookean_pass(const FemModel& m, const ElasticPass& p, int32_t begin, int32_t end);

/// Energy density Ψ(F) and first Piola stress P (row-major) for Lamé (λ, μ) of the scenario.
double stable_neo_hookean_stress(const double* F, double lambda, double mu, double* P);

}  // namespace stroma
