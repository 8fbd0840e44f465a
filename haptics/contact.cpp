#include "haptics/contact.hpp"

#include <algorithm>
#include <cmath>

#include "haptics/tool_shape.hpp"
#include "tissue/mat3.hpp"
#include "tissue/triangle_closest_point.hpp"

namespace stroma {

namespace {

/// A spring pulling the surface point (triangle t, barycentric u, v) towards `target`.
ContactSpring point_spring(const ContactSurface& surf, int32_t t, double u, double v, const double* x,
                           const double* target, double k) {
  ContactSpring sp;
  const auto& tri = surf.triangles[t];
  const double b[3] = {1.0 - u - v, u, v};
  set_spring_point(surf.dofs[t], b[0], b[1], b[2], sp);
  for (int k3 = 0; k3 < 3; ++k3) {
    double p = 0;
    for (int a = 0; a < 3; ++a) p += b[a] * x[3 * tri[a] + k3];
    sp.force[k3] = k * (target[k3] - p);
    sp.K[4 * k3] = k;
  }
  return sp;
}

/// Grasp logic of one tool: on the open → closed jaw transition, attach the surface points
/// within reach of the grasp centre (closest first, offsets in the tool frame) — the tip for a
/// sphere or probe, the middle of the jaws for a grasper (reach then spans the jaws' length);
/// on opening, release.
/// While points are held, each gets a spring to its attachment point. Returns true while holding.
bool grasp(const ContactSurface& surf, const ToolSpec& spec, ToolState& ts, ToolOutput& out, const double* c,
           const double* x, const TriangleBvh& bvh, std::vector<ContactSpring>& springs) {
  double Rm[9];
  quaternion_to_matrix(ts.pose.orientation, Rm);
  const bool closed_now = ts.pose.jaw < spec.grasp_close;
  const bool open_now = ts.pose.jaw > spec.grasp_open;
  if (closed_now && !ts.jaw_closed) {
    ts.jaw_closed = true;
    ts.grasped = 0;
    double reach = spec.grasp_reach * spec.radius;
    double gc[3] = {c[0], c[1], c[2]};
    if (spec.shape == ToolShape::Grasper) {  // between the jaws: along the tool's +z
      for (int k = 0; k < 3; ++k) gc[k] = c[k] + 0.5 * spec.shaft_length * Rm[3 * k + 2];
      reach += 0.5 * spec.shaft_length;
    }
    std::array<double, kMaxGrasped> dist2{};
    bvh.query_sphere(gc, reach, x, [&](int32_t t) {
      if (surf.active && !surf.active[t]) return;
      const auto& tri = surf.triangles[t];
      for_each_triangle_sample(surface_samples_per_edge(surf, t, spec.radius), [&](double u, double v) {
        double d[3], d2 = 0;  // d: from the tool origin (offset); d2: from the grasp centre
        for (int k = 0; k < 3; ++k) {
          const double p = (1 - u - v) * x[3 * tri[0] + k] + u * x[3 * tri[1] + k] + v * x[3 * tri[2] + k];
          d[k] = p - c[k];
          d2 += (p - gc[k]) * (p - gc[k]);
        }
        if (d2 > reach * reach) return;
        // Keep the kMaxGrasped closest points (insertion into a sorted fixed array).
        int pos = ts.grasped;
        if (pos == kMaxGrasped) {
          if (d2 >= dist2[kMaxGrasped - 1]) return;
          pos = kMaxGrasped - 1;
        } else {
          ++ts.grasped;
        }
        while (pos > 0 && dist2[pos - 1] > d2) {
          dist2[pos] = dist2[pos - 1];
          ts.grasp_triangle[pos] = ts.grasp_triangle[pos - 1];
          ts.grasp_uv[pos] = ts.grasp_uv[pos - 1];
          ts.grasp_offset[pos] = ts.grasp_offset[pos - 1];
          --pos;
        }
        dist2[pos] = d2;
        ts.grasp_triangle[pos] = t;
        ts.grasp_uv[pos] = {u, v};
        for (int k = 0; k < 3; ++k)  // offset in the tool frame: Rᵀ d
          ts.grasp_offset[pos][k] = Rm[k] * d[0] + Rm[3 + k] * d[1] + Rm[6 + k] * d[2];
      });
    });
  } else if (open_now && ts.jaw_closed) {
    ts.jaw_closed = false;
    ts.grasped = 0;  // release
  }
  if (ts.grasped == 0) return false;
  const double kg = spec.grasp_stiffness;
  for (int i = 0; i < ts.grasped; ++i) {
    if (springs.size() == springs.capacity()) {
      ++out.contacts_dropped;
      continue;
    }
    const Vec3& o = ts.grasp_offset[i];
    double target[3];
    for (int k = 0; k < 3; ++k) target[k] = c[k] + Rm[3 * k] * o[0] + Rm[3 * k + 1] * o[1] + Rm[3 * k + 2] * o[2];
    const ContactSpring sp = point_spring(surf, ts.grasp_triangle[i], ts.grasp_uv[i][0], ts.grasp_uv[i][1], x, target, kg);
    for (int k = 0; k < 3; ++k) {
      out.force[k] -= sp.force[k];
      out.stiffness[4 * k] -= kg;
      out.contact_energy += 0.5 * sp.force[k] * sp.force[k] / kg;
    }
    springs.push_back(sp);
    ++out.contacts;
  }
  out.grasping = true;
  return true;
}

/// Virtual coupling: moves the proxy by one implicit step of its quasi-static balance
/// k_v (device − proxy) + F_contact(proxy) = 0, from the last solved step's contact force and
/// stiffness (ts.force, ts.stiffness).
void coupling_step(const ToolSpec& spec, ToolState& ts) {
  const double kv = spec.coupling_stiffness;
  if (kv <= 0 || ts.last_command_time < 0) return;
  if (!ts.has_proxy) {
    ts.proxy = ts.pose.position;
    ts.has_proxy = true;
    return;
  }
  double A[9], Ai[9], b[3], dp[3];
  for (int i = 0; i < 9; ++i) A[i] = -ts.stiffness[i] + (i % 4 == 0 ? kv : 0.0);
  for (int i = 0; i < 3; ++i) b[i] = kv * (ts.pose.position[i] - ts.proxy[i]) + ts.force[i];
  m3::inverse(A, Ai);
  m3::mulv(Ai, b, dp);
  for (int i = 0; i < 3; ++i) ts.proxy[i] += dp[i];
}

/// The tool as capsules in world coordinates with one bounding sphere (qc, qr) for the BVH
/// query and the smallest capsule radius (sampling density).
struct ToolGeometry {
  Capsule caps[kMaxCapsules];
  int count = 0;
  double qc[3] = {0, 0, 0}, qr = 0, rmin = 1e300;
  double normal[3] = {0, 1, 0};  ///< the tool's local y in world coordinates (a blade's normal)
  // A cutting blade's body (ToolSpec::cuts): a plate of half-thickness `radius` behind its edge —
  // along the edge (local x) ±half_length, behind it (local −z) up to `height`.
  bool plate = false;
  double edge_dir[3] = {1, 0, 0}, back_dir[3] = {0, 0, -1};
  double half_length = 0, height = 0;
};

ToolGeometry tool_geometry(const ToolSpec& spec, const ToolPose& pose, const double* c) {
  ToolGeometry g;
  g.count = tool_capsules(spec, pose, c, g.caps);
  double Rm[9];
  quaternion_to_matrix(pose.orientation, Rm);
  for (int k = 0; k < 3; ++k) g.normal[k] = Rm[3 * k + 1];
  if (spec.cuts) {
    g.plate = true;
    g.half_length = 0.5 * spec.shaft_length;
    g.height = spec.blade_height;
    for (int k = 0; k < 3; ++k) {
      g.edge_dir[k] = Rm[3 * k];
      g.back_dir[k] = -Rm[3 * k + 2];
      g.qc[k] = c[k] + 0.5 * g.height * g.back_dir[k];
    }
    g.qr = std::sqrt(g.half_length * g.half_length + 0.25 * g.height * g.height) + spec.radius;
    // Samples spaced for the blade's body, not its thickness: the lips are flat against it
    // (at the thickness's spacing a liver's lips took 576 samples a face, collide 0.5 ms a tick).
    g.rmin = std::max(spec.radius, 0.5 * g.height);
    return g;
  }
  for (int i = 0; i < g.count; ++i)
    for (int k = 0; k < 3; ++k) g.qc[k] += 0.5 * (g.caps[i].a[k] + g.caps[i].b[k]) / g.count;
  for (int i = 0; i < g.count; ++i) {
    for (const double* e : {g.caps[i].a, g.caps[i].b}) {
      const double dd = std::sqrt((e[0] - g.qc[0]) * (e[0] - g.qc[0]) + (e[1] - g.qc[1]) * (e[1] - g.qc[1]) +
                                  (e[2] - g.qc[2]) * (e[2] - g.qc[2]));
      g.qr = std::max(g.qr, dd + g.caps[i].r);
    }
    g.rmin = std::min(g.rmin, g.caps[i].r);
  }
  return g;
}

/// The deepest capsule at point q: returns true if q is inside one, with d = q − the closest
/// axis point, dist2 = |d|² and Rs that capsule's radius.
bool deepest_capsule(const ToolGeometry& g, const double* q, double* d, double& dist2, double& Rs) {
  double best = 1e300;
  dist2 = 0;
  Rs = 0;
  for (int i = 0; i < g.count; ++i) {
    const Capsule& cap = g.caps[i];
    double ab[3], qa[3], ds[3];
    for (int a = 0; a < 3; ++a) {
      ab[a] = cap.b[a] - cap.a[a];
      qa[a] = q[a] - cap.a[a];
    }
    const double l2 = ab[0] * ab[0] + ab[1] * ab[1] + ab[2] * ab[2];
    const double tpar = l2 > 0 ? std::clamp((qa[0] * ab[0] + qa[1] * ab[1] + qa[2] * ab[2]) / l2, 0.0, 1.0) : 0.0;
    for (int a = 0; a < 3; ++a) ds[a] = qa[a] - tpar * ab[a];
    const double s2 = ds[0] * ds[0] + ds[1] * ds[1] + ds[2] * ds[2];
    const double sd = std::sqrt(s2) - cap.r;
    if (sd < best) {
      best = sd;
      dist2 = s2;
      Rs = cap.r;
      for (int a = 0; a < 3; ++a) d[a] = ds[a];
    }
  }
  return dist2 < Rs * Rs;
}

/// Friction of one contact: regularised Coulomb on the sliding velocity relative to the tool,
/// f_t = −c_t (I − n nᵀ)(v − v_tool), c_t = μ f_n / max(|v_t|, v_stick). Its damping matrix
/// enters the implicit system (C); the tool's own velocity stays explicit.
void add_friction(ContactSpring& sp, const double* dir, double fmag, double mu, double v_stick, const double* vel,
                  const double* vt, ToolOutput& out) {
  double vr[3];
  spring_point(sp, vel, vr);  // the contact point's velocity
  for (int a = 0; a < 3; ++a) vr[a] -= vt[a];
  const double vn = vr[0] * dir[0] + vr[1] * dir[1] + vr[2] * dir[2];
  double vtan[3];
  for (int a = 0; a < 3; ++a) vtan[a] = vr[a] - vn * dir[a];
  const double speed = std::sqrt(vtan[0] * vtan[0] + vtan[1] * vtan[1] + vtan[2] * vtan[2]);
  const double ct = mu * fmag / std::max(speed, v_stick);
  for (int a = 0; a < 3; ++a) {
    for (int b = 0; b < 3; ++b) {
      const double P = (a == b ? 1.0 : 0.0) - dir[a] * dir[b];
      sp.C[3 * a + b] += ct * P;
      sp.force[a] += ct * P * vt[b];  // the −C·v_tool part of −C·(v − v_tool)
    }
    out.force[a] += ct * vtan[a];  // the tool is dragged along by the tissue's motion
  }
}

}  // namespace

void tool_contact(const ToolSpec& spec, ToolState& ts, ToolOutput& out, const ContactSurface& surf,
                  const TriangleBvh& bvh, const double* x, const double* vel, double dt,
                  std::vector<ContactSpring>& springs) {
  coupling_step(spec, ts);
  out = ToolOutput{};
  out.spring_begin = out.spring_end = static_cast<int32_t>(springs.size());
  if (spec.shape == ToolShape::None || ts.last_command_time < 0) return;
  if (!ts.active) {
    // Idle (its client fell silent for longer than `timeout`, e.g. it died mid-press): the tool
    // lets go and leaves the tissue — no grasp, no contact, no force — rather than holding a
    // press nobody controls. Commands resuming bring it back from the pose they command.
    ts.grasped = 0;
    ts.jaw_closed = false;
    ts.has_center = false;
    ts.force = {0, 0, 0};
    ts.stiffness = {};
    return;
  }
  const double* c = tool_center(spec, ts).data();
  if (spec.can_grasp && grasp(surf, spec, ts, out, c, x, bvh, springs)) {  // holding tissue: no tip contact
    out.spring_end = static_cast<int32_t>(springs.size());
    return;
  }
  // Tool velocity (for friction), from its contact centre one tick ago.
  double vt[3] = {0, 0, 0};
  if (ts.has_center && dt > 0)
    for (int k = 0; k < 3; ++k) vt[k] = (c[k] - ts.last_center[k]) / dt;
  for (int k = 0; k < 3; ++k) ts.last_center[k] = c[k];
  ts.has_center = true;
  const double mu = vel ? spec.friction : 0.0;
  const double v_stick = 0.01 * spec.radius;
  const ToolGeometry g = tool_geometry(spec, ts.pose, c);
  bvh.query_sphere(g.qc, g.qr, x, [&](int32_t t) {
    if (surf.active && !surf.active[t]) return;
    // A cutting blade passes through tissue (its edge cuts what it sweeps) and touches only the
    // wound's lips: pushing on uncut surface would move the material it is about to cut off
    // its path (measured: nodes near the blade's plane pushed across it left the cut bridged).
    if (spec.cuts && !(surf.cut_face && surf.cut_face[t])) return;
    const auto& tri = surf.triangles[t];
    const double* p0 = x + 3 * tri[0];
    const double* p1 = x + 3 * tri[1];
    const double* p2 = x + 3 * tri[2];
    double nrm[3];
    triangle_normal(p0, p1, p2, nrm);
    const double twice_area = std::sqrt(nrm[0] * nrm[0] + nrm[1] * nrm[1] + nrm[2] * nrm[2]);
    if (twice_area <= 0) return;
    const double nsign = (surf.active && surf.active[t] == 2) ? -1.0 : 1.0;  // exposed from behind
    for (double& v : nrm) v *= nsign / twice_area;
    const int ns = surface_samples_per_edge(surf, t, g.rmin);
    const double sample_area = 0.5 * twice_area / (ns * ns);
    const double kc = spec.contact_stiffness * sample_area, cc = spec.contact_damping * sample_area;
    for_each_triangle_sample(ns, [&](double u, double v) {
      const double w0 = 1.0 - u - v;
      double q[3], d[3] = {0, 0, 0}, dist2 = 0, Rs = 0;
      for (int a = 0; a < 3; ++a) q[a] = w0 * p0[a] + u * p1[a] + v * p2[a];
      double dir[3];
      double depth = 0;
      if (g.plate) {
        // A cutting blade's sides push the wound's lips apart: inside its body (the plate behind
        // its edge), along its normal only. Which way is the lip's own: its material lies behind
        // its outward normal, so a lip facing +n (n the blade's normal) belongs on the −n side of
        // the plate, at side ≤ −radius. (Not the side it is on: the two lips of a fresh cut lie
        // on the blade's mid-plane together, and round-off would push them into each other.)
        double along = 0, back = 0, side = 0, facing = 0;
        for (int a = 0; a < 3; ++a) {
          along += (q[a] - c[a]) * g.edge_dir[a];
          back += (q[a] - c[a]) * g.back_dir[a];
          side += (q[a] - c[a]) * g.normal[a];
          facing += nrm[a] * g.normal[a];
        }
        // The blade is bevelled: its half-thickness grows from 0 at the edge to `radius` at
        // kBladeBevel radii behind it, so the lips open gradually as it advances (at 1/8 of its
        // speed) instead of being thrown a whole half-thickness apart in the tick that cut them.
        const double s_out = facing >= 0 ? 1.0 : -1.0;
        const double half = spec.radius * std::min(1.0, back / (kBladeBevel * spec.radius));
        depth = half + s_out * side;
        if (std::abs(along) > g.half_length || back < 0 || back > g.height || depth <= 0) return;
        if (depth > 2 * half) return;  // beyond the far side: not this lip's to push
        for (int a = 0; a < 3; ++a) dir[a] = -s_out * g.normal[a];
      } else {
        if (!deepest_capsule(g, q, d, dist2, Rs)) return;
        // Push along the distance gradient, or along the inward surface normal when the tool's
        // axis is already below the surface point (deep penetration).
        const double dist = std::sqrt(dist2);
        depth = Rs - dist;
        if (d[0] * nrm[0] + d[1] * nrm[1] + d[2] * nrm[2] <= 0 && dist > 1e-12 * Rs) {
          for (int a = 0; a < 3; ++a) dir[a] = d[a] / dist;
        } else {
          for (int a = 0; a < 3; ++a) dir[a] = -nrm[a];
        }
      }
      if (springs.size() == springs.capacity()) {
        ++out.contacts_dropped;
        return;
      }
      ContactSpring sp;
      set_spring_point(surf.dofs[t], w0, u, v, sp);
      const double fmag = kc * depth;
      out.contact_energy += 0.5 * kc * depth * depth;
      for (int a = 0; a < 3; ++a) {
        sp.force[a] = fmag * dir[a];
        out.force[a] -= sp.force[a];
        for (int b = 0; b < 3; ++b) {
          sp.K[3 * a + b] = kc * dir[a] * dir[b];
          sp.C[3 * a + b] = cc * dir[a] * dir[b];
          out.stiffness[3 * a + b] -= sp.K[3 * a + b];
        }
      }
      if (mu > 0) add_friction(sp, dir, fmag, mu, v_stick, vel, vt, out);
      // Torque of the tissue's force on the tool about the tip centre: (q − c) × (−f).
      const double r[3] = {q[0] - c[0], q[1] - c[1], q[2] - c[2]};
      out.torque[0] -= r[1] * sp.force[2] - r[2] * sp.force[1];
      out.torque[1] -= r[2] * sp.force[0] - r[0] * sp.force[2];
      out.torque[2] -= r[0] * sp.force[1] - r[1] * sp.force[0];
      springs.push_back(sp);
      ++out.contacts;
    });
  });
  out.spring_end = static_cast<int32_t>(springs.size());
}

}  // namespace stroma
