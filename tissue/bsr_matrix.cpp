#include "tissue/bsr_matrix.hpp"

#include <algorithm>

namespace stroma {

int32_t BsrPattern::find(int32_t i, int32_t j) const {
  const auto b = col.begin() + row_ptr[i];
  const auto e = col.begin() + row_ptr[i + 1];
  const auto it = std::lower_bound(b, e, j);
  return (it != e && *it == j) ? static_cast<int32_t>(it - col.begin()) : -1;
}

BsrPattern build_bsr_pattern(int32_t n, const std::vector<Tet>& tets, std::vector<ElementSlots>& slots,
                             const std::vector<int32_t>& group_ptr, const std::vector<int32_t>& group_node) {
  std::vector<std::vector<int32_t>> adj(n);
  for (int32_t i = 0; i < n; ++i) adj[i].push_back(i);
  for (const Tet& t : tets)
    for (int a = 0; a < 4; ++a)
      for (int b = 0; b < 4; ++b)
        if (t[a] <= t[b]) adj[t[a]].push_back(t[b]);  // upper triangle only
  for (size_t g = 0; g + 1 < group_ptr.size(); ++g)
    for (int32_t a = group_ptr[g]; a < group_ptr[g + 1]; ++a)
      for (int32_t b = group_ptr[g]; b < group_ptr[g + 1]; ++b)
        if (group_node[a] <= group_node[b]) adj[group_node[a]].push_back(group_node[b]);
  BsrPattern p;
  p.n = n;
  p.row_ptr.assign(n + 1, 0);
  for (int32_t i = 0; i < n; ++i) {
    auto& r = adj[i];
    std::sort(r.begin(), r.end());
    r.erase(std::unique(r.begin(), r.end()), r.end());
    p.row_ptr[i + 1] = p.row_ptr[i] + static_cast<int32_t>(r.size());
  }
  p.col.reserve(p.row_ptr[n]);
  for (auto& r : adj) p.col.insert(p.col.end(), r.begin(), r.end());
  p.diag.resize(n);
  for (int32_t i = 0; i < n; ++i) p.diag[i] = p.find(i, i);
  slots.resize(tets.size());
  for (size_t e = 0; e < tets.size(); ++e)
    for (int a = 0; a < 4; ++a)
      for (int b = 0; b < 4; ++b) slots[e][4 * a + b] = p.find_upper(tets[e][a], tets[e][b]);
  return p;
}

void bsr_spmv(const BsrPattern& p, const double* __restrict vals, const double* __restrict x,
              double* __restrict y) {
  const int32_t* __restrict rp = p.row_ptr.data();
  const int32_t* __restrict cl = p.col.data();
  std::fill(y, y + 3 * static_cast<size_t>(p.n), 0.0);
  for (int32_t i = 0; i < p.n; ++i) {
    // Row i's diagonal block comes first; rows before i have already added their (k, i)ᵀ parts.
    const double x0 = x[3 * i], x1 = x[3 * i + 1], x2 = x[3 * i + 2];
    const double* D = vals + 9 * rp[i];
    double y0 = y[3 * i] + D[0] * x0 + D[1] * x1 + D[2] * x2;
    double y1 = y[3 * i + 1] + D[3] * x0 + D[4] * x1 + D[5] * x2;
    double y2 = y[3 * i + 2] + D[6] * x0 + D[7] * x1 + D[8] * x2;
    for (int32_t s = rp[i] + 1; s < rp[i + 1]; ++s) {
      const double* B = vals + 9 * s;
      const double* xj = x + 3 * cl[s];
      double* yj = y + 3 * cl[s];
      y0 += B[0] * xj[0] + B[1] * xj[1] + B[2] * xj[2];
      y1 += B[3] * xj[0] + B[4] * xj[1] + B[5] * xj[2];
      y2 += B[6] * xj[0] + B[7] * xj[1] + B[8] * xj[2];
      yj[0] += B[0] * x0 + B[3] * x1 + B[6] * x2;
      yj[1] += B[1] * x0 + B[4] * x1 + B[7] * x2;
      yj[2] += B[2] * x0 + B[5] * x1 + B[8] * x2;
    }
    y[3 * i] = y0;
    y[3 * i + 1] = y1;
    y[3 * i + 2] = y2;
  }
}

}  // namespace stroma
