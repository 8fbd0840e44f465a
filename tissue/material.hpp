#pragma once
/// \file material.hpp
/// Isotropic linear-elastic material parameters and their conversion to Lamé constants.

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

/// Checks E > 0, −1 < ν < 0.5, density > 0, Rayleigh coefficients ≥ 0 (all finite).
/// Returns an empty string when valid, else "FIELD: message" describing the first problem.
std::string validate_material(double young_modulus, double poisson_ratio, double density,
                              double rayleigh_mass, double rayleigh_stiffness);

}  // namespace stroma
