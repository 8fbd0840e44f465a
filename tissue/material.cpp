#include "tissue/material.hpp"

#include <cmath>

#include <fmt/format.h>

namespace stroma {

std::string validate_material(double E, double nu, double density, double alpha, double beta) {
  auto bad = [](double v) { return !std::isfinite(v); };
  if (bad(E) || E <= 0)
    return fmt::format("young_modulus: {} is out of range: must be > 0 (Pa)", E);
  if (bad(nu) || nu <= -1.0 || nu >= 0.5)
    return fmt::format(
        "poisson_ratio: {} is out of range: must be > -1 and < 0.5 (0.5 is incompressible; "
        "use 0.49 or lower)", nu);
  if (bad(density) || density <= 0)
    return fmt::format("density: {} is out of range: must be > 0 (kg/m^3)", density);
  if (bad(alpha) || alpha < 0)
    return fmt::format("rayleigh_mass: {} is out of range: must be >= 0", alpha);
  if (bad(beta) || beta < 0)
    return fmt::format("rayleigh_stiffness: {} is out of range: must be >= 0", beta);
  return {};
}

}  // namespace stroma
