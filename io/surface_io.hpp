#pragma once
/// \file surface_io.hpp
/// Reader for triangle surface meshes: the visual surfaces that are drawn in place of the
/// (coarser) tetrahedral mesh and follow it through a barycentric mapping (visual_mapping.hpp).
///
/// Formats: Wavefront OBJ (.obj), STL (.stl, ASCII or binary), OFF (.off, ASCII) and PLY (.ply,
/// ASCII or binary of either byte order; the vertex element's x, y, z and the face element's
/// vertex_indices list, other elements and properties skipped). Only geometry is kept:
/// vertex positions and triangles; normals, texture coordinates, groups and materials are
/// ignored, because the mapping recomputes the surface from the deformed tetrahedra anyway.
/// Every problem is reported as stroma::InputError naming the file and the 1-based line (0 for
/// whole-file problems and for binary data).

#include <string>
#include <vector>

#include "tissue/tet_mesh.hpp"

namespace stroma {

/// A triangle surface (visual mesh) in file order.
struct SurfaceMesh {
  /// Positions. OBJ: in file order ('v' lines); STL: welded, in order of first use.
  std::vector<Vec3> vertices;
  std::vector<Tri> triangles;  ///< zero-based vertex indices, in file order, orientation as stored
  std::string source;          ///< file path (for messages)
};

/// Reads Wavefront OBJ (.obj), STL (.stl, ASCII or binary), OFF (.off) or PLY (.ply), chosen by extension
/// (case-insensitive). OBJ polygons with more than three vertices are fan-triangulated; STL
/// triangles, which carry their own copies of the corners, are welded on exactly equal
/// coordinates into an indexed mesh. Triangles that use one vertex twice are dropped.
/// Throws InputError(path, line, "", message) on any problem.
SurfaceMesh read_surface_mesh(const std::string& path);

}  // namespace stroma
