#pragma once
/// \file thread_contact.hpp
/// A thread's contacts (issue 43; docs/THREAD.md, "Contact"): with the tissue's surface, the
/// tools, the rigid bodies and itself (and other threads), as penalty springs of the collide
/// stage solved in the one implicit step with everything else.
///
/// The thread is a tube of radius r = diameter/2 around its centreline.
///  - Tissue: each segment is sampled at K = clamp(⌈ℓ/(4·diameter)⌉, 1, 8) points (its start,
///    then every ℓ/K; the rod's last node too). Each point takes the closest point q of the
///    nearby active surface triangles (one BVH query per segment; one triangle per point, so a
///    point over an edge is not counted twice); its signed distance σ (negative under the face)
///    gives the depth r − σ along the direction from the tissue to the thread. The spring joins
///    the thread's point (two rod nodes) and the triangle's point (its DOFs): a spring across
///    parts, its rod–tissue pairs applied matrix-free (ContactSpring::matrix_free), so the
///    thread presses on the tissue and the tissue on the thread in the same solve. Stiffness: the
///    thread's contact_stiffness (Pa/m; by default 10·E_max/diameter) over the point's projected
///    area diameter × its share of the arc length — per metre of thread 10·E_max, ten times the
///    tissue's own stiffness under a line load (~E), so the penalty's part of an indentation is
///    ~10 % of the tissue's. Not the rigid bodies' 100·E_max/feature: the pairs across the parts
///    are not in the preconditioner, and on the swinging suture that touches a block
///    (tests/data/server/thread.yaml) that stiffness took CG from ~7 to > 40 iterations, past
///    the served budget tick after tick; at 10·E_max it stays at ~7. Skipped: points deeper
///    than 10 diameters (the closest face is then no longer the one it came through: a thread
///    pressed that deep — a line load of 100·E_max·diameter — is lost); points within a hole
///    radius of a puncture or a needle's entry or exit (max(4·r, the body's track spacing, 4 needle
///    wire radii)) or of an anchored end's material point (1.5 segments); and the thread between the punctures it is inside of — pairing them from
///    the end not tied to a needle (that end is outside), the arc between each pair is in the
///    tissue.
///  - Itself and other threads: every pair of segments not sharing a node (|i − k| ≥ 2 on one
///    rod), closest points (s, t) on the two centrelines at distance d: a spring between the
///    two points (four rod nodes, matrix-free where the pattern lacks the pair), depth 2r − d
///    along the line joining them, stiff as the stiffer rod's segment axial spring k_s = E·A/ℓ
///    (a tension T presses two crossing threads T/k_s into each other: 1 N on a 5 GPa,
///    0.2 mm suture of 2 mm segments is 13 µm, an eighth of its radius).
///  - Tools: each shaped tool's capsules against each segment (closest points of the two
///    segments), penetrating only (tools are prescribed: a spring in front could only pull),
///    k_s; felt by the tool as its other springs. A tool holding a thread skips the two
///    segments either side of its grasp, one holding a needle the thread tied to it (a needle
///    holder's jaws hold the swaged end) — and, once it lets go of either, the segments within
///    its jaws' reach (their length and two radii, and two segments more) of where it held
///    until they are clear of its capsules (ToolState::released_segment). Frictionless: a tool's velocity
///    is not the step's to know.
///  - Rigid bodies: each segment's sample points against the body's shape (its signed distance,
///    rigid_contact.hpp shape_distance), k_s × the point's share of the segment; a thread skips
///    the needle it is tied to.
/// Speculative springs (points in front) are made when the approach at the start of the step
/// (and the fall under gravity) closes the gap to within a quarter radius, and released and the
/// step redone if they end it pulling (RigidContactPair, release_pulling_rigid_contacts). Friction: the thread's `friction`
/// (with another thread, the smaller), regularised Coulomb as rigid contact's (fill_contact_spring).
/// No allocation: per-segment buffers on the stack.

#include <vector>

#include "collision/contact_surface.hpp"
#include "collision/triangle_bvh.hpp"
#include "engine/model.hpp"
#include "engine/state.hpp"
#include "rigid/rigid_contact.hpp"

