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

/// Sparsity of a symmetric 3×3-block matrix over `n` nodes; every row has its diagonal block.
/// Columns in each row are sorted ascending.
struct BsrPattern {
  int32_t n = 0;                  ///< block rows (= nodes)
  std::vector<int32_t> row_ptr;   ///< n+1 offsets into `col`
  std::vector<int32_t> col;       ///< block column of each slot
  std::vector<int32_t> diag;      ///< slot of the diagonal block of each row
  /// Number of stored blocks.
  int32_t nnzb() const { return static_cast<int32_t>(col.size()); }
  /// Slot of block (i, j), or -1 if not in the pattern (binary search; load time only).
  int32_t find(int32_t i, int32_t j) const;
};

/// Scatter map of one tetrahedron: slot[4a+b] is the slot of block (node a, node b).
using ElementSlots = std::array<int32_t, 16>;

/// Builds the pattern coupling the nodes of each tetrahedron, and each element's scatter map.
/// Nodes are 0..n-1; `tets` may be the concatenation of several bodies (already offset).
BsrPattern build_bsr_pattern(int32_t n, const std::vector<Tet>& tets,
                             std::vector<ElementSlots>& slots);

/// y = A·x for a BSR matrix with values `vals` (9 doubles per slot, row-major blocks).
void bsr_spmv(const BsrPattern& p, const double* vals, const double* x, double* y);

}  // namespace stroma
