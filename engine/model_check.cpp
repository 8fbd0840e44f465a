#include "engine/model_check.hpp"

#include "tissue/cut_topology.hpp"

#include <cmath>
#include <string>

namespace stroma {

namespace {

/// Records the first broken invariant.
struct Checker {
  std::string* why;
  bool ok = true;
  bool operator()(bool holds, const std::string& what) {
    if (!holds && ok) {
      ok = false;
      if (why) *why = what;
    }
    return holds;
  }
};

}  // namespace

bool model_invariants_hold(const Model& m, std::string* why) {
  Checker c{why};
  const FemModel& f = m.fem;
  const size_t n = static_cast<size_t>(f.num_nodes), ne = f.elements.size();
  c(f.num_nodes > 0, "fem.num_nodes > 0");
  for (const RigidBodyModel& b : m.rigid_bodies) {
    std::string w;
    c(is_physical(b.mass, &w), "rigid body '" + b.name + "': " + w);
    c(b.mass.centre[0] == 0 && b.mass.centre[1] == 0 && b.mass.centre[2] == 0, "a rigid body's frame is at its centre of mass");
    const auto& q = b.initial.q;
    c(std::abs(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3] - 1) < 1e-9, "a rigid body's orientation is a unit quaternion");
  }
  c(f.rest.size() == 3 * n && f.f_ext.size() == 3 * n, "fem.rest and fem.f_ext have 3 entries per node");
  c(f.mass.size() == n && f.inv_mass.size() == n && f.alpha.size() == n && f.constrained.size() == n,
    "fem.mass, inv_mass, alpha and constrained have one entry per node");
  c(f.slots.size() == ne, "fem.slots parallel to fem.elements");
  c(f.rest_frame.empty() || f.rest_frame.size() == ne, "fem.rest_frame empty or parallel to the elements");
  c(f.element_density.empty() || f.element_density.size() == ne, "fem.element_density empty or per element");
  c(f.fibres.empty() || f.fibres.size() == ne, "fem.fibres empty or per element");
  c(f.pattern.n == f.num_nodes && f.pattern.diag.size() == n && f.pattern.row_ptr.size() == n + 1,
    "fem.pattern has a block row and a diagonal slot per node");
  c(f.node_element_ptr.size() == n + 1, "fem.node_element_ptr has nodes + 1 offsets");
  int32_t next = 0;
  for (const ElementRange& r : f.ranges) {
    c(r.begin == next && r.end >= r.begin, "fem.ranges cover the elements in order without overlap");
    c(r.visco < static_cast<int32_t>(f.visco.size()), "a range's Prony series is one of fem.visco");
    next = r.end;
  }
  c(static_cast<size_t>(next) == ne, "fem.ranges cover every element");
  for (const ElementParams& e : f.elements) {
    bool nodes_ok = true;
    for (int32_t v : e.node) nodes_ok = nodes_ok && v >= 0 && static_cast<size_t>(v) < n;
    c(nodes_ok, "every element's nodes are nodes of the model");
    c(e.volume > 0 && e.lambda >= 0 && e.mu >= 0 && e.beta >= 0, "elements: volume > 0, lambda, mu, beta >= 0");
    if (!c.ok) break;
  }
  // Rods (tissue/rod.hpp): after the bodies' nodes, in order, each with its slots.
  int32_t rod_next = f.bodies.empty() ? 0 : f.bodies.back().node_end;
  size_t rod_slots = 0;
  for (const RodRange& r : f.rods) {
    c(r.node_begin == rod_next && r.nodes() >= 3 && static_cast<size_t>(r.node_end) <= n,
      "rod '" + r.name + "': three nodes or more, after the bodies' and the rods' before it");
    c(r.segment_length > 0 && r.stretch_stiffness > 0 && r.bend_stiffness >= 0 && r.beta >= 0 && r.contact_stiffness >= 0 &&
          r.diameter >= 0 && r.friction >= 0,
      "rod '" + r.name + "': segment length and stretch stiffness > 0, bend and contact stiffness, beta, diameter and "
      "friction >= 0");
    c(r.slot_begin == static_cast<int32_t>(rod_slots), "rod '" + r.name + "': its slots follow the rods' before it");
    rod_slots += static_cast<size_t>(3 * r.segments() + 6 * (r.nodes() - 2));
    rod_next = r.node_end;
  }
  const int32_t tissue_nodes = f.bodies.empty() ? 0 : f.bodies.back().node_end;
  for (const RodAnchor& an : f.rod_anchors) {
    bool ok = an.node >= tissue_nodes && an.node < rod_next && an.stiffness > 0 && an.beta >= 0 &&
              an.slot_begin == static_cast<int32_t>(rod_slots);
    double sum = 0;
    for (int a = 0; a < 4; ++a) {
      ok = ok && an.tissue[a] >= 0 && an.tissue[a] < tissue_nodes && an.w[a] >= 0;
      sum += an.w[a];
    }
    c(ok && std::abs(sum - 1.0) < 1e-9,
      "a rod anchor ties a rod's node to tissue nodes with weights >= 0 summing to 1, stiffness > 0, its slots next");
    rod_slots += kRodAnchorSlots;
  }
  c(f.rod_slots.size() == rod_slots, "fem.rod_slots: 3 per segment and 6 per interior node of every rod, 15 per anchor");
  for (const int32_t slot : f.rod_slots) c(slot >= 0 && slot < f.pattern.nnzb(), "a rod's slots are in the pattern");
  for (const Model::ThreadTie& tie : m.thread_ties) {
    bool rod_node = false;
    for (const RodRange& r : f.rods) rod_node = rod_node || (tie.node >= r.node_begin && tie.node < r.node_end);
    c(rod_node && tie.body >= 0 && static_cast<size_t>(tie.body) < m.rigid_bodies.size() && tie.stiffness > 0,
      "a thread tie names a rod's node and a rigid body, stiffness > 0");
  }
  c(m.time_step > 0 && m.fem_every >= 1, "time_step > 0, fem_every >= 1");
  c(m.max_step_displacement > 0, "max_step_displacement > 0");
  bool shaped = false;
  for (const ToolSpec& t : m.tools) {
    shaped = shaped || t.shape != ToolShape::None;
    c(t.shape == ToolShape::None || t.contact_stiffness > 0, "a shaped tool's contact stiffness is resolved (> 0)");
    c(!t.can_grasp || t.grasp_stiffness > 0, "a grasping tool's grasp stiffness is resolved (> 0)");
    for (int k = 0; k < 3; ++k) c(t.workspace_min[k] <= t.workspace_max[k], "tool workspace min <= max");
  }
  c(m.has_contact == (shaped || m.body_contact.has_value() || !m.rigid_bodies.empty() || !m.fem.rods.empty()),
    "has_contact <=> a shaped tool, body contact, rigid bodies or threads");
  const size_t tris = m.collision_triangles.size();
  c(m.collision_dofs.size() == tris && m.collision_edge.size() == tris && m.collision_face_elem.size() == tris,
    "the collision arrays are parallel");
  c(m.has_contact || tris == 0, "collision arrays only for contact scenes");
  if (m.has_needles) {  // the mesh the needles' walks cross (engine/needle_mesh.hpp)
    c(m.tet_neighbours.size() == 4 * ne && m.node_tet.size() == n, "needles: 4 face neighbours per element, an element per node");
    c(m.collision_tri_elem.size() == tris, "needles: an element per collision triangle");
    for (const int32_t e : m.collision_tri_elem) c(e >= -1 && e < static_cast<int32_t>(ne), "needles: a collision triangle's element is one of the model's");
    c(m.element_plane_begin.empty() ||
          (m.element_plane_begin.size() == ne + 1 && m.element_plane_begin.front() == 0 &&
           static_cast<size_t>(m.element_plane_begin.back()) == m.element_planes.size()),
      "needles: element_plane_begin empty or per element, ending at element_planes' size");
    c(m.element_next_twin.size() == (m.element_plane_begin.empty() ? 0 : ne), "needles: a next twin per element of a cut model");
    for (size_t e = 0; e < m.element_next_twin.size(); ++e)
      c(m.element_next_twin[e] >= 0 && static_cast<size_t>(m.element_next_twin[e]) < ne &&
            (m.topology == nullptr || m.topology->copies[size_t(m.element_next_twin[e])].tet == m.topology->copies[e].tet),
        "needles: an element's next twin is a copy of its tetrahedron");
  }
  c(m.initial_x.empty() || m.initial_x.size() == f.rest.size(), "initial_x empty or 3 per node");
  c(m.body_damage.size() == f.bodies.size(), "one damage model per body");
  c(m.element_region_damage.empty() || m.element_region_damage.size() == ne,
    "element_region_damage empty or per element");
  c(m.has_damage == !m.element_node_mass.empty(), "element_node_mass sized exactly when has_damage");
  c(!m.has_damage || m.element_node_mass.size() == ne, "element_node_mass per element");
  c(!(m.has_damage && m.has_contact) || m.element_face_ptr.size() == ne + 1,
    "element_face_ptr has elements + 1 offsets with damage and contact");
  c(!m.cutting || m.topology != nullptr, "a cutting model has its topology");
  return c.ok;
}

bool state_sized_for(const Model& m, const State& s) {
  const size_t dofs = 3 * static_cast<size_t>(m.fem.num_nodes), ne = m.fem.elements.size();
  return s.tissue.x.size() == dofs && s.tissue.v.size() == dofs && s.tools.size() == m.tools.size() &&
         s.rigid.size() == m.rigid_bodies.size() && s.needles.size() == m.rigid_bodies.size() &&
         s.tissue.visco_q.size() == static_cast<size_t>(m.fem.visco_q_size) &&
         s.tissue.visco_s0.size() == static_cast<size_t>(m.fem.visco_s0_size) &&
         (m.has_damage ? s.damage.size() == ne && s.damage_level.size() == ne &&
                             s.node_mass.size() == static_cast<size_t>(m.fem.num_nodes)
                       : s.damage.empty()) &&
         s.edge_cut.size() == (m.cutting ? m.cut_edge_dofs.size() : 0) &&
         s.punctures.size() == static_cast<size_t>(m.puncture_capacity) && s.puncture_count >= 0 &&
         s.puncture_count <= m.puncture_capacity;
}

}  // namespace stroma
