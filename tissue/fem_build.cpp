#include "tissue/fem_build.hpp"

#include <algorithm>
#include <cmath>

#include "tissue/mat3.hpp"
#include "tissue/material.hpp"
#include "tissue/rotation.hpp"

namespace stroma {

namespace {

/// Appends one body's nodes, elements (Dm⁻¹, volume, Lamé, β, QR rest frame), lumped masses,
/// Rayleigh α, gravity, constraints and loads; `all_tets` gets its tetrahedra (global ids).
void add_body(FemModel& m, const FemBodyInput& b, const Vec3& gravity, bool any_qr, bool densities, bool fibres,
              int32_t node_off,
              std::vector<Tet>& all_tets) {
  const TetMesh& mesh = b.mesh->mesh;
  const Lame lame = lame_from_young_poisson(b.young_modulus, b.poisson_ratio);
  BodyRange br;
  br.name = b.name;
  br.density = b.density;
  br.node_begin = node_off;
  br.node_end = node_off + static_cast<int32_t>(mesh.nodes.size());
  br.element_begin = static_cast<int32_t>(m.elements.size());
  for (size_t i = 0; i < mesh.nodes.size(); ++i)
    for (int k = 0; k < 3; ++k) m.rest[3 * (node_off + i) + k] = mesh.nodes[i][k];
  const bool own = !b.element_material.empty();
  for (size_t ti = 0; ti < mesh.tets.size(); ++ti) {
    const Tet& t = mesh.tets[ti];
    ElementParams ep{};
    for (int k = 0; k < 4; ++k) ep.node[k] = t[k] + node_off;
    const Vec3& x0 = mesh.nodes[t[0]];
    double Dm[9];  // columns: rest edges X1−X0, X2−X0, X3−X0
    for (int c = 0; c < 3; ++c)
      for (int r = 0; r < 3; ++r) Dm[3 * r + c] = mesh.nodes[t[c + 1]][r] - x0[r];
    const double det = m3::inverse(Dm, ep.g);
    ep.volume = det / 6.0;
    double density = b.density;
    if (own) {
      const ElementMaterial& em = b.element_material[ti];
      const Lame l = lame_from_young_poisson(em.young_modulus, em.poisson_ratio);
      ep.lambda = l.lambda;
      ep.mu = l.mu;
      ep.beta = em.rayleigh_stiffness;
      density = em.density;
    } else {
      ep.lambda = lame.lambda;
      ep.mu = lame.mu;
      ep.beta = b.rayleigh_stiffness;
    }
    if (densities) m.element_density.push_back(density);
    if (fibres) m.fibres.push_back(b.element_fibres.empty() ? FibreParams{{1, 0, 0}, 0, 0} : b.element_fibres[ti]);
    if (any_qr) {
      const double e1[3] = {Dm[0], Dm[3], Dm[6]};
      const double e2[3] = {Dm[1], Dm[4], Dm[7]};
      edge_frame(e1, e2, m.rest_frame[m.elements.size()].data());
    }
    const double mq = density * ep.volume / 4.0;
    for (int k = 0; k < 4; ++k) m.mass[ep.node[k]] += mq;
    m.elements.push_back(ep);
    all_tets.push_back({ep.node[0], ep.node[1], ep.node[2], ep.node[3]});
  }
  br.element_end = static_cast<int32_t>(m.elements.size());
  ElementRange range{br.element_begin, br.element_end, ElementKernel::CorotationalPolar};
  if (b.model == ElementModel::Linear) range.kernel = ElementKernel::Linear;
  else if (b.model == ElementModel::StableNeoHookean) range.kernel = ElementKernel::StableNeoHookean;
  else if (b.model == ElementModel::StVenantKirchhoff) range.kernel = ElementKernel::StVenantKirchhoff;
  else if (b.rotation == RotationMethod::QR) range.kernel = ElementKernel::CorotationalQR;
  range.fibres = !b.element_fibres.empty();
  if (b.locking_free_share >= 0) {
    range.smoothed = true;
    range.element_share = b.locking_free_share;
    range.patch_elements = b.locking_free_patch;
    range.element_bulk_share = b.locking_free_bulk;
  }
  if (b.visco.terms > 0) {  // its internal variables' place in the state arrays
    range.visco = static_cast<int32_t>(m.visco.size());
    m.visco.push_back(b.visco);
    const int64_t ne = range.end - range.begin;
    range.visco_q_begin = m.visco_q_size;
    range.visco_s0_begin = m.visco_s0_size;
    m.visco_q_size += 6 * b.visco.terms * ne;
    m.visco_s0_size += 6 * ne;
  }
  m.ranges.push_back(range);
  if (b.uniform_mass) {  // the body's mass, the same on every node a tetrahedron uses
    double total = 0;
    int32_t used = 0;
    for (int32_t i = br.node_begin; i < br.node_end; ++i)
      if (m.mass[i] > 0) total += m.mass[i], ++used;
    for (int32_t i = br.node_begin; i < br.node_end; ++i)
      if (m.mass[i] > 0) m.mass[i] = total / used;
  }
  for (const Tri& f : b.mesh->boundary) br.boundary.push_back({f[0] + node_off, f[1] + node_off, f[2] + node_off});
  for (int32_t i = br.node_begin; i < br.node_end; ++i) {
    m.alpha[i] = b.rayleigh_mass;
    for (int k = 0; k < 3; ++k) m.f_ext[3 * i + k] += m.mass[i] * gravity[k];
  }
  for (const auto& [i, mask] : b.fixed) m.constrained[i + node_off] |= mask;
  for (int32_t i : b.mesh->unused_nodes) m.constrained[i + node_off] = 7;
  m.ranges.back().fixed = std::all_of(m.constrained.begin() + br.node_begin, m.constrained.begin() + br.node_end,
                                      [](uint8_t c) { return c == 7; });
  for (const auto& [i, f] : b.nodal_forces)
    for (int k = 0; k < 3; ++k) m.f_ext[3 * (i + node_off) + k] += f[k];
  m.bodies.push_back(std::move(br));
}

/// Appends one rod's nodes (rest = initial positions), lumped masses (ρ·A·ℓ/2 per segment end),
/// Rayleigh α, gravity, constraints and loads, and its RodRange (slots filled by build_pattern).
void add_rod(FemModel& m, const FemRodInput& rod, const Vec3& gravity, int32_t node_off) {
  RodRange r;
  r.name = rod.name;
  r.node_begin = node_off;
  r.node_end = node_off + static_cast<int32_t>(rod.nodes.size());
  r.segment_length = rod.segment_length;
  r.stretch_stiffness = rod_stretch_stiffness(rod.young_modulus, rod.diameter, rod.segment_length);
  r.bend_stiffness = rod_bend_stiffness(
      rod_flexural_rigidity(rod.young_modulus, rod.diameter, rod.bending_stiffness),
      rod.segment_length);
  r.beta = rod.rayleigh_stiffness;
  r.diameter = rod.diameter;
  r.friction = rod.friction;
  r.contact_stiffness = rod.contact_stiffness;
  const double pi = 3.14159265358979323846;
  const double half = rod.density * pi * rod.diameter * rod.diameter / 4.0 * rod.segment_length / 2.0;
  for (size_t i = 0; i < rod.nodes.size(); ++i) {
    const int32_t n = node_off + static_cast<int32_t>(i);
    for (int k = 0; k < 3; ++k) m.rest[3 * n + k] = rod.nodes[i][k];
    m.mass[n] = (i == 0 || i + 1 == rod.nodes.size()) ? half : 2 * half;
    m.alpha[n] = rod.rayleigh_mass;
    for (int k = 0; k < 3; ++k) m.f_ext[3 * n + k] += m.mass[n] * gravity[k];
  }
  for (const auto& [i, mask] : rod.fixed) m.constrained[i + node_off] |= mask;
  for (RodAnchor a : rod.anchors) {
    a.node += node_off;
    a.beta = rod.rayleigh_stiffness;
    m.rod_anchors.push_back(a);
  }
  for (const auto& [i, f] : rod.nodal_forces)
    for (int k = 0; k < 3; ++k) m.f_ext[3 * (i + node_off) + k] += f[k];
  m.rods.push_back(std::move(r));
}

/// Each rod's slots (RodRange::slot_begin): per segment 3, per interior node 6 (rod.hpp).
void assign_rod_slots(FemModel& m) {
  m.rod_slots.clear();
  for (RodRange& r : m.rods) {
    r.slot_begin = static_cast<int32_t>(m.rod_slots.size());
    for (int32_t i = r.node_begin; i + 1 < r.node_end; ++i)
      for (const auto& [a, b] : {std::pair{i, i}, {i, i + 1}, {i + 1, i + 1}}) m.rod_slots.push_back(m.pattern.find(a, b));
    for (int32_t i = r.node_begin + 1; i + 1 < r.node_end; ++i)
      for (const auto& [a, b] : {std::pair{i - 1, i - 1}, {i - 1, i}, {i - 1, i + 1}, {i, i}, {i, i + 1}, {i + 1, i + 1}})
        m.rod_slots.push_back(m.pattern.find(a, b));
  }
  for (RodAnchor& an : m.rod_anchors) {
    an.slot_begin = static_cast<int32_t>(m.rod_slots.size());
    const int32_t nodes[5] = {an.node, an.tissue[0], an.tissue[1], an.tissue[2], an.tissue[3]};
    for (int a = 0; a < 5; ++a)
      for (int b = a; b < 5; ++b) m.rod_slots.push_back(m.pattern.find_upper(nodes[a], nodes[b]));  // blocks ∝ I: a transpose is the block
  }
}

/// The BSR pattern and every element's 16 slots. Elements of fully fixed bodies stay out of the
/// pattern: the elastic pass skips them and their nodes' rows are the constraint projection's
/// identity, so their blocks would only ever hold zeros — which every CG product would still
/// walk (a fixed 1,205-node block under a 191-node bar: ~85 % of each SpMV). Their slots point at
/// their own nodes' diagonal blocks.
void build_pattern(FemModel& m, const std::vector<Tet>& all_tets) {
  std::vector<Tet> moving_tets;
  for (const ElementRange& r : m.ranges)
    if (!r.fixed) moving_tets.insert(moving_tets.end(), all_tets.begin() + r.begin, all_tets.begin() + r.end);
  std::vector<ElementSlots> moving_slots;
  // Node groups whose every pair is coupled: the node domains of locking-free bodies (their
  // patches, when assembled), and each rod's bending stencils (i − 1, i, i + 1).
  std::vector<int32_t> group_ptr, group_node;
  if (!m.smoothing.matrix_free) {
    group_ptr = m.smoothing.ptr;
    group_node = m.smoothing.patch_node;
  }
  if (!m.rods.empty()) {
    if (group_ptr.empty()) group_ptr.push_back(0);
    for (const RodRange& r : m.rods)
      for (int32_t i = r.node_begin + 1; i + 1 < r.node_end; ++i) {
        group_node.insert(group_node.end(), {i - 1, i, i + 1});
        group_ptr.push_back(static_cast<int32_t>(group_node.size()));
      }
    for (const RodAnchor& an : m.rod_anchors) {  // an anchor couples its rod node and tetrahedron
      group_node.insert(group_node.end(), {an.node, an.tissue[0], an.tissue[1], an.tissue[2], an.tissue[3]});
      group_ptr.push_back(static_cast<int32_t>(group_node.size()));
    }
  }
  m.pattern = build_bsr_pattern(m.num_nodes, moving_tets, moving_slots, group_ptr, group_node);
  m.slots.resize(all_tets.size());
  size_t next = 0;
  for (const ElementRange& r : m.ranges)
    for (int32_t e = r.begin; e < r.end; ++e) {
      if (!r.fixed) {
        m.slots[e] = moving_slots[next++];
        continue;
      }
      for (int a = 0; a < 4; ++a)
        for (int b = 0; b < 4; ++b) m.slots[e][4 * a + b] = m.pattern.diag[all_tets[e][a]];
    }
  assign_rod_slots(m);
  for (int32_t i = 0; i < m.num_nodes; ++i)
    for (int32_t s = m.pattern.row_ptr[i]; s < m.pattern.row_ptr[i + 1]; ++s) {
      const int32_t j = m.pattern.col[s];
      if (i != j && (m.constrained[i] || m.constrained[j])) m.constrained_offdiag.push_back({s, i, j});
    }
}

/// Node → element lists (CSR, elements in increasing order).
void build_node_elements(FemModel& m) {
  const int32_t nn = m.num_nodes;
  m.node_element_ptr.assign(nn + 1, 0);
  for (const ElementParams& ep : m.elements)
    for (int32_t n : ep.node) ++m.node_element_ptr[n + 1];
  for (int32_t i = 0; i < nn; ++i) m.node_element_ptr[i + 1] += m.node_element_ptr[i];
  m.node_element.resize(m.node_element_ptr.back());
  std::vector<int32_t> fill(m.node_element_ptr.begin(), m.node_element_ptr.end() - 1);
  for (size_t e = 0; e < m.elements.size(); ++e)
    for (int32_t n : m.elements[e].node) m.node_element[fill[n]++] = static_cast<int32_t>(e);
}

}  // namespace

FemModel build_fem_model(const std::vector<FemBodyInput>& bodies, const Vec3& gravity, bool smoothing_matrix_free,
                         const std::vector<FemRodInput>& rods) {
  FemModel m;
  m.smoothing.matrix_free = smoothing_matrix_free;
  int32_t nn = 0, ne = 0;
  for (const auto& b : bodies) {
    nn += static_cast<int32_t>(b.mesh->mesh.nodes.size());
    ne += static_cast<int32_t>(b.mesh->mesh.tets.size());
  }
  for (const FemRodInput& r : rods) nn += static_cast<int32_t>(r.nodes.size());
  m.num_nodes = nn;
  m.gravity = gravity;
  m.rest.resize(3 * nn);
  m.mass.assign(nn, 0.0);
  m.alpha.assign(nn, 0.0);
  m.constrained.assign(nn, 0);
  m.f_ext.assign(3 * nn, 0.0);
  m.elements.reserve(ne);
  const bool any_qr = std::any_of(bodies.begin(), bodies.end(), [](const FemBodyInput& b) {
    return b.model == ElementModel::Corotational && b.rotation == RotationMethod::QR;
  });
  if (any_qr) m.rest_frame.resize(ne);
  // Per-element densities only when some body's regions have a density of their own.
  const bool densities = std::any_of(bodies.begin(), bodies.end(), [](const FemBodyInput& b) {
    return std::any_of(b.element_material.begin(), b.element_material.end(),
                       [&](const ElementMaterial& e) { return e.density != b.density; });
  });
  if (densities) m.element_density.reserve(ne);
  const bool fibres = std::any_of(bodies.begin(), bodies.end(), [](const FemBodyInput& b) { return !b.element_fibres.empty(); });
  if (fibres) m.fibres.reserve(ne);
  std::vector<Tet> all_tets;
  all_tets.reserve(ne);
  int32_t node_off = 0;
  for (const auto& b : bodies) {
    add_body(m, b, gravity, any_qr, densities, fibres, node_off, all_tets);
    node_off += static_cast<int32_t>(b.mesh->mesh.nodes.size());
  }
  for (const FemRodInput& r : rods) {
    add_rod(m, r, gravity, node_off);
    node_off += static_cast<int32_t>(r.nodes.size());
  }
  finish_fem_model(m, all_tets);
  return m;
}

void finish_fem_model(FemModel& m, const std::vector<Tet>& all_tets) {
  const int32_t nn = m.num_nodes;
  m.inv_mass.resize(nn);
  m.constrained_nodes.clear();
  m.constrained_offdiag.clear();
  for (int32_t i = 0; i < nn; ++i) {
    if (m.constrained[i]) m.constrained_nodes.push_back(i);
    m.inv_mass[i] = m.mass[i] <= 0 ? 0.0 : 1.0 / m.mass[i];
  }
  build_node_elements(m);
  build_nodal_smoothing(m);
  build_pattern(m, all_tets);
  assign_smoothing_slots(m);
  m.any_stiffness_damping =
      std::any_of(m.elements.begin(), m.elements.end(), [](const ElementParams& e) { return e.beta != 0.0; }) ||
      std::any_of(m.rods.begin(), m.rods.end(), [](const RodRange& r) { return r.beta != 0.0; });
}

}  // namespace stroma
