/// \file options.cpp
/// Checks of MeshingOptions and the default size, shared by the surface and image meshers.

#include <cmath>

#include <fmt/format.h>

#include "tissue/input_error.hpp"
#include "tissue/meshing/mesher.hpp"

namespace stroma::meshing::detail {

void check_options(const std::string& source, const MeshingOptions& o) {
  if (!(o.size >= 0) || !std::isfinite(o.size))
    throw InputError(source, 0, "--size", fmt::format("{} is not a length > 0", o.size));
  if (!(o.min_dihedral_deg >= 0 && o.min_dihedral_deg < 30))
    throw InputError(source, 0, "--min-dihedral", fmt::format("{} degrees: CGAL's optimisers reach at most ~15-20; give 0..30", o.min_dihedral_deg));
  if (!(o.facet_distance >= 0) || !std::isfinite(o.facet_distance))
    throw InputError(source, 0, "--facet-distance", fmt::format("{} is not a length >= 0", o.facet_distance));
  if (o.size == 0 && o.target_tets < 1)
    throw InputError(source, 0, "--tets", fmt::format("{} is not a positive count", o.target_tets));
}

/// The edge length that gives about `target` tetrahedra in `volume`: Delaunay refinement with
/// these criteria, then ODT, leaves elements of mean volume ~0.05 H^3 (measured: a sphere
/// 0.063, SOFA's liver 0.052-0.054 H^3 at 2k-10k elements), against 0.118 H^3 for the regular
/// tetrahedron of edge H.
double size_for_tets(double volume, int64_t target) { return std::cbrt(volume / (0.05 * double(target))); }

}  // namespace stroma::meshing::detail
