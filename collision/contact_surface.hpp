#pragma once
/// \file contact_surface.hpp
/// The compiled contact surface of all bodies, as tools and other bodies touch it.
///
/// The surface's vertices are *surface points*: the DOFs themselves (point i < num_dofs is DOF
/// i), then, on a cut mesh, the embedded points where the cut crossed an element copy's edges
/// (point num_dofs + j is (1 − t)·x[a] + t·x[b] of embedded[j]). The collide stage fills their
/// positions once per tick (surface_positions: on an uncut mesh there are none and the DOF
/// array itself is used, no copy); the BVH, tool contact and body contact read them, and every
/// contact spring is expanded back onto the DOFs through the triangle's SurfaceTriangleDofs.

#include <array>
#include <cmath>
#include <cstdint>
#include <vector>

#include "tissue/contact_spring.hpp"
#include "tissue/cut_topology.hpp"

namespace stroma {

/// How a point of a surface triangle acts on the DOFs: the triangle's distinct DOFs (≤ 4: a
/// triangle lies in one element copy), the weight of each for each triangle vertex (the point
/// with barycentric b has weight Σ_v b_v·W[v][d] on dof[d]), and the BSR slots of the DOF pairs
/// (kSurfaceDofs·a + b). Invariants: 1 ≤ n ≤ kSurfaceDofs; each row W[v][0..n) sums to 1;
/// slot[kSurfaceDofs·a + b] for a, b < n is the stored block (dof[a], dof[b]) or −1 for the
/// lower triangle. An uncut triangle: its three nodes, W the identity.
inline constexpr int kSurfaceDofs = 4;
struct SurfaceTriangleDofs {
  int32_t n = 3;
  int32_t dof[kSurfaceDofs] = {0, 0, 0, 0};
  double W[3][kSurfaceDofs] = {};
  int32_t slot[kSurfaceDofs * kSurfaceDofs] = {};
};

/// How a single surface point acts on the DOFs (body contact's vertex side): on one DOF with
/// weight 1 — a node, or an embedded point's material end (see triangle_dofs) — whose diagonal
/// block is `slot`.
struct SurfacePointDofs {
  int32_t dof = 0;
  int32_t slot = 0;
};

/// The contact surface of all bodies, as compiled: outward triangles over surface points, how
/// each acts on the DOFs, and each triangle's longest rest edge.
struct ContactSurface {
  const std::vector<std::array<int32_t, 3>>& triangles;
  const std::vector<SurfaceTriangleDofs>& dofs;
  const std::vector<double>& longest_edge;
  /// Per face 0 inactive / 1 active / 2 active with reversed orientation; null: all active.
  const uint8_t* active = nullptr;
  /// Per face 1 on a cut (a wound's lip), 0 not; null: no cut faces (an uncut mesh).
  const uint8_t* cut_face = nullptr;
};

/// Samples per triangle edge: clamp(ceil(edge·kContactSamplesPerRadius / radius), 1, 24), so the
/// sample spacing stays a fraction of the toucher's size (a tool's radius, a rigid body's
/// smallest feature) whatever the mesh (smooth while sliding).
inline constexpr double kContactSamplesPerRadius = 4.0;

/// Subdivision of surface triangle t for a toucher of size R (see kContactSamplesPerRadius).
inline int surface_samples_per_edge(const ContactSurface& surf, int32_t t, double R) {
  const double s = std::ceil(surf.longest_edge[static_cast<size_t>(t)] * kContactSamplesPerRadius / R);
  return s < 1 ? 1 : (s > 24 ? 24 : static_cast<int>(s));
}

/// Calls f(u, v) for the centroids of the s² sub-triangles of a triangle (composite midpoint
/// rule), in barycentric coordinates of vertices 1 and 2.
template <class F>
inline void for_each_triangle_sample(int ns, F&& f) {
  const double inv = 1.0 / ns;
  for (int i = 0; i < ns; ++i)
    for (int j = 0; j < ns - i; ++j) {
      f((i + 1.0 / 3.0) * inv, (j + 1.0 / 3.0) * inv);
      if (j < ns - i - 1) f((i + 2.0 / 3.0) * inv, (j + 2.0 / 3.0) * inv);
    }
}

/// Sub-triangle rows and columns per block of for_each_triangle_sample_culled.
inline constexpr int kSampleBlock = 4;

/// for_each_triangle_sample, in the same order, skipping whole blocks of kSampleBlock ×
/// kSampleBlock sub-triangle cells: keep(u, v, half) is asked once per block (the first time one
/// of its samples comes up) with the block's centre (barycentric, of vertices 1 and 2) and its
/// half-width as a fraction of the triangle's edges; its samples are visited only if it returns
/// true. A toucher small beside the triangle (a needle's wire on a coarse organ) then costs
/// the blocks near it, not all s² samples.
template <class Keep, class F>
inline void for_each_triangle_sample_culled(int ns, Keep&& keep, F&& f) {
  constexpr int B = kSampleBlock, kMaxBlocks = (24 + B - 1) / B;
  if (ns <= B || ns > 24) return for_each_triangle_sample(ns, f);
  int8_t state[kMaxBlocks][kMaxBlocks];  // −1 not asked, 0 skip, 1 keep
  for (auto& row : state)
    for (int8_t& v : row) v = -1;
  const double inv = 1.0 / ns;
  auto kept = [&](int i, int j) {
    int8_t& st = state[i / B][j / B];
    if (st < 0) {
      const int i0 = (i / B) * B, j0 = (j / B) * B;
      const double half = 0.5 * B * inv;
      st = keep(i0 * inv + half, j0 * inv + half, half) ? 1 : 0;
    }
    return st == 1;
  };
  for (int i = 0; i < ns; ++i)
    for (int j = 0; j < ns - i; ++j) {
      if (!kept(i, j)) continue;
      f((i + 1.0 / 3.0) * inv, (j + 1.0 / 3.0) * inv);
      if (j < ns - i - 1) f((i + 2.0 / 3.0) * inv, (j + 2.0 / 3.0) * inv);
    }
}

/// Sets sp's DOFs, weights and slots to the point with barycentric (b0, b1, b2) on a triangle.
inline void set_spring_point(const SurfaceTriangleDofs& td, double b0, double b1, double b2, ContactSpring& sp) {
  sp.n = td.n;
  for (int d = 0; d < td.n; ++d) {
    sp.node[d] = td.dof[d];
    sp.w[d] = b0 * td.W[0][d] + b1 * td.W[1][d] + b2 * td.W[2][d];
  }
  for (int a = 0; a < td.n; ++a)
    for (int b = 0; b < td.n; ++b) sp.slot[spring_slot(a, b)] = td.slot[kSurfaceDofs * a + b];
}

/// Sets sp to act on a single surface point's DOF.
inline void set_spring_point(const SurfacePointDofs& pd, ContactSpring& sp) {
  sp.n = 1;
  sp.node[0] = pd.dof;
  sp.w[0] = 1.0;
  sp.slot[0] = pd.slot;
}

/// Positions (or velocities) of the surface points: the DOFs' values `x` (3·num_dofs), then the
/// embedded points' lerps, into `out` (3·(num_dofs + embedded.size()), sized by the caller).
inline void surface_positions(const double* x, int32_t num_dofs, const std::vector<CutVertex>& embedded,
                              double* out) {
  for (int32_t i = 0; i < 3 * num_dofs; ++i) out[i] = x[i];
  double* e = out + 3 * static_cast<size_t>(num_dofs);
  for (const CutVertex& p : embedded) {
    const double* a = x + 3 * p.a;
    const double* b = x + 3 * p.b;
    for (int k = 0; k < 3; ++k) e[k] = (1.0 - p.t) * a[k] + p.t * b[k];
    e += 3;
  }
}

}  // namespace stroma

