#include "tissue/cut_blade.hpp"

#include <algorithm>
#include <cmath>

namespace stroma {

namespace {
Vec3 sub(const Vec3& a, const Vec3& b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
Vec3 cross(const Vec3& a, const Vec3& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
double dot(const Vec3& a, const Vec3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
}  // namespace

double segment_triangle(const Vec3& p, const Vec3& q, const Vec3& a, const Vec3& b, const Vec3& c) {
  // Möller–Trumbore, with a relative tolerance so crossings exactly on the triangle's edges or
  // at the segment's ends count.
  const Vec3 d = sub(q, p), e1 = sub(b, a), e2 = sub(c, a);
  const Vec3 h = cross(d, e2);
  const double det = dot(e1, h);
  const double scale = std::sqrt(dot(d, d) * dot(e1, e1) * dot(e2, e2));
  if (!(std::abs(det) > 1e-12 * scale)) return -1;  // parallel (in or beside the plane), or degenerate
  const double inv = 1.0 / det;
  const Vec3 s = sub(p, a);
  const double u = inv * dot(s, h);
  constexpr double kEps = 1e-12;
  if (u < -kEps || u > 1 + kEps) return -1;
  const Vec3 qv = cross(s, e1);
  const double v = inv * dot(d, qv);
  if (v < -kEps || u + v > 1 + kEps) return -1;
  const double t = inv * dot(e2, qv);
  if (t < -kEps || t > 1 + kEps) return -1;
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
      const double s = segment_triangle(p, q, t[0], t[1], t[2]);
      if (s < 0) continue;
      edge_cut[e] = std::clamp(s, kCutMinFraction, 1.0 - kCutMinFraction);
      ++cut;
      break;
    }
  }
  return cut;
}

}  // namespace stroma
