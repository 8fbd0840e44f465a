#include "engine/thread_cut.hpp"

#include <stdexcept>
#include <string>

#include "engine/needle_mesh.hpp"

namespace stroma {

namespace {

/// The element of `f` whose nodes are exactly `node` in order (−1: none).
int32_t element_with_nodes(const FemModel& f, const int32_t* node) {
  for (int32_t j = f.node_element_ptr[size_t(node[0])]; j < f.node_element_ptr[size_t(node[0]) + 1]; ++j) {
    const int32_t e = f.node_element[size_t(j)];
    const Tet& t = f.elements[size_t(e)].node;
    if (t[0] == node[0] && t[1] == node[1] && t[2] == node[2] && t[3] == node[3]) return e;
  }
  return -1;
}

}  // namespace

std::vector<RodAnchor> cut_rod_anchors(const CutSupport& cs, const CutTopology& topo, const std::vector<double>& edge_cut) {
  std::vector<RodAnchor> out;
  out.reserve(cs.uncut.rod_anchors.size());
  for (const RodAnchor& a : cs.uncut.rod_anchors) {
    const int32_t tet = element_with_nodes(cs.uncut, a.tissue);
    if (tet < 0)
      throw std::logic_error("cut_rod_anchors: the anchor of rod node " + std::to_string(a.node) +
                             " is not in a tetrahedron of the uncut model");
    const std::array<double, 4> w{a.w[0], a.w[1], a.w[2], a.w[3]};
    const int32_t c = copy_containing(topo, cs.base.tets, cs.uncut.rest, edge_cut, cs.base.adj, tet, w);
    RodAnchor b = a;
    b.node = topo.node_dof[size_t(a.node)];
    for (int k = 0; k < 4; ++k) b.tissue[k] = topo.copies[size_t(c)].dof[size_t(k)];
    out.push_back(b);
  }
  return out;
}

std::vector<Model::ThreadTie> cut_thread_ties(const Model& current, const CutTopology& topo) {
  std::vector<Model::ThreadTie> out = current.thread_ties;
  for (Model::ThreadTie& t : out) t.node = topo.node_dof[size_t(current.topology->dof_node[size_t(t.node)])];
  return out;
}

int32_t carried_rod_dof(const Model& old_m, const Model& m, int32_t d) {
  return m.topology->node_dof[size_t(old_m.topology->dof_node[size_t(d)])];
}

void transfer_threads(const Model& old_m, const State& old_s, const Model& m, State& s) {
  for (size_t k = 0; k < s.tools.size(); ++k) {
    ToolState& ts = s.tools[k];
    if (ts.grasped_segment >= 0) ts.grasped_segment = carried_rod_dof(old_m, m, ts.grasped_segment);
    if (ts.released_segment >= 0) ts.released_segment = carried_rod_dof(old_m, m, ts.released_segment);
  }
  s.puncture_count = old_s.puncture_count;
  if (old_s.puncture_count == 0) return;
  const WalkMesh walk = needle_walk_mesh(m);
  for (int32_t i = 0; i < old_s.puncture_count; ++i) {
    RodPuncture p = old_s.punctures[size_t(i)];
    const int32_t old_copy = element_with_nodes(old_m.fem, p.node);
    if (old_copy >= 0) {  // (always: a puncture's nodes are its copy's)
      const int32_t c = carried_copy(*old_m.topology, old_copy, *m.topology, walk, p.w);
      for (int k = 0; k < 4; ++k) p.node[k] = m.topology->copies[size_t(c)].dof[size_t(k)];
    }
    s.punctures[size_t(i)] = p;
  }
}

}  // namespace stroma
