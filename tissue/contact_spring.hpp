#pragma once
/// \file contact_spring.hpp
/// A penalty contact acting at one point of the surface for one tick: the point is Σ w_a x_a
/// over up to four DOFs (a surface triangle's three nodes; on a cut surface, the four DOFs of
/// the element copy whose cut face it is — its vertices are points on that copy's edges), its
/// force is spread as w_a·f, and its stiffness and damping enter the implicit system as the
/// blocks w_a w_b K (so contact stays stable at 1 kHz with implicit Euler). The BSR slots of the
/// DOF pairs are precomputed at load time.
///
/// A spring may also join rigid bodies (tissue/rigid_rows.hpp): its anchor may move with a
/// rigid row's point (row_n), and a spring between two rigid bodies, or a body and a fixed
/// anchor, has no DOFs at all (n = 0) and its positive side is a rigid row's point (row_p).
///
/// And it may join two parts of the FEM node space whose nodes the pattern does not couple — a
/// thread's segment and the tetrahedron it passes through (a puncture): its point is then a
/// difference, Σ w_a x_a with the weights of one side positive and of the other negative (they
/// sum to 0, the anchor is the origin), and the pairs with no stored block are marked
/// kSlotMatrixFree: the time stepper applies their w_a w_b K terms in each CG product instead of
/// assembling them (matrix_free set), so the pattern stays fixed.

#include <cstdint>

namespace stroma {

/// Most DOFs one spring involves: a point of one element copy (4), or a thread's segment point
/// against a point of a tetrahedron (2 + 4).
inline constexpr int kSpringMaxNodes = 6;
/// ContactSpring::slot of a DOF pair the pattern has no block for (applied matrix-free).
inline constexpr int32_t kSlotMatrixFree = -2;

/// f = force on the tissue at the contact point (its positive side); ∂f/∂x ≈ −K, ∂f/∂v ≈ −C
/// (symmetric PSD, row-major) in the point's displacement relative to its anchor. The anchor is
/// fixed (or a tool's, prescribed) unless row_n ≥ 0: then it is the point x_c + arm_n of that
/// rigid row, which gets −f. Invariants: 0 ≤ n ≤ kSpringMaxNodes, n = 0 exactly when
/// row_p ≥ 0 (the positive side is then the rigid row's point x_c + arm_p); w[0..n) sums
/// to 1 (w ≥ 0) — or, for a spring joining two parts (no rows, matrix_free set), to 0;
/// slot[kSpringMaxNodes·a + b] (a, b < n) is the stored (upper-triangle) BSR block
/// (node[a], node[b]) when node[a] ≤ node[b], −1 for the lower-triangle pairs (their blocks are
/// the transposes of (b, a)'s, and K, C are symmetric), a harmless diagonal block for nodes
/// that never move, or kSlotMatrixFree (both (a, b) and (b, a)) for a pair the pattern lacks —
/// then matrix_free is 1.
struct ContactSpring {
  int32_t n = 3;  ///< DOFs in use
  int32_t node[kSpringMaxNodes] = {0, 0, 0, 0, 0, 0};
  double w[kSpringMaxNodes] = {1, 0, 0, 0, 0, 0};
  /// block (node[a], node[b]) at kSpringMaxNodes·a + b; −1: lower; kSlotMatrixFree: not stored
  int32_t slot[kSpringMaxNodes * kSpringMaxNodes] = {};
  double force[3] = {0, 0, 0};
  double K[9] = {};
  double C[9] = {};
  int32_t row_p = -1;  ///< ≥ 0: the positive side is this rigid row's point (and n = 0)
  int32_t row_n = -1;  ///< ≥ 0: the anchor is this rigid row's point
  double arm_p[3] = {0, 0, 0};  ///< m, world: row_p's point from its centre of mass
  double arm_n[3] = {0, 0, 0};  ///< m, world: row_n's point from its centre of mass
  uint8_t matrix_free = 0;      ///< 1: some pair's slot is kSlotMatrixFree
};

/// The slot index of DOF pair (a, b) of a spring.
inline constexpr int spring_slot(int a, int b) { return kSpringMaxNodes * a + b; }

/// Whether spring `sp` acts on a rigid row (its terms then go through tissue/rigid_rows.hpp).
inline bool spring_has_rows(const ContactSpring& sp) { return sp.row_p >= 0 || sp.row_n >= 0; }

/// The contact point Σ w_a x_a of spring `sp` at positions x.
/// (0 for a spring with no DOFs.)
inline void spring_point(const ContactSpring& sp, const double* x, double* p) {
  if (sp.n == 0) {
    p[0] = p[1] = p[2] = 0;
    return;
  }
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
