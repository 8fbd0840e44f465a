#pragma once
/// \file corotational_pass.hpp
/// The corotational kernels (polar and QR rotation; docs/TISSUE.md) and the linear one: one
/// element range's pass in batches of kBatch elements — gather, rotations (`batch_rotations`),
/// rotated stress and nodal forces (`batch_stress_forces`), K·v, the warped stiffness blocks
/// R·Ke·Rᵀ scattered into the BSR pattern (`scatter_blocks`), and a visco-elastic range's
/// history stress. fem_forces.cpp's elastic_pass (the dispatcher) runs each corotational range
/// through corotational_pass() and the hyperelastic ones through their own passes. No allocation.
///
/// Included by tissue/fem_forces.cpp alone, its functions with internal linkage: the kernels are
/// compiled in the dispatcher's translation unit exactly as before they had a file of their own,
/// so the compiler's inlining and vectorising choices are the same (bench/ab_ticks.py before and
/// after: docs/PERFORMANCE.md, "The house"). A translation unit of its own was tried and not
/// kept: its first A/B read 1.18× slower, in a run later found biased by which binary ran
/// second; not measured again.

#include <algorithm>
#include <cmath>

#include "tissue/element_batch.hpp"
#include "tissue/fem_forces.hpp"
#include "tissue/fem_model.hpp"
#include "tissue/mat3.hpp"
#include "tissue/material.hpp"
#include "tissue/rotation.hpp"
#include "tissue/viscoelastic.hpp"

namespace stroma {

namespace {

using element_batch::BatchInput;
using element_batch::batch_gradient;
using element_batch::gather;
using element_batch::kBatch;
using element_batch::Lanes;

/// Nodal contributions out[a] = −scale·R·σ(sym(RᵀG) − shift·I)·g_a (a = 0..3, g_0 = −Σ) per lane;
/// returns the per-lane energy density term V(μ ε:ε + λ/2 tr²ε) in `energy` when requested.
inline void batch_stress_forces(const double (&R)[9][kBatch], const double (&G)[9][kBatch],
                                const BatchInput& in, double shift, const Lanes& scale,
                                double (&out)[12][kBatch], double* energy) {
#pragma omp simd
  for (int l = 0; l < kBatch; ++l) {
    double S[9];
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j)
        S[3 * i + j] = R[i][l] * G[j][l] + R[3 + i][l] * G[3 + j][l] + R[6 + i][l] * G[6 + j][l];
    const double e00 = S[0] - shift, e11 = S[4] - shift, e22 = S[8] - shift;
    const double e01 = 0.5 * (S[1] + S[3]), e02 = 0.5 * (S[2] + S[6]), e12 = 0.5 * (S[5] + S[7]);
    const double tr = e00 + e11 + e22;
    const double mu2 = 2.0 * in.mu[l], lt = in.lambda[l] * tr;
    const double sig[9] = {mu2 * e00 + lt, mu2 * e01, mu2 * e02,
                           mu2 * e01, mu2 * e11 + lt, mu2 * e12,
                           mu2 * e02, mu2 * e12, mu2 * e22 + lt};
    if (energy) {
      const double ee = e00 * e00 + e11 * e11 + e22 * e22 + 2.0 * (e01 * e01 + e02 * e02 + e12 * e12);
      energy[l] = in.vol[l] * (in.mu[l] * ee + 0.5 * in.lambda[l] * tr * tr);
    }
    double P[9];
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j)
        P[3 * i + j] = R[3 * i][l] * sig[j] + R[3 * i + 1][l] * sig[3 + j] + R[3 * i + 2][l] * sig[6 + j];
    double f0[3] = {0, 0, 0};
    for (int a = 0; a < 3; ++a)
      for (int i = 0; i < 3; ++i) {
        const double v = -scale[l] * (P[3 * i] * in.g[3 * a][l] + P[3 * i + 1] * in.g[3 * a + 1][l] +
                                      P[3 * i + 2] * in.g[3 * a + 2][l]);
        out[3 * (a + 1) + i][l] = v;
        f0[i] -= v;
      }
    for (int i = 0; i < 3; ++i) out[i][l] = f0[i];
  }
}

