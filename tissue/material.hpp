#pragma once
/// \file material.hpp
/// Isotropic linear-elastic material parameters and their conversion to Lamé constants.

#include <cmath>
#include <string>

#include "tissue/mat3.hpp"

namespace stroma {

/// Lamé parameters of an isotropic material.
struct Lame {
  double lambda;  ///< first Lamé parameter λ = Eν / ((1+ν)(1−2ν))
  double mu;      ///< shear modulus μ = E / (2(1+ν))
};

/// Lamé parameters from Young's modulus E and Poisson's ratio ν (assumed validated).
inline Lame lame_from_young_poisson(double E, double nu) {
  return {E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu)), E / (2.0 * (1.0 + nu))};
}

/// Von Mises stress of the linear-elastic stress σ = λ tr(ε) I + 2μ ε of a small strain ε
/// (row-major 3×3, symmetric): √(½((σxx−σyy)² + (σyy−σzz)² + (σzz−σxx)²) + 3(σxy² + σxz² + σyz²)).
inline double von_mises_stress(const double* eps, double lambda, double mu) {
  const double tr = eps[0] + eps[4] + eps[8];
  double s[9];
  for (int k = 0; k < 9; ++k) s[k] = 2.0 * mu * eps[k];
  s[0] += lambda * tr;
  s[4] += lambda * tr;
  s[8] += lambda * tr;
  const double a = s[0] - s[4], b = s[4] - s[8], c = s[8] - s[0];
  return std::sqrt(0.5 * (a * a + b * b + c * c) + 3.0 * (s[1] * s[1] + s[2] * s[2] + s[5] * s[5]));
}

/// Checks E > 0, −1 < ν < 0.5, density > 0, Rayleigh coefficients ≥ 0 (all finite).
/// Returns an empty string when valid, else "FIELD: message" describing the first problem.
std::string validate_material(double young_modulus, double poisson_ratio, double density,
                              double rayleigh_mass, double rayleigh_stiffness);

/// P = R·σ(sym(RᵀG) − I·shift): the rotated small-strain stress of gradient G.
/// shift = 1 for positions (strain), 0 for velocities (strain rate).
inline void rotated_stress(const double* R, const double* G, double lambda, double mu,
                           double shift, double* P, double* eps_out) {
  double S[9];
  m3::mul_tn(R, G, S);
  double e[9];
  e[0] = S[0] - shift; e[4] = S[4] - shift; e[8] = S[8] - shift;
  e[1] = e[3] = 0.5 * (S[1] + S[3]);
  e[2] = e[6] = 0.5 * (S[2] + S[6]);
  e[5] = e[7] = 0.5 * (S[5] + S[7]);
  const double tr = e[0] + e[4] + e[8];
  double sig[9];
  for (int k = 0; k < 9; ++k) sig[k] = 2.0 * mu * e[k];
  sig[0] += lambda * tr; sig[4] += lambda * tr; sig[8] += lambda * tr;
  m3::mul(R, sig, P);
  if (eps_out)
    for (int k = 0; k < 9; ++k) eps_out[k] = e[k];
}

}  // namespace stroma
