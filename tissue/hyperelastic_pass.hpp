#pragma once
/// \file hyperelastic_pass.hpp
/// The elastic pass (fem_forces.hpp) of a hyperelastic material Ψ(F): energy, forces
/// f_a = −V·P·g_a, and the tangent V·Gᵀ·[∂²Ψ/∂F²]⁺·G projected to positive semi-definite from
/// the analytic eigensystem of an isotropic energy (Smith, de Goes & Kim 2018; Smith et al.
/// 2019), plus, when the range has fibres, the exponential fibre term (fibre.hpp), whose
/// Hessian is PSD where it acts and is added as it is.
///
/// Included by the material files only (stable_neo_hookean.cpp, st_venant_kirchhoff.cpp): each
/// instantiates the pass with its material policy. A policy `M` provides, for Lamé (λ, μ):
///   static double stress(const double* F, double lambda, double mu, double* P);
///       the energy density Ψ(F) and the first Piola stress P (row-major);
///   static void scaling(const double* sig, double lambda, double mu, double* A);
///       the 3×3 Hessian ∂²Ψ/∂σ_i∂σ_j in the signed singular values σ (rotation-variant SVD);
///   static void pair(const double* sig, int k, double lambda, double mu, double& twist, double& flip);
///       for the pair (i, j) = (k+1, k+2) mod 3: the eigenvalue of the twist mode
///       (u_i v_jᵀ − u_j v_iᵀ)/√2, (ψ_i + ψ_j)/(σ_i + σ_j), and of the flip mode
///       (u_i v_jᵀ + u_j v_iᵀ)/√2, (ψ_i − ψ_j)/(σ_i − σ_j), with ψ_i = ∂Ψ/∂σ_i — written out
///       as polynomials so that they stay exact at σ_i = ±σ_j.
/// Everything inlines: no virtual call or branch per element beyond the range's.

#include <algorithm>
#include <cmath>

#include "tissue/fem_forces.hpp"
#include "tissue/fibre.hpp"
#include "tissue/mat3.hpp"
#include "tissue/material.hpp"
#include "tissue/rotation.hpp"
#include "tissue/viscoelastic.hpp"

namespace stroma::hyperelastic {

/// Shape gradients g_a of the element's four nodes (g_0 = −g_1 − g_2 − g_3).
inline void shape_gradients(const ElementParams& ep, double (&g)[4][3]) {
  for (int a = 0; a < 3; ++a)
    for (int j = 0; j < 3; ++j) g[a + 1][j] = ep.g[3 * a + j];
  for (int j = 0; j < 3; ++j) g[0][j] = -(g[1][j] + g[2][j] + g[3][j]);
}

/// F = Σ_a x_a ⊗ g_a (row-major) of element ep at positions x.
inline void element_gradient(const ElementParams& ep, const double* x, double* F) {
  double g[4][3];
  shape_gradients(ep, g);
  for (int k = 0; k < 9; ++k) F[k] = 0;
  for (int a = 0; a < 4; ++a) {
    const double* xa = x + 3 * ep.node[a];
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) F[3 * i + j] += xa[i] * g[a][j];
  }
}

/// Singular values (σ_i = u_i·F·v_i) and the eigen-decomposition of the scaling block M::scaling
/// for W elements at once (SIMD across elements, cyclic Jacobi as in the SVD). On return A's
/// diagonal holds the block's eigenvalues and E's columns its eigenvectors. Eigen's closed-form
/// 3×3 solver is not used: it loses orthogonality at nearly repeated eigenvalues, which is every
/// element near rest.
template <class M, int W>
void scaling_block_batch(const double (&F)[9][W], const double (&U)[9][W], const double (&V)[9][W],
                         const double (&lambda)[W], const double (&mu)[W], double (&sig)[3][W],
                         double (&A)[9][W], double (&E)[9][W]) {
#pragma omp simd
  for (int l = 0; l < W; ++l) {
    double s[3], a[9];
    for (int i = 0; i < 3; ++i) {
      double si = 0;
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) si += U[3 * r + i][l] * F[3 * r + c][l] * V[3 * c + i][l];
      s[i] = sig[i][l] = si;
    }
    M::scaling(s, lambda[l], mu[l], a);
    for (int k = 0; k < 9; ++k) {
      A[k][l] = a[k];
      E[k][l] = (k % 4 == 0) ? 1.0 : 0.0;
    }
  }
  for (int k = 0; k < kPolarSweeps; ++k) {
    detail::jacobi_rotate<0, 1>(A, E);
    detail::jacobi_rotate<0, 2>(A, E);
    detail::jacobi_rotate<1, 2>(A, E);
  }
}

