#include "tissue/cut_model.hpp"

#include <algorithm>
#include <cmath>

#include <stdexcept>
#include <string>

#include "tissue/fem_build.hpp"

namespace stroma {

CutBase make_cut_base(const FemModel& uncut) {
  CutBase b;
  b.tets.reserve(uncut.elements.size());
  for (const ElementParams& e : uncut.elements) b.tets.push_back(e.node);
  b.adj = build_tet_adjacency(b.tets, uncut.num_nodes);
  for (const BodyRange& r : uncut.bodies) b.node_ranges.push_back(r.node_begin);
  if (!uncut.rods.empty()) b.node_ranges.push_back(uncut.rods.front().node_begin);  // the rods' range
  b.node_ranges.push_back(uncut.num_nodes);
  // Each edge's clamp, from its body's shortest edge (the edges of a body are its nodes').
  auto length = [&](const std::array<int32_t, 2>& e) {
    double d2 = 0;
    for (int k = 0; k < 3; ++k) {
      const double d = uncut.rest[3 * e[1] + k] - uncut.rest[3 * e[0] + k];
      d2 += d * d;
    }
    return std::sqrt(d2);
  };
  std::vector<double> h_min(uncut.bodies.size(), 1e300);
  auto body_of = [&](int32_t n) {
    size_t r = 0;
    while (r + 1 < uncut.bodies.size() && n >= uncut.bodies[r].node_end) ++r;
    return r;
  };
  for (const auto& e : b.adj.edges) {
    const double l = length(e);
    if (l > 0) h_min[body_of(e[0])] = std::min(h_min[body_of(e[0])], l);
  }
  b.min_fraction.reserve(b.adj.edges.size());
  for (const auto& e : b.adj.edges) b.min_fraction.push_back(cut_edge_min_fraction(length(e), h_min[body_of(e[0])]));
  return b;
}

FemModel build_cut_fem_model(const FemModel& u, const CutTopology& topo, const std::vector<RodAnchor>& cut_anchors) {
  const size_t ranges = u.bodies.size() + (u.rods.empty() ? 0 : 1);
  if (topo.tet_copy_begin.size() != u.elements.size() + 1 || topo.range_dof_begin.size() != ranges + 1 ||
      topo.node_dof.size() != static_cast<size_t>(u.num_nodes))
    throw std::invalid_argument("cut model: the topology is not one of this model's mesh");
  if (cut_anchors.size() != u.rod_anchors.size())
    throw std::invalid_argument("cut model: " + std::to_string(cut_anchors.size()) + " anchors given for the rods' " +
                                std::to_string(u.rod_anchors.size()));
  FemModel m;
  const int32_t nd = topo.num_dofs;
  // A fully fixed body (an obstacle) stays fixed in all its DOFs; elsewhere a clamp holds the
  // material, not the virtual copies of a clamped node on the far side of a cut.
  // (build_fem_model makes one element range per body, in body order.)
  std::vector<uint8_t> dof_in_fixed_body(static_cast<size_t>(nd), 0);
  for (size_t b = 0; b < u.bodies.size() && b < u.ranges.size(); ++b)
    if (u.ranges[b].fixed)
      for (int32_t d = topo.range_dof_begin[b]; d < topo.range_dof_begin[b + 1]; ++d) dof_in_fixed_body[d] = 1;
  m.num_nodes = nd;
  m.gravity = u.gravity;
  // Locking-free bodies: finish_fem_model builds the node domains of the cut mesh — one per DOF,
  // its patch the copies holding it (the copies of one piece never share a DOF with another's,
  // so no domain reaches across a cut) — applied as the uncut model's were. (The engine refuses
  // to cut such a body: a split domain stores more energy at the same positions than the whole.)
  m.smoothing.matrix_free = u.smoothing.matrix_free;
  m.rest.resize(3 * static_cast<size_t>(nd));
  m.mass.assign(nd, 0.0);
  m.alpha.resize(nd);
  m.constrained.resize(nd);
  m.f_ext.assign(3 * static_cast<size_t>(nd), 0.0);
  for (int32_t d = 0; d < nd; ++d) {
    const int32_t g = topo.dof_node[d];
    for (int k = 0; k < 3; ++k) m.rest[3 * d + k] = u.rest[3 * g + k];
    m.alpha[d] = u.alpha[g];
    m.constrained[d] = (topo.dof_material[d] || dof_in_fixed_body[d]) ? u.constrained[g] : uint8_t{0};
  }
  m.elements.reserve(topo.copies.size());
  if (!u.rest_frame.empty()) m.rest_frame.reserve(topo.copies.size());
  for (const ElementCopy& c : topo.copies) {
    ElementParams ep = u.elements[c.tet];
    ep.node = c.dof;
    ep.volume *= c.fraction;
    m.elements.push_back(ep);
    if (!u.rest_frame.empty()) m.rest_frame.push_back(u.rest_frame[c.tet]);
    if (!u.element_density.empty()) m.element_density.push_back(u.element_density[c.tet]);
    if (!u.fibres.empty()) m.fibres.push_back(u.fibres[c.tet]);  // a copy keeps its parent's fibres
  }
  // Each range's copies in the same order as its tetrahedra; a visco-elastic range's internal
  // variables are laid out over its copies as build_fem_model lays them over its elements.
  m.visco = u.visco;
  for (const ElementRange& r : u.ranges) {
    ElementRange c = r;
    c.begin = topo.tet_copy_begin[r.begin];
    c.end = topo.tet_copy_begin[r.end];
    if (r.visco >= 0) {
      const int64_t ne = c.end - c.begin, terms = u.visco[r.visco].terms;
      c.visco_q_begin = m.visco_q_size;
      c.visco_s0_begin = m.visco_s0_size;
      m.visco_q_size += 6 * terms * ne;
      m.visco_s0_size += 6 * ne;
    }
    m.ranges.push_back(c);
  }
  for (size_t b = 0; b < u.bodies.size(); ++b) {
    const BodyRange& ub = u.bodies[b];
    BodyRange br;
    br.name = ub.name;
    br.density = ub.density;
    br.node_begin = topo.range_dof_begin[b];
    br.node_end = topo.range_dof_begin[b + 1];
    br.element_begin = topo.tet_copy_begin[ub.element_begin];
    br.element_end = topo.tet_copy_begin[ub.element_end];
    // The uncut part of the surface whose corners are nodes (a clipped or cut face's corners are
    // points inside copies: the whole surface is topo.triangles, not this).
    if (topo.split_tets == 0)  // nothing separated: the uncut boundary, as it was
      for (const Tri& t : ub.boundary) br.boundary.push_back({topo.node_dof[t[0]], topo.node_dof[t[1]], topo.node_dof[t[2]]});
    for (const CutTriangle& t : topo.triangles) {
      if (topo.split_tets == 0) break;
      const int32_t tet = topo.copies[t.copy].tet;
      if (t.cut || tet < ub.element_begin || tet >= ub.element_end) continue;
      bool nodes = true;
      for (int32_t v : t.v) nodes &= topo.vertices[v].a == topo.vertices[v].b;
      if (nodes) br.boundary.push_back({topo.vertices[t.v[0]].a, topo.vertices[t.v[1]].a, topo.vertices[t.v[2]].a});
    }
    // Lumped masses as build_fem_model makes them (ρV/4 per node, elements in order): an uncut
    // topology gives the uncut masses bit for bit.
    for (int32_t e = br.element_begin; e < br.element_end; ++e) {
      const double mq = element_density(m, e, br) * m.elements[e].volume / 4.0;
      for (int32_t n : m.elements[e].node) m.mass[n] += mq;
    }
    m.bodies.push_back(std::move(br));
  }
  // Rods: their range's DOFs are their nodes in order (no copy has them: no extra DOFs), with
  // the masses the uncut model lumped on them.
  for (const RodRange& r : u.rods) {
    RodRange c = r;
    c.node_begin = topo.node_dof[r.node_begin];
    c.node_end = c.node_begin + r.nodes();
    for (int32_t g = r.node_begin; g < r.node_end; ++g) {
      if (topo.node_dof[g] != c.node_begin + (g - r.node_begin))
        throw std::invalid_argument("cut model: rod '" + r.name + "' is not one range of DOFs");
      m.mass[topo.node_dof[g]] = u.mass[g];
    }
    m.rods.push_back(std::move(c));
  }
  m.rod_anchors = cut_anchors;
  for (int32_t d = 0; d < nd; ++d) {
    const int32_t g = topo.dof_node[d];
    const bool primary = topo.node_dof[g] == d;
    for (int k = 0; k < 3; ++k) {
      if (primary && m.mass[d] == u.mass[g]) {  // an uncut node: its force as it was, to the bit
        m.f_ext[3 * d + k] = u.f_ext[3 * g + k];
        continue;
      }
      const double load = primary ? u.f_ext[3 * g + k] - u.mass[g] * u.gravity[k] : 0.0;
      m.f_ext[3 * d + k] = m.mass[d] * u.gravity[k] + load;
    }
  }
  std::vector<Tet> all_tets;
  all_tets.reserve(m.elements.size());
  for (const ElementParams& e : m.elements) all_tets.push_back(e.node);
  finish_fem_model(m, all_tets);
  return m;
}

std::vector<int32_t> continued_copies(const CutTopology& from, const CutTopology& to) {
  std::vector<int32_t> map(to.copies.size(), -1);
  for (size_t i = 0; i < to.copies.size(); ++i) {
    const ElementCopy& c = to.copies[i];
    for (int32_t j = from.tet_copy_begin[c.tet]; j < from.tet_copy_begin[c.tet + 1]; ++j)
      if ((from.copies[j].material & c.material) == c.material) {
        map[i] = j;
        break;
      }
    if (map[i] < 0)
      throw std::logic_error("continued_copies: the new topology does not refine the old one (tetrahedron " +
                             std::to_string(c.tet) + ")");
  }
  return map;
}

std::vector<int32_t> continued_dofs(const CutTopology& from, const CutTopology& to) {
  std::vector<int32_t> map(static_cast<size_t>(to.num_dofs), -1);
  for (const ElementCopy& c : to.copies) {
    // The copy of the same tetrahedron whose material holds this one's (refinement: one does).
    const ElementCopy* src = nullptr;
    for (int32_t i = from.tet_copy_begin[c.tet]; i < from.tet_copy_begin[c.tet + 1]; ++i)
      if ((from.copies[i].material & c.material) == c.material) {
        src = &from.copies[i];
        break;
      }
    if (!src)
      throw std::logic_error("continued_dofs: the new topology does not refine the old one (tetrahedron " +
                             std::to_string(c.tet) + ")");
    for (int k = 0; k < 4; ++k)
      if (map[c.dof[k]] < 0) map[c.dof[k]] = src->dof[k];
  }
  for (size_t g = 0; g < to.node_dof.size(); ++g)
    if (map[to.node_dof[g]] < 0) map[to.node_dof[g]] = from.node_dof[g];  // nodes of no element
  return map;
}

void transfer_state(const TissueState& from, const std::vector<int32_t>& from_dof, TissueState& to) {
  const size_t n = from_dof.size();
  to.x.resize(3 * n);
  to.v.resize(3 * n);
  to.dv.resize(3 * n);
  to.dv_prev.resize(3 * n);
  for (size_t d = 0; d < n; ++d)
    for (int k = 0; k < 3; ++k) {
      const size_t i = 3 * d + k, j = 3 * static_cast<size_t>(from_dof[d]) + k;
      to.x[i] = from.x[j];
      to.v[i] = from.v[j];
      to.dv[i] = from.dv[j];
      to.dv_prev[i] = from.dv_prev[j];
    }
}

// (Ranges correspond by index: both models come from the same uncut ranges.)
void transfer_visco_state(const FemModel& old_m, const TissueState& old_s, const FemModel& m,
                          const std::vector<int32_t>& from_element, TissueState& s) {
  for (size_t ri = 0; ri < m.ranges.size(); ++ri) {
    const ElementRange& r = m.ranges[ri];
    if (r.visco < 0) continue;
    const ElementRange& o = old_m.ranges[ri];
    const int64_t nq = 6 * static_cast<int64_t>(m.visco[r.visco].terms);
    for (int32_t e = r.begin; e < r.end; ++e) {
      const int64_t j = from_element[e] - o.begin;  // the parent copy, within its range
      std::copy_n(old_s.visco_q.begin() + o.visco_q_begin + nq * j, nq,
                  s.visco_q.begin() + r.visco_q_begin + nq * (e - r.begin));
      std::copy_n(old_s.visco_s0.begin() + o.visco_s0_begin + 6 * j, 6,
                  s.visco_s0.begin() + r.visco_s0_begin + 6 * (e - r.begin));
    }
  }
}

}  // namespace stroma
