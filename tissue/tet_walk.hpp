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

#include <cstdint>
#include <vector>

#include "tissue/fem_model.hpp"

namespace stroma {

/// Per element e, its face neighbours: out[4e + i] is the element across the face opposite its
/// node i (−1: a boundary face). Load time.
std::vector<int32_t> tet_face_neighbours(const std::vector<ElementParams>& elements);

/// Barycentric weights of p in element e at positions x (3 per node; may be negative outside).
void tet_weights(const ElementParams& e, const double* x, const double* p, double* w);

struct TetWalkResult {
  int32_t tet = -1;        ///< the tetrahedron reached (holding p when inside)
  double w[4] = {0, 0, 0, 0};  ///< p's weights in it (inside: ≥ 0, sum 1; outside: clamped to it)
  bool inside = false;
  bool lost = false;       ///< max_steps reached (a degenerate or cycling path): neither inside nor a boundary
  int32_t steps = 0;
};

/// Walks from element `start` to the point p at positions x. No allocation.
TetWalkResult walk_to_point(const std::vector<ElementParams>& elements, const int32_t* neighbours, const double* x,
                            int32_t start, const double* p, int32_t max_steps = 4096);

}  // namespace stroma
