#include "engine/thread_attach.hpp"

#include <algorithm>

#include "engine/rigid_grasp.hpp"
#include "haptics/tool_shape.hpp"

namespace stroma {

namespace {

/// The parameter (0..1) of the point of segment a–b nearest to p.
double nearest_on_segment(const double* a, const double* b, const double* p) {
  double ab2 = 0, t = 0;
  for (int k = 0; k < 3; ++k) {
    ab2 += (b[k] - a[k]) * (b[k] - a[k]);
    t += (p[k] - a[k]) * (b[k] - a[k]);
  }
  return ab2 > 0 ? std::clamp(t / ab2, 0.0, 1.0) : 0.0;
}

}  // namespace

void update_thread_grasps(const Model& m, State& s) {
  if (m.fem.rods.empty()) return;
  const double* x = s.tissue.x.data();
  for (size_t t = 0; t < m.tools.size(); ++t) {
    const ToolSpec& spec = m.tools[t];
    ToolState& ts = s.tools[t];
    if (!spec.can_grasp) continue;
    const bool closed_now = ts.pose.jaw < spec.grasp_close, open_now = ts.pose.jaw > spec.grasp_open;
    if (!ts.active || ts.last_command_time < 0 || open_now) {
      ts.grasped_segment = -1;  // (tool_contact resets jaw_closed)
      continue;
    }
    if (!closed_now || ts.jaw_closed) continue;  // no closing transition (or a body took it)
    double R[9], gc[3], reach;
    quaternion_to_matrix(ts.pose.orientation, R);
    grasp_centre(spec, ts, R, gc, &reach);
    int32_t best = -1;
    double best_d2 = reach * reach, best_s = 0;
    for (const RodRange& r : m.fem.rods)
      for (int32_t i = r.node_begin; i + 1 < r.node_end; ++i) {
        const double* a = x + 3 * i;
        const double* b = a + 3;
        const double u = nearest_on_segment(a, b, gc);
        double d2 = 0;
        for (int k = 0; k < 3; ++k) {
          const double q = a[k] + u * (b[k] - a[k]) - gc[k];
          d2 += q * q;
        }
        if (d2 <= best_d2) best_d2 = d2, best = i, best_s = u;
      }
    if (best < 0) continue;
    ts.jaw_closed = true;  // on the thread, not on tissue
    ts.grasped = 0;
    ts.grasped_segment = best;
    ts.grasp_segment_s = best_s;
    const Vec3& c = tool_center(spec, ts);
    double e[3];
    for (int k = 0; k < 3; ++k) e[k] = x[3 * best + k] + best_s * (x[3 * best + 3 + k] - x[3 * best + k]) - c[size_t(k)];
    for (int k = 0; k < 3; ++k) ts.grasp_segment_offset[size_t(k)] = R[k] * e[0] + R[3 + k] * e[1] + R[6 + k] * e[2];
  }
}

int thread_grasp_springs(const Model& m, const ToolSpec& spec, const ToolState& ts, const double* x, ToolOutput& out,
                         std::vector<ContactSpring>& springs) {
  if (ts.grasped_segment < 0) return 0;
  if (springs.size() == springs.capacity()) {
    ++out.contacts_dropped;
    return 0;
  }
  double R[9];
  quaternion_to_matrix(ts.pose.orientation, R);
  const Vec3& c = tool_center(spec, ts);
  const Vec3& o = ts.grasp_segment_offset;
  const int32_t i = ts.grasped_segment;
  const double u = ts.grasp_segment_s, k = spec.grasp_stiffness;
  ContactSpring sp;
  sp.n = 2;
  sp.node[0] = i;
  sp.node[1] = i + 1;
  sp.w[0] = 1.0 - u;
  sp.w[1] = u;
  for (int& sl : sp.slot) sl = -1;
  sp.slot[0] = m.fem.pattern.diag[i];
  sp.slot[1] = m.fem.pattern.find(i, i + 1);
  sp.slot[4 + 1] = m.fem.pattern.diag[i + 1];
  for (int a = 0; a < 3; ++a) {
    const double target = c[size_t(a)] + R[3 * a] * o[0] + R[3 * a + 1] * o[1] + R[3 * a + 2] * o[2];
    const double p = (1.0 - u) * x[3 * i + a] + u * x[3 * i + 3 + a];
    sp.force[a] = k * (target - p);  // on the thread, towards the jaws
    sp.K[4 * a] = k;
    out.stiffness[size_t(4 * a)] -= k;
  }
  springs.push_back(sp);
  ++out.contacts;
  out.spring_end = static_cast<int32_t>(springs.size());
  return 1;
}

int thread_tie_spring(const Model::ThreadTie& tie, const RigidState& body, int32_t row, const double* x,
                      const BsrPattern& pattern, std::vector<ContactSpring>& springs) {
  if (springs.size() == springs.capacity()) return 0;
  const std::array<double, 9> R = rotation_of(body.q);
  ContactSpring sp;
  sp.n = 1;
  sp.node[0] = tie.node;
  sp.w[0] = 1.0;
  for (int& sl : sp.slot) sl = -1;
  sp.slot[0] = pattern.diag[tie.node];
  sp.row_n = row;
  for (int a = 0; a < 3; ++a) {
    const double arm = R[size_t(3 * a)] * tie.arm[0] + R[size_t(3 * a + 1)] * tie.arm[1] + R[size_t(3 * a + 2)] * tie.arm[2];
    if (row >= 0) sp.arm_n[a] = arm;
    sp.force[a] = tie.stiffness * (body.x[size_t(a)] + arm - x[3 * tie.node + a]);  // on the thread, to the tail
    sp.K[4 * a] = tie.stiffness;
  }
  springs.push_back(sp);
  return 1;
}

}  // namespace stroma