/// Energy only, per lane: V(μ ε:ε + λ/2 tr²ε) with ε = sym(RᵀF) − I (the energy guard's pass:
/// no stress, no forces). The strain lines repeat batch_stress_forces' on purpose: a shared
/// helper returning the strain through a pointer stopped GCC 12 vectorising both loops (forces
/// 48 → 62 ns per element, measured 2026-12-02).
inline void batch_energy(const double (&R)[9][kBatch], const double (&G)[9][kBatch], const BatchInput& in,
                         double* energy) {
#pragma omp simd
  for (int l = 0; l < kBatch; ++l) {
    double S[9];
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j)
        S[3 * i + j] = R[i][l] * G[j][l] + R[3 + i][l] * G[3 + j][l] + R[6 + i][l] * G[6 + j][l];
    const double e00 = S[0] - 1.0, e11 = S[4] - 1.0, e22 = S[8] - 1.0;
    const double e01 = 0.5 * (S[1] + S[3]), e02 = 0.5 * (S[2] + S[6]), e12 = 0.5 * (S[5] + S[7]);
    const double tr = e00 + e11 + e22;
    const double ee = e00 * e00 + e11 * e11 + e22 * e22 + 2.0 * (e01 * e01 + e02 * e02 + e12 * e12);
    energy[l] = in.vol[l] * (in.mu[l] * ee + 0.5 * in.lambda[l] * tr * tr);
  }
}

/// The 10 distinct 3×3 blocks (a ≤ b) of s·R·Ke·Rᵀ per lane, in the order of kBlockPairs.
constexpr int kBlockPairs[10][2] = {{0, 0}, {0, 1}, {0, 2}, {0, 3}, {1, 1},
                                    {1, 2}, {1, 3}, {2, 2}, {2, 3}, {3, 3}};
/// Lanes [L0, L0 + kBlockLanes) only: the blocks of a whole batch of 16 would not stay in
/// registers and L1 (measured: 8 lanes at a time is ~10 % faster).
constexpr int kBlockLanes = 8;
template <int L0>
inline void batch_stiffness_blocks(const double (&R)[9][kBatch], const BatchInput& in,
                                   const Lanes& scale, double (&B)[10][9][kBlockLanes]) {
#pragma omp simd
  for (int j = 0; j < kBlockLanes; ++j) {
    const int l = L0 + j;
    double g[4][3], r[4][3];
    for (int a = 0; a < 3; ++a)
      for (int i = 0; i < 3; ++i) g[a + 1][i] = in.g[3 * a + i][l];
    for (int i = 0; i < 3; ++i) g[0][i] = -(g[1][i] + g[2][i] + g[3][i]);
#pragma GCC unroll 4
    for (int a = 0; a < 4; ++a)
      for (int i = 0; i < 3; ++i)
        r[a][i] = R[3 * i][l] * g[a][0] + R[3 * i + 1][l] * g[a][1] + R[3 * i + 2][l] * g[a][2];
    const double sl = scale[l] * in.lambda[l], sm = scale[l] * in.mu[l];
#pragma GCC unroll 10
    for (int k = 0; k < 10; ++k) {
      const int a = kBlockPairs[k][0], b = kBlockPairs[k][1];
      const double gg = sm * (g[a][0] * g[b][0] + g[a][1] * g[b][1] + g[a][2] * g[b][2]);
      for (int i = 0; i < 3; ++i)
        for (int c = 0; c < 3; ++c)
          B[k][3 * i + c][j] = sl * r[a][i] * r[b][c] + sm * r[b][i] * r[a][c] + (i == c ? gg : 0.0);
    }
  }
}

