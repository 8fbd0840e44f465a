#pragma once
/// \file multirate.hpp
/// Multirate ticks (solver.fem_every = N > 1, issue 14 §7): the tissue is stepped every N ticks
/// by N·time_step; every tick renders each tool's force from a local model of the last finished
/// step (HapticModel, haptics/tool.hpp). A real-time server runs the step on its own thread,
/// taking N ticks; a headless run emulates that pipeline exactly: the model of the step started
/// at tick kN is rendered from tick (k+1)N on, so headless errors are what a served run feels.
///
/// What a tick renders (solver.haptic_model): `hold` (the default) — the last finished step's
/// force and torque; `secant` — that force plus s·n nᵀ·(p − c): n = F/|F| the contact normal,
/// c the centre the step was solved with, p the tool's centre now, s the median of the last
/// kSecantWindow secants (ΔF·n)/(Δc·n) between consecutive steps (three needed; kept between 0
/// and the contact springs' own normal stiffness). Frictionless contact: no tangential term.
/// Measured (docs/PERFORMANCE.md, "Multirate"): on a steady press the secant cuts the force's
/// jump at each update by a third; on the raptor's press-and-slide its error against the full
/// model is the same as holding's (the error is the step's lag, not the rendering), so hold is
/// the default. Tried and dropped: the step's exact compliance h²·H A⁻¹ Hᵀ at the contacts
/// (three solves per step; its one-step response is the tissue's stiffest, and it rendered 7×
/// larger jumps than holding).

#include "engine/model.hpp"
#include "engine/state.hpp"
#include "engine/tick_types.hpp"

namespace stroma {

/// After a tissue step (hand_off done): each tool's haptic_next from that step (its force and
/// torque, the centre it was solved with, the secant stiffness along the normal).
void capture_haptic_models(const Model& m, State& s, const TickWorkspace& w);

/// Every multirate tick: each tool's force, torque and stiffness from its current model at its
/// current centre, then what its device renders (the same feedback path as every tick), into
/// `outs` (one per tool).
void render_haptic_models(const Model& m, State& s, std::vector<ToolOutput>& outs);

}  // namespace stroma
