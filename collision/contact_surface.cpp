#include "collision/contact_surface.hpp"

#include <stdexcept>
#include <string>

#include "tissue/bsr_matrix.hpp"

namespace stroma {

namespace {

/// Slot of the stored block (i, j) for i ≤ j, −1 for i > j (the transpose adds it), or the
/// diagonal block of i when the pair is not in the pattern (fixed nodes).
int32_t pair_slot(const BsrPattern& pattern, int32_t i, int32_t j) {
  if (i > j) return -1;
  const int32_t s = pattern.find(i, j);
  return s >= 0 ? s : pattern.diag[i];
}

/// Adds DOF d with weight w to the list (dof, n), returning its index.
int add_dof(int32_t* dof, int& n, int max_n, int32_t d) {
  for (int i = 0; i < n; ++i)
    if (dof[i] == d) return i;
  if (n == max_n) return -1;
  dof[n] = d;
  return n++;
}

void fill_slots(const BsrPattern& pattern, const int32_t* dof, int n, int32_t* slot) {
  for (int i = 0; i < kSurfaceDofs * kSurfaceDofs; ++i) slot[i] = -1;
  for (int a = 0; a < n; ++a)
    for (int b = 0; b < n; ++b) slot[kSurfaceDofs * a + b] = pair_slot(pattern, dof[a], dof[b]);
}

}  // namespace

SurfaceTriangleDofs triangle_dofs(const BsrPattern& pattern, const std::array<int32_t, 3>& tri, int32_t num_dofs,
                                  const std::vector<int32_t>& embedded_dof) {
  SurfaceTriangleDofs td;
  int n = 0;
  for (int v = 0; v < 3; ++v) {
    const int32_t p = tri[v];
    const int32_t d = p < num_dofs ? p : embedded_dof[static_cast<size_t>(p - num_dofs)];
    const int i = add_dof(td.dof, n, kSurfaceDofs, d);
    if (i < 0)
      throw std::invalid_argument("surface triangle (" + std::to_string(tri[0]) + ", " + std::to_string(tri[1]) +
                                  ", " + std::to_string(tri[2]) + ") involves more than four DOFs");
    td.W[v][i] += 1.0;
  }
  td.n = n;
  fill_slots(pattern, td.dof, n, td.slot);
  return td;
}

SurfacePointDofs point_dofs(const BsrPattern& pattern, int32_t point, int32_t num_dofs,
                            const std::vector<int32_t>& embedded_dof) {
  SurfacePointDofs pd;
  pd.dof = point < num_dofs ? point : embedded_dof[static_cast<size_t>(point - num_dofs)];
  pd.slot = pair_slot(pattern, pd.dof, pd.dof);
  return pd;
}

}  // namespace stroma
