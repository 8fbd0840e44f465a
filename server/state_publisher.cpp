#include "server/state_publisher.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <unordered_map>

#include "engine/cut_compile.hpp"
#include "haptics/tool_shape.hpp"
#include "tissue/fem_forces.hpp"

namespace stroma {

namespace {

template <class T>
void set_sequence(T& seq, const auto* data, size_t n) {
  seq._buffer = const_cast<std::remove_pointer_t<decltype(seq._buffer)>*>(data);
  seq._length = seq._maximum = static_cast<uint32_t>(n);
  seq._release = false;
}

}  // namespace

namespace {

/// Vertices of a surface being made, each a weighted sum of ≤ 4 DOFs, numbered in order of
/// first use by key.
struct VertexNumbering {
  PublishedSurface& s;
  std::unordered_map<int64_t, uint32_t> index;
  uint32_t add(int64_t key, const std::array<int32_t, 4>& dofs, const std::array<double, 4>& w) {
    const auto [it, fresh] = index.try_emplace(key, static_cast<uint32_t>(s.vertex_dofs.size()));
    if (fresh) {
      s.vertex_dofs.push_back(dofs);
      s.vertex_weights.push_back(w);
    }
    return it->second;
  }
};

/// The point of a cut topology's surface vertex as ≤ 4 weighted DOFs.
void cut_vertex_dofs(const CutVertex& p, std::array<int32_t, 4>& d, std::array<double, 4>& w) {
  d = {p.a, p.b, p.a, p.a};
  w = {1.0 - p.t, p.t, 0.0, 0.0};
}

bool copies_share_dof(const ElementCopy& a, const ElementCopy& b) {
  for (int32_t x : a.dof)
    for (int32_t y : b.dof)
      if (x == y) return true;
  return false;
}

bool tets_touch(const Tet& a, const Tet& b) {
  for (int32_t x : a)
    for (int32_t y : b)
      if (x == y) return true;
  return false;
}

/// A visual mesh on a cut model: each vertex re-mapped into the copy of its tetrahedron whose
/// material holds it (so it follows its side of the wound), and the triangles that span the cut
/// dropped — a triangle with two vertices in copies that share no DOF although their
/// tetrahedra touch: the cut runs between them. The wound's own faces fill the gap.
void remap_visual(const Model& m, const VisualModel& vis, PublishedSurface& s) {
  const CutTopology& topo = *m.topology;
  const CutSupport& cs = *m.cutting;
  const VisualMapping& map = vis.mapping;
  std::vector<int32_t> copy(map.size());
  for (size_t v = 0; v < map.size(); ++v) {
    const int32_t tet = map.tet[v];
    const Tet& t = cs.base.tets[tet];
    std::array<double, 4> bary{};
    int found = 0;
    for (int j = 0; j < 4; ++j)
      for (int i = 0; i < 4; ++i)
        if (map.node[v][i] == t[j]) {
          bary[j] = map.w[v][i];
          ++found;
          break;
        }
    const int32_t c = found == 4 ? copy_containing(topo, cs.base.tets, cs.uncut.rest, m.cut_edge_state, cs.base.adj, tet, bary)
                                 : topo.tet_copy_begin[tet];
    copy[v] = c;
    s.vertex_dofs.push_back(topo.copies[c].dof);
    s.vertex_weights.push_back(found == 4 ? bary : std::array<double, 4>{map.w[v][0], map.w[v][1], map.w[v][2], map.w[v][3]});
    if (found != 4) s.vertex_dofs.back() = map.node[v];  // (not expected: the mapping names its tet's nodes)
  }
  for (size_t i = 0; i + 2 < vis.triangles.size(); i += 3) {
    bool spans = false;
    for (int a = 0; a < 3 && !spans; ++a) {
      const uint32_t va = vis.triangles[i + a], vb = vis.triangles[i + (a + 1) % 3];
      const int32_t ca = copy[va], cb = copy[vb];
      spans = ca != cb && !copies_share_dof(topo.copies[ca], topo.copies[cb]) &&
              tets_touch(cs.base.tets[map.tet[va]], cs.base.tets[map.tet[vb]]);
    }
    if (!spans) s.triangles.insert(s.triangles.end(), {vis.triangles[i], vis.triangles[i + 1], vis.triangles[i + 2]});
  }
}

}  // namespace

SurfaceExtractor::SurfaceExtractor(const CompiledScenario& sc, const CutModelRegistry* cut_models)
    : sc_(sc), cut_models_(cut_models), model_(sc.model) {
  make_surfaces(*model_);
}

void SurfaceExtractor::make_surfaces(const Model& m) {
  const FemModel& fem = m.fem;
  const bool cut = m.topology_version > 0;
  surfaces_.clear();
  for (size_t b = 0; b < fem.bodies.size(); ++b) {
    const BodyRange& body = fem.bodies[b];
    PublishedSurface s;
    s.name = body.name;
    s.topology_version = static_cast<uint32_t>(m.topology_version);
    const VisualModel* vis = b < sc_.visuals.size() && sc_.visuals[b] ? &*sc_.visuals[b] : nullptr;
    VertexNumbering skin{s, {}};
    if (vis) {
      s.visual = true;
      if (cut) {
        remap_visual(m, *vis, s);
      } else {
        for (size_t v = 0; v < vis->mapping.size(); ++v) {
          s.vertex_dofs.push_back(vis->mapping.node[v]);
          s.vertex_weights.push_back(vis->mapping.w[v]);
        }
        s.triangles = vis->triangles;
      }
    } else if (!cut) {
      for (const Tri& t : body.boundary)
        for (int32_t n : t) s.triangles.push_back(skin.add(n, {n, n, n, n}, {1.0, 0.0, 0.0, 0.0}));
    } else {
      // The uncut part of the body's surface, over the cut topology's vertices.
      for (const CutTriangle& t : m.topology->triangles) {
        if (t.cut || t.copy < body.element_begin || t.copy >= body.element_end) continue;
        for (int32_t v : t.v) {
          std::array<int32_t, 4> d;
          std::array<double, 4> w;
          cut_vertex_dofs(m.topology->vertices[v], d, w);
          s.triangles.push_back(skin.add(v, d, w));
        }
      }
    }
    if (cut) {
      // The wound: the cut faces, over vertices of their own.
      s.cut_faces.assign(s.triangles.size() / 3, 0);
      VertexNumbering wound{s, {}};
      for (const CutTriangle& t : m.topology->triangles) {
        if (!t.cut || t.copy < body.element_begin || t.copy >= body.element_end) continue;
        for (int32_t v : t.v) {
          std::array<int32_t, 4> d;
          std::array<double, 4> w;
          cut_vertex_dofs(m.topology->vertices[v], d, w);
          s.triangles.push_back(wound.add(v, d, w));
        }
        s.cut_faces.push_back(1);
      }
    }
    const size_t nv = s.vertex_dofs.size();
    s.rest.resize(3 * nv);
    for (size_t v = 0; v < nv; ++v)
      for (int k = 0; k < 3; ++k) {
        double acc = 0;
        for (int i = 0; i < 4; ++i) acc += s.vertex_weights[v][i] * fem.rest[3 * s.vertex_dofs[v][i] + k];
        s.rest[3 * v + k] = static_cast<float>(acc);
      }
    s.positions.resize(3 * nv);
    s.scalar.resize(nv);
    if (m.has_damage) s.damage.resize(nv);
    surfaces_.push_back(std::move(s));
  }
  element_vm_.resize(fem.elements.size());
  node_vm_.resize(fem.num_nodes);
  node_damage_.resize(fem.num_nodes);
}

bool SurfaceExtractor::update(const StateFrame& f) {
  changed_ = false;
  if (f.cut_serial != model_->cut_serial) {
    std::shared_ptr<const Model> m = f.cut_serial == 0 ? sc_.model : cut_models_ ? cut_models_->find(f.cut_serial) : nullptr;
    if (!m || static_cast<size_t>(m->fem.num_nodes) != f.dofs) {
      ++skipped_;
      return false;
    }
    model_ = std::move(m);
    make_surfaces(*model_);
    changed_ = true;
  }
  const FemModel& fem = model_->fem;
  element_von_mises(fem, f.x.data(), element_vm_.data());
  // Nodal stress: the mean of its elements (smooth colours); nodal damage: the largest (a torn
  // element shows at every node it touches).
  const bool damage = f.elements > 0;
  for (int32_t n = 0; n < fem.num_nodes; ++n) {
    double acc = 0;
    float dmax = 0;
    for (int32_t j = fem.node_element_ptr[n]; j < fem.node_element_ptr[n + 1]; ++j) {
      acc += element_vm_[fem.node_element[j]];
      if (damage) dmax = std::max(dmax, f.damage[fem.node_element[j]]);
    }
    const int32_t cnt = fem.node_element_ptr[n + 1] - fem.node_element_ptr[n];
    node_vm_[n] = static_cast<float>(cnt ? acc / cnt : 0.0);
    node_damage_[n] = dmax;
  }
  for (PublishedSurface& s : surfaces_) {
    const size_t nv = s.vertex_dofs.size();
    for (size_t v = 0; v < nv; ++v) {
      const std::array<int32_t, 4>& d = s.vertex_dofs[v];
      const std::array<double, 4>& w = s.vertex_weights[v];
      double p[3] = {0, 0, 0};
      float vm = 0, dm = 0;
      for (int i = 0; i < 4; ++i) {
        if (w[i] == 0.0) continue;
        for (int k = 0; k < 3; ++k) p[k] += w[i] * f.x[3 * static_cast<size_t>(d[i]) + k];
        vm += static_cast<float>(w[i]) * node_vm_[d[i]];
        dm += static_cast<float>(w[i]) * node_damage_[d[i]];
      }
      for (int k = 0; k < 3; ++k) s.positions[3 * v + k] = static_cast<float>(p[k]);
      s.scalar[v] = vm;
      if (!s.damage.empty()) s.damage[v] = dm;
    }
  }
  return true;
}

stroma_TissueMesh tissue_mesh_message(const PublishedSurface& s, uint32_t b, uint64_t session) {
  stroma_TissueMesh msg{};
  std::snprintf(msg.body, sizeof(msg.body), "%s", s.name.c_str());
  msg.body_index = b;
  msg.visual = s.visual;
  msg.session = session;
  msg.topology_version = s.topology_version;
  set_sequence(msg.rest_positions, s.rest.data(), s.rest.size());
  set_sequence(msg.cut_faces, s.cut_faces.data(), s.cut_faces.size());
  set_sequence(msg.triangles, s.triangles.data(), s.triangles.size());
  return msg;
}

stroma_TissueState tissue_state_message(const PublishedSurface& s, const StateFrame& f, int64_t publish_ns,
                                        uint64_t session) {
  stroma_TissueState msg{};
  std::snprintf(msg.body, sizeof(msg.body), "%s", s.name.c_str());
  msg.frame = f.frame;
  msg.sim_time = f.sim_time;
  msg.publish_time_ns = publish_ns;
  msg.session = session;
  msg.topology_version = s.topology_version;
  set_sequence(msg.positions, s.positions.data(), s.positions.size());
  set_sequence(msg.scalar, s.scalar.data(), s.scalar.size());
  set_sequence(msg.damage, s.damage.data(), s.damage.size());
  return msg;
}

stroma_ToolState tool_state_message(const Model& m, int t, const StateFrame& f, std::vector<float>& capsules) {
  const ToolSpec& spec = m.tools[t];
  const ToolSnapshot& ts = f.tools[t];
  stroma_ToolState msg{};
  std::snprintf(msg.tool, sizeof(msg.tool), "%s", spec.name.c_str());
  msg.frame = f.frame;
  msg.sim_time = f.sim_time;
  msg.active = ts.active;
  msg.in_contact = ts.contacts > 0 || ts.grasped > 0;
  msg.grasped = static_cast<uint32_t>(ts.grasped);
  const Vec3& c = ts.center;
  for (int k = 0; k < 3; ++k) {
    msg.position[k] = c[k];
    msg.device_position[k] = ts.pose.position[k];
    msg.force[k] = ts.device_force[k];
  }
  for (int k = 0; k < 4; ++k) msg.orientation[k] = ts.pose.orientation[k];
  msg.jaw = ts.pose.jaw;
  capsules.clear();
  if (ts.commanded) {
    Capsule caps[kMaxCapsules];
    const int n = tool_capsules(spec, ts.pose, c.data(), caps);
    for (int i = 0; i < n; ++i)
      capsules.insert(capsules.end(), {float(caps[i].a[0]), float(caps[i].a[1]), float(caps[i].a[2]), float(caps[i].b[0]),
                                       float(caps[i].b[1]), float(caps[i].b[2]), float(caps[i].r)});
  }
  set_sequence(msg.capsules, capsules.data(), capsules.size());
  return msg;
}

stroma_RigidBody rigid_body_message(const Model& m, int k, uint64_t session, std::vector<float>& vertices,
                                    std::vector<uint32_t>& triangles) {
  const RigidBodyModel& b = m.rigid_bodies[size_t(k)];
  stroma_RigidBody msg{};
  std::snprintf(msg.body, sizeof(msg.body), "%s", b.name.c_str());
  msg.body_index = static_cast<uint32_t>(k);
  msg.session = session;
  static_assert(int(RigidShape::Needle) == int(stroma_SHAPE_NEEDLE) && int(RigidShape::Mesh) == int(stroma_SHAPE_MESH) &&
                int(RigidShape::Box) == int(stroma_SHAPE_BOX) && int(RigidShape::Capsule) == int(stroma_SHAPE_CAPSULE));
  msg.shape = static_cast<stroma_RigidShapeKind>(static_cast<int>(b.shape));
  msg.radius = b.radius;
  msg.length = b.shape == RigidShape::Needle ? b.needle.length : b.length;
  for (int c = 0; c < 3; ++c) msg.size[c] = b.size[size_t(c)];
  msg.wire_radius = b.needle.wire_radius;
  msg.curved = b.needle.curved;
  msg.arc_radius = b.needle.curved ? b.needle.arc_radius : 0.0;
  msg.angle = b.needle.curved ? b.needle.angle : 0.0;
  msg.is_fixed = b.fixed;
  msg.mass = b.fixed ? 0.0 : b.mass.mass;
  vertices.clear();
  triangles.clear();
  for (const Vec3& v : b.surface_vertices)  // body frame → shape frame
    for (int c = 0; c < 3; ++c) vertices.push_back(static_cast<float>(v[size_t(c)] - b.shape_origin[size_t(c)]));
  for (const Tri& t : b.surface_triangles)
    for (const int32_t i : t) triangles.push_back(static_cast<uint32_t>(i));
  set_sequence(msg.vertices, vertices.data(), vertices.size());
  set_sequence(msg.triangles, triangles.data(), triangles.size());
  return msg;
}

stroma_ThreadState thread_state_message(const Model& m, int k, const StateFrame& f, uint64_t session,
                                        std::vector<float>& positions, std::vector<float>& punctures) {
  const RodRange& r = m.fem.rods[size_t(k)];
  stroma_ThreadState msg{};
  std::snprintf(msg.thread, sizeof(msg.thread), "%s", r.name.c_str());
  msg.thread_index = static_cast<uint32_t>(k);
  msg.frame = f.frame;
  msg.sim_time = f.sim_time;
  msg.session = session;
  msg.diameter = r.diameter;
  msg.rest_length = r.segment_length * r.segments();
  positions.clear();
  // m is the scenario's model; f may be of a cut one, whose tissue has more DOFs — the rods'
  // nodes are the last DOFs of every model of a scenario, in the same order (engine/thread_cut.hpp).
  const int64_t shift = static_cast<int64_t>(f.dofs) - m.fem.num_nodes;
  if (shift >= 0) {
    const int32_t begin = r.node_begin + static_cast<int32_t>(shift), end = r.node_end + static_cast<int32_t>(shift);
    for (int32_t i = begin; i < end; ++i)
      for (int c = 0; c < 3; ++c) positions.push_back(static_cast<float>(f.x[3 * size_t(i) + size_t(c)]));
    for (int32_t i = begin; i + 1 < end; ++i) {
      const double* a = f.x.data() + 3 * i;
      const double len = std::sqrt((a[3] - a[0]) * (a[3] - a[0]) + (a[4] - a[1]) * (a[4] - a[1]) + (a[5] - a[2]) * (a[5] - a[2]));
      msg.length += len;
      msg.max_tension = std::max(msg.max_tension, r.stretch_stiffness * (len - r.segment_length));
    }
  }
  set_sequence(msg.positions, positions.data(), positions.size());
  punctures.clear();
  for (int32_t i = 0; i < f.puncture_count; ++i) {
    const RodPuncture& p = f.punctures[size_t(i)];
    if (p.rod != k) continue;
    float q[4] = {0, 0, 0, static_cast<float>(p.sigma)};
    for (int a = 0; a < 4; ++a) {
      const size_t n = static_cast<size_t>(p.node[a]);
      if (n >= f.dofs) continue;  // (its nodes are the frame's model's: never)
      for (int c = 0; c < 3; ++c) q[c] += static_cast<float>(p.w[a] * f.x[3 * n + size_t(c)]);
    }
    punctures.insert(punctures.end(), q, q + 4);
  }
  set_sequence(msg.punctures, punctures.data(), punctures.size());
  return msg;
}

stroma_RigidBodyState rigid_body_state_message(const Model& m, int k, const StateFrame& f, uint64_t session,
                                               std::vector<float>& track) {
  const RigidBodyModel& b = m.rigid_bodies[size_t(k)];
  const RigidSnapshot& r = f.rigid[size_t(k)];
  stroma_RigidBodyState msg{};
  std::snprintf(msg.body, sizeof(msg.body), "%s", b.name.c_str());
  msg.frame = f.frame;
  msg.sim_time = f.sim_time;
  msg.session = session;
  const std::array<double, 9> R = rotation_of(r.state.q);
  for (int i = 0; i < 3; ++i) {  // the shape frame's origin: the centre of mass + R·shape_origin
    msg.position[i] = r.state.x[size_t(i)];
    for (int j = 0; j < 3; ++j) msg.position[i] += R[size_t(3 * i + j)] * b.shape_origin[size_t(j)];
    msg.linear_velocity[i] = r.state.v[size_t(i)];
    msg.angular_velocity[i] = r.state.w[size_t(i)];
    msg.contact_force[i] = r.contact_force[size_t(i)];
  }
  for (int i = 0; i < 4; ++i) msg.orientation[i] = r.state.q[size_t(i)];
  for (int t = 0; t < f.tool_count; ++t)
    if (f.tools[size_t(t)].holding_body == k) std::snprintf(msg.held_by, sizeof(msg.held_by), "%s", m.tools[size_t(t)].name.c_str());
  msg.contacts = static_cast<uint32_t>(std::max(r.contacts, 0));
  static_assert(int(NeedlePhase::Inserted) == int(stroma_NEEDLE_INSERTED) && int(NeedlePhase::Exited) == int(stroma_NEEDLE_EXITED));
  msg.needle_phase = static_cast<stroma_NeedlePhase>(static_cast<int>(r.phase));
  if (r.tissue_body >= 0 && size_t(r.tissue_body) < m.fem.bodies.size())
    std::snprintf(msg.tissue, sizeof(msg.tissue), "%s", m.fem.bodies[size_t(r.tissue_body)].name.c_str());
  msg.punctures = static_cast<uint32_t>(std::max(r.punctures, 0));
  msg.inserted_length = r.inserted_length;
  msg.tip_force = r.tip_force;
  msg.friction_force = r.friction_force;
  track.clear();
  const size_t dofs = f.dofs;
  for (int32_t i = 0; i < r.track_count; ++i) {  // material points on the frame's positions
    const TrackPoint& p = f.track[size_t(r.track_begin + i)];
    float q[3] = {0, 0, 0};
    for (int a = 0; a < 4; ++a) {
      const size_t n = static_cast<size_t>(p.node[size_t(a)]);
      if (n >= dofs) continue;  // (a track of another model: never, cutting refuses needles)
      for (int c = 0; c < 3; ++c) q[c] += static_cast<float>(p.w[a] * f.x[3 * n + size_t(c)]);
    }
    track.insert(track.end(), q, q + 3);
  }
  set_sequence(msg.track, track.data(), track.size());
  return msg;
}

stroma_Scene scene_message(const CompiledScenario& sc, uint64_t session) {
  const RenderSpec& r = sc.spec.render;
  stroma_Scene msg{};
  std::snprintf(msg.scenario, sizeof(msg.scenario), "%s", sc.spec.name.c_str());
  msg.session = session;
  msg.has_camera = r.has_camera;
  Vec3 up{0, 1, 0};
  const Vec3& g = sc.spec.gravity;
  const double gn = std::sqrt(g[0] * g[0] + g[1] * g[1] + g[2] * g[2]);
  if (r.camera_up) up = *r.camera_up;
  else if (gn > 0) up = {-g[0] / gn, -g[1] / gn, -g[2] / gn};
  for (int k = 0; k < 3; ++k) {
    msg.camera_position[k] = r.camera_position[k];
    msg.camera_target[k] = r.camera_target[k];
    msg.camera_up[k] = up[k];
    msg.view_direction[k] = r.view_direction[k];
    msg.light_direction[k] = r.light_direction[k];
    msg.tissue_color[k] = static_cast<float>(r.tissue_color[k]);
    msg.background_color[k] = static_cast<float>(r.background_color[k]);
  }
  msg.fov_deg = r.fov_deg;
  msg.color_field = r.color_field == ColorFieldSpec::None     ? stroma_COLOR_NONE
                    : r.color_field == ColorFieldSpec::Stress ? stroma_COLOR_STRESS
                                                              : stroma_COLOR_DAMAGE;
  msg.color_min = r.color_min;
  msg.color_max = r.color_max;
  msg.wireframe = r.wireframe;
  msg.contacts = r.contacts;
  return msg;
}

}  // namespace stroma
