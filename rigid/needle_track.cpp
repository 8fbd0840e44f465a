#include "rigid/needle_track.hpp"

#include <algorithm>
#include <cmath>

#include "tissue/tet_walk.hpp"
#include "tissue/triangle_closest_point.hpp"

namespace stroma {

namespace {

inline double dot3(const double* a, const double* b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

/// The arc length of the tip's apex: the curve continues straight past the tip for one wire
/// radius (the rounded end's front), so track points there have a point to be tied to.
inline double apex_s(const RigidBodyModel& b) { return b.needle.length + b.needle.wire_radius; }

/// Tissue point of a track point at positions x.
inline void material_point(const TrackPoint& tp, const double* x, double* p) {
  for (int k = 0; k < 3; ++k)
    p[k] = tp.w[0] * x[3 * tp.node[0] + k] + tp.w[1] * x[3 * tp.node[1] + k] + tp.w[2] * x[3 * tp.node[2] + k] +
           tp.w[3] * x[3 * tp.node[3] + k];
}

/// A spring on the tissue point of tp (its element's slots), anchored at the needle's row.
void spring_on(const TrackPoint& tp, const FemModel& fem, int32_t row, const double* arm, ContactSpring& sp) {
  sp.n = 4;
  const ElementSlots& es = fem.slots[size_t(tp.tet)];
  for (int a = 0; a < 4; ++a) {
    sp.node[a] = tp.node[size_t(a)];
    sp.w[a] = tp.w[a];
  }
  for (int a = 0; a < 4; ++a)
    for (int c = 0; c < 4; ++c) sp.slot[spring_slot(a, c)] = tp.node[size_t(a)] <= tp.node[size_t(c)] ? es[size_t(4 * a + c)] : -1;
  sp.row_n = row;
  for (int k = 0; k < 3; ++k) sp.arm_n[k] = arm[k];
}

/// The needle's shape-frame point of world point p (state s).
void to_shape(const RigidBodyModel& b, const RigidState& s, const double* p, double* q) {
  const std::array<double, 9> R = rotation_of(s.q);
  const double d[3] = {p[0] - s.x[0], p[1] - s.x[1], p[2] - s.x[2]};
  for (int i = 0; i < 3; ++i) q[i] = R[size_t(i)] * d[0] + R[size_t(3 + i)] * d[1] + R[size_t(6 + i)] * d[2] - b.shape_origin[size_t(i)];
}

/// The arc length (on the curve extended to the apex) nearest world point p.
double project_s(const RigidBodyModel& b, const RigidState& s, const double* p) {
  double q[3];
  to_shape(b, s, p, q);
  const double si = needle_nearest_s(b.needle, q);
  if (si < b.needle.length) return si;
  double c[3], t[3];  // past the tip: along its tangent
  needle_curve(b.needle, b.needle.length, c, t);
  const double d[3] = {q[0] - c[0], q[1] - c[1], q[2] - c[2]};
  return std::min(b.needle.length + std::max(0.0, dot3(d, t)), apex_s(b));  // a point made there is on the needle
}

TrackPoint point_from_walk(const TetWalkResult& r, const FemModel& fem) {
  TrackPoint tp;
  tp.tet = r.tet;
  tp.node = fem.elements[size_t(r.tet)].node;
  for (int k = 0; k < 4; ++k) tp.w[k] = r.w[k];
  for (size_t b = 0; b < fem.bodies.size(); ++b)
    if (r.tet >= fem.bodies[b].element_begin && r.tet < fem.bodies[b].element_end) tp.body = static_cast<int16_t>(b);
  return tp;
}

/// A track point made where the tip is cutting: the needle slides past it from the start (the
/// kinetic limit, its spring at the kinetic force of a nominal share, pulling it along the
/// insertion: its needle point just ahead of it).
TrackPoint sliding_back(TrackPoint tp, const NeedleTissue& nt, double k, double s_max) {
  tp.sliding = 2;
  tp.s = std::min(tp.s + nt.friction_kinetic * nt.track_spacing / k, s_max);
  return tp;
}

/// Appends tp to the track if there is room (the deepest end). False: full.
bool push_point(NeedleState& ns, const TrackPoint& tp) {
  if (ns.count >= static_cast<int32_t>(ns.track.size())) return false;
  ns.track[size_t(ns.count++)] = tp;
  return true;
}

}  // namespace

void needle_world_point(const RigidBodyModel& b, const RigidState& s, double arc, double* p, double* t, double* arm) {
  double c[3], tc[3];
  needle_curve(b.needle, arc, c, tc);
  if (arc > b.needle.length)
    for (int k = 0; k < 3; ++k) c[k] += (arc - b.needle.length) * tc[k];
  const std::array<double, 9> R = rotation_of(s.q);
  const double pb[3] = {c[0] + b.shape_origin[0], c[1] + b.shape_origin[1], c[2] + b.shape_origin[2]};
  for (int i = 0; i < 3; ++i) {
    arm[i] = R[size_t(3 * i)] * pb[0] + R[size_t(3 * i + 1)] * pb[1] + R[size_t(3 * i + 2)] * pb[2];
    t[i] = R[size_t(3 * i)] * tc[0] + R[size_t(3 * i + 1)] * tc[1] + R[size_t(3 * i + 2)] * tc[2];
    p[i] = s.x[size_t(i)] + arm[i];
  }
}

int32_t body_of_node(const FemModel& fem, int32_t node) {
  for (size_t b = 0; b < fem.bodies.size(); ++b)
    if (node >= fem.bodies[b].node_begin && node < fem.bodies[b].node_end) return static_cast<int32_t>(b);
  return -1;
}

int32_t needle_tip_contact(const RigidBodyModel& b, const RigidState& s, int32_t row, NeedleState& ns,
                           const ContactSurface& surf, const TriangleBvh& bvh, const double* x, double h,
                           std::vector<ContactSpring>& springs, std::vector<RigidContactPair>& pairs,
                           RigidContactOutput& out, int32_t* triangle) {
  if (springs.size() == springs.capacity() || pairs.size() == pairs.capacity()) return -1;
  const double r = b.needle.wire_radius;
  double apex[3], t[3], arm[3];
  needle_world_point(b, s, apex_s(b), apex, t, arm);
  double va[3];
  body_point_velocity(s, arm, va);
  // A tip in front makes a (speculative) contact only if its travel this step can reach the
  // surface, as the bodies' do (rigid_contact.hpp), or it pressed at the end of the last (a
  // steady press stays on). A fixed margin gave a tip at rest within it a spring that could only
  // pull: released and the step redone, or kept pulling for a tick where a served tick's budget
  // skips the redo.
  const double reach = 2.0 * h * std::sqrt(dot3(va, va)) + (ns.tip_touching ? 0.25 * r : 0.0);
  // An exited needle may already be in the next surface: the lips of an incision press on each
  // other only through the tissue (no contact between them), so the near lip the needle pushes
  // out can pass into the far one, and the apex comes out of the near lip inside the far. Such a
  // surface is behind the apex, this side of the last bite's entry (whose own surface, crossed
  // going in, faces the same way): look back most of the way there.
  double behind = reach + 2.0 * r;
  if (ns.phase == NeedlePhase::Exited)
    for (int32_t i = ns.count - 1; i >= 0; --i)
      if (ns.track[size_t(i)].surface == 1) {
        double e[3];
        material_point(ns.track[size_t(i)], x, e);
        const double d[3] = {apex[0] - e[0], apex[1] - e[1], apex[2] - e[2]};
        behind = std::max(behind, 0.75 * std::sqrt(dot3(d, d)));
        break;
      }
  // Where the needle's axis through the apex crosses the surface (a front-facing triangle,
  // n·t < 0): the crossing nearest the apex. Its depth is how far the apex is past it along t.
  // Along the axis the crossing moves continuously from triangle to triangle (a nearest-
  // triangle normal would flip at the dimple's edges and rattle the needle).
  int32_t best = -1;
  double best_w[3] = {0, 0, 0}, best_depth = 0, best_abs = 1e300;
  bvh.query_sphere(apex, behind, x, [&](int32_t tri_index) {
    if (surf.active && !surf.active[tri_index]) return;
    const auto& tri = surf.triangles[size_t(tri_index)];
    const double* A = x + 3 * tri[0];
    const double* B = x + 3 * tri[1];
    const double* C = x + 3 * tri[2];
    const double e1[3] = {B[0] - A[0], B[1] - A[1], B[2] - A[2]}, e2[3] = {C[0] - A[0], C[1] - A[1], C[2] - A[2]};
    const double n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
    const double nt = dot3(n, t);
    if (!(nt < 0)) return;  // seen from behind, or edge-on
    // apex + λ t on the plane: n·(apex + λ t − A) = 0; its barycentrics (Möller–Trumbore form).
    const double ao[3] = {apex[0] - A[0], apex[1] - A[1], apex[2] - A[2]};
    const double lambda = -dot3(n, ao) / nt;
    if (-lambda > behind) return;  // behind the exit (or the query's reach)
    const double pt[3] = {ao[0] + lambda * t[0], ao[1] + lambda * t[1], ao[2] + lambda * t[2]};
    const double nn = dot3(n, n);
    const double c1[3] = {pt[1] * e2[2] - pt[2] * e2[1], pt[2] * e2[0] - pt[0] * e2[2], pt[0] * e2[1] - pt[1] * e2[0]};
    const double c2[3] = {e1[1] * pt[2] - e1[2] * pt[1], e1[2] * pt[0] - e1[0] * pt[2], e1[0] * pt[1] - e1[1] * pt[0]};
    const double u = dot3(c1, n) / nn, w = dot3(c2, n) / nn;
    const double tol = -1e-9;
    if (u < tol || w < tol || u + w > 1 - tol) return;
    if (std::abs(lambda) < best_abs) {
      best_abs = std::abs(lambda);
      best = tri_index;
      best_w[0] = 1 - u - w, best_w[1] = u, best_w[2] = w;
      best_depth = -lambda;  // > 0: the surface is behind the apex (it is in)
    }
  });
  if (best < 0 || best_depth < -reach) return -1;
  *triangle = best;
  if (!ns.tip_touching) ns.tip_offset = std::max(best_depth, 0.0);  // found in: it pushes from there
  best_depth -= ns.tip_offset;
  const double k = b.contact_stiffness * M_PI * r * r;
  ContactSpring sp;
  set_spring_point(surf.dofs[size_t(best)], best_w[0], best_w[1], best_w[2], sp);
  const double* into = t;  // the tip pushes the tissue along its own axis
  for (int a = 0; a < 3; ++a) {
    sp.force[a] = k * best_depth * into[a];
    for (int c = 0; c < 3; ++c) sp.K[3 * a + c] = k * into[a] * into[c];
  }
  sp.row_n = row;
  for (int a = 0; a < 3; ++a) sp.arm_n[a] = arm[a];
  RigidContactPair pr;
  pr.spring = static_cast<int32_t>(springs.size());
  for (int a = 0; a < 3; ++a) pr.n[a] = into[a];
  pr.depth0 = best_depth;
  pairs.push_back(pr);
  springs.push_back(sp);
  ++out.contacts;
  if (best_depth > 0) {
    out.energy += 0.5 * k * best_depth * best_depth;
    out.max_depth = std::max(out.max_depth, best_depth);
  }
  return pr.spring;
}

ContactExclusion needle_contact_exclusion(const RigidBodyModel& b, const NeedleState& ns, const double* x,
                                          double track_spacing, bool tip_pressing, double* holes) {
  ContactExclusion ex;
  if (ns.phase == NeedlePhase::Outside) return ex;
  ex.holes = holes;
  for (int32_t i = 0; i < ns.count && ex.n_holes < kMaxNeedleHoles; ++i)
    if (ns.track[size_t(i)].surface) material_point(ns.track[size_t(i)], x, holes + 3 * ex.n_holes++);
  ex.hole_radius = std::max(4.0 * b.needle.wire_radius, track_spacing);
  ex.track_s0 = 1e300, ex.track_s1 = -1e300;
  for (int32_t i = 0; i < ns.count; ++i) {
    ex.track_s0 = std::min(ex.track_s0, ns.track[size_t(i)].s);
    ex.track_s1 = std::max(ex.track_s1, ns.track[size_t(i)].s);
  }
  if (ns.has_front) ex.track_s0 = std::min(ex.track_s0, ns.front.s), ex.track_s1 = std::max(ex.track_s1, ns.front.s);
  if (tip_pressing && ns.phase == NeedlePhase::Exited) ex.tip_zone = ex.hole_radius;
  return ex;
}

namespace {

/// Track point i's share of the inserted length: from the midpoints to its neighbours (an
/// entry's from itself, an exit's to itself — the gap between two bites is not in tissue; the
/// deepest's to the apex while the tip is in).
double share_of(const NeedleState& ns, int32_t i, double top) {
  const TrackPoint& tp = ns.track[size_t(i)];
  const double s = tp.s;
  const double lo = i == 0 || tp.surface == 1 ? s : 0.5 * (ns.track[size_t(i - 1)].s + s);
  const double hi = tp.surface == 2 ? s : i + 1 == ns.count ? std::max(top, s) : 0.5 * (s + ns.track[size_t(i + 1)].s);
  return std::max(0.0, hi - lo);
}

/// The top of the track: the apex while inserted, the exit point once through.
double track_top(const RigidBodyModel& b, const NeedleState& ns) {
  return ns.phase == NeedlePhase::Inserted ? apex_s(b) : ns.track[size_t(ns.count - 1)].s;
}

}  // namespace

int needle_track_springs(const RigidBodyModel& b, const RigidState& s, int32_t row, const NeedleState& ns,
                         const std::vector<NeedleTissue>& tissues, const FemModel& fem, const double* x, double h,
                         std::vector<ContactSpring>& springs, std::vector<RigidContactPair>& pairs,
                         std::vector<NeedleSlip>& slips) {
  if (ns.phase == NeedlePhase::Outside) return 0;
  const double top = track_top(b, ns);
  int made = 0;
  for (int32_t i = 0; i < ns.count; ++i) {
    if (springs.size() == springs.capacity() || slips.size() == slips.capacity()) return made;
    const TrackPoint& tp = ns.track[size_t(i)];
    const NeedleTissue& tissue = tissues[size_t(tp.body)];  // its own body's (bites may be in two)
    const double k = tissue.track_stiffness * tissue.track_spacing;
    double p[3], c[3], t[3], arm[3];
    material_point(tp, x, p);
    needle_world_point(b, s, tp.s, c, t, arm);
    ContactSpring sp;
    spring_on(tp, fem, row, arm, sp);
    const double d[3] = {p[0] - c[0], p[1] - c[1], p[2] - c[2]};
    const double e = dot3(d, t);
    if (tp.sliding) {  // across: the spring; along: the kinetic friction, constant over the step
      // The way it slid last (e, its elongation, is ±f_k/k then — or 0 without friction).
      const double fk = tissue.friction_kinetic * share_of(ns, i, top), sign = tp.sliding == 1 ? 1.0 : -1.0;
      for (int a = 0; a < 3; ++a) {
        sp.force[a] = -k * (d[a] - e * t[a]) - sign * fk * t[a];
        for (int c2 = 0; c2 < 3; ++c2) sp.K[3 * a + c2] = k * ((a == c2 ? 1.0 : 0.0) - t[a] * t[c2]);
      }
      NeedleSlip sl;
      sl.spring = static_cast<int32_t>(springs.size());
      std::copy(t, t + 3, sl.t);
      sl.d = sign;
      sl.k = k;
      slips.push_back(sl);
    } else {
      for (int a = 0; a < 3; ++a) {
        sp.force[a] = -k * d[a];  // on the tissue, towards the curve's point
        sp.K[4 * a] = k;
      }
    }
    springs.push_back(sp);
    ++made;
  }
  if (ns.has_front && springs.size() < springs.capacity() && pairs.size() < pairs.capacity() &&
      slips.size() < slips.capacity()) {
    const NeedleTissue& tissue = tissues[size_t(ns.front.body)];
    const double k = tissue.track_stiffness * tissue.track_spacing;
    double q[3], c[3], t[3], arm[3];
    material_point(ns.front, x, q);
    needle_world_point(b, s, apex_s(b), c, t, arm);
    const double e = dot3(t, c) - dot3(t, q);  // > 0: the apex is past the front, pushing it
    double vt[3];
    body_point_velocity(s, arm, vt);
    const double reach = 2.0 * h * std::sqrt(dot3(vt, vt)) + 1e-12;
    if (e > -reach) {
      ContactSpring sp;
      spring_on(ns.front, fem, row, arm, sp);
      const bool cutting = ns.front.sliding && e > 0;  // the cutting force, constant over the step
      for (int a = 0; a < 3; ++a) {
        sp.force[a] = (cutting ? tissue.cutting_force : k * e) * t[a];
        for (int c2 = 0; c2 < 3; ++c2) sp.K[3 * a + c2] = cutting ? 0.0 : k * t[a] * t[c2];
      }
      RigidContactPair pr;
      pr.spring = static_cast<int32_t>(springs.size());
      for (int a = 0; a < 3; ++a) pr.n[a] = t[a];
      pr.depth0 = e;
      pairs.push_back(pr);
      if (cutting) {
        NeedleSlip sl;
        sl.spring = pr.spring;
        sl.pair = static_cast<int32_t>(pairs.size() - 1);
        std::copy(t, t + 3, sl.t);
        sl.d = -1.0;  // (front − apex)·t < 0 while it cuts
        sl.k = k;
        slips.push_back(sl);
      }
      springs.push_back(sp);
      ++made;
    }
  }
  return made;
}

int stick_reversed_slips(const double* x0, const double* x, const RigidState* start, const RigidState* end,
                         const int32_t* row_body, const std::vector<RigidContactPair>& pairs,
                         std::vector<NeedleSlip>& slips, std::vector<ContactSpring>& springs) {
  int stuck = 0;
  for (NeedleSlip& sl : slips) {
    if (!sl.active) continue;
    if (sl.pair >= 0 && !pairs[size_t(sl.pair)].active) {  // a front released as it ended pulling: gone
      sl.active = false;
      continue;
    }
    ContactSpring& sp = springs[size_t(sl.spring)];
    double p0[3], p1[3], dn[3] = {0, 0, 0};
    spring_point(sp, x0, p0);
    spring_point(sp, x, p1);
    if (sp.row_n >= 0) body_point_displacement(start[row_body[sp.row_n]], end[row_body[sp.row_n]], sp.arm_n, dn);
    const double rel[3] = {p1[0] - p0[0] - dn[0], p1[1] - p0[1] - dn[1], p1[2] - p0[2] - dn[2]};
    if (sl.d * dot3(rel, sl.t) >= 0) continue;
    sl.active = false;
    for (int a = 0; a < 3; ++a)
      for (int c = 0; c < 3; ++c) sp.K[3 * a + c] += sl.k * sl.t[a] * sl.t[c];
    ++stuck;
  }
  return stuck;
}

void needle_after_step(const RigidBodyModel& b, int32_t body_index, const RigidState* start, const RigidState* end,
                       const int32_t* row_body, const ContactSpring* springs, int32_t tip_spring,
                       int32_t tip_element, const std::vector<NeedleTissue>& tissue, const FemModel& fem,
                       const WalkMesh& mesh, const int32_t* node_tet, const double* x0, const double* x, const double* v,
                       NeedleState& ns, NeedleOutput& out) {
  const RigidState& se = end[size_t(body_index)];
  auto nt_of = [&](int32_t body) -> const NeedleTissue& { return tissue[size_t(body)]; };
  auto k_of = [&](int32_t body) { return tissue[size_t(body)].track_stiffness * tissue[size_t(body)].track_spacing; };
  const double r = b.needle.wire_radius, L = b.needle.length, Lapex = apex_s(b);
  out = NeedleOutput{};
  double tip[3], t_tip[3], arm_tip[3], apex[3];
  needle_world_point(b, se, L, tip, t_tip, arm_tip);
  for (int k = 0; k < 3; ++k) apex[k] = tip[k] + r * t_tip[k];

  // Outside (or exited: a second bite), the tip's push on the tissue (its contact spring's force
  // after the step, along t): above the touched body's puncture force, the tip enters.
  if (tip_spring < 0) ns.tip_touching = 0;
  if (ns.phase != NeedlePhase::Inserted && tip_spring >= 0) {
    const ContactSpring& sp = springs[tip_spring];
    double f[3];
    rigid_spring_force_after_step(sp, x0, x, v, start, end, row_body, f);
    const double push = dot3(f, t_tip);
    out.tip_force = push;
    ns.tip_touching = push > 0;
    int32_t node = sp.node[0];
    for (int a = 1; a < sp.n; ++a)
      if (sp.w[a] > sp.w[0]) node = sp.node[a];
    const int32_t body = body_of_node(fem, node);
    if (body >= 0 && tissue[size_t(body)].enabled && push > tissue[size_t(body)].puncture_force) {
      // The material point at the apex (or the nearest point of the boundary there).
      const int32_t from = tip_element >= 0 ? tip_element : node_tet[node];  // the touched face's element
      const TetWalkResult wr = walk_to_point(mesh, x, from, apex);
      TrackPoint tp = point_from_walk(wr, fem);
      double q[3];
      material_point(tp, x, q);
      tp.s = project_s(b, se, q);
      tp.surface = 1;
      // The entry is a track point if the apex has reached it; if it is still ahead (the apex
      // short of the dimpled surface), it is the front alone, and the first cut makes the entry.
      const bool reached = dot3(t_tip, apex) - dot3(t_tip, q) >= 0;
      if (!reached || push_point(ns, sliding_back(tp, nt_of(body), k_of(body), Lapex))) {
        ns.phase = NeedlePhase::Inserted;
        ns.tissue_body = body;
        ns.front = tp;
        ns.front.surface = reached ? 0 : 1;  // 1: its first cut makes the entry
        ns.has_front = 1;
        ns.tip_touching = 0;
        out.punctured = true;
        ++ns.punctures;
      }
    }
  }
  if (ns.phase == NeedlePhase::Outside) return;

  // The track's friction: each point's share of the inserted length sets its limits; a point
  // past its limit slips to the kinetic force (s moves), and keeps that limit while it slides.
  const double top = track_top(b, ns);
  double inserted = 0, along = 0;
  for (int32_t i = 0; i < ns.count; ++i) {
    TrackPoint& tp = ns.track[size_t(i)];
    const NeedleTissue& nt = nt_of(tp.body);
    const double k = k_of(tp.body);
    const double share = share_of(ns, i, top);
    inserted += share;
    double p[3], c[3], t[3], arm[3];
    material_point(tp, x, p);
    needle_world_point(b, se, tp.s, c, t, arm);
    const double d[3] = {p[0] - c[0], p[1] - c[1], p[2] - c[2]};
    double e = dot3(d, t);
    const double limit = (tp.sliding ? nt.friction_kinetic : nt.friction_static) * share;
    if (k * std::abs(e) > limit) {
      const double e_new = (e > 0 ? 1.0 : -1.0) * nt.friction_kinetic * share / k;
      tp.sliding = e > 0 ? 1 : 2;  // the way it slides (e_new is 0 without friction)
      tp.s += e - e_new;
      e = e_new;
    } else {
      tp.sliding = 0;
    }
    along += k * e * dot3(t, t_tip);  // the tissue pulls the needle towards its point
  }
  out.friction_force = along;

  // The cutting front: pushed past the cutting force, it moves on to F_c/k behind the apex.
  if (ns.phase == NeedlePhase::Inserted && ns.has_front) {
    const NeedleTissue& nt = nt_of(ns.front.body);
    const double k = k_of(ns.front.body);
    double q[3];
    material_point(ns.front, x, q);
    const double e = dot3(t_tip, apex) - dot3(t_tip, q);
    if (!out.punctured) out.tip_force = std::min(std::max(0.0, k * e), nt.cutting_force);
    ns.front.sliding = 0;
    if (k * e >= nt.cutting_force * (1 - 1e-9)) {
      const double lag = nt.cutting_force / k;
      const double target[3] = {apex[0] - lag * t_tip[0], apex[1] - lag * t_tip[1], apex[2] - lag * t_tip[2]};
      TetWalkResult wr = walk_to_point(mesh, x, ns.front.tet, target);
      if (!wr.inside && !wr.lost) {
        // Cut through: the exit is where the segment from the front to the target leaves the
        // last element (its weights along the segment, clipped at the first that reaches 0), or
        // its material (a cut model's copy: the first of its material planes crossed).
        double wa[4], wb[4], lam = 1.0;
        tet_weights(fem.elements[size_t(wr.tet)], x, q, wa);
        tet_weights(fem.elements[size_t(wr.tet)], x, target, wb);
        for (int c = 0; c < 4; ++c)
          if (wb[c] < 0 && wa[c] > wb[c]) lam = std::min(lam, std::max(0.0, wa[c]) / (std::max(0.0, wa[c]) - wb[c]));
        if (mesh.plane_begin != nullptr)
          for (int32_t j = mesh.plane_begin[wr.tet]; j < mesh.plane_begin[wr.tet + 1]; ++j) {
            const std::array<double, 4>& c = mesh.planes[j];
            const double ca = c[0] * wa[0] + c[1] * wa[1] + c[2] * wa[2] + c[3] * wa[3];
            const double cb = c[0] * wb[0] + c[1] * wb[1] + c[2] * wb[2] + c[3] * wb[3];
            if (cb < 0 && ca > cb) lam = std::min(lam, std::max(0.0, ca) / (std::max(0.0, ca) - cb));
          }
        double sum = 0;
        for (int c = 0; c < 4; ++c) sum += (wr.w[c] = std::max(0.0, wa[c] + lam * (wb[c] - wa[c])));
        for (double& v : wr.w) v = sum > 0 ? v / sum : 0.25;
        if (mesh.material_depth(wr.tet, wr.w) < 0) mesh.into_material(wr.tet, wr.w);  // (a front from another copy)
      }
      TrackPoint tp = point_from_walk(wr, fem);
      double pq[3];
      material_point(tp, x, pq);
      tp.s = project_s(b, se, pq);
      if (wr.lost) {
        // The walk found neither the target nor the boundary (a degenerate path): the front
        // stays where it is this step.
      } else if (!wr.inside) {  // cut through: the boundary point it crossed is the exit
        tp.surface = 2;
        if (push_point(ns, tp)) {
          ns.phase = NeedlePhase::Exited;
          ns.has_front = 0;
          out.exited = true;
          ++ns.punctures;
        }
      } else {
        const bool entry = ns.front.surface == 1;  // the puncture left the front alone
        ns.front = tp;
        ns.front.sliding = 1;  // cutting: the next step pushes it with the cutting force
        const double last = ns.count > 0 ? ns.track[size_t(ns.count - 1)].s : -1e300;
        tp.surface = entry ? 1 : 0;
        if (entry || tp.s - last >= nt.track_spacing) push_point(ns, sliding_back(tp, nt, k, Lapex));
      }
    }
  }

  // Points that slid off either end of the needle leave it.
  int32_t kept = 0;
  for (int32_t i = 0; i < ns.count; ++i) {
    const TrackPoint& tp = ns.track[size_t(i)];
    if (tp.s < 0) {  // past the tail: an entry or exit there is where a tied thread now passes
      if (tp.surface != 0 && out.passed_count < static_cast<int32_t>(out.passed.size()))
        out.passed[size_t(out.passed_count++)] = tp;
      continue;
    }
    if (tp.s > Lapex) {
      if (ns.phase == NeedlePhase::Exited && i + 1 == ns.count) {  // withdrawn back through the exit
        ns.phase = NeedlePhase::Inserted;
        ns.tissue_body = tp.body;
        ns.front = tp;
        ns.front.surface = 0;
        ns.front.sliding = 0;  // pushed again, it is a spring before it cuts
        ns.has_front = 1;
      }
      continue;
    }
    ns.track[size_t(kept++)] = tp;
  }
  ns.count = kept;
  // Left: no track point on the needle and no front it still reaches (drawn back out of the
  // hole by more than half a spacing, or none).
  bool front_reached = false;
  if (ns.has_front) {
    double q[3];
    material_point(ns.front, x, q);
    front_reached = dot3(t_tip, apex) - dot3(t_tip, q) > -0.5 * nt_of(ns.front.body).track_spacing;
  }
  if (ns.phase == NeedlePhase::Inserted && ns.count > 0 && ns.track[size_t(ns.count - 1)].surface == 2 && !front_reached) {
    // Drawn back out of a later bite: between the bites again, through the earlier ones.
    ns.phase = NeedlePhase::Exited;
    ns.has_front = 0;
    ns.tissue_body = ns.track[size_t(ns.count - 1)].body;
  }
  if (ns.count == 0 && !front_reached) {
    ns.phase = NeedlePhase::Outside;
    ns.has_front = 0;
    out.tissue_body = ns.tissue_body;  // the one it left
    ns.tissue_body = -1;
    out.left = true;
  }
  out.phase = ns.phase;
  if (ns.tissue_body >= 0) out.tissue_body = ns.tissue_body;
  out.inserted_length = ns.count > 0 ? inserted : 0.0;
  out.track_points = ns.count;
}

}  // namespace stroma
