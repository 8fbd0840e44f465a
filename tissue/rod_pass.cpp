#include "tissue/rod_pass.hpp"

#include <cmath>

namespace stroma {

namespace {

/// y += s·B·v for a 3×3 row-major B.
inline void add_mv(double* y, double s, const double* B, const double* v) {
  for (int r = 0; r < 3; ++r) y[r] += s * (B[3 * r] * v[0] + B[3 * r + 1] * v[1] + B[3 * r + 2] * v[2]);
}

inline void add_scaled(double* S, double s, const double* B) {
  for (int q = 0; q < 9; ++q) S[q] += s * B[q];
}

inline void add_identity(double* S, double s) {
  S[0] += s;
  S[4] += s;
  S[8] += s;
}

}  // namespace

double rod_pass(const FemModel& m, const ElasticPass& p) {
  double energy = 0;
  const double* x = p.x;
  for (const RodRange& r : m.rods) {
    const double kscale = p.k_beta * r.beta + p.k_const;
    const double vscale = p.kv_beta * r.beta + p.kv_const;
    const int32_t* slot = m.rod_slots.data() + r.slot_begin;
    // Stretching: one axial spring per segment.
    for (int32_t i = r.node_begin; i + 1 < r.node_end; ++i, slot += 3) {
      const int32_t j = i + 1;
      const double e[3] = {x[3 * j] - x[3 * i], x[3 * j + 1] - x[3 * i + 1], x[3 * j + 2] - x[3 * i + 2]};
      const double len = std::sqrt(e[0] * e[0] + e[1] * e[1] + e[2] * e[2]);
      const double stretch = len - r.segment_length;
      energy += 0.5 * r.stretch_stiffness * stretch * stretch;
      if (len <= 0) continue;  // no direction: no force, no tangent
      const double t[3] = {e[0] / len, e[1] / len, e[2] / len};
      if (p.force) {
        const double f = r.stretch_stiffness * stretch;  // tension > 0 pulls the ends together
        for (int k = 0; k < 3; ++k) {
          p.force[3 * i + k] += f * t[k];
          p.force[3 * j + k] -= f * t[k];
        }
      }
      if (!p.kvals && !p.kv) continue;
      // H = k_s (t tᵀ + g (I − t tᵀ)), g = max(0, 1 − ℓ/|e|): the block (j, j) = (i, i) = −(i, j).
      const double g = stretch > 0 ? stretch / len : 0.0;
      double H[9];
      for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b) H[3 * a + b] = r.stretch_stiffness * ((1 - g) * t[a] * t[b] + (a == b ? g : 0.0));
      if (p.kvals) {
        add_scaled(p.kvals + 9 * slot[0], kscale, H);
        add_scaled(p.kvals + 9 * slot[1], -kscale, H);
        add_scaled(p.kvals + 9 * slot[2], kscale, H);
      }
      if (p.kv && vscale != 0) {
        const double dv[3] = {p.v[3 * j] - p.v[3 * i], p.v[3 * j + 1] - p.v[3 * i + 1], p.v[3 * j + 2] - p.v[3 * i + 2]};
        add_mv(p.kv + 3 * j, vscale, H, dv);
        add_mv(p.kv + 3 * i, -vscale, H, dv);
      }
    }
    // Bending: ½ k_b |x_{i−1} − 2 x_i + x_{i+1}|² per interior node; Hessian k_b w wᵀ ⊗ I,
    // w = (1, −2, 1).
    const double kb = r.bend_stiffness;
    for (int32_t i = r.node_begin + 1; i + 1 < r.node_end; ++i, slot += 6) {
      const int32_t a = i - 1, c = i + 1;
      double d[3];
      for (int k = 0; k < 3; ++k) d[k] = x[3 * a + k] - 2 * x[3 * i + k] + x[3 * c + k];
      energy += 0.5 * kb * (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
      if (p.force)
        for (int k = 0; k < 3; ++k) {
          p.force[3 * a + k] -= kb * d[k];
          p.force[3 * i + k] += 2 * kb * d[k];
          p.force[3 * c + k] -= kb * d[k];
        }
      if (p.kvals) {
        const double s = kscale * kb;
        add_identity(p.kvals + 9 * slot[0], s);       // (a, a)   1·1
        add_identity(p.kvals + 9 * slot[1], -2 * s);  // (a, i)   1·(−2)
        add_identity(p.kvals + 9 * slot[2], s);       // (a, c)   1·1
        add_identity(p.kvals + 9 * slot[3], 4 * s);   // (i, i)   (−2)·(−2)
        add_identity(p.kvals + 9 * slot[4], -2 * s);  // (i, c)   (−2)·1
        add_identity(p.kvals + 9 * slot[5], s);       // (c, c)   1·1
      }
      if (p.kv && vscale != 0) {
        const double s = vscale * kb;
        for (int k = 0; k < 3; ++k) {
          const double dv = p.v[3 * a + k] - 2 * p.v[3 * i + k] + p.v[3 * c + k];
          p.kv[3 * a + k] += s * dv;
          p.kv[3 * i + k] -= 2 * s * dv;
          p.kv[3 * c + k] += s * dv;
        }
      }
    }
  }
  // Anchors: ½ k |x_r − Σ w_a x_a|²; Hessian k c cᵀ ⊗ I, c = (1, −w_0 … −w_3) (rod.hpp).
  const int32_t* anchor_slot = m.rod_slots.data() + (m.rod_anchors.empty() ? 0 : m.rod_anchors.front().slot_begin);
  for (const RodAnchor& an : m.rod_anchors) {
    const int32_t nodes[5] = {an.node, an.tissue[0], an.tissue[1], an.tissue[2], an.tissue[3]};
    const double c[5] = {1.0, -an.w[0], -an.w[1], -an.w[2], -an.w[3]};
    double d[3] = {0, 0, 0};
    for (int a = 0; a < 5; ++a)
      for (int k = 0; k < 3; ++k) d[k] += c[a] * x[3 * nodes[a] + k];
    energy += 0.5 * an.stiffness * (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    if (p.force)
      for (int a = 0; a < 5; ++a)
        for (int k = 0; k < 3; ++k) p.force[3 * nodes[a] + k] -= an.stiffness * c[a] * d[k];
    const double kscale = p.k_beta * an.beta + p.k_const;
    const double vscale = p.kv_beta * an.beta + p.kv_const;
    if (p.kvals) {
      const int32_t* slot = anchor_slot;
      for (int a = 0; a < 5; ++a)
        for (int b = a; b < 5; ++b) add_identity(p.kvals + 9 * *slot++, kscale * an.stiffness * c[a] * c[b]);
    }
    if (p.kv && vscale != 0) {
      double dv[3] = {0, 0, 0};
      for (int a = 0; a < 5; ++a)
        for (int k = 0; k < 3; ++k) dv[k] += c[a] * p.v[3 * nodes[a] + k];
      for (int a = 0; a < 5; ++a)
        for (int k = 0; k < 3; ++k) p.kv[3 * nodes[a] + k] += vscale * an.stiffness * c[a] * dv[k];
    }
    anchor_slot += kRodAnchorSlots;
  }
  return energy;
}

}  // namespace stroma
