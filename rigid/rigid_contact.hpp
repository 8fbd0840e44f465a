#pragma once
/// \file rigid_contact.hpp
/// Rigid bodies' contacts with the tissue and with each other, for one step, as contact springs
/// that name the bodies' rows (tissue/rigid_rows.hpp): the tissue and the body are solved
/// together, so the body pushes the tissue and the tissue pushes the body in the same implicit
/// step.
///
///  - Tissue against a body: the tissue's surface triangles near the body are sampled at the
///    centroids of s² sub-triangles (as a tool samples them, haptics/contact.hpp, spaced by the
///    body's smallest feature); a sample inside the body's shape (its signed distance d < 0)
///    gets a penalty pressure k·(−d) over its share of the area, along the shape's outward
///    normal, acting between the tissue point and the body's point there. A free body's spring
///    moves with its row; a fixed body's is anchored.
///  - Speculative contacts: a sample in front of the body (0 ≤ d) within the step's reach —
///    its predicted approach h·v_rel·n + h²·g·n, or the body's own travel h·|v| — gets the same
///    linear spring, k·A·(−d − n·Δ): it pushes only from where the sample would reach the
///    surface. A spring that ends the step pulling (the sample stayed in front) is released and
///    the step redone (release_pulling_rigid_contacts, as body–body contact does). A penalty
///    contact found only once it penetrates stores ½k d² the approach never paid for (measured:
///    a steel ball dropped 10 mm on 10 kPa tissue gained 55 % of its drop's energy in one tick,
///    the light surface nodes it had pushed ahead rebounding into it); a speculative one's
///    potential is the penalty's own, so impacts add no energy.
///  - A needle's wire samples the surface instead (rigid/wire_contact.hpp), with the same
///    springs: a thin wire slips between a coarse surface's samples.
///  - Friction: regularised Coulomb on the sliding velocity relative to the body (the tools'
///    rule), as damping in the spring's C: it acts on both sides in the implicit step.
///  - Body against body: the smaller body's surface samples (RigidBodyModel::sample_points,
///    by bounding radius) against the larger's shape, the same springs between the two rows
///    (or against a fixed body). One direction only, so a face on a face is not counted twice.
///
/// Shapes' signed distances are exact for the sphere, capsule and box; for a closed mesh the
/// distance to its nearest triangle, inside where the generalised winding number exceeds ½.
/// No allocation: springs go to a vector whose capacity is fixed at load.

#include <cstdint>
#include <vector>

#include "collision/contact_surface.hpp"
#include "collision/triangle_bvh.hpp"
#include "rigid/rigid_body.hpp"

