#pragma once
/// \file barycentric.hpp
/// Locating material points in a tetrahedral mesh and interpolating with barycentric weights
/// (probes now; visual-mesh mapping later).

#include <array>

#include "tissue/tet_mesh.hpp"

namespace stroma {

/// A point embedded in one tetrahedron: x(p) = Σ w_k x(node_k).
struct BarycentricPoint {
  std::array<int32_t, 4> node{};  ///< node indices (in the mesh it was located in)
  std::array<double, 4> w{};      ///< weights, sum to 1
  int32_t tet = -1;               ///< containing (or nearest) tetrahedron
  double distance = 0;            ///< 0 if inside; else distance to the nearest tetrahedron
};

/// Barycentric coordinates of p in tetrahedron t (may be negative outside).
std::array<double, 4> barycentric_coordinates(const TetMesh& mesh, const Tet& t, const Vec3& p);

/// Finds the tetrahedron containing p (within a small tolerance) or, if none does, the one
/// nearest to it, whose weights are clamped to the tetrahedron (the projection onto it).
BarycentricPoint locate_point(const TetMesh& mesh, const Vec3& p);

}  // namespace stroma
