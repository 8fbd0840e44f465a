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
///  - where a thread goes through the tissue (State::punctures, tissue/rod.hpp RodPuncture): made
///    where the tail of the needle it is tied to passes one of the needle's entries or exits (the
///    track's surface points), the thread then tied to that material point at σ — its tied end
///    at first. Each tick a spring joins the thread's point at σ (two nodes of a segment) and the
///    tissue's point (four nodes of a tetrahedron): stiff across the thread and along it, its
///    cross pairs applied matrix-free (ContactSpring::matrix_free), so pulling the thread pulls
///    the tissue there. After each step, friction: along the thread the spring holds at most
///    μ·|its force across the thread| (Coulomb, μ the thread's `friction`) — beyond, σ moves so
///    that it holds exactly that (the thread slides through); a puncture a free end slides out
///    of is gone (at an end tied to the needle σ stays at the end). At a bend θ through a point this is T₂ − T₁ = μ·N, the capstan law's first order.
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

/// Most a sliding puncture's σ is predicted to move in one step (segments).
inline constexpr double kMaxPunctureSlip = 0.5;

/// The rod's point at σ and the segment it is on: x = (1 − u)·x_j + u·x_{j+1}.
struct RodPoint {
  int32_t j = 0;  ///< global node of the segment's start
  double u = 0;
};
RodPoint rod_point(const RodRange& r, double sigma);

/// Before a step: a puncture that slid in the last step starts this one that much further on
/// (σ += slip) — the slip a steady pull makes each step, so its spring is not dragged behind.
void thread_punctures_before_step(const Model& m, State& s);

/// Puncture p's spring for this step (its thread's segment point less the tissue's point,
/// matrix-free across the parts), appended capacity permitting. Returns 0 or 1.
int thread_puncture_spring(const FemModel& fem, const RodPuncture& p, const double* x, std::vector<ContactSpring>& springs);

/// After a step at positions x, velocities v: each puncture's friction (σ slides where the force along the
/// thread is beyond μ·|the force across it|; the punctures the thread left are dropped), then
/// new punctures where needle k's tail passed its entries and exits this step (`passed`) for
/// each thread tied to its tail. Returns how many were made (those beyond the capacity are
/// counted in `dropped`).
int thread_punctures_after_step(const Model& m, State& s, const double* x, const double* v, const NeedleOutput* needles,
                                int* dropped);

}  // namespace stroma
