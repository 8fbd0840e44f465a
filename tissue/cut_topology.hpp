#pragma once
/// \file cut_topology.hpp
/// Cutting by the virtual node algorithm (Molino, Bao & Fedkiw 2004), as the mesh's topology:
/// which tetrahedra are split, into which copies, which node copies ("DOFs") the copies share,
/// and the surface the material now has (docs/CUTTING.md says why this method).
///
/// The cut state is one number per edge of the uncut mesh: where along the edge the blade
/// crossed it (or that it did not). Everything here is a pure function of the uncut mesh and
/// that state, so a topology can be rebuilt from scratch on any thread and a replay rebuilds
/// the same one bit for bit.
///
///  - A tetrahedron's nodes fall into components joined by its uncut edges. One component: the
///    tetrahedron is whole (one copy). More: one copy per component, each with the whole
///    tetrahedron's rest shape (so no element is ever worse shaped than the uncut mesh's) and the
///    share of its volume on that component's side of the cut (so mass and stiffness are
///    conserved exactly).
///  - A copy's nodes are its component's ("material") nodes and, for the others, new virtual
///    nodes. Copies of face-neighbouring tetrahedra whose material meets on the shared face are
///    glued: they share the face's three node copies. The DOFs are the classes of that gluing.
///  - The surface is, per copy, the boundary of its material (the cut polygon through the cut
///    points of its edges, and its part of each face), with the parts two glued copies share
///    cancelled: a closed oriented surface, the cut faces flagged.

#include <array>
#include <cstdint>
#include <vector>

#include "tissue/tet_mesh.hpp"

