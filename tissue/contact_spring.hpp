#pragma once
/// \file contact_spring.hpp
/// A penalty contact acting at one point of a surface triangle for one tick: the point is
/// Σ w_a x_a over the triangle's nodes, its force is spread as w_a·f, and its stiffness and
/// damping enter the implicit system as the blocks w_a w_b K (so contact stays stable at 1 kHz
/// with implicit Euler). The BSR slots of the 3×3 node pairs are precomputed at load time.

#include <cstdint>

namespace stroma {

/// f = force on the tissue at the contact point; ∂f/∂x ≈ −K, ∂f/∂v ≈ −C (symmetric PSD,
/// row-major), both for the contact point. Invariants: w sums to 1 (w ≥ 0); slot[3a + b] is the
/// stored (upper-triangle) BSR block (node[a], node[b]) when node[a] ≤ node[b], −1 for the
/// lower-triangle pairs (their blocks are the transposes of (b, a)'s, and K, C are symmetric),
/// or a harmless diagonal block for nodes that never move.
struct ContactSpring {
  int32_t node[3] = {0, 0, 0};
  double w[3] = {1, 0, 0};
  int32_t slot[9] = {};  ///< BSR slot of block (node[a], node[b]) at 3a+b; −1: lower, skipped
  double force[3] = {0, 0, 0};
  double K[9] = {};
  double C[9] = {};
};

/// The contact point Σ w_a x_a of spring `sp` at positions x.
inline void spring_point(const ContactSpring& sp, const double* x, double* p) {
  for (int k = 0; k < 3; ++k)
    p[k] = sp.w[0] * x[3 * sp.node[0] + k] + sp.w[1] * x[3 * sp.node[1] + k] + sp.w[2] * x[3 * sp.node[2] + k];
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
