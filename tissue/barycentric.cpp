#include "tissue/barycentric.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "tissue/mat3.hpp"

namespace stroma {

std::array<double, 4> barycentric_coordinates(const TetMesh& mesh, const Tet& t, const Vec3& p) {
  const Vec3& a = mesh.nodes[t[0]];
  double D[9], Di[9];
  for (int c = 0; c < 3; ++c)
    for (int r = 0; r < 3; ++r) D[3 * r + c] = mesh.nodes[t[c + 1]][r] - a[r];
  m3::inverse(D, Di);
  const double d[3] = {p[0] - a[0], p[1] - a[1], p[2] - a[2]};
  double l[3];
  m3::mulv(Di, d, l);
  return {1.0 - l[0] - l[1] - l[2], l[0], l[1], l[2]};
}

namespace {

/// Closest point of tetrahedron t to p, by projected-gradient iterations on the barycentric
/// simplex (exact enough for locating probes; load time only).
std::array<double, 4> clamp_to_tet(const TetMesh& mesh, const Tet& t, const Vec3& p) {
  // Minimise |Σ w_k x_k − p|² over the simplex with a few Frank–Wolfe-free projected steps:
  // simple and robust: search over faces/edges/vertices via brute force of sub-simplices.
  double best = std::numeric_limits<double>::max();
  std::array<double, 4> best_w{1, 0, 0, 0};
  // Enumerate all non-empty subsets of the 4 vertices; project onto their affine hull and
  // keep projections with non-negative weights.
  for (int mask = 1; mask < 16; ++mask) {
    int idx[4], k = 0;
    for (int i = 0; i < 4; ++i)
      if (mask & (1 << i)) idx[k++] = i;
    std::array<double, 4> w{0, 0, 0, 0};
    const Vec3& o = mesh.nodes[t[idx[0]]];
    if (k == 1) {
      w[idx[0]] = 1;
    } else {
      // Solve the normal equations G λ = r for edges e_j = x_idx[j] − o.
      double E[3][3] = {}, G[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1}, r[3] = {0, 0, 0};
      const int m = k - 1;
      for (int j = 0; j < m; ++j)
        for (int c = 0; c < 3; ++c) E[j][c] = mesh.nodes[t[idx[j + 1]]][c] - o[c];
      for (int i = 0; i < m; ++i) {
        for (int j = 0; j < m; ++j) G[3 * i + j] = m3::dot(E[i], E[j]);
        const double d[3] = {p[0] - o[0], p[1] - o[1], p[2] - o[2]};
        r[i] = m3::dot(E[i], d);
      }
      double Gi[9], lam[3];
      if (std::fabs(m3::inverse(G, Gi)) < 1e-300) continue;
      m3::mulv(Gi, r, lam);
      double sum = 0;
      bool ok = true;
      for (int j = 0; j < m; ++j) {
        if (lam[j] < 0) ok = false;
        w[idx[j + 1]] = lam[j];
        sum += lam[j];
      }
      if (!ok || sum > 1) continue;
      w[idx[0]] = 1 - sum;
    }
    double q[3] = {0, 0, 0};
    for (int i = 0; i < 4; ++i)
      for (int c = 0; c < 3; ++c) q[c] += w[i] * mesh.nodes[t[i]][c];
    const double d2 = (q[0] - p[0]) * (q[0] - p[0]) + (q[1] - p[1]) * (q[1] - p[1]) +
                      (q[2] - p[2]) * (q[2] - p[2]);
    if (d2 < best) {
      best = d2;
      best_w = w;
    }
  }
  return best_w;
}

}  // namespace

BarycentricPoint locate_point(const TetMesh& mesh, const Vec3& p) {
  BarycentricPoint best;
  double best_min = -std::numeric_limits<double>::max();
  // Inside test with a tolerance relative to the weights: the tet maximising the smallest
  // weight contains p if that weight is ≥ −1e-9.
  for (size_t e = 0; e < mesh.tets.size(); ++e) {
    const auto w = barycentric_coordinates(mesh, mesh.tets[e], p);
    const double mn = *std::min_element(w.begin(), w.end());
    if (mn > best_min) {
      best_min = mn;
      best.tet = static_cast<int32_t>(e);
      best.w = w;
    }
  }
  best.node = mesh.tets[best.tet];
  if (best_min >= -1e-9) return best;
  // Outside: nearest tetrahedron by true distance.
  double best_d = std::numeric_limits<double>::max();
  for (size_t e = 0; e < mesh.tets.size(); ++e) {
    const auto w = clamp_to_tet(mesh, mesh.tets[e], p);
    double q[3] = {0, 0, 0};
    for (int i = 0; i < 4; ++i)
      for (int c = 0; c < 3; ++c) q[c] += w[i] * mesh.nodes[mesh.tets[e][i]][c];
    const double d = std::sqrt((q[0] - p[0]) * (q[0] - p[0]) + (q[1] - p[1]) * (q[1] - p[1]) +
                               (q[2] - p[2]) * (q[2] - p[2]));
    if (d < best_d) {
      best_d = d;
      best.tet = static_cast<int32_t>(e);
      best.w = w;
    }
  }
  best.node = mesh.tets[best.tet];
  best.distance = best_d;
  return best;
}

}  // namespace stroma
