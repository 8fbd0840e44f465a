#include <stdexcept>
#include <algorithm>
#include <map>
#include <cmath>
#include <filesystem>
#include <unordered_map>

#include <fmt/format.h>

#include "io/surface_check.hpp"
#include "io/surface_io.hpp"
#include "rigid/mass_properties.hpp"
#include "rigid/rigid_contact.hpp"
#include "engine/needle_mesh.hpp"
#include "engine/cut_compile.hpp"
#include "engine/model.hpp"
#include "engine/model_check.hpp"
#include "engine/state.hpp"
#include "io/mesh_io.hpp"
#include "io/surface_io.hpp"
#include "scene/compiled_scenario.hpp"
#include "scene/solver_comparison.hpp"
#include "scene/yaml_schema.hpp"
#include "tissue/bounding_box.hpp"
#include "tissue/cholmod_solver.hpp"
#include "tissue/demand.hpp"
#include "tissue/fem_build.hpp"
#include "tissue/input_error.hpp"
#include "tissue/mat3.hpp"
#include "tissue/material.hpp"
#include "tissue/mesh_prepare.hpp"

namespace stroma {

namespace {

/// Local node indices selected by `sel` in `mesh`. Throws if the selection is empty or an index
/// is out of range: a constraint that silently selects nothing is a classic scenario bug.
std::vector<int32_t> select_nodes(const NodeSelection& sel, const PreparedMesh& pm,
                                  const std::string& field) {
  const TetMesh& mesh = pm.mesh;
  std::vector<int32_t> out;
  const int32_t n = static_cast<int32_t>(mesh.nodes.size());
  std::vector<char> facing;  // surface: nodes of boundary faces facing the normal
  if (sel.surface) {
    facing.assign(static_cast<size_t>(n), 0);
    const double cos_max = std::cos(sel.surface->max_angle_deg * M_PI / 180.0);
    const Vec3& d = sel.surface->normal;
    for (const Tri& t : pm.boundary) {
      const Vec3 &a = mesh.nodes[t[0]], &b = mesh.nodes[t[1]], &c = mesh.nodes[t[2]];
      const double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, v[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
      double nrm[3];  // outward (boundary faces are CCW seen from outside)
      m3::cross(u, v, nrm);
      const double len = std::sqrt(m3::dot(nrm, nrm));
      if (len > 0 && m3::dot(nrm, d.data()) >= cos_max * len)
        for (int k = 0; k < 3; ++k) facing[static_cast<size_t>(t[k])] = 1;
    }
    if (!sel.box) {
      for (int32_t i = 0; i < n; ++i)
        if (facing[static_cast<size_t>(i)]) out.push_back(i);
      if (out.empty())
        throw InputError(sel.where.file, sel.where.line, field + ".surface",
                         fmt::format("no boundary face of mesh '{}' faces [{}, {}, {}] within {} degrees", mesh.source,
                                     d[0], d[1], d[2], sel.surface->max_angle_deg));
    }
  }
  if (sel.box) {
    const BoxSpec& b = *sel.box;
    for (int32_t i = 0; i < n; ++i) {
      const Vec3& p = mesh.nodes[i];
      if (p[0] >= b.min[0] && p[0] <= b.max[0] && p[1] >= b.min[1] && p[1] <= b.max[1] &&
          p[2] >= b.min[2] && p[2] <= b.max[2] && (facing.empty() || facing[static_cast<size_t>(i)]))
        out.push_back(i);
    }
    if (out.empty())
      throw InputError(sel.where.file, sel.where.line, field + (sel.surface ? "" : ".box"),
                       fmt::format("box [{}, {}, {}]..[{}, {}, {}]{} selects no node of mesh '{}'",
                                   b.min[0], b.min[1], b.min[2], b.max[0], b.max[1], b.max[2],
                                   sel.surface ? " with the surface condition" : "", mesh.source));
  }
  for (int i : sel.nodes) {
    if (i < 0 || i >= n)
      throw InputError(sel.where.file, sel.where.line, field + ".nodes",
                       fmt::format("node {} is out of range: mesh '{}' has {} nodes (0-based)", i,
                                   mesh.source, n));
    out.push_back(i);
  }
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

/// Loads each body's `visual:` surface and maps it into the body's tetrahedra.
std::vector<std::optional<VisualModel>> compile_visuals(const ScenarioSpec& spec, const std::vector<PreparedMesh>& meshes,
                                                        const Model& model, std::vector<std::string>& notes) {
  std::vector<std::optional<VisualModel>> visuals(spec.bodies.size());
  for (size_t bi = 0; bi < spec.bodies.size(); ++bi) {
    const BodySpec& b = spec.bodies[bi];
    if (!b.visual) continue;
    const VisualSpec& v = *b.visual;
    const std::string field = fmt::format("bodies[{}].visual", bi);
    SurfaceMesh surf;
    try {
      surf = read_surface_mesh(v.mesh_path);
    } catch (const InputError& e) {
      throw InputError(v.where.file, v.where.line, field, e.what());
    }
    for (Vec3& p : surf.vertices)
      for (int k = 0; k < 3; ++k) p[k] = p[k] * b.scale + b.translate[k];
    const TetMesh& tm = meshes[bi].mesh;
    // Automatic: 5 % of the body's bounding-box diagonal.
    const double max_distance = v.max_distance > 0 ? v.max_distance : 0.05 * bounding_box(tm.nodes).diagonal();
    const BodyRange& range = model.fem.bodies[bi];
    VisualModel vm;
    vm.source = v.mesh_path;
    try {
      vm.mapping = build_visual_mapping(tm, surf.vertices, max_distance, range.node_begin, range.element_begin,
                                        v.mesh_path);
    } catch (const InputError& e) {
      throw InputError(v.where.file, v.where.line, field,
                       fmt::format("{} (raise max_distance under visual: if the surface is meant to lie that far "
                                   "outside the tetrahedra)", e.what()));
    }
    if (vm.mapping.outside > 0)
      notes.push_back(fmt::format("body '{}': {} of {} visual vertices lie outside the tetrahedra (at most "
                                        "{:.3g} away) and follow their nearest tetrahedron",
                                        b.name, vm.mapping.outside, surf.vertices.size(), vm.mapping.max_distance));
    vm.rest = std::move(surf.vertices);
    for (const Tri& t : surf.triangles)
      for (int32_t i : t) vm.triangles.push_back(static_cast<uint32_t>(i));
    visuals[bi] = std::move(vm);
  }
  return visuals;
}

/// Body–body contact: each body's rest-boundary vertices with a third of their adjacent
/// surface area, their diagonal slots, the body of every collision triangle, and the automatic
/// stiffness (from the stiffest material and the mean surface edge) and each body's depth (a
/// quarter of its smallest extent).
void compile_body_contact(const BodyContactSpec& spec, const ScenarioSpec& scenario, Model& model) {
  const FemModel& fem = model.fem;
  BodyContactModel bc;
  double e_max = 0;
  for (const BodySpec& b : scenario.bodies) e_max = std::max(e_max, b.material.young_modulus);
  std::vector<double> area(fem.num_nodes, 0.0);
  std::vector<uint8_t> on_surface(fem.num_nodes, 0);
  for (const BodyRange& b : fem.bodies) {
    const double extent =
        bounding_box(fem.rest.data() + 3 * b.node_begin, static_cast<size_t>(b.node_end - b.node_begin)).min_extent();
    bc.body_depth.push_back(spec.max_depth > 0 ? spec.max_depth : 0.25 * extent);
    for (const Tri& t : b.boundary) {
      const double* a = &fem.rest[3 * t[0]];
      const double* p = &fem.rest[3 * t[1]];
      const double* q = &fem.rest[3 * t[2]];
      const double u[3] = {p[0] - a[0], p[1] - a[1], p[2] - a[2]}, w[3] = {q[0] - a[0], q[1] - a[1], q[2] - a[2]};
      const double cx = u[1] * w[2] - u[2] * w[1], cy = u[2] * w[0] - u[0] * w[2], cz = u[0] * w[1] - u[1] * w[0];
      const double third = std::sqrt(cx * cx + cy * cy + cz * cz) / 6.0;
      for (int32_t n : t) {
        area[n] += third;
        on_surface[n] = 1;
      }
    }
  }
  // Automatic stiffness: a vertex's spring k·A is ~10× the stiffness E·h of the elements
  // behind it (h: mean rest surface edge), stiff enough that resting penetration is a tenth
  // of an element's strain-equivalent, soft enough not to dominate CG's conditioning.
  double edge_sum = 0;
  int64_t edges = 0;
  for (const BodyRange& b : fem.bodies)
    for (const Tri& t : b.boundary)
      for (int a = 0; a < 3; ++a) {
        double d2 = 0;
        for (int k = 0; k < 3; ++k) {
          const double d = fem.rest[3 * t[a] + k] - fem.rest[3 * t[(a + 1) % 3] + k];
          d2 += d * d;
        }
        edge_sum += std::sqrt(d2);
        ++edges;
      }
  const double h_mean = edge_sum / static_cast<double>(std::max<int64_t>(edges, 1));
  bc.stiffness = spec.stiffness > 0 ? spec.stiffness : 10.0 * e_max / h_mean;
  for (const BodyRange& b : fem.bodies) {
    bc.body_vertex_begin.push_back(static_cast<int32_t>(bc.vertex.size()));
    for (int32_t i = b.node_begin; i < b.node_end; ++i)
      if (on_surface[i]) {
        bc.vertex.push_back(i);
        bc.vertex_area.push_back(area[i]);
        bc.vertex_dofs.push_back(point_dofs(fem.pattern, i, fem.num_nodes, {}));
        bc.vertex_fixed.push_back(fem.constrained[i] == 7 ? 1 : 0);
      }
  }
  bc.body_vertex_begin.push_back(static_cast<int32_t>(bc.vertex.size()));
  bc.num_dofs = fem.num_nodes;
  std::vector<std::vector<int32_t>> tris_of(fem.num_nodes);  // rest-boundary triangles per node
  std::vector<Tri> all_boundary;
  for (const BodyRange& b : fem.bodies)
    for (const Tri& t : b.boundary) {
      for (int32_t n : t) tris_of[n].push_back(static_cast<int32_t>(all_boundary.size()));
      all_boundary.push_back(t);
    }
  for (int32_t v : bc.vertex) {
    bc.vertex_tri_begin.push_back(static_cast<int32_t>(bc.vertex_tris.size()));
    for (int32_t t : tris_of[v]) bc.vertex_tris.push_back({all_boundary[t][0], all_boundary[t][1], all_boundary[t][2]});
  }
  bc.vertex_tri_begin.push_back(static_cast<int32_t>(bc.vertex_tris.size()));
  for (const auto& t : model.collision_triangles) {
    int32_t body = 0;
    while (t[0] >= fem.bodies[body].node_end) ++body;
    bc.triangle_body.push_back(body);
  }
  model.body_contact = std::move(bc);
}

/// Reads, scales and prepares each body's mesh; notes what preparation changed.
std::vector<PreparedMesh> load_meshes(const ScenarioSpec& spec, std::vector<std::string>& notes) {
  std::vector<PreparedMesh> meshes;
  meshes.reserve(spec.bodies.size());
  for (size_t bi = 0; bi < spec.bodies.size(); ++bi) {
    const BodySpec& b = spec.bodies[bi];
    const std::string field = fmt::format("bodies[{}].mesh", bi);
    TetMesh mesh;
    try {
      mesh = load_tet_mesh(b.mesh_path);
    } catch (const InputError& e) {
      // Say which scenario line asked for this mesh, then what is wrong inside it.
      throw InputError(b.mesh_where.file, b.mesh_where.line, field, e.what());
    }
    for (Vec3& p : mesh.nodes)  // scale, then place: selections are in scene coordinates
      for (int k = 0; k < 3; ++k) p[k] = p[k] * b.scale + b.translate[k];
    try {
      meshes.push_back(prepare_mesh(std::move(mesh)));
    } catch (const InputError& e) {
      throw InputError(b.mesh_where.file, b.mesh_where.line, field, e.what());
    }
    const PreparedMesh& pm = meshes.back();
    if (!pm.reoriented.empty())
      notes.push_back(fmt::format("body '{}': {} inverted tetrahedra re-oriented", b.name, pm.reoriented.size()));
    if (!pm.unused_nodes.empty())
      notes.push_back(fmt::format("body '{}': {} nodes are used by no tetrahedron and are kept out of the system "
                                  "(first: {})",
                                  b.name, pm.unused_nodes.size(), pm.unused_nodes.front()));
  }
  return meshes;
}

/// The region tag that regions[k] of body b names in its mesh (by name or number; −1 for a
/// name the mesh lacks: apply_regions reports that).
int32_t region_tag(const BodySpec& b, const TetMesh& mesh, size_t k) {
  const RegionSpec& r = b.regions[k];
  if (r.name.empty()) return r.tag;
  for (const auto& [t, nm] : mesh.tag_names)
    if (nm == r.name) return t;
  return -1;
}

/// A body's `regions:`: each region's tetrahedra (by the mesh's region name or tag) get the
/// body's material with what the region changes. Errors name the region entry.
void apply_regions(const BodySpec& b, const PreparedMesh& pm, const std::string& field, FemBodyInput& in) {
  if (b.regions.empty()) return;
  const TetMesh& mesh = pm.mesh;
  std::map<int32_t, size_t> tets_of;
  for (int32_t t : mesh.tet_tags) ++tets_of[t];
  auto region_list = [&] {
    std::string out;
    for (const auto& [tag, n] : tets_of) {
      std::string name;
      for (const auto& [t, nm] : mesh.tag_names)
        if (t == tag) name = nm;
      out += fmt::format("{}{}{} ({} tets)", out.empty() ? "" : ", ", tag, name.empty() ? "" : " '" + name + "'", n);
    }
    return out;
  };
  const ElementMaterial base{in.young_modulus, in.poisson_ratio, in.density, in.rayleigh_stiffness};
  in.element_material.assign(mesh.tets.size(), base);
  std::map<int32_t, size_t> given;
  for (size_t k = 0; k < b.regions.size(); ++k) {
    const RegionSpec& r = b.regions[k];
    const std::string rf = fmt::format("{}.regions[{}].region", field, k);
    auto fail = [&](const std::string& msg) { throw InputError(r.region_where.file, r.region_where.line, rf, msg); };
    if (mesh.tet_tags.empty())
      fail(fmt::format("mesh {} has no regions: none of its tetrahedra is in a gmsh physical volume (give the "
                       "volumes physical groups, e.g. Physical Volume(\"tumour\") = {{2}};)",
                       b.mesh_path));
    int32_t tag = r.tag;
    if (!r.name.empty()) {
      bool found = false;
      for (const auto& [t, nm] : mesh.tag_names)
        if (nm == r.name) {
          tag = t;
          found = true;
        }
      if (!found) fail(fmt::format("no region named '{}' in {}; its regions are: {}", r.name, b.mesh_path, region_list()));
    }
    if (tets_of.count(tag) == 0)
      fail(fmt::format("no tetrahedron of {} is in region {}; its regions are: {}", b.mesh_path, tag, region_list()));
    if (const auto g = given.find(tag); g != given.end())
      fail(fmt::format("region {} is given twice (also {}.regions[{}])", tag, field, g->second));
    given[tag] = k;
    ElementMaterial em = base;
    if (r.young_modulus) em.young_modulus = *r.young_modulus;
    if (r.poisson_ratio) em.poisson_ratio = *r.poisson_ratio;
    if (r.density) em.density = *r.density;
    if (r.rayleigh_stiffness) em.rayleigh_stiffness = *r.rayleigh_stiffness;
    const std::string err = validate_material(em.young_modulus, em.poisson_ratio, em.density, b.material.rayleigh_mass,
                                              em.rayleigh_stiffness);
    if (!err.empty()) throw InputError(r.where.file, r.where.line, fmt::format("{}.regions[{}].material", field, k), err);
    for (size_t t = 0; t < mesh.tets.size(); ++t)
      if (mesh.tet_tags[t] == tag) in.element_material[t] = em;
  }
}

/// A body's fibres (its material's and its regions'), per tetrahedron: a direction given in the
/// scenario, or each tetrahedron's own from the mesh (`direction: mesh`; a zero vector there
/// means no fibres in that tetrahedron). Errors name the field; a non-finite direction in the
/// mesh names its tetrahedron.
void apply_fibres(const BodySpec& b, const PreparedMesh& pm, const std::string& field, FemBodyInput& in) {
  const TetMesh& mesh = pm.mesh;
  const bool any_region = std::any_of(b.regions.begin(), b.regions.end(), [](const RegionSpec& r) { return r.fibres.has_value(); });
  if (!b.material.fibres && !any_region) return;
  if (in.model != ElementModel::StableNeoHookean && in.model != ElementModel::StVenantKirchhoff) {
    const RegionSpec* r = nullptr;
    for (const RegionSpec& x : b.regions)
      if (x.fibres) r = &x;
    const SourceLocation w = r ? r->fibres->where : b.material.where;
    throw InputError(w.file, w.line, field + ".material.model",
                     "fibres need a hyperelastic matrix: model stable_neo_hookean or st_venant_kirchhoff");
  }
  auto params_for = [&](const FibreSpec& s, const std::string& f, size_t t) {
    FibreParams p{{s.direction[0], s.direction[1], s.direction[2]}, s.k1, s.k2};
    if (!s.from_mesh) return p;
    if (mesh.tet_fibres.empty())
      throw InputError(s.where.file, s.where.line, f + ".direction",
                       fmt::format("mesh {} has no fibre directions: give its tetrahedra a 3-component VTU cell-data "
                                   "array named 'fibres', or give the direction here as [x, y, z]",
                                   b.mesh_path));
    const Vec3& d = mesh.tet_fibres[t];
    const double len = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    if (!std::isfinite(len))
      throw InputError(s.where.file, s.where.line, f + ".direction",
                       fmt::format("tetrahedron {} of {} has a non-finite fibre direction", t, b.mesh_path));
    if (len < 1e-12) return FibreParams{{1, 0, 0}, 0, 0};  // no fibres here
    for (int k = 0; k < 3; ++k) p.a[k] = d[k] / len;
    return p;
  };
  in.element_fibres.assign(mesh.tets.size(), FibreParams{{1, 0, 0}, 0, 0});
  if (b.material.fibres)
    for (size_t t = 0; t < mesh.tets.size(); ++t) in.element_fibres[t] = params_for(*b.material.fibres, field + ".material.fibres", t);
  for (size_t k = 0; k < b.regions.size(); ++k) {
    if (!b.regions[k].fibres) continue;
    const int32_t tag = region_tag(b, mesh, k);  // (apply_regions has checked it names a region)
    const std::string f = fmt::format("{}.regions[{}].material.fibres", field, k);
    for (size_t t = 0; t < mesh.tets.size(); ++t)
      if (mesh.tet_tags[t] == tag) in.element_fibres[t] = params_for(*b.regions[k].fibres, f, t);
  }
}

/// Materials, constraints and loads of each body, validated against its mesh, as FEM inputs.
/// `meshes` are the bodies as they are (selections are made on them); `rest_meshes` their rest
/// shapes (the same but for a prestretched body's nodes), which the FEM is built on.
std::vector<FemBodyInput> body_inputs(const ScenarioSpec& spec, const std::vector<PreparedMesh>& meshes,
                                      const std::vector<PreparedMesh>& rest_meshes) {
  std::vector<FemBodyInput> inputs;
  for (size_t bi = 0; bi < spec.bodies.size(); ++bi) {
    const BodySpec& b = spec.bodies[bi];
    const std::string field = fmt::format("bodies[{}]", bi);
    const PreparedMesh& pm = meshes[bi];
    const MaterialSpec& mat = b.material;
    const std::string err = validate_material(mat.young_modulus, mat.poisson_ratio, mat.density,
                                              mat.rayleigh_mass, mat.rayleigh_stiffness);
    if (!err.empty()) throw InputError(mat.where.file, mat.where.line, field + ".material", err);
    FemBodyInput in;
    in.name = b.name;
    in.model = mat.model;
    in.rotation = mat.rotation;
    in.young_modulus = mat.young_modulus;
    in.poisson_ratio = mat.poisson_ratio;
    in.density = mat.density;
    in.rayleigh_mass = mat.rayleigh_mass;
    in.rayleigh_stiffness = mat.rayleigh_stiffness;
    in.uniform_mass = mat.uniform_mass;
    if (mat.uniform_mass) {
      // Rupture removes an element's ρV/4 from its nodes and a cut re-lumps its copies by volume:
      // neither is defined for masses shared equally.
      const bool region_damage = std::any_of(b.regions.begin(), b.regions.end(), [](const RegionSpec& r) {
        return r.damage && r.damage->enabled;
      });
      if (mat.damage.enabled || region_damage)
        throw InputError(mat.where.file, mat.where.line, field + ".material.mass_lumping",
                         "uniform masses with a damage model are not supported (rupture removes each element's "
                         "ρV/4 from its nodes); use mass_lumping: volume");
      for (size_t ti = 0; ti < spec.tools.size(); ++ti)
        if (spec.tools[ti].spec.cuts)
          throw InputError(mat.where.file, mat.where.line, field + ".material.mass_lumping",
                           fmt::format("uniform masses on a body that can be cut are not supported (tools[{}] cuts; a "
                                       "cut re-lumps its element copies by volume); use mass_lumping: volume",
                                       ti));
    }
    if (const auto& ve = mat.viscoelastic) {
      const std::string vf = field + ".material.viscoelastic";
      if (ve->model == "kelvin_voigt") {
        in.rayleigh_stiffness = ve->kelvin_voigt_tau;  // σ = Eε + ηε̇: stiffness damping β = η/E
      } else {
        if (spec.solver.integrator != Integrator::ImplicitEuler)
          throw InputError(ve->where.file, ve->where.line, vf,
                           "a Prony series needs solver.integrator implicit_euler (its internal variables step with "
                           "the ticks: a static solve has no time, symplectic Euler is not supported)");
        if (spec.solver.fem_every != 1)
          throw InputError(ve->where.file, ve->where.line, vf, "a Prony series needs solver.fem_every 1 for now");
        in.visco = ve->series;
      }
    }
    if (const auto& lf = mat.locking_free) {
      for (size_t ti = 0; ti < spec.tools.size(); ++ti)
        if (spec.tools[ti].spec.cuts)
          throw InputError(lf->where.file, lf->where.line, field + ".material.locking_free",
                           fmt::format("cutting a locking-free body is not supported yet (tools[{}] cuts): a cut splits "
                                       "node domains, and a split domain's energy exceeds the whole's, so the cut would "
                                       "create energy (docs/TISSUE.md)",
                                       ti));
      in.locking_free_share = lf->stabilisation;
      in.locking_free_patch = lf->patch_elements;
      in.locking_free_bulk = lf->element_bulk;
    }
    in.mesh = &rest_meshes[bi];
    apply_regions(b, pm, field, in);
    apply_fibres(b, pm, field, in);
    for (size_t k = 0; k < b.fixed.size(); ++k) {
      auto sel = select_nodes(b.fixed[k], pm, fmt::format("{}.fixed[{}]", field, k));
      for (int32_t i : sel) in.fixed.push_back({i, b.fixed[k].axes});
    }
    for (size_t k = 0; k < b.loads.size(); ++k) {
      const NodalLoadSpec& l = b.loads[k];
      auto sel = select_nodes(l.select, pm, fmt::format("{}.loads[{}]", field, k));
      const double share = l.per_node ? 1.0 : 1.0 / static_cast<double>(sel.size());
      for (int32_t i : sel) in.nodal_forces.push_back({i, {l.force[0] * share, l.force[1] * share, l.force[2] * share}});
    }
    inputs.push_back(std::move(in));
  }
  return inputs;
}

/// Per-body damage models and, when any body has one, each element's share of nodal mass
/// (removed from its nodes at rupture).
void compile_damage(const ScenarioSpec& spec, const std::vector<PreparedMesh>& meshes, Model& model) {
  for (const BodySpec& b : spec.bodies) {
    model.body_damage.push_back(b.material.damage);
    model.has_damage = model.has_damage || b.material.damage.enabled;
  }
  // Regions with damage thresholds of their own: their tetrahedra follow those.
  for (size_t bi = 0; bi < spec.bodies.size(); ++bi) {
    const BodySpec& b = spec.bodies[bi];
    for (size_t k = 0; k < b.regions.size(); ++k) {
      if (!b.regions[k].damage) continue;
      const int32_t tag = region_tag(b, meshes[bi].mesh, k);
      if (model.element_region_damage.empty()) model.element_region_damage.assign(model.fem.elements.size(), -1);
      const int32_t index = static_cast<int32_t>(model.region_damage.size());
      model.region_damage.push_back(*b.regions[k].damage);
      model.has_damage = true;
      const std::vector<int32_t>& tags = meshes[bi].mesh.tet_tags;
      for (size_t t = 0; t < tags.size(); ++t)
        if (tags[t] == tag) model.element_region_damage[model.fem.bodies[bi].element_begin + static_cast<int32_t>(t)] = index;
    }
  }
  if (!model.has_damage) return;
  const FemModel& f = model.fem;
  model.element_node_mass.resize(f.elements.size());
  for (size_t bi = 0; bi < f.bodies.size(); ++bi)
    for (int32_t e = f.bodies[bi].element_begin; e < f.bodies[bi].element_end; ++e)
      model.element_node_mass[e] = element_density(f, e, f.bodies[bi]) * f.elements[e].volume / 4.0;
}

/// Probes: each point located in its body's tetrahedra (a point far outside is an error).
void compile_probes(const ScenarioSpec& spec, const std::vector<PreparedMesh>& meshes, Model& model) {
  for (size_t pi = 0; pi < spec.probes.size(); ++pi) {
    const ProbeSpec& p = spec.probes[pi];
    int body = -1;
    for (size_t bi = 0; bi < spec.bodies.size(); ++bi)
      if (spec.bodies[bi].name == p.body) body = static_cast<int>(bi);
    if (body < 0)
      throw InputError(p.where.file, p.where.line, fmt::format("probes[{}].body", pi),
                       fmt::format("no body named '{}'", p.body));
    const PreparedMesh& pm = meshes[body];
    ProbeModel pmod;
    pmod.name = p.name;
    pmod.body = body;
    pmod.where = locate_point(pm.mesh, p.point);
    // A probe far outside its body is almost certainly a typo (wrong units or axis).
    const double diag = bounding_box(pm.mesh.nodes).diagonal();
    if (pmod.where.distance > 0.05 * diag)
      throw InputError(p.where.file, p.where.line, fmt::format("probes[{}].point", pi),
                       fmt::format("point [{}, {}, {}] is {:.3g} outside body '{}' (its size is {:.3g})",
                                   p.point[0], p.point[1], p.point[2], pmod.where.distance, p.body, diag));
    for (int32_t& nidx : pmod.where.node) nidx += model.fem.bodies[body].node_begin;
    model.probes.push_back(pmod);
  }
}

/// Tools with their automatic values resolved (contact and grasp stiffness), and their scripts.
/// Needles (rigid/needle_track.hpp): each tissue body's `material.needle` resolved (automatic
/// track stiffness 100·E per m, spacing half the body's mean surface edge) and each needle's
/// track capacity (the mesh its walks cross: compile_needle_mesh, once the surface is made).
void compile_needles(const ScenarioSpec& spec, Model& model) {
  model.has_needles = std::any_of(model.rigid_bodies.begin(), model.rigid_bodies.end(),
                                  [](const RigidBodyModel& b) { return b.shape == RigidShape::Needle; });
  if (!model.has_needles) return;
  const FemModel& fem = model.fem;
  model.needle_tissue.assign(fem.bodies.size(), NeedleTissue{});
  double spacing_min = 1e300;
  for (size_t bi = 0; bi < spec.bodies.size(); ++bi) {
    const MaterialSpec& mat = spec.bodies[bi].material;
    if (!mat.needle) continue;
    const NeedleTissueSpec& n = *mat.needle;
    NeedleTissue& t = model.needle_tissue[bi];
    t.enabled = true;
    t.puncture_force = n.puncture_force;
    t.cutting_force = n.cutting_force;
    t.friction_static = n.friction_static;
    t.friction_kinetic = n.friction_kinetic;
    t.track_stiffness = n.track_stiffness > 0 ? n.track_stiffness : 100.0 * mat.young_modulus;
    double edges = 0;
    int count = 0;
    for (const Tri& tri : fem.bodies[bi].boundary)
      for (int k = 0; k < 3; ++k) {
        const int32_t a = tri[size_t(k)], c = tri[size_t((k + 1) % 3)];
        double d2 = 0;
        for (int j = 0; j < 3; ++j) d2 += (fem.rest[size_t(3 * a + j)] - fem.rest[size_t(3 * c + j)]) * (fem.rest[size_t(3 * a + j)] - fem.rest[size_t(3 * c + j)]);
        edges += std::sqrt(d2);
        ++count;
      }
    t.track_spacing = n.track_spacing > 0 ? n.track_spacing : 0.5 * edges / std::max(count, 1);
    spacing_min = std::min(spacing_min, t.track_spacing);
  }
  if (spacing_min == 1e300) spacing_min = 1e-3;  // no body can be punctured: the track stays empty
  for (RigidBodyModel& b : model.rigid_bodies)
    if (b.shape == RigidShape::Needle)  // points ≤ the needle's length / spacing, and an exit's and the ends'
      b.track_capacity = static_cast<int32_t>(std::ceil((b.needle.length + b.needle.wire_radius) / spacing_min)) + 8;
}

/// A needle's wire and curve from its scenario entry (rigid/needle_shape.hpp).
NeedleGeometry needle_geometry(const RigidBodySpec& r) {
  NeedleGeometry g;
  g.wire_radius = r.wire_radius;
  g.curved = r.angle_deg > 0;
  g.arc_radius = g.curved ? r.radius : 0.0;
  g.angle = r.angle_deg * M_PI / 180.0;
  g.length = g.curved ? g.arc_radius * g.angle : r.length;
  return g;
}

/// `rigid_bodies:` → RigidBodyModel: mass properties from the shape (a mesh read, checked
/// closed and scaled), the body frame moved to the centre of mass, the initial state.
void compile_rigid_bodies(const ScenarioSpec& spec, Model& model) {
  if (!spec.rigid_bodies.empty() && spec.solver.integrator == Integrator::Static) {
    const RigidBodySpec& r = spec.rigid_bodies[0];
    throw InputError(r.where.file, r.where.line, "rigid_bodies",
                     "a static scenario finds equilibria of the tissue; rigid bodies move: use integrator implicit_euler");
  }
  if (!spec.rigid_bodies.empty() && spec.solver.integrator == Integrator::SymplecticEuler) {
    const RigidBodySpec& r = spec.rigid_bodies[0];
    throw InputError(r.where.file, r.where.line, "rigid_bodies",
                     "rigid bodies join the tissue's implicit step (their contacts are solved with it): use integrator "
                     "implicit_euler");
  }
  double e_max = 0;
  for (const BodySpec& b : spec.bodies) e_max = std::max(e_max, b.material.young_modulus);
  for (size_t i = 0; i < spec.rigid_bodies.size(); ++i) {
    const RigidBodySpec& r = spec.rigid_bodies[i];
    const std::string field = fmt::format("rigid_bodies[{}]", i);
    RigidBodyModel b;
    b.name = r.name;
    b.fixed = r.fixed;
    MassProperties p;
    try {
      switch (r.shape) {
        case RigidShapeKind::Sphere:
          b.shape = RigidShape::Sphere, b.radius = r.radius;
          p = sphere_mass_properties(r.radius, r.density);
          break;
        case RigidShapeKind::Box:
          b.shape = RigidShape::Box, b.size = r.size;
          p = box_mass_properties(r.size, r.density);
          break;
        case RigidShapeKind::Capsule:
          b.shape = RigidShape::Capsule, b.radius = r.radius, b.length = r.length;
          p = capsule_mass_properties(r.radius, r.length, r.density);
          break;
        case RigidShapeKind::Needle: {
          b.shape = RigidShape::Needle;
          b.needle = needle_geometry(r);
          p = needle_mass_properties(b.needle, r.density);
          break;
        }
        case RigidShapeKind::Mesh: {
          b.shape = RigidShape::Mesh;
          SurfaceMesh sm = read_surface_mesh(r.mesh_path);  // InputError naming the file
          const SurfaceDefects d = find_surface_defects(sm);
          if (!d.empty())
            throw InputError(r.shape_where.file, r.shape_where.line, field + ".shape.file",
                             fmt::format("'{}' is not the closed surface of a solid: ", r.mesh_path) +
                                 describe_surface_defects(sm, d));
          for (Vec3& v : sm.vertices)
            for (double& c : v) c *= r.mesh_scale;
          p = mesh_mass_properties(sm.vertices, sm.triangles, r.density);
          b.surface_vertices = std::move(sm.vertices);
          b.surface_triangles = std::move(sm.triangles);
          break;
        }
      }
    } catch (const std::invalid_argument& e) {
      throw InputError(r.shape_where.file, r.shape_where.line, field + ".shape", e.what());
    }
    std::string why;
    if (!is_physical(p, &why))
      throw InputError(r.shape_where.file, r.shape_where.line, field + ".shape", "its inertia is not a solid's: " + why);
    // The body frame: origin at the centre of mass, axes the shape's.
    const Vec3 c = p.centre;
    p.centre = {0, 0, 0};
    b.mass = p;
    b.shape_origin = {-c[0], -c[1], -c[2]};
    for (Vec3& v : b.surface_vertices)
      for (int k = 0; k < 3; ++k) v[size_t(k)] -= c[size_t(k)];
    RigidState& s0 = b.initial;
    s0.q = r.orientation;
    const std::array<double, 9> R = rotation_of(s0.q);
    for (int k = 0; k < 3; ++k)
      s0.x[size_t(k)] = r.position[size_t(k)] + R[size_t(3 * k)] * c[0] + R[size_t(3 * k + 1)] * c[1] + R[size_t(3 * k + 2)] * c[2];
    s0.v = r.velocity;
    s0.w = r.angular_velocity;
    make_contact_samples(b);
    // Automatic contact stiffness: as a tool's, stiff against the stiffest tissue at this size.
    b.contact_stiffness = r.contact_stiffness > 0 ? r.contact_stiffness : 100.0 * e_max / b.feature;
    b.contact_damping = r.contact_damping;
    b.friction = r.friction;
    model.rigid_bodies.push_back(std::move(b));
    model.has_contact = true;
  }
  compile_needles(spec, model);
}

void compile_tools(const ScenarioSpec& spec, Model& model, std::vector<Trajectory>& scripts) {
  double e_max = 0;
  for (const BodySpec& b : spec.bodies) e_max = std::max(e_max, b.material.young_modulus);
  for (size_t ti = 0; ti < spec.tools.size(); ++ti) {
    const ToolEntry& t = spec.tools[ti];
    ToolSpec ts = t.spec;
    for (int k = 0; k < 3; ++k)
      if (ts.workspace_min[k] > ts.workspace_max[k])
        throw InputError(t.where.file, t.where.line, fmt::format("tools[{}].workspace", ti),
                         "min must not exceed max");
    if (ts.shape != ToolShape::None) {
      model.has_contact = true;
      if (ts.cuts && ts.blade_height == 0) ts.blade_height = 0.5 * ts.shaft_length;
      // Automatic: stiff against the stiffest body at this size — a cutting blade's size is
      // its body's height, not its half-thickness (100·E/thickness made the lips' pushes 10⁴ N
      // on a 20 µm blade).
      if (ts.contact_stiffness == 0) ts.contact_stiffness = 100.0 * e_max / (ts.cuts ? ts.blade_height : ts.radius);
      if (ts.can_grasp && ts.grasp_stiffness == 0) ts.grasp_stiffness = 0.25 * ts.contact_stiffness * ts.radius * ts.radius;
    }
    if (t.has_pose)
      for (int k = 0; k < 3; ++k)
        if (ts.rest_pose.position[k] < ts.workspace_min[k] || ts.rest_pose.position[k] > ts.workspace_max[k])
          throw InputError(t.where.file, t.where.line, fmt::format("tools[{}].pose", ti),
                           fmt::format("position[{}] = {} is outside the tool's workspace [{}, {}]", k,
                                       ts.rest_pose.position[k], ts.workspace_min[k], ts.workspace_max[k]));
    Trajectory tr;
    if (!t.script.empty()) {
      try {
        tr = load_trajectory(t.script);
      } catch (const InputError& e) {
        throw InputError(t.where.file, t.where.line, fmt::format("tools[{}].script", ti), e.what());
      }
      if (!t.has_pose && !tr.keys.empty()) ts.rest_pose = tr.keys.front().pose;  // where the script starts
    }
    model.tools.push_back(ts);
    scripts.push_back(std::move(tr));
  }
}

/// The collision surface: each body's boundary, or — for bodies that can rupture — every
/// tetrahedron face (inactive while both its elements are intact), so a tear exposes new surface
/// without any rebuild. Each face gets its BSR slots and longest rest edge.
void compile_collision_faces(Model& model) {
  const FemModel& fem = model.fem;
  auto add_face = [&](const Tri& t, int32_t ea, int32_t eb) {
    model.collision_face_elem.push_back({ea, eb});
    model.collision_triangles.push_back({t[0], t[1], t[2]});
    model.collision_dofs.push_back(triangle_dofs(fem.pattern, {t[0], t[1], t[2]}, fem.num_nodes, {}));
    double e = 0;
    for (int a = 0; a < 3; ++a) {
      const int32_t p = t[a], q = t[(a + 1) % 3];
      double d2 = 0;
      for (int k = 0; k < 3; ++k) {
        const double dk = fem.rest[3 * p + k] - fem.rest[3 * q + k];
        d2 += dk * dk;
      }
      e = std::max(e, std::sqrt(d2));
    }
    model.collision_edge.push_back(e);
  };
  std::vector<std::array<int32_t, 4>> faces_of(fem.elements.size(), {-1, -1, -1, -1});
  for (size_t bi = 0; bi < fem.bodies.size(); ++bi) {
    const BodyRange& b = fem.bodies[bi];
    if (!body_can_tear(model, bi)) {
      for (const Tri& t : b.boundary) add_face(t, -1, -1);  // always active
      continue;
    }
    static constexpr int kFaces[4][3] = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};  // outward
    std::unordered_map<uint64_t, int32_t> seen;
    for (int32_t e = b.element_begin; e < b.element_end; ++e)
      for (int f = 0; f < 4; ++f) {
        const auto& nd = fem.elements[e].node;
        const Tri tri{nd[kFaces[f][0]], nd[kFaces[f][1]], nd[kFaces[f][2]]};
        Tri key = tri;
        std::sort(key.begin(), key.end());
        const uint64_t k = (static_cast<uint64_t>(key[0]) << 42) ^ (static_cast<uint64_t>(key[1]) << 21) ^
                           static_cast<uint64_t>(key[2]);
        const auto it = seen.find(k);
        if (it == seen.end()) {
          seen.emplace(k, static_cast<int32_t>(model.collision_triangles.size()));
          faces_of[e][f] = static_cast<int32_t>(model.collision_triangles.size());
          add_face(tri, e, -1);
        } else {
          model.collision_face_elem[it->second][1] = e;
          faces_of[e][f] = it->second;
        }
      }
  }
  model.element_face_ptr.assign(1, 0);
  for (const auto& fs : faces_of) {
    for (int32_t f : fs)
      if (f >= 0) model.element_face.push_back(f);
    model.element_face_ptr.push_back(static_cast<int32_t>(model.element_face.size()));
  }
}

/// solver.fem_every > 1 steps the tissue N× longer than the tick: only implicit Euler stays
/// stable there, and a virtually coupled tool's proxy moves with the tissue step (not yet).
void check_multirate(const ScenarioSpec& spec) {
  const SolverSpec& s = spec.solver;
  if (s.fem_every == 1) return;
  const SourceLocation& at = s.fem_every_where;
  auto fail = [&](const std::string& what) {
    throw InputError(at.file.empty() ? spec.file : at.file, at.line, "solver.fem_every", what);
  };
  if (s.integrator != Integrator::ImplicitEuler)
    fail(fmt::format("fem_every {} needs integrator implicit_euler: a static run has no ticks to interleave, and an "
                     "explicit step {} times longer than the tick is far past its stability limit",
                     s.fem_every, s.fem_every));
  for (const ToolEntry& t : spec.tools)
    if (t.spec.coupling_stiffness > 0)
      fail(fmt::format("fem_every {} with tool '{}' virtually coupled (coupling.stiffness): not supported yet — "
                       "the proxy would move only at the tissue's rate; drop the coupling or use fem_every 1",
                       s.fem_every, t.spec.name));
}

/// A needle's tail (its curve at s = 0, world) and the way a thread leaves it (the curve's
/// tangent there, backwards), from the scenario's pose and shape.
void needle_tail(const RigidBodySpec& r, Vec3& tail, Vec3& away) {
  double c[3], t[3], R[9];
  needle_curve(needle_geometry(r), 0.0, c, t);
  quaternion_to_matrix(r.orientation, R);
  for (int k = 0; k < 3; ++k) {
    tail[k] = r.position[k] + R[3 * k] * c[0] + R[3 * k + 1] * c[1] + R[3 * k + 2] * c[2];
    away[k] = -(R[3 * k] * t[0] + R[3 * k + 1] * t[1] + R[3 * k + 2] * t[2]);
  }
}

const RigidBodySpec& rigid_spec(const ScenarioSpec& spec, const std::string& name) {
  for (const RigidBodySpec& r : spec.rigid_bodies)
    if (r.name == name) return r;
  throw std::logic_error("no rigid body " + name);  // the loader checked the name
}

/// Each thread as a rod's FEM input (tissue/rod.hpp): its nodes straight from start along its
/// direction (or from its needle's tail, backwards), or at equal arc length along its path; its
/// end nodes fixed as it says; an end attached to a tissue body tied to the material point it
/// lies at (an anchor: within one segment of the body, else an error naming the attachment).
std::vector<FemRodInput> thread_inputs(const ScenarioSpec& spec, const std::vector<PreparedMesh>& meshes) {
  std::vector<FemRodInput> out;
  for (size_t ti = 0; ti < spec.threads.size(); ++ti) {
    ThreadSpec t = spec.threads[ti];
    if (t.from_needle)
      for (const ThreadSpec::Attach& a : t.attach)
        if (a.needle && !a.last) needle_tail(rigid_spec(spec, a.target), t.start, t.direction);
    FemRodInput r;
    r.name = t.name;
    r.segment_length = t.length / t.segments;
    r.young_modulus = t.young_modulus;
    r.bending_stiffness = t.bending_stiffness;
    r.diameter = t.diameter;
    r.density = t.density;
    r.rayleigh_mass = t.rayleigh_mass;
    r.rayleigh_stiffness = t.rayleigh_stiffness;
    r.friction = t.friction;
    {  // 10·E_max per metre of thread (engine/thread_contact.hpp says why not the rigid bodies' 100)
      double e_max = 0;
      for (const BodySpec& b : spec.bodies) e_max = std::max(e_max, b.material.young_modulus);
      r.contact_stiffness = t.contact_stiffness > 0 ? t.contact_stiffness : 10.0 * e_max / t.diameter;
    }
    size_t leg = 0;       // the path's segment the next node is on
    double leg_start = 0;  // arc length at the start of that leg
    for (int i = 0; i <= t.segments; ++i) {
      const double sl = t.length * i / t.segments;
      Vec3 p;
      if (t.path.empty()) {
        for (int k = 0; k < 3; ++k) p[k] = t.start[k] + sl * t.direction[k];
      } else {
        auto leg_length = [&](size_t j) {
          const Vec3 &a = t.path[j], &b = t.path[j + 1];
          return std::sqrt((b[0] - a[0]) * (b[0] - a[0]) + (b[1] - a[1]) * (b[1] - a[1]) + (b[2] - a[2]) * (b[2] - a[2]));
        };
        while (leg + 2 < t.path.size() && sl > leg_start + leg_length(leg)) leg_start += leg_length(leg++);
        const double ll = leg_length(leg);
        const double u = ll > 0 ? std::clamp((sl - leg_start) / ll, 0.0, 1.0) : 0.0;
        for (int k = 0; k < 3; ++k) p[k] = t.path[leg][k] + u * (t.path[leg + 1][k] - t.path[leg][k]);
      }
      r.nodes.push_back(p);
    }
    if (t.fix_first) r.fixed.push_back({0, 7});
    if (t.fix_last) r.fixed.push_back({t.segments, 7});
    for (size_t ai = 0; ai < t.attach.size(); ++ai) {
      const ThreadSpec::Attach& a = t.attach[ai];
      const int32_t local = a.last ? t.segments : 0;
      const Vec3& p = r.nodes[size_t(local)];
      const std::string field = fmt::format("threads[{}].attach[{}]", ti, ai);
      if (a.needle) {  // the end must start at the tail: the tie would otherwise yank it there
        Vec3 tail, away;
        needle_tail(rigid_spec(spec, a.target), tail, away);
        const double d = std::sqrt((p[0] - tail[0]) * (p[0] - tail[0]) + (p[1] - tail[1]) * (p[1] - tail[1]) +
                                   (p[2] - tail[2]) * (p[2] - tail[2]));
        if (d > 0.5 * r.segment_length)
          throw InputError(a.where.file, a.where.line, field + ".needle",
                           fmt::format("the thread's {} end is at ({}, {}, {}), {} mm from needle '{}''s tail at ({}, "
                                       "{}, {}): it must start there (within half a segment, {} mm) — or omit start "
                                       "and direction to start the thread at the tail",
                                       a.last ? "last" : "first", yaml::format_number(p[0]), yaml::format_number(p[1]),
                                       yaml::format_number(p[2]), fmt::format("{:.3g}", 1e3 * d), a.target, yaml::format_number(tail[0]),
                                       yaml::format_number(tail[1]), yaml::format_number(tail[2]),
                                       yaml::format_number(500 * r.segment_length)));
        continue;
      }
      size_t bi = 0;
      int32_t off = 0;
      while (spec.bodies[bi].name != a.target) off += static_cast<int32_t>(meshes[bi++].mesh.nodes.size());
      const BarycentricPoint bp = locate_point(meshes[bi].mesh, p);
      if (bp.tet < 0 || bp.distance > r.segment_length)
        throw InputError(a.where.file, a.where.line, field + ".tissue",
                         fmt::format("the thread's {} end at ({}, {}, {}) is {} mm from tissue body '{}': an anchor "
                                     "must lie in the body or within one segment ({} mm) of it",
                                     a.last ? "last" : "first", yaml::format_number(p[0]), yaml::format_number(p[1]),
                                     yaml::format_number(p[2]), fmt::format("{:.3g}", 1e3 * bp.distance), a.target,
                                     yaml::format_number(1e3 * r.segment_length)));
      RodAnchor an;
      an.node = local;
      for (int k = 0; k < 4; ++k) {
        an.tissue[k] = bp.node[size_t(k)] + off;
        an.w[k] = bp.w[size_t(k)];
      }
      an.stiffness = rod_stretch_stiffness(t.young_modulus, t.diameter, r.segment_length);
      r.anchors.push_back(an);
    }
    out.push_back(std::move(r));
  }
  return out;
}

/// Threads' ends tied to needles' tails (Model::thread_ties, stiff as one of the thread's
/// segments), and no thread node inside a rigid body but the one at its needle's tail.
void compile_thread_ties(const ScenarioSpec& spec, Model& model) {
  size_t rod = 0;
  for (size_t ti = 0; ti < spec.threads.size(); ++ti, ++rod) {
    const ThreadSpec& t = spec.threads[ti];
    const RodRange& r = model.fem.rods[rod];
    std::vector<int32_t> tied_body(size_t(r.nodes()), -1);
    for (const ThreadSpec::Attach& a : t.attach) {
      if (!a.needle) continue;
      Model::ThreadTie tie;
      tie.node = a.last ? r.node_end - 1 : r.node_begin;
      for (size_t k = 0; k < spec.rigid_bodies.size(); ++k)
        if (spec.rigid_bodies[k].name == a.target) tie.body = static_cast<int32_t>(k);
      const RigidBodyModel& b = model.rigid_bodies[size_t(tie.body)];
      double c[3], tan[3];
      needle_curve(b.needle, 0.0, c, tan);
      for (int k = 0; k < 3; ++k) tie.arm[k] = b.shape_origin[k] + c[k];
      tie.stiffness = r.stretch_stiffness;
      tied_body[size_t(tie.node - r.node_begin)] = tie.body;
      model.thread_ties.push_back(tie);
      model.puncture_capacity = kThreadPunctures;
    }
    for (int32_t i = r.node_begin; i < r.node_end; ++i)
      for (size_t k = 0; k < model.rigid_bodies.size(); ++k) {
        if (tied_body[size_t(i - r.node_begin)] == static_cast<int32_t>(k)) continue;
        const RigidBodyModel& b = model.rigid_bodies[k];
        const std::array<double, 9> R = rotation_of(b.initial.q);
        const double* x = model.fem.rest.data() + 3 * i;
        const double d[3] = {x[0] - b.initial.x[0], x[1] - b.initial.x[1], x[2] - b.initial.x[2]};
        double pb[3], nrm[3];
        for (int a = 0; a < 3; ++a) pb[a] = R[size_t(a)] * d[0] + R[size_t(3 + a)] * d[1] + R[size_t(6 + a)] * d[2];
        const double dist = shape_distance(b, pb, nrm);
        if (dist < 0)
          throw InputError(t.where.file, t.where.line, fmt::format("threads[{}]", ti),
                           fmt::format("thread '{}' starts inside rigid body '{}': its node {} at ({}, {}, {}) is {} "
                                       "mm deep in it",
                                       t.name, b.name, i - r.node_begin, yaml::format_number(x[0]), yaml::format_number(x[1]),
                                       yaml::format_number(x[2]), fmt::format("{:.3g}", -1e3 * dist)));
      }
  }
}

/// A cutting blade needs ticks (a static run has no sweep between them) and, for now, the
/// tissue stepped every tick (a multirate haptic model would outlive the topology it came from).
void check_cutting(const ScenarioSpec& spec) {
  for (size_t ti = 0; ti < spec.tools.size(); ++ti) {
    const ToolEntry& t = spec.tools[ti];
    if (!t.spec.cuts) continue;
    const std::string field = fmt::format("tools[{}].cut", ti);
    if (spec.solver.integrator == Integrator::Static)
      throw InputError(t.where.file, t.where.line, field,
                       "a cutting blade needs a dynamic integrator (a static run has no ticks for the blade to sweep "
                       "between)");
    if (spec.solver.fem_every != 1)
      throw InputError(t.where.file, t.where.line, field,
                       fmt::format("cutting with solver.fem_every {} is not supported yet (use fem_every 1)",
                                   spec.solver.fem_every));
  }
}

}  // namespace

CompiledScenario compile_scenario(const ScenarioSpec& spec_in, const CompileOptions& options) {
  CompiledScenario out;
  out.spec = spec_in;
  if (options.converge) converge_solver(out.spec.solver);
  const ScenarioSpec& spec = out.spec;
  auto model = std::make_shared<Model>();
  model->name = spec.name;
  model->time_step = spec.time_step;
  const SolverSpec& s = spec.solver;
  check_multirate(spec);
  check_cutting(spec);
  model->fem_every = s.fem_every;
  model->fem_step = spec.time_step * s.fem_every;
  model->haptic_secant = s.haptic_secant;
  model->stepper = StepperSettings{s.integrator,   s.linear_solver, s.preconditioner.value_or(Preconditioner::Jacobi),
                                   s.max_iterations, s.tolerance,   s.warm_start,
                                   s.static_tolerance, s.static_max_newton,
                                   resolved_newton_iterations(s.newton_iterations, model->fem_step),
                                   s.newton_tolerance, s.preconditioner_refresh};
  model->stepper.stiffness_every = s.stiffness_every;
  model->time_budget = s.time_budget;

  const std::vector<PreparedMesh> meshes = load_meshes(spec, out.notes);
  // Prestretch (docs/TISSUE.md): the mesh is the body as it is; its rest shape is the mesh shrunk
  // by 1/s per axis about its centroid (an affine map: a point's barycentric weights, the visual
  // mesh's and the probes', are the same in both), and the state starts as the mesh.
  std::vector<PreparedMesh> rest_meshes = meshes;
  for (size_t bi = 0; bi < spec.bodies.size(); ++bi) {
    const Vec3& s = spec.bodies[bi].prestretch;
    if (s[0] == 1 && s[1] == 1 && s[2] == 1) continue;
    Vec3 c{0, 0, 0};
    for (const Vec3& p : meshes[bi].mesh.nodes)
      for (int k = 0; k < 3; ++k) c[k] += p[k] / static_cast<double>(meshes[bi].mesh.nodes.size());
    for (Vec3& p : rest_meshes[bi].mesh.nodes)
      for (int k = 0; k < 3; ++k) p[k] = c[k] + (p[k] - c[k]) / s[k];
  }
  try {
    // Locking-free node domains: matrix-free under CG, assembled (two-ring) for CHOLMOD.
    // Element patches are always assembled: their pattern grows little, and the warped
    // factor is then of the system itself (docs/PERFORMANCE.md, "F-bar-patch").
    bool patches = false;
    for (const BodySpec& b : spec.bodies)
      patches = patches || (b.material.locking_free && b.material.locking_free->patch_elements > 0);
    model->fem = build_fem_model(body_inputs(spec, meshes, rest_meshes), spec.gravity,
                                 spec.solver.linear_solver == LinearSolverKind::CG && !patches, thread_inputs(spec, meshes));
  } catch (const std::invalid_argument& e) {  // a mesh the locking-free smoothing cannot take
    const BodySpec* lf = nullptr;
    for (const BodySpec& b : spec.bodies)
      if (b.material.locking_free && !lf) lf = &b;
    if (!lf) throw;
    throw InputError(lf->material.locking_free->where.file, lf->material.locking_free->where.line,
                     "material.locking_free", e.what());
  }
  for (size_t bi = 0; bi < spec.bodies.size(); ++bi) {  // a prestretched body starts as its mesh
    const Vec3& s = spec.bodies[bi].prestretch;
    if (s[0] == 1 && s[1] == 1 && s[2] == 1) continue;
    if (model->initial_x.empty()) model->initial_x = model->fem.rest;
    // The mesh's nodes themselves (the FEM keeps each body's node order), not the rest shape
    // stretched back: that differs from the mesh by round-off.
    const std::vector<Vec3>& nodes = meshes[bi].mesh.nodes;
    const int32_t begin = model->fem.bodies[bi].node_begin;
    STROMA_DEMAND(static_cast<size_t>(model->fem.bodies[bi].node_end - begin) == nodes.size(),
                  "a body's FEM nodes are its mesh's, in order");
    for (size_t i = 0; i < nodes.size(); ++i)
      for (int k = 0; k < 3; ++k) model->initial_x[3 * (size_t(begin) + i) + size_t(k)] = nodes[i][k];
  }
  model->max_step_displacement = 0.5 * bounding_box(model->fem.rest.data(), model->fem.rest.size() / 3).diagonal();
  model->substep_on_cg_cap = resolved_substep_on_cg_cap(s.on_cg_cap, s.integrator, energy_guard_applies(model->fem));
  if (!s.preconditioner) {  // `auto`: trial steps of this scene decide (tissue/solver_choice.hpp)
    ChoiceOptions co;
    co.budgeted = options.budgeted || s.time_budget > 0;
    out.solver_choice = choose_preconditioner(model->fem, model->stepper, model->fem_step, co);
    model->stepper.preconditioner = out.solver_choice->preconditioner;
  }
  // `preconditioner_refresh: auto` resolved here (TimeStepper::prepare would resolve it the
  // same way), so the model, the log line and the reports say the period the ticks start from:
  // from the trial's warped iterations and, compiled for serve, the real-time step. The tick
  // then re-evaluates it from its own warped iterations (SolverHistory::pace_iterations).
  if (model->stepper.preconditioner == Preconditioner::WarpedCholesky && s.integrator == Integrator::ImplicitEuler &&
      s.linear_solver == LinearSolverKind::CG && model->stepper.preconditioner_refresh < 0) {
    const double entries = out.solver_choice && out.solver_choice->factor_entries > 0
                               ? out.solver_choice->factor_entries
                               : CholmodSolver(model->fem.pattern).factor_entries();
    // A refreshed factor is of the assembled system, which lacks matrix-free node domains.
    const double iterations = out.solver_choice ? warped_trial_iterations(*out.solver_choice) : kTypicalWarpedIterations;
    model->stepper.preconditioner_refresh = model->fem.smoothing.matrix_free && !model->fem.smoothing.empty()
                                                ? 0
                                                : auto_refresh_period(model->fem, entries, iterations,
                                                                      options.budgeted ? model->fem_step : 0.0);
    model->stepper.refresh_follows_pace = model->stepper.preconditioner_refresh > 0;
  }
  // A refresh period the scenario gave that nothing uses is said, not silently dropped.
  if (s.preconditioner_refresh > 0 && model->stepper.preconditioner != Preconditioner::WarpedCholesky)
    out.notes.push_back(fmt::format("solver.preconditioner_refresh has no effect: the preconditioner is {} ({})",
                                    preconditioner_name(model->stepper.preconditioner),
                                    s.preconditioner ? "scenario" : "chosen by the engine: set `preconditioner: "
                                                                    "warped_cholesky` to use the refresh"));
  out.visuals = compile_visuals(spec, meshes, *model, out.notes);
  compile_damage(spec, meshes, *model);
  model->body_tets.resize(meshes.size());
  for (size_t bi = 0; bi < meshes.size(); ++bi) {
    const int32_t off = model->fem.bodies[bi].node_begin;
    for (const Tet& t : meshes[bi].mesh.tets)
      model->body_tets[bi].push_back({t[0] + off, t[1] + off, t[2] + off, t[3] + off});
  }
  compile_probes(spec, meshes, *model);
  compile_tools(spec, *model, out.tool_scripts);
  compile_rigid_bodies(spec, *model);
  compile_thread_ties(spec, *model);
  if (spec.body_contact || !spec.threads.empty()) model->has_contact = true;  // threads touch (thread_contact.hpp)
  if (model->has_contact) compile_collision_faces(*model);
  if (model->has_needles) compile_needle_mesh(*model);  // the needles' walks (engine/needle_mesh.hpp)
  if (spec.body_contact) compile_body_contact(*spec.body_contact, spec, *model);
  if (std::any_of(model->tools.begin(), model->tools.end(), [](const ToolSpec& t) { return t.cuts; }))
    enable_cutting(*model);
#if STROMA_DEMANDS_ON
  std::string why;  // the model's documented invariants (engine/model_check.hpp)
  STROMA_DEMAND(model_invariants_hold(*model, &why), "compiled model: " + why);
#endif
  out.model = std::move(model);
  return out;
}

std::shared_ptr<const Model> compile_model(const ScenarioSpec& spec) { return compile_scenario(spec).model; }

Vec3 probe_position(const Model& m, const State& s, const ProbeModel& p) {
  Vec3 r{0, 0, 0};
  for (int k = 0; k < 4; ++k)
    for (int c = 0; c < 3; ++c) r[c] += p.where.w[k] * s.tissue.x[3 * p.where.node[k] + c];
  return r;
}

Vec3 probe_displacement(const Model& m, const State& s, const ProbeModel& p) {
  Vec3 r{0, 0, 0};
  for (int k = 0; k < 4; ++k)
    for (int c = 0; c < 3; ++c) {
      const int32_t d = 3 * p.where.node[k] + c;
      r[c] += p.where.w[k] * (s.tissue.x[d] - m.fem.rest[d]);
    }
  return r;
}

}  // namespace stroma
