#include "tissue/fem_forces.hpp"

#include <algorithm>
#include <cmath>

#include "tissue/corotational_pass.hpp"
#include "tissue/element_batch.hpp"
#include "tissue/mat3.hpp"
#include "tissue/nodal_smoothing.hpp"
#include "tissue/material.hpp"
#include "tissue/rod_pass.hpp"
#include "tissue/rotation.hpp"
#include "tissue/stable_neo_hookean.hpp"
#include "tissue/st_venant_kirchhoff.hpp"

namespace stroma {

double elastic_pass(const FemModel& m, const ElasticPass& p) {
  double energy = 0.0;
  for (const ElementRange& r : m.ranges) {
    if (p.parts == PassParts::Rest) break;
    if (r.fixed) continue;  // a fixed body: nothing it computes could move anything
    switch (r.kernel) {
      case ElementKernel::Linear:
      case ElementKernel::CorotationalPolar:
      case ElementKernel::CorotationalQR:
        energy += corotational_pass(m, p, r);
        break;
      case ElementKernel::StableNeoHookean:
        energy += stable_neo_hookean_pass(m, p, r);
        break;
      case ElementKernel::StVenantKirchhoff:
        energy += st_venant_kirchhoff_pass(m, p, r);
        break;
    }
  }
  if (p.parts == PassParts::Elements) return energy;
  if (!m.smoothing.empty() && !p.unsmoothed) energy += nodal_smoothing_pass(m, p);
  if (!m.rods.empty()) energy += rod_pass(m, p);
  return energy;
}

void element_von_mises(const FemModel& m, const double* x, double* out) {
  for (const ElementRange& r : m.ranges)
    for (int32_t e = r.begin; e < r.end; ++e) {
      const ElementParams& ep = m.elements[e];
      double F[9], d1[3], d2[3], R[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
      element_batch::deformation_gradient(x, ep, F, d1, d2);
      if (r.kernel == ElementKernel::CorotationalPolar || r.kernel == ElementKernel::StableNeoHookean ||
          r.kernel == ElementKernel::StVenantKirchhoff)
        polar_rotation(F, R);
      else if (r.kernel == ElementKernel::CorotationalQR)
        qr_rotation(m.rest_frame[e].data(), d1, d2, R);
      double P[9], eps[9];
      rotated_stress(R, F, ep.lambda, ep.mu, 1.0, P, eps);
      out[e] = von_mises_stress(eps, ep.lambda, ep.mu);  // in the element frame: rotation-invariant
    }
}

}  // namespace stroma
