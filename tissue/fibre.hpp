#pragma once
/// \file fibre.hpp
/// Fibre reinforcement of a hyperelastic matrix (tendon, muscle, vessel walls): the exponential
/// fibre energy of Holzapfel, Gasser & Ogden (J. Elasticity 2000), one family, perfectly
/// aligned (no dispersion),
///
///   Ψ_f = k1/(2·k2)·(exp(k2·(I4 − 1)²) − 1)   for I4 > 1,   0 otherwise,
///   I4 = ‖F·a‖² (the squared fibre stretch),  a the unit fibre direction at rest,
///
/// added to the isotropic matrix's energy (stable Neo-Hookean or St. Venant–Kirchhoff). Fibres
/// bear tension only: a compressed fibre buckles and carries nothing (the HGO convention). Past
/// an extreme stretch the exponential continues quadratically (kFibreMaxExponent). The
/// term is stiff-in-tension and exponential, as the collagen fibrils of the lecture make the
/// tendon's stress–stretch curve. k2 = 0 is the quadratic limit k1/2·(I4 − 1)².
///
/// With b = F·a: P_f = 2ψ′·b⊗a, and ∂²Ψ_f/∂F² = 2ψ′·(I ⊗ a⊗a) + 4ψ″·vec(b⊗a)·vec(b⊗a)ᵀ,
/// ψ′ = k1·x·e, ψ″ = k1·e·(1 + 2·k2·x²), x = I4 − 1, e = exp(k2·x²). Both parts are PSD where
/// the fibre is stretched (x > 0), so the sum with the projected matrix tangent stays PSD with
/// no projection of its own. Rigid rotations leave I4 = 1: no force.

#include <algorithm>
#include <cmath>

namespace stroma {

/// One element's fibres. Invariants: |a| = 1; k1 ≥ 0 (Pa); k2 ≥ 0 (dimensionless). k1 = 0: no
/// fibres (the element is the matrix alone).
struct FibreParams {
  double a[3] = {1, 0, 0};  ///< unit fibre direction in the rest configuration
  double k1 = 0;            ///< Pa: the fibres' stiffness at small stretch (2·k1 per unit I4)
  double k2 = 0;            ///< dimensionless: how fast they stiffen
};

/// What the fibre term contributes at one F: energy density, b = F·a, ψ′ = ∂Ψ_f/∂I4, ψ″.
struct FibreResponse {
  double psi = 0;
  double d1 = 0, d2 = 0;
  double b[3] = {0, 0, 0};
};

/// Where the exponential stops: beyond x_c = √(kFibreMaxExponent/k2) (I4 − 1 = 1.1 for k2 = 8,
/// a fibre stretch of 1.45, far past a tendon's ~1.1 failure), Ψ_f continues as its second-order
/// Taylor expansion at x_c — ψ′ and ψ″ stay continuous, the stiffness stays at its value there
/// (e¹⁰ ≈ 22,000× the small-stretch one). Without it an element torn open by a bad state (an
/// inverted or crushed mesh) meets a stiffness of e^(k2·x²) that no step can follow (measured:
/// exp(300)-scale forces, every tick rolled back; docs/STABILITY.md).
inline constexpr double kFibreMaxExponent = 10.0;

/// The fibre term at F (row-major) with its stiffness scaled by `keep` (1 − damage).
inline FibreResponse fibre_response(const double* F, const FibreParams& fp, double keep) {
  FibreResponse r;
  for (int i = 0; i < 3; ++i) r.b[i] = F[3 * i] * fp.a[0] + F[3 * i + 1] * fp.a[1] + F[3 * i + 2] * fp.a[2];
  const double x = r.b[0] * r.b[0] + r.b[1] * r.b[1] + r.b[2] * r.b[2] - 1.0;
  const double k1 = keep * fp.k1;
  if (!(x > 0) || !(k1 > 0)) return r;
  if (fp.k2 * x * x <= kFibreMaxExponent) {
    const double arg = fp.k2 * x * x, ex = std::exp(arg);
    r.psi = fp.k2 > 0 ? 0.5 * k1 / fp.k2 * std::expm1(arg) : 0.5 * k1 * x * x;
    r.d1 = k1 * x * ex;
    r.d2 = k1 * ex * (1.0 + 2.0 * fp.k2 * x * x);
    return r;
  }
  const double xc = std::sqrt(kFibreMaxExponent / fp.k2), ex = std::exp(kFibreMaxExponent), dx = x - xc;
  const double psi_c = 0.5 * k1 / fp.k2 * std::expm1(kFibreMaxExponent), d1_c = k1 * xc * ex;
  r.d2 = k1 * ex * (1.0 + 2.0 * kFibreMaxExponent);
  r.d1 = d1_c + r.d2 * dx;
  r.psi = psi_c + d1_c * dx + 0.5 * r.d2 * dx * dx;
  return r;
}

/// The fibre term's energy density and first Piola stress P (row-major, +=).
inline double fibre_stress(const double* F, const FibreParams& fp, double* P) {
  const FibreResponse r = fibre_response(F, fp, 1.0);
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) P[3 * i + j] += 2.0 * r.d1 * r.b[i] * fp.a[j];
  return r.psi;
}

}  // namespace stroma