namespace stroma {

/// A speculative contact of this tick: its spring, the normal it is measured along (from the
/// anchor's side to the positive side) and its depth at the start of the step (< 0: in front).
struct RigidContactPair {
  int32_t spring = 0;
  double n[3] = {0, 0, 0};
  double depth0 = 0;
  bool active = true;
  /// Kept even if it ends the step pulling: the threads' continuous check found its two sides
  /// meet within the step without it (engine/thread_contact.hpp, thread_missed_self_contacts).
  bool pinned = false;
};

/// What one body's contacts did in one step (tick output).
struct RigidContactOutput {
  int32_t contacts = 0;    ///< springs made (speculative ones included)
  int32_t dropped = 0;     ///< beyond the springs' capacity (not applied)
  double energy = 0;       ///< J: penalty potential Σ ½ k A d² of the penetrating samples
  double max_depth = 0;    ///< m
  /// N: the contacts' force on the body as the step applied it (at its end state; filled by
  /// rigid_forces_after_step).
  Vec3 force{0, 0, 0};
};

/// One contact's spring between its positive side's point and a body's: normal n (world, from
/// the anchor's body towards the positive side), depth (> 0 penetrating; < 0 a speculative
/// spring, pulling until released), area stiffness kc and damping cc, regularised Coulomb
/// friction mu on the sliding velocity rel (positive side's less the anchor's; v_stick its
/// regularisation). Counts the contact, and a penetrating one's energy and depth, in `out`.
void fill_contact_spring(ContactSpring& sp, const double* n, double depth, bool speculative, double kc, double cc,
                         double mu, const double* rel, double v_stick, RigidContactOutput& out);

/// Signed distance (m) of the body-frame point p to the body's shape (< 0 inside), and the
/// shape's outward unit normal there (body frame) into `normal`.
double shape_distance(const RigidBodyModel& b, const double* p, double* normal);

/// Surface samples of a shape (body frame) spaced about `spacing`: fills b.sample_points,
/// sample_normals and sample_areas, b.bounding_radius and b.feature, and a needle's wire
/// samples (rigid/wire_contact.hpp). Load time.
void make_contact_samples(RigidBodyModel& b);

/// Where a needle makes no contact with the tissue's surface (rigid/needle_track.hpp): ahead of
/// its tip, around its holes — the tissue points within `hole_radius` of one of the `n_holes` points `holes`
/// (3 each, world) — and along the part of its wire in the tissue, arc lengths
/// [track_s0, track_s1] (an empty range when track_s0 > track_s1), coupled to the tissue by its
/// track instead (a cut across the track makes faces the shaft crosses).
struct ContactExclusion {
  const double* holes = nullptr;
  int n_holes = 0;
  double hole_radius = 0;
  double track_s0 = 1, track_s1 = 0;
  /// m of arc before the needle's tip where a surface ahead of the wire (its contact normal
  /// within 60° of the tip's direction) is the tip's to press and puncture, not the wire's
  /// (0: none; needle_contact_exclusion in rigid/needle_track.hpp sets it while an exited needle's
  /// tip presses).
  double tip_zone = 0;
};

/// Whether the world point q is within ex.hole_radius of one of ex's holes.
bool near_a_hole(const ContactExclusion& ex, const double* q);

/// Room for one more contact spring — and, for a speculative one (gap ≥ 0), its pair, recorded
/// for the spring about to be appended (along n, depth0 = −gap): false (nothing recorded) when
/// either list is full.
inline bool reserve_contact(const std::vector<ContactSpring>& springs, std::vector<RigidContactPair>& pairs,
                            double gap, const double* n) {
  const bool speculative = gap >= 0;
  if (springs.size() == springs.capacity() || (speculative && pairs.size() == pairs.capacity())) return false;
  if (speculative) {
    RigidContactPair pr;
    pr.spring = static_cast<int32_t>(springs.size());
    for (int k = 0; k < 3; ++k) pr.n[k] = n[k];
    pr.depth0 = -gap;
    pairs.push_back(pr);
  }
  return true;
}

/// Appends the contact spring between the tissue's surface point (barycentric b0, b1, b2 on the
/// triangle with DOFs td) and the point of body state s at `arm` (world, from its centre of
/// mass; `row` its row, −1 anchored), along the unit n from the body to the tissue, `gap` apart
/// (< 0 penetrating). One in front (gap ≥ 0) is speculative and made only if the step can close
/// it — its approach h·v_rel·n plus, for a free body, its fall h²·g·n, or the body's own travel
/// h·speed. kc, cc: area stiffness and damping; mu, v_stick: friction. Counts a spring beyond
/// the vectors' capacity as dropped. Returns whether it made one.
bool add_tissue_body_spring(const SurfaceTriangleDofs& td, double b0, double b1, double b2, const RigidState& s,
                            int32_t row, const double* arm, const double* n, double gap, double kc, double cc,
                            double mu, double v_stick, const double* v, double h, const Vec3& g, double speed,
                            std::vector<ContactSpring>& springs, std::vector<RigidContactPair>& pairs,
                            RigidContactOutput& out);

/// The tissue's surface (points x, velocities v; BVH refitted) against body b at state s.
/// `row`: the body's row in the step (−1: a fixed body, anchored). `constrained` (per DOF node,
/// the axes held as bits; may be null): a fixed body skips triangles whose DOFs are all held
/// (nothing there can move). Nothing is made where `ex` excludes it. Appends springs up to the
/// vector's capacity.
void rigid_tissue_contact(const RigidBodyModel& b, const RigidState& s, int32_t row, const ContactSurface& surf,
                          const TriangleBvh& bvh, const double* x, const double* v, const uint8_t* constrained,
                          double h, const Vec3& g,
                          std::vector<ContactSpring>& springs, std::vector<RigidContactPair>& pairs,
                          RigidContactOutput& out, const ContactExclusion& ex = {});

/// Body a's surface samples against body b's shape (rows −1 for fixed bodies; not both fixed).
void rigid_rigid_contact(const RigidBodyModel& a, const RigidState& sa, int32_t row_a, const RigidBodyModel& b,
                         const RigidState& sb, int32_t row_b, double h, const Vec3& g,
                         std::vector<ContactSpring>& springs, std::vector<RigidContactPair>& pairs,
                         RigidContactOutput& out_a, RigidContactOutput& out_b);

/// The contacts' forces on each body as the solved step applied them — each spring at the
/// step's end, f − K·Δ − C·v_rel (Δ, v_rel: its sides' relative displacement and end velocity)
/// — summed into out[body].force (set, not added). Tissue velocities v, bodies from `start`
/// to `end`; `row_body` maps rows to bodies.
void rigid_forces_after_step(const double* x0, const double* x, const double* v, const RigidState* start,
                             const RigidState* end, const int32_t* row_body, const ContactSpring* springs, int count,
                             RigidContactOutput* out, int bodies);

/// Velocity of the body's point at arm r (world): v + ω × r.
inline void body_point_velocity(const RigidState& s, const double* r, double* out) {
  out[0] = s.v[0] + s.w[1] * r[2] - s.w[2] * r[1];
  out[1] = s.v[1] + s.w[2] * r[0] - s.w[0] * r[2];
  out[2] = s.v[2] + s.w[0] * r[1] - s.w[1] * r[0];
}

/// How far the point at arm `a` (world, at the start) of a body moved from `s0` to `s1`.
void body_point_displacement(const RigidState& s0, const RigidState& s1, const double* a, double* d);

/// The force on spring sp's positive side as the solved step applied it: f − K·Δ − C·v_rel at
/// the step's end (Δ, v_rel: its sides' relative displacement and end velocity; tissue from x0
/// to x with end velocities v, bodies from `start` to `end`, rows mapped by row_body).
void rigid_spring_force_after_step(const ContactSpring& sp, const double* x0, const double* x, const double* v,
                                   const RigidState* start, const RigidState* end, const int32_t* row_body,
                                   double* f);

/// After a step from tissue positions x0 to x and rigid states `start` to `end` (per body;
/// `row_body` maps the springs' rows to bodies): the speculative contacts whose spring ends
/// the step pulling are switched off (their springs zeroed). Returns how many.
int release_pulling_rigid_contacts(const double* x0, const double* x, const RigidState* start, const RigidState* end,
                                   const int32_t* row_body, std::vector<RigidContactPair>& pairs,
                                   std::vector<ContactSpring>& springs);

}  // namespace stroma
