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
/// away from rest; it is projected to the nearest positive semi-definite matrix (negative
/// eigenvalues set to 0) so implicit Euler and CG see a symmetric PSD system. Its eigensystem is
/// analytic (Smith, de Goes & Kim 2018, §4; Smith et al. 2019): with the rotation-variant SVD
/// F = U·Σ·Vᵀ, three "scaling" modes U·diag(e)·Vᵀ from the 3×3 Hessian in σ, and per pair
/// (i, j) a twist mode (eigenvalue μ + λ'(J − α)σ_k) and a flip mode (μ − λ'(J − α)σ_k).
/// A 3×3 SVD and a 3×3 eigensolve per element instead of a 9×9 eigensolve: ~8× cheaper
/// (docs/PERFORMANCE.md).

#include <cstdint>

#include "tissue/fem_forces.hpp"

namespace stroma {

/// The elastic pass (fem_forces.hpp) over range r's elements with the stable Neo-Hookean
/// material (hyperelastic_pass.hpp), plus FemModel::fibres' term when r.fibres and its Prony
/// series when r.visco ≥ 0; returns their energy. `rotations` (when requested with forces or a matrix, for the warped
/// preconditioner; an energy-only pass writes none) are the polar rotations of F.
double stable_neo_hookean_pass(const FemModel& m, const ElasticPass& p, const ElementRange& r);

/// Energy density Ψ(F) and first Piola stress P (row-major) for Lamé (λ, μ) of the scenario.
double stable_neo_hookean_stress(const double* F, double lambda, double mu, double* P);

/// The exact (unprojected) Hessian ∂²Ψ/∂F² as a 9×9 row-major matrix H[9·(3i+j) + 3k+l]:
/// the reference the analytic eigensystem is tested against.
void stable_neo_hookean_hessian(const double* F, double lambda, double mu, double* H);

/// The analytic eigensystem of ∂²Ψ/∂F²: values[9] and orthonormal modes[9][9] (mode m is the
/// row-major 3×3 matrix modes + 9m), so that H = Σ_m values[m]·vec(Q_m)·vec(Q_m)ᵀ.
void stable_neo_hookean_eigensystem(const double* F, double lambda, double mu, double* values, double* modes);

}  // namespace stroma
