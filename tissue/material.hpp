#pragma once
/// \file material.hpp
/// Isotropic linear-elastic material parameters and their conversion to Lamé constants.

#include <cmath>
#include <string>

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

}  // namespace stroma
