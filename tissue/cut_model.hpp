#pragma once
/// \file cut_model.hpp
/// A cut mesh as a FemModel, and a state carried from one topology to the next.
///
/// The cut model is built off the physics thread from the uncut model and a CutTopology
/// (cut_topology.hpp): each copy is its tetrahedron's element (same shape gradients, Lamé
/// parameters, damping) with its volume share; masses are re-lumped from the copies' volumes,
/// so the total mass is the uncut model's to rounding; a DOF keeps its node's rest position,
/// constraint, Rayleigh α; a node's load goes to its primary DOF. The pattern, slots and node
/// lists are rebuilt (finish_fem_model), so nothing of the old pattern survives.

#include <vector>

#include "tissue/cut_topology.hpp"
#include "tissue/fem_model.hpp"
#include "tissue/tissue_state.hpp"

namespace stroma {

/// What cutting needs of an uncut model, computed once: its elements' nodes, their adjacency,
/// and the bodies' node ranges.
struct CutBase {
  std::vector<Tet> tets;
  TetAdjacency adj;
  /// {bodies[0].node_begin, …, bodies.back().node_end}, then the rods' nodes' end when there are
  /// rods: the rods' nodes are a range of their own, which no cut touches (no tetrahedron has
  /// them), so their DOFs are the rods' nodes in order after the cut tissue's.
  std::vector<int32_t> node_ranges;
  /// Per edge, how close to its ends a cut point may lie (cut_edge_min_fraction: relative to
  /// its body's shortest edge).
  std::vector<double> min_fraction;
};

/// The cut base of an uncut model.
CutBase make_cut_base(const FemModel& uncut);

/// The FemModel of `uncut` cut to `topo` (a topology of the same mesh). With no cut it equals
/// `uncut` in every array. A DOF takes its node's constraint only if it holds the node as
/// material (CutTopology::dof_material) or its body is fully fixed. bodies[b].boundary is the
/// uncut part of the surface with node corners; the whole surface is topo.triangles. Throws
/// std::invalid_argument if `topo` is not a topology of this model's mesh.
/// Rods (suture threads) come along whole after the cut tissue's DOFs: their nodes' rest
/// positions, masses, loads and constraints as they were, their ranges renumbered;
/// `cut_anchors` are the uncut model's rod_anchors on the cut one (the same order: their rod
/// nodes and the DOFs of the copies holding their material points — the caller finds those,
/// copy_containing); required when it has anchors.
FemModel build_cut_fem_model(const FemModel& uncut, const CutTopology& topo,
                             const std::vector<RodAnchor>& cut_anchors = {});

/// For each DOF of `to`, the DOF of `from` it continues: `to` must refine `from` (its cuts a
/// superset of from's), so every copy of `to` lies in one copy of `from` and every DOF of `to`
/// in one DOF of `from`. Throws std::logic_error if it does not.
std::vector<int32_t> continued_dofs(const CutTopology& from, const CutTopology& to);

/// For each copy (element) of `to`, the copy of `from` whose material holds it (`to` must refine
/// `from`; std::logic_error if not): per-element state such as damage carries over through it.
std::vector<int32_t> continued_copies(const CutTopology& from, const CutTopology& to);

/// The state on the new DOFs: each takes the position, velocity and solver warm start of the
/// DOF it continues (`from_dof`, continued_dofs()). A cut moves nothing: the two lips start
/// where the material was, at its velocity. Writes into `to` (resized once, so a caller may
/// keep its capacity).
void transfer_state(const TissueState& from, const std::vector<int32_t>& from_dof, TissueState& to);

/// The visco-elastic internal variables on the new copies (`to` sized for model m): each copy
/// continues its parent copy's (`from_element`, continued_copies()) branch stresses Q and the
/// strain σ₀ⁿ they were last stepped from. A copy is a part of its parent's material at the same
/// deformation, so its stress is the parent's; the stored energy V·½Q:C⁻¹:Q shrinks with the
/// volume, and the parts never hold more volume than the whole: a cut creates no energy.
/// `old_m` and `m` are cuts of the same uncut model (their ranges correspond by index).
void transfer_visco_state(const FemModel& old_m, const TissueState& from, const FemModel& m,
                          const std::vector<int32_t>& from_element, TissueState& to);

}  // namespace stroma
