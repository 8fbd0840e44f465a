#pragma once
/// \file state.hpp
/// The small mutable simulation state (as MuJoCo's mjData): copy it to snapshot, assign it
/// back to roll back. Scratch memory lives elsewhere (TimeStepper), so copies stay small.

#include <cstdint>

#include "engine/model.hpp"
#include "tissue/tissue_state.hpp"

namespace stroma {

/// Simulation state at one instant.
struct State {
  TissueState tissue;  ///< positions, velocities, solver warm start
  std::vector<ToolState> tools;  ///< one per scenario tool
  double time = 0;     ///< simulated time (s)
  int64_t step = 0;    ///< ticks done

  /// The initial state of a model: every body at rest in its rest configuration.
  static State initial(const Model& m) {
    State s{TissueState::at_rest(m.fem), std::vector<ToolState>(m.tools.size()), 0.0, 0};
    return s;
  }
};

/// Displacement of a probe in state s.
Vec3 probe_displacement(const Model& m, const State& s, const ProbeModel& p);
/// Current position of a probe in state s.
Vec3 probe_position(const Model& m, const State& s, const ProbeModel& p);

}  // namespace stroma
