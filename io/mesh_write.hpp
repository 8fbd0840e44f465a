#pragma once
/// \file mesh_write.hpp
/// Writers for tetrahedral meshes, in forms Stroma's readers (mesh_io.hpp) and other tools read
/// back: gmsh 2.2 ASCII (.msh: tetrahedra with their physical region tags, $PhysicalNames from
/// `tag_names`) and VTK XML (.vtu, ASCII, with the region tags as the integer cell data
/// `region`). Coordinates are written with 17 significant digits, so reading back gives the
/// same doubles.

#include <string>

#include "tissue/tet_mesh.hpp"

namespace stroma {

/// Writes `mesh` to `path` (.msh or .vtu by extension) through a temporary file renamed into
/// place, so a failed write leaves no half file. Throws std::runtime_error on failure.
void write_tet_mesh(const std::string& path, const TetMesh& mesh);

}  // namespace stroma
