#include "engine/cut_compile.hpp"
#include "engine/model_check.hpp"
#include "engine/needle_mesh.hpp"
#include "engine/thread_cut.hpp"
#include "tissue/demand.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <stdexcept>

#include "collision/contact_surface.hpp"

namespace stroma {

namespace {

double distance(const double* a, const double* b) {
  const double d[3] = {a[0] - b[0], a[1] - b[1], a[2] - b[2]};
  return std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
}

double triangle_area(const double* a, const double* b, const double* c) {
  const double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, w[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
  const double n[3] = {u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]};
  return 0.5 * std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
}

/// Body of a DOF (bodies own consecutive DOF ranges).
int32_t body_of_dof(const FemModel& f, int32_t d) {
  int32_t b = 0;
  while (b + 1 < static_cast<int32_t>(f.bodies.size()) && d >= f.bodies[b].node_end) ++b;
  return b;
}

/// The collision surface of a cut model: topo's triangles over surface points (node corners are
/// DOFs, cut points embedded), their DOF maps and longest rest edges; every face always active
/// (a cut model's surface is exactly its material's boundary).
void compile_cut_surface(const CutTopology& topo, Model& m, std::vector<double>& rest_points) {
  const FemModel& f = m.fem;
  std::vector<int32_t> point(topo.vertices.size());
  for (size_t v = 0; v < topo.vertices.size(); ++v) {
    const CutVertex& cv = topo.vertices[v];
    if (cv.a == cv.b || cv.t == 0.0) {
      point[v] = cv.a;
    } else {
      point[v] = f.num_nodes + static_cast<int32_t>(m.collision_embedded.size());
      m.collision_embedded.push_back(cv);
    }
  }
  rest_points.resize(3 * (static_cast<size_t>(f.num_nodes) + m.collision_embedded.size()));
  surface_positions(f.rest.data(), f.num_nodes, m.collision_embedded, rest_points.data());
  // Each embedded point's material end: the end its copy holds as material (a cut vertex lies
  // on an edge between one of its copy's material nodes and one virtual node).
  m.collision_embedded_dof.assign(m.collision_embedded.size(), -1);
  auto material_ends = [&](const std::array<int32_t, 3>& tv, int32_t copy) {
    const ElementCopy& c = topo.copies[copy];
    for (int32_t v : tv) {
      if (point[v] < f.num_nodes) continue;
      int32_t& d = m.collision_embedded_dof[point[v] - f.num_nodes];
      if (d >= 0) continue;
      const CutVertex& cv = topo.vertices[v];
      d = cv.a;  // (if neither end were material — never on a consistent topology — keep one)
      for (int k = 0; k < 4; ++k)
        if ((c.material >> k & 1) && (c.dof[k] == cv.a || c.dof[k] == cv.b)) d = c.dof[k];
    }
  };
  for (const CutTriangle& t : topo.triangles) material_ends(t.v, t.copy);
  for (const CutInternalFace& t : topo.internal) material_ends(t.v, t.a);
  // A body that can tear (a damage model) gets, as in the uncut model, the faces inside it too:
  // each surface face belongs to its copy (closed when that copy ruptures), each internal face
  // to the two copies it lies between (open when exactly one of them has ruptured).
  auto tears = [&](int32_t copy) {
    for (size_t b = 0; b < f.bodies.size(); ++b)
      if (copy >= f.bodies[b].element_begin && copy < f.bodies[b].element_end)
        return body_can_tear(m, b);
    return false;
  };
  std::vector<std::vector<int32_t>> faces_of(f.elements.size());
  auto add_face = [&](const std::array<int32_t, 3>& v, int32_t ea, int32_t eb, bool cut, int32_t copy) {
    const std::array<int32_t, 3> tri{point[v[0]], point[v[1]], point[v[2]]};
    const int32_t id = static_cast<int32_t>(m.collision_triangles.size());
    m.collision_triangles.push_back(tri);
    if (m.has_needles) m.collision_tri_elem.push_back(copy);  // a puncture's walk starts in its copy
    m.collision_dofs.push_back(triangle_dofs(f.pattern, tri, f.num_nodes, m.collision_embedded_dof));
    double e = 0;
    for (int a = 0; a < 3; ++a) e = std::max(e, distance(&rest_points[3 * tri[a]], &rest_points[3 * tri[(a + 1) % 3]]));
    m.collision_edge.push_back(e);
    m.collision_face_elem.push_back({ea, eb});
    m.collision_cut_face.push_back(cut ? 1 : 0);
    if (ea >= 0) faces_of[ea].push_back(id);
    if (eb >= 0) faces_of[eb].push_back(id);
  };
  for (const CutTriangle& t : topo.triangles) add_face(t.v, tears(t.copy) ? t.copy : -1, -1, t.cut, t.copy);
  for (const CutInternalFace& t : topo.internal)
    if (tears(t.a) && tears(t.b)) add_face(t.v, t.a, t.b, false, t.a);
  m.element_face_ptr.assign(1, 0);
  for (const auto& fs : faces_of) {
    m.element_face.insert(m.element_face.end(), fs.begin(), fs.end());
    m.element_face_ptr.push_back(static_cast<int32_t>(m.element_face.size()));
  }
}

/// Body contact over the cut surface: the scenario's stiffness and depths, the surface points
/// as vertices (grouped by body), their areas, DOF maps and normals' triangles.
void compile_cut_body_contact(const BodyContactModel& uncut, const CutTopology& topo,
                              const std::vector<double>& rest_points, Model& m) {
  const FemModel& f = m.fem;
  BodyContactModel bc;
  bc.stiffness = uncut.stiffness;
  bc.body_depth = uncut.body_depth;
  bc.num_dofs = f.num_nodes;
  const size_t points = rest_points.size() / 3;
  std::vector<double> area(points, 0.0);
  std::vector<std::vector<int32_t>> tris_of(points);
  // The surface only (the first topo.triangles.size() collision faces; faces inside a body that
  // can tear follow them): body contact's vertices are the surface's points, as in the uncut model.
  for (size_t t = 0; t < topo.triangles.size(); ++t) {
    const auto& tri = m.collision_triangles[t];
    const double third =
        triangle_area(&rest_points[3 * tri[0]], &rest_points[3 * tri[1]], &rest_points[3 * tri[2]]) / 3.0;
    for (int32_t p : tri) {
      area[p] += third;
      tris_of[p].push_back(static_cast<int32_t>(t));
    }
  }
  auto point_body = [&](size_t p) {
    const int32_t d = p < static_cast<size_t>(f.num_nodes) ? static_cast<int32_t>(p)
                                                           : m.collision_embedded[p - f.num_nodes].a;
    return body_of_dof(f, d);
  };
  for (size_t b = 0; b < f.bodies.size(); ++b) {
    bc.body_vertex_begin.push_back(static_cast<int32_t>(bc.vertex.size()));
    for (size_t p = 0; p < points; ++p) {
      if (tris_of[p].empty() || point_body(p) != static_cast<int32_t>(b)) continue;
      const SurfacePointDofs pd = point_dofs(f.pattern, static_cast<int32_t>(p), f.num_nodes, m.collision_embedded_dof);
      bc.vertex.push_back(static_cast<int32_t>(p));
      bc.vertex_area.push_back(area[p]);
      bc.vertex_dofs.push_back(pd);
      bc.vertex_fixed.push_back(f.constrained[pd.dof] == 7 ? 1 : 0);
    }
  }
  bc.body_vertex_begin.push_back(static_cast<int32_t>(bc.vertex.size()));
  for (int32_t v : bc.vertex) {
    bc.vertex_tri_begin.push_back(static_cast<int32_t>(bc.vertex_tris.size()));
    for (int32_t t : tris_of[v]) bc.vertex_tris.push_back(m.collision_triangles[t]);
  }
  bc.vertex_tri_begin.push_back(static_cast<int32_t>(bc.vertex_tris.size()));
  for (const auto& tri : m.collision_triangles) bc.triangle_body.push_back(point_body(tri[0]));
  m.body_contact = std::move(bc);
}

/// Per uncut edge, the DOFs of a copy holding it as material (its ends, lower node first).
std::vector<std::array<int32_t, 2>> edge_dofs(const CutBase& base, const CutTopology& topo) {
  // Edges no copy holds as material (cut ones: never tested again) keep their nodes' primary DOFs.
  std::vector<std::array<int32_t, 2>> out(base.adj.edges.size());
  for (size_t e = 0; e < out.size(); ++e)
    out[e] = {topo.node_dof[base.adj.edges[e][0]], topo.node_dof[base.adj.edges[e][1]]};
  for (const ElementCopy& c : topo.copies) {
    const Tet& tet = base.tets[c.tet];
    for (int k = 0; k < 6; ++k) {
      const int a = kTetEdge[k][0], b = kTetEdge[k][1];
      if (!(c.material >> a & 1) || !(c.material >> b & 1)) continue;
      const int32_t e = base.adj.tet_edges[c.tet][k];
      const bool a_low = tet[a] == base.adj.edges[e][0];
      out[e] = a_low ? std::array<int32_t, 2>{c.dof[a], c.dof[b]} : std::array<int32_t, 2>{c.dof[b], c.dof[a]};
    }
  }
  return out;
}

}  // namespace

void enable_cutting(Model& m) {
  auto cs = std::make_shared<CutSupport>();
  cs->uncut = m.fem;
  cs->base = make_cut_base(m.fem);
  cs->probes = m.probes;
  const std::vector<double> none(cs->base.adj.edges.size(), kEdgeUncut);
  cs->uncut_topology = std::make_shared<const CutTopology>(
      build_cut_topology(cs->base.tets, m.fem.rest, cs->base.adj, none, cs->base.node_ranges));
  double length = 0, volume = 0;
  for (const auto& e : cs->base.adj.edges) length += distance(&m.fem.rest[3 * e[0]], &m.fem.rest[3 * e[1]]);
  for (const ElementParams& e : m.fem.elements) volume += e.volume;
  cs->edges_per_area = volume > 0 ? 0.5 * length / volume : 0.0;
  cs->internal_faces = m.has_damage && m.has_contact;
  cs->element_region_damage = m.element_region_damage;
  m.topology = cs->uncut_topology;
  m.cut_edge_dofs = cs->base.adj.edges;
  m.cutting = std::move(cs);
}

std::shared_ptr<Model> compile_cut_model(const Model& current, std::shared_ptr<const CutTopology> topo,
                                         const std::vector<double>& edge_cut, int32_t version) {
  if (!current.cutting) throw std::invalid_argument("compile_cut_model: the model has no cutting support");
  const CutSupport& cs = *current.cutting;
  auto m = std::make_shared<Model>();
  m->constants() = current.constants();  // what a topology change keeps, whole
  // The topology part, built anew: the cut FEM system and everything indexed by its elements,
  // nodes and surface faces.
  m->topology = topo;
  m->topology_version = version;
  m->cut_edge_state = edge_cut;
  static std::atomic<uint64_t> serial{0};
  m->cut_serial = serial.fetch_add(1, std::memory_order_relaxed) + 1;
  // The cut FEM system and what hangs off its elements.
  m->fem = build_cut_fem_model(cs.uncut, *topo, cut_rod_anchors(cs, *topo, edge_cut));  // threads ride along
  m->thread_ties = cut_thread_ties(current, *topo);
  m->puncture_capacity = current.puncture_capacity;
  if (!cs.element_region_damage.empty()) {  // each copy follows its tetrahedron's region
    m->element_region_damage.resize(topo->copies.size());
    for (size_t c = 0; c < topo->copies.size(); ++c) m->element_region_damage[c] = cs.element_region_damage[topo->copies[c].tet];
  }
  const FemModel& f = m->fem;
  if (m->has_damage) {
    m->element_node_mass.resize(f.elements.size());
    for (const BodyRange& b : f.bodies)
      for (int32_t e = b.element_begin; e < b.element_end; ++e)
        m->element_node_mass[e] = element_density(f, e, b) * f.elements[e].volume / 4.0;
  }
  m->body_tets.resize(f.bodies.size());
  for (size_t b = 0; b < f.bodies.size(); ++b)
    for (int32_t e = f.bodies[b].element_begin; e < f.bodies[b].element_end; ++e)
      m->body_tets[b].push_back(f.elements[e].node);
  // Probes: the copy holding each probe's material point.
  for (const ProbeModel& p : cs.probes) {
    ProbeModel q = p;
    const int32_t tet = cs.uncut.bodies[p.body].element_begin + p.where.tet;
    const int32_t c = copy_containing(*topo, cs.base.tets, cs.uncut.rest, edge_cut, cs.base.adj, tet, p.where.w);
    for (int k = 0; k < 4; ++k) q.where.node[k] = topo->copies[c].dof[k];
    m->probes.push_back(q);
  }
  std::vector<double> rest_points;
  if (m->has_contact) compile_cut_surface(*topo, *m, rest_points);
  if (current.body_contact) compile_cut_body_contact(*current.body_contact, *topo, rest_points, *m);
  if (m->has_needles) compile_cut_needle_mesh(*m, *topo, cs.base, cs.uncut.rest, edge_cut);
  m->cut_edge_dofs = edge_dofs(cs.base, *topo);
  // What the cuts made.
  CutStats& st = m->cut_stats;
  st.elements_split = topo->split_tets;
  st.edges_cut = topo->cut_edges;
  st.nodes_created = topo->num_dofs - cs.uncut.num_nodes;
  std::vector<double> pts(3 * topo->vertices.size());
  for (size_t v = 0; v < topo->vertices.size(); ++v) {
    const CutVertex& cv = topo->vertices[v];
    for (int k = 0; k < 3; ++k) pts[3 * v + k] = (1 - cv.t) * f.rest[3 * cv.a + k] + cv.t * f.rest[3 * cv.b + k];
  }
  double area = 0;
  for (const CutTriangle& t : topo->triangles) {
    if (!t.cut) continue;
    ++st.faces_created;
    area += triangle_area(&pts[3 * t.v[0]], &pts[3 * t.v[1]], &pts[3 * t.v[2]]);
  }
  st.cut_area = 0.5 * area;
#if STROMA_DEMANDS_ON
  std::string why;  // a cut model keeps the model's invariants (engine/model_check.hpp)
  STROMA_DEMAND(model_invariants_hold(*m, &why), "cut model: " + why);
#endif
  return m;
}

}  // namespace stroma
