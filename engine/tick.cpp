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
    r_.stage_ns[s_] += now_ns() - t0_;  // += : a retried tick runs stages more than once
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

/// Puts the tissue back to the start of the tick; the warm start is cleared (it may hold the
/// failed solve).
void restore(TissueState& t, const TickWorkspace& w) {
  std::copy(w.backup_x.begin(), w.backup_x.end(), t.x.begin());
  std::copy(w.backup_v.begin(), w.backup_v.end(), t.v.begin());
  std::fill(t.dv.begin(), t.dv.end(), 0.0);
  std::fill(t.dv_prev.begin(), t.dv_prev.end(), 0.0);
}

/// True if the step just integrated over h moved no node by more than `limit` (|v|·h, v the
/// new velocity) and every position and velocity is finite (NaN/Inf fail the comparisons).
bool sane_step(const TissueState& t, double h, double limit) {
  const double v2max = (limit / h) * (limit / h);
  bool ok = true;
  for (size_t i = 0; i + 2 < t.v.size(); i += 3)
    ok &= t.v[i] * t.v[i] + t.v[i + 1] * t.v[i + 1] + t.v[i + 2] * t.v[i + 2] <= v2max;
  return ok && all_finite(t.x);
}

/// assemble → solve → integrate over h. False (state possibly half-updated: the caller rolls
/// back) if the solve is non-finite, capped while `cap_fails`, or the result is not sane.
/// `first` says whether this is the tick's full step (timed stages report into r either way).
bool step(TimeStepper& stepper, TissueState& t, TickWorkspace& w, double h, TickReport& r, bool first,
          bool cap_fails) {
  {
    StageTimer st(r, Stage::Assemble);
    const double e = stepper.assemble(t, h);
    if (first) r.elastic_energy = e;
  }
  {
    StageTimer st(r, Stage::Solve);
    r.solve = stepper.solve(t);
  }
  // A capped CG is usable (its residual may exceed ‖b‖ — CG minimises the error's energy norm,
  // not the residual) but on a badly conditioned step it can add energy: by default the tick is
  // redone in sub-steps, whose systems are better conditioned (solver.on_cg_cap). A diverging
  // solve shows up as NaN/Inf or as an absurd displacement below.
  if (!std::isfinite(r.solve.relative_residual) || !all_finite(t.dv)) return false;
  if (cap_fails && !r.solve.converged) return false;
  if (stepper.settings().newton_iterations > 1) {
    StageTimer st(r, Stage::Solve);
    r.newton = stepper.newton(t, h);
    if (!all_finite(t.dv)) return false;
  }
  {
    StageTimer st(r, Stage::Integrate);
    stepper.integrate(t, h);
  }
  return sane_step(t, h, w.max_step_displacement);
}

}  // namespace

/// Collide stage: refit the surface BVH, then each tool's coupling, grasp and contact
/// (haptics/contact.hpp) and body–body contact (collision/body_contact.hpp); the springs go to
/// the time stepper for this tick's assembly.
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
  if (m.body_contact)
    body_contact(*m.body_contact, surf, w.bvh, x, s.tissue.v.data(), m.time_step, m.fem.gravity.data(),
                 m.fem.constrained.data(),
                 w.body_boxes.data(), w.springs, w.body_pairs, s.body_contact);
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
  // Rollback point: the tissue's positions and velocities (two copies of 3n doubles).
  std::copy(s.tissue.x.begin(), s.tissue.x.end(), w.backup_x.begin());
  std::copy(s.tissue.v.begin(), s.tissue.v.end(), w.backup_v.begin());
  const bool cap_fails = m.spec.solver.substep_on_cg_cap;
  bool ok = step(stepper, s.tissue, w, h, r, true, cap_fails);
  // Speculative body contacts whose vertex never reached its face would pull it in: release them
  // and redo the step (only ticks where something is about to touch pay for this).
  for (int pass = 0; ok && m.body_contact && pass < kMaxContactReleases &&
                     release_pulling_contacts(s.tissue.x.data(), w.body_pairs, w.springs) > 0;
       ++pass) {
    restore(s.tissue, w);
    ok = step(stepper, s.tissue, w, h, r, false, cap_fails);
  }
  if (!ok) {
    // The engine defends itself: roll back and redo the tick in 2, 4, … sub-steps (a smaller
    // step is both more stable and better conditioned), warm start cleared.
    for (int k = 2; k <= kMaxSubsteps && !ok; k *= 2) {
      restore(s.tissue, w);
      ok = true;
      // From kKeepCappedSubsteps on a capped solve is kept: a finite, advanced state beats none.
      for (int i = 0; i < k && ok; ++i)
        ok = step(stepper, s.tissue, w, h / k, r, false, cap_fails && k < kKeepCappedSubsteps);
      r.substeps = k;
    }
    if (!ok) {
      restore(s.tissue, w);
      r.status = TickStatus::NonFinite;
      r.total_ns = now_ns() - t0;
      return r;
    }
    r.status = TickStatus::Recovered;
  }
  s.time = static_cast<double>(s.step + 1) * h;
  ++s.step;
  if (m.has_damage) {
    StageTimer t(r, Stage::Damage);
    w.damage_events.clear();
    r.damage_events = update_damage(m, s, &w.damage_events);
  }
  // hand_off: the server's physics loop does it (headless: nothing to hand off).
  if (r.status == TickStatus::Ok && !r.solve.converged) r.status = TickStatus::SolverNotConverged;
  r.total_ns = now_ns() - t0;
  return r;
}

}  // namespace stroma
