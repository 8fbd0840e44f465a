#pragma once
/// \file tet_walk.hpp
/// Finding the tetrahedron that holds a point of the deformed tissue by walking from a nearby
/// one across faces (a visibility walk), in time proportional to the distance rather than to the
/// mesh: what the needle's track (rigid/needle_track.hpp) does each time its tip cuts on.
///
/// Each step leaves the current tetrahedron through the face opposite its most negative
/// barycentric weight; the walk ends inside one (every weight ≥ −1e-9), or where that face is on
/// the mesh's boundary (the point is outside the tissue there: a needle's tip leaving it), or
/// after `max_steps` (a degenerate or cycling path: reported as lost).
///
/// Across a cut mesh (tissue/cut_topology.hpp) the elements are copies of tetrahedra: each has
/// its whole tetrahedron's shape but material only on its side of the cut, and copies across the
/// cut share no face (their DOFs differ), so the cut faces are boundary faces. A point inside a
/// copy's shape but beyond its material planes (WalkMesh) is past the cut — outside the tissue
/// there, as beyond a boundary face: the walk ends outside, its weights moved into the material —
/// unless the walk entered that copy through a face whose DOFs a twin (another copy of the same
/// tetrahedron: WalkMesh::next_twin) shares and the twin holds the point in its material. Where
/// an incision ends, a face can border both twins, each on its part of the face; the walk
/// enters the one its face neighbours name (tissue/cut_walk_neighbours.hpp) and takes the twin
/// if the point is there. From its start copy, or into a twin not glued to the face it came
/// through, a walk never goes: that is across the cut.

#include <array>
#include <cstdint>
#include <vector>

#include "tissue/fem_model.hpp"

namespace stroma {

/// Per element e, its face neighbours: out[4e + i] is the element across the face opposite its
/// node i (−1: a boundary face). Load time.
std::vector<int32_t> tet_face_neighbours(const std::vector<ElementParams>& elements);

/// The face of element e opposite its node i, its node indices sorted: a key shared by the
/// elements on both sides of an inner face (and by a surface triangle over it).
std::array<int32_t, 3> sorted_tet_face(const ElementParams& e, int i);

/// Barycentric weights of p in element e at positions x (3 per node; may be negative outside).
void tet_weights(const ElementParams& e, const double* x, const double* p, double* w);

/// The tetrahedra a walk crosses: elements, their face neighbours (tet_face_neighbours) and, for
/// a cut mesh's copies, where each one's material lies — element e's planes are
/// planes[plane_begin[e] .. plane_begin[e + 1]), each as weights c with c·w ≥ 0 on the material's
/// side (tissue/cut_topology.hpp, copy_material_planes; a whole tetrahedron has none).
/// next_twin[e] is the next copy of e's tetrahedron, cycling through them (e itself for a
/// tetrahedron of one copy). Invariant: plane_begin and next_twin are both null (an uncut mesh)
/// or have elements->size() + 1 and elements->size() entries.
struct WalkMesh {
  const std::vector<ElementParams>* elements = nullptr;
  const int32_t* neighbours = nullptr;
  const int32_t* plane_begin = nullptr;
  const std::array<double, 4>* planes = nullptr;
  const int32_t* next_twin = nullptr;

  /// How far inside e's material the weights w lie (m, rest): the least c·w over its planes
  /// (+∞ for an element all material).
  double material_depth(int32_t e, const double* w) const;
  /// Moves weights w (inside e's shape, beyond its material) into its material along the line
  /// to its material nodes' centroid, to the first point every plane accepts.
  void into_material(int32_t e, double* w) const;
};

struct TetWalkResult {
  int32_t tet = -1;        ///< the tetrahedron reached (holding p when inside)
  double w[4] = {0, 0, 0, 0};  ///< p's weights in it (inside: ≥ 0, sum 1; outside: clamped to it)
  bool inside = false;
  bool lost = false;       ///< max_steps reached (a degenerate or cycling path): neither inside nor a boundary
  bool past_cut = false;   ///< outside because p is beyond the cut in `tet` and its twins (its weights moved into `tet`'s material)
  int32_t steps = 0;
};

/// Walks from element `start` to the point p at positions x. No allocation.
TetWalkResult walk_to_point(const WalkMesh& mesh, const double* x, int32_t start, const double* p,
                            int32_t max_steps = 4096);

/// An uncut mesh's walk.
inline TetWalkResult walk_to_point(const std::vector<ElementParams>& elements, const int32_t* neighbours,
                                   const double* x, int32_t start, const double* p, int32_t max_steps = 4096) {
  return walk_to_point(WalkMesh{&elements, neighbours, nullptr, nullptr, nullptr}, x, start, p, max_steps);
}

}  // namespace stroma
