#include "engine/thread_contact.hpp"

#include <algorithm>
#include <cmath>

#include "haptics/tool_shape.hpp"
#include "rigid/rigid_motion.hpp"
#include "tissue/bsr_matrix.hpp"
#include "tissue/triangle_closest_point.hpp"

namespace stroma {

namespace {

inline double dot3(const double* a, const double* b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
inline double norm3(const double* a) { return std::sqrt(dot3(a, a)); }

/// Samples per segment of rod r (thread_contact.hpp): every kThreadSampleDiameters diameters.
int segment_samples(const RodRange& r) {
  if (!(r.diameter > 0)) return 1;
  return std::clamp(static_cast<int>(std::ceil(r.segment_length / (kThreadSampleDiameters * r.diameter))), 1,
                    kThreadSamplesPerSegment);
}

/// The larger speed of segment (i, i + 1)'s nodes.
double segment_speed(const double* v, int32_t i) { return std::max(norm3(v + 3 * i), norm3(v + 3 * i + 3)); }

/// A speculative contact (gap ≥ 0) is made only if this step can close it: by the approach at the
/// start of the step (rel·n < 0) and the positive side's fall relative to the other's (`fall` =
/// h²·g·n times that), to within `margin` (what the step's own accelerations may add). Not
/// rigid/rigid_contact.hpp's "any motion up to the body's speed": a thread's end swings at metres
/// per second along surfaces it never nears, and a speculative spring pulls by its gap until
/// the step is redone without it — a redo the time budget may skip (measured: a 10 cm suture
/// swinging past a block pulled the block's corner 5 cm out, served).
bool out_of_reach(double gap, double approach, double fall, double h, double margin) {
  return gap >= 0 && gap + h * std::min(approach, 0.0) + fall >= margin;
}

/// A thread segment's point: nodes (i, i + 1) with weights (1 − u, u), the pattern's slots.
void segment_spring(const BsrPattern& pattern, int32_t i, double u, ContactSpring& sp) {
  const int32_t nodes[2] = {i, i + 1};
  const double w[2] = {1.0 - u, u};
  set_spring_nodes(pattern, nodes, w, 2, sp);
}

/// A whole rod is tied to rigid body k (its end to the needle's tail).
bool rod_tied_to(const Model& m, const RodRange& r, int32_t k) {
  for (const Model::ThreadTie& t : m.thread_ties)
    if (t.body == k && t.node >= r.node_begin && t.node < r.node_end) return true;
  return false;
}

/// Where the thread is inside the tissue between its punctures: intervals of σ (node units).
/// Pairing the punctures from the end not tied to a needle (it is outside), the arc between
/// each pair is in the tissue; an odd one left pairs with the tied end (the needle's tail is in
/// the tissue: the thread follows it in).
struct InsideArcs {
  double lo[kThreadPunctures], hi[kThreadPunctures];
  int n = 0;
  bool contains(double sigma) const {
    for (int k = 0; k < n; ++k)
      if (sigma > lo[k] && sigma < hi[k]) return true;
    return false;
  }
};

InsideArcs inside_arcs(const Model& m, const State& s, int32_t rod) {
  InsideArcs a;
  const RodRange& r = m.fem.rods[size_t(rod)];
  double sig[kThreadPunctures];
  int n = 0;
  for (int32_t i = 0; i < s.puncture_count && n < kThreadPunctures; ++i)
    if (s.punctures[size_t(i)].rod == rod) sig[n++] = s.punctures[size_t(i)].sigma;
  if (n == 0) return a;
  std::sort(sig, sig + n);
  bool tied_first = false, tied_last = false;
  for (const Model::ThreadTie& t : m.thread_ties) {
    tied_first = tied_first || t.node == r.node_begin;
    tied_last = tied_last || t.node == r.node_end - 1;
  }
  const double segs = static_cast<double>(r.segments());
  if (tied_first && !tied_last) {  // from the last end, outside, downwards
    int k = n - 1;
    for (; k >= 1; k -= 2) a.lo[a.n] = sig[k - 1], a.hi[a.n++] = sig[k];
    if (k == 0) a.lo[a.n] = -1.0, a.hi[a.n++] = sig[0];
  } else {  // from the first end upwards
    int k = 0;
    for (; k + 1 < n; k += 2) a.lo[a.n] = sig[k], a.hi[a.n++] = sig[k + 1];
    if (k == n - 1 && tied_last) a.lo[a.n] = sig[k], a.hi[a.n++] = segs + 1.0;
  }
  return a;
}

/// The holes the thread–tissue contact skips around: its punctures' material points and the
/// needles' entries and exits, each with its radius.
struct Holes {
  double p[3 * kMaxThreadHoles];
  double r2[kMaxThreadHoles];
  int n = 0;
  void add(const double* w, const int32_t* node, const double* x, double radius) {
    if (n == kMaxThreadHoles) return;
    for (int k = 0; k < 3; ++k) {
      double q = 0;
      for (int a = 0; a < 4; ++a) q += w[a] * x[3 * node[a] + k];
      p[3 * n + k] = q;
    }
    r2[n++] = radius * radius;
  }
  bool near(const double* q) const {
    for (int j = 0; j < n; ++j) {
      const double d[3] = {q[0] - p[3 * j], q[1] - p[3 * j + 1], q[2] - p[3 * j + 2]};
      if (dot3(d, d) < r2[j]) return true;
    }
    return false;
  }
};

Holes thread_holes(const Model& m, const State& s, const double* x) {
  Holes h;
  double d_max = 0;
  for (const RodRange& r : m.fem.rods) d_max = std::max(d_max, r.diameter);
  for (int32_t i = 0; i < s.puncture_count; ++i) {
    const RodPuncture& p = s.punctures[size_t(i)];
    double radius = 2.0 * d_max;
    if (size_t(p.body) < m.needle_tissue.size()) radius = std::max(radius, m.needle_tissue[size_t(p.body)].track_spacing);
    h.add(p.w, p.node, x, radius);
  }
  for (const RodAnchor& an : m.fem.rod_anchors) {  // an anchor knot: its segments end in the tissue
    double len = 0;
    for (const RodRange& r : m.fem.rods)
      if (an.node >= r.node_begin && an.node < r.node_end) len = r.segment_length;
    h.add(an.w, an.tissue, x, std::max(2.0 * d_max, 1.5 * len));
  }
  for (size_t k = 0; k < m.rigid_bodies.size() && k < s.needles.size(); ++k) {
    const RigidBodyModel& b = m.rigid_bodies[k];
    const NeedleState& ns = s.needles[k];
    if (b.shape != RigidShape::Needle || ns.tissue_body < 0) continue;
    const double radius = std::max({2.0 * d_max, 4.0 * b.needle.wire_radius,
                                    m.needle_tissue[size_t(ns.tissue_body)].track_spacing});
    for (int32_t i = 0; i < ns.count; ++i)
      if (ns.track[size_t(i)].surface) h.add(ns.track[size_t(i)].w, ns.track[size_t(i)].node.data(), x, radius);
  }
  return h;
}

}  // namespace

double segment_closest_points(const double* p0, const double* p1, const double* q0, const double* q1, double* s,
                              double* t) {
  const double d1[3] = {p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2]};
  const double d2[3] = {q1[0] - q0[0], q1[1] - q0[1], q1[2] - q0[2]};
  const double r[3] = {p0[0] - q0[0], p0[1] - q0[1], p0[2] - q0[2]};
  const double a = dot3(d1, d1), e = dot3(d2, d2), f = dot3(d2, r);
  double ss = 0, tt = 0;
  if (a <= 1e-300 && e <= 1e-300) {
    ss = tt = 0;
  } else if (a <= 1e-300) {
    tt = std::clamp(f / e, 0.0, 1.0);
  } else {
    const double c = dot3(d1, r);
    if (e <= 1e-300) {
      ss = std::clamp(-c / a, 0.0, 1.0);
    } else {
      const double b = dot3(d1, d2), denom = a * e - b * b;
      ss = denom > 1e-14 * a * e ? std::clamp((b * f - c * e) / denom, 0.0, 1.0) : 0.0;  // parallel: any s
      tt = (b * ss + f) / e;
      if (tt < 0) {
        tt = 0;
        ss = std::clamp(-c / a, 0.0, 1.0);
      } else if (tt > 1) {
        tt = 1;
        ss = std::clamp((b - c) / a, 0.0, 1.0);
      }
    }
  }
  *s = ss;
  *t = tt;
  double d2s = 0;
  for (int k = 0; k < 3; ++k) {
    const double q = p0[k] + ss * d1[k] - q0[k] - tt * d2[k];
    d2s += q * q;
  }
  return d2s;
}

void set_spring_nodes(const BsrPattern& pattern, const int32_t* nodes, const double* w, int n, ContactSpring& sp) {
  sp.n = n;
  sp.matrix_free = 0;
  for (int a = 0; a < n; ++a) sp.node[a] = nodes[a], sp.w[a] = w[a];
  // Pairs across the two sides (weights of opposite signs) are always applied matrix-free, even
  // where the pattern has their block (a thread's segment and the next-but-one's share bending
  // blocks; an anchored end's tetrahedron): assembling some cross blocks but not others leaves
  // an assembled part that need not be positive definite (CHOLMOD refused it, measured), while
  // each side's own blocks are a PSD w wᵀ ⊗ K.
  for (int a = 0; a < n; ++a)
    for (int b = 0; b < n; ++b) {
      const bool cross = (w[a] < 0) != (w[b] < 0);
      const int32_t sl = cross ? -1 : pattern.find_upper(nodes[a], nodes[b]);
      sp.slot[spring_slot(a, b)] = sl < 0 ? kSlotMatrixFree : (nodes[a] <= nodes[b] ? sl : -1);
      if (sl < 0) sp.matrix_free = 1;
    }
}

void thread_tissue_contact(const Model& m, const State& s, const ContactSurface& surf, const TriangleBvh& bvh,
                           const double* px, const double* v, std::vector<ContactSpring>& springs,
                           std::vector<RigidContactPair>& pairs, ThreadContactOutput& out) {
  if (m.fem.rods.empty() || surf.triangles.empty()) return;
  const double* x = s.tissue.x.data();
  const double h = m.fem_step;
  const double* g = m.fem.gravity.data();
  const double gn = norm3(g);
  const Holes holes = thread_holes(m, s, x);
  constexpr int kMax = kThreadSamplesPerSegment + 1;
  for (size_t ri = 0; ri < m.fem.rods.size(); ++ri) {
    const RodRange& r = m.fem.rods[ri];
    if (!(r.contact_stiffness > 0)) continue;
    const double rad = 0.5 * r.diameter;
    const int K = segment_samples(r);
    const InsideArcs inside = inside_arcs(m, s, static_cast<int32_t>(ri));
    const double v_stick = 0.01 * r.diameter;
    for (int32_t i = r.node_begin; i + 1 < r.node_end; ++i) {
      const double* a = x + 3 * i;
      const double* b = a + 3;
      const int ns = i + 2 == r.node_end ? K + 1 : K;
      const double speed = segment_speed(v, i);
      const double cap = rad + 2.0 * h * speed + h * h * gn + 0.25 * rad;  // the step's reach in front
      const double keep = std::max(cap, 10.0 * r.diameter);                // and how deep a point is kept
      double c[kMax][3], u[kMax], best_d2[kMax], best_w[kMax][3];
      int32_t best_tri[kMax];
      double mid[3], half2 = 0;
      for (int k = 0; k < 3; ++k) {
        mid[k] = 0.5 * (a[k] + b[k]);
        half2 += 0.25 * (b[k] - a[k]) * (b[k] - a[k]);
      }
      int live = 0;
      for (int j = 0; j < ns; ++j) {
        u[j] = static_cast<double>(j) / K;
        for (int k = 0; k < 3; ++k) c[j][k] = a[k] + u[j] * (b[k] - a[k]);
        best_d2[j] = keep * keep;
        best_tri[j] = -1;
        const double sigma = static_cast<double>(i - r.node_begin) + u[j];
        if (inside.contains(sigma) || holes.near(c[j])) best_d2[j] = 0;  // none: in the tissue, or at a hole
        else ++live;
      }
      if (live == 0) continue;
      bvh.query_sphere(mid, std::sqrt(half2) + keep, px, [&](int32_t t) {
        if (surf.active && !surf.active[t]) return;
        const auto& tri = surf.triangles[size_t(t)];
        const double* A = px + 3 * tri[0];
        const double* B = px + 3 * tri[1];
        const double* C = px + 3 * tri[2];
        double nrm[3];
        if (!triangle_unit_normal(A, B, C, nrm)) return;
        for (int j = 0; j < ns; ++j) keep_closer_on_triangle(c[j], A, B, C, nrm, t, best_d2[j], best_tri[j], best_w[j]);
      });
      for (int j = 0; j < ns; ++j) {
        const int32_t t = best_tri[j];
        if (t < 0) continue;
        const auto& tri = surf.triangles[size_t(t)];
        const double* A = px + 3 * tri[0];
        const double* B = px + 3 * tri[1];
        const double* C = px + 3 * tri[2];
        double q[3], qc[3], face[3];
        for (int k = 0; k < 3; ++k) {
          q[k] = best_w[j][0] * A[k] + best_w[j][1] * B[k] + best_w[j][2] * C[k];
          qc[k] = c[j][k] - q[k];
        }
        triangle_normal(A, B, C, face);
        const double flen = norm3(face);
        const double sgn = surf.active && surf.active[t] == 2 ? -1.0 : 1.0;  // a face turned round
        for (double& k : face) k *= sgn / flen;
        const double dist = std::sqrt(best_d2[j]);
        const bool under = dot3(qc, face) < 0;
        const double sigma = under ? -dist : dist;  // the centreline's signed distance to the surface
        if (sigma >= cap) continue;
        // From the tissue to the thread: outside along c − q, under the surface towards it.
        double n[3];
        if (dist > 1e-6 * rad)
          for (int k = 0; k < 3; ++k) n[k] = (under ? -qc[k] : qc[k]) / dist;
        else
          for (int k = 0; k < 3; ++k) n[k] = face[k];
        ContactSpring tri_sp;
        set_spring_point(surf.dofs[size_t(t)], best_w[j][0], best_w[j][1], best_w[j][2], tri_sp);
        int32_t nodes[kSpringMaxNodes];
        double w[kSpringMaxNodes];
        nodes[0] = i, nodes[1] = i + 1, w[0] = 1.0 - u[j], w[1] = u[j];
        for (int d = 0; d < tri_sp.n; ++d) nodes[2 + d] = tri_sp.node[d], w[2 + d] = -tri_sp.w[d];
        ContactSpring sp;
        set_spring_nodes(m.fem.pattern, nodes, w, 2 + tri_sp.n, sp);
        double rel[3];
        spring_point(sp, v, rel);  // the thread's point's velocity less the tissue's
        const double gap = sigma - rad;
        if (out_of_reach(gap, dot3(rel, n), h * h * dot3(g, n), h, 0.25 * rad)) continue;
        const bool speculative = gap >= 0;
        if (!reserve_contact(springs, pairs, gap, n)) {
          ++out.dropped;
          continue;
        }
        const double share = r.segment_length / K * ((i == r.node_begin && j == 0) || j == K ? 0.5 : 1.0);
        RigidContactOutput counts;
        fill_contact_spring(sp, n, -gap, speculative, r.contact_stiffness * r.diameter * share, 0.0, r.friction, rel,
                            v_stick, counts);
        springs.push_back(sp);
        ++out.tissue;
        out.max_depth = std::max(out.max_depth, counts.max_depth);
      }
    }
  }
}

namespace {

/// The self-contact of segments (i, i + 1) of rod A and (j, j + 1) of rod B, appended when within
/// reach this step.
void segment_pair_contact(const Model& m, const RodRange& A, const RodRange& B, int32_t i, int32_t j, const double* x,
                          const double* v, std::vector<ContactSpring>& springs, std::vector<RigidContactPair>& pairs,
                          ThreadContactOutput& out) {
  const double h = m.fem_step;
  const double rad = 0.5 * (A.diameter + B.diameter);  // the two radii's sum
  const double* a0 = x + 3 * i;
  const double* a1 = a0 + 3;
  const double* b0 = x + 3 * j;
  const double* b1 = b0 + 3;
  const double cap = rad + 2.0 * h * (segment_speed(v, i) + segment_speed(v, j)) + 0.25 * rad;
  double s, t;
  const double d2 = segment_closest_points(a0, a1, b0, b1, &s, &t);
  if (d2 >= cap * cap) return;
  const double d = std::sqrt(d2);
  double n[3];
  if (d > 1e-9 * rad) {
    for (int k = 0; k < 3; ++k) n[k] = (a0[k] + s * (a1[k] - a0[k]) - b0[k] - t * (b1[k] - b0[k])) / d;
  } else {  // crossing exactly: across both
    const double ea[3] = {a1[0] - a0[0], a1[1] - a0[1], a1[2] - a0[2]}, eb[3] = {b1[0] - b0[0], b1[1] - b0[1], b1[2] - b0[2]};
    const double cr[3] = {ea[1] * eb[2] - ea[2] * eb[1], ea[2] * eb[0] - ea[0] * eb[2], ea[0] * eb[1] - ea[1] * eb[0]};
    const double cl = norm3(cr);
    if (!(cl > 0)) return;
    for (int k = 0; k < 3; ++k) n[k] = cr[k] / cl;
  }
  const int32_t nodes[4] = {i, i + 1, j, j + 1};
  const double w[4] = {1.0 - s, s, -(1.0 - t), -t};
  ContactSpring sp;
  set_spring_nodes(m.fem.pattern, nodes, w, 4, sp);
  double rel[3];
  spring_point(sp, v, rel);
  const double gap = d - rad;
  if (out_of_reach(gap, dot3(rel, n), 0.0, h, 0.125 * rad)) return;
  const bool speculative = gap >= 0;
  if (!reserve_contact(springs, pairs, gap, n)) {
    ++out.dropped;
    return;
  }
  RigidContactOutput counts;
  const double k_c = std::max(A.stretch_stiffness, B.stretch_stiffness);
  const double mu = std::min(A.friction, B.friction);
  const double v_stick = 0.01 * std::min(A.diameter, B.diameter);
  fill_contact_spring(sp, n, -gap, speculative, k_c, 0.0, mu, rel, v_stick, counts);
  springs.push_back(sp);
  ++out.self;
  out.max_depth = std::max(out.max_depth, counts.max_depth);
}

}  // namespace

namespace {

/// Every pair of segments whose spheres overlap and that share no node, each once in a fixed
/// order (lower rod, then lower node first): a sweep along the axis the spheres' centres spread
/// most on. `spheres` filled by the caller; `order` is scratch (capacity reserved at load).
template <class PairFn>
void sweep_segment_pairs(const std::vector<SegmentSphere>& spheres, std::vector<int32_t>& order, PairFn&& pair) {
  const size_t n = spheres.size();
  if (n < 2) return;
  double mean[3] = {0, 0, 0}, sq[3] = {0, 0, 0};
  for (const SegmentSphere& sp : spheres)
    for (int k = 0; k < 3; ++k) mean[k] += sp.c[k], sq[k] += sp.c[k] * sp.c[k];
  int axis = 0;
  double spread = -1;
  for (int k = 0; k < 3; ++k) {
    const double var = sq[k] / double(n) - (mean[k] / double(n)) * (mean[k] / double(n));
    if (var > spread) spread = var, axis = k;
  }
  order.resize(n);  // (capacity reserved)
  for (size_t q = 0; q < n; ++q) order[q] = static_cast<int32_t>(q);
  std::sort(order.begin(), order.end(), [&](int32_t a, int32_t b) {
    const double la = spheres[size_t(a)].c[axis] - spheres[size_t(a)].r, lb = spheres[size_t(b)].c[axis] - spheres[size_t(b)].r;
    return la < lb || (la == lb && a < b);
  });
  for (size_t p = 0; p < n; ++p) {
    const SegmentSphere& a = spheres[size_t(order[p])];
    const double hi = a.c[axis] + a.r;
    for (size_t q = p + 1; q < n; ++q) {
      const SegmentSphere& b = spheres[size_t(order[q])];
      if (b.c[axis] - b.r > hi) break;  // sorted by their low ends: none further overlaps a
      if (a.rod == b.rod && std::abs(a.node - b.node) < 2) continue;  // neighbours share a node
      double d2 = 0;
      for (int k = 0; k < 3; ++k) d2 += (a.c[k] - b.c[k]) * (a.c[k] - b.c[k]);
      if (d2 >= (a.r + b.r) * (a.r + b.r)) continue;  // their spheres apart
      const bool a_first = a.rod < b.rod || (a.rod == b.rod && a.node < b.node);
      pair(a_first ? a : b, a_first ? b : a);
    }
  }
}

/// Every rod segment's sphere: its midpoint in x, its half-length plus `reach(i, rod)`.
template <class ReachFn>
void segment_spheres(const std::vector<RodRange>& rods, const double* x, std::vector<SegmentSphere>& spheres,
                     ReachFn&& reach) {
  spheres.clear();
  for (size_t ri = 0; ri < rods.size(); ++ri) {
    const RodRange& r = rods[ri];
    if (!(r.diameter > 0)) continue;
    for (int32_t i = r.node_begin; i + 1 < r.node_end; ++i) {
      const double* a0 = x + 3 * i;
      const double* a1 = a0 + 3;
      SegmentSphere sp;
      double l2 = 0;
      for (int k = 0; k < 3; ++k) {
        sp.c[k] = 0.5 * (a0[k] + a1[k]);
        l2 += (a1[k] - a0[k]) * (a1[k] - a0[k]);
      }
      sp.r = 0.5 * std::sqrt(l2) + reach(i, r);
      sp.node = i;
      sp.rod = static_cast<int32_t>(ri);
      spheres.push_back(sp);  // (capacity: every segment, reserved at load)
    }
  }
}

/// The distance between the two segments' centrelines at τ of the motion x0 → x1 (closest
/// parameters s, t).
double segments_at(const double* x0, const double* x1, int32_t i, int32_t j, double tau, double* s, double* t) {
  double p[4][3];
  const int32_t nodes[4] = {i, i + 1, j, j + 1};
  for (int a = 0; a < 4; ++a)
    for (int k = 0; k < 3; ++k) p[a][k] = x0[3 * nodes[a] + k] + tau * (x1[3 * nodes[a] + k] - x0[3 * nodes[a] + k]);
  return std::sqrt(segment_closest_points(p[0], p[1], p[2], p[3], s, t));
}

/// The self-contact spring of segments (i, i + 1) and (j, j + 1) in springs[begin, end), or −1.
int32_t self_spring(const std::vector<ContactSpring>& springs, size_t begin, int32_t i, int32_t j) {
  for (size_t q = begin; q < springs.size(); ++q) {
    const ContactSpring& sp = springs[q];
    if (sp.n == 4 && sp.node[0] == i && sp.node[1] == i + 1 && sp.node[2] == j && sp.node[3] == j + 1)
      return static_cast<int32_t>(q);
  }
  return -1;
}

/// A spring the continuous check made (its pair's gap at the step's start along n): in the place
/// of the pair's released one if any (reactivated), else appended with a speculative pair of its
/// own; pinned either way. False if there is no room (not applied).
bool place_pinned(const ContactSpring& sp, double gap, const double* n, RigidContactPair* released,
                  std::vector<ContactSpring>& springs, std::vector<RigidContactPair>& pairs) {
  if (released != nullptr) {
    springs[size_t(released->spring)] = sp;
    released->active = true;
    released->pinned = true;
    released->depth0 = -gap;
    for (int q = 0; q < 3; ++q) released->n[q] = n[q];
    return true;
  }
  if (!reserve_contact(springs, pairs, gap, n)) return false;
  if (gap >= 0) pairs.back().pinned = true;
  springs.push_back(sp);
  return true;
}

}  // namespace

void thread_self_contact(const Model& m, const double* x, const double* v, std::vector<SegmentSphere>& spheres,
                         std::vector<int32_t>& order, std::vector<ContactSpring>& springs,
                         std::vector<RigidContactPair>& pairs, ThreadContactOutput& out) {
  const std::vector<RodRange>& rods = m.fem.rods;
  const double h = m.fem_step;
  // Broad phase: each segment's sphere (the pair's cap = the sum of the two reaches beyond the
  // half-lengths: rad_a + rad_b + 2h(s_a + s_b) + 0.25(rad_a + rad_b)), swept along the axis the
  // midpoints spread most on. (All pairs: 4,950 for 100 segments, ~4 % of the stitch scene's
  // tick; the sweep tests a few per segment.)
  segment_spheres(rods, x, spheres,
                  [&](int32_t i, const RodRange& r) { return 2.0 * h * segment_speed(v, i) + 1.25 * 0.5 * r.diameter; });
  sweep_segment_pairs(spheres, order, [&](const SegmentSphere& f, const SegmentSphere& g) {
    segment_pair_contact(m, rods[size_t(f.rod)], rods[size_t(g.rod)], f.node, g.node, x, v, springs, pairs, out);
  });
}

int thread_missed_self_contacts(const Model& m, const double* x0, const double* v0, const double* x1,
                                std::vector<SegmentSphere>& spheres, std::vector<int32_t>& order, size_t self_begin,
                                std::vector<ContactSpring>& springs, std::vector<RigidContactPair>& pairs,
                                ThreadContactOutput& out) {
  const std::vector<RodRange>& rods = m.fem.rods;
  const auto moved = [&](int32_t i) {
    double d = 0;
    for (int a = 0; a < 2; ++a) {
      double q = 0;
      for (int k = 0; k < 3; ++k) q += (x1[3 * (i + a) + k] - x0[3 * (i + a) + k]) * (x1[3 * (i + a) + k] - x0[3 * (i + a) + k]);
      d = std::max(d, q);
    }
    return std::sqrt(d);
  };
  // Each sphere holds its segment over the whole motion: |p(τ, u) − c₀| ≤ half-length₀ + the
  // farther node's displacement.
  segment_spheres(rods, x0, spheres, [&](int32_t i, const RodRange& r) { return moved(i) + 0.5 * r.diameter; });
  int added = 0;
  sweep_segment_pairs(spheres, order, [&](const SegmentSphere& f, const SegmentSphere& g) {
    const RodRange& A = rods[size_t(f.rod)];
    const RodRange& B = rods[size_t(g.rod)];
    const double rad = 0.5 * (A.diameter + B.diameter);
    const int32_t i = f.node, j = g.node;
    double s, t;
    if (segments_at(x0, x1, i, j, 0.0, &s, &t) < rad) return;  // touching at the start: the step's own spring
    // Samples every quarter radius of relative motion: the centrelines' distance changes by at
    // most that between two, so a crossing (distance 0) leaves a sample within an eighth.
    const double rel = moved(i) + moved(j);
    const int K = std::clamp(static_cast<int>(std::ceil(rel / (0.25 * rad))), 1, kThreadCcdSamples);
    double s_prev = s, t_prev = t, tau_prev = 0.0;
    for (int k = 1; k <= K; ++k) {
      const double tau = static_cast<double>(k) / K;
      double sk, tk;
      if (segments_at(x0, x1, i, j, tau, &sk, &tk) >= rad) {
        s_prev = sk, t_prev = tk, tau_prev = tau;
        continue;
      }
      // A spring of the pair acting in the step: the solve had it. One released from it (it
      // ended an earlier pass pulling) is made again where the pair now meets.
      const int32_t existing = self_spring(springs, self_begin, i, j);
      RigidContactPair* released = nullptr;
      if (existing >= 0) {
        for (RigidContactPair& pr : pairs)
          if (pr.spring == existing && !pr.active) released = &pr;
        if (released == nullptr) return;
      }
      // The spring where they were just before they touched: its normal the direction between
      // those points then, its depth theirs at the step's start along it.
      double pa[3], pb[3], n[3], nl = 0;
      for (int q = 0; q < 3; ++q) {
        const double a = (1 - s_prev) * x0[3 * i + q] + s_prev * x0[3 * i + 3 + q];
        const double b = (1 - t_prev) * x0[3 * j + q] + t_prev * x0[3 * j + 3 + q];
        const double a1 = (1 - s_prev) * x1[3 * i + q] + s_prev * x1[3 * i + 3 + q];
        const double b1 = (1 - t_prev) * x1[3 * j + q] + t_prev * x1[3 * j + 3 + q];
        pa[q] = a, pb[q] = b;
        n[q] = (a + tau_prev * (a1 - a)) - (b + tau_prev * (b1 - b));
        nl += n[q] * n[q];
      }
      nl = std::sqrt(nl);
      if (!(nl > 1e-9 * rad)) return;
      for (double& q : n) q /= nl;
      double gap = -rad;
      for (int q = 0; q < 3; ++q) gap += (pa[q] - pb[q]) * n[q];
      const int32_t nodes[4] = {i, i + 1, j, j + 1};
      const double w[4] = {1.0 - s_prev, s_prev, -(1.0 - t_prev), -t_prev};
      ContactSpring sp;
      set_spring_nodes(m.fem.pattern, nodes, w, 4, sp);
      double relv[3];
      spring_point(sp, v0, relv);
      RigidContactOutput counts;
      fill_contact_spring(sp, n, -gap, gap >= 0, std::max(A.stretch_stiffness, B.stretch_stiffness), 0.0,
                          std::min(A.friction, B.friction), relv, 0.01 * std::min(A.diameter, B.diameter), counts);
      if (!place_pinned(sp, gap, n, released, springs, pairs)) {
        ++out.dropped;
        return;
      }
      if (released == nullptr) ++out.self;
      ++out.missed;
      ++added;
      return;
    }
  });
  return added;
}

int thread_missed_rigid_contacts(const Model& m, int32_t k, const RigidState& bs0, const RigidState& bs1, int32_t row,
                                 const double* x0, const double* v0, const double* x1,
                                 std::vector<ContactSpring>& springs, std::vector<RigidContactPair>& pairs,
                                 RigidContactOutput& bout, ThreadContactOutput& out) {
  const RigidBodyModel& b = m.rigid_bodies[size_t(k)];
  const std::array<double, 9> R0 = rotation_of(bs0.q), R1 = rotation_of(bs1.q);
  // World → body frame: Rᵀ (p − c) (R row-major).
  const auto to_body = [](const std::array<double, 9>& R, const std::array<double, 3>& c, const double* p, double* q) {
    const double r[3] = {p[0] - c[0], p[1] - c[1], p[2] - c[2]};
    for (int a = 0; a < 3; ++a) q[a] = R[size_t(a)] * r[0] + R[size_t(3 + a)] * r[1] + R[size_t(6 + a)] * r[2];
  };
  int added = 0;
  for (const RodRange& r : m.fem.rods) {
    if (rod_tied_to(m, r, k)) continue;
    const double rad = 0.5 * r.diameter;
    const int K = segment_samples(r);
    for (int32_t i = r.node_begin; i + 1 < r.node_end; ++i) {
      const int ns = i + 2 == r.node_end ? K + 1 : K;
      for (int j = 0; j < ns; ++j) {
        const double u = static_cast<double>(j) / K;
        double p0[3], p1[3], b0[3], b1[3], db[3];
        for (int q = 0; q < 3; ++q) {
          p0[q] = (1 - u) * x0[3 * i + q] + u * x0[3 * i + 3 + q];
          p1[q] = (1 - u) * x1[3 * i + q] + u * x1[3 * i + 3 + q];
        }
        to_body(R0, bs0.x, p0, b0);
        to_body(R1, bs1.x, p1, b1);
        for (int q = 0; q < 3; ++q) db[q] = b1[q] - b0[q];
        // The point's path in the body's frame, b0 → b1: out of its bounding sphere all along?
        const double len2 = dot3(db, db);
        const double along = len2 > 0 ? std::clamp(-dot3(b0, db) / len2, 0.0, 1.0) : 0.0;
        double c2 = 0;
        for (int q = 0; q < 3; ++q) c2 += (b0[q] + along * db[q]) * (b0[q] + along * db[q]);
        const double reach = b.bounding_radius + rad;
        if (c2 > reach * reach) continue;
        double nprev[3];
        double dprev = shape_distance(b, b0, nprev);
        if (dprev < rad) continue;  // touching at the start: the step's own spring
        const int S = std::clamp(static_cast<int>(std::ceil(std::sqrt(len2) / (0.25 * rad))), 1, kThreadCcdSamples);
        double prev[3] = {b0[0], b0[1], b0[2]};
        for (int t = 1; t <= S; ++t) {
          const double tau = static_cast<double>(t) / S;
          double bt[3], nt[3];
          for (int q = 0; q < 3; ++q) bt[q] = b0[q] + tau * db[q];
          const double dt = shape_distance(b, bt, nt);
          if (dt >= rad) {
            std::copy(bt, bt + 3, prev);
            std::copy(nt, nt + 3, nprev);
            dprev = dt;
            continue;
          }
          // It met the body within the step: a spring where it was just before, at the body's
          // start pose — unless the step had one of this point against this body.
          RigidContactPair* released = nullptr;
          bool acting = false;
          for (RigidContactPair& pr : pairs) {
            const ContactSpring& sp = springs[size_t(pr.spring)];
            if (sp.n == 2 && sp.node[0] == i && std::abs(sp.w[1] - u) < 1e-12 && sp.row_n == row && sp.row_p < 0) {
              if (pr.active) acting = true;
              else released = &pr;
            }
          }
          if (acting) break;
          double n[3], arm[3];
          double surf_b[3];  // the body's surface point then, in its frame
          for (int q = 0; q < 3; ++q) {
            n[q] = R0[size_t(3 * q)] * nprev[0] + R0[size_t(3 * q + 1)] * nprev[1] + R0[size_t(3 * q + 2)] * nprev[2];
            surf_b[q] = prev[q] - dprev * nprev[q];
          }
          for (int q = 0; q < 3; ++q)
            arm[q] = R0[size_t(3 * q)] * surf_b[0] + R0[size_t(3 * q + 1)] * surf_b[1] + R0[size_t(3 * q + 2)] * surf_b[2];
          double gap = -rad, vb[3], rel[3];
          for (int q = 0; q < 3; ++q) gap += (p0[q] - bs0.x[size_t(q)] - arm[q]) * n[q];
          body_point_velocity(bs0, arm, vb);
          for (int q = 0; q < 3; ++q) rel[q] = (1 - u) * v0[3 * i + q] + u * v0[3 * i + 3 + q] - vb[q];
          ContactSpring sp;
          segment_spring(m.fem.pattern, i, u, sp);
          const double share = (i == r.node_begin && j == 0) || j == K ? 0.5 / K : 1.0 / K;
          fill_contact_spring(sp, n, -gap, gap >= 0, r.stretch_stiffness * share, 0.0, std::min(r.friction, b.friction),
                              rel, 0.01 * std::min(r.diameter, b.feature), bout);
          sp.row_n = row;
          if (row >= 0)
            for (int q = 0; q < 3; ++q) sp.arm_n[q] = arm[q];
          if (!place_pinned(sp, gap, n, released, springs, pairs)) {
            ++out.dropped;
            ++bout.dropped;
            break;
          }
          if (released == nullptr) ++out.rigid;
          ++out.missed;
          ++added;
          break;
        }
      }
    }
  }
  return added;
}

int thread_tool_contact(const Model& m, const ToolSpec& spec, ToolState& ts, const double* x, ToolOutput& out,
                        std::vector<ContactSpring>& springs, ThreadContactOutput& tout) {
  if (m.fem.rods.empty() || spec.shape == ToolShape::None || !ts.active || ts.last_command_time < 0) return 0;
  Capsule cap[kMaxCapsules];
  const int nc = tool_capsules(spec, ts.pose, tool_center(spec, ts).data(), cap);
  int made = 0;
  bool released_clear = true;  // the segments it let go of are out of its capsules
  for (const RodRange& r : m.fem.rods) {
    if (ts.grasped_body >= 0 && rod_tied_to(m, r, ts.grasped_body)) continue;  // the thread of the needle it holds
    const double rad = 0.5 * r.diameter;
    const double k = r.stretch_stiffness;
    // The segments the jaws may still hold once they let go: as far as they reach, and two more.
    const int32_t window = static_cast<int32_t>(std::ceil((spec.shaft_length + 2.0 * spec.radius) / r.segment_length)) + 2;
    // The segment it holds or let go of, if on this rod (node indices of another rod may be near).
    const auto on_rod = [&](int32_t node) { return node >= r.node_begin && node < r.node_end; };
    const bool holds = on_rod(ts.grasped_segment), let_go = on_rod(ts.released_segment);
    for (int32_t i = r.node_begin; i + 1 < r.node_end; ++i) {
      if (holds && std::abs(ts.grasped_segment - i) <= 2) continue;  // in its jaws
      const bool released = let_go && std::abs(ts.released_segment - i) <= window;
      const double* a = x + 3 * i;
      const double* b = a + 3;
      for (int c = 0; c < nc; ++c) {
        const double reach = cap[c].r + rad;
        double s, t;
        const double d2 = segment_closest_points(a, b, cap[c].a, cap[c].b, &s, &t);
        if (d2 >= reach * reach) continue;
        if (released) {  // still between the jaws that let it go
          released_clear = false;
          continue;
        }
        const double d = std::sqrt(d2);
        double n[3];  // from the tool's axis to the thread
        for (int q = 0; q < 3; ++q) n[q] = a[q] + s * (b[q] - a[q]) - cap[c].a[q] - t * (cap[c].b[q] - cap[c].a[q]);
        if (d > 1e-12) {
          for (double& q : n) q /= d;
        } else {
          continue;  // on the axis: no direction to push it out along
        }
        if (springs.size() == springs.capacity()) {
          ++out.contacts_dropped;
          ++tout.dropped;
          continue;
        }
        ContactSpring sp;
        segment_spring(m.fem.pattern, i, s, sp);
        const double depth = reach - d;
        for (int p = 0; p < 3; ++p) {
          sp.force[p] = k * depth * n[p];
          for (int q = 0; q < 3; ++q) {
            sp.K[3 * p + q] = k * n[p] * n[q];
            out.stiffness[size_t(3 * p + q)] -= k * n[p] * n[q];
          }
        }
        out.contact_energy += 0.5 * k * depth * depth;
        springs.push_back(sp);
        ++out.contacts;
        ++tout.tools;
        tout.max_depth = std::max(tout.max_depth, depth);
        ++made;
      }
    }
  }
  if (released_clear) ts.released_segment = -1;
  if (made > 0) out.spring_end = static_cast<int32_t>(springs.size());
  return made;
}

int thread_rigid_contact(const Model& m, int32_t k, const RigidState& bs, int32_t row, const double* x,
                         const double* v, std::vector<ContactSpring>& springs, std::vector<RigidContactPair>& pairs,
                         RigidContactOutput& bout, ThreadContactOutput& out) {
  const RigidBodyModel& b = m.rigid_bodies[size_t(k)];
  const double h = m.fem_step;
  const double* g = m.fem.gravity.data();
  const double gn = norm3(g);
  const std::array<double, 9> R = rotation_of(bs.q);
  const double bspeed = norm3(bs.v.data()) + norm3(bs.w.data()) * b.bounding_radius;
  const double fall_side = row >= 0 ? 0.0 : 1.0;  // the thread falls; a free body with it
  int made = 0;
  for (const RodRange& r : m.fem.rods) {
    if (rod_tied_to(m, r, k)) continue;
    const double rad = 0.5 * r.diameter;
    const int K = segment_samples(r);
    const double mu = std::min(r.friction, b.friction);
    const double v_stick = 0.01 * std::min(r.diameter, b.feature);
    for (int32_t i = r.node_begin; i + 1 < r.node_end; ++i) {
      const double* a = x + 3 * i;
      const double* e = a + 3;
      const double speed = segment_speed(v, i) + bspeed;
      const double cap = rad + 2.0 * h * speed + h * h * gn + 0.25 * rad;
      double dm2 = 0, l2 = 0;
      for (int q = 0; q < 3; ++q) {
        const double dq = 0.5 * (a[q] + e[q]) - bs.x[size_t(q)];
        dm2 += dq * dq;
        l2 += (e[q] - a[q]) * (e[q] - a[q]);
      }
      const double reach = b.bounding_radius + 0.5 * std::sqrt(l2) + cap;
      if (dm2 >= reach * reach) continue;
      const int ns = i + 2 == r.node_end ? K + 1 : K;
      for (int j = 0; j < ns; ++j) {
        const double u = static_cast<double>(j) / K;
        double p[3], rp[3], pb[3], nb[3], n[3];
        for (int q = 0; q < 3; ++q) {
          p[q] = a[q] + u * (e[q] - a[q]);
          rp[q] = p[q] - bs.x[size_t(q)];
        }
        for (int q = 0; q < 3; ++q) pb[q] = R[size_t(q)] * rp[0] + R[size_t(3 + q)] * rp[1] + R[size_t(6 + q)] * rp[2];
        const double d = shape_distance(b, pb, nb);
        const double gap = d - rad;
        if (gap >= cap) continue;
        for (int q = 0; q < 3; ++q) n[q] = R[size_t(3 * q)] * nb[0] + R[size_t(3 * q + 1)] * nb[1] + R[size_t(3 * q + 2)] * nb[2];
        double arm[3], vb[3], rel[3];
        for (int q = 0; q < 3; ++q) arm[q] = rp[q] - d * n[q];  // the body's surface point
        body_point_velocity(bs, arm, vb);
        for (int q = 0; q < 3; ++q) rel[q] = v[3 * i + q] * (1.0 - u) + v[3 * i + 3 + q] * u - vb[q];
        if (out_of_reach(gap, dot3(rel, n), fall_side * h * h * dot3(g, n), h, 0.25 * rad)) continue;
        const bool speculative = gap >= 0;
        if (!reserve_contact(springs, pairs, gap, n)) {
          ++out.dropped;
          ++bout.dropped;
          continue;
        }
        ContactSpring sp;
        segment_spring(m.fem.pattern, i, u, sp);
        const double share = (i == r.node_begin && j == 0) || j == K ? 0.5 / K : 1.0 / K;
        fill_contact_spring(sp, n, -gap, speculative, r.stretch_stiffness * share, 0.0, mu, rel, v_stick, bout);
        sp.row_n = row;
        if (row >= 0)
          for (int q = 0; q < 3; ++q) sp.arm_n[q] = arm[q];
        springs.push_back(sp);
        ++out.rigid;
        if (!speculative) out.max_depth = std::max(out.max_depth, -gap);
        ++made;
      }
    }
  }
  return made;
}

}  // namespace stroma
