#include "tissue/st_venant_kirchhoff.hpp"

#include "tissue/hyperelastic_pass.hpp"

namespace stroma {

double st_venant_kirchhoff_stress(const double* F, double lambda, double mu, double* P) {
  double E[9];  // (FᵀF − I)/2
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      E[3 * i + j] = 0.5 * (F[i] * F[j] + F[3 + i] * F[3 + j] + F[6 + i] * F[6 + j] - (i == j ? 1.0 : 0.0));
  const double tr = E[0] + E[4] + E[8];
  double S[9], ee = 0;
  for (int k = 0; k < 9; ++k) {
    S[k] = 2.0 * mu * E[k];
    ee += E[k] * E[k];
  }
  S[0] += lambda * tr;
  S[4] += lambda * tr;
  S[8] += lambda * tr;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) P[3 * i + j] = F[3 * i] * S[j] + F[3 * i + 1] * S[3 + j] + F[3 * i + 2] * S[6 + j];
  return mu * ee + 0.5 * lambda * tr * tr;
}

namespace {

/// The St. Venant–Kirchhoff policy of the hyperelastic pass. In the singular values:
/// Ψ = μ/4·Σ(σ_i² − 1)² + λ/8·T², T = Σ(σ_i² − 1); ψ_i = μ(σ_i² − 1)σ_i + λ/2·T·σ_i.
struct StVenantKirchhoff {
  static double stress(const double* F, double lambda, double mu, double* P) {
    return st_venant_kirchhoff_stress(F, lambda, mu, P);
  }
  /// ∂ψ_i/∂σ_i = μ(3σ_i² − 1) + λ/2·T + λσ_i²; ∂ψ_i/∂σ_j = λσ_iσ_j.
  static void scaling(const double* sig, double lambda, double mu, double* A) {
    const double T = sig[0] * sig[0] + sig[1] * sig[1] + sig[2] * sig[2] - 3.0;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j)
        A[3 * i + j] = lambda * sig[i] * sig[j] + (i == j ? mu * (3.0 * sig[i] * sig[i] - 1.0) + 0.5 * lambda * T : 0.0);
  }
  /// Twist (ψ_i + ψ_j)/(σ_i + σ_j) = μ(σ_i² − σ_iσ_j + σ_j² − 1) + λT/2; flip
  /// (ψ_i − ψ_j)/(σ_i − σ_j) = μ(σ_i² + σ_iσ_j + σ_j² − 1) + λT/2.
  static void pair(const double* sig, int k, double lambda, double mu, double& twist, double& flip) {
    const int i = (k + 1) % 3, j = (k + 2) % 3;
    const double T = sig[0] * sig[0] + sig[1] * sig[1] + sig[2] * sig[2] - 3.0;
    const double q = sig[i] * sig[i] + sig[j] * sig[j] - 1.0, c = sig[i] * sig[j];
    twist = mu * (q - c) + 0.5 * lambda * T;
    flip = mu * (q + c) + 0.5 * lambda * T;
  }
};

}  // namespace

void st_venant_kirchhoff_eigensystem(const double* F, double lambda, double mu, double* values, double* modes) {
  hyperelastic::eigensystem<StVenantKirchhoff>(F, lambda, mu, values, modes);
}

double st_venant_kirchhoff_pass(const FemModel& m, const ElasticPass& p, const ElementRange& r) {
  return r.fibres ? hyperelastic::pass<StVenantKirchhoff, true>(m, p, r) : hyperelastic::pass<StVenantKirchhoff, false>(m, p, r);
}

}  // namespace stroma
