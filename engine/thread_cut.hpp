#pragma once
/// \file thread_cut.hpp
/// Threads across a cut (issue 43; docs/THREAD.md, "Threads and cutting"): a cut model keeps the
/// threads whole — their nodes are a node range of their own that no cut touches, so their DOFs
/// follow the cut tissue's in order (tissue/cut_model.hpp) — and what ties them to the tissue is
/// carried to the copies that hold the same material: an anchor's material point (a model
/// constant), a puncture's (state), and the thread nodes named by needles' ties and tools'
/// grasps (renumbered with the rods' DOFs).

#include <vector>

#include "engine/cut_compile.hpp"
#include "engine/model.hpp"
#include "engine/state.hpp"

namespace stroma {

/// The uncut model's rod anchors on the cut topology `topo` (built from edge_cut): each rod node
/// renumbered, its material point held by the copy of its tetrahedron that contains it
/// (copy_containing), weights as they were. Cut-build time.
std::vector<RodAnchor> cut_rod_anchors(const CutSupport& cs, const CutTopology& topo, const std::vector<double>& edge_cut);

/// `current`'s needle ties with their rod nodes renumbered onto `topo` (a cut of its scenario).
std::vector<Model::ThreadTie> cut_thread_ties(const Model& current, const CutTopology& topo);

/// The rod DOF of cut model m for rod DOF d of old_m (both models of one scenario).
int32_t carried_rod_dof(const Model& old_m, const Model& m, int32_t d);

/// The threads' part of a state carried to the cut model m (after transfer_tools copied the
/// tools): each puncture's material point to the copy of m holding it (its tetrahedron's, the
/// deepest in its material: carried_copy), each tool's held and released thread segment and
/// the punctures' count. No allocation (the tick boundary of `serve`).
void transfer_threads(const Model& old_m, const State& old_s, const Model& m, State& s);

}  // namespace stroma
