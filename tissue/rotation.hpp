#pragma once
/// \file rotation.hpp
/// Per-element rotation extraction for the corotational formulation.
///
/// - `polar_rotation`: the rotation factor R of the polar decomposition F = R·S. Where det F > 0
///   by Newton's polar iteration (a few steps; the usual case), else — and where Newton has not
///   converged in kPolarNewtonSteps — through a 3×3 SVD (cyclic Jacobi on FᵀF with a fixed
///   number of sweeps, then a Gram–Schmidt completion of U). For inverted elements (det F < 0)
///   it returns the proper rotation of Irving et al. 2004: the sign goes onto the smallest
///   singular value, so R ∈ SO(3) always and R maximises tr(RᵀF), i.e. it is the rotation
///   nearest F. Batched, the path is chosen per batch: one inverted element sends its batch
///   through the SVD (the two agree to round-off).
/// - `qr_rotation`: SOFA's cheaper "large" frame from the first two edges of the tetrahedron.
///   Not the polar rotation (0.4–1.5 rad off under large shear) and it breaks the symmetry of a
///   symmetric body, but ~5× cheaper; offered for the run-time/error comparison.

#include <algorithm>
#include <cmath>

#include "tissue/mat3.hpp"

namespace stroma {

namespace detail {

/// One Jacobi rotation in the (p, q) plane that zeroes S(p,q) in every lane, accumulating
/// V ← V·J. Branch-free: a zero off-diagonal gives t = 0 (identity rotation). Arrays are
/// structure-of-arrays, [entry][lane], so the lane loop vectorises (W doubles per instruction).
template <int p, int q, int W>
inline void jacobi_rotate(double (&S)[9][W], double (&V)[9][W]) {
  constexpr int r = 3 - p - q;
#pragma omp simd
  for (int l = 0; l < W; ++l) {
    const double apq = S[3 * p + q][l];
    const double d = S[3 * q + q][l] - S[3 * p + p][l];
    const double hyp = std::sqrt(d * d + 4.0 * apq * apq);
    // t = tan θ of the classical Jacobi rotation, written without dividing by apq.
    const double t = 2.0 * apq * (d >= 0.0 ? 1.0 : -1.0) / (std::fabs(d) + hyp + 1e-300);
    const double c = 1.0 / std::sqrt(1.0 + t * t);
    const double s = t * c;
    S[3 * p + p][l] -= t * apq;
    S[3 * q + q][l] += t * apq;
    S[3 * p + q][l] = 0.0;
    S[3 * q + p][l] = 0.0;
    const double srp = S[3 * r + p][l], srq = S[3 * r + q][l];
    const double nrp = c * srp - s * srq;
    const double nrq = s * srp + c * srq;
    S[3 * r + p][l] = nrp;
    S[3 * p + r][l] = nrp;
    S[3 * r + q][l] = nrq;
    S[3 * q + r][l] = nrq;
    for (int i = 0; i < 3; ++i) {
      const double vp = V[3 * i + p][l], vq = V[3 * i + q][l];
      V[3 * i + p][l] = c * vp - s * vq;
      V[3 * i + q][l] = s * vp + c * vq;
    }
  }
}

/// Orders eigenvalues i, j descending in every lane, swapping the columns of V with selects
/// and negating one of them so det V stays +1.
template <int i, int j, int W>
inline void sort_pair(double (&ev)[3][W], double (&V)[9][W]) {
#pragma omp simd
  for (int l = 0; l < W; ++l) {
    const bool sw = ev[i][l] < ev[j][l];
    const double ei = ev[i][l], ej = ev[j][l];
    ev[i][l] = sw ? ej : ei;
    ev[j][l] = sw ? ei : ej;
    for (int k = 0; k < 3; ++k) {
      const double a = V[3 * k + i][l], b = V[3 * k + j][l];
      V[3 * k + i][l] = sw ? b : a;
      V[3 * k + j][l] = sw ? -a : b;
    }
  }
}

}  // namespace detail

/// Number of cyclic Jacobi sweeps. Four sweeps drive the off-diagonal of FᵀF to round-off for
/// every 3×3 matrix tried (tests/tissue/test_rotation.cpp checks against Eigen's SVD).
inline constexpr int kPolarSweeps = 4;

/// Rotation-variant SVD of W deformation gradients at once: F = U·Σ·Vᵀ with U, V ∈ SO(3)
/// (row-major, [entry][lane]) and Σ sorted by magnitude, the sign of det F on the last singular
/// value (Irving et al. 2004). Σ itself is not returned (σ_i = u_i·F·v_i when needed).
template <int W>
inline void svd_rotations_batch(const double (&F)[9][W], double (&U)[9][W], double (&V)[9][W]) {
  double S[9][W], ev[3][W];
#pragma omp simd
  for (int l = 0; l < W; ++l) {
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j)
        S[3 * i + j][l] = F[i][l] * F[j][l] + F[3 + i][l] * F[3 + j][l] + F[6 + i][l] * F[6 + j][l];
    for (int k = 0; k < 9; ++k) V[k][l] = (k % 4 == 0) ? 1.0 : 0.0;
  }
  for (int k = 0; k < kPolarSweeps; ++k) {
    detail::jacobi_rotate<0, 1>(S, V);
    detail::jacobi_rotate<0, 2>(S, V);
    detail::jacobi_rotate<1, 2>(S, V);
  }
#pragma omp simd
  for (int l = 0; l < W; ++l) {
    ev[0][l] = S[0][l];
    ev[1][l] = S[4][l];
    ev[2][l] = S[8][l];
  }
  detail::sort_pair<0, 1>(ev, V);
  detail::sort_pair<0, 2>(ev, V);
  detail::sort_pair<1, 2>(ev, V);

