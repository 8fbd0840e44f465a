#include "engine/thread_attach.hpp"

#include <algorithm>
#include <cmath>

#include "engine/rigid_grasp.hpp"
#include "engine/thread_contact.hpp"
#include "haptics/tool_shape.hpp"

namespace stroma {

namespace {

/// The parameter (0..1) of the point of segment a–b nearest to p.
double nearest_on_segment(const double* a, const double* b, const double* p) {
  double ab2 = 0, t = 0;
  for (int k = 0; k < 3; ++k) {
    ab2 += (b[k] - a[k]) * (b[k] - a[k]);
    t += (p[k] - a[k]) * (b[k] - a[k]);
  }
  return ab2 > 0 ? std::clamp(t / ab2, 0.0, 1.0) : 0.0;
}

}  // namespace

void update_thread_grasps(const Model& m, State& s) {
  if (m.fem.rods.empty()) return;
  const double* x = s.tissue.x.data();
  for (size_t t = 0; t < m.tools.size(); ++t) {
    const ToolSpec& spec = m.tools[t];
    ToolState& ts = s.tools[t];
    if (!spec.can_grasp) continue;
    const bool closed_now = ts.pose.jaw < spec.grasp_close, open_now = ts.pose.jaw > spec.grasp_open;
    if (!ts.active || ts.last_command_time < 0 || open_now) {
      if (ts.grasped_segment >= 0) ts.released_segment = ts.grasped_segment;  // clear of its jaws yet?
      ts.grasped_segment = -1;  // (tool_contact resets jaw_closed)
      continue;
    }
    if (!closed_now || ts.jaw_closed) continue;  // no closing transition (or a body took it)
    double R[9], gc[3], reach;
    quaternion_to_matrix(ts.pose.orientation, R);
    grasp_centre(spec, ts, R, gc, &reach);
    int32_t best = -1;
    double best_d2 = reach * reach, best_s = 0;
    for (const RodRange& r : m.fem.rods)
      for (int32_t i = r.node_begin; i + 1 < r.node_end; ++i) {
        const double* a = x + 3 * i;
        const double* b = a + 3;
        const double u = nearest_on_segment(a, b, gc);
        double d2 = 0;
        for (int k = 0; k < 3; ++k) {
          const double q = a[k] + u * (b[k] - a[k]) - gc[k];
          d2 += q * q;
        }
        if (d2 <= best_d2) best_d2 = d2, best = i, best_s = u;
      }
    if (best < 0) continue;
    ts.jaw_closed = true;  // on the thread, not on tissue
    ts.grasped = 0;
    ts.grasped_segment = best;
    ts.grasp_segment_s = best_s;
    const Vec3& c = tool_center(spec, ts);
    double e[3];
    for (int k = 0; k < 3; ++k) e[k] = x[3 * best + k] + best_s * (x[3 * best + 3 + k] - x[3 * best + k]) - c[size_t(k)];
    for (int k = 0; k < 3; ++k) ts.grasp_segment_offset[size_t(k)] = R[k] * e[0] + R[3 + k] * e[1] + R[6 + k] * e[2];
  }
}

int thread_grasp_springs(const Model& m, const ToolSpec& spec, const ToolState& ts, const double* x, ToolOutput& out,
                         std::vector<ContactSpring>& springs) {
  if (ts.grasped_segment < 0) return 0;
  if (springs.size() == springs.capacity()) {
    ++out.contacts_dropped;
    return 0;
  }
  double R[9];
  quaternion_to_matrix(ts.pose.orientation, R);
  const Vec3& c = tool_center(spec, ts);
  const Vec3& o = ts.grasp_segment_offset;
  const int32_t i = ts.grasped_segment;
  const double u = ts.grasp_segment_s, k = spec.grasp_stiffness;
  ContactSpring sp;
  sp.n = 2;
  sp.node[0] = i;
  sp.node[1] = i + 1;
  sp.w[0] = 1.0 - u;
  sp.w[1] = u;
  for (int& sl : sp.slot) sl = -1;
  sp.slot[spring_slot(0, 0)] = m.fem.pattern.diag[i];
  sp.slot[spring_slot(0, 1)] = m.fem.pattern.find(i, i + 1);
  sp.slot[spring_slot(1, 1)] = m.fem.pattern.diag[i + 1];
  for (int a = 0; a < 3; ++a) {
    const double target = c[size_t(a)] + R[3 * a] * o[0] + R[3 * a + 1] * o[1] + R[3 * a + 2] * o[2];
    const double p = (1.0 - u) * x[3 * i + a] + u * x[3 * i + 3 + a];
    sp.force[a] = k * (target - p);  // on the thread, towards the jaws
    sp.K[4 * a] = k;
    out.stiffness[size_t(4 * a)] -= k;
  }
  springs.push_back(sp);
  ++out.contacts;
  out.spring_end = static_cast<int32_t>(springs.size());
  return 1;
}

int thread_tie_spring(const Model::ThreadTie& tie, const RigidState& body, int32_t row, const double* x,
                      const BsrPattern& pattern, std::vector<ContactSpring>& springs) {
  if (springs.size() == springs.capacity()) return 0;
  const std::array<double, 9> R = rotation_of(body.q);
  ContactSpring sp;
  sp.n = 1;
  sp.node[0] = tie.node;
  sp.w[0] = 1.0;
  for (int& sl : sp.slot) sl = -1;
  sp.slot[0] = pattern.diag[tie.node];
  sp.row_n = row;
  for (int a = 0; a < 3; ++a) {
    const double arm = R[size_t(3 * a)] * tie.arm[0] + R[size_t(3 * a + 1)] * tie.arm[1] + R[size_t(3 * a + 2)] * tie.arm[2];
    if (row >= 0) sp.arm_n[a] = arm;
    sp.force[a] = tie.stiffness * (body.x[size_t(a)] + arm - x[3 * tie.node + a]);  // on the thread, to the tail
    sp.K[4 * a] = tie.stiffness;
  }
  springs.push_back(sp);
  return 1;
}

RodPoint rod_point(const RodRange& r, double sigma) {
  RodPoint p;
  const int32_t segs = r.segments();
  const double sg = std::clamp(sigma, 0.0, static_cast<double>(segs));
  const int32_t j = std::min(static_cast<int32_t>(sg), segs - 1);
  p.j = r.node_begin + j;
  p.u = sg - j;
  return p;
}

namespace {

/// Unit vector of segment (i, i + 1) (zero for a segment of zero length), and its length.
double segment_unit(const double* x, int32_t i, double* e) {
  double l2 = 0;
  for (int k = 0; k < 3; ++k) {
    e[k] = x[3 * i + 3 + k] - x[3 * i + k];
    l2 += e[k] * e[k];
  }
  const double l = std::sqrt(l2);
  for (int k = 0; k < 3; ++k) e[k] = l > 0 ? e[k] / l : 0.0;
  return l;
}

/// The puncture's thread point, the thread's unit tangent there, its segment's length, and the
/// tissue point. The tangent is the bisector of the segments before and after the point's
/// segment (at an end, the segment itself): where the thread turns by θ through the puncture —
/// a segment cutting the corner, whatever its own slant — it halves θ, so the point's force
/// across it is (T₁ + T₂)·sin(θ/2) and along it (T₂ − T₁)·cos(θ/2): the split the friction law
/// acts on (docs/THREAD.md). (The segment's own direction would tilt with T₂/T₁.)
void puncture_geometry(const FemModel& fem, const RodPuncture& p, const double* x, RodPoint& rp, double* T, double* t,
                       double* len, double* P) {
  const RodRange& r = fem.rods[size_t(p.rod)];
  rp = rod_point(r, p.sigma);
  double e[3], ep[3], en[3];
  *len = segment_unit(x, rp.j, e);
  if (rp.j > r.node_begin) segment_unit(x, rp.j - 1, ep);
  else std::copy(e, e + 3, ep);
  if (rp.j + 2 < r.node_end) segment_unit(x, rp.j + 1, en);
  else std::copy(e, e + 3, en);
  double n2 = 0;
  for (int k = 0; k < 3; ++k) {
    const double* a = x + 3 * rp.j;
    T[k] = (1 - rp.u) * a[k] + rp.u * a[3 + k];
    t[k] = ep[k] + en[k];
    n2 += t[k] * t[k];
    P[k] = 0;
    for (int q = 0; q < 4; ++q) P[k] += p.w[q] * x[3 * p.node[q] + k];
  }
  const double n = std::sqrt(n2);
  for (int k = 0; k < 3; ++k) t[k] = n > 0 ? t[k] / n : e[k];
}

}  // namespace

void thread_punctures_before_step(const Model& m, State& s) {
  for (int32_t i = 0; i < s.puncture_count; ++i) {
    RodPuncture& p = s.punctures[size_t(i)];
    p.sigma = std::clamp(p.sigma + p.slip, 0.0, static_cast<double>(m.fem.rods[size_t(p.rod)].segments()));
  }
}

int thread_puncture_spring(const FemModel& fem, const RodPuncture& p, const double* x, std::vector<ContactSpring>& springs) {
  if (springs.size() == springs.capacity()) return 0;
  RodPoint rp;
  double T[3], t[3], len, P[3];
  puncture_geometry(fem, p, x, rp, T, t, &len, P);
  ContactSpring sp;
  const int32_t nodes[6] = {rp.j, rp.j + 1, p.node[0], p.node[1], p.node[2], p.node[3]};
  const double w[6] = {1 - rp.u, rp.u, -p.w[0], -p.w[1], -p.w[2], -p.w[3]};
  set_spring_nodes(fem.pattern, nodes, w, 6, sp);  // its cross pairs matrix-free
  // A zero-length spring k·I (the last step's slip relaxed its axial part to the friction limit;
  // a sliding puncture's σ already moved on by that slip again: thread_punctures_before_step).
  const double k = p.stiffness;
  for (int c = 0; c < 3; ++c) {
    sp.force[c] = -k * (T[c] - P[c]);  // on the thread's point; the tissue's is its opposite
    sp.K[4 * c] = k;
  }
  springs.push_back(sp);
  return 1;
}

int thread_punctures_after_step(const Model& m, State& s, const double* x, const double* v, const NeedleOutput* needles,
                                int* dropped) {
  // Friction: a return mapping of each spring's axial part onto the Coulomb limit.
  int32_t kept = 0;
  for (int32_t i = 0; i < s.puncture_count; ++i) {
    RodPuncture p = s.punctures[size_t(i)];
    const RodRange& r = m.fem.rods[size_t(p.rod)];
    RodPoint rp;
    double T[3], t[3], len, P[3];
    puncture_geometry(m.fem, p, x, rp, T, t, &len, P);
    const double d[3] = {T[0] - P[0], T[1] - P[1], T[2] - P[2]};
    const double da = d[0] * t[0] + d[1] * t[1] + d[2] * t[2];
    const double dn2 = std::max(0.0, d[0] * d[0] + d[1] * d[1] + d[2] * d[2] - da * da);
    const double limit = r.friction * p.stiffness * std::sqrt(dn2);  // μ·|F_n|
    const double fa = p.stiffness * std::abs(da);
    p.slip = 0;
    if (fa >= limit * (1 - 1e-9) && len > 0) {
      // At the limit: slide — the thread's point moves back along it by the stretch beyond the
      // limit, and the next step starts ahead by the thread's travel at its speed relative to
      // the tissue now (if it still moves the way it slid).
      const double way = da > 0 ? 1.0 : -1.0;
      p.sigma -= way * (fa - limit) / p.stiffness / len;
      double va = 0;
      for (int k = 0; k < 3; ++k) {
        double vt = (1 - rp.u) * v[3 * rp.j + k] + rp.u * v[3 * rp.j + 3 + k], vp = 0;
        for (int q = 0; q < 4; ++q) vp += p.w[q] * v[3 * p.node[q] + k];
        va += (vt - vp) * t[k];
      }
      // At most half a segment a step (1 m/s for 2 mm segments at 1 kHz): a solve cut short by
      // the budget can leave a velocity no thread has, and a prediction from it can fling σ past
      // the thread's end (the puncture dropped: scenarios/liver_stitch_thread.yaml under its
      // 0.8 ms budget lost its entry puncture in some runs; clamped, both stay, 2 of 2 runs).
      if (va * way > 0) p.slip = std::clamp(-va * m.fem_step / len, -kMaxPunctureSlip, kMaxPunctureSlip);
    }
    // A free end that slides out leaves the puncture; an end tied to a needle cannot (the needle
    // is there: σ stays at it — as right after the puncture is made, where the tissue's point,
    // dragged on by the needle's friction, may lie a little ahead of the tail).
    auto tied = [&](int32_t node) {
      for (const Model::ThreadTie& tie : m.thread_ties)
        if (tie.node == node) return true;
      return false;
    };
    if (p.sigma < 0) {
      if (!tied(r.node_begin)) continue;
      p.sigma = 0, p.slip = 0;
    }
    if (p.sigma > r.segments()) {
      if (!tied(r.node_end - 1)) continue;
      p.sigma = r.segments(), p.slip = 0;
    }
    s.punctures[size_t(kept++)] = p;
  }
  s.puncture_count = kept;
  // New punctures where a needle's tail passed an entry or exit: each thread tied to that tail
  // goes through it from its tied end on.
  int made = 0;
  for (const Model::ThreadTie& tie : m.thread_ties) {
    const NeedleOutput& out = needles[size_t(tie.body)];
    for (int32_t q = 0; q < out.passed_count; ++q) {
      const TrackPoint& tp = out.passed[size_t(q)];
      int32_t rod = 0;
      while (!(tie.node >= m.fem.rods[size_t(rod)].node_begin && tie.node < m.fem.rods[size_t(rod)].node_end)) ++rod;
      const RodRange& r = m.fem.rods[size_t(rod)];
      if (s.puncture_count == static_cast<int32_t>(s.punctures.size())) {
        ++*dropped;
        continue;
      }
      RodPuncture p;
      for (int a = 0; a < 4; ++a) p.w[a] = tp.w[a], p.node[a] = tp.node[size_t(a)];
      p.sigma = tie.node == r.node_begin ? 0.0 : static_cast<double>(r.segments());
      const NeedleTissue& nt = m.needle_tissue[size_t(tp.body)];
      p.stiffness = nt.track_stiffness * nt.track_spacing;
      p.rod = rod;
      p.body = tp.body;
      s.punctures[size_t(s.puncture_count++)] = p;
      ++made;
    }
  }
  return made;
}

}  // namespace stroma
