#pragma once
/// \file visual_mapping.hpp
/// The barycentric mapping of a visual surface onto a tetrahedral mesh: the fine surface that
/// is drawn (and touched) follows the coarse mesh that is simulated. Compiled once at load time
/// (locating every vertex in the tetrahedra, with a grid so large meshes load in well under a
/// second); applied every frame as a fixed weighted sum, with no search and no allocation.

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "tissue/tet_mesh.hpp"

namespace stroma {

/// p = Φ(q): each visual vertex is a fixed barycentric combination of the 4 nodes of the
/// tetrahedron containing it (nearest tetrahedron, with weights clamped onto it, for vertices
/// just outside). Linear in q, so its Jacobian J = ∂p/∂q is the constant weight matrix; forces
/// on visual vertices map back to nodes as Jᵀf.
struct VisualMapping {
  std::vector<std::array<int32_t, 4>> node;  ///< global node indices, per visual vertex
  std::vector<std::array<double, 4>> w;      ///< weights (sum to 1), per visual vertex
  std::vector<int32_t> tet;  ///< containing/nearest tet (global element index if offset given)
  double max_distance = 0;   ///< largest distance of a vertex outside the mesh (0 if none)
  int outside = 0;           ///< vertices outside the mesh (mapped to their projection on it)

  /// Number of visual vertices.
  size_t size() const { return node.size(); }

  /// out[3v+k] = Σ_i w[v][i] · x[3·node[v][i] + k]. x: 3 doubles per node (global numbering);
  /// out: 3 values per visual vertex. The float overload feeds vertex buffers directly (sums
  /// are taken in double, then rounded once).
  void apply(const double* x, double* out) const;
  /// See apply(const double*, double*).
  void apply(const double* x, float* out) const;

  /// f_nodes[3n+k] += Σ over visual vertices v using node n of w · f_visual[3v+k] (Jᵀf).
  /// Accumulates: the caller clears f_nodes, so several mappings (or other loads) can add up.
  void apply_transpose(const double* f_visual, double* f_nodes) const;
};

/// Builds the mapping of `vertices` into `mesh` (its nodes are numbered from node_offset, its
/// tets from tet_offset in the global arrays). A vertex inside a tetrahedron (barycentric
/// weights ≥ −1e-9) keeps its exact weights; one outside every tetrahedron is projected onto
/// the nearest one and counted in `outside`. Throws InputError(source, 0, "", ...) if a vertex
/// is farther than `max_distance` from every tetrahedron (naming the first such vertex, its
/// distance and how many there are), or if the mesh has no tetrahedra.
VisualMapping build_visual_mapping(const TetMesh& mesh, const std::vector<Vec3>& vertices,
                                   double max_distance, int32_t node_offset = 0,
                                   int32_t tet_offset = 0, const std::string& source = "");

}  // namespace stroma
