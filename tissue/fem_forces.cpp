#include "tissue/fem_forces.hpp"

#include <algorithm>
#include <cmath>

#include "tissue/mat3.hpp"
#include "tissue/rotation.hpp"

namespace stroma {

namespace {

/// Deformation gradient F = Σ_{a=1..3} (x_a − x_0) ⊗ g_a of element e.
inline void deformation_gradient(const double* __restrict x, const ElementParams& ep,
                                 double* F, double* d1, double* d2) {
  const double* x0 = x + 3 * ep.node[0];
  double d[3][3];
  for (int a = 0; a < 3; ++a) {
    const double* xa = x + 3 * ep.node[a + 1];
    for (int i = 0; i < 3; ++i) d[a][i] = xa[i] - x0[i];
  }
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      F[3 * i + j] = d[0][i] * ep.g[j] + d[1][i] * ep.g[3 + j] + d[2][i] * ep.g[6 + j];
  for (int i = 0; i < 3; ++i) {
    d1[i] = d[0][i];
    d2[i] = d[1][i];
  }
}

/// P = R·σ(sym(RᵀG) − I·shift): the rotated small-strain stress of gradient G.
/// shift = 1 for positions (strain), 0 for velocities (strain rate).
inline void rotated_stress(const double* R, const double* G, double lambda, double mu,
                           double shift, double* P, double* eps_out) {
  double S[9];
  m3::mul_tn(R, G, S);
  double e[9];
  e[0] = S[0] - shift; e[4] = S[4] - shift; e[8] = S[8] - shift;
  e[1] = e[3] = 0.5 * (S[1] + S[3]);
  e[2] = e[6] = 0.5 * (S[2] + S[6]);
  e[5] = e[7] = 0.5 * (S[5] + S[7]);
  const double tr = e[0] + e[4] + e[8];
  double sig[9];
  for (int k = 0; k < 9; ++k) sig[k] = 2.0 * mu * e[k];
  sig[0] += lambda * tr; sig[4] += lambda * tr; sig[8] += lambda * tr;
  m3::mul(R, sig, P);
  if (eps_out)
    for (int k = 0; k < 9; ++k) eps_out[k] = e[k];
}

/// out_a = −scale·P·g_a for a = 1..3 and out_0 = −Σ, accumulated into the nodal array.
inline void scatter_pg(const ElementParams& ep, const double* P, double scale, double* out) {
  double f[4][3];
  for (int a = 0; a < 3; ++a) {
    const double* g = ep.g + 3 * a;
    for (int i = 0; i < 3; ++i) f[a + 1][i] = -scale * (P[3 * i] * g[0] + P[3 * i + 1] * g[1] + P[3 * i + 2] * g[2]);
  }
  for (int i = 0; i < 3; ++i) f[0][i] = -(f[1][i] + f[2][i] + f[3][i]);
  for (int a = 0; a < 4; ++a) {
    double* o = out + 3 * ep.node[a];
    o[0] += f[a][0];
    o[1] += f[a][1];
    o[2] += f[a][2];
  }
}

/// Elements per batch of the rotation kernel: 8 doubles fill an AVX-512 register.
constexpr int kBatch = 8;

/// Rotations of elements [e0, e0+count) into R[entry][lane] (count ≤ kBatch; spare lanes get
/// identity gradients so they stay finite).
template <ElementKernel K>
inline void batch_rotations(const FemModel& m, const double* x, int32_t e0, int count,
                            double (&R)[9][kBatch]) {
  if constexpr (K == ElementKernel::Linear) {
    for (int k = 0; k < 9; ++k)
      for (int l = 0; l < kBatch; ++l) R[k][l] = (k % 4 == 0) ? 1.0 : 0.0;
  } else if constexpr (K == ElementKernel::CorotationalPolar) {
    double F[9][kBatch];
    for (int l = 0; l < kBatch; ++l) {
      double f[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1}, d1[3], d2[3];
      if (l < count) deformation_gradient(x, m.elements[e0 + l], f, d1, d2);
      for (int k = 0; k < 9; ++k) F[k][l] = f[k];
    }
    polar_rotation_batch<kBatch>(F, R);
  } else {
    for (int l = 0; l < kBatch; ++l) {
      double f[9], d1[3] = {1, 0, 0}, d2[3] = {0, 1, 0}, r[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
      if (l < count) {
        deformation_gradient(x, m.elements[e0 + l], f, d1, d2);
        qr_rotation(m.rest_frame[e0 + l].data(), d1, d2, r);
      }
      for (int k = 0; k < 9; ++k) R[k][l] = r[k];
    }
  }
}

template <ElementKernel K, bool kHasKv, bool kHasK>
double pass_range(const FemModel& m, const ElasticPass& p, int32_t begin, int32_t end) {
  double energy = 0.0;
  const double* __restrict x = p.x;
  for (int32_t e0 = begin; e0 < end; e0 += kBatch) {
    const int count = std::min<int32_t>(kBatch, end - e0);
    double Rb[9][kBatch];
    batch_rotations<K>(m, x, e0, count, Rb);
    for (int l = 0; l < count; ++l) {
      const int32_t e = e0 + l;
      const ElementParams& ep = m.elements[e];
      double F[9], d1[3], d2[3], R[9];
      deformation_gradient(x, ep, F, d1, d2);
      for (int k = 0; k < 9; ++k) R[k] = Rb[k][l];
      if (p.rotations)
        for (int k = 0; k < 9; ++k) p.rotations[9 * e + k] = R[k];

      double P[9], eps[9];
      rotated_stress(R, F, ep.lambda, ep.mu, 1.0, P, eps);
      const double tr = eps[0] + eps[4] + eps[8];
      double ee = 0;
      for (int k = 0; k < 9; ++k) ee += eps[k] * eps[k];
      energy += ep.volume * (ep.mu * ee + 0.5 * ep.lambda * tr * tr);
      if (p.force) scatter_pg(ep, P, ep.volume, p.force);

      if constexpr (kHasKv) {
        double L[9], d1v[3], d2v[3], Q[9];
        deformation_gradient(p.v, ep, L, d1v, d2v);
        rotated_stress(R, L, ep.lambda, ep.mu, 0.0, Q, nullptr);
        // scatter_pg adds −scale·Q·g; K·v is +V·Q·g, hence the negative scale.
        scatter_pg(ep, Q, -ep.volume * (p.kv_beta * ep.beta + p.kv_const), p.kv);
      }

      if constexpr (kHasK) {
        const double s = ep.volume * (p.k_beta * ep.beta + p.k_const);
        double r[4][3], g[4][3];
        for (int a = 0; a < 3; ++a)
          for (int i = 0; i < 3; ++i) g[a + 1][i] = ep.g[3 * a + i];
        for (int i = 0; i < 3; ++i) g[0][i] = -(g[1][i] + g[2][i] + g[3][i]);
        for (int a = 0; a < 4; ++a) m3::mulv(R, g[a], r[a]);
        const double sl = s * ep.lambda, sm = s * ep.mu;
        const ElementSlots& slot = m.slots[e];
        for (int a = 0; a < 4; ++a)
          for (int b = a; b < 4; ++b) {
            double B[9];
            const double gg = sm * m3::dot(g[a], g[b]);
            for (int i = 0; i < 3; ++i)
              for (int j = 0; j < 3; ++j) B[3 * i + j] = sl * r[a][i] * r[b][j] + sm * r[b][i] * r[a][j];
            B[0] += gg; B[4] += gg; B[8] += gg;
            double* Kab = p.kvals + 9 * slot[4 * a + b];
            for (int k = 0; k < 9; ++k) Kab[k] += B[k];
            if (a != b) {
              double* Kba = p.kvals + 9 * slot[4 * b + a];
              for (int i = 0; i < 3; ++i)
                for (int j = 0; j < 3; ++j) Kba[3 * i + j] += B[3 * j + i];
            }
          }
      }
    }
  }
  return energy;
}

template <ElementKernel K>
double dispatch_flags(const FemModel& m, const ElasticPass& p, int32_t b, int32_t e) {
  const bool kv = p.kv != nullptr, k = p.kvals != nullptr;
  if (kv && k) return pass_range<K, true, true>(m, p, b, e);
  if (kv) return pass_range<K, true, false>(m, p, b, e);
  if (k) return pass_range<K, false, true>(m, p, b, e);
  return pass_range<K, false, false>(m, p, b, e);
}

}  // namespace

double elastic_pass(const FemModel& m, const ElasticPass& p) {
  double energy = 0.0;
  for (const ElementRange& r : m.ranges) {
    switch (r.kernel) {
      case ElementKernel::Linear:
        energy += dispatch_flags<ElementKernel::Linear>(m, p, r.begin, r.end);
        break;
      case ElementKernel::CorotationalPolar:
        energy += dispatch_flags<ElementKernel::CorotationalPolar>(m, p, r.begin, r.end);
        break;
      case ElementKernel::CorotationalQR:
        energy += dispatch_flags<ElementKernel::CorotationalQR>(m, p, r.begin, r.end);
        break;
    }
  }
  return energy;
}

void element_von_mises(const FemModel& m, const double* x, double* out) {
  for (const ElementRange& r : m.ranges)
    for (int32_t e = r.begin; e < r.end; ++e) {
      const ElementParams& ep = m.elements[e];
      double F[9], d1[3], d2[3], R[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
      deformation_gradient(x, ep, F, d1, d2);
      if (r.kernel == ElementKernel::CorotationalPolar) polar_rotation(F, R);
      else if (r.kernel == ElementKernel::CorotationalQR)
        qr_rotation(m.rest_frame[e].data(), d1, d2, R);
      double P[9], eps[9];
      rotated_stress(R, F, ep.lambda, ep.mu, 1.0, P, eps);
      // σ in the element frame (rotation does not change the von Mises value).
      const double tr = eps[0] + eps[4] + eps[8];
      double s[9];
      for (int k = 0; k < 9; ++k) s[k] = 2.0 * ep.mu * eps[k];
      s[0] += ep.lambda * tr; s[4] += ep.lambda * tr; s[8] += ep.lambda * tr;
      const double a = s[0] - s[4], b = s[4] - s[8], c = s[8] - s[0];
      out[e] = std::sqrt(0.5 * (a * a + b * b + c * c) + 3.0 * (s[1] * s[1] + s[2] * s[2] + s[5] * s[5]));
    }
}

}  // namespace stroma