/// Rotations of the batch into R[entry][lane].
template <ElementKernel K>
inline void batch_rotations(const FemModel& m, int32_t e0, int count, const BatchInput& in,
                            const double (&F)[9][kBatch], double (&R)[9][kBatch]) {
  if constexpr (K == ElementKernel::Linear) {
    for (int k = 0; k < 9; ++k)
      for (int l = 0; l < kBatch; ++l) R[k][l] = (k % 4 == 0) ? 1.0 : 0.0;
  } else if constexpr (K == ElementKernel::CorotationalPolar) {
    polar_rotation_batch<kBatch>(F, R);
  } else {
    for (int l = 0; l < kBatch; ++l) {
      double r[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
      if (l < count) {
        const double d1[3] = {in.d[0][l], in.d[1][l], in.d[2][l]};
        const double d2[3] = {in.d[3][l], in.d[4][l], in.d[5][l]};
        qr_rotation(m.rest_frame[e0 + l].data(), d1, d2, r);
      }
      for (int k = 0; k < 9; ++k) R[k][l] = r[k];
    }
  }
}

/// R[entry][lane] from / into 9 doubles per element (row-major), elements e0 .. e0 + count.
/// Spare lanes get the identity (finite, as gather's spare elements expect).
inline void load_rotations(const double* __restrict rot, int32_t e0, int count, double (&R)[9][kBatch]) {
  for (int l = 0; l < kBatch; ++l)
    for (int k = 0; k < 9; ++k) R[k][l] = l < count ? rot[9 * (e0 + l) + k] : ((k % 4 == 0) ? 1.0 : 0.0);
}
inline void store_rotations(const double (&R)[9][kBatch], int32_t e0, int count, double* __restrict rot) {
  for (int l = 0; l < count; ++l)
    for (int k = 0; k < 9; ++k) rot[9 * (e0 + l) + k] = R[k][l];
}

inline void scatter_nodal(const ElementParams& ep, const double (&c)[12][kBatch], int l,
                          double* __restrict out) {
  for (int a = 0; a < 4; ++a) {
    double* o = out + 3 * ep.node[a];
    o[0] += c[3 * a][l];
    o[1] += c[3 * a + 1][l];
    o[2] += c[3 * a + 2][l];
  }
}

/// The stiffness blocks of lanes [L0, L0 + kBlockLanes) of a batch, added to the matrix.
template <int L0>
void scatter_blocks(const FemModel& m, const ElasticPass& p, const double (&R)[9][kBatch], const BatchInput& in,
                    const Lanes& k_scale, int32_t e0, int count) {
  double B[10][9][kBlockLanes];
  batch_stiffness_blocks<L0>(R, in, k_scale, B);
  for (int j = 0; j < std::min(count - L0, kBlockLanes); ++j) {
    // Upper-triangle storage: 10 blocks per element, each added to the stored block that
    // holds it, transposed when its row node is the larger index.
    const ElementSlots& slot = m.slots[e0 + L0 + j];
    const auto& node = m.elements[e0 + L0 + j].node;
    for (int k = 0; k < 10; ++k) {
      const int a = kBlockPairs[k][0], b = kBlockPairs[k][1];
      double* __restrict S = p.kvals + 9 * slot[4 * a + b];
      if (node[a] <= node[b]) {
        for (int q = 0; q < 9; ++q) S[q] += B[k][q][j];
      } else {
        for (int i = 0; i < 3; ++i)
          for (int c = 0; c < 3; ++c) S[3 * i + c] += B[k][3 * c + i][j];
      }
    }
  }
}

/// The visco-elastic history stress of a batch's elements (viscoelastic.hpp): per lane the
/// force −V·R·H·g_a added to `fo` (when given) and the energy V·H:ε added to `en`, with
/// H = Σ(decayᵢ·Qᵢ − ggᵢ·σ₀ⁿ) from the state. Per batch of a visco-elastic range only.
void add_visco_history(const ElementRange& r, const ElasticPass& p, const ViscoStep& st, int32_t e0, int count,
                       const double (&R)[9][kBatch], const double (&F)[9][kBatch], const BatchInput& in,
                       double (*fo)[kBatch], double* en) {
  // H per lane (Voigt order xx, yy, zz, xy, xz, yz; lanes past `count` zero), then the rest
  // across the lanes together (vectorised: one element at a time it cost twice as much).
  double Hb[6][kBatch] = {};
  for (int l = 0; l < count; ++l) {
    const int64_t j = e0 + l - r.begin;
    double h6[6];
    visco_history(st, p.visco_q + r.visco_q_begin + 6 * st.terms * j, p.visco_s0 + r.visco_s0_begin + 6 * j, h6);
    for (int k = 0; k < 6; ++k) Hb[k][l] = h6[k];
  }
  double he[kBatch], P[9][kBatch];
#pragma omp simd
  for (int l = 0; l < kBatch; ++l) {
    const double H[9] = {Hb[0][l], Hb[3][l], Hb[4][l], Hb[3][l], Hb[1][l], Hb[5][l], Hb[4][l], Hb[5][l], Hb[2][l]};
    double S[9];  // RᵀF
    for (int i = 0; i < 3; ++i)
      for (int k = 0; k < 3; ++k) S[3 * i + k] = R[i][l] * F[k][l] + R[3 + i][l] * F[3 + k][l] + R[6 + i][l] * F[6 + k][l];
    // H:ε with ε = sym(RᵀF) − I (H symmetric: H:sym(S) = H:S).
    double e = 0;
    for (int k = 0; k < 9; ++k) e += H[k] * S[k];
    he[l] = in.vol[l] * (e - H[0] - H[4] - H[8]);
    for (int i = 0; i < 3; ++i)  // −V·R·H
      for (int k = 0; k < 3; ++k)
        P[3 * i + k][l] = -in.vol[l] * (R[3 * i][l] * H[k] + R[3 * i + 1][l] * H[3 + k] + R[3 * i + 2][l] * H[6 + k]);
  }
  for (int l = 0; l < count; ++l) en[l] += he[l];
  if (!fo) return;
#pragma omp simd
  for (int l = 0; l < kBatch; ++l)
    for (int a = 0; a < 3; ++a)
      for (int i = 0; i < 3; ++i) {
        const double v = P[3 * i][l] * in.g[3 * a][l] + P[3 * i + 1][l] * in.g[3 * a + 1][l] + P[3 * i + 2][l] * in.g[3 * a + 2][l];
        fo[3 * (a + 1) + i][l] += v;
        fo[i][l] -= v;
      }
}

template <ElementKernel K, bool kHasKv, bool kHasK>
double pass_range(const FemModel& m, const ElasticPass& p, const ElementRange& r) {
  const int32_t begin = r.begin, end = r.end;
  double energy = 0.0;
  BatchInput in;
  double F[9][kBatch], R[9][kBatch], fo[12][kBatch], en[kBatch];
  Lanes force_scale, kv_scale, k_scale;  // force_scale = +V: the forces are −V·P·g_a
  // A visco-elastic range stepped over h: stiffness c(h)·(λ, μ) plus the history stress.
  const bool visco = r.visco >= 0 && p.visco_q != nullptr;
  const ViscoStep vstep = visco ? visco_step(m.visco[r.visco], p.visco_h) : ViscoStep{};
  for (int32_t e0 = begin; e0 < end; e0 += kBatch) {
    const int count = std::min<int32_t>(kBatch, end - e0);
    gather(m, p.x, e0, count, in, p.damage);
    if (visco)
      for (int l = 0; l < count; ++l) {
        in.lambda[l] *= vstep.c;
        in.mu[l] *= vstep.c;
      }
    if (r.smoothed && !p.unsmoothed)  // locking-free: the elements keep a share of the deviatoric part
      for (int l = 0; l < count; ++l) {  // (and element patches a share of the bulk, too)
        const double kappa = in.lambda[l] + (2.0 / 3.0) * in.mu[l];
        in.mu[l] *= r.element_share;
        in.lambda[l] = -(2.0 / 3.0) * in.mu[l] + r.element_bulk_share * kappa;
      }
    batch_gradient(in.d, in.g, F);
    if (K != ElementKernel::Linear && p.rotations_in)
      load_rotations(p.rotations_in, e0, count, R);
    else
      batch_rotations<K>(m, e0, count, in, F, R);
    if (!kHasKv && !kHasK && !p.force) {  // energy only (and the rotations when asked)
      batch_energy(R, F, in, en);
      if (visco) add_visco_history(r, p, vstep, e0, count, R, F, in, nullptr, en);
      for (int l = 0; l < count; ++l) energy += en[l];
      if (p.rotations) store_rotations(R, e0, count, p.rotations);
      continue;
    }
    for (int l = 0; l < kBatch; ++l) force_scale[l] = in.vol[l];
    batch_stress_forces(R, F, in, 1.0, force_scale, fo, en);
    if (visco) add_visco_history(r, p, vstep, e0, count, R, F, in, fo, en);
    for (int l = 0; l < count; ++l) {
      const ElementParams& ep = m.elements[e0 + l];
      energy += en[l];
      if (p.force) scatter_nodal(ep, fo, l, p.force);
    }
    if (p.rotations) store_rotations(R, e0, count, p.rotations);
    if constexpr (kHasKv) {
      // K·v = V·R·σ(sym(Rᵀ L))·g_a with L the velocity gradient (a negative scale turns the
      // force sign convention of batch_stress_forces into +K·v).
      BatchInput vin;
      gather(m, p.v, e0, count, vin);
      double L[9][kBatch], kv[12][kBatch];
      batch_gradient(vin.d, in.g, L);
      for (int l = 0; l < kBatch; ++l) kv_scale[l] = -in.vol[l] * (p.kv_beta * in.beta[l] + p.kv_const);
      batch_stress_forces(R, L, in, 0.0, kv_scale, kv, nullptr);
      for (int l = 0; l < count; ++l) scatter_nodal(m.elements[e0 + l], kv, l, p.kv);
    }
    static_assert(kBatch == ElasticPass::kPassBatch, "ElasticPass::blocks_due counts the pass's batches");
    if constexpr (kHasK) {
      if (!p.blocks_due(e0)) continue;
      for (int l = 0; l < kBatch; ++l) k_scale[l] = in.vol[l] * (p.k_beta * in.beta[l] + p.k_const);
      scatter_blocks<0>(m, p, R, in, k_scale, e0, count);
      if (count > kBlockLanes) scatter_blocks<kBlockLanes>(m, p, R, in, k_scale, e0, count);
    }
  }
  return energy;
}

template <ElementKernel K>
double dispatch_flags(const FemModel& m, const ElasticPass& p, const ElementRange& r) {
  const bool kv = p.kv != nullptr, k = p.kvals != nullptr;
  if (kv && k) return pass_range<K, true, true>(m, p, r);
  if (kv) return pass_range<K, true, false>(m, p, r);
  if (k) return pass_range<K, false, true>(m, p, r);
  return pass_range<K, false, false>(m, p, r);
}

/// The pass over range r (its kernel Linear, CorotationalPolar or CorotationalQR; 0 for any
/// other) with p's inputs and outputs (ElasticPass). Returns the range's elastic energy.
inline double corotational_pass(const FemModel& m, const ElasticPass& p, const ElementRange& r) {
  switch (r.kernel) {
    case ElementKernel::Linear: return dispatch_flags<ElementKernel::Linear>(m, p, r);
    case ElementKernel::CorotationalPolar: return dispatch_flags<ElementKernel::CorotationalPolar>(m, p, r);
    case ElementKernel::CorotationalQR: return dispatch_flags<ElementKernel::CorotationalQR>(m, p, r);
    default: return 0.0;  // (the hyperelastic kernels have their own passes)
  }
}

}  // namespace

}  // namespace stroma