  // B = F·V; its columns b1, b2 give u1, u2 by Gram–Schmidt; u3 = u1 × u2 makes det U = +1,
  // which leaves the sign of det F on the smallest singular value (Irving et al. 2004).
#pragma omp simd
  for (int l = 0; l < W; ++l) {
    double b1[3], b2[3];
    for (int i = 0; i < 3; ++i) {
      b1[i] = F[3 * i][l] * V[0][l] + F[3 * i + 1][l] * V[3][l] + F[3 * i + 2][l] * V[6][l];
      b2[i] = F[3 * i][l] * V[1][l] + F[3 * i + 1][l] * V[4][l] + F[3 * i + 2][l] * V[7][l];
    }
    const double tiny = 1e-24 * (ev[0][l] + 1e-300);
    double n1 = b1[0] * b1[0] + b1[1] * b1[1] + b1[2] * b1[2];
    const bool z1 = !(n1 > tiny);  // F ≈ 0: any frame will do; take V's first column
    double u1[3] = {z1 ? V[0][l] : b1[0], z1 ? V[3][l] : b1[1], z1 ? V[6][l] : b1[2]};
    n1 = z1 ? 1.0 : n1;
    const double i1 = 1.0 / std::sqrt(n1);
    u1[0] *= i1; u1[1] *= i1; u1[2] *= i1;
    const double pr = u1[0] * b2[0] + u1[1] * b2[1] + u1[2] * b2[2];
    double u2[3] = {b2[0] - pr * u1[0], b2[1] - pr * u1[1], b2[2] - pr * u1[2]};
    double n2 = u2[0] * u2[0] + u2[1] * u2[1] + u2[2] * u2[2];
    // Element flattened to a line: any unit vector normal to u1 (e × u1).
    const bool ex = std::fabs(u1[0]) < 0.9;
    const double e0 = ex ? 1.0 : 0.0, e1 = ex ? 0.0 : 1.0;
    const double w2[3] = {e1 * u1[2], -e0 * u1[2], e0 * u1[1] - e1 * u1[0]};
    const double nw = w2[0] * w2[0] + w2[1] * w2[1] + w2[2] * w2[2];
    const bool z2 = !(n2 > tiny);
    u2[0] = z2 ? w2[0] : u2[0];
    u2[1] = z2 ? w2[1] : u2[1];
    u2[2] = z2 ? w2[2] : u2[2];
    n2 = z2 ? nw : n2;
    const double i2 = 1.0 / std::sqrt(n2);
    u2[0] *= i2; u2[1] *= i2; u2[2] *= i2;
    const double u3[3] = {u1[1] * u2[2] - u1[2] * u2[1], u1[2] * u2[0] - u1[0] * u2[2],
                          u1[0] * u2[1] - u1[1] * u2[0]};
    for (int i = 0; i < 3; ++i) {
      U[3 * i][l] = u1[i];
      U[3 * i + 1][l] = u2[i];
      U[3 * i + 2][l] = u3[i];
    }
  }
}

