#pragma once
/// \file viscoelastic.hpp
/// Visco-elastic tissue: a generalised Maxwell model (Prony series) on the corotational
/// element. The relaxation modulus is
///
///   E(t) = E₀·[1 − Σᵢ gᵢ·(1 − e^(−t/τᵢ))],   E∞ = E₀·(1 − Σᵢ gᵢ),
///
/// with E₀ the scenario's (instantaneous) Young's modulus, gᵢ ∈ [0, 1) the branches' relative
/// moduli (Σ gᵢ < 1: a solid) and τᵢ > 0 their relaxation times. The same series scales λ and μ
/// (ν does not relax). The stress, in the element's rotated frame, is
///
///   σ = (1 − Σ gᵢ)·σ₀(ε) + Σ Qᵢ,   Q̇ᵢ + Qᵢ/τᵢ = gᵢ·σ̇₀,
///
/// σ₀ the instantaneous linear-elastic stress of the corotated strain, Qᵢ the branches'
/// overstresses: internal variables per element that live in the state (TissueState::visco_q,
/// with σ₀ of the step's start in visco_s0), so snapshot, rollback and replay keep them.
///
/// Time discretisation (Simo 1987; Simo & Hughes, "Computational Inelasticity", §10.3): over a
/// step h with σ₀ taken linear in time,
///
///   Qᵢⁿ⁺¹ = e^(−h/τᵢ)·Qᵢⁿ + gᵢ·γᵢ·(σ₀ⁿ⁺¹ − σ₀ⁿ),   γᵢ = (1 − e^(−h/τᵢ))/(h/τᵢ),
///
/// exact for a strain linear over the step, unconditionally stable and dissipative. Hence
/// σⁿ⁺¹ = c·σ₀ⁿ⁺¹ + H with c = 1 − Σ gᵢ(1 − γᵢ) and H = Σ (e^(−h/τᵢ)·Qᵢⁿ − gᵢγᵢ·σ₀ⁿ) fixed over
/// the step: the implicit system gets the consistent visco-elastic tangent c·K (no explicit lag,
/// no limit on h), and H is a stress the step's start already knows. At h = 0 (c = 1) the
/// formula is the present stress. After each step the internal variables are brought to the
/// new positions (viscous_update).
///
/// The named models are one-branch series: the standard linear solid (Kelvin form: a spring
/// E∞ in parallel with a Maxwell arm), g = 1 − E∞/E₀, τ = η/(E₀ − E∞); the Maxwell fluid,
/// g = 1 (allowed only under that name: nothing holds its shape under a constant load).
/// Kelvin–Voigt (a dashpot η in parallel with the spring) is stiffness-proportional damping
/// σ = E₀ε + ηε̇, i.e. Rayleigh β = η/E₀ (compile turns `kelvin_voigt` into it).

#include <cstdint>

namespace stroma {

inline constexpr int kMaxPronyTerms = 8;

/// One Prony series. Invariants: 1 ≤ terms ≤ kMaxPronyTerms; every g ∈ [0, 1] and τ > 0;
/// Σ g < 1 unless the series is the Maxwell fluid (one term, g = 1).
struct PronySeries {
  int terms = 0;
  double g[kMaxPronyTerms] = {};
  double tau[kMaxPronyTerms] = {};
};

/// What a step of length h (≥ 0) needs: the tangent scale c, per term the decay e^(−h/τ) and
/// g·γ.
struct ViscoStep {
  int terms = 0;
  double c = 1;
  double decay[kMaxPronyTerms] = {};
  double gg[kMaxPronyTerms] = {};
};

ViscoStep visco_step(const PronySeries& s, double h);

/// The history stress H (6 values, xx yy zz xy xz yz) of one element: Σ (decayᵢ·Qᵢ − ggᵢ·σ₀ⁿ).
/// `q`: its terms × 6 overstresses; `s0`: its σ₀ⁿ.
inline void visco_history(const ViscoStep& st, const double* q, const double* s0, double* H) {
  for (int k = 0; k < 6; ++k) H[k] = 0;
  for (int i = 0; i < st.terms; ++i)
    for (int k = 0; k < 6; ++k) H[k] += st.decay[i] * q[6 * i + k] - st.gg[i] * s0[k];
}

}  // namespace stroma
