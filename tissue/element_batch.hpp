#pragma once
/// \file element_batch.hpp
/// The element pass's batches, shared by the passes that walk the elements in them (the
/// corotational pass, tissue/fem_forces.cpp; the visco-elastic update, tissue/viscoelastic.cpp):
/// kBatch elements gathered into structure-of-arrays lanes, their deformation gradients.

#include <cstdint>

#include "tissue/fem_model.hpp"

namespace stroma::element_batch {

/// Elements per batch. Everything up to the final scatter into nodal arrays and matrix slots is
/// computed for 16 elements at once in [entry][lane] (structure-of-arrays) form, so the compiler
/// vectorises across elements: two AVX-512 registers per entry. Why 16 and not 8 (one
/// register): the rotation's Jacobi sweeps are a chain of dependent square roots and divisions,
/// latency-bound; two independent chains per instruction stream hide it (polar rotation 52.7 →
/// 31.6 ns per element, the whole implicit element pass 110 → 88 ns; 32 lanes gain nothing more;
/// docs/PERFORMANCE.md).
inline constexpr int kBatch = 16;
using Lanes = double[kBatch];

/// Gathered inputs of one batch. Spare lanes (past the range end) hold an undeformed unit
/// element with zero volume: finite values, zero contributions, never scattered.
struct BatchInput {
  double g[9][kBatch];   // shape gradients g1, g2, g3 (rows)
  double d[9][kBatch];   // current edges x_a − x_0, a = 1..3 (d[3(a−1)+i])
  double vol[kBatch], lambda[kBatch], mu[kBatch], beta[kBatch];
};

inline void gather(const FemModel& m, const double* __restrict x, int32_t e0, int count,
                   BatchInput& in, const float* damage = nullptr) {
  for (int l = 0; l < kBatch; ++l) {
    if (l < count) {
      const ElementParams& ep = m.elements[e0 + l];
      const double* x0 = x + 3 * ep.node[0];
      for (int a = 0; a < 3; ++a) {
        const double* xa = x + 3 * ep.node[a + 1];
        for (int i = 0; i < 3; ++i) in.d[3 * a + i][l] = xa[i] - x0[i];
      }
      for (int k = 0; k < 9; ++k) in.g[k][l] = ep.g[k];
      in.vol[l] = ep.volume;
      const double sc = damage ? 1.0 - static_cast<double>(damage[e0 + l]) : 1.0;
      in.lambda[l] = ep.lambda * sc;
      in.mu[l] = ep.mu * sc;
      in.beta[l] = ep.beta;
    } else {
      for (int k = 0; k < 9; ++k) in.d[k][l] = in.g[k][l] = (k % 4 == 0) ? 1.0 : 0.0;
      in.vol[l] = in.lambda[l] = in.mu[l] = in.beta[l] = 0.0;
    }
  }
}

/// G[i][j] = Σ_a d[a][i]·g[a][j] for every lane (F from positions, L from velocities).
inline void batch_gradient(const double (&d)[9][kBatch], const double (&g)[9][kBatch],
                           double (&G)[9][kBatch]) {
#pragma omp simd
  for (int l = 0; l < kBatch; ++l)
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j)
        G[3 * i + j][l] = d[i][l] * g[j][l] + d[3 + i][l] * g[3 + j][l] + d[6 + i][l] * g[6 + j][l];
}

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

}  // namespace stroma::element_batch
