#pragma once
/// \file feedback.hpp
/// The one feedback path: what a tool felt in a tick and what its device renders, computed
/// once here and used identically by headless runs and by `stroma serve`.
///
///  1. tool_force_after_step: the tissue's force on the tool is the force of the springs the
///     implicit step was solved with, evaluated at the step's end state (f − K·Δp − C·v). It is
///     not the force found at the start of the tick — there this tick's tool motion is pressed
///     into last tick's surface, mostly penalty overlap the solve then removes. Its torque is
///     taken about the tool centre at the end positions; its stiffness dF/dx is the contacts'.
///  2. device_feedback: without coupling the device renders that contact wrench; with virtual
///     coupling it renders the coupling's spring–damper between proxy and device and its torque
///     about the device point ((proxy − device) × F: the coupling ties positions only, so the
///     contacts' torque on the proxy does not reach the device). The force is clamped to
///     max_force (the torque scaled with it: the wrench keeps its line of action).

#include "haptics/tool.hpp"
#include "tissue/contact_spring.hpp"

namespace stroma {

/// Fills out.force and out.torque from the tool's springs [out.spring_begin, out.spring_end) at
/// the end of a step from x0 to x (end velocities v); `center` is the tool centre the contacts
/// were found with. out.stiffness (from the collide stage) is kept.
void tool_force_after_step(const ContactSpring* springs, const double* x0, const double* x, const double* v,
                           const Vec3& center, ToolOutput& out);

/// What the device renders from this tick's contact output (coupling, then the clamp). Updates
/// the coupling's damper memory in `ts` (the stretch of this tick). dt: the tick (s).
ToolFeedback device_feedback(const ToolSpec& spec, ToolState& ts, const ToolOutput& out, double dt);

}  // namespace stroma
