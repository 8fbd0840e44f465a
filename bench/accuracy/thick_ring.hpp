#pragma once
/// \file thick_ring.hpp
/// An inhomogeneous fibre problem with an independent reference: a thick-walled ring (a vessel
/// wall) in plane strain, inner radius A, outer B, stable Neo-Hookean matrix with HGO fibres
/// running circumferentially (tissue/fibre.hpp), inflated by a dead pressure p0 on its inner
/// surface (a nominal traction: p0 per unit of rest area). Strain and fibre direction vary
/// through the wall, so no element state is homogeneous.
///
/// Reference: the axisymmetric problem reduced to one ordinary differential equation. With the
/// radial map r(R), stretches λ_r = r′, λ_θ = r/R, λ_z = 1, the energy per unit rest volume
///   W = μ/2(λ_r² + λ_θ² − 2) + λ′/2(λ_rλ_θ − α)² + Ψ_f(λ_θ²) − Ψ₀
/// and equilibrium d/dR(R·W_r) = W_θ (W_r = ∂W/∂λ_r, W_θ = ∂W/∂λ_θ) with W_r(A) = −p0,
/// W_r(B) = 0. W_r is linear in λ_r, so with q = R·W_r the state (r, q) obeys an explicit ODE,
/// integrated by 4th-order Runge–Kutta (20,000 steps) and shot on r(A) to q(B) = 0 (bisection):
/// a 1-D method sharing nothing with the tetrahedral FEM but the constitutive law.

#include <string>

namespace stroma {

/// Material and geometry of the ring (SI). Fibres: k1 = 0 for the matrix alone.
struct ThickRing {
  double A = 0.010, B = 0.015;       ///< inner and outer rest radius (m)
  double E = 1e4, nu = 0.45;         ///< matrix
  double k1 = 5e4, k2 = 8;           ///< fibres (Pa, dimensionless)
  double p0 = 5e3;                   ///< inner dead pressure (Pa per rest area): inner hoop stretch 1.08
};

/// The reference solution's inner and outer radial displacements (m).
struct ThickRingSolution {
  double u_inner = 0, u_outer = 0;
  int shots = 0;  ///< bisection steps used
};

/// Solves the 1-D reference to ~1e-10 relative. Throws std::runtime_error if the shooting fails.
ThickRingSolution solve_thick_ring(const ThickRing& ring);

/// Writes a quarter of the ring (x, y ≥ 0), `layer` thick in z, as an ASCII VTU: nr × nθ × nz
/// cells in (R, θ, z), six tetrahedra each, and a cell-data array `fibres` holding each
/// tetrahedron's circumferential direction at its centroid (`direction: mesh`). Returns path.
std::string write_quarter_ring_vtu(const std::string& path, const ThickRing& ring, double layer, int nr, int ntheta,
                                   int nz);

}  // namespace stroma
