#pragma once
/// \file triangle_closest_point.hpp
/// Closest point of a triangle to a point, as barycentric weights, and its normal. Shared by the
/// visual-mesh mapping (vertices just outside the tetrahedra), body–body contact (vertex against
/// face) and a needle's contacts (rigid/).

#include <array>
#include <cmath>

#include "tissue/tet_mesh.hpp"

namespace stroma {

/// The normal (B − A) × (C − A) of triangle (A, B, C), 3 doubles each: counter-clockwise seen
/// from where it points; its length twice the area.
inline void triangle_normal(const double* A, const double* B, const double* C, double* n) {
  const double e1[3] = {B[0] - A[0], B[1] - A[1], B[2] - A[2]}, e2[3] = {C[0] - A[0], C[1] - A[1], C[2] - A[2]};
  n[0] = e1[1] * e2[2] - e1[2] * e2[1];
  n[1] = e1[2] * e2[0] - e1[0] * e2[2];
  n[2] = e1[0] * e2[1] - e1[1] * e2[0];
}

/// The unit normal of triangle (A, B, C) into n; false (n unusable) for a degenerate triangle.
inline bool triangle_unit_normal(const double* A, const double* B, const double* C, double* n) {
  triangle_normal(A, B, C, n);
  const double len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
  if (!(len > 0)) return false;
  for (int k = 0; k < 3; ++k) n[k] /= len;
  return true;
}

/// Closest point of triangle (a, b, c) to p, as weights of a, b, c: the Voronoi-region walk of
/// Ericson, Real-Time Collision Detection §5.1.5. Exact in the regions (weights 0 or 1 where
/// the point is a vertex or on an edge), so clamped weights are never negative.
inline std::array<double, 3> closest_on_triangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  auto sub = [](const Vec3& u, const Vec3& v) { return Vec3{u[0] - v[0], u[1] - v[1], u[2] - v[2]}; };
  auto dot = [](const Vec3& u, const Vec3& v) { return u[0] * v[0] + u[1] * v[1] + u[2] * v[2]; };
  const Vec3 ab = sub(b, a), ac = sub(c, a), ap = sub(p, a);
  const double d1 = dot(ab, ap), d2 = dot(ac, ap);
  if (d1 <= 0 && d2 <= 0) return {1, 0, 0};
  const Vec3 bp = sub(p, b);
  const double d3 = dot(ab, bp), d4 = dot(ac, bp);
  if (d3 >= 0 && d4 <= d3) return {0, 1, 0};
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) {
    const double v = d1 / (d1 - d3);
    return {1 - v, v, 0};
  }
  const Vec3 cp = sub(p, c);
  const double d5 = dot(ab, cp), d6 = dot(ac, cp);
  if (d6 >= 0 && d5 <= d6) return {0, 0, 1};
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) {
    const double w = d2 / (d2 - d6);
    return {1 - w, 0, w};
  }
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
    const double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    return {0, 1 - w, w};
  }
  const double denom = 1 / (va + vb + vc);
  const double v = vb * denom, w = vc * denom;
  return {1 - v - w, v, w};
}

/// Point c against triangle t (corners A, B, C; unit normal nrm): if the triangle's closest point
/// is nearer than best_d2 (squared), it becomes the best — best_d2, best_tri and its barycentric
/// weights best_w[3] updated. The distance to the plane rules most triangles out before the
/// closest point is computed. (Samples against the surface: a needle's wire, a thread.)
inline void keep_closer_on_triangle(const double* c, const double* A, const double* B, const double* C,
                                    const double* nrm, int32_t t, double& best_d2, int32_t& best_tri, double* best_w) {
  const double hgt = (c[0] - A[0]) * nrm[0] + (c[1] - A[1]) * nrm[1] + (c[2] - A[2]) * nrm[2];
  if (hgt * hgt >= best_d2) return;
  const std::array<double, 3> w = closest_on_triangle(Vec3{c[0], c[1], c[2]}, Vec3{A[0], A[1], A[2]},
                                                      Vec3{B[0], B[1], B[2]}, Vec3{C[0], C[1], C[2]});
  double d2 = 0;
  for (int k = 0; k < 3; ++k) {
    const double q = w[0] * A[k] + w[1] * B[k] + w[2] * C[k] - c[k];
    d2 += q * q;
  }
  if (d2 >= best_d2) return;
  best_d2 = d2;
  best_tri = t;
  for (int k = 0; k < 3; ++k) best_w[k] = w[size_t(k)];
}

}  // namespace stroma
