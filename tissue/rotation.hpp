#pragma once
/// \file rotation.hpp
/// Per-element rotation extraction for the corotational formulation.
///
/// - `polar_rotation`: the rotation factor R of the polar decomposition F = R·S, computed
///   through a 3×3 SVD (cyclic Jacobi on FᵀF with a fixed number of sweeps, then a Gram–Schmidt
///   completion of U). For inverted elements (det F < 0) it returns the proper rotation of
///   Irving et al. 2004: the sign goes onto the smallest singular value, so R ∈ SO(3) always and
///   R maximises tr(RᵀF), i.e. it is the rotation nearest F. Fixed cost, no data-dependent loop.
/// - `qr_rotation`: SOFA's cheaper "large" frame from the first two edges of the tetrahedron.
///   Not the polar rotation (0.4–1.5 rad off under large shear) and it breaks the symmetry of a
///   symmetric body, but ~5× cheaper; offered for the run-time/error comparison.

#include <cmath>

#include "tissue/mat3.hpp"

namespace stroma {

namespace detail {

/// One Jacobi rotation in the (p, q) plane that zeroes S(p,q); accumulates V ← V·J.
/// Branch-free: a zero off-diagonal gives t = 0 (identity rotation).
template <int p, int q>
inline void jacobi_rotate(double* S, double* V) {
  constexpr int r = 3 - p - q;
  const double apq = S[3 * p + q];
  const double d = S[3 * q + q] - S[3 * p + p];
  const double hyp = std::sqrt(d * d + 4.0 * apq * apq);
  const double t = 2.0 * apq * std::copysign(1.0, d) / (std::fabs(d) + hyp + 1e-300);
  const double c = 1.0 / std::sqrt(1.0 + t * t);
  const double s = t * c;
  S[3 * p + p] -= t * apq;
  S[3 * q + q] += t * apq;
  S[3 * p + q] = S[3 * q + p] = 0.0;
  const double srp = S[3 * r + p], srq = S[3 * r + q];
  const double nrp = c * srp - s * srq;
  const double nrq = s * srp + c * srq;
  S[3 * r + p] = S[3 * p + r] = nrp;
  S[3 * r + q] = S[3 * q + r] = nrq;
  for (int i = 0; i < 3; ++i) {
    const double vp = V[3 * i + p], vq = V[3 * i + q];
    V[3 * i + p] = c * vp - s * vq;
    V[3 * i + q] = s * vp + c * vq;
  }
}

/// Swaps columns i, j of V (and eigenvalues) if ev[i] < ev[j]; negates one column to keep
/// det V = +1.
template <int i, int j>
inline void sort_pair(double* ev, double* V) {
  if (ev[i] < ev[j]) {
    const double t = ev[i];
    ev[i] = ev[j];
    ev[j] = t;
    for (int k = 0; k < 3; ++k) {
      const double a = V[3 * k + i];
      V[3 * k + i] = V[3 * k + j];
      V[3 * k + j] = -a;
    }
  }
}

}  // namespace detail

/// Number of cyclic Jacobi sweeps. Four sweeps drive the off-diagonal of FᵀF to round-off for
/// every 3×3 matrix tried (tests/test_rotation.cpp checks 1e-12 against Eigen's SVD).
inline constexpr int kPolarSweeps = 4;

/// Rotation of the polar decomposition of F (row-major 3×3), sign-corrected for inversion.
inline void polar_rotation(const double* F, double* R) {
  double S[9];
  m3::mul_tn(F, F, S);
  double V[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  for (int k = 0; k < kPolarSweeps; ++k) {
    detail::jacobi_rotate<0, 1>(S, V);
    detail::jacobi_rotate<0, 2>(S, V);
    detail::jacobi_rotate<1, 2>(S, V);
  }
  double ev[3] = {S[0], S[4], S[8]};
  detail::sort_pair<0, 1>(ev, V);
  detail::sort_pair<0, 2>(ev, V);
  detail::sort_pair<1, 2>(ev, V);

  // B = F·V; columns b1, b2 give u1, u2 by Gram–Schmidt; u3 = u1 × u2 makes det U = +1, which
  // leaves the sign of det F on the smallest singular value (Irving et al.).
  double B[9];
  m3::mul(F, V, B);
  double u1[3] = {B[0], B[3], B[6]};
  double b2[3] = {B[1], B[4], B[7]};
  const double scale2 = ev[0] + 1e-300;
  double n1 = m3::dot(u1, u1);
  if (n1 < 1e-24 * scale2 || n1 == 0.0) {  // F ≈ 0: any frame will do
    u1[0] = V[0]; u1[1] = V[3]; u1[2] = V[6];
    n1 = 1.0;
  }
  const double i1 = 1.0 / std::sqrt(n1);
  u1[0] *= i1; u1[1] *= i1; u1[2] *= i1;
  const double proj = m3::dot(u1, b2);
  double u2[3] = {b2[0] - proj * u1[0], b2[1] - proj * u1[1], b2[2] - proj * u1[2]};
  double n2 = m3::dot(u2, u2);
  if (n2 < 1e-24 * scale2 || n2 == 0.0) {  // element flattened to a line: pick any normal
    const double e[3] = {std::fabs(u1[0]) < 0.9 ? 1.0 : 0.0, std::fabs(u1[0]) < 0.9 ? 0.0 : 1.0, 0.0};
    m3::cross(e, u1, u2);
    n2 = m3::dot(u2, u2);
  }
  const double i2 = 1.0 / std::sqrt(n2);
  u2[0] *= i2; u2[1] *= i2; u2[2] *= i2;
  double u3[3];
  m3::cross(u1, u2, u3);
  const double U[9] = {u1[0], u2[0], u3[0], u1[1], u2[1], u3[1], u1[2], u2[2], u3[2]};
  m3::mul_nt(U, V, R);
}

/// Orthonormal frame (rows) from two edges: x along e1, z normal to the (e1, e2) plane.
inline void edge_frame(const double* e1, const double* e2, double* frame) {
  double x[3] = {e1[0], e1[1], e1[2]};
  const double ix = 1.0 / std::sqrt(m3::dot(x, x) + 1e-300);
  x[0] *= ix; x[1] *= ix; x[2] *= ix;
  double z[3];
  m3::cross(x, e2, z);
  const double iz = 1.0 / std::sqrt(m3::dot(z, z) + 1e-300);
  z[0] *= iz; z[1] *= iz; z[2] *= iz;
  double y[3];
  m3::cross(z, x, y);
  frame[0] = x[0]; frame[1] = x[1]; frame[2] = x[2];
  frame[3] = y[0]; frame[4] = y[1]; frame[5] = y[2];
  frame[6] = z[0]; frame[7] = z[1]; frame[8] = z[2];
}

/// SOFA-style "large" rotation: R = Frame(current edges)ᵀ · Frame(rest edges).
/// `rest_frame` is edge_frame of the rest edges; e1, e2 are the current edges x1−x0, x2−x0.
inline void qr_rotation(const double* rest_frame, const double* e1, const double* e2, double* R) {
  double cur[9];
  edge_frame(e1, e2, cur);
  m3::mul_tn(cur, rest_frame, R);
}

}  // namespace stroma
