#pragma once
/// \file hausdorff.hpp
/// Surface deviation of a produced mesh: the symmetric Hausdorff distance between two triangle
/// surfaces, by CGAL's AABB tree. Approximate from below: each surface is sampled at its
/// vertices, edge midpoints and triangle centroids (and, for triangles longer than `spacing`,
/// a regular barycentric grid of that spacing), and the largest distance from a sample to the
/// other surface is reported.

#include <vector>

#include "tissue/tet_mesh.hpp"

namespace stroma::meshing {

/// max(d(A -> B), d(B -> A)). `spacing` > 0 bounds the sample spacing on long triangles
/// (0: vertices, edge midpoints and centroids only).
double symmetric_hausdorff(const std::vector<Vec3>& va, const std::vector<Tri>& ta, const std::vector<Vec3>& vb,
                           const std::vector<Tri>& tb, double spacing);

}  // namespace stroma::meshing
