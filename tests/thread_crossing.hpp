#pragma once
/// \file thread_crossing.hpp
/// The threads tests' independent continuous check: whether two segments moving linearly over
/// a tick pass through each other, and how many pairs of a model's threads did.

#include <cmath>
#include <cstdint>
#include <vector>

#include "engine/model.hpp"

namespace stroma::test_support {

/// Whether segments a and b (end points at the start, a0/a1/b0/b1, and at the end of a tick,
/// A0/A1/B0/B1, moving linearly between) pass through each other during the tick: where the four
/// points are coplanar (the triple product's sign changes, bisected over 64 sub-intervals), the
/// two segments intersect in that plane (each one's end points on opposite sides of the other).
inline bool segments_pass(const double* a0, const double* a1, const double* b0, const double* b1, const double* A0,
                   const double* A1, const double* B0, const double* B1) {
  auto at = [](const double* p, const double* P, double t, double* q) {
    for (int k = 0; k < 3; ++k) q[k] = p[k] + t * (P[k] - p[k]);
  };
  auto sub = [](const double* p, const double* q, double* r) {
    for (int k = 0; k < 3; ++k) r[k] = p[k] - q[k];
  };
  auto cross = [](const double* u, const double* v, double* c) {
    c[0] = u[1] * v[2] - u[2] * v[1];
    c[1] = u[2] * v[0] - u[0] * v[2];
    c[2] = u[0] * v[1] - u[1] * v[0];
  };
  auto dot = [](const double* u, const double* v) { return u[0] * v[0] + u[1] * v[1] + u[2] * v[2]; };
  auto triple = [&](double t) {
    double p0[3], p1[3], q0[3], q1[3], u[3], v[3], z[3], c[3];
    at(a0, A0, t, p0), at(a1, A1, t, p1), at(b0, B0, t, q0), at(b1, B1, t, q1);
    sub(p1, p0, u), sub(q0, p0, v), sub(q1, p0, z);
    cross(u, v, c);
    return dot(c, z);
  };
  auto intersect = [&](double t) {
    double p0[3], p1[3], q0[3], q1[3], u[3], v[3], n[3], d[3], c[3];
    at(a0, A0, t, p0), at(a1, A1, t, p1), at(b0, B0, t, q0), at(b1, B1, t, q1);
    sub(p1, p0, u), sub(q1, q0, v);
    cross(u, v, n);
    if (dot(n, n) < 1e-30) return false;  // parallel: no crossing to speak of
    auto side = [&](const double* e, const double* o, const double* p) {
      sub(p, o, d);
      cross(e, d, c);
      return dot(c, n);
    };
    return side(u, p0, q0) * side(u, p0, q1) <= 0 && side(v, q0, p0) * side(v, q0, p1) <= 0;
  };
  constexpr int kSub = 64;
  double f0 = triple(0);
  for (int i = 1; i <= kSub; ++i) {
    const double t1 = double(i) / kSub;
    const double f1 = triple(t1);
    if (f0 == 0 || (f0 < 0) != (f1 < 0)) {
      double lo = double(i - 1) / kSub, hi = t1, flo = f0;
      for (int it = 0; it < 50; ++it) {
        const double mid = 0.5 * (lo + hi), fm = triple(mid);
        if ((fm < 0) == (flo < 0) && fm != 0) lo = mid, flo = fm;
        else hi = mid;
      }
      if (intersect(0.5 * (lo + hi))) return true;
    }
    f0 = f1;
  }
  return false;
}


/// Pass-throughs over one tick (x0 → x) among every pair of segments of every thread sharing
/// no node (segments_pass). Pairs whose swept bounding spheres (the start's midpoint, its
/// half-length plus its farther node's displacement) are apart cannot meet and are skipped.
inline int count_passes(const Model& m, const std::vector<double>& x0, const double* x) {
  struct Seg {
    int32_t i;
    double c[3], r;
  };
  std::vector<Seg> seg;
  for (const RodRange& r : m.fem.rods)
    for (int32_t i = r.node_begin; i + 1 < r.node_end; ++i) {
      Seg sg{i, {0, 0, 0}, 0};
      double l2 = 0, m0 = 0, m1 = 0;
      for (int k = 0; k < 3; ++k) {
        const double a = x0[size_t(3 * i + k)], b = x0[size_t(3 * i + 3 + k)];
        sg.c[k] = 0.5 * (a + b);
        l2 += (b - a) * (b - a);
        m0 += (x[3 * i + k] - a) * (x[3 * i + k] - a);
        m1 += (x[3 * i + 3 + k] - b) * (x[3 * i + 3 + k] - b);
      }
      sg.r = 0.5 * std::sqrt(l2) + std::sqrt(std::max(m0, m1));
      seg.push_back(sg);
    }
  int passes = 0;
  for (size_t p = 0; p < seg.size(); ++p)
    for (size_t q = p + 1; q < seg.size(); ++q) {
      const int32_t i = seg[p].i, j = seg[q].i;
      if (j - i < 2) continue;  // neighbours on one rod share a node (no two rods' nodes adjoin)
      double d2 = 0;
      for (int k = 0; k < 3; ++k) d2 += (seg[p].c[k] - seg[q].c[k]) * (seg[p].c[k] - seg[q].c[k]);
      if (d2 > (seg[p].r + seg[q].r) * (seg[p].r + seg[q].r)) continue;
      passes += segments_pass(&x0[size_t(3 * i)], &x0[size_t(3 * i + 3)], &x0[size_t(3 * j)], &x0[size_t(3 * j + 3)],
                              x + 3 * i, x + 3 * i + 3, x + 3 * j, x + 3 * j + 3);
    }
  return passes;
}

}  // namespace stroma::test_support
