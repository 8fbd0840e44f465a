#pragma once
/// \file contact_spring.hpp
/// A penalty contact acting at one point of the surface for one tick: the point is Σ w_a x_a
/// over up to four DOFs (a surface triangle's three nodes; on a cut surface, the four DOFs of
/// the element copy whose cut face it is — its vertices are points on that copy's edges), its
/// force is spread as w_a·f, and its stiffness and damping enter the implicit system as the
/// blocks w_a w_b K (so contact stays stable at 1 kHz with implicit Euler). The BSR slots of the
/// DOF pairs are precomputed at load time.

#include <cstdint>

namespace stroma {

/// Most DOFs one contact point involves (a point of one element copy).
inline constexpr int kSpringMaxNodes = 4;

/// f = force on the tissue at the contact point; ∂f/∂x ≈ −K, ∂f/∂v ≈ −C (symmetric PSD,
/// row-major), both for the contact point. Invariants: 1 ≤ n ≤ kSpringMaxNodes; w[0..n) sums
/// to 1 (w ≥ 0); slot[4a + b] (a, b < n) is the stored (upper-triangle) BSR block
/// (node[a], node[b]) when node[a] ≤ node[b], −1 for the lower-triangle pairs (their blocks are
/// the transposes of (b, a)'s, and K, C are symmetric), or a harmless diagonal block for nodes
/// that never move.
struct ContactSpring {
  int32_t n = 3;  ///< DOFs in use
  int32_t node[kSpringMaxNodes] = {0, 0, 0, 0};
  double w[kSpringMaxNodes] = {1, 0, 0, 0};
  int32_t slot[kSpringMaxNodes * kSpringMaxNodes] = {};  ///< block (node[a], node[b]) at 4a+b; −1: lower
  double force[3] = {0, 0, 0};
  double K[9] = {};
  double C[9] = {};
};

/// The contact point Σ w_a x_a of spring `sp` at positions x.
inline void spring_point(const ContactSpring& sp, const double* x, double* p) {
  for (int k = 0; k < 3; ++k) {
    double s = sp.w[0] * x[3 * sp.node[0] + k];
    for (int a = 1; a < sp.n; ++a) s += sp.w[a] * x[3 * sp.node[a] + k];
    p[k] = s;
  }
}

/// The force on the tissue of spring `sp` as the implicit step applied it, at the end of a step
/// from positions x0 to x with end velocities v: f − K·(p(x) − p(x0)) − C·v_p (the spring is
/// linearised where it was found; implicit Euler evaluates it at the end of the step).
inline void spring_force_after_step(const ContactSpring& sp, const double* x0, const double* x, const double* v,
                                    double* f) {
  double p0[3], p1[3], vp[3];
  spring_point(sp, x0, p0);
  spring_point(sp, x, p1);
  spring_point(sp, v, vp);
  const double dp[3] = {p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2]};
  for (int k = 0; k < 3; ++k)
    f[k] = sp.force[k] - (sp.K[3 * k] * dp[0] + sp.K[3 * k + 1] * dp[1] + sp.K[3 * k + 2] * dp[2]) -
           (sp.C[3 * k] * vp[0] + sp.C[3 * k + 1] * vp[1] + sp.C[3 * k + 2] * vp[2]);
}

}  // namespace stroma
