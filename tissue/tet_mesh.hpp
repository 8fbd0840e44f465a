#pragma once
/// \file tet_mesh.hpp
/// A linear tetrahedral mesh as read from a file: node positions in file order and the
/// tetrahedra (4 zero-based node indices each). Plain data; validation and clean-up
/// (orientation, degenerate and unused nodes, boundary surface) live in mesh_prepare.hpp.

#include <array>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

namespace stroma {

/// 3-vector of doubles, used for plain geometric data outside the hot loops.
using Vec3 = std::array<double, 3>;
/// A tetrahedron: four zero-based node indices.
using Tet = std::array<int32_t, 4>;
/// A surface triangle: three zero-based node indices, counter-clockwise seen from outside.
using Tri = std::array<int32_t, 3>;

/// Tetrahedral mesh in file order. `source` names where it came from (for messages).
struct TetMesh {
  std::vector<Vec3> nodes;   ///< node positions, index = position in the file (0-based)
  std::vector<Tet> tets;     ///< tetrahedra, in file order; other element types are dropped
  std::string source;        ///< file path (or a description for generated meshes)
  /// Per tetrahedron, its region tag (gmsh: its physical group; 0: none), or empty when the
  /// file has no regions. Scenarios give regions their own material (`regions:`).
  std::vector<int32_t> tet_tags;
  /// Names of region tags (gmsh $PhysicalNames of dimension 3), in file order.
  std::vector<std::pair<int32_t, std::string>> tag_names;
  /// Per tetrahedron, a fibre direction (VTU cell data `fibres`, 3 components; not
  /// normalised, (0, 0, 0): none there), or empty when the file has none. `fibres: {direction:
  /// mesh}` reads it.
  std::vector<Vec3> tet_fibres;
};

}  // namespace stroma
