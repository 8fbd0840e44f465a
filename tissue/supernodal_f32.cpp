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
    val_.resize(L->xsize);
    int32_t max_rows = 0;
    for (int32_t k = 0; k < nsuper_; ++k) max_rows = std::max(max_rows, pi[k + 1] - pi[k]);
    y_.assign(L->n, 0.0);
    tmp_.assign(max_rows, 0.0);
    n_ = static_cast<int32_t>(L->n);
  }
  for (size_t k = 0; k < val_.size(); ++k) val_[k] = static_cast<float>(x[k]);
  return true;
}

namespace {
/// Σ a[i]·b[i] with eight partial sums (one running sum would be a chain of dependent adds).
inline double dot(const float* a, const double* b, int32_t n) {
  double p[8] = {0, 0, 0, 0, 0, 0, 0, 0};
  int32_t i = 0;
  for (; i + 8 <= n; i += 8)
    for (int l = 0; l < 8; ++l) p[l] += a[i + l] * b[i + l];
  for (; i < n; ++i) p[0] += a[i] * b[i];
  return ((p[0] + p[1]) + (p[2] + p[3])) + ((p[4] + p[5]) + (p[6] + p[7]));
}
}  // namespace

void SupernodalF32::solve(const double* b, double* x) const {
  double* y = y_.data();
  double* w = tmp_.data();
  for (int32_t k = 0; k < n_; ++k) y[k] = b[perm_[k]];
  // Each supernode's columns k1..k1+nscol are a dense nsrow × nscol block (column-major), whose
  // first nscol rows are the diagonal block's lower triangle and the rest the rows `rows`. The
  // solves work on w = [y of the supernode's columns, y of its other rows], so every column's
  // update (forward) or dot product (backward) is one contiguous loop over the column.
  // Forward, L y = Pb.
  for (int32_t s = 0; s < nsuper_; ++s) {
    const int32_t k1 = super_[s], nscol = super_[s + 1] - k1;
    const int32_t nsrow = pi_[s + 1] - pi_[s];
    const int32_t* rows = rows_.data() + pi_[s];
    const float* Ls = val_.data() + px_[s];
    std::copy(y + k1, y + k1 + nscol, w);
    std::fill(w + nscol, w + nsrow, 0.0);
    for (int32_t j = 0; j < nscol; ++j) {
      const float* col = Ls + static_cast<size_t>(j) * nsrow;
      const double wj = w[j] / col[j];
      w[j] = wj;
      for (int32_t i = j + 1; i < nsrow; ++i) w[i] -= col[i] * wj;
    }
    std::copy(w, w + nscol, y + k1);
    for (int32_t i = nscol; i < nsrow; ++i) y[rows[i]] += w[i];
  }
  // Backward, Lᵀ z = y, supernodes in reverse (the rows below are final by then).
  for (int32_t s = nsuper_ - 1; s >= 0; --s) {
    const int32_t k1 = super_[s], nscol = super_[s + 1] - k1;
    const int32_t nsrow = pi_[s + 1] - pi_[s];
    const int32_t* rows = rows_.data() + pi_[s];
    const float* Ls = val_.data() + px_[s];
    std::copy(y + k1, y + k1 + nscol, w);
    for (int32_t i = nscol; i < nsrow; ++i) w[i] = y[rows[i]];
    for (int32_t j = nscol - 1; j >= 0; --j) {
      const float* col = Ls + static_cast<size_t>(j) * nsrow;
      w[j] = (w[j] - dot(col + j + 1, w + j + 1, nsrow - j - 1)) / col[j];
    }
    std::copy(w, w + nscol, y + k1);
  }
  for (int32_t k = 0; k < n_; ++k) x[perm_[k]] = y[k];
}

}  // namespace stroma
