#pragma once
/// \file rigid_rows.hpp
/// Rigid bodies' rows of the implicit step (docs/ARCHITECTURE.md, "Bodies of more than one
/// kind"): six unknowns per body touching something this step — Δu = (Δv of its centre of mass,
/// Δω), world frame — joined to the tissue's Δv by the contact springs that name a row
/// (ContactSpring::row_p, row_n). The step's linear system is then
///
///     [ A_tt  B    ] [Δv]   [b_t]        A_tt: the tissue's (M + hC + h²K) with its springs
///     [ Bᵀ    A_rr ] [Δu] = [b_r]        A_rr: M_r + Σ Gᵀ(h²K_s + hC_s)G over the rows' springs
///
/// with G the spring's relative velocity (tissue point − rigid point: W v − J u, J = [I, −[r]×]).
/// It is solved whole, by eliminating the rows: CG (or CHOLMOD) runs on the Schur complement
/// S = A_tt − B A_rr⁻¹ Bᵀ, applied matrix-free in each product (a few 3×3 and 6×6 products per
/// rigid spring), with b_t − B A_rr⁻¹ b_r, then Δu = A_rr⁻¹ (b_r − Bᵀ Δv). S is the system's
/// Schur complement, so symmetric positive definite: CG, its preconditioners and the tissue's
/// pattern are unchanged while bodies come and go. A_rr (6 per row, dense: rows touching each
/// other couple) is factored once per step; there are few rows.
///
/// The gyroscopic term ω × Iω is not in these rows: the caller steps it before (torque-free,
/// energy kept exactly: rigid/rigid_motion.hpp) and hands u0 with its ω.
///
/// Invariants: rows ≤ the capacity reserved; mass > 0; each inertia (world) is symmetric
/// positive definite; every spring's row_p, row_n < rows. No allocation after reserve().

#include <cstdint>
#include <vector>

#include "tissue/contact_spring.hpp"
#include "tissue/fem_model.hpp"

namespace stroma {

/// What the rows of one step are: the bodies the springs name, at the step's start.
struct RigidRowsInput {
  int32_t rows = 0;
  const double* mass = nullptr;     ///< kg, per row
  const double* inertia = nullptr;  ///< kg·m², 9 per row, world frame (R I_body Rᵀ)
  const double* u0 = nullptr;       ///< 6 per row: v (m/s), ω (rad/s) at the step's start
  const double* force = nullptr;    ///< 6 per row: applied force (N) and torque (N·m), e.g. m·g
  double* du = nullptr;             ///< 6 per row: the step's Δu (filled by the solve)
};

class RigidRows {
 public:
  /// Capacity: at most `rows` rows per step.
  void reserve(int32_t rows);
  int32_t capacity() const { return cap_; }
  /// Rows in the current step (0: none; the step is the tissue's alone).
  int32_t rows() const { return rows_; }
  /// The step's rows: forms A_rr (factored) and b_r from `in` and the springs at step h with
  /// tissue velocities v_t0, and adds the tissue's share of the anchors' start velocity,
  /// Wᵀ(h²K + hC)J u0, to rhs_t (free DOFs of m only). False if A_rr is not positive definite
  /// (then rows() is 0). `spring_force` (3 per spring; null: the springs' own): each spring's
  /// force where the step starts (StepInputs::spring_force).
  bool assemble(const RigidRowsInput& in, const ContactSpring* springs, int count, double h, const double* v_t0,
                double* rhs_t, const FemModel& m, const double* spring_force = nullptr);
  /// No rows this step.
  void clear() { rows_ = 0; }
  /// rhs_t −= B A_rr⁻¹ b_r: the reduced right-hand side.
  void reduce_rhs(double* rhs_t) const;
  /// y −= B A_rr⁻¹ Bᵀ x (adds the Schur term to A_tt·x).
  void apply(const double* x, double* y) const;
  /// Δu = A_rr⁻¹ (b_r − Bᵀ Δv) into the input's du.
  void back_substitute(const double* dv) const;
  /// The same as a CgSolver ExtraOperator (context: this).
  static void apply_fn(void* self, const double* x, double* y) { static_cast<const RigidRows*>(self)->apply(x, y); }

 private:
  /// z = Bᵀ x (6 per row).
  void mul_bt(const double* x, double* z) const;
  /// y −= B z (free DOFs).
  void sub_b(const double* z, double* y) const;
  /// z ← A_rr⁻¹ z with the factor.
  void solve_rr(double* z) const;
  int32_t cap_ = 0, rows_ = 0;
  const RigidRowsInput* in_ = nullptr;
  const ContactSpring* springs_ = nullptr;
  int count_ = 0;
  const FemModel* m_ = nullptr;
  double kscale_ = 0, cscale_ = 0;  ///< h², h: the springs' K' = h²K + hC
  std::vector<double> A_;           ///< (6 rows)², row-major; its Cholesky factor L (lower) after assemble
  std::vector<double> b_;           ///< 6 rows
  mutable std::vector<double> z_;   ///< 6 rows scratch
};

}  // namespace stroma
