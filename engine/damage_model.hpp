#pragma once
/// \file damage_model.hpp
/// A compiled damage model (the Model's, engine/model.hpp): thresholds on a per-element measure.
/// The scenario's `material.damage:` section parses straight into it (DamageSpec is this type:
/// nothing in it needs resolving). Invariants when enabled: 0 ≤ warning ≤ onset < rupture.

namespace stroma {

/// Which per-element quantity damage thresholds apply to.
enum class DamageMeasure {
  VonMises,         ///< von Mises stress of the corotated small strain (Pa)
  PrincipalStrain   ///< largest principal value of the corotated small strain (–)
};

/// Between onset and rupture the damage variable d = (m − onset)/(rupture − onset) grows (never
/// decreases) and scales the element's stiffness by (1 − d); at rupture (d = 1) the element
/// carries no stiffness.
struct DamageModel {
  bool enabled = false;
  DamageMeasure measure = DamageMeasure::VonMises;
  double warning = 0;  ///< reported before harm (≤ onset); 0 = onset
  double onset = 0;
  double rupture = 0;
};

}  // namespace stroma
