#include "engine/cut_swap.hpp"

#include <algorithm>
#include <chrono>

#include "collision/contact_surface.hpp"
#include "engine/cut_compile.hpp"
#include "engine/damage.hpp"
#include "engine/needle_mesh.hpp"
#include "engine/thread_cut.hpp"
#include "tissue/triangle_closest_point.hpp"

namespace stroma {

namespace {

/// The world position of tool k's grasped point i on model m's surface at DOF positions x (the
/// surface point itself: an embedded vertex is its lerp, not the DOF its force acts on).
Vec3 grasped_point(const Model& m, const ToolState& ts, int i, const double* x) {
  const double u = ts.grasp_uv[i][0], v = ts.grasp_uv[i][1];
  const double b[3] = {1.0 - u - v, u, v};
  const auto& tri = m.collision_triangles[ts.grasp_triangle[i]];
  Vec3 p{0, 0, 0};
  for (int c = 0; c < 3; ++c) {
    const int32_t q = tri[c];
    for (int k = 0; k < 3; ++k) {
      double pk;
      if (q < m.fem.num_nodes) {
        pk = x[3 * q + k];
      } else {
        const CutVertex& cv = m.collision_embedded[q - m.fem.num_nodes];
        pk = (1.0 - cv.t) * x[3 * cv.a + k] + cv.t * x[3 * cv.b + k];
      }
      p[k] += b[c] * pk;
    }
  }
  return p;
}

/// The tools' part of a state carried to the cut model m: each tool's state as it was, its
/// grasped points re-attached to the closest point of the new surface within its radius
/// (dropping, in order, those with none) — the same material, now on the cut model. `s` is
/// the new state with its tissue already carried over (the surface is refitted to it).
void transfer_tools(const Model& old_m, const State& old_s, const Model& m, TickWorkspace& w, State& s) {
  std::copy(old_s.tools.begin(), old_s.tools.end(), s.tools.begin());
  const double* old_x = old_s.tissue.x.data();
  std::vector<ToolState>& tools = s.tools;
  bool any = false;
  for (const ToolState& ts : tools) any = any || ts.grasped > 0;
  if (!any || !m.has_contact) return;
  const double* px = s.tissue.x.data();
  if (!m.collision_embedded.empty()) {
    surface_positions(px, m.fem.num_nodes, m.collision_embedded, w.surface_x.data());
    px = w.surface_x.data();
  }
  w.bvh.refit(px);
  for (size_t k = 0; k < tools.size(); ++k) {
    ToolState& ts = tools[k];
    int kept = 0;
    for (int i = 0; i < ts.grasped; ++i) {
      const Vec3 p = grasped_point(old_m, ts, i, old_x);
      const double r = std::max(m.tools[k].radius, 1e-9);
      int32_t best = -1;
      double best_d2 = r * r;
      std::array<double, 3> best_w{};
      w.bvh.query_sphere(p.data(), r, px, [&](int32_t t) {
        const auto& tri = m.collision_triangles[t];
        auto pt = [&](int c) { return Vec3{px[3 * tri[c]], px[3 * tri[c] + 1], px[3 * tri[c] + 2]}; };
        const Vec3 A = pt(0), B = pt(1), C = pt(2);
        const auto wt = closest_on_triangle(p, A, B, C);
        double d2 = 0;
        for (int c = 0; c < 3; ++c) {
          const double d = p[c] - (wt[0] * A[c] + wt[1] * B[c] + wt[2] * C[c]);
          d2 += d * d;
        }
        if (d2 <= best_d2) best = t, best_d2 = d2, best_w = wt;
      });
      if (best < 0) continue;
      ts.grasp_triangle[kept] = best;
      ts.grasp_uv[kept] = {best_w[1], best_w[2]};
      ts.grasp_offset[kept] = ts.grasp_offset[i];
      ++kept;
    }
    ts.grasped = kept;
  }
}

}  // namespace

CutBuild build_cut(const Model& current, const std::vector<double>& edge_cut) {
  const auto t0 = std::chrono::steady_clock::now();
  CutBuild b;
  b.base_version = current.topology_version;
  const CutSupport& cs = *current.cutting;
  auto topo = std::make_shared<const CutTopology>(
      build_cut_topology(cs.base.tets, cs.uncut.rest, cs.base.adj, edge_cut, cs.base.node_ranges, cs.internal_faces));
  const CutTopology& old = *current.topology;
  b.changed = topo->copies.size() != old.copies.size() || topo->num_dofs != old.num_dofs;
  if (b.changed) {
    b.from_dof = continued_dofs(old, *topo);
    b.from_element = continued_copies(old, *topo);
    std::shared_ptr<const Model> m = compile_cut_model(current, topo, edge_cut, current.topology_version + 1);
    b.workspace = std::make_unique<TickWorkspace>(*m);
    b.state = State::initial(*m);
    b.model = std::move(m);
  }
  b.build_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  return b;
}

bool apply_cut(CutBuild& b, std::shared_ptr<const Model>& m, std::unique_ptr<TickWorkspace>& w, State& s) {
  if (!b.changed || !b.model || b.base_version != m->topology_version) return false;
  const Model& nm = *b.model;
  State& ns = b.state;
  // Each part of the state that follows the topology, through its own transfer.
  transfer_state(s.tissue, b.from_dof, ns.tissue);                      // tissue: x, v, warm start
  transfer_visco_state(m->fem, s.tissue, nm.fem, b.from_element, ns.tissue);  // visco-elastic
  if (nm.has_damage) transfer_damage(s, b.from_dof, b.from_element, nm, ns);  // damage, masses, faces
  transfer_tools(*m, s, nm, *b.workspace, ns);                          // tools, grasps re-attached
  if (!nm.fem.rods.empty()) transfer_threads(*m, s, nm, ns);            // threads' punctures and grasps
  std::copy(s.edge_cut.begin(), s.edge_cut.end(), ns.edge_cut.begin());
  std::copy(s.rigid.begin(), s.rigid.end(), ns.rigid.begin());          // rigid bodies: no topology
  if (nm.has_needles) transfer_needles(*m, s.needles, nm, ns.needles);  // track points to their copies
  ns.time = s.time;
  ns.step = s.step;
  std::swap(s, ns);
  std::swap(m, b.model);
  std::swap(w, b.workspace);
  return true;
}

}  // namespace stroma
