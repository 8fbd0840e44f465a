#pragma once
/// \file rigid_grasp.hpp
/// A tool's grasp of a rigid body (issue 42; docs/RIGID.md): closing the jaws (the open →
/// closed transition of ToolState::jaw_closed, as for tissue) with a rigid body's shape within
/// reach of the grasp centre — the tip for a sphere or probe, the middle of the jaws for a
/// grasper; reach = grasp.reach × radius (+ half the jaws' length) — holds the nearest such
/// body instead of tissue; opening releases it. While held, three points of the body (at the
/// grasp centre and one lever along each of two tool axes) are tied to where they were in the
/// tool's frame by springs of the tool's grasp stiffness: a six-degree-of-freedom hold, solved
/// in the implicit step with the body's rows (tissue/rigid_rows.hpp), its force felt by the
/// tool (the one feedback path). A released body falls and can be grasped again.

#include <vector>

#include "engine/model.hpp"
#include "engine/state.hpp"
#include "haptics/tool.hpp"
#include "tissue/contact_spring.hpp"

namespace stroma {

/// The grasps' transitions this tick, before the tools' contacts: a closing jaw takes the
/// nearest rigid body within reach (its hold points recorded), an opening one or an idle tool
/// lets go.
void update_rigid_grasps(const Model& m, State& s);

/// The grasp centre `gc` (as haptics/contact.cpp's grasp: the tip, or between a grasper's jaws)
/// and the reach around it, for a tool at rotation R (row-major).
void grasp_centre(const ToolSpec& spec, const ToolState& ts, const double* R, double* gc, double* reach);

/// The lever of the hold points (m): the tool's radius, at least a millimetre.
double hold_lever(const ToolSpec& spec);

/// Tool k's hold on its body as three springs on the body's row `row` (anchored to the tool),
/// appended up to capacity. Returns how many.
int rigid_grasp_springs(const ToolSpec& spec, const ToolState& ts, const RigidState& body, int32_t row,
                        std::vector<ContactSpring>& springs);

/// After the step: the hold's force on the tool (−Σ the springs' forces on the body at the
/// step's end) and its stiffness into `out`, added to what the tissue did; springs
/// [begin, end) are the tool's hold, the body moved from `start` to `end`.
void rigid_grasp_feedback(const ContactSpring* springs, int begin, int end, const RigidState& start,
                          const RigidState& end_state, const Vec3& tool_centre, ToolOutput& out);

}  // namespace stroma
