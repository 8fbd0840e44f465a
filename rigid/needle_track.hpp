#pragma once
/// \file needle_track.hpp
/// A needle in tissue (issue 42; docs/NEEDLE.md): puncture, the track it cuts, the friction
/// along it and the exit — as contact springs naming the needle's rigid row, solved in the
/// tissue's implicit step like every other coupling (docs/ARCHITECTURE.md, "Bodies of more than
/// one kind"), and a short update of the needle's state after each step.
///
/// Phases (NeedleState::phase): Outside → (puncture) → Inserted → (exit) → Exited, and back to
/// Outside once no track point is left on the needle (withdrawn, or pulled through). An exited
/// needle punctures again as an outside one does (a second bite: the other lip of a wound, or
/// another body): Exited → Inserted, the first bite's track kept; drawn back out of the second
/// bite it is Exited again.
///
///  - **Puncture.** Outside, the tip presses the tissue through the ordinary contact springs
///    (rigid/rigid_contact.hpp). After a step, the force those within 1.5 wire radii of the tip's
///    centre put on the tissue along the tip's direction t is compared with the touched body's
///    puncture force (its material's `needle.puncture_force`); above it the tip enters: the
///    entry point (the tissue's material point where the tip's apex is, or the nearest boundary
///    point) becomes the first track point and the cutting front. Contact is then skipped around
///    the track's surface points (the hole), so the dimple relaxes: the force drops.
///  - **Track points.** Material points of the tissue (barycentric in a tetrahedron, as probes
///    are) tied to the needle's curve at arc length s: a spring k_t·ℓ₀ across the curve and
///    along it (ℓ₀: the track spacing; k_t: the material's `track_stiffness`, N/m per m). Along
///    the curve the spring is elasto-plastic friction (a Karnopp-like stick–slip): after each
///    step, a point whose axial force exceeds its static limit f_s·ℓᵢ (ℓᵢ: its share of the
///    inserted length) slips — s moves so the force is the kinetic f_k·ℓᵢ — and keeps the kinetic
///    limit while it slides; a step that needs no slip sticks it again. Slipping only lowers the
///    spring's energy. A curved needle's points follow the arc (c(s) is on it), so driving the
///    needle along its own curve drags the tissue only by friction.
///  - **Cutting.** The front is the material point at the end of the cut: a one-sided spring
///    along t pushes it ahead of the tip's apex (speculative, released if it ends the step
///    pulling, as contacts are). A front force above the cutting force moves the front on —
///    walking the tetrahedra to the point F_c/k behind the apex (tissue/tet_walk.hpp) — so the
///    axial resistance there is the cutting force; every ℓ₀ of new track a track point is made.
///  - **Exit.** A front whose walk leaves the mesh has cut through: the boundary point it
///    crossed becomes the exit track point (in a cut model, a cut face is such a boundary: the
///    walk ends where it leaves its copy's material, tissue/tet_walk.hpp); the tip's contact from inside is the same as
///    outside (its push on the far surface puncture it as above). Track points that slide off
///    either end of the curve (s < 0 or s > L) leave the needle; when none is left the needle is
///    outside again. Withdrawal slides the points towards the tip: friction reverses.
///
/// No allocation: the track has a fixed capacity (NeedleState::track is sized at load).

#include <cstdint>
#include <vector>

#include "rigid/rigid_body.hpp"
#include "rigid/rigid_contact.hpp"
#include "tissue/contact_spring.hpp"
#include "tissue/fem_model.hpp"
#include "tissue/tet_walk.hpp"

