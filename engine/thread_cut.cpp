#include "engine/thread_cut.hpp"

#include <stdexcept>
#include <string>

#include "engine/needle_mesh.hpp"

namespace stroma {

namespace {

bool same_nodes(const Tet& t, const int32_t* node) {
  return t[0] == node[0] && t[1] == node[1] && t[2] == node[2] && t[3] == node[3];
}

/// The first element of `f` whose nodes are exactly `node` in order (−1: none).
int32_t element_with_nodes(const FemModel& f, const int32_t* node) {
  for (int32_t j = f.node_element_ptr[size_t(node[0])]; j < f.node_element_ptr[size_t(node[0]) + 1]; ++j)
    if (same_nodes(f.elements[size_t(f.node_element[size_t(j)])].node, node)) return f.node_element[size_t(j)];
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
  const FemModel& f = old_m.fem;
  for (int32_t i = 0; i < old_s.puncture_count; ++i) {
    RodPuncture p = old_s.punctures[size_t(i)];
    // Its copy: the element with exactly its four nodes — where a cut ends inside the tissue, two
    // copies of one tetrahedron can have the same four DOFs (both glued to the uncut neighbours),
    // so every such copy is a candidate, and the new copy is the one, among all their
    // refinements, whose material the point lies deepest in.
    int32_t best = -1;
    double best_depth = 0;
    for (int32_t j = f.node_element_ptr[size_t(p.node[0])]; j < f.node_element_ptr[size_t(p.node[0]) + 1]; ++j) {
      const int32_t e = f.node_element[size_t(j)];
      if (!same_nodes(f.elements[size_t(e)].node, p.node)) continue;
      const int32_t c = carried_copy(*old_m.topology, e, *m.topology, walk, p.w);
      const double depth = walk.material_depth(c, p.w);
      if (best < 0 || depth > best_depth) best = c, best_depth = depth;
    }
    if (best >= 0)  // (always: a puncture's nodes are its copy's)
      for (int k = 0; k < 4; ++k) p.node[k] = m.topology->copies[size_t(best)].dof[size_t(k)];
    s.punctures[size_t(i)] = p;
  }
}

}  // namespace stroma
