#include "engine/damage.hpp"

#include <algorithm>
#include <cmath>

#include "tissue/material.hpp"
#include "tissue/rotation.hpp"

namespace stroma {

double element_damage_measure(const Model& m, const double* x, int32_t e, DamageMeasure measure) {
  const ElementParams& ep = m.fem.elements[e];
  const double* x0 = x + 3 * ep.node[0];
  double F[9];
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) {
      double v = 0;
      for (int a = 0; a < 3; ++a) v += (x[3 * ep.node[a + 1] + i] - x0[i]) * ep.g[3 * a + j];
      F[3 * i + j] = v;
    }
  double R[9];
  polar_rotation(F, R);
  double S[9];
  m3::mul_tn(R, F, S);
  double eps[9];
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) eps[3 * i + j] = 0.5 * (S[3 * i + j] + S[3 * j + i]) - (i == j ? 1.0 : 0.0);
  if (measure == DamageMeasure::VonMises) return von_mises_stress(eps, ep.lambda, ep.mu);
  // Largest principal strain: eigenvalues of the symmetric ε by the fixed-sweep Jacobi kernel.
  double E[9][1], V[9][1];
  for (int k = 0; k < 9; ++k) {
    E[k][0] = eps[k];
    V[k][0] = (k % 4 == 0) ? 1.0 : 0.0;
  }
  for (int k = 0; k < kPolarSweeps; ++k) {
    detail::jacobi_rotate<0, 1>(E, V);
    detail::jacobi_rotate<0, 2>(E, V);
    detail::jacobi_rotate<1, 2>(E, V);
  }
  return std::max(E[0][0], std::max(E[4][0], E[8][0]));
}

int update_damage(const Model& m, State& s, std::vector<DamageEventRecord>* records) {
  int events = 0;
  const double* x = s.tissue.x.data();
  for (size_t b = 0; b < m.body_damage.size(); ++b) {
    const bool regions = !m.element_region_damage.empty();
    if (!m.body_damage[b].enabled && !regions) continue;
    const BodyRange& br = m.fem.bodies[b];
    for (int32_t e = br.element_begin; e < br.element_end; ++e) {
      const DamageModel& d = damage_of(m, b, e);
      if (!d.enabled) continue;
      if (s.damage_level[e] == kRuptured) continue;
      const double v = element_damage_measure(m, x, e, d.measure);
      uint8_t level = s.damage_level[e];
      if (v >= d.warning && level < kWarned) level = kWarned;
      if (v >= d.onset) {
        const float dd = static_cast<float>(std::min(1.0, (v - d.onset) / (d.rupture - d.onset)));
        s.damage[e] = std::max(s.damage[e], dd);  // irreversible
        if (level < kDamaged) level = kDamaged;
        if (s.damage[e] >= 1.0f) level = kRuptured;
      }
      if (level != s.damage_level[e]) {
        ++events;
        for (uint8_t l = s.damage_level[e] + 1; l <= level; ++l) ++s.damage_count[l];
        if (level >= kDamaged && s.first_damage_time < 0) s.first_damage_time = s.time;
        s.damage_level[e] = level;
        if (level == kRuptured) {
          // The element's mass leaves the nodes that still belong to intact tissue; nodes left
          // with no intact element keep theirs (free debris, so no node becomes massless).
          for (int32_t n : m.fem.elements[e].node)
            if (node_attached(m, s.damage_level, n)) s.node_mass[n] = std::max(0.0, s.node_mass[n] - m.element_node_mass[e]);
        }
        if (level == kRuptured && !s.face_active.empty()) {
          // The tear: faces between this element and an intact one become surface.
          for (int32_t j = m.element_face_ptr[e]; j < m.element_face_ptr[e + 1]; ++j) {
            const int32_t f = m.element_face[j];
            s.face_active[f] = face_activity(m, s.damage_level, f);
          }
        }
        if (records && records->size() < records->capacity())
          records->push_back(DamageEventRecord{e, level, v, s.time, -1});
      }
    }
  }
  return events;
}

void transfer_damage(const State& from, const std::vector<int32_t>& from_dof, const std::vector<int32_t>& from_element,
                     const Model& nm, State& to) {
  for (size_t e = 0; e < to.damage.size(); ++e) {
    to.damage[e] = from.damage[from_element[e]];
    to.damage_level[e] = from.damage_level[from_element[e]];
  }
  for (int32_t n = 0; n < nm.fem.num_nodes; ++n) {
    if (!node_attached(nm, to.damage_level, n)) {
      to.node_mass[n] = std::min(nm.fem.mass[n], from.node_mass[from_dof[n]]);
      continue;
    }
    double mass = nm.fem.mass[n];
    for (int32_t j = nm.fem.node_element_ptr[n]; j < nm.fem.node_element_ptr[n + 1]; ++j) {
      const int32_t e = nm.fem.node_element[j];
      if (to.damage_level[e] == kRuptured) mass -= nm.element_node_mass[e];
    }
    to.node_mass[n] = std::max(0.0, mass);
  }
  to.damage_count = from.damage_count;
  to.first_damage_time = from.first_damage_time;
  for (size_t f = 0; f < to.face_active.size(); ++f) to.face_active[f] = face_activity(nm, to.damage_level, static_cast<int32_t>(f));
}

}  // namespace stroma