namespace stroma {

/// Most sample points per segment (thread–tissue, thread–rigid).
inline constexpr int kThreadSamplesPerSegment = 8;
/// Sample spacing, in diameters.
inline constexpr double kThreadSampleDiameters = 4.0;
/// Most holes (punctures, needles' entries and exits) the thread–tissue contact skips around.
inline constexpr int kMaxThreadHoles = 64;

/// What the threads' contacts did in one tick (TickReport::thread_contact).
struct ThreadContactOutput {
  int32_t tissue = 0, self = 0, tools = 0, rigid = 0;  ///< springs made (speculative ones included)
  int32_t dropped = 0;     ///< beyond the springs' capacity (not applied)
  /// Springs the continuous checks after the step added (thread_missed_self_contacts,
  /// thread_missed_rigid_contacts; the step redone with them), counted in `self` or `rigid` too.
  int32_t missed = 0;
  /// Passes after which the continuous checks did not run: no redo would have fitted before the
  /// deadline (served; engine/step_with_recovery.cpp).
  int32_t unchecked = 0;
  double max_depth = 0;    ///< m: the deepest penetration of a thread's surface found
};

/// Sets sp's DOFs: nodes[0..n) with weights w (signed: a spring across parts), each pair's
/// slot from the pattern — kSlotMatrixFree (and matrix_free set) where it has no block, and for
/// every pair across the sides (weights of opposite signs), so the assembled part is PSD.
void set_spring_nodes(const BsrPattern& pattern, const int32_t* nodes, const double* w, int n, ContactSpring& sp);

/// Every thread against the tissue's surface (surface points px, DOF velocities v; BVH
/// refitted), after the punctures' before-step update. Appends springs (and the speculative
/// ones' pairs).
void thread_tissue_contact(const Model& m, const State& s, const ContactSurface& surf, const TriangleBvh& bvh,
                           const double* px, const double* v, std::vector<ContactSpring>& springs,
                           std::vector<RigidContactPair>& pairs, ThreadContactOutput& out);

/// A rod segment's bounding sphere for the self-contact broad phase: its midpoint and its
/// half-length plus its reach this step (2·h·speed + 1.25 × its radius), so two segments can touch
/// in the step only if their spheres overlap (reach_a + reach_b ≥ the pair's cap).
struct SegmentSphere {
  double c[3] = {0, 0, 0};
  double r = 0;
  int32_t node = 0;  ///< the segment's first node (global)
  int32_t rod = 0;
};

/// Every thread against itself and the other threads: a sweep along the axis the segments'
/// midpoints spread most on (`spheres`, `order`: scratch sized to the rods' segments at load),
/// then the pairs whose spheres overlap and that share no node, in a deterministic order.
void thread_self_contact(const Model& m, const double* x, const double* v, std::vector<SegmentSphere>& spheres,
                         std::vector<int32_t>& order, std::vector<ContactSpring>& springs,
                         std::vector<RigidContactPair>& pairs, ThreadContactOutput& out);

/// Most samples of a segment pair's motion in the continuous check (every quarter of the two
/// radii of relative motion: a crossing is seen up to 16 radii a step, 1.6 m/s for a 0.2 mm
/// suture at 1 kHz).
inline constexpr int kThreadCcdSamples = 64;

/// The continuous check after a step x0 → x1 (issue 43's "never passes through itself"): the
/// speculative springs of thread_self_contact are made only for pairs whose approach at the
/// step's start closes their gap, and a thread's bending can accelerate two segments through
/// each other within the step (a knot laid tight springing open). Every pair of segments sharing
/// no node whose centrelines, moving linearly from x0 to x1, come closer than the two radii —
/// sampled every quarter radius of relative motion — and that has no self spring in
/// springs[self_begin, end) acting in the step gets one, made where they were just before
/// touching (its normal the line between those points, its depth theirs at the step's start
/// along it) — a released one of the pair (it ended an earlier pass pulling) made again in its
/// place. Either is pinned (RigidContactPair::pinned): kept to the step's end even if it ends
/// it pulling, a little stickiness for a tick rather than a pass-through (released, such a pair
/// was seen to go through in the redone step: a knot's tightening) — for that tick a pinned
/// spring holds its pair touching, as a two-sided constraint would. Only pairs that meet are
/// taken: a margin (tried: a quarter of the two radii) pinned resting neighbours of a knot
/// together tick after tick, and the knot froze. v0: the start velocities (friction). Returns
/// how many: the caller redoes the step with them.
int thread_missed_self_contacts(const Model& m, const double* x0, const double* v0, const double* x1,
                                std::vector<SegmentSphere>& spheres, std::vector<int32_t>& order, size_t self_begin,
                                std::vector<ContactSpring>& springs, std::vector<RigidContactPair>& pairs,
                                ThreadContactOutput& out);

/// The same continuous check for threads against rigid body k over the step (start state bs0,
/// end bs1; step row `row`, −1 for a fixed body): a thread's sample point (those of
/// thread_rigid_contact) whose path in the body's frame, x0 → x1 against bs0 → bs1, enters the
/// body's shape less the thread's radius (sampled every quarter radius of the motion) and that
/// has no spring acting against the body in the step gets one, pinned, made where it was just
/// before (the shape's normal there, at the body's start pose) — a released one made again in
/// its place. A free body without a row this step (it touched nothing at its start) is not
/// checked: a row cannot be added after the collide stage (the caller skips it). Returns how
/// many.
int thread_missed_rigid_contacts(const Model& m, int32_t k, const RigidState& bs0, const RigidState& bs1, int32_t row,
                                 const double* x0, const double* v0, const double* x1,
                                 std::vector<ContactSpring>& springs, std::vector<RigidContactPair>& pairs,
                                 RigidContactOutput& bout, ThreadContactOutput& out);

/// Tool `spec` (state ts) against every thread: springs appended to the tool's range
/// (out.spring_end moves; out.contacts and out.stiffness count them); clears
/// ts.released_segment once the thread it let go of is clear. Returns how many.
int thread_tool_contact(const Model& m, const ToolSpec& spec, ToolState& ts, const double* x, ToolOutput& out,
                        std::vector<ContactSpring>& springs, ThreadContactOutput& tout);

/// Rigid body k (state bs, step row `row`, −1: none) against every thread not tied to it.
/// Returns how many springs.
int thread_rigid_contact(const Model& m, int32_t k, const RigidState& bs, int32_t row, const double* x,
                         const double* v, std::vector<ContactSpring>& springs, std::vector<RigidContactPair>& pairs,
                         RigidContactOutput& bout, ThreadContactOutput& out);

/// Closest points of segments p0–p1 and q0–q1: parameters s, t in [0, 1] (Ericson, Real-Time
/// Collision Detection §5.1.9); returns the squared distance.
double segment_closest_points(const double* p0, const double* p1, const double* q0, const double* q1, double* s,
                              double* t);

}  // namespace stroma