/// Newton's iteration for the polar factor (Higham 1986), X ← ½(ζX + X⁻ᵀ/ζ) from X = F, for W
/// matrices at once: quadratic convergence to the orthogonal factor, each step one cofactor
/// matrix and one division per lane against the SVD's twelve Jacobi rotations (each two square
/// roots and two divisions). The first two steps are scaled by ζ = (‖X⁻¹‖/‖X‖)^½ (Frobenius),
/// which brings stretched or compressed elements near the orthogonal group at once; the rest
/// are unscaled. Stops when every lane's last step moved X by less than 1e-9 (its error is then
/// ~1e-18: the next step would square it). Returns false — R then undefined — when a lane has
/// det F ≤ 0 (inverted or flat: Irving's rotation needs the SVD's smallest singular direction)
/// or the lanes have not converged in kPolarNewtonSteps steps (det F near 0).
inline constexpr int kPolarNewtonSteps = 10;
template <int W>
inline bool polar_rotation_newton_batch(const double (&F)[9][W], double (&R)[9][W]) {
  double X[9][W];
  for (int k = 0; k < 9; ++k)
#pragma omp simd
    for (int l = 0; l < W; ++l) X[k][l] = F[k][l];
  for (int it = 0; it < kPolarNewtonSteps; ++it) {
    double bad = 0.0, moved = 0.0;
#pragma omp simd reduction(max : bad, moved)
    for (int l = 0; l < W; ++l) {
      const double a = X[0][l], b = X[1][l], c = X[2][l], d = X[3][l], e = X[4][l], f = X[5][l],
                   g = X[6][l], h = X[7][l], i = X[8][l];
      // Cofactors: X⁻ᵀ = C / det X.
      const double C[9] = {e * i - f * h, f * g - d * i, d * h - e * g, c * h - b * i, a * i - c * g,
                           b * g - a * h, b * f - c * e, c * d - a * f, a * e - b * d};
      const double det = a * C[0] + b * C[1] + c * C[2];
      bad = std::max(bad, det > 0.0 ? 0.0 : 1.0);  // also NaN
      const double safe = det > 0.0 ? det : 1.0;  // keeps a bad lane finite: the batch is abandoned below
      double zeta = 1.0;
      if (it < 2) {
        double nx = 0, nc = 0;
        for (int k = 0; k < 9; ++k) {
          nx += X[k][l] * X[k][l];
          nc += C[k] * C[k];
        }
        // ‖X⁻¹‖/‖X‖ = ‖C‖/(det·‖X‖); ζ is its square root.
        zeta = std::sqrt(std::sqrt(nc / (nx + 1e-300)) / safe);
      }
      const double p = 0.5 * zeta, q = 0.5 / (zeta * safe);
      double dx = 0;
      for (int k = 0; k < 9; ++k) {
        const double xn = p * X[k][l] + q * C[k];
        dx += (xn - X[k][l]) * (xn - X[k][l]);
        X[k][l] = xn;
      }
      moved = std::max(moved, dx);
    }
    if (bad > 0.0) return false;
    if (it >= 2 && moved < 1e-18) {
      for (int k = 0; k < 9; ++k)
#pragma omp simd
        for (int l = 0; l < W; ++l) R[k][l] = X[k][l];
      return true;
    }
  }
  return false;
}

/// Polar rotations through the SVD alone (svd_rotations_batch), sign-corrected for inversion.
template <int W>
inline void polar_rotation_svd_batch(const double (&F)[9][W], double (&R)[9][W]) {
  double U[9][W], V[9][W];
  svd_rotations_batch<W>(F, U, V);
#pragma omp simd
  for (int l = 0; l < W; ++l)
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j)
        R[3 * i + j][l] = U[3 * i][l] * V[3 * j][l] + U[3 * i + 1][l] * V[3 * j + 1][l] + U[3 * i + 2][l] * V[3 * j + 2][l];
}

/// Polar rotations R = U·Vᵀ of W deformation gradients at once. F and R are [entry][lane]
/// (row-major 3×3 entries), vectorised across elements: with AVX-512 eight elements go through
/// every instruction together. Newton's iteration where every lane has det F > 0 and converges
/// (polar_rotation_newton_batch: the usual case, ~3× cheaper), else the SVD for the whole batch
/// (svd_rotations_batch: fixed cost, Irving's rotation for inverted elements). The two agree to
/// round-off (tests/tissue/test_rotation.cpp).
template <int W>
inline void polar_rotation_batch(const double (&F)[9][W], double (&R)[9][W]) {
  if (polar_rotation_newton_batch<W>(F, R)) return;
  polar_rotation_svd_batch<W>(F, R);
}

/// Rotation-variant SVD of one F (row-major 3×3): F = U·diag(sigma)·Vᵀ, U, V ∈ SO(3), the sign
/// of det F on sigma[2] (svd_rotations_batch).
inline void svd_rotations(const double* F, double* U, double* sigma, double* V) {
  double Fb[9][1], Ub[9][1], Vb[9][1];
  for (int k = 0; k < 9; ++k) Fb[k][0] = F[k];
  svd_rotations_batch<1>(Fb, Ub, Vb);
  for (int k = 0; k < 9; ++k) {
    U[k] = Ub[k][0];
    V[k] = Vb[k][0];
  }
  for (int i = 0; i < 3; ++i) {  // σ_i = u_i · F v_i
    double s = 0;
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) s += U[3 * r + i] * F[3 * r + c] * V[3 * c + i];
    sigma[i] = s;
  }
}

/// Rotation of the polar decomposition of one F (row-major 3×3), sign-corrected for inversion.
inline void polar_rotation(const double* F, double* R) {
  double Fb[9][1], Rb[9][1];
  for (int k = 0; k < 9; ++k) Fb[k][0] = F[k];
  polar_rotation_batch<1>(Fb, Rb);
  for (int k = 0; k < 9; ++k) R[k] = Rb[k][0];
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
