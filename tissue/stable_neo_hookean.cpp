#include "tissue/stable_neo_hookean.hpp"

#include <algorithm>
#include <cmath>

#include "tissue/rotation.hpp"

namespace stroma {

namespace {

/// cof F = ∂J/∂F (row-major): columns f1×f2, f2×f0, f0×f1 of F's columns f0, f1, f2.
inline void cofactor(const double* F, double* C) {
  auto col = [&](int j, int i) { return F[3 * i + j]; };
  for (int j = 0; j < 3; ++j) {
    const int a = (j + 1) % 3, b = (j + 2) % 3;
    C[0 * 3 + j] = col(a, 1) * col(b, 2) - col(a, 2) * col(b, 1);
    C[1 * 3 + j] = col(a, 2) * col(b, 0) - col(a, 0) * col(b, 2);
    C[2 * 3 + j] = col(a, 0) * col(b, 1) - col(a, 1) * col(b, 0);
  }
}

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

/// Levi-Civita symbol ε_ijk.
inline double levi(int i, int j, int k) { return 0.5 * (i - j) * (j - k) * (k - i); }

}  // namespace

double stable_neo_hookean_stress(const double* F, double lambda, double mu, double* P) {
  const double lp = lambda + mu;
  if (!(lp > 0)) {  // a ruptured element (damage 1): no material left
    for (int k = 0; k < 9; ++k) P[k] = 0;
    return 0;
  }
  const double alpha = 1.0 + mu / lp;
  double C[9];
  cofactor(F, C);
  const double J = F[0] * C[0] + F[3] * C[3] + F[6] * C[6];  // det F = f0 · (f1 × f2)
  double ff = 0;
  for (int k = 0; k < 9; ++k) {
    P[k] = mu * F[k] + lp * (J - alpha) * C[k];
    ff += F[k] * F[k];
  }
  return 0.5 * mu * (ff - 3.0) + 0.5 * lp * (J - alpha) * (J - alpha) - 0.5 * mu * mu / lp;
}

void stable_neo_hookean_hessian(const double* F, double lambda, double mu, double* H) {
  const double lp = lambda + mu, alpha = 1.0 + mu / lp;
  double C[9];
  cofactor(F, C);
  const double J = F[0] * C[0] + F[3] * C[3] + F[6] * C[6];
  for (int r = 0; r < 9; ++r)
    for (int c = 0; c < 9; ++c) H[9 * r + c] = lp * C[r] * C[c] + (r == c ? mu : 0.0);
  // λ'(J − α) ∂²J/∂F_ij∂F_kl, with ∂²J/∂F_ij∂F_kl = Σ_mn ε_ikm ε_jln F_mn.
  const double s = lp * (J - alpha);
  for (int i = 0; i < 3; ++i)
    for (int k = 0; k < 3; ++k) {
      if (i == k) continue;
      const int mm = 3 - i - k;  // the third index (only i ≠ k contributes)
      for (int j = 0; j < 3; ++j)
        for (int l = 0; l < 3; ++l) {
          if (j == l) continue;
          const int n = 3 - j - l;
          H[9 * (3 * i + j) + 3 * k + l] += s * levi(i, k, mm) * levi(j, l, n) * F[3 * mm + n];
        }
    }
}

namespace {

/// Singular values (σ_i = u_i·F·v_i) and the eigen-decomposition of the scaling block, the 3×3
/// Hessian of Ψ(σ0, σ1, σ2) with ψ_i = μσ_i + λ'(J − α)·J/σ_i, for W elements at once (SIMD
/// across elements, cyclic Jacobi as in the SVD). On return A's diagonal holds the block's
/// eigenvalues and E's columns its eigenvectors. Eigen's closed-form 3×3 solver is not used: it
/// loses orthogonality at nearly repeated eigenvalues, which is every element near rest.
template <int W>
void scaling_block_batch(const double (&F)[9][W], const double (&U)[9][W], const double (&V)[9][W],
                         const double (&lambda)[W], const double (&mu)[W], double (&sig)[3][W],
                         double (&A)[9][W], double (&E)[9][W]) {
#pragma omp simd
  for (int l = 0; l < W; ++l) {
    for (int i = 0; i < 3; ++i) {
      double si = 0;
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) si += U[3 * r + i][l] * F[3 * r + c][l] * V[3 * c + i][l];
      sig[i][l] = si;
    }
    const double lp = lambda[l] + mu[l], alpha = lp > 0 ? 1.0 + mu[l] / lp : 1.0;  // (lp = 0: ruptured)
    const double J = sig[0][l] * sig[1][l] * sig[2][l];
    const double c = lp * (J - alpha);
    const double dJ[3] = {sig[1][l] * sig[2][l], sig[2][l] * sig[0][l], sig[0][l] * sig[1][l]};  // ∂J/∂σ_i
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j)
        A[3 * i + j][l] = lp * dJ[i] * dJ[j] + (i == j ? mu[l] : c * sig[3 - i - j][l]);
    for (int k = 0; k < 9; ++k) E[k][l] = (k % 4 == 0) ? 1.0 : 0.0;
  }
  for (int k = 0; k < kPolarSweeps; ++k) {
    detail::jacobi_rotate<0, 1>(A, E);
    detail::jacobi_rotate<0, 2>(A, E);
    detail::jacobi_rotate<1, 2>(A, E);
  }
}

