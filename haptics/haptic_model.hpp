#pragma once
/// \file haptic_model.hpp
/// Rendering a tool's force between tissue steps from its HapticModel (haptics/tool.hpp;
/// multirate, solver.fem_every > 1; engine/multirate.hpp builds the model): the device feels
/// force + stiffness·(p − center) at the tool's current centre p, so the force keeps following
/// the hand at the haptic rate while the FEM catches up (the idea of Courtecuisse et al. 2015
/// and SOFA's LCPForceFeedback, with a measured stiffness instead of a compliance matrix).

#include <array>

#include "haptics/tool.hpp"

namespace stroma {

/// The wrench the model gives at tool centre p (torque held), into out.force, out.torque and
/// out.stiffness. A held model (haptic_model: hold) has zero stiffness: its force stays.
inline void render_haptic_model(const HapticModel& hm, const Vec3& p, ToolOutput& out) {
  if (!hm.valid) {  // no step has finished yet
    out.force = {0, 0, 0};
    out.torque = {0, 0, 0};
    out.stiffness = {};
    return;
  }
  out.torque = hm.torque;
  out.stiffness = hm.stiffness;
  const double d[3] = {p[0] - hm.center[0], p[1] - hm.center[1], p[2] - hm.center[2]};
  for (int i = 0; i < 3; ++i)
    out.force[i] = hm.force[i] + hm.stiffness[3 * i] * d[0] + hm.stiffness[3 * i + 1] * d[1] +
                   hm.stiffness[3 * i + 2] * d[2];
  // Contact pushes, never pulls: a tool withdrawn past where the linear model crosses zero
  // feels nothing (not an attraction) until the next step says otherwise.
  if (out.force[0] * hm.force[0] + out.force[1] * hm.force[1] + out.force[2] * hm.force[2] < 0) {
    out.force = {0, 0, 0};
    out.torque = {0, 0, 0};
  }
}

}  // namespace stroma
