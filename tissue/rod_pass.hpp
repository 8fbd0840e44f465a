#pragma once
/// \file rod_pass.hpp
/// The rods' part of the element pass (rod.hpp): forces, K·v for damping and the implicit
/// right-hand side, and the tangent stiffness into the rods' precomputed pattern slots.

#include "tissue/fem_forces.hpp"

namespace stroma {

/// Adds every rod's forces, K·v and stiffness as `pass` asks (the same conventions as the
/// elements': kvals += (k_beta·β + k_const)·K, kv += (kv_beta·β + kv_const)·K·v) and returns
/// their elastic energy. The stretching tangent is k_s·(t tᵀ + max(0, 1 − ℓ/|e|)·(I − t tᵀ)):
/// its geometric part dropped under compression, where it is negative, so K stays positive
/// semi-definite. No allocation; a segment of zero length contributes only its axial-free
/// energy ½·k_s·ℓ² and no force (no direction).
double rod_pass(const FemModel& m, const ElasticPass& pass);

}  // namespace stroma