/// The nine eigenpairs of ∂²Ψ/∂F² of one element from its SVD (U, V row-major rotations, sig)
/// and its scaling block's eigenvalues `a` and eigenvectors E (columns, row-major).
template <class M>
void eigensystem_from_svd(const double* U, const double* sig, const double* V, const double* a, const double* E,
                          double lambda, double mu, double* values, double* modes) {
  // Scaling modes: U·diag(e_m)·Vᵀ = Σ_k e_m[k] u_k v_kᵀ.
  for (int m = 0; m < 3; ++m) {
    values[m] = a[m];
    double* Q = modes + 9 * m;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j)
        Q[3 * i + j] = E[m] * U[3 * i] * V[3 * j] + E[3 + m] * U[3 * i + 1] * V[3 * j + 1] + E[6 + m] * U[3 * i + 2] * V[3 * j + 2];
  }
  const double r2 = std::sqrt(0.5);
  for (int k = 0; k < 3; ++k) {
    const int i = (k + 1) % 3, j = (k + 2) % 3;
    M::pair(sig, k, lambda, mu, values[3 + k], values[6 + k]);
    double* Qt = modes + 9 * (3 + k);
    double* Qf = modes + 9 * (6 + k);
    for (int r = 0; r < 3; ++r)
      for (int q = 0; q < 3; ++q) {
        const double ij = r2 * U[3 * r + i] * V[3 * q + j], ji = r2 * U[3 * r + j] * V[3 * q + i];
        Qt[3 * r + q] = ij - ji;
        Qf[3 * r + q] = ij + ji;
      }
  }
}

/// The eigensystem of one F (the tested reference path; the pass batches it).
template <class M>
void eigensystem(const double* F, double lambda, double mu, double* values, double* modes) {
  double Fb[9][1], Ub[9][1], Vb[9][1], sb[3][1], Ab[9][1], Eb[9][1];
  const double lb[1] = {lambda}, mb[1] = {mu};
  for (int k = 0; k < 9; ++k) Fb[k][0] = F[k];
  svd_rotations_batch<1>(Fb, Ub, Vb);
  scaling_block_batch<M, 1>(Fb, Ub, Vb, lb, mb, sb, Ab, Eb);
  double U[9], V[9], E[9], sig[3] = {sb[0][0], sb[1][0], sb[2][0]}, a[3] = {Ab[0][0], Ab[4][0], Ab[8][0]};
  for (int k = 0; k < 9; ++k) {
    U[k] = Ub[k][0];
    V[k] = Vb[k][0];
    E[k] = Eb[k][0];
  }
  eigensystem_from_svd<M>(U, sig, V, a, E, lambda, mu, values, modes);
}

/// Elements per batch: the SVD and the scaling block run across elements in SIMD lanes (as the
/// corotational pass's polar decomposition; 16 lanes, two AVX-512 registers, hide the Jacobi
/// sweeps' latency there: tissue/fem_forces.cpp).
inline constexpr int kBatch = 16;
static_assert(kBatch == ElasticPass::kPassBatch, "ElasticPass::blocks_due counts the pass's batches");

/// The polar rotation R = U·Vᵀ (row-major) from the rotation-variant SVD's U and V.
inline void polar_from_svd(const double* U, const double* V, double* R) {
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) R[3 * i + j] = U[3 * i] * V[3 * j] + U[3 * i + 1] * V[3 * j + 1] + U[3 * i + 2] * V[3 * j + 2];
}

