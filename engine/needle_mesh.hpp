#pragma once
/// \file needle_mesh.hpp
/// The tetrahedra a needle's walks cross (rigid/needle_track.hpp, tissue/tet_walk.hpp), compiled
/// into the model's topology part: each element's face neighbours, an element of each node, the
/// element of each collision triangle (where a puncture's walk starts) and, in a cut model, where
/// each element copy's material lies (so a needle exits at a cut face and bites the other lip).

#include <vector>

#include "engine/model.hpp"
#include "tissue/tet_walk.hpp"

namespace stroma {

struct CutBase;

/// A scenario's (uncut) model with needles: tet_neighbours, node_tet and collision_tri_elem
/// (each collision triangle's element: the one it is a face of; −1 for none). Load time.
void compile_needle_mesh(Model& m);

/// A cut model with needles (engine/cut_compile.cpp): tet_neighbours over the copies
/// (tissue/cut_walk_neighbours.hpp: copies across the cut share no face, so cut faces are
/// boundary faces; a copy's twin is never its neighbour), node_tet, and each split
/// copy's material planes (tissue/cut_topology.hpp). Its collision_tri_elem is made with its
/// surface (each triangle's copy). Cut-build time.
void compile_cut_needle_mesh(Model& m, const CutTopology& topo, const CutBase& base, const std::vector<double>& rest,
                             const std::vector<double>& edge_cut);

/// The walk's view of m (no allocation).
inline WalkMesh needle_walk_mesh(const Model& m) {
  WalkMesh w;
  w.elements = &m.fem.elements;
  w.neighbours = m.tet_neighbours.data();
  if (!m.element_plane_begin.empty()) {
    w.plane_begin = m.element_plane_begin.data();
    w.planes = m.element_planes.data();
    w.next_twin = m.element_next_twin.data();
  }
  return w;
}

/// The copy of `m`'s topology `topo` holding the material point of weights w (4) of copy
/// `old_copy` of `old_topo`, which `topo` refines: among its tetrahedron's new copies within the
/// old one's material, the one whose material planes (`walk`: m's) it lies deepest inside.
int32_t carried_copy(const CutTopology& old_topo, int32_t old_copy, const CutTopology& topo, const WalkMesh& walk,
                     const double* w);

/// Carries the needles' insertion over a cut swap: each track point and front, a material point
/// of an element copy of `old_m`, goes to the copy of `m` holding the same material point (same
/// tetrahedron, same weights; among a newly split tetrahedron's copies the one whose material
/// planes it lies deepest inside) and takes that copy's DOFs — the rest of the needle's state as it
/// was. No allocation (the tick boundary of `serve`).
void transfer_needles(const Model& old_m, const std::vector<NeedleState>& from, const Model& m,
                      std::vector<NeedleState>& to);

}  // namespace stroma
