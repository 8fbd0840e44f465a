#pragma once
/// \file st_venant_kirchhoff.hpp
/// St. Venant–Kirchhoff elements, the lectures' first hyperelastic model: linear elasticity's
/// energy written in the Green–Lagrange strain E = (FᵀF − I)/2,
///
///   Ψ(F) = μ·E:E + λ/2·(tr E)²,   S = λ·tr(E)·I + 2μ·E,   P = F·S.
///
/// Exact under any rigid rotation and equal to linear elasticity at small strain, so its (E, ν)
/// mean what they mean for the other models. Its known failure is in compression: Ψ depends on
/// F through FᵀF only, so an element squeezed flat (J → 0) has finite energy and a *falling*
/// resistance — at ν = 0 the uniaxial nominal stress μ(s³ − s) turns over at a stretch
/// s = 1/√3 and reaches zero at s = 0 — and an element pushed through flat is a mirrored
/// rest state with zero energy. Large compression therefore collapses or inverts it where
/// stable Neo-Hookean pushes back (docs/STABILITY.md shows it; docs/TISSUE.md says when to use
/// which). The tangent is indefinite under compression; it is projected to PSD from the analytic
/// eigensystem of the isotropic energy (hyperelastic_pass.hpp).

#include <cstdint>

#include "tissue/fem_forces.hpp"

namespace stroma {

/// The elastic pass over range r's elements with St. Venant–Kirchhoff (plus FemModel::fibres'
/// term when r.fibres, its Prony series when r.visco ≥ 0); returns their energy.
double st_venant_kirchhoff_pass(const FemModel& m, const ElasticPass& p, const ElementRange& r);

/// Energy density Ψ(F) and first Piola stress P (row-major) for Lamé (λ, μ).
double st_venant_kirchhoff_stress(const double* F, double lambda, double mu, double* P);

/// The analytic eigensystem of ∂²Ψ/∂F² (as stable_neo_hookean_eigensystem): values[9],
/// modes[9][9] (row-major 3×3 each), H = Σ_m values[m]·vec(Q_m)·vec(Q_m)ᵀ.
void st_venant_kirchhoff_eigensystem(const double* F, double lambda, double mu, double* values, double* modes);

}  // namespace stroma
