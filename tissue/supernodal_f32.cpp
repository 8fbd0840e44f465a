#include "tissue/supernodal_f32.hpp"

#include <cholmod.h>

#include <algorithm>

namespace stroma {

bool SupernodalF32::load(const void* factor) {
  const auto* L = static_cast<const cholmod_factor*>(factor);
  if (!L || !L->is_super || !L->is_ll || L->itype != CHOLMOD_INT || L->xtype != CHOLMOD_REAL) return false;
  const auto* super = static_cast<const int*>(L->super);
  const auto* pi = static_cast<const int*>(L->pi);
  const auto* px = static_cast<const int*>(L->px);
  const auto* s = static_cast<const int*>(L->s);
  const auto* x = static_cast<const double*>(L->x);
  if (n_ == 0) {  // structure: fixed by the symbolic analysis, copied once
    nsuper_ = static_cast<int32_t>(L->nsuper);
    super_.assign(super, super + nsuper_ + 1);
    pi_.assign(pi, pi + nsuper_ + 1);
    px_.assign(px, px + nsuper_ + 1);
    rows_.assign(s, s + pi[nsuper_]);
    perm_.assign(static_cast<const int*>(L->Perm), static_cast<const int*>(L->Perm) + L->n);
    val_.assign(L->xsize + kPad, 0.0f);  // kPad: the blocked loops may read past the last column
    int32_t max_rows = 0;
    for (int32_t k = 0; k < nsuper_; ++k) max_rows = std::max(max_rows, pi[k + 1] - pi[k]);
    y_.assign(L->n, 0.0);
    panel_ptr_.assign(nsuper_ + 1, 0);
    for (int32_t k = 0; k < nsuper_; ++k) panel_ptr_[k + 1] = panel_ptr_[k] + (super[k + 1] - super[k] + kPanel - 1) / kPanel;
    panel_inv_.assign(static_cast<size_t>(panel_ptr_[nsuper_]) * kPanel * kPanel, 0.0f);
    panel_inv_t_.assign(panel_inv_.size(), 0.0f);
    tmp_.assign(static_cast<size_t>(max_rows) + 8, 0.0);  // + 8: zeros the padded dot products read
    n_ = static_cast<int32_t>(L->n);
  }
  for (size_t k = 0; k < L->xsize; ++k) val_[k] = static_cast<float>(x[k]);
  // Each panel's small triangle T (kPanel columns of a diagonal block) inverted, from the
  // rounded values: the solves multiply by T⁻¹ (forward) and T⁻ᵀ (backward) instead of running
  // the triangle's chain of dependent steps. Column-major 8 × 8, zero outside T⁻¹'s triangle.
  for (int32_t sn = 0; sn < nsuper_; ++sn) {
    const int32_t k1 = super_[sn], nscol = super_[sn + 1] - k1, nsrow = pi_[sn + 1] - pi_[sn];
    const float* Ls = val_.data() + px_[sn];
    for (int32_t p0 = 0; p0 < nscol; p0 += kPanel) {
      const size_t panel = static_cast<size_t>(panel_ptr_[sn] + p0 / kPanel);
      const int32_t np = std::min(kPanel, nscol - p0);
      double T[kPanel][kPanel] = {}, Ti[kPanel][kPanel] = {};  // [row][column]
      for (int32_t j = 0; j < np; ++j)
        for (int32_t i = j; i < np; ++i) T[i][j] = static_cast<double>(Ls[static_cast<size_t>(p0 + j) * nsrow + p0 + i]);
      for (int32_t c = 0; c < np; ++c)  // T·Ti[:, c] = e_c by forward substitution
        for (int32_t i = c; i < np; ++i) {
          double r = i == c ? 1.0 : 0.0;
          for (int32_t k = c; k < i; ++k) r -= T[i][k] * Ti[k][c];
          Ti[i][c] = r / T[i][i];
        }
      float* M = &panel_inv_[panel * kPanel * kPanel];
      float* Mt = &panel_inv_t_[panel * kPanel * kPanel];
      for (int32_t j = 0; j < kPanel; ++j)
        for (int32_t l = 0; l < kPanel; ++l) {
          M[j * kPanel + l] = static_cast<float>(Ti[l][j]);   // column j of T⁻¹
          Mt[j * kPanel + l] = static_cast<float>(Ti[j][l]);  // column j of T⁻ᵀ
        }
    }
  }
  return true;
}

namespace {

/// Σ_{i<n} a[i]·b[i] with eight partial sums, reading ⌈n/8⌉·8 entries of both: the caller
/// guarantees b is zero past n and a is readable (the factor is padded).
inline double dot8(const float* a, const double* b, int32_t n) {
  double p[8] = {0, 0, 0, 0, 0, 0, 0, 0};
  for (int32_t i = 0; i < n; i += 8)
    for (int l = 0; l < 8; ++l) p[l] += static_cast<double>(a[i + l]) * b[i + l];
  return ((p[0] + p[1]) + (p[2] + p[3])) + ((p[4] + p[5]) + (p[6] + p[7]));
}

/// out[c] = Σ_{i<n} L_c[i]·w[i] for four columns L_c = L + c·ld (the transposed product, four
/// columns sharing each load of w), padded as dot8.
inline void four_dots8(const float* L, int32_t ld, const double* w, int32_t n, double* out) {
  double p[4][8] = {};
  for (int32_t i = 0; i < n; i += 8)
    for (int c = 0; c < 4; ++c)
      for (int l = 0; l < 8; ++l) p[c][l] += static_cast<double>(L[static_cast<size_t>(c) * ld + i + l]) * w[i + l];
  for (int c = 0; c < 4; ++c)
    out[c] = ((p[c][0] + p[c][1]) + (p[c][2] + p[c][3])) + ((p[c][4] + p[c][5]) + (p[c][6] + p[c][7]));
}

/// acc[l] = Σ_j c_j[l]·w[j] for l < R, c_j = L + j·ld: R rows of a column-major block times a
/// vector, the rows kept in registers (R/8 8-wide accumulators; 32 rows hide the FMA latency)
/// while the columns stream by. Reads R rows even past the block's end (the caller uses only
/// its rows; the factor is padded).
template <int R>
inline void rows_times_vector(const float* L, int32_t ld, const double* w, int32_t ncol, double* acc) {
  double a[R];
  for (int l = 0; l < R; ++l) a[l] = 0.0;
  for (int32_t j = 0; j < ncol; ++j) {
    const float* c = L + static_cast<size_t>(j) * ld;
    const double wj = w[j];
    for (int l = 0; l < R; ++l) a[l] += static_cast<double>(c[l]) * wj;
  }
  for (int l = 0; l < R; ++l) acc[l] = a[l];
}

/// out[i] −= (L·w)[i] for the m rows of a column-major block (ld, ncol columns), kRows (32)
/// rows at a time and a last block of 8, 16 or 32 (the fewest lanes that cover it).
inline void subtract_block_times_vector(const float* L, int32_t ld, const double* w, int32_t ncol, int32_t m,
                                        double* out) {
  constexpr int kRows = SupernodalF32::kRows;
  static_assert(kRows == 32, "the last block picks 8, 16 or 32 lanes");
  double acc[kRows];
  for (int32_t i0 = 0; i0 < m; i0 += kRows) {
    const int32_t left = m - i0;
    if (left > 16) rows_times_vector<32>(L + i0, ld, w, ncol, acc);
    else if (left > 8) rows_times_vector<16>(L + i0, ld, w, ncol, acc);
    else rows_times_vector<8>(L + i0, ld, w, ncol, acc);
    const int32_t n = std::min<int32_t>(kRows, left);
    for (int32_t l = 0; l < n; ++l) out[i0 + l] -= acc[l];
  }
}

/// w[0..np) ← M·w[0..np) for a panel's 8 × 8 column-major M (zero past np columns' entries).
inline void panel_times(const float* M, double* w, int32_t np) {
  double t[8] = {0, 0, 0, 0, 0, 0, 0, 0};
  for (int32_t j = 0; j < np; ++j) {
    const double wj = w[j];
    for (int l = 0; l < 8; ++l) t[l] += static_cast<double>(M[j * 8 + l]) * wj;
  }
  for (int32_t l = 0; l < np; ++l) w[l] = t[l];
}

}  // namespace

void SupernodalF32::solve(const double* b, double* x) const {
  double* y = y_.data();
  double* w = tmp_.data();
  static_assert(kPanel == 8, "panel_times is written for 8 x 8 panels");
  for (int32_t k = 0; k < n_; ++k) y[k] = b[perm_[k]];
  // Each supernode's columns k1..k1+nscol are a dense nsrow × nscol block (column-major), whose
  // first nscol rows are the diagonal block's lower triangle and the rest the rows `rows`. Both
  // solves work on w = [y of the supernode's columns, y of its other rows] in panels of kPanel
  // columns: a panel's own small triangle by its precomputed inverse, and everything below it —
  // the rest of the triangle and the off-diagonal rows, one contiguous run of each column — by
  // register-blocked products (one load and store of w per row and panel, not per entry).
  // Forward, L y = Pb; w's off-diagonal rows collect the updates, added to y at the end.
  for (int32_t s = 0; s < nsuper_; ++s) {
    const int32_t k1 = super_[s], nscol = super_[s + 1] - k1;
    const int32_t nsrow = pi_[s + 1] - pi_[s];
    const int32_t* rows = rows_.data() + pi_[s];
    const float* Ls = val_.data() + px_[s];
    std::copy(y + k1, y + k1 + nscol, w);
    std::fill(w + nscol, w + nsrow, 0.0);
    for (int32_t p0 = 0; p0 < nscol; p0 += kPanel) {
      const int32_t p1 = std::min(p0 + kPanel, nscol);
      panel_times(&panel_inv_[static_cast<size_t>(panel_ptr_[s] + p0 / kPanel) * kPanel * kPanel], w + p0, p1 - p0);
      subtract_block_times_vector(Ls + static_cast<size_t>(p0) * nsrow + p1, nsrow, w + p0, p1 - p0, nsrow - p1, w + p1);
    }
    std::copy(w, w + nscol, y + k1);
    for (int32_t i = nscol; i < nsrow; ++i) y[rows[i]] += w[i];
  }
  // Backward, Lᵀ z = y, supernodes in reverse (the rows below are final by then), panels from
  // the last: each column's dot product with everything below its panel, four columns at a
  // time, then the panel's small triangle. w is zero past nsrow for the padded dot products.
  for (int32_t s = nsuper_ - 1; s >= 0; --s) {
    const int32_t k1 = super_[s], nscol = super_[s + 1] - k1;
    const int32_t nsrow = pi_[s + 1] - pi_[s];
    const int32_t* rows = rows_.data() + pi_[s];
    const float* Ls = val_.data() + px_[s];
    std::copy(y + k1, y + k1 + nscol, w);
    for (int32_t i = nscol; i < nsrow; ++i) w[i] = y[rows[i]];
    std::fill(w + nsrow, w + nsrow + 8, 0.0);
    for (int32_t p0 = (nscol - 1) / kPanel * kPanel; p0 >= 0; p0 -= kPanel) {
      const int32_t p1 = std::min(p0 + kPanel, nscol), below = nsrow - p1;
      if (below > 0) {
        int32_t c = p0;
        for (; c + 4 <= p1; c += 4) {
          double t[4];
          four_dots8(Ls + static_cast<size_t>(c) * nsrow + p1, nsrow, w + p1, below, t);
          for (int q = 0; q < 4; ++q) w[c + q] -= t[q];
        }
        for (; c < p1; ++c) w[c] -= dot8(Ls + static_cast<size_t>(c) * nsrow + p1, w + p1, below);
      }
      panel_times(&panel_inv_t_[static_cast<size_t>(panel_ptr_[s] + p0 / kPanel) * kPanel * kPanel], w + p0, p1 - p0);
    }
    std::copy(w, w + nscol, y + k1);
  }
  for (int32_t k = 0; k < n_; ++k) x[perm_[k]] = y[k];
}

}  // namespace stroma
