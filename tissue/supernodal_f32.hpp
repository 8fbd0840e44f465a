#pragma once
/// \file supernodal_f32.hpp
/// A single-precision copy of a CHOLMOD supernodal LLᵀ factor and its two triangular solves,
/// for preconditioning: the warped Cholesky preconditioner applies a factor once per CG
/// iteration (5.5 MB in double for SOFA's 6,480-tet beam; half in float). The solves are
/// hand-written for that one use: each supernode's diagonal triangle in panels of kPanel
/// columns, each panel's small triangle by its precomputed inverse (no chain of dependent
/// divisions and updates), and everything below a panel — the rest of the triangle and the
/// off-diagonal rows, contiguous in each column — by register-blocked products (forward: 32 rows
/// of w held in registers while the panel's columns stream by; backward: four columns' dot
/// products sharing each load of w). Accumulation is in double; the factor's rounding (~1e-7
/// relative) only changes the preconditioner, never what CG converges to, and the operator
/// stays symmetric to that rounding. Measured against cholmod_solve2 in docs/PERFORMANCE.md
/// (the factor fits this machine's caches: the solve is bound by its instructions, not memory).

#include <cstddef>
#include <cstdint>
#include <vector>

namespace stroma {

/// Invariant: after load(), solve() applies (P LLᵀ Pᵀ)⁻¹ with the loaded factor's values
/// rounded to float; the structure (supernodes, rows, permutation) is that of the factor.
/// solve() allocates nothing.
class SupernodalF32 {
 public:
  /// Copies the structure (once) and the values of a supernodal LLᵀ cholmod_factor (int
  /// version). Returns false (nothing loaded) if the factor is not supernodal LLᵀ.
  bool load(const void* cholmod_factor);
  /// x = A⁻¹ b (n = the factor's size); b and x may not alias.
  void solve(const double* b, double* x) const;
  bool loaded() const { return n_ > 0; }
  /// Rows of L21 the forward solve keeps in registers at once (four 8-wide accumulators).
  static constexpr int kRows = 32;
  /// Columns of a diagonal triangle solved as one small triangle (by its precomputed inverse);
  /// the rest of the triangle is updated by register-blocked products (a large supernode's
  /// triangle holds ~1/3 of the factor).
  static constexpr int32_t kPanel = 8;
  /// Floats of zeros after the factor's values: the forward row blocks read up to kRows − 1,
  /// the backward padded dot products up to 7, past a block's last row.
  static constexpr size_t kPad = kRows;

 private:
  int32_t n_ = 0, nsuper_ = 0;
  std::vector<int32_t> super_, pi_, px_, rows_, perm_;
  std::vector<float> val_;
  /// Per panel (supernodes in order, kPanel columns each; supernode s's first is panel_ptr_[s])
  /// its triangle's inverse T⁻¹ and T⁻ᵀ, kPanel × kPanel column-major, rounded to float (in
  /// double the solves measured slower). T⁻ᵀ is T⁻¹ stored transposed so that the backward
  /// solve's product streams columns as the forward one does (no horizontal sums).
  std::vector<int32_t> panel_ptr_;
  std::vector<float> panel_inv_, panel_inv_t_;
  mutable std::vector<double> y_, tmp_;
};

}  // namespace stroma
