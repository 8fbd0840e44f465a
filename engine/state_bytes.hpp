#pragma once
/// \file state_bytes.hpp
/// A State as a self-describing byte string, for moving a snapshot to another process (Python's
/// pickle, a worker pool, a file) and back. The bytes carry the fingerprint of the uncut model the
/// state belongs to, so a state is only ever restored into the scenario it came from; a state of a
/// cut model carries its edge cuts, from which that scenario rebuilds the same cut model
/// (the topology is a function of the uncut mesh and the edge cuts: tissue/cut_topology.hpp).
///
/// Layout (little-endian, as this machine's memory): magic "STROMA-STATE", format version,
/// fingerprint, sizeof(ToolState), then each field in State's order, arrays as a 64-bit count and
/// the elements. Bytes are read with every count checked against what is left, so truncated or
/// corrupt input is an InputError, never a crash or a huge allocation.

#include <cstdint>
#include <string>

#include "engine/model.hpp"
#include "engine/state.hpp"

namespace stroma {

/// A hash of everything of a compiled scenario's uncut model that a tick reads: the FEM system
/// (rest positions, elements and their constants, kernels, masses, fibres, Prony series,
/// Rayleigh α, constraints, external forces and gravity), the stepper's settings, the time step,
/// multirate, budget and cap policy, every tool's limits and constants, the damage models,
/// contact and the collision surface. A snapshot is restored only into a simulation whose model
/// has its fingerprint: another scenario that happens to share the mesh (other gravity, fixed
/// set, damping, tools) is refused. Equal scenarios compiled in different processes give equal
/// fingerprints.
uint64_t model_fingerprint(const Model& uncut);

/// The part of model_fingerprint that hashes the constants a topology change keeps
/// (ModelConstants: stepper, time step, multirate, budget, cap policy, tools, damage models,
/// contact, cutting): equal for a model and every cut model compiled from it.
uint64_t constants_fingerprint(const ModelConstants& m);

/// `s` as bytes, stamped with `fingerprint` (model_fingerprint of its scenario's uncut model).
std::string encode_state(const State& s, uint64_t fingerprint);

/// The state in `bytes` and the fingerprint it was stamped with. Throws InputError (field names
/// what was wrong: "magic", "version", "tool size", an array's name, "trailing bytes") on input
/// encode_state did not write.
State decode_state(const std::string& bytes, uint64_t* fingerprint);

/// Whether `s` has the sizes model m's states have (DOFs, tools, damage, visco-elastic variables,
/// edge cuts); if not, `why` says which differs.
bool state_fits_model(const State& s, const Model& m, std::string* why);

}  // namespace stroma
