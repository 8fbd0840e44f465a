#pragma once
/// \file surface_check.hpp
/// Is a triangle surface the boundary of a volume? The topological checks `stroma mesh surface`
/// runs before meshing (self-intersection, which needs exact predicates, is the mesher's): every
/// edge shared by exactly two triangles (a boundary edge has one: the surface is open; an edge
/// with three or more is non-manifold), every vertex's triangles forming one fan, no triangle of
/// zero area. Plain combinatorics on the indexed mesh (surface_io welds STL corners).

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "io/surface_io.hpp"

namespace stroma {

/// What is wrong with a surface, each list complete and sorted (edges as (lo, hi) vertex pairs).
struct SurfaceDefects {
  std::vector<std::array<int32_t, 2>> boundary_edges;     ///< used by one triangle
  std::vector<std::array<int32_t, 2>> nonmanifold_edges;  ///< used by three or more
  std::vector<int32_t> nonmanifold_vertices;  ///< triangles around it form more than one fan
  std::vector<int32_t> degenerate_triangles;  ///< zero area (collinear corners)
  bool empty() const {
    return boundary_edges.empty() && nonmanifold_edges.empty() && nonmanifold_vertices.empty() &&
           degenerate_triangles.empty();
  }
};

/// Finds every defect of `s`.
SurfaceDefects find_surface_defects(const SurfaceMesh& s);

/// A message naming the defects (counts, then at most `max_listed` of each with coordinates),
/// for an InputError about `s`.
std::string describe_surface_defects(const SurfaceMesh& s, const SurfaceDefects& d, size_t max_listed = 8);

}  // namespace stroma
