#include "engine/rigid_grasp.hpp"

#include <algorithm>
#include <cmath>

#include "haptics/tool_shape.hpp"
#include "rigid/rigid_contact.hpp"

namespace stroma {

void grasp_centre(const ToolSpec& spec, const ToolState& ts, const double* R, double* gc, double* reach) {
  const Vec3& c = tool_center(spec, ts);
  *reach = spec.grasp_reach * spec.radius;
  for (int k = 0; k < 3; ++k) gc[k] = c[size_t(k)];
  if (spec.shape == ToolShape::Grasper) {
    for (int k = 0; k < 3; ++k) gc[k] += 0.5 * spec.shaft_length * R[3 * k + 2];
    *reach += 0.5 * spec.shaft_length;
  }
}

double hold_lever(const ToolSpec& spec) { return std::max(spec.radius, 1e-3); }

void update_rigid_grasps(const Model& m, State& s) {
  if (m.rigid_bodies.empty()) return;
  for (size_t t = 0; t < m.tools.size(); ++t) {
    const ToolSpec& spec = m.tools[t];
    ToolState& ts = s.tools[t];
    if (!spec.can_grasp) continue;
    const bool closed_now = ts.pose.jaw < spec.grasp_close, open_now = ts.pose.jaw > spec.grasp_open;
    if (!ts.active || ts.last_command_time < 0 || open_now) {
      // Letting go of a needle with a thread tied to it: the thread at its tail is still
      // between the jaws (engine/thread_contact.hpp, ToolState::released_segment).
      for (const Model::ThreadTie& tie : m.thread_ties)
        if (ts.grasped_body >= 0 && tie.body == ts.grasped_body) ts.released_segment = tie.node;
      ts.grasped_body = -1;  // (tool_contact resets jaw_closed and any tissue grasp)
      continue;
    }
    if (!closed_now || ts.jaw_closed) continue;
    double R[9], gc[3], reach;
    quaternion_to_matrix(ts.pose.orientation, R);
    grasp_centre(spec, ts, R, gc, &reach);
    int32_t best = -1;
    double best_d = reach;
    for (size_t k = 0; k < m.rigid_bodies.size(); ++k) {
      const RigidBodyModel& b = m.rigid_bodies[k];
      if (b.fixed) continue;
      const RigidState& rs = s.rigid[k];
      const std::array<double, 9> Rb = rotation_of(rs.q);
      const double d[3] = {gc[0] - rs.x[0], gc[1] - rs.x[1], gc[2] - rs.x[2]};
      double pb[3], nrm[3];
      for (int i = 0; i < 3; ++i) pb[i] = Rb[size_t(i)] * d[0] + Rb[size_t(3 + i)] * d[1] + Rb[size_t(6 + i)] * d[2];
      const double dist = shape_distance(b, pb, nrm);
      if (dist <= best_d) best_d = dist, best = static_cast<int32_t>(k);
    }
    if (best < 0) continue;
    // Held: the jaws are closed on the body, not on tissue.
    ts.jaw_closed = true;
    ts.grasped = 0;
    ts.grasped_body = best;
    const RigidState& rs = s.rigid[size_t(best)];
    const std::array<double, 9> Rb = rotation_of(rs.q);
    const Vec3& c = tool_center(spec, ts);
    const double l = hold_lever(spec);
    for (int i = 0; i < 3; ++i) {
      double p[3];  // the grasp centre, and a lever along the tool's x and y axes
      for (int k = 0; k < 3; ++k) p[k] = gc[k] + (i == 0 ? 0.0 : l * R[3 * k + (i - 1)]);
      const double d[3] = {p[0] - rs.x[0], p[1] - rs.x[1], p[2] - rs.x[2]};
      const double e[3] = {p[0] - c[0], p[1] - c[1], p[2] - c[2]};
      for (int k = 0; k < 3; ++k) {
        ts.body_hold_point[size_t(i)][size_t(k)] = Rb[size_t(k)] * d[0] + Rb[size_t(3 + k)] * d[1] + Rb[size_t(6 + k)] * d[2];
        ts.tool_hold_point[size_t(i)][size_t(k)] = R[k] * e[0] + R[3 + k] * e[1] + R[6 + k] * e[2];
      }
    }
  }
}

int rigid_grasp_springs(const ToolSpec& spec, const ToolState& ts, const RigidState& body, int32_t row,
                        std::vector<ContactSpring>& springs) {
  double R[9];
  quaternion_to_matrix(ts.pose.orientation, R);
  const std::array<double, 9> Rb = rotation_of(body.q);
  const Vec3& c = tool_center(spec, ts);
  const double k = spec.grasp_stiffness;
  int made = 0;
  for (int i = 0; i < 3; ++i) {
    if (springs.size() == springs.capacity()) break;
    const Vec3& o = ts.tool_hold_point[size_t(i)];
    const Vec3& b = ts.body_hold_point[size_t(i)];
    ContactSpring sp;
    sp.n = 0;
    sp.row_p = row;
    for (int a = 0; a < 3; ++a) {
      const double anchor = c[size_t(a)] + R[3 * a] * o[0] + R[3 * a + 1] * o[1] + R[3 * a + 2] * o[2];
      sp.arm_p[a] = Rb[size_t(3 * a)] * b[0] + Rb[size_t(3 * a + 1)] * b[1] + Rb[size_t(3 * a + 2)] * b[2];
      sp.force[a] = k * (anchor - (body.x[size_t(a)] + sp.arm_p[a]));  // on the body, towards the anchor
      sp.K[4 * a] = k;
    }
    springs.push_back(sp);
    ++made;
  }
  return made;
}

void rigid_grasp_feedback(const ContactSpring* springs, int begin, int end, const RigidState& start,
                          const RigidState& end_state, const Vec3& tool_centre, ToolOutput& out) {
  for (int i = begin; i < end; ++i) {
    const ContactSpring& sp = springs[i];
    double disp[3], now[3], f[3];
    body_point_displacement(start, end_state, sp.arm_p, disp);
    for (int k = 0; k < 3; ++k) {
      now[k] = sp.arm_p[k] + disp[k] - (end_state.x[size_t(k)] - start.x[size_t(k)]);  // the arm at the end
      f[k] = sp.force[k] - sp.K[4 * k] * disp[k];  // on the body at the step's end
    }
    for (int k = 0; k < 3; ++k) {
      out.force[size_t(k)] -= f[k];
      out.stiffness[size_t(4 * k)] -= sp.K[4 * k];
    }
    const double r[3] = {end_state.x[0] + now[0] - tool_centre[0], end_state.x[1] + now[1] - tool_centre[1],
                         end_state.x[2] + now[2] - tool_centre[2]};
    out.torque[0] -= r[1] * f[2] - r[2] * f[1];
    out.torque[1] -= r[2] * f[0] - r[0] * f[2];
    out.torque[2] -= r[0] * f[1] - r[1] * f[0];
  }
}

}  // namespace stroma
