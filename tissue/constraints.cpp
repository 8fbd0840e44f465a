#include "tissue/constraints.hpp"

namespace stroma {

void project_constraints(const FemModel& m, double* A, double diag_scale, bool scale_by_mass) {
  for (const auto& [slot, i, j] : m.constrained_offdiag) {
    double* B = A + 9 * slot;
    const uint8_t ri = m.constrained[i], cj = m.constrained[j];
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c)
        if (((ri >> r) & 1) || ((cj >> c) & 1)) B[3 * r + c] = 0.0;
  }
  for (int32_t i : m.constrained_nodes) {
    double* D = A + 9 * m.pattern.diag[i];
    const uint8_t mask = m.constrained[i];
    const double d = (scale_by_mass && m.mass[i] > 0) ? m.mass[i] * diag_scale : diag_scale;
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c)
        if (((mask >> r) & 1) || ((mask >> c) & 1)) D[3 * r + c] = (r == c) ? d : 0.0;
  }
}

}  // namespace stroma
