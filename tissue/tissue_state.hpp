#pragma once
/// \file tissue_state.hpp
/// The small mutable state of the deformable bodies. Snapshot and restore are plain copies.

#include <vector>

#include "tissue/fem_model.hpp"

namespace stroma {

/// Positions, velocities and the solver's warm start. Everything else is either in the
/// immutable FemModel or scratch space that need not survive a tick. Invariants: the four
/// arrays have 3·num_nodes entries; fixed DOFs keep their rest (or driven) position and zero
/// velocity; after any tick every entry is finite (a tick that cannot keep them so is rolled
/// back).
struct TissueState {
  std::vector<double> x;   ///< 3n positions (m)
  std::vector<double> v;   ///< 3n velocities (m/s)
  std::vector<double> dv;  ///< 3n last velocity increment: CG warm start (implicit Euler)
  std::vector<double> dv_prev;  ///< 3n velocity increment of the tick before (extrapolation)
  /// Visco-elastic internal variables (viscoelastic.hpp; empty without visco-elastic bodies):
  /// each branch's overstress Qᵢ and the instantaneous stress σ₀ at the positions x, per element
  /// in its rotated frame (6 values: xx yy zz xy xz yz; FemModel sizes and ElementRange offsets).
  std::vector<double> visco_q, visco_s0;

  /// State at rest: x = rest positions, v = 0.
  static TissueState at_rest(const FemModel& m) {
    TissueState s;
    s.x = m.rest;
    s.v.assign(m.rest.size(), 0.0);
    s.dv.assign(m.rest.size(), 0.0);
    s.dv_prev.assign(m.rest.size(), 0.0);
    s.visco_q.assign(static_cast<size_t>(m.visco_q_size), 0.0);
    s.visco_s0.assign(static_cast<size_t>(m.visco_s0_size), 0.0);
    return s;
  }
};

}  // namespace stroma
