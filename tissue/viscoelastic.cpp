#include "tissue/viscoelastic.hpp"

#include <algorithm>
#include <cmath>

#include "tissue/element_batch.hpp"
#include "tissue/fem_forces.hpp"
#include "tissue/rotation.hpp"

namespace stroma {

ViscoStep visco_step(const PronySeries& s, double h) {
  ViscoStep st;
  st.terms = s.terms;
  for (int i = 0; i < s.terms; ++i) {
    const double x = h / s.tau[i];
    st.decay[i] = std::exp(-x);
    const double gamma = x > 1e-8 ? -std::expm1(-x) / x : 1.0 - 0.5 * x;  // (1 − e^(−x))/x
    st.gg[i] = s.g[i] * gamma;
    st.c -= s.g[i] * (1.0 - gamma);
  }
  return st;
}

// The visco-elastic internal variables over the elements (declared in tissue/fem_forces.hpp
// with the element pass that reads them): stepped here, beside the Prony series they follow.

void viscous_update(const FemModel& m, const double* x, const float* damage, double h, double* visco_q,
                    double* visco_s0) {
  using element_batch::kBatch;
  element_batch::BatchInput in;
  double F[9][kBatch], R[9][kBatch];
  for (const ElementRange& r : m.ranges) {
    if (r.visco < 0 || r.fixed) continue;
    const ViscoStep st = visco_step(m.visco[r.visco], h);
    // Corotational (polar: the loader checks) or hyperelastic, whose branches are corotational
    // (hyperelastic_pass.hpp): the batched polar rotations U·Vᵀ both passes use, then per
    // element σ₀ = λ tr(ε) I + 2με in the rotated frame.
    for (int32_t e0 = r.begin; e0 < r.end; e0 += kBatch) {
      const int count = std::min<int32_t>(kBatch, r.end - e0);
      element_batch::gather(m, x, e0, count, in, damage);
      element_batch::batch_gradient(in.d, in.g, F);
      polar_rotation_batch<kBatch>(F, R);
      for (int l = 0; l < count; ++l) {
        double S[9];  // RᵀF
        for (int i = 0; i < 3; ++i)
          for (int k = 0; k < 3; ++k) S[3 * i + k] = R[i][l] * F[k][l] + R[3 + i][l] * F[3 + k][l] + R[6 + i][l] * F[6 + k][l];
        const double e00 = S[0] - 1, e11 = S[4] - 1, e22 = S[8] - 1;
        const double e01 = 0.5 * (S[1] + S[3]), e02 = 0.5 * (S[2] + S[6]), e12 = 0.5 * (S[5] + S[7]);
        const double lt = in.lambda[l] * (e00 + e11 + e22), mu2 = 2 * in.mu[l];
        const double s0[6] = {mu2 * e00 + lt, mu2 * e11 + lt, mu2 * e22 + lt, mu2 * e01, mu2 * e02, mu2 * e12};
        const int64_t j = e0 + l - r.begin;
        double* q = visco_q + r.visco_q_begin + 6 * st.terms * j;
        double* sn = visco_s0 + r.visco_s0_begin + 6 * j;
        for (int i = 0; i < st.terms; ++i)
          for (int k = 0; k < 6; ++k) q[6 * i + k] = st.decay[i] * q[6 * i + k] + st.gg[i] * (s0[k] - sn[k]);
        for (int k = 0; k < 6; ++k) sn[k] = s0[k];
      }
    }
  }
}

double viscous_stored_energy(const FemModel& m, const double* visco_q) {
  double energy = 0;
  for (const ElementRange& r : m.ranges) {
    if (r.visco < 0) continue;
    const PronySeries& ps = m.visco[r.visco];
    for (int32_t e = r.begin; e < r.end; ++e) {
      const ElementParams& ep = m.elements[e];
      const double* q = visco_q + r.visco_q_begin + 6 * ps.terms * (e - r.begin);
      for (int i = 0; i < ps.terms; ++i) {
        // ½ Q : C⁻¹ : Q for the isotropic C = g·(λ, μ): (Q:Q − λ/(3λ + 2μ)·tr²Q)/(4μ)/g.
        const double* Q = q + 6 * i;
        const double qq = Q[0] * Q[0] + Q[1] * Q[1] + Q[2] * Q[2] + 2 * (Q[3] * Q[3] + Q[4] * Q[4] + Q[5] * Q[5]);
        const double tr = Q[0] + Q[1] + Q[2];
        if (!(ps.g[i] > 0) || !(ep.mu > 0)) continue;
        energy += ep.volume * (qq - ep.lambda / (3 * ep.lambda + 2 * ep.mu) * tr * tr) / (4 * ep.mu * ps.g[i]);
      }
    }
  }
  return energy;
}

}  // namespace stroma