/// The nine eigenpairs of ∂²Ψ/∂F² of one element from its SVD (U, V row-major rotations, sig)
/// and its scaling block's eigenvalues `a` and eigenvectors E (columns, row-major).
void eigensystem_from_svd(const double* U, const double* sig, const double* V, const double* a, const double* E,
                          double lambda, double mu, double* values, double* modes) {
  const double lp = lambda + mu, alpha = lp > 0 ? 1.0 + mu / lp : 1.0;  // (lp = 0: ruptured)
  const double c = lp * (sig[0] * sig[1] * sig[2] - alpha);
  // Scaling modes: U·diag(e_m)·Vᵀ = Σ_k e_m[k] u_k v_kᵀ.
  for (int m = 0; m < 3; ++m) {
    values[m] = a[m];
    double* Q = modes + 9 * m;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j)
        Q[3 * i + j] = E[m] * U[3 * i] * V[3 * j] + E[3 + m] * U[3 * i + 1] * V[3 * j + 1] + E[6 + m] * U[3 * i + 2] * V[3 * j + 2];
  }
  // Per pair (i, j) with third index k: the twist mode (u_i v_jᵀ − u_j v_iᵀ)/√2, eigenvalue
  // μ + λ'(J − α)σ_k, and the flip mode (u_i v_jᵀ + u_j v_iᵀ)/√2, μ − λ'(J − α)σ_k. Polynomial
  // in σ: no division, fine at σ_i = σ_j.
  const double r2 = std::sqrt(0.5);
  for (int k = 0; k < 3; ++k) {
    const int i = (k + 1) % 3, j = (k + 2) % 3;
    values[3 + k] = mu + c * sig[k];
    values[6 + k] = mu - c * sig[k];
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

/// Elements per batch: the SVD and the scaling block run across elements in SIMD lanes (as the
/// corotational pass's polar decomposition; 16 lanes, two AVX-512 registers, hide the Jacobi
/// sweeps' latency there: tissue/fem_forces.cpp).
constexpr int kBatch = 16;

}  // namespace

void stable_neo_hookean_eigensystem(const double* F, double lambda, double mu, double* values, double* modes) {
  double Fb[9][1], Ub[9][1], Vb[9][1], sb[3][1], Ab[9][1], Eb[9][1];
  const double lb[1] = {lambda}, mb[1] = {mu};
  for (int k = 0; k < 9; ++k) Fb[k][0] = F[k];
  svd_rotations_batch<1>(Fb, Ub, Vb);
  scaling_block_batch<1>(Fb, Ub, Vb, lb, mb, sb, Ab, Eb);
  double U[9], V[9], E[9], sig[3] = {sb[0][0], sb[1][0], sb[2][0]}, a[3] = {Ab[0][0], Ab[4][0], Ab[8][0]};
  for (int k = 0; k < 9; ++k) {
    U[k] = Ub[k][0];
    V[k] = Vb[k][0];
    E[k] = Eb[k][0];
  }
  eigensystem_from_svd(U, sig, V, a, E, lambda, mu, values, modes);
}

