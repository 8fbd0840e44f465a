#pragma once
/// \file cut_walk_neighbours.hpp
/// The face neighbours a walk (tissue/tet_walk.hpp) crosses in a cut mesh, found through the
/// uncut mesh's adjacency rather than by matching DOFs alone.
///
/// Why not tet_face_neighbours on the copies: near where a cut ends, two copies of one
/// tetrahedron can hold the same DOFs on a face (each holds the other's nodes as virtual nodes
/// that the material around the cut's end glues back to the real ones), so three or four copies
/// share that face's DOF triple, and pairing them in order paired the two siblings — a walk
/// leaving one copy through that face entered its twin, which holds the point at the same
/// weights, and cycled between them until it gave up. A served needle's cutting front stopped
/// there and dragged the tissue along (issue 42).

#include <cstdint>
#include <vector>

#include "tissue/cut_topology.hpp"
#include "tissue/tet_mesh.hpp"

namespace stroma {

/// Per copy c of `topo` and its face opposite local node i: out[4c + i] is the copy across that
/// face — a copy of the uncut tetrahedron adj.face_neighbor[topo.copies[c].tet][i] holding the
/// same DOF at each of the face's three nodes — whose material shares the most of the face's
/// nodes with c's (the first such copy on a tie); −1 where there is none (the mesh's boundary
/// or a face of the cut). Never a copy of c's own tetrahedron. `tets` and `adj` are the uncut
/// mesh's (CutBase). Load and cut-build time.
std::vector<int32_t> cut_copy_face_neighbours(const CutTopology& topo, const std::vector<Tet>& tets,
                                              const TetAdjacency& adj);

}  // namespace stroma
