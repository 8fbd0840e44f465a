#pragma once
/// \file damage.hpp
/// Tissue damage: per-element measures from the corotated strain — von Mises stress
/// or the largest principal strain — compared with each body's thresholds after every tick
/// (the "damage" stage). Above onset a damage variable d ∈ [0, 1] grows irreversibly and the
/// element's stiffness is scaled by (1 − d); at rupture d = 1 and the element carries no load.
/// Only bodies with a `damage:` section are visited: a scene pays only for what it uses.
///
/// At rupture the faces between the ruptured element and intact neighbours become collision
/// surface (tools can enter the tear; no rebuild, no allocation: every tet face of a body with a
/// damage model is in the collision set from load time, switched on and off), and the element's
/// mass (ρV/4 per node) leaves the nodes still attached to intact tissue (nodes left with no
/// intact element keep theirs as free debris, so none becomes massless); gravity follows.
/// Renderers see damage as a per-vertex colour (TissueState.damage); the published surface
/// itself is not re-extracted at a tear.

#include <cstdint>
#include <vector>

#include "engine/model.hpp"
#include "engine/state.hpp"

namespace stroma {

/// Element damage levels, in the order they are reached.
enum DamageLevel : uint8_t { kIntact = 0, kWarned = 1, kDamaged = 2, kRuptured = 3 };

/// Per-element measure of the body's DamageMeasure at positions x (polar rotation recomputed).
double element_damage_measure(const Model& m, const double* x, int32_t element, DamageMeasure measure);

/// An element reaching a new damage level (for events and logs).
struct DamageEventRecord {
  int32_t element = 0;   ///< global element index
  uint8_t level = 0;     ///< DamageLevel reached (the highest, if several at once)
  double value = 0;      ///< the measure at that moment
  double time = 0;       ///< sim time
  int32_t tool = -1;     ///< tool in contact at that moment (−1: none); set by the caller
};

/// Collision face f's activity under the elements' damage levels (State::face_active's values):
/// a face is surface where exactly one side is intact — 1 as stored (its first element intact),
/// 2 reversed, 0 inside intact tissue or between ruptured elements; a face with no element on
/// either side (the boundary of a body without a damage model) is always 1.
inline uint8_t face_activity(const Model& m, const std::vector<uint8_t>& level, int32_t f) {
  const int32_t ea = m.collision_face_elem[f][0], eb = m.collision_face_elem[f][1];
  if (ea < 0 && eb < 0) return 1;
  const bool a_ok = ea >= 0 && level[ea] != kRuptured;
  const bool b_ok = eb >= 0 && level[eb] != kRuptured;
  return a_ok && !b_ok ? 1 : (!a_ok && b_ok ? 2 : 0);
}

/// Whether node n still belongs to intact tissue (some element around it is not ruptured).
inline bool node_attached(const Model& m, const std::vector<uint8_t>& level, int32_t n) {
  for (int32_t j = m.fem.node_element_ptr[n]; j < m.fem.node_element_ptr[n + 1]; ++j)
    if (level[m.fem.node_element[j]] != kRuptured) return true;
  return false;
}

/// The damage part of a state carried across a topology change (engine/cut_swap.cpp): `to`,
/// sized for the new model `nm`, gets each element's damage and level from the element it
/// refines (from_element), the counters, and what the rules above make of them on the new
/// topology — lumped masses without the ruptured elements' shares (a node left with no intact
/// element is free debris and keeps what it had, at most its new lumped mass, so debris never
/// gains mass across swaps) and each collision face's activity. No allocation.
void transfer_damage(const State& from, const std::vector<int32_t>& from_dof, const std::vector<int32_t>& from_element,
                     const Model& nm, State& to);

/// The damage stage: updates s.damage / s.damage_level / counters from the current positions.
/// Returns how many elements reached a new level this tick; if `events` is given, appends
/// their records while it has spare capacity (never reallocates). No allocation.
int update_damage(const Model& m, State& s, std::vector<DamageEventRecord>* events = nullptr);

}  // namespace stroma
