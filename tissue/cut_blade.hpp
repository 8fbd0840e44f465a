#pragma once
/// \file cut_blade.hpp
/// Where a blade cuts: the surface its edge sweeps over one step, against the mesh's edges in
/// their current positions. A crossed edge records the crossing as a parameter along the edge —
/// a material point (the same parameter in the rest shape), so the cut follows the tissue
/// however it has deformed. An edge is cut once; later crossings leave it as it is.

#include <array>
#include <cstdint>
#include <vector>

#include "tissue/cut_topology.hpp"
#include "tissue/tet_mesh.hpp"

namespace stroma {

/// The blade's cutting edge at the start (a0 → b0) and end (a1 → b1) of a step. The swept
/// surface is the ruled quad a0 b0 b1 a1, taken as the triangles (a0, b0, b1) and (a0, b1, a1).
struct SweptBlade {
  Vec3 a0, b0, a1, b1;
};

/// One step of a blade's edge in its own plane: the swept surface, the travel it counts, and
/// whether it went forward.
struct BladeStep {
  SweptBlade sweep;
  Vec3 travel{0, 0, 0};  ///< the edge midpoint's travel within the blade's plane (m)
  double travel_len2 = 0;
  bool forward = false;  ///< the travel has a component along the way the edge faces
};

/// The surface a blade's edge sweeps from its last position (last_a → last_b) to now (a → b),
/// given the blade's normal (the flat's direction: its local y) and the way its edge faces
/// (local z), for a blade of half-thickness `half_thickness`. Only the sharp edge cuts, in the
/// blade's plane: the travel's component along the normal is the flat pushing tissue aside
/// (contact on the lips, no cut), so the last position is moved sideways into the current plane;
/// a blade drawn backwards or along its own edge sweeps nothing (forward = false). The swept
/// surface starts behind where the edge was — by the half-thickness or half the travel,
/// whichever is more: each step tests the mesh where it is now, so tissue that moved back
/// across the edge's last position between two steps would otherwise fall between two sweeps
/// (measured: a node of a sagging beam 0.1 mm behind the edge left the beam joined). An edge is
/// cut once (cut_edges), so the overlap cuts nothing twice.
BladeStep blade_step(const Vec3& last_a, const Vec3& last_b, const Vec3& a, const Vec3& b, const double normal[3],
                     const double forward[3], double half_thickness);

/// The cutting resistance of a step that cut `edges` edges with `travel` (its length² travel_len2):
/// toughness × the area cut (estimated as edges / edges_per_area: CutSupport) per unit of
/// travel, against the travel (N). Zero when nothing was cut or nothing is known.
Vec3 cut_resistance(int edges, double edges_per_area, double toughness, const Vec3& travel, double travel_len2);

/// Cuts every uncut edge of `adj` that the swept surface crosses: edge_cut[e] becomes the
/// crossing's parameter from the edge's lower node, kept in [f_e, 1 − f_e] with f_e =
/// min_fraction[e] (null: kCutMinFraction for every edge; cut_topology.hpp). The edge's ends are the points edge_points[e] of `x` (3 per point): on
/// the uncut mesh its nodes (adj.edges); on a cut one, the DOFs of a copy holding the (uncut)
/// edge as material. Returns the number of edges it cut. No allocation.
int cut_edges(const double* x, const TetAdjacency& adj, const std::vector<std::array<int32_t, 2>>& edge_points,
              const SweptBlade& blade, std::vector<double>& edge_cut, const double* min_fraction = nullptr);
/// The same on the uncut mesh (edge ends: its nodes).
inline int cut_edges(const double* x, const TetAdjacency& adj, const SweptBlade& blade, std::vector<double>& edge_cut) {
  return cut_edges(x, adj, adj.edges, blade, edge_cut);
}

/// Where segment p → q crosses triangle (a, b, c): the parameter along the segment in [0, 1], or
/// a negative number when it does not. p and q must lie strictly on opposite sides of the
/// triangle's plane, a point *on* the plane counting as the side its normal points to: so an
/// edge lying in the plane is not cut, and a blade passing exactly through a node cuts the
/// node's edges to one side only (it does not cut the node out as a chip). The crossing may lie
/// on the triangle's edges.
double edge_crossing(const Vec3& p, const Vec3& q, const Vec3& a, const Vec3& b, const Vec3& c);

}  // namespace stroma
