#pragma once
/// \file quarter_block_mesh.hpp
/// The indentation problem's mesh (refs/e): a quarter block [0, a]² × [0, H] graded
/// geometrically towards the contact point (0, 0, H), six tetrahedra per hexahedron (Kuhn split,
/// conforming), written as Gmsh 2.2. Used by the indentation test and `stroma bench accuracy`.

#include <string>
#include <vector>

namespace stroma {

/// 0, h0, h0(1+r), … up to `length` (the last spacing absorbed): cells growing by `ratio`.
std::vector<double> graded_coordinates(double h0, double ratio, double length);

/// Writes the quarter block with first cell `h0` and growth `ratio` to `path`; returns path.
std::string write_quarter_block(const std::string& path, double a, double H, double h0, double ratio);

}  // namespace stroma
