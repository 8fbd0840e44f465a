#include "tissue/stable_neo_hookean.hpp"

#include <Eigen/Eigenvalues>

#include <algorithm>

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

/// Levi-Civita symbol ε_ijk.
inline double levi(int i, int j, int k) { return 0.5 * (i - j) * (j - k) * (k - i); }

}  // namespace

double stable_neo_hookean_stress(const double* F, double lambda, double mu, double* P) {
  const double lp = lambda + mu, alpha = 1.0 + mu / lp;
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

double stable_neo_hookean_pass(const FemModel& m, const ElasticPass& p, int32_t begin, int32_t end) {
  double energy = 0;
  const bool want_k = p.kvals != nullptr || p.kv != nullptr;
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 9, 9>> eig;
  for (int32_t e = begin; e < end; ++e) {
    const ElementParams& ep = m.elements[e];
    const double keep = p.damage ? 1.0 - static_cast<double>(p.damage[e]) : 1.0;
    const double lambda = keep * ep.lambda, mu = keep * ep.mu, V = ep.volume;
    // Shape gradients of the four nodes and F = Σ x_a ⊗ g_a.
    double g[4][3];
    for (int a = 0; a < 3; ++a)
      for (int j = 0; j < 3; ++j) g[a + 1][j] = ep.g[3 * a + j];
    for (int j = 0; j < 3; ++j) g[0][j] = -(g[1][j] + g[2][j] + g[3][j]);
    double F[9] = {};
    for (int a = 0; a < 4; ++a) {
      const double* xa = p.x + 3 * ep.node[a];
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) F[3 * i + j] += xa[i] * g[a][j];
    }
    double P[9];
    energy += V * stable_neo_hookean_stress(F, lambda, mu, P);
    if (p.force)
      for (int a = 0; a < 4; ++a)
        for (int i = 0; i < 3; ++i)
          p.force[3 * ep.node[a] + i] -= V * (P[3 * i] * g[a][0] + P[3 * i + 1] * g[a][1] + P[3 * i + 2] * g[a][2]);
    if (p.rotations) polar_rotation(F, p.rotations + 9 * e);
    if (!want_k) continue;
    // ∂²Ψ/∂F² in vec(F) (index 3i + j), projected to PSD.
    const double lp = lambda + mu, alpha = 1.0 + mu / lp;
    double C[9];
    cofactor(F, C);
    const double J = F[0] * C[0] + F[3] * C[3] + F[6] * C[6];
    Eigen::Matrix<double, 9, 9> H;
    for (int r = 0; r < 9; ++r)
      for (int c = 0; c < 9; ++c) H(r, c) = lp * C[r] * C[c] + (r == c ? mu : 0.0);
    // λ'(J − α) ∂²J/∂F_ij∂F_kl, with ∂²J/∂F_ij∂F_kl = Σ_mn ε_ikm ε_jln F_mn.
    const double s = lp * (J - alpha);
    for (int i = 0; i < 3; ++i)
      for (int k = 0; k < 3; ++k) {
        const int mm = 3 - i - k;  // the third index (only i ≠ k contributes)
        if (i == k) continue;
        for (int j = 0; j < 3; ++j)
          for (int l = 0; l < 3; ++l) {
            if (j == l) continue;
            const int n = 3 - j - l;
            H(3 * i + j, 3 * k + l) += s * levi(i, k, mm) * levi(j, l, n) * F[3 * mm + n];
          }
      }
    eig.compute(H);
    Eigen::Matrix<double, 9, 1> ev = eig.eigenvalues().cwiseMax(0.0);
    const Eigen::Matrix<double, 9, 9> Hp = eig.eigenvectors() * ev.asDiagonal() * eig.eigenvectors().transpose();
    // Element blocks K_ab[i][k] = V Σ_jl g_a[j] Hp(3i+j, 3k+l) g_b[l].
    double K[4][4][9];
    for (int a = 0; a < 4; ++a)
      for (int b = a; b < 4; ++b) {
        for (int i = 0; i < 3; ++i)
          for (int k = 0; k < 3; ++k) {
            double acc = 0;
            for (int j = 0; j < 3; ++j)
              for (int l = 0; l < 3; ++l) acc += g[a][j] * Hp(3 * i + j, 3 * k + l) * g[b][l];
            K[a][b][3 * i + k] = V * acc;
          }
        if (b != a)
          for (int i = 0; i < 3; ++i)
            for (int k = 0; k < 3; ++k) K[b][a][3 * k + i] = K[a][b][3 * i + k];
      }
    if (p.kvals) {
      const double sc = p.k_beta * ep.beta + p.k_const;
      const ElementSlots& slot = m.slots[e];
      for (int a = 0; a < 4; ++a)
        for (int b = 0; b < 4; ++b) {
          double* B = p.kvals + 9 * slot[4 * a + b];
          for (int q = 0; q < 9; ++q) B[q] += sc * K[a][b][q];
        }
    }
    if (p.kv) {
      const double sc = p.kv_beta * ep.beta + p.kv_const;
      for (int a = 0; a < 4; ++a)
        for (int b = 0; b < 4; ++b) {
          const double* vb = p.v + 3 * ep.node[b];
          for (int i = 0; i < 3; ++i)
            p.kv[3 * ep.node[a] + i] +=
                sc * (K[a][b][3 * i] * vb[0] + K[a][b][3 * i + 1] * vb[1] + K[a][b][3 * i + 2] * vb[2]);
        }
    }
  }
  return energy;
}

}  // namespace stroma