namespace stroma {

/// How one tissue body meets needles (its material's `needle:` block), resolved at load.
/// Invariants when enabled: puncture_force, cutting_force > 0; 0 ≤ friction_kinetic ≤
/// friction_static; track_stiffness, track_spacing > 0.
struct NeedleTissue {
  bool enabled = false;           ///< false: needles press this body but never puncture it
  double puncture_force = 0;      ///< N, along the tip's direction
  double cutting_force = 0;       ///< N, at the tip while it advances in the tissue
  double friction_static = 0;     ///< N per m of inserted length
  double friction_kinetic = 0;    ///< N per m of inserted length
  double track_stiffness = 0;     ///< N/m per m of track (the coupling across and along the needle)
  double track_spacing = 0;       ///< m between track points
};

enum class NeedlePhase : uint8_t { Outside = 0, Inserted = 1, Exited = 2 };
/// "outside", "inserted", "exited" (outputs, DDS, Python).
inline const char* needle_phase_name(NeedlePhase p) {
  return p == NeedlePhase::Inserted ? "inserted" : (p == NeedlePhase::Exited ? "exited" : "outside");
}

/// A material point of the tissue tied to the needle's curve. Invariants: w ≥ 0, Σw = 1;
/// node are the element's nodes. No padding (copied and hashed as bytes).
struct TrackPoint {
  double w[4] = {0, 0, 0, 0};
  double s = 0;          ///< m: the arc length it is tied to
  int32_t tet = -1;
  std::array<int32_t, 4> node{};
  uint8_t sliding = 0;   ///< 0: stuck; slid last step (the kinetic limit holds) with 1: e > 0, 2: e < 0
  uint8_t surface = 0;   ///< 1: an entry, 2: an exit (contact is skipped around them); a front: 1 makes its first cut an entry
  int16_t body = 0;      ///< the FEM body it is in (a needle through two lips has points in both)
};
static_assert(sizeof(TrackPoint) == 64, "TrackPoint has padding");

/// Everything of a needle's insertion the next tick depends on. Invariants: track.size() is
/// the capacity (fixed at load), count ≤ it; track[0..count) in order of increasing s (entry
/// first) — one run from an entry (surface 1) per bite, each but the one being cut ending in its
/// exit (surface 2); has_front ⇒ phase == Inserted; phase == Outside ⇒ count == 0 (an Inserted
/// needle may have its front alone: punctured where the apex had not reached the dimpled
/// surface yet).
struct NeedleState {
  NeedlePhase phase = NeedlePhase::Outside;
  int32_t tissue_body = -1;  ///< the FEM body it is in (−1: outside)
  int32_t count = 0;
  std::vector<TrackPoint> track;
  TrackPoint front;          ///< the cutting front (valid when has_front)
  uint8_t has_front = 0;
  uint8_t tip_touching = 0;  ///< 1: the tip pressed the tissue at the end of the last step
  int32_t punctures = 0;     ///< entries and exits so far (events)
  /// m: how deep the tip's apex already was when its contact began (0 for one found in front, as
  /// an approach finds it). A contact found deep — the apex left in its own hole as the needle
  /// came out — pushes only from there: a penalty found deep would hold energy no approach paid
  /// for. Kept while it touches.
  double tip_offset = 0;
};

/// What a needle did in one tick (TickReport): its events and the forces along it.
struct NeedleOutput {
  NeedlePhase phase = NeedlePhase::Outside;
  bool punctured = false, exited = false, left = false;  ///< events this tick
  int32_t tissue_body = -1;    ///< the FEM body it is in (left: the one it left); −1: none
  double tip_force = 0;        ///< N: the tip's contact push along t (outside), or the front's (inside)
  double friction_force = 0;   ///< N: Σ the track's axial forces on the needle along t at the tip (signed)
  double inserted_length = 0;  ///< m
  int32_t track_points = 0;
  /// Entries and exits (surface track points) the needle's tail passed this step — where a
  /// thread tied to its tail now goes through the tissue (engine/thread_attach.hpp).
  std::array<TrackPoint, 4> passed{};
  int32_t passed_count = 0;
};

/// A track point or front sliding in this step (its axial force the kinetic one, constant): if
/// the needle turns back relative to it during the step, it sticks again — its spring gets its
/// axial stiffness back and the step is redone (stick_reversed_slips), as a speculative contact
/// that ends pulling is released.
struct NeedleSlip {
  int32_t spring = 0;
  double t[3] = {0, 0, 0};  ///< the needle's tangent there
  double d = 0;             ///< the sign of (tissue point − needle point)·t while it slides
  double k = 0;             ///< N/m: the axial stiffness it gets back
  int32_t pair = -1;        ///< a front's speculative pair (released: the slip goes with it)
  bool active = true;
};

/// The curve's world point, tangent and arm (from the centre of mass) at arc length s.
void needle_world_point(const RigidBodyModel& b, const RigidState& s, double arc, double* p, double* t, double* arm);

/// The tissue's springs of the needle for one step: one per track point, and the front's
/// (speculative: a RigidContactPair). `row`: the needle's rigid row (−1: fixed). Appends up to
/// the vectors' capacity; returns the springs made.
int needle_track_springs(const RigidBodyModel& b, const RigidState& s, int32_t row, const NeedleState& ns,
                         const std::vector<NeedleTissue>& tissue, const FemModel& fem, const double* x, double h,
                         std::vector<ContactSpring>& springs, std::vector<RigidContactPair>& pairs,
                         std::vector<NeedleSlip>& slips);

/// After a step: the sliding track points and fronts (slips) the needle turned back against
/// stick (their springs get k·t tᵀ back). Returns how many; the caller redoes the step.
int stick_reversed_slips(const double* x0, const double* x, const RigidState* start, const RigidState* end,
                         const int32_t* row_body, const std::vector<RigidContactPair>& pairs,
                         std::vector<NeedleSlip>& slips, std::vector<ContactSpring>& springs);

/// The tip's own contact while the needle is outside or exited (not cutting): its apex (the point one wire radius past
/// the curve's end) against the tissue surface where the needle's axis crosses it, pushing along
/// the axis — a sharp point on a surface, where the rounded end's samples would slide off a
/// coarse triangle sideways. Stiffness: the body's contact stiffness over the wire's
/// cross-section (a frictionless point: no force across the axis).
/// Speculative in front of the surface (released if it ends pulling). Sets ns.tip_offset when a
/// contact begins. An exited needle also looks back along its axis, most of the way to its last
/// bite's entry: a surface it is already in (the far lip of an incision, pushed into by the near
/// one — the lips have no contact of their own) is touched from where the apex is. Returns the spring's index (and its surface triangle in `triangle`), or −1.
int32_t needle_tip_contact(const RigidBodyModel& b, const RigidState& s, int32_t row, NeedleState& ns,
                           const ContactSurface& surf, const TriangleBvh& bvh, const double* x, double h,
                           std::vector<ContactSpring>& springs, std::vector<RigidContactPair>& pairs,
                           RigidContactOutput& out, int32_t* triangle);

/// Most holes (entries and exits) around which contact is skipped for one needle: four bites
/// (two lips, and a sliver a served cut can leave between them).
inline constexpr int kMaxNeedleHoles = 8;

/// What the tissue's contact with needle b (state ns, tissue at x) leaves out, the rule in one
/// place (rigid/rigid_contact.hpp's ContactExclusion): once in, the surface within hole_radius
/// (4 wire radii, or the track spacing `track_spacing` if larger) of its holes — the track's
/// entries and exits, their positions written to `holes` (room for kMaxNeedleHoles) — and the
/// wire along the track's arc (its first track point's to its last's or the front's); and, while
/// an exited needle's tip presses the next surface (`tip_pressing`: its tip contact this step),
/// a surface ahead of the wire within hole_radius behind the tip: coming out of one lip of an
/// incision its wire already touches the other, whose puncture is the tip's. Outside: nothing.
ContactExclusion needle_contact_exclusion(const RigidBodyModel& b, const NeedleState& ns, const double* x,
                                          double track_spacing, bool tip_pressing, double* holes);

/// The tissue body of DOF node n (by the bodies' node ranges), or −1.
int32_t body_of_node(const FemModel& fem, int32_t node);

/// After a solved step: puncture, the track's friction (return mapping), the front's cutting,
/// new track points, exit, points leaving the needle. `tip_spring`: the tip's contact spring
/// this step (needle_tip_contact; −1: none), whose force after the step decides puncture, and
/// `tip_element` an element with its triangle's face (the entry's walk starts there); x0/x/v the
/// tissue at the step's start and end; start/end the needle's rigid state; row_body maps rows
/// to bodies (for the springs' other sides). `mesh` is the tetrahedra the walks cross (a cut
/// model's copies with their material planes: a cut face is the tissue's boundary, where the
/// front exits and the other lip is bitten), `node_tet` an element of each node (walks start there).
void needle_after_step(const RigidBodyModel& b, int32_t body_index, const RigidState* start, const RigidState* end,
                       const int32_t* row_body, const ContactSpring* springs, int32_t tip_spring,
                       int32_t tip_element, const std::vector<NeedleTissue>& tissue, const FemModel& fem,
                       const WalkMesh& mesh, const int32_t* node_tet, const double* x0, const double* x, const double* v,
                       NeedleState& ns, NeedleOutput& out);

}  // namespace stroma
