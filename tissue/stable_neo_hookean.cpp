#include "tissue/stable_neo_hookean.hpp"

#include <algorithm>
#include <cmath>

#include "tissue/hyperelastic_pass.hpp"

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

/// The stable Neo-Hookean policy of the hyperelastic pass (hyperelastic_pass.hpp).
struct StableNeoHookean {
  static double stress(const double* F, double lambda, double mu, double* P) {
    return stable_neo_hookean_stress(F, lambda, mu, P);
  }
  /// ∂²Ψ/∂σ_i∂σ_j with ψ_i = μσ_i + λ'(J − α)·J/σ_i.
  static void scaling(const double* sig, double lambda, double mu, double* A) {
    const double lp = lambda + mu, alpha = lp > 0 ? 1.0 + mu / lp : 1.0;  // (lp = 0: ruptured)
    const double J = sig[0] * sig[1] * sig[2];
    const double c = lp * (J - alpha);
    const double dJ[3] = {sig[1] * sig[2], sig[2] * sig[0], sig[0] * sig[1]};  // ∂J/∂σ_i
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) A[3 * i + j] = lp * dJ[i] * dJ[j] + (i == j ? mu : c * sig[3 - i - j]);
  }
  /// Twist μ + λ'(J − α)σ_k, flip μ − λ'(J − α)σ_k: polynomial in σ, fine at σ_i = σ_j.
  static void pair(const double* sig, int k, double lambda, double mu, double& twist, double& flip) {
    const double lp = lambda + mu, alpha = lp > 0 ? 1.0 + mu / lp : 1.0;
    const double c = lp * (sig[0] * sig[1] * sig[2] - alpha);
    twist = mu + c * sig[k];
    flip = mu - c * sig[k];
  }
};

}  // namespace

void stable_neo_hookean_eigensystem(const double* F, double lambda, double mu, double* values, double* modes) {
  hyperelastic::eigensystem<StableNeoHookean>(F, lambda, mu, values, modes);
}

double stable_neo_hookean_pass(const FemModel& m, const ElasticPass& p, const ElementRange& r) {
  return r.fibres ? hyperelastic::pass<StableNeoHookean, true>(m, p, r) : hyperelastic::pass<StableNeoHookean, false>(m, p, r);
}

}  // namespace stroma
