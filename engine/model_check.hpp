#pragma once
/// \file model_check.hpp
/// The documented invariants of a compiled Model (engine/model.hpp) and of a State for it
/// (engine/state.hpp), as functions: STROMA_DEMAND (tissue/demand.hpp) checks them after every
/// compile (scenario and cut models) and at every tick's entry in debug and sanitizer builds.

#include <string>

#include "engine/model.hpp"
#include "engine/state.hpp"

namespace stroma {

/// Whether m keeps Model's documented invariants (array sizes, ranges covering the elements,
/// resolved tools, the contact and damage arrays); if not, `why` names the first broken one.
/// O(nodes + elements): for after a compile, not for the tick.
bool model_invariants_hold(const Model& m, std::string* why);

/// Whether s has the sizes a state of m has (positions, velocities, tools, damage, edge cuts):
/// O(1), no allocation — the tick's entry check. state_fits_model (engine/state_bytes.hpp) is
/// the complete one, for restores.
bool state_sized_for(const Model& m, const State& s);

}  // namespace stroma
