#pragma once
/// \file cantilever_with_probe.hpp
/// The dynamic cantilever (clamped at x = 0, 0.1 × 0.01 × 0.01 m) without gravity, stiffened to
/// E 100 kPa and heavily damped (it settles quickly) with a 3 mm spherical probe, CG to 1e-10:
/// the contact and multirate tests press it.

#include <string>

#include "scene/scenario_spec.hpp"

namespace stroma::test_scenarios {

inline ScenarioSpec cantilever_with_probe() {
  ScenarioSpec s = load_scenario(std::string(STROMA_SOURCE_DIR) + "/scenarios/cantilever_dynamic.yaml");
  s.gravity = {0, 0, 0};
  s.bodies[0].material.young_modulus = 1e5;
  s.bodies[0].material.rayleigh_mass = 60;  // settle quickly to equilibrium
  s.solver.preconditioner = Preconditioner::Jacobi;
  s.solver.tolerance = 1e-10;
  s.solver.max_iterations = 2000;
  ToolEntry t;
  t.spec.name = "probe";
  t.spec.shape = ToolShape::Sphere;
  t.spec.radius = 0.003;
  t.spec.timeout = 10;
  s.tools.push_back(t);
  return s;
}

}  // namespace stroma::test_scenarios
