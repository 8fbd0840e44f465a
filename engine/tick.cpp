#include "engine/tick.hpp"

#include "engine/damage.hpp"
#include "haptics/contact.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>

namespace stroma {

std::string_view stage_name(Stage s) {
  switch (s) {
    case Stage::ReadInputs: return "read_inputs";
    case Stage::Collide: return "collide";
    case Stage::Assemble: return "assemble";
    case Stage::Solve: return "solve";
    case Stage::Integrate: return "integrate";
    case Stage::Damage: return "damage";
    case Stage::HandOff: return "hand_off";
    case Stage::Count: break;
  }
  return "?";
}

namespace {

inline int64_t now_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

/// Times one stage into the report.
class StageTimer {
 public:
  StageTimer(TickReport& r, Stage s) : r_(r), s_(static_cast<int>(s)), t0_(now_ns()) {}
  ~StageTimer() {
    r_.stage_ns[s_] = now_ns() - t0_;
    r_.stage_ran[s_] = true;
  }

 private:
  TickReport& r_;
  int s_;
  int64_t t0_;
};

bool all_finite(const std::vector<double>& a) {
  double acc = 0;
  for (double v : a) acc += v * 0.0;  // NaN/Inf poison the sum; finite values add exact zeros
  return acc == 0.0;
}

}  // namespace

/// Collide stage: refit the surface BVH, then each tool's coupling, grasp and contact
/// (haptics/contact.hpp); the springs go to the time stepper for this tick's assembly.
void collide(const Model& m, State& s, TickWorkspace& w) {
  const double* x = s.tissue.x.data();
  w.bvh.refit(x);
  w.springs.clear();  // keeps its capacity: no allocation
  const ContactSurface surf{m.collision_triangles, m.collision_slots, m.collision_edge,
                            s.face_active.empty() ? nullptr : s.face_active.data()};
  for (size_t k = 0; k < m.tools.size(); ++k) {
    tool_contact(m.tools[k], s.tools[k], surf, w.bvh, x, s.tissue.v.data(), m.time_step, w.springs);
    device_feedback(m.tools[k], s.tools[k], m.time_step);
  }
  w.stepper().set_contact_springs(w.springs.data(), static_cast<int>(w.springs.size()));
}

TickReport tick(const Model& m, State& s, TickWorkspace& w, const ToolInput* inputs,
                int input_count) {
  TickReport r;
  const int64_t t0 = now_ns();
  const double h = m.time_step;
  TimeStepper& stepper = w.stepper();
  stepper.set_element_damage(m.has_damage ? s.damage.data() : nullptr);
  stepper.set_node_mass(m.has_damage ? s.node_mass.data() : nullptr);
  if (!m.tools.empty()) {
    StageTimer t(r, Stage::ReadInputs);
    for (int i = 0; i < input_count; ++i) {
      const ToolInput& in = inputs[i];
      ToolState& ts = s.tools[in.tool];
      ts.pose = in.pose;
      ts.seq = in.seq;
      ts.client_time_ns = in.client_time_ns;
      ts.last_command_time = s.time;
      ts.active = true;
    }
    // A silent client: the tool holds its last accepted pose, then goes idle.
    for (size_t k = 0; k < s.tools.size(); ++k)
      if (s.tools[k].active && s.time - s.tools[k].last_command_time > m.tools[k].timeout)
        s.tools[k].active = false;
  }
  if (m.has_contact) {
    StageTimer t(r, Stage::Collide);
    collide(m, s, w);
  }
  {
    StageTimer t(r, Stage::Assemble);
    r.elastic_energy = stepper.assemble(s.tissue, h);
  }
  {
    StageTimer t(r, Stage::Solve);
    r.solve = stepper.solve(s.tissue);
  }
  if (!std::isfinite(r.solve.relative_residual) || !all_finite(s.tissue.dv)) {
    r.status = TickStatus::NonFinite;
    std::fill(s.tissue.dv.begin(), s.tissue.dv.end(), 0.0);  // keep the warm start usable
    r.total_ns = now_ns() - t0;
    return r;
  }
  {
    StageTimer t(r, Stage::Integrate);
    stepper.integrate(s.tissue, h);
  }
  s.time = static_cast<double>(s.step + 1) * h;
  ++s.step;
  if (m.has_damage) {
    StageTimer t(r, Stage::Damage);
    w.damage_events.clear();
    r.damage_events = update_damage(m, s, &w.damage_events);
  }
  // hand_off: the server's physics loop does it (headless: nothing to hand off).
  if (!r.solve.converged) r.status = TickStatus::SolverNotConverged;
  r.total_ns = now_ns() - t0;
  return r;
}

}  // namespace stroma
