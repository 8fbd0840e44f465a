#pragma once
/// \file test_scenarios.hpp
/// Scenario text and temporary files shared by the engine tests: the sphere-indentation block of
/// refs/e (quarter model, symmetry planes sliding, bottom bonded) with a scripted sphere, and a
/// helper that writes a temporary file.

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>

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

}  // namespace stroma::test_scenarios
