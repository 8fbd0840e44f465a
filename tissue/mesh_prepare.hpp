#pragma once
/// \file mesh_prepare.hpp
/// Turns a mesh as read from a file into one the solver can use: tetrahedra re-oriented to
/// positive volume, degenerate tetrahedra rejected (naming the element), nodes that no
/// tetrahedron uses reported, and the boundary surface extracted.

#include <vector>

#include "tissue/tet_mesh.hpp"

namespace stroma {

/// Result of prepare_mesh. Node numbering is unchanged (the file's order).
struct PreparedMesh {
  TetMesh mesh;                      ///< tetrahedra all with positive signed volume
  std::vector<int32_t> reoriented;   ///< indices of tetrahedra whose two last nodes were swapped
  std::vector<int32_t> unused_nodes; ///< nodes referenced by no tetrahedron (kept out of the system)
  std::vector<Tri> boundary;         ///< faces owned by one tetrahedron, outward normals (CCW)
};

/// Signed volume of tetrahedron (a, b, c, d): det[b−a, c−a, d−a] / 6.
double signed_volume(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d);

/// Validates and cleans `mesh`. A tetrahedron whose |volume| is below
/// `degenerate_ratio` × (its longest edge)³ is degenerate: throws InputError naming the
/// element (0-based and as the file's 1-based number) and its volume. Also throws on node
/// indices out of range and on a mesh without tetrahedra.
PreparedMesh prepare_mesh(TetMesh mesh, double degenerate_ratio = 1e-10);

/// Faces of the tetrahedra that belong to exactly one tetrahedron, oriented outward
/// (assumes positively oriented tetrahedra).
std::vector<Tri> extract_boundary(const std::vector<Tet>& tets);

}  // namespace stroma
