#pragma once
/// \file bsr_matrix.hpp
/// Block sparse row matrix with 3×3 blocks and a sparsity pattern fixed at compile time.
/// The pattern and the element→slot scatter maps are built once from the mesh; each tick only
/// the values are refilled (no allocation, no search).

#include <array>
#include <cstdint>
#include <vector>

#include "tissue/tet_mesh.hpp"

namespace stroma {

/// Sparsity of a symmetric 3×3-block matrix over `n` nodes, upper triangle only: row i stores
/// the blocks (i, j) with j ≥ i; block (j, i) is the transpose of (i, j) and is not stored.
/// Every row has its diagonal block, first (columns in each row are sorted ascending).
/// Why upper only: the element pass adds 10 blocks per tetrahedron instead of 16 and the SpMV
/// reads ~0.55× the bytes (docs/PERFORMANCE.md, "Physical scale": the optimisations table).
struct BsrPattern {
  int32_t n = 0;                  ///< block rows (= nodes)
  std::vector<int32_t> row_ptr;   ///< n+1 offsets into `col`
  std::vector<int32_t> col;       ///< block column of each slot
  std::vector<int32_t> diag;      ///< slot of the diagonal block of each row
  /// Number of stored blocks.
  int32_t nnzb() const { return static_cast<int32_t>(col.size()); }
  /// Slot of block (i, j), i ≤ j, or -1 if not in the pattern (binary search; load time only).
  int32_t find(int32_t i, int32_t j) const;
  /// Slot of the stored block holding (i, j) or its transpose: find(min, max).
  int32_t find_upper(int32_t i, int32_t j) const { return i <= j ? find(i, j) : find(j, i); }
};

/// Scatter map of one tetrahedron: slot[4a+b] is the slot of the stored block holding
/// (node a, node b): block (node a, node b) itself when node a ≤ node b, else its transpose's.
/// Only the pairs a ≤ b are ever added (the element's block (a, b) transposed when
/// node a > node b); slot[4a+b] == slot[4b+a].
using ElementSlots = std::array<int32_t, 16>;

/// Builds the pattern coupling the nodes of each tetrahedron, and each element's scatter map.
/// Nodes are 0..n-1; `tets` may be the concatenation of several bodies (already offset).
/// `group_ptr`/`group_node` (CSR, may be empty): further node groups whose every pair is
/// coupled too (the locking-free node domains, tissue/nodal_smoothing.hpp).
BsrPattern build_bsr_pattern(int32_t n, const std::vector<Tet>& tets, std::vector<ElementSlots>& slots,
                             const std::vector<int32_t>& group_ptr = {},
                             const std::vector<int32_t>& group_node = {});

/// y = A·x for the symmetric matrix whose upper triangle `vals` holds (9 doubles per slot,
/// row-major blocks): each off-diagonal block is applied as (i, j) and, transposed, as (j, i).
void bsr_spmv(const BsrPattern& p, const double* vals, const double* x, double* y);

/// Adds the 3×3 block B (row-major) of pair (node a, node b) to the upper-triangle values at
/// `slot` (the slot of find_upper(a, b)): B itself if a ≤ b, else Bᵀ.
inline void add_block_upper(double* __restrict vals, int32_t slot, bool transposed, const double* __restrict B) {
  double* __restrict S = vals + 9 * slot;
  if (!transposed) {
    for (int q = 0; q < 9; ++q) S[q] += B[q];
  } else {
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) S[3 * i + j] += B[3 * j + i];
  }
}

}  // namespace stroma
