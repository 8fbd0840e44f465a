#pragma once
/// \file cut_swap.hpp
/// A changing topology in a fixed-rate loop: the cut model is built off the physics thread
/// (build_cut: topology, Model, TickWorkspace, a State sized for them — every allocation), then
/// swapped in at a tick boundary (apply_cut: the state carried over into the pre-sized arrays,
/// three pointers exchanged — no allocation). The old model, workspace and state leave in the
/// build, to be released off the thread. docs/ARCHITECTURE.md, "Cutting".

#include <cstdint>
#include <memory>
#include <vector>

#include "engine/model.hpp"
#include "engine/state.hpp"
#include "engine/tick.hpp"

namespace stroma {

/// A cut model ready to swap in. Invariants when `changed`: state is sized for model (its
/// arrays are what apply_cut writes into); from_dof / from_element map the model's DOFs and
/// elements to those of the model of version base_version they refine.
struct CutBuild {
  std::shared_ptr<const Model> model;
  std::unique_ptr<TickWorkspace> workspace;
  State state;
  std::vector<int32_t> from_dof, from_element;
  int32_t base_version = 0;
  /// False: the edges cut since the current topology separate nothing new (a crack still inside
  /// its tetrahedra): nothing to swap.
  bool changed = false;
  double build_ms = 0;  ///< wall time the build took (off the physics thread in `serve`)
};

/// Off the physics thread: the topology of `edge_cut` (a snapshot of the state's; it must
/// contain every cut of `current`'s topology) and, if it separates more than current's, its
/// model (version current + 1), workspace and sized state. Throws what compiling throws
/// (std::invalid_argument, std::logic_error) — never expected; a caller in a real-time loop
/// counts it and keeps the current model.
CutBuild build_cut(const Model& current, const std::vector<double>& edge_cut);

/// At a tick boundary: carries `s` into the build's state — positions, velocities and warm start
/// through from_dof (a cut moves nothing), damage per element through from_element, lumped
/// masses recomputed from the ruptured set, tools (grasped points re-attached to the nearest
/// point of the new surface, within the tool's radius), edge cuts, time — and swaps model,
/// workspace and state with the build's. Returns false, doing nothing, when the build is not
/// `changed` or is stale (built on another version than m's). No allocation.
bool apply_cut(CutBuild& b, std::shared_ptr<const Model>& m, std::unique_ptr<TickWorkspace>& w, State& s);

}  // namespace stroma
