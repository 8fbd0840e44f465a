#include "engine/needle_mesh.hpp"

#include <algorithm>
#include <array>
#include <limits>
#include <map>

#include "tissue/cut_model.hpp"
#include "tissue/cut_walk_neighbours.hpp"

namespace stroma {

namespace {

/// An element of each node (a walk's start from a touched node).
std::vector<int32_t> element_of_each_node(const FemModel& fem) {
  std::vector<int32_t> out(size_t(fem.num_nodes), 0);
  for (size_t e = 0; e < fem.elements.size(); ++e)
    for (const int32_t n : fem.elements[e].node) out[size_t(n)] = static_cast<int32_t>(e);
  return out;
}

}  // namespace

void compile_needle_mesh(Model& m) {
  const FemModel& fem = m.fem;
  m.tet_neighbours = tet_face_neighbours(fem.elements);
  m.node_tet = element_of_each_node(fem);
  // Each collision triangle's element: the one it is a face of (the first, for an inner face of
  // a body that can tear).
  std::map<std::array<int32_t, 3>, int32_t> face_elem;
  for (size_t e = 0; e < fem.elements.size(); ++e)
    for (int i = 0; i < 4; ++i) face_elem.emplace(sorted_tet_face(fem.elements[e], i), static_cast<int32_t>(e));
  m.collision_tri_elem.assign(m.collision_triangles.size(), -1);
  for (size_t t = 0; t < m.collision_triangles.size(); ++t) {
    std::array<int32_t, 3> f = m.collision_triangles[t];
    std::sort(f.begin(), f.end());
    const auto it = face_elem.find(f);
    if (it != face_elem.end()) m.collision_tri_elem[t] = it->second;
  }
}

void compile_cut_needle_mesh(Model& m, const CutTopology& topo, const CutBase& base, const std::vector<double>& rest,
                             const std::vector<double>& edge_cut) {
  m.tet_neighbours = cut_copy_face_neighbours(topo, base.tets, base.adj);
  m.node_tet = element_of_each_node(m.fem);
  m.element_plane_begin.assign(1, 0);
  m.element_planes.clear();
  for (size_t c = 0; c < topo.copies.size(); ++c) {
    copy_material_planes(topo, base.tets, rest, edge_cut, base.adj, static_cast<int32_t>(c), m.element_planes);
    m.element_plane_begin.push_back(static_cast<int32_t>(m.element_planes.size()));
  }
  m.element_next_twin.resize(topo.copies.size());
  for (size_t t = 0; t + 1 < topo.tet_copy_begin.size(); ++t)
    for (int32_t c = topo.tet_copy_begin[t]; c < topo.tet_copy_begin[t + 1]; ++c)
      m.element_next_twin[size_t(c)] = c + 1 < topo.tet_copy_begin[t + 1] ? c + 1 : topo.tet_copy_begin[t];
}

int32_t carried_copy(const CutTopology& old_topo, int32_t old_copy, const CutTopology& topo, const WalkMesh& walk,
                     const double* w) {
  const ElementCopy& src = old_topo.copies[size_t(old_copy)];
  // The new copies of its tetrahedron that refine its old copy (their material within its),
  // the one whose material the point lies deepest in.
  int32_t best = -1;
  double best_depth = -std::numeric_limits<double>::infinity();
  for (int32_t c = topo.tet_copy_begin[size_t(src.tet)]; c < topo.tet_copy_begin[size_t(src.tet) + 1]; ++c) {
    if ((topo.copies[size_t(c)].material & src.material) != topo.copies[size_t(c)].material) continue;
    const double depth = walk.material_depth(c, w);
    if (best < 0 || depth > best_depth) best = c, best_depth = depth;
  }
  return best < 0 ? topo.tet_copy_begin[size_t(src.tet)] : best;  // (never on a refinement: keep one)
}

void transfer_needles(const Model& old_m, const std::vector<NeedleState>& from, const Model& m,
                      std::vector<NeedleState>& to) {
  const CutTopology& old_topo = *old_m.topology;
  const CutTopology& topo = *m.topology;
  const WalkMesh walk = needle_walk_mesh(m);
  auto carry = [&](TrackPoint& tp) {
    tp.tet = carried_copy(old_topo, tp.tet, topo, walk, tp.w);
    tp.node = topo.copies[size_t(tp.tet)].dof;
  };
  for (size_t k = 0; k < from.size(); ++k) {
    NeedleState& ns = to[k];
    ns = from[k];  // the same capacity: no allocation
    for (int32_t i = 0; i < ns.count; ++i) carry(ns.track[size_t(i)]);
    if (ns.has_front) carry(ns.front);
  }
}

}  // namespace stroma
