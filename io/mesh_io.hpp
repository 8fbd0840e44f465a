#pragma once
/// \file mesh_io.hpp
/// Readers for tetrahedral mesh files: gmsh .msh (ASCII 1.0, 2.x, 4.1), legacy VTK .vtk
/// (UNSTRUCTURED_GRID, ASCII or BINARY) and VTK XML .vtu (UnstructuredGrid: ascii, inline base64
/// or appended raw / base64 DataArrays, uncompressed or zlib-compressed — VTK's default is
/// appended raw zlib — with UInt32 or UInt64 headers, either byte order).
///
/// The readers return the mesh exactly as stored: nodes in file order, linear tetrahedra in file
/// order with their node references turned into zero-based indices into `nodes`. Every other
/// element type (points, lines, triangles, ...) is skipped silently; higher-order tetrahedra are
/// an error rather than being dropped, because losing the volume elements would be silent
/// nonsense. Geometry is not checked or reoriented here (see mesh_prepare.hpp).
///
/// Every problem is reported as stroma::InputError naming the file, the 1-based line (0 where a
/// line number means nothing, e.g. inside binary data), the section or field, and what is wrong.

#include <iosfwd>
#include <string>

#include "tissue/tet_mesh.hpp"

namespace stroma {

/// Reads a tetrahedral mesh; format chosen by extension (.msh gmsh, .vtk legacy VTK, .vtu VTK
/// XML; case-insensitive). Throws InputError for an unknown extension, a file that cannot be
/// opened, or any problem the format reader finds. The mesh's `source` is `path`.
TetMesh load_tet_mesh(const std::string& path);

/// Reads a gmsh mesh in ASCII format version 1.0 ($NOD/$ELM), 2.x ($MeshFormat 2.0-2.2) or 4.1.
/// Keeps linear tetrahedra (element type 4); node tags, which need not be contiguous, are mapped
/// to zero-based indices in file order. `source` names the input in error messages and the result.
TetMesh read_gmsh(std::istream& in, const std::string& source);

/// Reads a legacy VTK file (DATASET UNSTRUCTURED_GRID), ASCII or BINARY (big-endian, as the VTK
/// spec requires), in the classic CELLS layout or the VTK 5.x OFFSETS/CONNECTIVITY layout.
/// Keeps cells of type 10 (VTK_TETRA); point and cell data are ignored.
TetMesh read_vtk_legacy(std::istream& in, const std::string& source);

/// Reads a VTK XML UnstructuredGrid (.vtu) with one <Piece>. DataArrays may be format="ascii" or
/// format="binary" (inline base64, UInt32 or UInt64 size header per header_type, byte order per
/// byte_order, no compressor); appended data is rejected. Keeps cells of type 10 (VTK_TETRA).
TetMesh read_vtu(std::istream& in, const std::string& source);

}  // namespace stroma
