#include "rigid/wire_contact.hpp"

#include <algorithm>
#include <cmath>

#include "tissue/triangle_closest_point.hpp"

namespace stroma {

namespace {

inline double dot3(const double* a, const double* b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

}  // namespace

void make_wire_samples(RigidBodyModel& b) {
  b.wire_axis.clear();
  b.wire_share.clear();
  b.wire_arc.clear();
  if (b.shape != RigidShape::Needle) return;
  const NeedleGeometry& g = b.needle;
  // From the tail to one radius short of the curve's end: the last sphere reaches the end, and
  // the apex beyond it (one radius further) is the tip's own contact (rigid/needle_track.hpp).
  const double span = std::max(g.length - g.wire_radius, 0.5 * g.length);
  const int n = std::clamp(static_cast<int>(std::ceil(span / (0.5 * g.wire_radius))) + 1, 2, kMaxWireSamples);
  const double step = span / (n - 1);
  for (int j = 0; j < n; ++j) {
    double c[3], t[3];
    needle_curve(g, step * j, c, t);
    b.wire_axis.push_back({b.shape_origin[0] + c[0], b.shape_origin[1] + c[1], b.shape_origin[2] + c[2]});
    b.wire_share.push_back(j == 0 || j == n - 1 ? 0.5 * step : step);
    b.wire_arc.push_back(step * j);
  }
}

void wire_tissue_contact(const RigidBodyModel& b, const RigidState& s, int32_t row, const ContactSurface& surf,
                         const TriangleBvh& bvh, const double* x, const double* v, double h, const Vec3& g,
                         std::vector<ContactSpring>& springs, std::vector<RigidContactPair>& pairs,
                         RigidContactOutput& out, const ContactExclusion& ex) {
  const int n = static_cast<int>(b.wire_axis.size());
  if (n == 0) return;
  const double r = b.needle.wire_radius;
  const std::array<double, 9> R = rotation_of(s.q);
  const double speed = std::sqrt(dot3(s.v.data(), s.v.data())) + std::sqrt(dot3(s.w.data(), s.w.data())) * b.bounding_radius;
  const double gn = std::sqrt(dot3(g.data(), g.data()));
  // The farthest a point's surface can be and still make a spring this step (the step's reach,
  // bounded as rigid_tissue_contact bounds it, the tissue's speed included through the BVH's
  // box of this step).
  const double cap = r + 2.0 * h * speed + h * h * gn + 0.25 * r;
  double c[kMaxWireSamples][3];           // the axis points, world
  double best_d2[kMaxWireSamples];        // squared distance to the closest surface point so far
  int32_t best_tri[kMaxWireSamples];      // its triangle (−1: none within cap)
  double best_w[kMaxWireSamples][3];      // its barycentric weights
  for (int j = 0; j < n; ++j) {
    const Vec3& p = b.wire_axis[size_t(j)];
    for (int k = 0; k < 3; ++k)
      c[j][k] = s.x[size_t(k)] + R[size_t(3 * k)] * p[0] + R[size_t(3 * k + 1)] * p[1] + R[size_t(3 * k + 2)] * p[2];
    best_d2[j] = cap * cap;
    best_tri[j] = -1;
    const double arc = b.wire_arc[size_t(j)];
    if (arc >= ex.track_s0 - ex.hole_radius && arc <= ex.track_s1 + ex.hole_radius) best_d2[j] = 0;  // none
  }
  bvh.query_sphere(s.x.data(), b.bounding_radius + cap, x, [&](int32_t t) {
    if (surf.active && !surf.active[t]) return;
    const auto& tri = surf.triangles[size_t(t)];
    const double* A = x + 3 * tri[0];
    const double* B = x + 3 * tri[1];
    const double* C = x + 3 * tri[2];
    double nrm[3];
    if (!triangle_unit_normal(A, B, C, nrm)) return;
    for (int j = 0; j < n; ++j) keep_closer_on_triangle(c[j], A, B, C, nrm, t, best_d2[j], best_tri[j], best_w[j]);
  });
  const double v_stick = 0.01 * b.feature;
  double tip_dir[3] = {0, 0, 0};  // the tip's direction, world
  if (ex.tip_zone > 0) {
    double c_end[3], t_end[3];
    needle_curve(b.needle, b.needle.length, c_end, t_end);
    for (int k = 0; k < 3; ++k) tip_dir[k] = R[size_t(3 * k)] * t_end[0] + R[size_t(3 * k + 1)] * t_end[1] + R[size_t(3 * k + 2)] * t_end[2];
  }
  for (int j = 0; j < n; ++j) {
    const int32_t t = best_tri[j];
    if (t < 0) continue;
    const auto& tri = surf.triangles[size_t(t)];
    const double* A = x + 3 * tri[0];
    const double* B = x + 3 * tri[1];
    const double* C = x + 3 * tri[2];
    double q[3], cq[3], face[3];
    for (int k = 0; k < 3; ++k) {
      q[k] = best_w[j][0] * A[k] + best_w[j][1] * B[k] + best_w[j][2] * C[k];
      cq[k] = q[k] - c[j][k];
    }
    {
      triangle_normal(A, B, C, face);
      const double len = std::sqrt(dot3(face, face));
      const double sgn = surf.active && surf.active[t] == 2 ? -1.0 : 1.0;  // a face turned round
      for (double& k : face) k *= sgn / len;
    }
    // σ: the axis point's signed distance to the surface (negative under the face); n from the
    // wire to the tissue: along q − c outside, away from the face inside.
    const double dist = std::sqrt(best_d2[j]);
    const bool under = dot3(cq, face) > 0;
    const double sigma = under ? -dist : dist;
    if (sigma <= -r) continue;  // deep: the inserted shaft (or a wire already through)
    double n[3];
    if (dist > 1e-6 * r)
      for (int k = 0; k < 3; ++k) n[k] = (under ? -cq[k] : cq[k]) / dist;
    else
      for (int k = 0; k < 3; ++k) n[k] = -face[k];
    // Ahead of the tip: the tip's contact presses there (and punctures); the wire's points behind
    // the apex would take its load (measured: on the 5 kPa liver an exited needle then never
    // punctured an incision's far lip, which its wire touched as it came out of the near one).
    if (b.wire_arc[size_t(j)] >= b.needle.length - ex.tip_zone && dot3(n, tip_dir) > 0.5) continue;
    if (near_a_hole(ex, q)) continue;
    double arm[3];
    for (int k = 0; k < 3; ++k) arm[k] = c[j][k] + r * n[k] - s.x[size_t(k)];
    const double area = 2.0 * r * b.wire_share[size_t(j)];
    add_tissue_body_spring(surf.dofs[size_t(t)], best_w[j][0], best_w[j][1], best_w[j][2], s, row, arm, n, sigma - r,
                           b.contact_stiffness * area, b.contact_damping * area, b.friction, v_stick, v, h, g, speed,
                           springs, pairs, out);
  }
}

}  // namespace stroma
