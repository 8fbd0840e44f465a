#pragma once
/// \file supernodal_f32.hpp
/// A single-precision copy of a CHOLMOD supernodal LLᵀ factor and its two triangular solves,
/// for preconditioning: the warped Cholesky preconditioner applies a factor once per CG
/// iteration, and that solve streams the whole factor through memory (5.5 MB in double for
/// SOFA's 6,480-tet beam). In float it streams half, and the hand-written loops skip
/// CHOLMOD's per-supernode BLAS calls, which dominate small supernodes. Accumulation is in
/// double; the factor's rounding (~1e-7 relative) only changes the preconditioner, never what
/// CG converges to. Measured against cholmod_solve2 in docs/PERFORMANCE.md.

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

 private:
  int32_t n_ = 0, nsuper_ = 0;
  std::vector<int32_t> super_, pi_, px_, rows_, perm_;
  std::vector<float> val_;
  mutable std::vector<double> y_, tmp_;
};

}  // namespace stroma
