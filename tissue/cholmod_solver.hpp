#pragma once
/// \file cholmod_solver.hpp
/// Sparse direct solver (SuiteSparse CHOLMOD) for the symmetric positive definite BSR systems.
/// The symbolic analysis (fill-reducing ordering) is done once for the fixed pattern; each
/// factor() refills the values through a precomputed BSR→CSC map and refactors numerically.

#include <memory>
#include <vector>

#include "tissue/bsr_matrix.hpp"

namespace stroma {

/// CHOLMOD LLᵀ/LDLᵀ factorisation of a BSR matrix with a fixed pattern.
class CholmodSolver {
 public:
  /// Builds the upper-triangle CSC pattern and runs the symbolic analysis.
  explicit CholmodSolver(const BsrPattern& pattern);
  ~CholmodSolver();
  CholmodSolver(const CholmodSolver&) = delete;
  CholmodSolver& operator=(const CholmodSolver&) = delete;

  /// Solves with a single-precision copy of the factor (tissue/supernodal_f32.hpp) from the
  /// next factor() on: for preconditioning, where half the memory traffic matters and the
  /// factor's last digits do not. Call before factor().
  void use_float_solves() { float_solves_ = true; }
  /// Numeric factorisation of the matrix with BSR values `vals`. False if not positive definite.
  bool factor(const double* vals);
  /// x = A⁻¹ b with the last factorisation.
  void solve(const double* b, double* x);
  /// Stored entries of the factor L, explicit zeros of relaxed supernodes included (its memory
  /// is what a solve streams through).
  double factor_entries() const;
  /// Floating-point operations of one numeric factorisation (from the symbolic analysis).
  double factor_flops() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  bool float_solves_ = false;
};

}  // namespace stroma
