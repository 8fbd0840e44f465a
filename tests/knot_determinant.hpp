#pragma once
/// \file knot_determinant.hpp
/// The knot tests' independent topological check: the determinant of the knot an open thread
/// makes once its ends are joined far away — 1 for the unknot, 3 for the trefoil (an overhand
/// knot, a half knot round a rod), 9 for a square or a granny knot (3 × 3: a connected sum).
/// A knot invariant: a thread that passed through itself, or a knot that came undone, changes it.

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

namespace stroma::test_support {

/// |det| of the Fox colouring matrix (less a row and a column) of the projection of the polyline
/// `x` closed outside a ball round it — each end out radially from the centroid to `far`, joined
/// along that sphere (any arc outside the ball gives the same knot) — along a direction drawn
/// from `seed` (a generic one: the determinant is the knot's, whatever the projection). Each
/// crossing (over strand o, under strand entering u₁ and leaving u₂) gives the row 2·o − u₁ − u₂.
/// −1 if that projection is degenerate (a glancing crossing, or one at a vertex): take another.
inline int knot_determinant(const std::vector<std::array<double, 3>>& x, uint64_t seed, double far = 0.2) {
  using P3 = std::array<double, 3>;
  auto norm = [](P3 v) {
    const double n = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    return n > 0 ? P3{v[0] / n, v[1] / n, v[2] / n} : v;
  };
  P3 c{0, 0, 0};
  for (const P3& p : x)
    for (int k = 0; k < 3; ++k) c[size_t(k)] += p[size_t(k)] / double(x.size());
  const P3 da = norm({x.back()[0] - c[0], x.back()[1] - c[1], x.back()[2] - c[2]});
  const P3 db = norm({x.front()[0] - c[0], x.front()[1] - c[1], x.front()[2] - c[2]});
  P3 mid{da[0] + db[0], da[1] + db[1], da[2] + db[2]};
  if (std::sqrt(mid[0] * mid[0] + mid[1] * mid[1] + mid[2] * mid[2]) < 1e-6)  // opposite ends
    mid = {da[1] * 0.1 - da[2] * 0.9, da[2] * 0.3 - da[0] * 0.1, da[0] * 0.9 - da[1] * 0.3};
  mid = norm(mid);
  std::vector<P3> poly = x;
  for (int leg = 0; leg < 2; ++leg)
    for (int i = 0; i <= 8; ++i) {
      const double t = i / 8.0;
      const P3& p = leg == 0 ? da : mid;
      const P3& q = leg == 0 ? mid : db;
      const P3 v = norm({(1 - t) * p[0] + t * q[0], (1 - t) * p[1] + t * q[1], (1 - t) * p[2] + t * q[2]});
      poly.push_back({c[0] + far * v[0], c[1] + far * v[1], c[2] + far * v[2]});
    }
  // A random rotation (a uniform unit quaternion); project on its first two axes, depth the third.
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g;
  double q[4], qn = 0;
  for (double& e : q) e = g(rng), qn += e * e;
  for (double& e : q) e /= std::sqrt(qn);
  const double w = q[0], a = q[1], b = q[2], d = q[3];
  const double R[9] = {1 - 2 * (b * b + d * d), 2 * (a * b - d * w), 2 * (a * d + b * w),
                       2 * (a * b + d * w),     1 - 2 * (a * a + d * d), 2 * (b * d - a * w),
                       2 * (a * d - b * w),     2 * (b * d + a * w),     1 - 2 * (a * a + b * b)};
  const size_t n = poly.size();
  std::vector<P3> Q(n);
  for (size_t i = 0; i < n; ++i)
    for (int r = 0; r < 3; ++r)
      Q[i][size_t(r)] = R[3 * r] * poly[i][0] + R[3 * r + 1] * poly[i][1] + R[3 * r + 2] * poly[i][2];
  struct Crossing {
    double over, under;  // parameters along the closed curve (segment index + fraction)
  };
  std::vector<Crossing> cross;
  for (size_t i = 0; i < n; ++i)
    for (size_t j = i + 2; j < n; ++j) {
      if (i == 0 && j == n - 1) continue;  // neighbours across the closure
      const P3 &A = Q[i], &B = Q[(i + 1) % n], &C = Q[j], &D = Q[(j + 1) % n];
      const double r0 = B[0] - A[0], r1 = B[1] - A[1], s0 = D[0] - C[0], s1 = D[1] - C[1];
      const double den = r0 * s1 - r1 * s0;
      if (den == 0) continue;
      const double qp0 = C[0] - A[0], qp1 = C[1] - A[1];
      const double t = (qp0 * s1 - qp1 * s0) / den, u = (qp0 * r1 - qp1 * r0) / den;
      if (!(t >= 0 && t < 1 && u >= 0 && u < 1)) continue;
      // A glancing crossing (the projected segments within ~0.06° of parallel) or one at a vertex
      // is where rounding can misplace a crossing: no diagram from this projection.
      const double sine = den / std::sqrt((r0 * r0 + r1 * r1) * (s0 * s0 + s1 * s1));
      if (std::abs(sine) < 1e-3 || t < 1e-9 || u < 1e-9 || t > 1 - 1e-9 || u > 1 - 1e-9) return -1;
      const double zi = A[2] + t * (B[2] - A[2]), zj = C[2] + u * (D[2] - C[2]);
      if (zi > zj) cross.push_back({double(i) + t, double(j) + u});
      else cross.push_back({double(j) + u, double(i) + t});
    }
  const size_t m = cross.size();
  if (m < 2) return 1;
  std::vector<double> unders(m);
  for (size_t k = 0; k < m; ++k) unders[k] = cross[k].under;
  std::sort(unders.begin(), unders.end());
  // Arc k runs from the (k−1)-th under-crossing to the k-th (arc 0 wraps round the closure).
  auto arc_of = [&](double s) { return size_t(std::upper_bound(unders.begin(), unders.end(), s) - unders.begin()) % m; };
  std::vector<double> M(m * m, 0.0);
  for (size_t row = 0; row < m; ++row) {
    const size_t k = size_t(std::lower_bound(unders.begin(), unders.end(), cross[row].under) - unders.begin());
    M[row * m + arc_of(cross[row].over)] += 2;
    M[row * m + k] -= 1;
    M[row * m + (k + 1) % m] -= 1;
  }
  // The determinant of the leading (m − 1) minor, by Gaussian elimination with partial pivoting.
  const size_t s = m - 1;
  double det = 1;
  for (size_t col = 0; col < s; ++col) {
    size_t piv = col;
    for (size_t r = col + 1; r < s; ++r)
      if (std::abs(M[r * m + col]) > std::abs(M[piv * m + col])) piv = r;
    if (M[piv * m + col] == 0) return 0;
    if (piv != col) {
      for (size_t k = 0; k < s; ++k) std::swap(M[piv * m + k], M[col * m + k]);
      det = -det;
    }
    det *= M[col * m + col];
    for (size_t r = col + 1; r < s; ++r) {
      const double f = M[r * m + col] / M[col * m + col];
      for (size_t k = col; k < s; ++k) M[r * m + k] -= f * M[col * m + k];
    }
  }
  return static_cast<int>(std::lround(std::abs(det)));
}

}  // namespace stroma::test_support
