#pragma once
/// \file starter_scenario.hpp
/// The starter scenario `stroma mesh --scenario` writes next to a new mesh: a YAML file that
/// runs as is (`stroma run`), in SI units, with soft-tissue defaults, the mesh's downward-facing
/// boundary clamped, gravity, the real-time solver settings of the shipped physical scenes, and
/// comments that say what to change. Every region of the mesh is listed (commented out) with the
/// body's material, ready to be given its own.

#include <cstddef>
#include <cstdint>
#include <string>

#include "tissue/tet_mesh.hpp"

namespace stroma {

/// About what one core steps at 1 kHz with the starter's solver (docs/REALTIME.md; `stroma mesh`'s
/// default --tets). A mesh beyond kFarBeyondRealTime times that gets a warning in the scenario and
/// on the terminal: it runs, slower than real time.
inline constexpr int64_t kRealTimeTets = 5000;
inline constexpr int64_t kFarBeyondRealTime = 4;

/// Whether a mesh of `tets` elements is far beyond what 1 kHz steps; the warning says how far.
std::string real_time_warning(size_t tets);

/// What the starter scenario needs to know.
struct StarterScenarioSpec {
  std::string name;           ///< scenario and body name
  std::string mesh_path;      ///< as written into the YAML (relative to the YAML's folder)
  std::string made_by;        ///< the command that made the mesh (a comment)
  int up_axis = 2;            ///< 0, 1, 2: x, y, z is up (gravity along -up)
  double up_sign = 1.0;       ///< +1 or -1
};

/// The YAML text for `mesh` (already in metres).
std::string starter_scenario_yaml(const TetMesh& mesh, const StarterScenarioSpec& spec);

}  // namespace stroma