namespace stroma {

struct BsrPattern;

/// The DOF map of the triangle over surface points `tri` (points ≥ num_dofs are embedded
/// points). DOFs are listed in the order the vertices first name them (an uncut
/// triangle: its nodes in order, W the identity). An embedded point acts on one DOF,
/// embedded_dof[p − num_dofs]: the material end of its copy edge (see below). A DOF pair
/// missing from the pattern joins nodes of a fully fixed body (whose elements are not in it):
/// its row is projected to identity, so the first DOF's diagonal block is a harmless place for
/// what contact adds. Throws std::invalid_argument if the triangle involves more than four DOFs.
///
/// Why an embedded point's force goes to its material end only: the other end is a virtual
/// node, held by its copy alone — a copy whose share of the tetrahedron may be 5 % — so a
/// contact spread by the point's weights moved virtual nodes by up to 1/t times the push
/// (measured: a blade 0.5 mm thick pushing the lips of a beam's cut moved them 3–20 mm and
/// inverted copies). On the material end the push meets the tissue's full stiffness; the lip
/// follows its material node.
SurfaceTriangleDofs triangle_dofs(const BsrPattern& pattern, const std::array<int32_t, 3>& tri, int32_t num_dofs,
                                  const std::vector<int32_t>& embedded_dof);

/// The DOF map of one surface point (body contact's vertex side).
SurfacePointDofs point_dofs(const BsrPattern& pattern, int32_t point, int32_t num_dofs,
                            const std::vector<int32_t>& embedded_dof);

}  // namespace stroma