/// The pass over one range's elements; `Fibres`: they carry FemModel::fibres. Returns their
/// energy.
///
/// A visco-elastic range (viscoelastic.hpp) is a generalised Maxwell solid whose equilibrium
/// spring is the hyperelastic matrix, scaled by g∞ = 1 − Σgᵢ, and whose branches (moduli gᵢ·(λ,
/// μ)) are corotational linear in the element's polar frame: Ψ = g∞·Ψ_M(F) + Σ ½·Qᵢ:(gᵢC)⁻¹:Qᵢ.
/// Over a step h (p.visco_h; h = 0 without p.visco_q) the branches add the stress
/// c_b·σ(ε) + H (c_b = Σgᵢγᵢ; H the history held over the step), so energy, forces and the
/// tangent are g∞·(matrix) + c_b·(corotational element) + H's energy V·H:ε and forces
/// −V·R·H·g_a. Why linear branches: their stored energy is exact, so the free energy above is
/// a Lyapunov function (energy is never created, tested and stress-tested); branches driven by
/// the hyperelastic stress itself have no such energy, and at ν → 0.5 the pressure's finite-
/// strain terms swamp it. At small strain the model is the Prony series on the hyperelastic
/// material; the fibres (when present) stay elastic.
template <class M, bool Fibres>
double pass(const FemModel& m, const ElasticPass& p, const ElementRange& r) {
  const int32_t begin = r.begin, end = r.end;
  double energy = 0;
  const bool visco = r.visco >= 0;
  const bool history = visco && p.visco_q != nullptr;
  const ViscoStep vstep = visco ? visco_step(m.visco[r.visco], history ? p.visco_h : 0.0) : ViscoStep{};
  double g_inf = 1;  // the matrix's share
  if (visco)
    for (int i = 0; i < vstep.terms; ++i) g_inf -= m.visco[r.visco].g[i];
  const double cb = vstep.c - g_inf;  // the branches' instantaneous share over the step
  const bool want_k = p.kvals != nullptr || p.kv != nullptr;
  // An energy-only pass (the energy guard's) needs no SVD here and writes no rotations: only
  // corotational ranges hand theirs on (TimeStepper::end_rot_ reuses nothing of this range).
  const bool write_rotations = p.rotations != nullptr && (want_k || p.force != nullptr);
  const bool want_svd = want_k || write_rotations || visco;
  double Fb[9][kBatch], Ub[9][kBatch], Vb[9][kBatch], sb[3][kBatch], Ab[9][kBatch], Eb[9][kBatch];
  double lb[kBatch], mb[kBatch];
  for (int32_t e0 = begin; e0 < end; e0 += kBatch) {
    const int n = std::min<int32_t>(kBatch, end - e0);
    // F = Σ x_a ⊗ g_a and Lamé parameters of the batch's elements (unused lanes: identity).
    for (int l = 0; l < kBatch; ++l) {
      double F[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
      lb[l] = mb[l] = 1.0;
      if (l < n) {
        const ElementParams& ep = m.elements[e0 + l];
        element_gradient(ep, p.x, F);
        const double keep = p.damage ? 1.0 - static_cast<double>(p.damage[e0 + l]) : 1.0;
        lb[l] = keep * ep.lambda;
        mb[l] = keep * ep.mu;
      }
      for (int k = 0; k < 9; ++k) Fb[k][l] = F[k];
    }
    if (want_svd) svd_rotations_batch<kBatch>(Fb, Ub, Vb);
    if (want_k) scaling_block_batch<M, kBatch>(Fb, Ub, Vb, lb, mb, sb, Ab, Eb);
    for (int l = 0; l < n; ++l) {
      const int32_t e = e0 + l;
      const ElementParams& ep = m.elements[e];
      const double keep = p.damage ? 1.0 - static_cast<double>(p.damage[e]) : 1.0;
      const double lambda = keep * ep.lambda, mu = keep * ep.mu, V = ep.volume;
      double g[4][3];
      shape_gradients(ep, g);
      double F[9];
      for (int k = 0; k < 9; ++k) F[k] = Fb[k][l];
      double P[9];
      double element_energy = M::stress(F, lambda, mu, P);
      // The fibre term: P_f = 2ψ′·b⊗a with b = F·a, so its force on node a is −V·2ψ′·(a·g_a)·b.
      FibreResponse fr;
      double s[4] = {0, 0, 0, 0};  // a·g_a
      if constexpr (Fibres) {
        const FibreParams& fp = m.fibres[e];
        fr = fibre_response(F, fp, keep);
        for (int a = 0; a < 4; ++a) s[a] = fp.a[0] * g[a][0] + fp.a[1] * g[a][1] + fp.a[2] * g[a][2];
      }
      energy += V * (g_inf * element_energy + fr.psi);
      if (p.force)
        for (int a = 0; a < 4; ++a)
          for (int i = 0; i < 3; ++i) {
            double f = g_inf * (P[3 * i] * g[a][0] + P[3 * i + 1] * g[a][1] + P[3 * i + 2] * g[a][2]);
            if constexpr (Fibres) f += 2.0 * fr.d1 * s[a] * fr.b[i];
            p.force[3 * ep.node[a] + i] -= V * f;
          }
      if (!want_svd) continue;
      double U[9], Vr[9], sig[3];
      for (int k = 0; k < 9; ++k) {
        U[k] = Ub[k][l];
        Vr[k] = Vb[k][l];
      }
      double R[9];  // the polar rotation (warped preconditioner; the visco-elastic frame)
      if (write_rotations || visco) polar_from_svd(U, Vr, R);
      if (write_rotations) std::copy(R, R + 9, p.rotations + 9 * e);
      if (visco) {  // the branches: the corotational element's stress c_b·R·σ(ε) plus R·H
        double h6[6] = {0, 0, 0, 0, 0, 0};
        if (history) {
          const int64_t j = e - r.begin;
          visco_history(vstep, p.visco_q + r.visco_q_begin + 6 * vstep.terms * j, p.visco_s0 + r.visco_s0_begin + 6 * j, h6);
        }
        const double H[9] = {h6[0], h6[3], h6[4], h6[3], h6[1], h6[5], h6[4], h6[5], h6[2]};
        double Pb[9], eps[9], RH[9];
        rotated_stress(R, F, lambda, mu, 1.0, Pb, eps);
        m3::mul(R, H, RH);
        const double tr = eps[0] + eps[4] + eps[8];
        double ee = 0, he = 0;
        for (int k = 0; k < 9; ++k) {
          ee += eps[k] * eps[k];
          he += H[k] * eps[k];
        }
        energy += V * (cb * (mu * ee + 0.5 * lambda * tr * tr) + he);
        if (p.force)
          for (int a = 0; a < 4; ++a)
            for (int i = 0; i < 3; ++i) {
              double f = 0;
              for (int k = 0; k < 3; ++k) f += (cb * Pb[3 * i + k] + RH[3 * i + k]) * g[a][k];
              p.force[3 * ep.node[a] + i] -= V * f;
            }
      }
      if (!want_k) continue;
      double a[3] = {Ab[0][l], Ab[4][l], Ab[8][l]}, E[9];
      for (int k = 0; k < 9; ++k) E[k] = Eb[k][l];
      for (int i = 0; i < 3; ++i) sig[i] = sb[i][l];
      // The tangent from the analytic eigensystem of ∂²Ψ/∂F², negative eigenvalues dropped (PSD
      // projection): K = V Σ_m λ_m⁺ w_m w_mᵀ, w_m = ∂(Q_m : F)/∂x, i.e. w_m[a][i] = (Q_m g_a)_i.
      double values[9], modes[81];
      eigensystem_from_svd<M>(U, sig, Vr, a, E, lambda, mu, values, modes);
      double K[12][12] = {};
      for (int md = 0; md < 9; ++md) {
        const double lam = values[md];
        if (!(lam > 0)) continue;
        const double* Q = modes + 9 * md;
        double w[12];
        for (int b = 0; b < 4; ++b)
          for (int i = 0; i < 3; ++i) w[3 * b + i] = Q[3 * i] * g[b][0] + Q[3 * i + 1] * g[b][1] + Q[3 * i + 2] * g[b][2];
        const double sc = g_inf * V * lam;
        for (int r1 = 0; r1 < 12; ++r1) {
          const double sr = sc * w[r1];
          for (int c1 = r1; c1 < 12; ++c1) K[r1][c1] += sr * w[c1];
        }
      }
      // The fibre term's Hessian, PSD where the fibre is stretched (zero elsewhere):
      // K_ab = V·s_a·s_b·(2ψ′·I + 4ψ″·b·bᵀ).
      if constexpr (Fibres) {
        if (fr.d1 > 0 || fr.d2 > 0)
          for (int b1 = 0; b1 < 4; ++b1)
            for (int b2 = b1; b2 < 4; ++b2) {
              const double ss = V * s[b1] * s[b2];
              for (int i = 0; i < 3; ++i)
                for (int k = 0; k < 3; ++k) {
                  const int r1 = 3 * b1 + i, c1 = 3 * b2 + k;
                  if (c1 < r1) continue;
                  K[r1][c1] += ss * ((i == k ? 2.0 * fr.d1 : 0.0) + 4.0 * fr.d2 * fr.b[i] * fr.b[k]);
                }
            }
      }
      // The branches' corotational element stiffness c_b·R·K₀·Rᵀ, K₀_ab = V·(λ g_a g_bᵀ +
      // μ g_b g_aᵀ + μ (g_a·g_b) I) (H is held over the step: no term of its own).
      if (visco && cb > 0)
        for (int b1 = 0; b1 < 4; ++b1)
          for (int b2 = b1; b2 < 4; ++b2) {
            const double gg = g[b1][0] * g[b2][0] + g[b1][1] * g[b2][1] + g[b1][2] * g[b2][2];
            double K0[9], T[9];
            for (int i = 0; i < 3; ++i)
              for (int k = 0; k < 3; ++k)
                K0[3 * i + k] = cb * V * (lambda * g[b1][i] * g[b2][k] + mu * g[b1][k] * g[b2][i] + (i == k ? mu * gg : 0.0));
            for (int i = 0; i < 3; ++i)  // T = K₀·Rᵀ
              for (int k = 0; k < 3; ++k) T[3 * i + k] = K0[3 * i] * R[3 * k] + K0[3 * i + 1] * R[3 * k + 1] + K0[3 * i + 2] * R[3 * k + 2];
            for (int i = 0; i < 3; ++i)
              for (int k = 0; k < 3; ++k) {
                const int r1 = 3 * b1 + i, c1 = 3 * b2 + k;
                if (c1 < r1) continue;
                K[r1][c1] += R[3 * i] * T[k] + R[3 * i + 1] * T[3 + k] + R[3 * i + 2] * T[6 + k];
              }
          }
      for (int r1 = 0; r1 < 12; ++r1)
        for (int c1 = 0; c1 < r1; ++c1) K[r1][c1] = K[c1][r1];
      if (p.kvals && p.blocks_due(e0)) {  // (the tangent is made for K·v and the SVD anyway)
        const double sc = p.k_beta * ep.beta + p.k_const;
        const ElementSlots& slot = m.slots[e];
        for (int b1 = 0; b1 < 4; ++b1)
          for (int b2 = b1; b2 < 4; ++b2) {  // upper-triangle storage (bsr_matrix.hpp)
            double blk[9];
            for (int i = 0; i < 3; ++i)
              for (int k = 0; k < 3; ++k) blk[3 * i + k] = sc * K[3 * b1 + i][3 * b2 + k];
            add_block_upper(p.kvals, slot[4 * b1 + b2], ep.node[b1] > ep.node[b2], blk);
          }
      }
      if (p.kv) {
        const double sc = p.kv_beta * ep.beta + p.kv_const;
        for (int b1 = 0; b1 < 4; ++b1)
          for (int b2 = 0; b2 < 4; ++b2) {
            const double* vb = p.v + 3 * ep.node[b2];
            for (int i = 0; i < 3; ++i)
              p.kv[3 * ep.node[b1] + i] += sc * (K[3 * b1 + i][3 * b2] * vb[0] + K[3 * b1 + i][3 * b2 + 1] * vb[1] +
                                                 K[3 * b1 + i][3 * b2 + 2] * vb[2]);
          }
      }
    }
  }
  return energy;
}

}  // namespace stroma::hyperelastic
