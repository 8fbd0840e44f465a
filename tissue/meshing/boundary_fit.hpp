#pragma once
/// \file boundary_fit.hpp
/// Volume-preserving fit of a mesh's boundary to the curved surface it was meshed from.
///
/// Delaunay refinement puts boundary vertices on the surface, so every boundary facet is a
/// chord: inside a convex part, outside a concave one, and a curved region loses volume in
/// proportion to facet size squared over curvature radius (docs/MESHING.md measures it: -2.4 %
/// on a 5,000-element torus, -4.9 % on its 10 mm inclusion). Over a facet whose vertices lie on
/// a smooth surface the gap is a quadratic vanishing at the vertices, whose mean over the
/// facet is 3/4 of its value at the centroid (for any quadratic: the mean of the barycentric
/// product l_i l_j is 1/12, its centroid value 1/9). So each facet's centroid gap s is found
/// along its normal, and each surface vertex moves along the facets' normals by 3/4 of the
/// area-weighted mean s of its facets: the facets then straddle the surface, region volumes are
/// kept to second order, and the largest deviation halves. Vertices where three or more
/// regions meet stay put (they lie on the region's curves); a move that would shrink any of
/// the vertex's elements below a fifth of its volume, or give one of them a dihedral angle
/// below both its own smallest and `min_dihedral_deg`, is not made.

#include <cstdint>
#include <functional>

#include "tissue/tet_mesh.hpp"

namespace stroma::meshing {

struct BoundaryFitReport {
  int64_t facets = 0;           ///< boundary and interface facets
  int64_t facets_measured = 0;  ///< whose gap to the surface was found within the search range
  int64_t vertices_moved = 0;
  int64_t vertices_kept = 0;    ///< junctions, and moves refused for an element's sake
  double max_shift = 0;         ///< largest vertex move (mesh units)
};

/// Fits `mesh` (tags: regions; background 0) to the surface where `tag_at` (the region at a
/// point, 0 outside) changes. `search` bounds how far from a facet the surface is sought (a few
/// facet distances). Elements keep their orientation.
BoundaryFitReport fit_boundary_to_surface(TetMesh& mesh, const std::function<int32_t(const Vec3&)>& tag_at, double search,
                                          double min_dihedral_deg);

}  // namespace stroma::meshing
