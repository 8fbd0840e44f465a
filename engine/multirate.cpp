#include "engine/multirate.hpp"

#include <algorithm>
#include <cmath>

#include "haptics/feedback.hpp"
#include "haptics/haptic_model.hpp"
#include "haptics/tool_shape.hpp"

namespace stroma {

namespace {

double dot3(const Vec3& a, const Vec3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

/// The springs' own stiffness along n (the contact with the tissue held still): no secant may
/// be stiffer.
double spring_normal_stiffness(const ContactSpring* springs, int begin, int end, const Vec3& n) {
  double k = 0;
  for (int s = begin; s < end; ++s) {
    const double* K = springs[s].K;
    for (int i = 0; i < 3; ++i) k += n[i] * (K[3 * i] * n[0] + K[3 * i + 1] * n[1] + K[3 * i + 2] * n[2]);
  }
  return k;
}

}  // namespace

void capture_haptic_models(const Model& m, State& s, const TickWorkspace& w) {
  for (size_t k = 0; k < m.tools.size(); ++k) {
    const ToolOutput& out = w.report.tools[k];
    HapticModel& hm = s.tools[k].haptic_next;
    const HapticModel last = hm;  // the previous step's model
    hm.valid = true;
    hm.center = tool_center(m.tools[k], s.tools[k]);
    hm.force = out.force;
    hm.torque = out.torque;
    hm.stiffness.fill(0.0);
    const double f = std::sqrt(dot3(hm.force, hm.force));
    if (f <= 0 || out.spring_end <= out.spring_begin) {
      hm.secant_count = 0;  // out of contact: the next contact measures afresh
      continue;
    }
    const Vec3 n{hm.force[0] / f, hm.force[1] / f, hm.force[2] / f};
    const Vec3 dp{hm.center[0] - last.center[0], hm.center[1] - last.center[1], hm.center[2] - last.center[2]};
    const Vec3 df{hm.force[0] - last.force[0], hm.force[1] - last.force[1], hm.force[2] - last.force[2]};
    const double dpn = dot3(dp, n);
    const double kmax = spring_normal_stiffness(w.springs.data(), out.spring_begin, out.spring_end, n);
    // A secant only from a step that moved the tool along the normal (1 µm), in contact before.
    if (last.valid && dot3(last.force, last.force) > 0 && std::fabs(dpn) > 1e-6) {
      const double secant = std::clamp(dot3(df, n) / dpn, -kmax, 0.0);
      std::copy_backward(hm.secants.begin(), hm.secants.end() - 1, hm.secants.end());
      hm.secants[0] = secant;
      hm.secant_count = std::min(hm.secant_count + 1, kSecantWindow);
    }
    // One or two secants may be a contact forming (its force jumps as points come in): the
    // median of three rejects one.
    if (!m.haptic_secant || hm.secant_count < kSecantWindow) continue;
    const auto& [a, b, c] = hm.secants;
    const double sn = std::max(std::min(a, b), std::min(std::max(a, b), c));
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) hm.stiffness[3 * i + j] = sn * n[i] * n[j];
  }
}

void render_haptic_models(const Model& m, State& s, std::vector<ToolOutput>& outs) {
  for (size_t k = 0; k < m.tools.size(); ++k) {
    ToolState& ts = s.tools[k];
    ToolOutput& out = outs[k];
    render_haptic_model(ts.haptic, tool_center(m.tools[k], ts), out);
    out.feedback = device_feedback(m.tools[k], ts, out, m.time_step);
  }
}

}  // namespace stroma
