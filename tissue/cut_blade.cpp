#include "tissue/cut_blade.hpp"

#include <algorithm>
#include <cmath>

#include "tissue/vec3.hpp"

namespace stroma {

namespace {
using v3::cross;
using v3::dot;
using v3::sub;
}  // namespace

double edge_crossing(const Vec3& p, const Vec3& q, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 n = cross(sub(b, a), sub(c, a));
  if (!(dot(n, n) > 0)) return -1;  // a degenerate (or non-finite) triangle cuts nothing
  // Sides of the plane, a point on it counting as the positive side: a node is on one side of
  // the blade, never both, so a blade through a node does not cut it out of its neighbours.
  const double sp = dot(n, sub(p, a)), sq = dot(n, sub(q, a));
  if ((sp >= 0) == (sq >= 0)) return -1;
  const double t = sp / (sp - sq);  // sp, sq of opposite signs: t ∈ [0, 1]
  const Vec3 x{p[0] + t * (q[0] - p[0]), p[1] + t * (q[1] - p[1]), p[2] + t * (q[2] - p[2])};
  // Inside the triangle (its edges included): the three edge functions agree with n.
  constexpr double kEps = 1e-12;
  const double nn = dot(n, n);
  const Vec3* v[3] = {&a, &b, &c};
  for (int i = 0; i < 3; ++i) {
    const Vec3& u = *v[i];
    const Vec3& w = *v[(i + 1) % 3];
    if (dot(cross(sub(w, u), sub(x, u)), n) < -kEps * nn) return -1;
  }
  return std::clamp(t, 0.0, 1.0);
}

namespace {

/// Whether x lies in triangle (a, b, c) (its edges included), x on the triangle's plane.
bool in_triangle(const Vec3& x, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 n = cross(sub(b, a), sub(c, a));
  const double nn = dot(n, n);
  if (!(nn > 0)) return false;
  constexpr double kEps = 1e-12;
  const Vec3* v[3] = {&a, &b, &c};
  for (int i = 0; i < 3; ++i) {
    const Vec3& u = *v[i];
    const Vec3& w = *v[(i + 1) % 3];
    if (dot(cross(sub(w, u), sub(x, u)), n) < -kEps * nn) return false;
  }
  return true;
}

}  // namespace

int cut_edges(const double* x, const TetAdjacency& adj, const std::vector<std::array<int32_t, 2>>& edge_points,
              const SweptBlade& blade, std::vector<double>& edge_cut, const double* min_fraction) {
  // One side function for the whole swept quad (its mean plane: normal from the diagonals,
  // through the centroid), so every node has one side this tick — the two triangles' own planes
  // disagree in the last bit for a node on them, which split a node's edges between the sides
  // and left the cut bridged (measured: a beam mesh with nodes on the blade's plane).
  const Vec3 n = cross(sub(blade.b1, blade.a0), sub(blade.a1, blade.b0));
  if (!(dot(n, n) > 0)) return 0;  // a blade that did not move (or degenerate): nothing swept
  Vec3 c;
  for (int k = 0; k < 3; ++k) c[k] = 0.25 * (blade.a0[k] + blade.b0[k] + blade.a1[k] + blade.b1[k]);
  Vec3 lo = blade.a0, hi = blade.a0;
  for (const Vec3& p : {blade.b0, blade.a1, blade.b1})
    for (int k = 0; k < 3; ++k) {
      lo[k] = std::min(lo[k], p[k]);
      hi[k] = std::max(hi[k], p[k]);
    }
  int cut = 0;
  for (size_t e = 0; e < adj.edges.size(); ++e) {
    if (edge_cut[e] >= 0) continue;
    const double* pa = x + 3 * static_cast<size_t>(edge_points[e][0]);
    const double* pb = x + 3 * static_cast<size_t>(edge_points[e][1]);
    bool outside = false;  // the edge's box misses the blade's
    for (int k = 0; k < 3 && !outside; ++k)
      outside = std::max(pa[k], pb[k]) < lo[k] || std::min(pa[k], pb[k]) > hi[k];
    if (outside) continue;
    const Vec3 p{pa[0], pa[1], pa[2]}, q{pb[0], pb[1], pb[2]};
    // Sides of the plane, a point on it counting as the side n points to: a node is on one side
    // of the blade, never both, so a blade through a node does not cut it out of its neighbours.
    const double sp = dot(n, sub(p, c)), sq = dot(n, sub(q, c));
    if ((sp >= 0) == (sq >= 0)) continue;
    const double t = sp / (sp - sq);
    Vec3 xc;
    for (int k = 0; k < 3; ++k) xc[k] = p[k] + t * (q[k] - p[k]);
    // Within the swept quad: its projection onto the mean plane lies in one of its triangles.
    const double off = dot(n, sub(xc, c)) / dot(n, n);
    for (int k = 0; k < 3; ++k) xc[k] -= off * n[k];
    if (!in_triangle(xc, blade.a0, blade.b0, blade.b1) && !in_triangle(xc, blade.a0, blade.b1, blade.a1)) continue;
    const double f = min_fraction ? min_fraction[e] : kCutMinFraction;
    edge_cut[e] = std::clamp(t, f, 1.0 - f);
    ++cut;
  }
  return cut;
}

BladeStep blade_step(const Vec3& last_a, const Vec3& last_b, const Vec3& a, const Vec3& b, const double normal[3],
                     const double forward[3], double half_thickness) {
  BladeStep st;
  Vec3 pa = last_a, pb = last_b;
  double sideways = 0, ahead = 0;
  for (int i = 0; i < 3; ++i) sideways += 0.5 * (a[i] + b[i] - pa[i] - pb[i]) * normal[i];
  for (int i = 0; i < 3; ++i) {
    pa[i] += sideways * normal[i];
    pb[i] += sideways * normal[i];
    st.travel[i] = 0.5 * (a[i] + b[i] - pa[i] - pb[i]);
    st.travel_len2 += st.travel[i] * st.travel[i];
    ahead += st.travel[i] * forward[i];
  }
  Vec3 a0 = pa, b0 = pb;
  if (st.travel_len2 > 0) {
    const double back = std::max(half_thickness / std::sqrt(st.travel_len2), 0.5);
    for (int i = 0; i < 3; ++i) {
      a0[i] -= back * st.travel[i];
      b0[i] -= back * st.travel[i];
    }
  }
  st.sweep = SweptBlade{a0, b0, a, b};
  st.forward = ahead > 0;
  return st;
}

Vec3 cut_resistance(int edges, double edges_per_area, double toughness, const Vec3& travel, double travel_len2) {
  Vec3 f{0, 0, 0};
  if (edges <= 0 || toughness <= 0 || edges_per_area <= 0 || travel_len2 <= 0) return f;
  const double area = edges / edges_per_area;
  const double len = std::sqrt(travel_len2);
  for (int i = 0; i < 3; ++i) f[i] = -toughness * area / len * (travel[i] / len);
  return f;
}

}  // namespace stroma
