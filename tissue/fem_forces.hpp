#pragma once
/// \file fem_forces.hpp
/// The per-element pass of a tick: rotations, elastic forces, stiffness-times-velocity for the
/// damping and implicit right-hand side, and assembly of the stiffness-warped tangent R·Ke·Rᵀ
/// into the fixed BSR pattern — all in one sweep over the elements.
///
/// Ke is never stored: with shape gradients g_a and rotated gradients r_a = R·g_a,
///   R·K_ab·Rᵀ = V (λ r_a r_bᵀ + μ r_b r_aᵀ + μ (g_a·g_b) I),
/// and the elastic force is f_a = −V·R·σ(ε)·g_a with ε = sym(RᵀF) − I, σ = λ tr(ε) I + 2μ ε,
/// which equals −R·Ke·(Rᵀx − X) and, for the polar R, is exactly −∂E/∂x.

#include "tissue/fem_model.hpp"

namespace stroma {

/// Inputs and outputs of one element pass. Output arrays are accumulated into (+=): the
/// caller zeroes them. Null outputs are skipped (their work is not done).
/// Which parts of the model an elastic pass runs over: the element ranges, the rest (the
/// locking-free node domains and element patches, the rods), or both.
enum class PassParts : uint8_t { All, Elements, Rest };

struct ElasticPass {
  const double* x = nullptr;   ///< 3n current positions (required)
  double* force = nullptr;     ///< 3n: += elastic force
  const double* v = nullptr;   ///< 3n velocities, required when kv is set
  double* kv = nullptr;        ///< 3n: += (kv_beta·β_e + kv_const)·K_e·v
  double kv_beta = 0, kv_const = 0;
  double* kvals = nullptr;     ///< BSR values: += (k_beta·β_e + k_const)·R·Ke·Rᵀ
  double k_beta = 0, k_const = 0;
  /// 9 per element: the element rotation (row-major). An energy-only pass (no force, no
  /// matrix) writes those of the corotational and linear ranges only, not the hyperelastic.
  double* rotations = nullptr;
  /// 9 per element: the corotational elements' rotations at x, already computed (an energy
  /// pass's `rotations` at the same positions); used instead of recomputing them. Null: computed.
  const double* rotations_in = nullptr;
  const float* damage = nullptr;  ///< per element damage d: λ, μ scaled by (1 − d); null = none
  /// Visco-elastic state (TissueState::visco_q / visco_s0) and the step length h ≥ 0 it is
  /// stepped over: a visco-elastic range's stress is c(h)·σ₀ + H (viscoelastic.hpp). Null: the
  /// instantaneous elastic response (c = 1, H = 0).
  const double* visco_q = nullptr;
  const double* visco_s0 = nullptr;
  double visco_h = 0;
  /// Locking-free bodies with a matrix-free tangent (NodalSmoothing::matrix_free): where the
  /// node domains record their part of the system when kvals is set (required then).
  NodalSystem* nodal_system = nullptr;
  /// Compute locking-free bodies as plain elements with their full material, without node
  /// domains: the warped preconditioner's one-ring stand-in for the smoothed system.
  bool unsmoothed = false;
  PassParts parts = PassParts::All;  ///< see PassParts
  /// With k_every > 1, only a share of the elements add their blocks to kvals: the batches
  /// (kPassBatch elements from e0 on) whose e0 / kPassBatch ≡ k_phase (mod k_every) — over
  /// k_every passes with phases 0 … k_every − 1, every batch of every range exactly once.
  static constexpr int32_t kPassBatch = 16;  ///< the element passes' batch (each asserts it)
  int k_every = 1, k_phase = 0;
  bool blocks_due(int32_t e0) const { return k_every <= 1 || (e0 / kPassBatch) % k_every == k_phase; }
};

/// Runs the pass over every element; returns the total elastic energy
/// Σ V (μ ε:ε + λ/2 tr²ε).
double elastic_pass(const FemModel& m, const ElasticPass& pass);

/// Brings the visco-elastic internal variables to positions x at the end of a step of length h
/// (viscoelastic.hpp; defined in tissue/viscoelastic.cpp, beside the Prony series it steps): Qᵢ ← e^(−h/τᵢ)Qᵢ + gᵢγᵢ(σ₀(x) − σ₀ⁿ), σ₀ⁿ ← σ₀(x). `damage` scales σ₀
/// as it scales the element (null: none). Nothing without visco-elastic ranges.
void viscous_update(const FemModel& m, const double* x, const float* damage, double h, double* visco_q,
                    double* visco_s0);

/// Energy stored in the visco-elastic branches, Σ V·½·Qᵢ : Cᵢ⁻¹ : Qᵢ with Cᵢ = gᵢ·C₀ (0
/// without visco-elastic ranges). Total mechanical energy = kinetic + elastic + this.
double viscous_stored_energy(const FemModel& m, const double* visco_q);

/// Per-element von Mises stress of the corotated small strain (Pa) at positions x.
void element_von_mises(const FemModel& m, const double* x, double* out);

}  // namespace stroma
