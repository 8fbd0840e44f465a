#pragma once
/// \file thread_attach.hpp
/// A thread's attachments that live in the tick (issue 43; docs/THREAD.md), as springs of the
/// collide stage solved in the one implicit step:
///  - an end tied to a needle's tail (Model::thread_ties): a spring between the rod's node and
///    the needle's point, naming the needle's rigid row — the thread follows the needle, and
///    pulls on it;
///  - a tool's grasp of a thread: closing the jaws with a thread's segment within reach of the
///    grasp centre (as for tissue and rigid bodies: the tip, or the middle of a grasper's jaws;
///    reach = grasp.reach × radius, + half the jaws' length) — and no rigid body there, which
///    takes precedence — holds the segment's point nearest to the grasp centre where it was in
///    the tool's frame, by a spring of the tool's grasp stiffness, felt by the tool; opening
///    releases it.
/// (An end anchored in tissue is a constant of the model: tissue/rod.hpp, RodAnchor.)

#include <vector>

#include "engine/model.hpp"
#include "engine/state.hpp"
#include "tissue/contact_spring.hpp"

namespace stroma {

/// The thread grasps' transitions this tick, after update_rigid_grasps and before the tools'
/// contacts: a closing jaw with no body grasped takes the nearest thread point within reach;
/// an opening one or an idle tool lets go.
void update_thread_grasps(const Model& m, State& s);

/// Tool k's hold on its thread point, appended (capacity permitting) and added to its output
/// (contacts, the tool's range of springs, stiffness). Returns how many (0 or 1).
int thread_grasp_springs(const Model& m, const ToolSpec& spec, const ToolState& ts, const double* x, ToolOutput& out,
                         std::vector<ContactSpring>& springs);

/// Tie `tie`'s spring (its rod node to the needle's tail) on the needle's row `row` (−1: the
/// needle is fixed: the tail a fixed anchor), appended capacity permitting. Returns 0 or 1.
int thread_tie_spring(const Model::ThreadTie& tie, const RigidState& body, int32_t row, const double* x,
                      const BsrPattern& pattern, std::vector<ContactSpring>& springs);

}  // namespace stroma
