#pragma once
/// \file mesh_quality.hpp
/// Element quality of a tetrahedral mesh, as `stroma mesh` reports it: radius ratio and
/// dihedral angles (histograms, extremes), slivers, inverted elements and the volume of each
/// region. Plain geometry, no meshing library: it measures any TetMesh (a produced one, or one a
/// user brings).
///
/// Measures (each 1 for the regular tetrahedron, 0 for a flat one):
/// - radius ratio  rho = 3 r_in / R_circ, in [0, 1];
/// - dihedral angles: the six angles between face pairs, in degrees (70.53 for the regular
///   tetrahedron; a sliver has some near 0 and some near 180).
/// A *sliver* here is an element whose smallest dihedral angle is below `sliver_angle_deg`: the
/// elements that make corotational FEM stiff and ill-conditioned, whatever their shape's name
/// (sliver, cap, needle, wedge all have a small dihedral angle).

#include <cstdint>
#include <string>
#include <vector>

#include "tissue/tet_mesh.hpp"

namespace stroma {

/// Volume of one region of a mesh, and the volume it should have (the input's; NaN if unknown).
struct RegionVolume {
  int32_t tag = 0;
  std::string name;
  int64_t tets = 0;
  double volume = 0;                    ///< m^3 (mesh units cubed)
  double input_volume = 0.0 / 0.0;      ///< m^3; NaN when not known
  double relative_error() const { return (volume - input_volume) / input_volume; }
};

/// A histogram over [lo, hi) with equal bins; values outside go into the end bins.
struct Histogram {
  double lo = 0, hi = 1;
  std::vector<int64_t> counts;
};

/// Quality of a tetrahedral mesh. Invariants: counts of both histograms sum to `tets`;
/// radius_ratio_min <= radius_ratio_max; dihedral_min_deg <= dihedral_max_deg.
struct MeshQuality {
  int64_t nodes = 0, tets = 0;
  double radius_ratio_min = 0, radius_ratio_max = 0, radius_ratio_mean = 0;
  double dihedral_min_deg = 0, dihedral_max_deg = 0;
  /// Edge lengths over the mesh's distinct edges (mesh units): what `stroma mesh --size` aims at.
  double edge_min = 0, edge_mean = 0, edge_max = 0;
  Histogram radius_ratio;  ///< per element, 20 bins over [0, 1]
  Histogram dihedral;      ///< every element's six angles, 18 bins of 10 degrees over [0, 180]
  double sliver_angle_deg = 5.0;
  int64_t slivers = 0;     ///< elements with a dihedral angle below sliver_angle_deg
  int64_t inverted = 0;    ///< elements with volume <= 0 (as ordered)
  std::vector<RegionVolume> regions;  ///< by tag, increasing; one entry (tag 0) without tags
  double total_volume = 0;
  /// Symmetric Hausdorff distance between the mesh's boundary and the input surface (m); NaN
  /// when not measured (set by the mesher, which has the input).
  double hausdorff = 0.0 / 0.0;
  std::string hausdorff_reference;  ///< what the distance is measured against
};

/// Measures `mesh`. Region names come from mesh.tag_names. `sliver_angle_deg` sets the sliver
/// threshold.
MeshQuality measure_mesh_quality(const TetMesh& mesh, double sliver_angle_deg = 5.0);

/// Mean length of the mesh's distinct edges (0 without elements).
double mean_edge_length(const TetMesh& mesh);

/// Radius ratio 3 r_in / R_circ of one tetrahedron (0 for a degenerate one).
double tet_radius_ratio(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d);

/// The six dihedral angles of one tetrahedron, degrees, at edges 01, 02, 03, 12, 13, 23.
std::array<double, 6> tet_dihedral_angles_deg(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d);

/// Human-readable multi-line summary (what `stroma mesh` prints).
std::string format_mesh_quality(const MeshQuality& q);

}  // namespace stroma
