#include "rigid/rigid_contact.hpp"

#include <algorithm>
#include <cmath>

#include "rigid/wire_contact.hpp"
#include "tissue/triangle_closest_point.hpp"

namespace stroma {

namespace {

constexpr double kPi = 3.14159265358979323846;

inline double dot3(const double* a, const double* b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
inline double norm3(const double* a) { return std::sqrt(dot3(a, a)); }

/// y = R x and y = Rᵀ x for a row-major rotation.
inline void rot(const std::array<double, 9>& R, const double* x, double* y) {
  for (int i = 0; i < 3; ++i) y[i] = R[size_t(3 * i)] * x[0] + R[size_t(3 * i + 1)] * x[1] + R[size_t(3 * i + 2)] * x[2];
}
inline void rot_t(const std::array<double, 9>& R, const double* x, double* y) {
  for (int i = 0; i < 3; ++i) y[i] = R[size_t(i)] * x[0] + R[size_t(3 + i)] * x[1] + R[size_t(6 + i)] * x[2];
}


/// Solid angle of triangle (a, b, c) seen from the origin (Van Oosterom & Strackee 1983).
double solid_angle(const double* a, const double* b, const double* c) {
  const double la = norm3(a), lb = norm3(b), lc = norm3(c);
  const double bxc[3] = {b[1] * c[2] - b[2] * c[1], b[2] * c[0] - b[0] * c[2], b[0] * c[1] - b[1] * c[0]};
  const double num = dot3(a, bxc);
  const double den = la * lb * lc + dot3(a, b) * lc + dot3(a, c) * lb + dot3(b, c) * la;
  return 2.0 * std::atan2(num, den);
}

double mesh_distance(const RigidBodyModel& b, const double* p, double* normal) {
  const Vec3 q{p[0], p[1], p[2]};
  double best = 1e300, wind = 0;
  Vec3 cbest{0, 0, 0};
  for (const Tri& t : b.surface_triangles) {
    const Vec3& A = b.surface_vertices[size_t(t[0])];
    const Vec3& B = b.surface_vertices[size_t(t[1])];
    const Vec3& C = b.surface_vertices[size_t(t[2])];
    const std::array<double, 3> w = closest_on_triangle(q, A, B, C);
    Vec3 c;
    for (int k = 0; k < 3; ++k) c[size_t(k)] = w[0] * A[size_t(k)] + w[1] * B[size_t(k)] + w[2] * C[size_t(k)];
    const double d2 = (c[0] - q[0]) * (c[0] - q[0]) + (c[1] - q[1]) * (c[1] - q[1]) + (c[2] - q[2]) * (c[2] - q[2]);
    if (d2 < best) best = d2, cbest = c;
    const double a[3] = {A[0] - q[0], A[1] - q[1], A[2] - q[2]};
    const double bb[3] = {B[0] - q[0], B[1] - q[1], B[2] - q[2]};
    const double cc[3] = {C[0] - q[0], C[1] - q[1], C[2] - q[2]};
    wind += solid_angle(a, bb, cc);
  }
  const bool inside = wind > 2.0 * kPi;  // winding number > ½
  const double d = std::sqrt(best);
  const double dir[3] = {q[0] - cbest[0], q[1] - cbest[1], q[2] - cbest[2]};
  const double s = d > 1e-300 ? (inside ? -1.0 : 1.0) / d : 0.0;
  for (int k = 0; k < 3; ++k) normal[k] = s * dir[k];
  if (d <= 1e-300) normal[0] = normal[1] = 0, normal[2] = 1;
  return inside ? -d : d;
}

/// Fibonacci points on the unit sphere's part with z ≥ z0 (z0 = −1: all of it).
template <class F>
void fibonacci(int n, double z0, F&& f) {
  const double golden = kPi * (3.0 - std::sqrt(5.0));
  for (int i = 0; i < n; ++i) {
    const double z = 1.0 - (1.0 - z0) * (i + 0.5) / n;
    const double r = std::sqrt(std::max(0.0, 1.0 - z * z)), phi = golden * i;
    f(r * std::cos(phi), r * std::sin(phi), z);
  }
}

}  // namespace

void fill_contact_spring(ContactSpring& sp, const double* n, double depth, bool speculative, double kc, double cc,
                         double mu, const double* rel, double v_stick, RigidContactOutput& out) {
  const double fmag = kc * depth;  // < 0 (pulling) for a speculative one: released if it ends so
  for (int a = 0; a < 3; ++a) {
    sp.force[a] = fmag * n[a];
    for (int b = 0; b < 3; ++b) {
      sp.K[3 * a + b] = kc * n[a] * n[b];
      sp.C[3 * a + b] = cc * n[a] * n[b];
    }
  }
  if (mu > 0 && fmag > 0) {  // regularised Coulomb on the sliding velocity (haptics/contact.cpp's rule)
    const double vn = dot3(rel, n);
    const double vt[3] = {rel[0] - vn * n[0], rel[1] - vn * n[1], rel[2] - vn * n[2]};
    const double ct = mu * fmag / std::max(norm3(vt), v_stick);
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b) sp.C[3 * a + b] += ct * ((a == b ? 1.0 : 0.0) - n[a] * n[b]);
  }
  if (!speculative) {
    out.energy += 0.5 * kc * depth * depth;
    out.max_depth = std::max(out.max_depth, depth);
  }
  ++out.contacts;
}

bool near_a_hole(const ContactExclusion& ex, const double* q) {
  for (int j = 0; j < ex.n_holes; ++j) {
    const double* hole = ex.holes + 3 * j;
    const double dq[3] = {q[0] - hole[0], q[1] - hole[1], q[2] - hole[2]};
    if (dot3(dq, dq) < ex.hole_radius * ex.hole_radius) return true;
  }
  return false;
}

bool add_tissue_body_spring(const SurfaceTriangleDofs& td, double b0, double b1, double b2, const RigidState& s,
                            int32_t row, const double* arm, const double* n, double gap, double kc, double cc,
                            double mu, double v_stick, const double* v, double h, const Vec3& g, double speed,
                            std::vector<ContactSpring>& springs, std::vector<RigidContactPair>& pairs,
                            RigidContactOutput& out) {
  ContactSpring sp;
  set_spring_point(td, b0, b1, b2, sp);
  double vq[3], vb[3], rel[3];
  spring_point(sp, v, vq);
  body_point_velocity(s, arm, vb);
  for (int k = 0; k < 3; ++k) rel[k] = vq[k] - vb[k];
  const bool speculative = gap >= 0;
  if (speculative && gap + h * std::min(dot3(rel, n), 0.0) - h * h * dot3(g.data(), n) * (row >= 0 ? 1.0 : 0.0) >= h * speed)
    return false;
  if (!reserve_contact(springs, pairs, gap, n)) {
    ++out.dropped;
    return false;
  }
  fill_contact_spring(sp, n, -gap, speculative, kc, cc, mu, rel, v_stick, out);
  sp.row_n = row;
  for (int k = 0; k < 3; ++k) sp.arm_n[k] = arm[k];
  springs.push_back(sp);
  return true;
}

double shape_distance(const RigidBodyModel& b, const double* p, double* normal) {
  const double q[3] = {p[0] - b.shape_origin[0], p[1] - b.shape_origin[1], p[2] - b.shape_origin[2]};
  switch (b.shape) {
    case RigidShape::Sphere:
    case RigidShape::Capsule: {
      const double h = b.shape == RigidShape::Capsule ? 0.5 * b.length : 0.0;
      const double d[3] = {q[0], q[1], q[2] - std::clamp(q[2], -h, h)};
      const double r = norm3(d);
      if (r > 1e-300)
        for (int k = 0; k < 3; ++k) normal[k] = d[k] / r;
      else
        normal[0] = 1, normal[1] = normal[2] = 0;
      return r - b.radius;
    }
    case RigidShape::Box: {
      double o[3], outside2 = 0, inside = -1e300;
      int axis = 0;
      for (int k = 0; k < 3; ++k) {
        o[k] = std::abs(q[k]) - 0.5 * b.size[size_t(k)];
        if (o[k] > 0) outside2 += o[k] * o[k];
        if (o[k] > inside) inside = o[k], axis = k;
      }
      if (outside2 > 0) {
        const double d = std::sqrt(outside2);
        for (int k = 0; k < 3; ++k) normal[k] = (o[k] > 0 ? o[k] : 0.0) * (q[k] < 0 ? -1.0 : 1.0) / d;
        return d;
      }
      normal[0] = normal[1] = normal[2] = 0;
      normal[axis] = q[axis] < 0 ? -1.0 : 1.0;
      return inside;
    }
    case RigidShape::Mesh: return mesh_distance(b, p, normal);
    case RigidShape::Needle: return needle_distance(b.needle, q, normal);
  }
  return 1e300;
}

void make_contact_samples(RigidBodyModel& b) {
  b.sample_points.clear();
  b.sample_normals.clear();
  b.sample_areas.clear();
  const Vec3 o = b.shape_origin;
  auto add = [&](double x, double y, double z, double nx, double ny, double nz, double area) {
    b.sample_points.push_back({o[0] + x, o[1] + y, o[2] + z});
    b.sample_normals.push_back({nx, ny, nz});
    b.sample_areas.push_back(area);
  };
  switch (b.shape) {
    case RigidShape::Sphere: {
      const int n = 256;
      const double r = b.radius, a = 4 * kPi * r * r / n;
      fibonacci(n, -1.0, [&](double x, double y, double z) { add(r * x, r * y, r * z, x, y, z, a); });
      b.bounding_radius = r;
      b.feature = r;
      break;
    }
    case RigidShape::Capsule: {
      const double r = b.radius, L = b.length;
      const int around = 24, along = std::clamp(static_cast<int>(std::ceil(L / (2 * kPi * r / around))), 1, 64);
      const double a = 2 * kPi * r * L / (around * along);
      for (int j = 0; j < along; ++j)
        for (int i = 0; i < around; ++i) {
          const double phi = 2 * kPi * (i + 0.5 * (j % 2)) / around, z = -0.5 * L + L * (j + 0.5) / along;
          add(r * std::cos(phi), r * std::sin(phi), z, std::cos(phi), std::sin(phi), 0, a);
        }
      const int cap = 64;
      const double ac = 2 * kPi * r * r / cap;
      for (const double s : {1.0, -1.0})
        fibonacci(cap, 0.0, [&](double x, double y, double z) { add(r * x, r * y, s * (0.5 * L + r * z), x, y, s * z, ac); });
      b.bounding_radius = 0.5 * L + r;
      b.feature = r;
      break;
    }
    case RigidShape::Box: {
      const double smin = std::min({b.size[0], b.size[1], b.size[2]});
      for (int axis = 0; axis < 3; ++axis) {
        const int u = (axis + 1) % 3, v = (axis + 2) % 3;
        const int nu = std::clamp(static_cast<int>(std::ceil(b.size[size_t(u)] / (0.25 * smin))), 2, 24);
        const int nv = std::clamp(static_cast<int>(std::ceil(b.size[size_t(v)] / (0.25 * smin))), 2, 24);
        const double a = b.size[size_t(u)] * b.size[size_t(v)] / (nu * nv);
        for (const double s : {1.0, -1.0})
          for (int i = 0; i < nu; ++i)
            for (int j = 0; j < nv; ++j) {
              double p[3], n[3] = {0, 0, 0};
              p[axis] = 0.5 * s * b.size[size_t(axis)];
              p[u] = b.size[size_t(u)] * ((i + 0.5) / nu - 0.5);
              p[v] = b.size[size_t(v)] * ((j + 0.5) / nv - 0.5);
              n[axis] = s;
              add(p[0], p[1], p[2], n[0], n[1], n[2], a);
            }
      }
      b.bounding_radius = 0.5 * std::sqrt(b.size[0] * b.size[0] + b.size[1] * b.size[1] + b.size[2] * b.size[2]);
      b.feature = 0.5 * smin;
      break;
    }
    case RigidShape::Needle: {  // rings around the wire along its curve, and its two caps
      const NeedleGeometry& g = b.needle;
      const double r = g.wire_radius;
      const int around = 12, along = std::clamp(static_cast<int>(std::ceil(g.length / (2 * kPi * r / around))), 1, 256);
      const double a = 2 * kPi * r * g.length / (around * along);
      b.bounding_radius = 0;
      for (int j = 0; j < along; ++j) {
        double c[3], t[3];
        needle_curve(g, g.length * (j + 0.5) / along, c, t);
        // Two unit vectors across the tangent.
        double u[3] = {t[1], -t[0], 0};
        if (std::abs(t[2]) > 0.9) u[0] = 1, u[1] = 0, u[2] = 0;
        const double un = norm3(u);
        for (double& x : u) x /= un;
        const double w[3] = {t[1] * u[2] - t[2] * u[1], t[2] * u[0] - t[0] * u[2], t[0] * u[1] - t[1] * u[0]};
        for (int i = 0; i < around; ++i) {
          const double phi = 2 * kPi * (i + 0.5 * (j % 2)) / around, cs = std::cos(phi), sn = std::sin(phi);
          const double n[3] = {cs * u[0] + sn * w[0], cs * u[1] + sn * w[1], cs * u[2] + sn * w[2]};
          add(c[0] + r * n[0], c[1] + r * n[1], c[2] + r * n[2], n[0], n[1], n[2], a);
        }
      }
      for (const double s : {0.0, g.length}) {
        double c[3], t[3];
        needle_curve(g, s, c, t);
        add(c[0] + (s > 0 ? r : -r) * t[0], c[1] + (s > 0 ? r : -r) * t[1], c[2] + (s > 0 ? r : -r) * t[2],
            s > 0 ? t[0] : -t[0], s > 0 ? t[1] : -t[1], s > 0 ? t[2] : -t[2], kPi * r * r);
      }
      for (const Vec3& p : b.sample_points) b.bounding_radius = std::max(b.bounding_radius, norm3(p.data()));
      b.feature = r;
      break;
    }
    case RigidShape::Mesh: {
      const size_t nv = b.surface_vertices.size();
      std::vector<Vec3> nrm(nv, Vec3{0, 0, 0});
      std::vector<double> area(nv, 0.0);
      double edges = 0;
      for (const Tri& t : b.surface_triangles) {
        const Vec3& A = b.surface_vertices[size_t(t[0])];
        const Vec3& B = b.surface_vertices[size_t(t[1])];
        const Vec3& C = b.surface_vertices[size_t(t[2])];
        const double e1[3] = {B[0] - A[0], B[1] - A[1], B[2] - A[2]}, e2[3] = {C[0] - A[0], C[1] - A[1], C[2] - A[2]};
        const double e3[3] = {C[0] - B[0], C[1] - B[1], C[2] - B[2]};
        const double cr[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
        const double ar = 0.5 * norm3(cr);
        edges += norm3(e1) + norm3(e2) + norm3(e3);
        for (const int32_t i : t) {
          area[size_t(i)] += ar / 3;
          for (int k = 0; k < 3; ++k) nrm[size_t(i)][size_t(k)] += 0.5 * cr[k];
        }
      }
      b.bounding_radius = 0;
      for (size_t i = 0; i < nv; ++i) {
        const Vec3& p = b.surface_vertices[i];
        const double l = norm3(nrm[i].data());
        const double s = l > 0 ? 1.0 / l : 0.0;
        b.sample_points.push_back(p);
        b.sample_normals.push_back({nrm[i][0] * s, nrm[i][1] * s, nrm[i][2] * s});
        b.sample_areas.push_back(area[i]);
        b.bounding_radius = std::max(b.bounding_radius, norm3(p.data()));
      }
      b.feature = b.surface_triangles.empty() ? b.bounding_radius : edges / (3.0 * b.surface_triangles.size());
      break;
    }
  }
  make_wire_samples(b);
}

void rigid_tissue_contact(const RigidBodyModel& b, const RigidState& s, int32_t row, const ContactSurface& surf,
                          const TriangleBvh& bvh, const double* x, const double* v, const uint8_t* constrained,
                          double h, const Vec3& g, std::vector<ContactSpring>& springs,
                          std::vector<RigidContactPair>& pairs, RigidContactOutput& out, const ContactExclusion& ex) {
  if (!b.wire_axis.empty())  // a needle: its wire samples the surface (rigid/wire_contact.hpp)
    return wire_tissue_contact(b, s, row, surf, bvh, x, v, h, g, springs, pairs, out, ex);
  const std::array<double, 9> R = rotation_of(s.q);
  const double speed = norm3(s.v.data()) + norm3(s.w.data()) * b.bounding_radius;
  const double reach = b.bounding_radius + 2.0 * h * speed + h * h * norm3(g.data()) + 0.25 * b.feature;
  const double v_stick = 0.01 * b.feature;
  bvh.query_sphere(s.x.data(), reach, x, [&](int32_t t) {
    if (surf.active && !surf.active[t]) return;
    if (row < 0 && constrained) {  // a fixed body against tissue held in place: nothing to do
      const SurfaceTriangleDofs& td = surf.dofs[size_t(t)];
      bool held = true;
      for (int a = 0; a < td.n && held; ++a) held = constrained[td.dof[a]] == 7;
      if (held) return;
    }
    const auto& tri = surf.triangles[size_t(t)];
    const double* p0 = x + 3 * tri[0];
    const double* p1 = x + 3 * tri[1];
    const double* p2 = x + 3 * tri[2];
    const double e1[3] = {p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2]};
    const double e2[3] = {p2[0] - p0[0], p2[1] - p0[1], p2[2] - p0[2]};
    const double cr[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
    const double twice_area = norm3(cr);
    if (twice_area <= 0) return;
    // The distance is 1-Lipschitz and every point of the triangle is within its longest edge of
    // a vertex: if the vertices are all farther than that (and the step's reach), skip it.
    {
      double dmin = 1e300;
      for (const double* p : {p0, p1, p2}) {
        double arm[3], pb[3], nb[3];
        for (int k = 0; k < 3; ++k) arm[k] = p[k] - s.x[size_t(k)];
        rot_t(R, arm, pb);
        dmin = std::min(dmin, shape_distance(b, pb, nb));
      }
      const double longest = std::max({norm3(e1), norm3(e2), std::sqrt((p2[0] - p1[0]) * (p2[0] - p1[0]) +
                                                                       (p1[1] - p2[1]) * (p1[1] - p2[1]) +
                                                                       (p2[2] - p1[2]) * (p2[2] - p1[2]))});
      if (dmin > longest + reach - b.bounding_radius) return;
    }
    const int ns = surface_samples_per_edge(surf, t, b.feature);
    const double area = 0.5 * twice_area / (ns * ns);
    const double kc = b.contact_stiffness * area, cc = b.contact_damping * area;
    // A block of samples whose centre is farther from the shape than its half-diagonal plus the
    // farthest a sample can be and still make a spring (the step's reach below, bounded with the
    // fastest of the triangle's DOFs) is skipped whole: the distance is 1-Lipschitz, so none of
    // its samples would pass. The same samples, in the same order, as without the test.
    // (Only triangles sampled in blocks need the bound: ns > kSampleBlock.)
    const double w_body = norm3(s.w.data());
    const bool can_cull = ns > kSampleBlock && h * w_body < 0.5;
    double v_tri = 0;
    if (can_cull) {
      const SurfaceTriangleDofs& td = surf.dofs[size_t(t)];
      for (int a = 0; a < td.n; ++a) v_tri = std::max(v_tri, norm3(v + 3 * td.dof[a]));
    }
    const double far = (h * (2.0 * speed + v_tri) + h * h * norm3(g.data())) / (1.0 - std::min(h * w_body, 0.5));
    const double diag = std::max(std::sqrt((e1[0] + e2[0]) * (e1[0] + e2[0]) + (e1[1] + e2[1]) * (e1[1] + e2[1]) +
                                           (e1[2] + e2[2]) * (e1[2] + e2[2])),
                                 std::sqrt((e1[0] - e2[0]) * (e1[0] - e2[0]) + (e1[1] - e2[1]) * (e1[1] - e2[1]) +
                                           (e1[2] - e2[2]) * (e1[2] - e2[2])));
    auto keep = [&](double u, double w, double half) {
      if (!can_cull) return true;
      double arm[3], pb[3], nb[3];
      for (int k = 0; k < 3; ++k) arm[k] = p0[k] + u * e1[k] + w * e2[k] - s.x[size_t(k)];
      rot_t(R, arm, pb);
      return shape_distance(b, pb, nb) - half * diag < far;
    };
    for_each_triangle_sample_culled(ns, keep, [&](double u, double w) {
      const double w0 = 1.0 - u - w;
      double q[3], arm[3], pb[3], nb[3], n[3];
      for (int k = 0; k < 3; ++k) {
        q[k] = w0 * p0[k] + u * p1[k] + w * p2[k];
        arm[k] = q[k] - s.x[size_t(k)];
      }
      if (near_a_hole(ex, q)) return;
      rot_t(R, arm, pb);
      const double d = shape_distance(b, pb, nb);
      rot(R, nb, n);
      // In front (d ≥ 0): made only within the step's reach (the approach predicted, the body's
      // fall included, or its own travel: light surface nodes it pushed ahead can rebound into it).
      add_tissue_body_spring(surf.dofs[size_t(t)], w0, u, w, s, row, arm, n, d, kc, cc, b.friction, v_stick, v, h, g,
                             speed, springs, pairs, out);
    });
  });
}

void rigid_rigid_contact(const RigidBodyModel& a, const RigidState& sa, int32_t row_a, const RigidBodyModel& b,
                         const RigidState& sb, int32_t row_b, double h, const Vec3& g,
                         std::vector<ContactSpring>& springs, std::vector<RigidContactPair>& pairs,
                         RigidContactOutput& out_a, RigidContactOutput& out_b) {
  const double dx[3] = {sa.x[0] - sb.x[0], sa.x[1] - sb.x[1], sa.x[2] - sb.x[2]};
  const double speed = norm3(sa.v.data()) + norm3(sb.v.data()) + norm3(sa.w.data()) * a.bounding_radius +
                       norm3(sb.w.data()) * b.bounding_radius;
  const double margin = 2.0 * h * speed + h * h * norm3(g.data());
  if (norm3(dx) > a.bounding_radius + b.bounding_radius + margin) return;
  const std::array<double, 9> Ra = rotation_of(sa.q), Rb = rotation_of(sb.q);
  const double k = std::min(a.contact_stiffness, b.contact_stiffness);
  const double c = std::min(a.contact_damping, b.contact_damping);
  const double mu = std::min(a.friction, b.friction);
  const double v_stick = 0.01 * std::min(a.feature, b.feature);
  const double fall = (row_a >= 0 ? 1.0 : 0.0) - (row_b >= 0 ? 1.0 : 0.0);  // a's point's fall relative to b's
  for (size_t i = 0; i < a.sample_points.size(); ++i) {
    double ra[3], p[3], rb[3], pb[3], nb[3], n[3];
    rot(Ra, a.sample_points[i].data(), ra);
    for (int k = 0; k < 3; ++k) {
      p[k] = sa.x[size_t(k)] + ra[k];
      rb[k] = p[k] - sb.x[size_t(k)];
    }
    rot_t(Rb, rb, pb);
    const double d = shape_distance(b, pb, nb);
    if (d > margin) continue;
    rot(Rb, nb, n);
    double va[3], vb[3], rel[3];
    body_point_velocity(sa, ra, va);
    body_point_velocity(sb, rb, vb);
    for (int q = 0; q < 3; ++q) rel[q] = va[q] - vb[q];
    const bool speculative = d >= 0;
    if (speculative && d + h * std::min(dot3(rel, n), 0.0) + h * h * dot3(g.data(), n) * fall >= h * speed) continue;
    if (springs.size() == springs.capacity() || (speculative && pairs.size() == pairs.capacity())) {
      ++out_a.dropped;
      continue;
    }
    if (speculative) {
      RigidContactPair pr;
      pr.spring = static_cast<int32_t>(springs.size());
      for (int q = 0; q < 3; ++q) pr.n[q] = row_a >= 0 ? n[q] : -n[q];
      pr.depth0 = -d;
      pairs.push_back(pr);
    }
    ContactSpring sp;
    sp.n = 0;
    const double area = a.sample_areas[i];
    if (row_a >= 0) {  // a's point is the positive side, b's the anchor (fixed when row_b < 0)
      fill_contact_spring(sp, n, -d, speculative, k * area, c * area, mu, rel, v_stick, out_a);
      sp.row_p = row_a;
      sp.row_n = row_b;
      for (int q = 0; q < 3; ++q) sp.arm_p[q] = ra[q], sp.arm_n[q] = rb[q];
    } else {  // a fixed: b's point is the positive side, pushed along −n, against a fixed anchor
      const double nn[3] = {-n[0], -n[1], -n[2]}, rr[3] = {-rel[0], -rel[1], -rel[2]};
      fill_contact_spring(sp, nn, -d, speculative, k * area, c * area, mu, rr, v_stick, out_b);
      sp.row_p = row_b;
      for (int q = 0; q < 3; ++q) sp.arm_p[q] = rb[q];
    }
    ++(row_a >= 0 ? out_b : out_a).contacts;
    springs.push_back(sp);
  }
}


void body_point_displacement(const RigidState& s0, const RigidState& s1, const double* a, double* d) {
  const std::array<double, 9> R0 = rotation_of(s0.q), R1 = rotation_of(s1.q);
  double body[3], now[3];
  rot_t(R0, a, body);
  rot(R1, body, now);
  for (int k = 0; k < 3; ++k) d[k] = s1.x[size_t(k)] - s0.x[size_t(k)] + now[k] - a[k];
}

void rigid_spring_force_after_step(const ContactSpring& sp, const double* x0, const double* x, const double* v,
                                   const RigidState* start, const RigidState* end, const int32_t* row_body,
                                   double* f) {
  // Each side's displacement and end velocity.
  double dp[3] = {0, 0, 0}, dn[3] = {0, 0, 0}, vp[3] = {0, 0, 0}, vn[3] = {0, 0, 0};
  auto body_side = [&](int32_t row, const double* arm, double* d, double* vel) {
    const int32_t b = row_body[row];
    body_point_displacement(start[b], end[b], arm, d);
    double now[3];  // the arm at the end
    for (int k = 0; k < 3; ++k) now[k] = arm[k] + d[k] - (end[b].x[size_t(k)] - start[b].x[size_t(k)]);
    body_point_velocity(end[b], now, vel);
  };
  if (sp.row_p >= 0) {
    body_side(sp.row_p, sp.arm_p, dp, vp);
  } else {
    double p0[3], p1[3];
    spring_point(sp, x0, p0);
    spring_point(sp, x, p1);
    spring_point(sp, v, vp);
    for (int k = 0; k < 3; ++k) dp[k] = p1[k] - p0[k];
  }
  if (sp.row_n >= 0) body_side(sp.row_n, sp.arm_n, dn, vn);
  double dr[3], vr[3];
  for (int k = 0; k < 3; ++k) dr[k] = dp[k] - dn[k], vr[k] = vp[k] - vn[k];
  for (int k = 0; k < 3; ++k)
    f[k] = sp.force[k] - (sp.K[3 * k] * dr[0] + sp.K[3 * k + 1] * dr[1] + sp.K[3 * k + 2] * dr[2]) -
           (sp.C[3 * k] * vr[0] + sp.C[3 * k + 1] * vr[1] + sp.C[3 * k + 2] * vr[2]);
}

void rigid_forces_after_step(const double* x0, const double* x, const double* v, const RigidState* start,
                             const RigidState* end, const int32_t* row_body, const ContactSpring* springs, int count,
                             RigidContactOutput* out, int bodies) {
  for (int b = 0; b < bodies; ++b) out[b].force = {0, 0, 0};
  for (int c = 0; c < count; ++c) {
    const ContactSpring& sp = springs[c];
    if (!spring_has_rows(sp)) continue;
    double f[3];
    rigid_spring_force_after_step(sp, x0, x, v, start, end, row_body, f);
    for (int k = 0; k < 3; ++k) {
      if (sp.row_p >= 0) out[row_body[sp.row_p]].force[size_t(k)] += f[k];
      if (sp.row_n >= 0) out[row_body[sp.row_n]].force[size_t(k)] -= f[k];
    }
  }
}

int release_pulling_rigid_contacts(const double* x0, const double* x, const RigidState* start, const RigidState* end,
                                   const int32_t* row_body, std::vector<RigidContactPair>& pairs,
                                   std::vector<ContactSpring>& springs) {
  int released = 0;
  for (RigidContactPair& pr : pairs) {
    if (!pr.active || pr.pinned) continue;
    ContactSpring& sp = springs[size_t(pr.spring)];
    double dp[3] = {0, 0, 0}, dn[3] = {0, 0, 0};  // the two sides' displacements
    if (sp.row_p >= 0) {
      const int32_t b = row_body[sp.row_p];
      body_point_displacement(start[b], end[b], sp.arm_p, dp);
    } else {
      double p0[3], p1[3];
      spring_point(sp, x0, p0);
      spring_point(sp, x, p1);
      for (int k = 0; k < 3; ++k) dp[k] = p1[k] - p0[k];
    }
    if (sp.row_n >= 0) {
      const int32_t b = row_body[sp.row_n];
      body_point_displacement(start[b], end[b], sp.arm_n, dn);
    }
    double depth = pr.depth0;
    for (int k = 0; k < 3; ++k) depth -= (dp[k] - dn[k]) * pr.n[k];
    if (depth >= 0) continue;
    pr.active = false;
    std::fill(std::begin(sp.force), std::end(sp.force), 0.0);
    std::fill(std::begin(sp.K), std::end(sp.K), 0.0);
    std::fill(std::begin(sp.C), std::end(sp.C), 0.0);
    ++released;
  }
  return released;
}

}  // namespace stroma
