#pragma once
/// \file tick.hpp
/// One simulation tick as a flat list of named, timed stages (engine/tick.cpp):
///   read_inputs → collide → step_with_recovery (assemble → solve → integrate, retried)
///   → damage → hand_off.
/// Stages a scene does not need are skipped (and report zero time). The same tick runs
/// headless and in the real-time server (both through engine/simulation.hpp). It never
/// allocates, locks, logs or throws: problems come back as a status code, outputs in the
/// workspace's TickReport (engine/tick_types.hpp).

#include "engine/model.hpp"
#include "engine/state.hpp"
#include "engine/tick_types.hpp"
#include "haptics/tool.hpp"
#include "tissue/deadline.hpp"

namespace stroma {

/// Collide stage on its own: contacts of every shaped tool and between bodies at s.x, into
/// w.springs and w.report (tools' contact outputs, body contact). The static solver calls it
/// per Newton iteration.
void collide(const Model& m, State& s, TickWorkspace& w);

/// The step's inputs for the time stepper: this tick's springs, the element damage and the
/// current lumped masses (StepInputs' pointers stay valid while s and w do).
StepInputs step_inputs(const Model& m, const State& s, const TickWorkspace& w);

/// Clears a report's per-tick fields (status Ok, no stages run, nothing stepped).
void begin_report(TickReport& r);
/// read_inputs stage: each command takes effect (pose, seq, timestamps); a tool whose client
/// fell silent holds its last accepted pose, then goes idle after its timeout. Timed into r.
void apply_tool_inputs(const Model& m, State& s, TickReport& r, const ToolInput* inputs, int input_count);
/// The tissue's part of a tick, into w.report: collide, the step (m.fem_step) with recovery,
/// then — advancing s by `ticks` ticks — damage, hand_off and (multirate) the tools' next
/// haptic models. Returns false when the step was non-finite (s rolled back, not advanced).
/// tick() calls it; so does `serve`'s tissue worker when solver.fem_every > 1.
bool step_tissue(const Model& m, State& s, TickWorkspace& w, Deadline deadline, int ticks);

/// Advances `s` by one time step of the model. `inputs` are tool commands that take effect at
/// the start of this tick (read_inputs stage; skipped when the scene has no tools).
/// `deadline`: when the engine's own work must stop (tissue/deadline.hpp) — a steady-clock
/// time, or (replay) the check at which the recorded tick ran out of time; none given = the
/// model's time_budget from the tick's start (none if that is 0). Returns w.report.
const TickReport& tick(const Model& m, State& s, TickWorkspace& w, const ToolInput* inputs = nullptr,
                       int input_count = 0, Deadline deadline = {});

}  // namespace stroma
