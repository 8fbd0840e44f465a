/// \file starter_scenario.cpp
/// Starter scenario YAML for a new mesh (see starter_scenario.hpp).

#include "scene/starter_scenario.hpp"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>

namespace stroma {

std::string real_time_warning(size_t tets) {
  if (static_cast<int64_t>(tets) <= kFarBeyondRealTime * kRealTimeTets) return "";
  return fmt::format("{} tetrahedra are about {:.0f}x what one core steps at 1 kHz ({}; docs/REALTIME.md): the scenario "
                     "runs, but slower than real time, and `stroma serve` will degrade every tick; for real time, "
                     "mesh with --tets {} (or a larger --size)",
                     tets, double(tets) / double(kRealTimeTets), kRealTimeTets, kRealTimeTets);
}

std::string starter_scenario_yaml(const TetMesh& mesh, const StarterScenarioSpec& spec) {
  Vec3 lo{1e300, 1e300, 1e300}, hi{-1e300, -1e300, -1e300};
  for (const Vec3& p : mesh.nodes)
    for (int a = 0; a < 3; ++a) {
      lo[size_t(a)] = std::min(lo[size_t(a)], p[size_t(a)]);
      hi[size_t(a)] = std::max(hi[size_t(a)], p[size_t(a)]);
    }
  const char* axis = spec.up_axis == 0 ? "x" : spec.up_axis == 1 ? "y" : "z";
  double g[3] = {0, 0, 0}, down[3] = {0, 0, 0};
  g[spec.up_axis] = -9.81 * spec.up_sign;
  down[spec.up_axis] = -spec.up_sign;
  auto num = [](double v) { return v == 0 ? std::string("0") : fmt::format("{:g}", v); };
  std::string y;
  y += fmt::format("# Starter scenario for {} ({} tetrahedra, {} nodes; {:.3g} x {:.3g} x {:.3g} m).\n", spec.mesh_path,
                   mesh.tets.size(), mesh.nodes.size(), hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]);
  if (!spec.made_by.empty()) {
    std::string one_line = spec.made_by;  // a comment must stay one line, whatever the arguments held
    for (char& c : one_line)
      if (c == '\n' || c == '\r') c = ' ';
    y += fmt::format("# Mesh made by: {}\n", one_line);
  }
  if (const std::string w = real_time_warning(mesh.tets.size()); !w.empty()) y += "# WARNING: " + w + ".\n";
  y += "# Runs as is: `stroma run THIS_FILE` (1 s under gravity; outputs in a folder beside it).\n"
       "# Units are SI throughout: metres, seconds, kilograms, pascals. What to change:\n"
       "#   material   soft tissue defaults (liver-like: E 5 kPa, nu 0.45, 1060 kg/m^3); stiffer organs\n"
       "#              have E 10-100 kPa, nearly incompressible ones nu up to 0.49 (docs/TISSUE.md).\n"
       "#   regions    each labelled region may get its own material (uncomment and change a value).\n";
  y += fmt::format("#   fixed      the boundary faces that look down (normal within 45 deg of {}{}) are clamped,\n"
                   "#              as if the organ lay on what is beneath it; gravity pulls along {}{}.\n",
                   spec.up_sign > 0 ? "-" : "+", axis, spec.up_sign > 0 ? "-" : "+", axis);
  y += "#   solver     Jacobi CG to a relative residual of 1e-4 (at most 200 iterations). For `stroma serve` at\n"
       "#              1 kHz add `time_budget: 0.00085` (docs/REALTIME.md): CG then stops at the budget.\n"
       "#   tools      add a probe to press it (scenarios/physical/liver_fine_16cm.yaml shows one).\n";
  y += fmt::format("name: {}\n", spec.name);
  y += "time_step: 0.001\n";
  y += fmt::format("gravity: [{}, {}, {}]\n", num(g[0]), num(g[1]), num(g[2]));
  y += "solver: {integrator: implicit_euler, linear_solver: cg, preconditioner: jacobi, max_iterations: 200,\n"
       "         tolerance: 1.0e-4, on_cg_cap: continue}\n";
  y += "bodies:\n";
  y += fmt::format("  - name: {}\n", spec.name);
  std::string quoted;  // a YAML double-quoted scalar: any path, spaces and colons included
  for (char c : spec.mesh_path) {
    if (c == '"' || c == '\\') quoted += '\\';
    quoted += c;
  }
  y += fmt::format("    mesh: \"{}\"\n", quoted);
  y += "    material: {model: corotational, young_modulus: 5000, poisson_ratio: 0.45, density: 1060,\n"
       "               rayleigh_mass: 1.0, rayleigh_stiffness: 0.005}\n";
  if (mesh.tag_names.size() > 1) {
    y += "    # regions:   # each label's own material; a region must change at least one value\n";
    for (const auto& [tag, name] : mesh.tag_names)
      y += fmt::format("    #   - {{region: {}, material: {{young_modulus: 5000, density: 1060}}}}   # tag {}\n", name, tag);
  }
  y += "    fixed:\n";
  y += fmt::format("      - surface: {{normal: [{}, {}, {}], max_angle: 45}}\n", num(down[0]), num(down[1]), num(down[2]));
  y += "run: {duration: 1.0}\n";
  return y;
}

}  // namespace stroma
