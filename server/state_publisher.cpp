#include "server/state_publisher.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

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

SurfaceExtractor::SurfaceExtractor(const CompiledScenario& sc) : m_(*sc.model) {
  const Model& m = *sc.model;
  const FemModel& fem = m.fem;
  for (size_t b = 0; b < fem.bodies.size(); ++b) {
    const BodyRange& body = fem.bodies[b];
    PublishedSurface s;
    s.name = body.name;
    if (b < sc.visuals.size() && sc.visuals[b]) {
      const VisualModel& v = *sc.visuals[b];
      s.visual = true;
      s.mapping = &v.mapping;
      for (const Vec3& p : v.rest) s.rest.insert(s.rest.end(), {float(p[0]), float(p[1]), float(p[2])});
      s.triangles = v.triangles;
    } else {
      std::vector<int32_t> local(fem.num_nodes, -1);
      for (const Tri& t : body.boundary)
        for (int32_t n : t) {
          if (local[n] < 0) {
            local[n] = static_cast<int32_t>(s.nodes.size());
            s.nodes.push_back(n);
          }
          s.triangles.push_back(static_cast<uint32_t>(local[n]));
        }
      for (int32_t n : s.nodes)
        for (int k = 0; k < 3; ++k) s.rest.push_back(static_cast<float>(fem.rest[3 * n + k]));
    }
    const size_t nv = s.rest.size() / 3;
    s.positions.resize(3 * nv);
    s.scalar.resize(nv);
    if (m.has_damage) s.damage.resize(nv);
    surfaces_.push_back(std::move(s));
  }
  element_vm_.resize(fem.elements.size());
  node_vm_.resize(fem.num_nodes);
  node_damage_.resize(fem.num_nodes);
}

void SurfaceExtractor::update(const StateFrame& f) {
  const FemModel& fem = m_.fem;
  element_von_mises(fem, f.x.data(), element_vm_.data());
  // Nodal stress: the mean of its elements (smooth colours); nodal damage: the largest (a torn
  // element shows at every node it touches).
  for (int32_t n = 0; n < fem.num_nodes; ++n) {
    double acc = 0;
    float dmax = 0;
    for (int32_t j = fem.node_element_ptr[n]; j < fem.node_element_ptr[n + 1]; ++j) {
      acc += element_vm_[fem.node_element[j]];
      if (!f.damage.empty()) dmax = std::max(dmax, f.damage[fem.node_element[j]]);
    }
    const int32_t cnt = fem.node_element_ptr[n + 1] - fem.node_element_ptr[n];
    node_vm_[n] = static_cast<float>(cnt ? acc / cnt : 0.0);
    node_damage_[n] = dmax;
  }
  for (PublishedSurface& s : surfaces_) {
    if (s.visual) {
      const VisualMapping& map = *s.mapping;
      map.apply(f.x.data(), s.positions.data());
      for (size_t v = 0; v < map.size(); ++v) {
        float vm = 0, d = 0;
        for (int k = 0; k < 4; ++k) {
          const float w = static_cast<float>(map.w[v][k]);
          vm += w * node_vm_[map.node[v][k]];
          d += w * node_damage_[map.node[v][k]];
        }
        s.scalar[v] = vm;
        if (!s.damage.empty()) s.damage[v] = d;
      }
    } else {
      for (size_t i = 0; i < s.nodes.size(); ++i) {
        const int32_t n = s.nodes[i];
        for (int k = 0; k < 3; ++k) s.positions[3 * i + k] = static_cast<float>(f.x[3 * n + k]);
        s.scalar[i] = node_vm_[n];
        if (!s.damage.empty()) s.damage[i] = node_damage_[n];
      }
    }
  }
}

stroma_TissueMesh tissue_mesh_message(const PublishedSurface& s, uint32_t b, uint64_t session) {
  stroma_TissueMesh msg{};
  std::snprintf(msg.body, sizeof(msg.body), "%s", s.name.c_str());
  msg.body_index = b;
  msg.visual = s.visual;
  msg.session = session;
  set_sequence(msg.rest_positions, s.rest.data(), s.rest.size());
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