double stable_neo_hookean_pass(const FemModel& m, const ElasticPass& p, int32_t begin, int32_t end) {
  double energy = 0;
  const bool want_k = p.kvals != nullptr || p.kv != nullptr;
  const bool want_svd = want_k || p.rotations != nullptr;
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
    if (want_k) scaling_block_batch<kBatch>(Fb, Ub, Vb, lb, mb, sb, Ab, Eb);
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
    energy += V * stable_neo_hookean_stress(F, lambda, mu, P);
    if (p.force)
      for (int a = 0; a < 4; ++a)
        for (int i = 0; i < 3; ++i)
          p.force[3 * ep.node[a] + i] -= V * (P[3 * i] * g[a][0] + P[3 * i + 1] * g[a][1] + P[3 * i + 2] * g[a][2]);
    if (!want_svd) continue;
    double U[9], Vr[9], sig[3];
    for (int k = 0; k < 9; ++k) {
      U[k] = Ub[k][l];
      Vr[k] = Vb[k][l];
    }
    if (p.rotations) {  // the polar rotation R = U·Vᵀ (for the warped preconditioner)
      double* R = p.rotations + 9 * e;
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) R[3 * i + j] = U[3 * i] * Vr[3 * j] + U[3 * i + 1] * Vr[3 * j + 1] + U[3 * i + 2] * Vr[3 * j + 2];
    }
    if (!want_k) continue;
    double a[3] = {Ab[0][l], Ab[4][l], Ab[8][l]}, E[9];
    for (int k = 0; k < 9; ++k) E[k] = Eb[k][l];
    for (int i = 0; i < 3; ++i) sig[i] = sb[i][l];
    // The tangent from the analytic eigensystem of ∂²Ψ/∂F², negative eigenvalues dropped (PSD
    // projection): K = V Σ_m λ_m⁺ w_m w_mᵀ, w_m = ∂(Q_m : F)/∂x, i.e. w_m[a][i] = (Q_m g_a)_i.
    double values[9], modes[81];
    eigensystem_from_svd(U, sig, Vr, a, E, lambda, mu, values, modes);
    double K[12][12] = {};
    for (int md = 0; md < 9; ++md) {
      const double lam = values[md];
      if (!(lam > 0)) continue;
      const double* Q = modes + 9 * md;
      double w[12];
      for (int a = 0; a < 4; ++a)
        for (int i = 0; i < 3; ++i) w[3 * a + i] = Q[3 * i] * g[a][0] + Q[3 * i + 1] * g[a][1] + Q[3 * i + 2] * g[a][2];
      const double s = V * lam;
      for (int r = 0; r < 12; ++r) {
        const double sr = s * w[r];
        for (int c = r; c < 12; ++c) K[r][c] += sr * w[c];
      }
    }
    for (int r = 0; r < 12; ++r)
      for (int c = 0; c < r; ++c) K[r][c] = K[c][r];
    if (p.kvals) {
      const double sc = p.k_beta * ep.beta + p.k_const;
      const ElementSlots& slot = m.slots[e];
      for (int a = 0; a < 4; ++a)
        for (int b = a; b < 4; ++b) {  // upper-triangle storage (bsr_matrix.hpp)
          double blk[9];
          for (int i = 0; i < 3; ++i)
            for (int k = 0; k < 3; ++k) blk[3 * i + k] = sc * K[3 * a + i][3 * b + k];
          add_block_upper(p.kvals, slot[4 * a + b], ep.node[a] > ep.node[b], blk);
        }
    }
    if (p.kv) {
      const double sc = p.kv_beta * ep.beta + p.kv_const;
      for (int a = 0; a < 4; ++a)
        for (int b = 0; b < 4; ++b) {
          const double* vb = p.v + 3 * ep.node[b];
          for (int i = 0; i < 3; ++i)
            p.kv[3 * ep.node[a] + i] +=
                sc * (K[3 * a + i][3 * b] * vb[0] + K[3 * a + i][3 * b + 1] * vb[1] + K[3 * a + i][3 * b + 2] * vb[2]);
        }
    }
  }
  }
  return energy;
}

}  // namespace stroma
