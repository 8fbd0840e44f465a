#include "haptics/feedback.hpp"

#include <cmath>

#include "tissue/mat3.hpp"

namespace stroma {

void tool_force_after_step(const ContactSpring* springs, const double* x0, const double* x, const double* v,
                           const Vec3& center, ToolOutput& out) {
  out.force = {0, 0, 0};
  out.torque = {0, 0, 0};
  for (int32_t i = out.spring_begin; i < out.spring_end; ++i) {
    const ContactSpring& sp = springs[i];
    double f[3], q[3];
    spring_force_after_step(sp, x0, x, v, f);
    spring_point(sp, x, q);
    const double r[3] = {q[0] - center[0], q[1] - center[1], q[2] - center[2]};
    // The tool feels the opposite of the force on the tissue, at the contact point.
    for (int k = 0; k < 3; ++k) out.force[k] -= f[k];
    out.torque[0] -= r[1] * f[2] - r[2] * f[1];
    out.torque[1] -= r[2] * f[0] - r[0] * f[2];
    out.torque[2] -= r[0] * f[1] - r[1] * f[0];
  }
}

ToolFeedback device_feedback(const ToolSpec& spec, ToolState& ts, const ToolOutput& out, double dt) {
  ToolFeedback fb;
  const double kv = spec.coupling_stiffness;
  if (kv > 0 && ts.has_proxy) {
    // Series stiffness of coupling and contact: dF/d(device) = −kv·Kc·(Kc + kv I)⁻¹ with
    // Kc = −dF_contact/dx.
    double Kc[9], A[9], Ai[9], KA[9];
    for (int i = 0; i < 9; ++i) {
      Kc[i] = -out.stiffness[i];
      A[i] = Kc[i] + (i % 4 == 0 ? kv : 0.0);
    }
    m3::inverse(A, Ai);
    m3::mul(Kc, Ai, KA);
    // Spring–damper between proxy and device; the damper acts on the stretch rate (per tick).
    double stretch[3];
    for (int i = 0; i < 3; ++i) {
      stretch[i] = ts.proxy[i] - ts.pose.position[i];
      fb.force[i] = kv * stretch[i] + spec.coupling_damping * (stretch[i] - ts.coupling_stretch[i]) / dt;
      ts.coupling_stretch[i] = stretch[i];
    }
    for (int i = 0; i < 9; ++i) fb.stiffness[i] = -kv * KA[i];
    // The coupling's torque about the device point: its force acts at the proxy.
    fb.torque = {stretch[1] * fb.force[2] - stretch[2] * fb.force[1], stretch[2] * fb.force[0] - stretch[0] * fb.force[2],
                 stretch[0] * fb.force[1] - stretch[1] * fb.force[0]};
  } else {
    fb.force = out.force;
    fb.torque = out.torque;
    fb.stiffness = out.stiffness;
  }
  const double fn = std::sqrt(fb.force[0] * fb.force[0] + fb.force[1] * fb.force[1] + fb.force[2] * fb.force[2]);
  if (fn > spec.max_force) {
    const double scale = spec.max_force / fn;
    for (int k = 0; k < 3; ++k) {
      fb.force[k] *= scale;
      fb.torque[k] *= scale;
    }
    fb.clamped = true;
  }
  return fb;
}

}  // namespace stroma
