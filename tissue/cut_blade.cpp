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

int cut_edges(const double* x, const TetAdjacency& adj, const SweptBlade& blade, std::vector<double>& edge_cut) {
  const Vec3 tri[2][3] = {{blade.a0, blade.b0, blade.b1}, {blade.a0, blade.b1, blade.a1}};
  Vec3 lo = blade.a0, hi = blade.a0;
  for (const Vec3& p : {blade.b0, blade.a1, blade.b1})
    for (int k = 0; k < 3; ++k) {
      lo[k] = std::min(lo[k], p[k]);
      hi[k] = std::max(hi[k], p[k]);
    }
  int cut = 0;
  for (size_t e = 0; e < adj.edges.size(); ++e) {
    if (edge_cut[e] >= 0) continue;
    const double* pa = x + 3 * static_cast<size_t>(adj.edges[e][0]);
    const double* pb = x + 3 * static_cast<size_t>(adj.edges[e][1]);
    bool outside = false;  // the edge's box misses the blade's
    for (int k = 0; k < 3 && !outside; ++k)
      outside = std::max(pa[k], pb[k]) < lo[k] || std::min(pa[k], pb[k]) > hi[k];
    if (outside) continue;
    const Vec3 p{pa[0], pa[1], pa[2]}, q{pb[0], pb[1], pb[2]};
    for (const auto& t : tri) {
      const double s = edge_crossing(p, q, t[0], t[1], t[2]);
      if (s < 0) continue;
      edge_cut[e] = std::clamp(s, kCutMinFraction, 1.0 - kCutMinFraction);
      ++cut;
      break;
    }
  }
  return cut;
}

}  // namespace stroma
