#pragma once
/// \file test_scenarios.hpp
/// Scenario text and temporary files shared by the engine tests: the sphere-indentation block of
/// refs/e (quarter model, symmetry planes sliding, bottom bonded) with a scripted sphere, the
/// tests' own cantilever and liver (fixtures: the unit tests do not load the shipped demo
/// scenes, which may be retuned for their users; these are frozen copies, meshes from
/// scenarios/meshes/), and a helper that writes a temporary file.

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "scene/scenario_spec.hpp"

namespace stroma::test_scenarios {

/// Writes `text` to a file `name` in the temporary directory; returns its path.
inline std::string write_temp(const std::string& name, const std::string& text) {
  // In a directory of this process's own: ctest runs tests in parallel processes, and two
  // tests writing one fixed path read each other's files (SessionLog's bad-log tests did).
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("stroma_test_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  const std::filesystem::path p = dir / name;
  std::ofstream(p) << text;
  return p.string();
}

/// The head of a scenario about rigid bodies alone (y up, SI units, implicit Euler with block
/// Jacobi to 1e-10): a scenario needs a tissue body, so a small one held still far away. The
/// caller appends its `tools:` and `rigid_bodies:`.
inline std::string rigid_scene_head(const std::string& name) {
  return "name: " + name + R"(
time_step: 0.001
gravity: [0, -9.81, 0]
solver: {integrator: implicit_euler, preconditioner: block_jacobi, tolerance: 1.0e-10}
bodies:
  - name: far
    mesh: )" + std::string(STROMA_SOURCE_DIR) + R"(/scenarios/meshes/cube_tet4_h5p000mm.msh
    scale: 0.1
    translate: [1, 1, 1]
    material: {young_modulus: 1.0e4, poisson_ratio: 0.45, density: 1000}
    fixed:
      - box: {min: [-10, -10, -10], max: [10, 10, 10]}
)";
}

/// The indentation quarter block (0.05 × 0.05 × 0.05 m of `mesh`, E 5 kPa, ν 0.45, ρ 1000) with
/// the sphere (R 5 mm, penalty 1e9 Pa/m) driven by `script`. `solver` is the solver: map's
/// text, `material_extra` and `tool_extra` are appended inside the material map and to the
/// tool entry (lines indented by four spaces).
inline std::string indentation_block_yaml(const std::string& mesh, const std::string& script, const std::string& solver,
                                          const std::string& model = "linear", const std::string& material_extra = "",
                                          const std::string& tool_extra = "") {
  return "name: indentation\n"
         "gravity: [0, 0, 0]\n"
         "solver: " + solver + "\n"
         "bodies:\n"
         "  - name: block\n"
         "    mesh: " + mesh + "\n"
         "    material: {model: " + model + ", young_modulus: 5000, poisson_ratio: 0.45, density: 1000" +
         material_extra + "}\n"
         "    fixed:\n"
         "      - box: {min: [-1, -1, -1.0e-9], max: [1, 1, 1.0e-9]}\n"
         "      - {box: {min: [-1.0e-9, -1, -1], max: [1.0e-9, 1, 1]}, axes: [x]}\n"
         "      - {box: {min: [-1, -1.0e-9, -1], max: [1, 1.0e-9, 1]}, axes: [y]}\n"
         "tools:\n"
         "  - name: sphere\n"
         "    script: " + script + "\n"
         "    shape: {type: sphere, radius: 0.005}\n"
         "    contact: {stiffness: 1.0e9}\n" + tool_extra;
}

/// The tests' cantilever: the beam of refs/d_cantilever_dynamic (100 × 10 × 10 mm, clamped at
/// x = 0, 480 tetrahedra; E 10 MPa, ν 0.3, ρ 1000), gravity −y from rest, undamped, implicit
/// Euler at 1 ms with warped-Cholesky CG to 1e-8, a tip probe; 0.2 s.
inline ScenarioSpec cantilever_dynamic() {
  return parse_scenario(R"(name: cantilever_dynamic
time_step: 0.001
gravity: [0, -9.81, 0]
solver:
  integrator: implicit_euler
  linear_solver: cg
  preconditioner: warped_cholesky
  max_iterations: 500
  tolerance: 1.0e-8
bodies:
  - name: beam
    mesh: meshes/beam_tet4_h5p000mm.msh
    material:
      model: corotational
      young_modulus: 1.0e7
      poisson_ratio: 0.3
      density: 1000
    fixed:
      - box: {min: [-1.0e-6, -1, -1], max: [1.0e-6, 1, 1]}
probes:
  - name: tip
    body: beam
    point: [0.1, 0.005, 0.005]
run:
  duration: 0.2
)", "test_cantilever_dynamic.yaml", STROMA_SOURCE_DIR "/scenarios");
}

/// The tests' liver: SOFA's liver demo (mesh units: E 3000, ν 0.3, density 1, Rayleigh 0.1 /
/// 0.1, nodes 3, 39, 64 fixed, gravity −y) at 1 ms, Jacobi CG to 1e-6 (cap 100), its smooth
/// visual surface, a lobe probe, and a grasping sphere probe of radius 0.3 with its limits.
inline ScenarioSpec liver() {
  return parse_scenario(R"(name: liver
time_step: 0.001
gravity: [0, -9.81, 0]
solver:
  integrator: implicit_euler
  linear_solver: cg
  preconditioner: jacobi
  max_iterations: 100
  tolerance: 1.0e-6
  warm_start: true
bodies:
  - name: liver
    mesh: meshes/liver.msh
    material:
      model: corotational
      rotation: polar
      young_modulus: 3000
      poisson_ratio: 0.3
      density: 1
      rayleigh_mass: 0.1
      rayleigh_stiffness: 0.1
    fixed:
      - nodes: [3, 39, 64]
    visual: meshes/liver-smooth.obj
probes:
  - name: lobe
    body: liver
    point: [-2.0, 3.0, 1.5]
tools:
  - name: probe
    shape: {type: sphere, radius: 0.3}
    max_force: 5
    workspace: {min: [-8, -2, -5], max: [5, 10, 6]}
    max_speed: 50
    timeout: 0.5
    on_invalid: reject
    grasp: {close: 0.05, open: 0.1}
run:
  duration: 2.0
)", "test_liver.yaml", STROMA_SOURCE_DIR "/scenarios");
}

}  // namespace stroma::test_scenarios
