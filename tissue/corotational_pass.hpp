#pragma once
/// \file corotational_pass.hpp
/// The corotational kernels (polar and QR rotation; docs/TISSUE.md) and the linear one: one
/// element range's pass in batches of kBatch elements — gather, rotations (`batch_rotations`),
/// rotated stress and nodal forces (`batch_stress_forces`), K·v, the warped stiffness blocks
/// R·Ke·Rᵀ scattered into the BSR pattern (`scatter_blocks`), and a visco-elastic range's
/// history stress. fem_forces.cpp's elastic_pass dispatches each range here or to the
/// hyperelastic passes (stable_neo_hookean, st_venant_kirchhoff). No allocation.

#include "tissue/fem_forces.hpp"
#include "tissue/fem_model.hpp"

namespace stroma {

/// The pass over range r (its kernel Linear, CorotationalPolar or CorotationalQR; 0 for any
/// other) with p's inputs and outputs (ElasticPass). Returns the range's elastic energy.
double corotational_pass(const FemModel& m, const ElasticPass& p, const ElementRange& r);

}  // namespace stroma