namespace stroma {

/// Local edges of a tetrahedron: edge k joins nodes kTetEdge[k][0] < kTetEdge[k][1].
inline constexpr int kTetEdge[6][2] = {{0, 1}, {0, 2}, {0, 3}, {1, 2}, {1, 3}, {2, 3}};

/// Edges and face neighbours of a tetrahedral mesh (the uncut one); fixed for its life.
/// Invariants: edges[e][0] < edges[e][1]; tet_edges[t][k] is the edge joining the tet's local
/// nodes kTetEdge[k]; face_neighbor[t][k] is the tetrahedron across the face opposite local
/// node k (−1: a boundary face).
struct TetAdjacency {
  std::vector<std::array<int32_t, 2>> edges;
  std::vector<std::array<int32_t, 6>> tet_edges;
  std::vector<std::array<int32_t, 4>> face_neighbor;
};

/// Builds the adjacency of `tets` over `num_nodes` nodes. Throws std::invalid_argument if a face
/// is shared by more than two tetrahedra (not a manifold mesh).
TetAdjacency build_tet_adjacency(const std::vector<Tet>& tets, int32_t num_nodes);

/// "Not cut" in an edge-cut array.
inline constexpr double kEdgeUncut = -1.0;
/// Cut points are kept at least a fraction f_e of an edge from its ends, so no copy's volume
/// share falls below f_e³ and no cut face degenerates: f_e = kCutMinFraction on an edge no longer
/// than 4·(the body's shortest edge); on longer edges it shrinks, to keep the cut within
/// kCutMaxShift of the body's shortest edge of the blade (the shift is f_e·|e|), down to
/// kCutMinFractionFloor (on an edge over 20× the shortest). cut_edge_min_fraction computes it.
inline constexpr double kCutMinFraction = 0.05;
inline constexpr double kCutMinFractionFloor = 0.01;
inline constexpr double kCutMaxShift = 0.2;  ///< of the body's shortest edge (the issue's bound: 1/4)

/// f_e for an edge of length `length` in a body whose shortest edge is `h_min`.
inline double cut_edge_min_fraction(double length, double h_min) {
  if (!(length > 0)) return kCutMinFraction;
  const double f = kCutMaxShift * h_min / length;
  return f > kCutMinFraction ? kCutMinFraction : f < kCutMinFractionFloor ? kCutMinFractionFloor : f;
}

/// One copy of a tetrahedron. `material` has bit k set when local node k is on its side.
struct ElementCopy {
  int32_t tet = 0;                 ///< the uncut tetrahedron
  uint8_t material = 0xF;          ///< its component's local nodes (bits 0..3)
  double fraction = 1.0;           ///< its share of the tetrahedron's volume, in (0, 1]
  std::array<int32_t, 4> dof{};    ///< the DOF of each local node
};

/// A surface vertex: the point (1 − t)·X[a] + t·X[b] of DOFs a and b (a node: a == b, t = 0).
struct CutVertex {
  int32_t a = 0, b = 0;
  double t = 0;
};

/// A surface triangle, counter-clockwise seen from outside the material.
struct CutTriangle {
  std::array<int32_t, 3> v{};  ///< CutTopology::vertices
  int32_t copy = 0;            ///< the copy whose material it bounds (all its DOFs are that copy's)
  bool cut = false;            ///< a face the cut made (inner tissue), not the uncut surface
};

/// A face inside the material: shared by two glued copies (`a`, `b`), counter-clockwise seen
/// from outside a's material (into b). Tears open such faces (engine/damage.cpp).
struct CutInternalFace {
  std::array<int32_t, 3> v{};  ///< CutTopology::vertices
  int32_t a = 0, b = 0;        ///< the copies on either side
};

/// The topology of a cut mesh. Invariants: copies are ordered by tetrahedron (a tetrahedron's
/// copies contiguous, by their lowest material node); each tetrahedron has ≥ 1 copy and its
/// copies' fractions sum to 1; every DOF is used by some copy or is an unused node's; dof_node
/// maps each DOF to its uncut node, node_dof each uncut node to its primary DOF (the first
/// class holding it as material); DOFs are numbered per node range: a range's uncut nodes keep
/// their order at the range's start and its new DOFs follow, so an uncut mesh's DOFs are its
/// nodes.
struct CutTopology {
  std::vector<ElementCopy> copies;
  std::vector<int32_t> tet_copy_begin;  ///< copies of tet t: [tet_copy_begin[t], tet_copy_begin[t+1])
  int32_t num_dofs = 0;
  std::vector<int32_t> dof_node;
  std::vector<int32_t> node_dof;
  /// 1 when the DOF holds its node as material in some copy (or is an unused node's), 0 for a
  /// purely virtual node copy: a clamp holds the material, not its virtual copies across a cut.
  std::vector<uint8_t> dof_material;
  std::vector<int32_t> range_dof_begin;  ///< per node range, its first DOF (and num_dofs last)
  std::vector<CutVertex> vertices;
  std::vector<CutTriangle> triangles;
  /// The faces between glued copies (only when asked for: build_cut_topology's internal_faces);
  /// their vertices follow the surface's in `vertices`.
  std::vector<CutInternalFace> internal;
  int32_t split_tets = 0;       ///< tetrahedra with more than one copy
  int32_t cut_edges = 0;        ///< edges with a cut point
  /// Triangles the cancellation could not pair (overlapping parts of one face): 0 on every
  /// consistent input; counted, not thrown, so a cut never stops the simulation.
  int32_t unpaired_faces = 0;
  /// Edges of the surface still shared by more than two triangles after it was made manifold
  /// (cut_topology.cpp, make_manifold): 0 on every input tested; counted, never thrown.
  int32_t nonmanifold_edges = 0;
};

/// The topology of the mesh (`tets` over `rest`, 3 per node) cut at `edge_cut` (per edge of
/// `adj`: the parameter along it from its lower node, in [f_e, 1 − f_e] (f_e ≤ kCutMinFraction),
/// or kEdgeUncut). `node_ranges` split the nodes into consecutive ranges (the bodies) whose DOFs
/// stay together: {0, n₁, …, num_nodes}; {0, num_nodes} for one body. Throws
/// std::invalid_argument when the arrays do not fit together (sizes, ranges not covering the
/// nodes in order). Surface vertices are numbered in order of first use by a triangle.
/// `internal_faces`: also list the faces between glued copies (CutTopology::internal), for
/// bodies that can tear; the surface is the same either way.
CutTopology build_cut_topology(const std::vector<Tet>& tets, const std::vector<double>& rest,
                               const TetAdjacency& adj, const std::vector<double>& edge_cut,
                               const std::vector<int32_t>& node_ranges, bool internal_faces = false);

/// Where copy `copy`'s material lies in its tetrahedron: one plane per triangle of its cut
/// polygon (rest shape), appended to `planes` as weights c of the tetrahedron's four local nodes
/// such that, for a point with barycentric weights w, c·w is its distance (m, rest) inside the
/// material's side of that plane (negative: beyond the cut). The point is in the material where
/// every plane gives ≥ 0 (a non-planar quad's fold makes this a little stricter than the true
/// side near the fold). A whole tetrahedron's only copy has none. Barycentric weights move with
/// the copy's linear deformation, so the planes hold in every deformed shape: what a needle's
/// walk across a cut mesh tests (tissue/tet_walk.hpp). Load or cut-build time (allocates).
void copy_material_planes(const CutTopology& topo, const std::vector<Tet>& tets, const std::vector<double>& rest,
                          const std::vector<double>& edge_cut, const TetAdjacency& adj, int32_t copy,
                          std::vector<std::array<double, 4>>& planes);

/// The copy of tetrahedron `tet` whose material holds the point with barycentric coordinates
/// `bary` (weights of the tet's four nodes) in the rest shape.
int32_t copy_containing(const CutTopology& topo, const std::vector<Tet>& tets, const std::vector<double>& rest,
                        const std::vector<double>& edge_cut, const TetAdjacency& adj, int32_t tet,
                        const std::array<double, 4>& bary);

}  // namespace stroma
