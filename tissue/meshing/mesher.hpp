#pragma once
/// \file mesher.hpp
/// Volume meshing for `stroma mesh`: a closed triangle surface, or a labelled image (a
/// segmentation), to a quality tetrahedral mesh, by CGAL's Mesh_3 (Delaunay refinement, then
/// ODT smoothing, sliver perturbation and sliver exudation). Stroma writes no mesher; this
/// layer turns Stroma's inputs into CGAL's domains, its options into CGAL's criteria, and
/// CGAL's complex back into a TetMesh, and checks what it got.
///
/// Sizes: `size` is the mesh's mean edge length (output units: metres for images, the
/// surface's units times `scale` for surfaces); without it, `target_tets` is the element count.
/// CGAL bounds circumradii, not edges: a CGAL size H becomes the cell size 0.61 H (a regular
/// tetrahedron of edge H has circumradius sqrt(6)/4 H) and the facet size 0.58 H, and the
/// edges it makes are shorter than H by a factor that depends on the shape (boundary facets
/// are refined for the facet distance). So H is found by a size control: refine, measure the
/// mean edge (or the count), correct H by a secant step on log scales, up to four refinements
/// (refinement is the cheap stage; the optimisers run once, on the last).
///
/// Determinism: CGAL's random choices draw from a generator seeded with `seed`, and meshing is
/// sequential, so the same input and options give the same mesh.

#include <cstdint>
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "io/label_image.hpp"
#include "tissue/mesh_quality.hpp"
#include "io/surface_io.hpp"
#include "tissue/tet_mesh.hpp"
#include "tissue/meshing/boundary_fit.hpp"

namespace stroma::meshing {

/// Meshing parameters. Defaults are what `stroma mesh` uses.
struct MeshingOptions {
  /// Mean edge length the mesh should have (> 0), within 8 %. 0: about `target_tets` elements.
  double size = 0;
  /// For size 0: the element count, within 15 %. Default: what one core steps at 1 kHz
  /// (docs/REALTIME.md).
  int64_t target_tets = 5000;
  /// Smallest dihedral angle the mesh must have (degrees): the optimisers aim 5 degrees above
  /// it, and the result is checked against it. CGAL guarantees no bound; measured minima are
  /// 8-10 degrees on smooth surfaces and 1 mm images, 5.6-7.4 on anisotropic and 256^3 images
  /// (docs/MESHING.md), hence the default.
  double min_dihedral_deg = 5.0;
  /// Elements with a dihedral angle below this are reported as slivers (degrees).
  double sliver_angle_deg = 5.0;
  /// Largest distance between a boundary facet and the input surface; 0: H / 40 for a surface;
  /// for an image H / 20 but at least a quarter of the voxel's mean width (finer would resolve
  /// the voxels' ripples in the smoothed labels, not the shape).
  double facet_distance = 0;
  /// Fit the boundary so that facets straddle the surface instead of being its chords
  /// (boundary_fit.hpp): region volumes kept to second order in the facet size. Surfaces with
  /// protected feature edges (`feature_angle_deg` > 0) are not fitted.
  bool fit_boundary = true;
  double max_seconds_per_optimiser = 60;  ///< ODT, perturbation and exudation each
  uint32_t seed = 1;
  /// Surfaces: let CGAL remove self-intersections (PMP::experimental::remove_self_intersections:
  /// the triangles around each are removed and the hole refilled) instead of refusing them.
  bool repair_self_intersections = false;
  /// Surfaces: protect sharp edges, where neighbouring triangles' normals differ by more than
  /// this (degrees; 0: none). Organs are smooth, so the default is 0; CAD-like parts with
  /// crisp edges keep them with e.g. 60.
  double feature_angle_deg = 0;
  /// Images: the Gaussian that smooths each label's indicator, sigma in voxels along each axis
  /// (0: trilinear interpolation of the raw labels, staircase surfaces).
  double smooth_voxels = 0.4;
  /// Called with a one-line message at each stage and every few seconds during long ones.
  std::function<void(const std::string&)> progress;
};

/// A produced mesh with its quality report and what each stage cost.
struct MeshingResult {
  TetMesh mesh;            ///< nodes in output units; tet_tags = region labels (1 for a surface)
  MeshQuality quality;     ///< regions carry input volumes; hausdorff is set
  double size = 0;         ///< the CGAL size H the size control settled on
  std::string size_asked;  ///< what the size control aimed at ("mean edge 0.0015", "5000 elements")
  int size_passes = 0;     ///< refinements the size control made
  BoundaryFitReport fit;   ///< images: what the boundary fit moved
  std::vector<std::pair<std::string, double>> stage_seconds;
  std::vector<std::string> notes;  ///< what was changed on the way (a repaired surface)
};

/// Meshes the volume a closed surface bounds. `scale` multiplies the input's coordinates first.
/// Throws InputError (naming `input.source`) when the surface is open, non-manifold or
/// self-intersecting, listing the offending edges or triangle pairs with their coordinates, or
/// when an option is out of range. Nothing is written by this function.
MeshingResult mesh_surface(const SurfaceMesh& input, double scale, const MeshingOptions& options);

/// Meshes the labelled regions of `image`: every label in `labels` (label, name) becomes a
/// region of tetrahedra tagged with that label; other labels are background. Interfaces between
/// labels are conforming (one shared surface). Throws InputError for a label not in the image, a
/// region too small for the size, or an image with nothing to mesh.
MeshingResult mesh_label_image(const LabelImage& image, const std::vector<std::pair<int32_t, std::string>>& labels,
                               const MeshingOptions& options);

}  // namespace stroma::meshing
