#include "engine/step_with_recovery.hpp"

#include <algorithm>
#include <array>
#include <cmath>

#include "engine/stage_timer.hpp"
#include "engine/tick.hpp"  // step_inputs
#include "rigid/rigid_motion.hpp"
#include "tissue/contact_spring.hpp"
#include "tissue/mat3.hpp"
#include "tissue/time_stepper.hpp"

namespace stroma {

namespace {

bool all_finite(const std::vector<double>& a) {
  double acc = 0;
  for (double v : a) acc += v * 0.0;  // NaN/Inf poison the sum; finite values add exact zeros
  return acc == 0.0;
}

/// Puts the tissue and the rigid bodies back to the start of the tick; the warm start is
/// cleared (it may hold the failed solve).
void restore(State& s, const TickWorkspace& w) {
  std::copy(w.backup_rigid.begin(), w.backup_rigid.end(), s.rigid.begin());
  TissueState& t = s.tissue;
  std::copy(w.backup_x.begin(), w.backup_x.end(), t.x.begin());
  std::copy(w.backup_v.begin(), w.backup_v.end(), t.v.begin());
  std::copy(w.backup_visco_q.begin(), w.backup_visco_q.end(), t.visco_q.begin());
  std::copy(w.backup_visco_s0.begin(), w.backup_visco_s0.end(), t.visco_s0.begin());
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

/// The rigid rows' inputs for a step of length h (tissue/rigid_rows.hpp): each row's mass,
/// world inertia, applied force (its weight) and start velocities — ω after the step's
/// gyroscopic part (rigid/rigid_motion.hpp), which the rows leave out.
void prepare_rigid_rows(const Model& m, const State& s, TickWorkspace& w, double h) {
  for (int32_t r = 0; r < w.rigid_in.rows; ++r) {
    const RigidBodyModel& b = m.rigid_bodies[size_t(w.row_body[size_t(r)])];
    const RigidState& rs = s.rigid[size_t(w.row_body[size_t(r)])];
    w.row_mass[size_t(r)] = b.mass.mass;
    const std::array<double, 9> I = world_inertia(b.mass.inertia, rs.q);
    std::copy(I.begin(), I.end(), w.row_inertia.begin() + 9 * r);
    const Vec3 wg = gyroscopic_step(b.mass.inertia, h, rs);
    for (int k = 0; k < 3; ++k) {
      w.row_u0[size_t(6 * r + k)] = rs.v[size_t(k)];
      w.row_u0[size_t(6 * r + 3 + k)] = wg[size_t(k)];
      w.row_force[size_t(6 * r + k)] = b.mass.mass * m.fem.gravity[size_t(k)];
      w.row_force[size_t(6 * r + 3 + k)] = 0.0;
    }
  }
}

/// The rigid bodies over the step h: a body with a row takes its solved Δu, then its pose
/// follows; the others step free (rigid/rigid_motion.hpp). True if every body is finite.
bool integrate_rigid(const Model& m, State& s, const TickWorkspace& w, double h) {
  double acc = 0;
  for (size_t k = 0; k < m.rigid_bodies.size(); ++k) {
    if (m.rigid_bodies[k].fixed) continue;
    RigidState& rs = s.rigid[k];
    const int32_t r = w.body_row[k];
    if (r >= 0) {
      for (int i = 0; i < 3; ++i) {
        rs.v[size_t(i)] = w.row_u0[size_t(6 * r + i)] + w.row_du[size_t(6 * r + i)];
        rs.w[size_t(i)] = w.row_u0[size_t(6 * r + 3 + i)] + w.row_du[size_t(6 * r + 3 + i)];
      }
      advance_pose(h, rs);
    } else {
      step_free_rigid(m.rigid_bodies[k].mass.inertia, m.fem.gravity, h, rs);
    }
    for (int i = 0; i < 3; ++i) acc += (rs.x[size_t(i)] + rs.v[size_t(i)] + rs.w[size_t(i)]) * 0.0;
  }
  return acc == 0.0;
}

/// d = the spring's tissue point at positions x1 less at x0.
void tissue_point_travel(const ContactSpring& sp, const double* x0, const double* x1, double* d) {
  double p0[3], p1[3];
  spring_point(sp, x0, p0);
  spring_point(sp, x1, p1);
  for (int i = 0; i < 3; ++i) d[i] = p1[i] - p0[i];
}

/// The rigid rows' share of the energy guard's account for a full step (from the tick's start,
/// w.backup_rigid, to s.rigid): the bodies with rows — kinetic energy and gravity's potential
/// before and after — and the springs naming a row as the step linearised them: d, the point's
/// displacement less its anchor's, with a row's point moving by h·(v + ω × arm) at the step's
/// end velocities (the rows' linear model, tissue/rigid_rows.hpp).
GuardRows guard_rows(const Model& m, const State& s, const TickWorkspace& w, double h) {
  GuardRows g;
  const Vec3& gr = m.fem.gravity;
  for (size_t k = 0; k < m.rigid_bodies.size(); ++k) {
    if (m.rigid_bodies[k].fixed || w.body_row[k] < 0) continue;
    const RigidBodyModel& b = m.rigid_bodies[k];
    const RigidState &s0 = w.backup_rigid[k], &s1 = s.rigid[k];
    g.kinetic0 += rigid_kinetic_energy(b.mass.mass, b.mass.inertia, s0);
    g.kinetic1 += rigid_kinetic_energy(b.mass.mass, b.mass.inertia, s1);
    for (int i = 0; i < 3; ++i) {
      g.gravity0 -= b.mass.mass * gr[size_t(i)] * s0.x[size_t(i)];
      g.gravity1 -= b.mass.mass * gr[size_t(i)] * s1.x[size_t(i)];
    }
  }
  auto row_travel = [&](int32_t row, const double* arm, double* d, double sign) {
    const RigidState& rs = s.rigid[size_t(w.row_body[size_t(row)])];
    double c[3];
    m3::cross(rs.w.data(), arm, c);  // ω × arm
    for (int i = 0; i < 3; ++i) d[i] += sign * h * (rs.v[size_t(i)] + c[i]);
  };
  const double* x0 = w.backup_x.data();
  const double* x1 = s.tissue.x.data();
  for (const ContactSpring& sp : w.springs) {
    if (!spring_has_rows(sp)) continue;
    double d[3] = {0, 0, 0};
    if (sp.n > 0) tissue_point_travel(sp, x0, x1, d);
    else row_travel(sp.row_p, sp.arm_p, d, 1.0);
    if (sp.row_n >= 0) row_travel(sp.row_n, sp.arm_n, d, -1.0);
    for (int i = 0; i < 3; ++i) {
      g.spring_linear -= sp.force[i] * d[i];
      g.spring_quadratic += 0.5 * d[i] * (sp.K[3 * i] * d[0] + sp.K[3 * i + 1] * d[1] + sp.K[3 * i + 2] * d[2]);
    }
  }
  return g;
}

/// The bodies with rows follow what the energy guard did to the tissue (GuardRows' out): their
/// poses θ of the way from the tick's start (the orientation by normalised interpolation: a
/// step's turn is small), their velocities scaled.
void follow_guard(const Model& m, State& s, const TickWorkspace& w, const GuardRows& g) {
  for (size_t k = 0; k < m.rigid_bodies.size(); ++k) {
    if (m.rigid_bodies[k].fixed || w.body_row[k] < 0) continue;
    const RigidState& s0 = w.backup_rigid[k];
    RigidState& rs = s.rigid[k];
    if (g.theta < 1) {
      double dot = 0;
      for (int i = 0; i < 4; ++i) dot += s0.q[size_t(i)] * rs.q[size_t(i)];
      const double sign = dot < 0 ? -1.0 : 1.0;
      double n2 = 0;
      for (int i = 0; i < 4; ++i) {
        rs.q[size_t(i)] = (1 - g.theta) * s0.q[size_t(i)] + g.theta * sign * rs.q[size_t(i)];
        n2 += rs.q[size_t(i)] * rs.q[size_t(i)];
      }
      const double inv = 1.0 / std::sqrt(n2);
      for (int i = 0; i < 4; ++i) rs.q[size_t(i)] *= inv;
      for (int i = 0; i < 3; ++i) rs.x[size_t(i)] = s0.x[size_t(i)] + g.theta * (rs.x[size_t(i)] - s0.x[size_t(i)]);
    }
    for (int i = 0; i < 3; ++i) {
      rs.v[size_t(i)] *= g.velocity_scale;
      rs.w[size_t(i)] *= g.velocity_scale;
    }
  }
}

/// Each spring's force where a sub-step starts, into w.substep_force: f − K·d, d the spring's
/// relative displacement since the tick's start, where it was found and linearised — its
/// tissue point's (from w.backup_x) less a body's point at its arm (from w.backup_rigid; a
/// rigid pair's row_p side counts positive). Without it every sub-step would start from the
/// force found at the tick's start: a speculative spring (f = −k·gap, pulling) would ask each
/// sub-step to close its whole gap — a node and the box moved ~45 mm and ~16 mm in a sub-step
/// of h/16, v ∝ 1/h, and every level failed (docs/RIGID.md).
const double* substep_spring_forces(const State& s, TickWorkspace& w) {
  const double* x0 = w.backup_x.data();
  const double* x1 = s.tissue.x.data();
  auto body_travel = [&](int32_t row, const double* arm, double sign, double* d) {
    const size_t b = size_t(w.row_body[size_t(row)]);
    const RigidState &a = w.backup_rigid[b], &c = s.rigid[b];
    // The arm's point moves with the body: (x_c − x_a) + (R_c·R_aᵀ − I)·arm.
    const std::array<double, 9> Ra = rotation_of(a.q), Rc = rotation_of(c.q);
    double local[3], now[3];
    for (int i = 0; i < 3; ++i) local[i] = Ra[size_t(i)] * arm[0] + Ra[size_t(3 + i)] * arm[1] + Ra[size_t(6 + i)] * arm[2];
    for (int i = 0; i < 3; ++i)
      now[i] = Rc[size_t(3 * i)] * local[0] + Rc[size_t(3 * i + 1)] * local[1] + Rc[size_t(3 * i + 2)] * local[2];
    for (int i = 0; i < 3; ++i) d[i] += sign * (c.x[size_t(i)] - a.x[size_t(i)] + now[i] - arm[i]);
  };
  double* out = w.substep_force.data();
  for (size_t c = 0; c < w.springs.size(); ++c) {
    const ContactSpring& sp = w.springs[c];
    double d[3] = {0, 0, 0};
    if (sp.n > 0) tissue_point_travel(sp, x0, x1, d);
    else if (sp.row_p >= 0) body_travel(sp.row_p, sp.arm_p, 1.0, d);
    if (sp.row_n >= 0) body_travel(sp.row_n, sp.arm_n, -1.0, d);
    for (int i = 0; i < 3; ++i)
      out[3 * c + i] = sp.force[i] - (sp.K[3 * i] * d[0] + sp.K[3 * i + 1] * d[1] + sp.K[3 * i + 2] * d[2]);
  }
  return out;
}

/// Records the worst degradation of the tick.
void degrade(TickReport& r, Degradation d) {
  if (static_cast<int>(d) > static_cast<int>(r.degradation)) r.degradation = d;
}

/// assemble → solve → integrate over h. False (state possibly half-updated: the caller rolls
/// back) if the solve is non-finite, capped while `cap_fails`, or the result is not sane.
/// `first` says whether this is the tick's full step (its elastic energy is reported).
bool step(const Model& m, State& s, TickWorkspace& w, double h, TickReport& r, bool first, bool cap_fails,
          Deadline& deadline) {
  TimeStepper& stepper = w.stepper();
  TissueState& t = s.tissue;
  {
    StageTimer st(r, Stage::Assemble);
    if (w.rigid_in.rows > 0) prepare_rigid_rows(m, s, w, h);
    StepInputs in = step_inputs(m, s, w);
    // A sub-step (the ladder's, from the tick's start or where the last one ended): the springs
    // found at the tick's start, evaluated where it starts.
    if (h != m.fem_step && !w.springs.empty() && w.substep_force.size() >= 3 * w.springs.size())
      in.spring_force = substep_spring_forces(s, w);
    const double e = stepper.assemble(t, h, in);
    if (first) r.elastic_energy = e;
  }
  // A headless wait for a late refresh worker is not the engine's work: the deadline moves
  // with it (a served tick never waits).
  if (const int64_t waited = stepper.last_refresh_wait_ns(); waited > 0) {
    r.refresh_wait_ns += waited;
    r.stage_ns[static_cast<int>(Stage::Assemble)] -= waited;  // the stage times the work alone
    if (deadline.at_ns > 0) deadline.at_ns += waited;
  }
  {
    StageTimer st(r, Stage::Solve);
    r.solve = stepper.solve(t, &deadline);
  }
  if (r.solve.budget_stopped) degrade(r, Degradation::SolveTruncated);
  // A capped CG is usable (its residual may exceed ‖b‖ — CG minimises the error's energy norm,
  // not the residual) but on a badly conditioned step it can add energy: by default the tick is
  // redone in sub-steps, whose systems are better conditioned (solver.on_cg_cap). A diverging
  // solve shows up as NaN/Inf or as an absurd displacement below.
  if (!std::isfinite(r.solve.relative_residual) || !all_finite(t.dv)) return false;
  // A capped solve redoes the tick in sub-steps (solver.on_cg_cap); one stopped by the budget is
  // kept when sane — there is no time for sub-steps.
  if (cap_fails && !r.solve.converged && !r.solve.budget_stopped) return false;
  if (stepper.settings().newton_iterations > 1) {
    // Newton iterations: their element passes count under Assemble, their solves under Solve.
    const int64_t t0 = steady_now_ns();
    r.newton = stepper.newton(t, h, &deadline);
    if (r.newton.budget_stopped) degrade(r, Degradation::NewtonStopped);
    const int64_t total = steady_now_ns() - t0;
    r.stage_ns[static_cast<int>(Stage::Assemble)] += r.newton.element_pass_ns;
    r.stage_ns[static_cast<int>(Stage::Solve)] += total - r.newton.element_pass_ns;
    if (!all_finite(t.dv)) return false;
  }
  {
    StageTimer st(r, Stage::Integrate);
    stepper.integrate(t, h);
    if (!m.rigid_bodies.empty() && !integrate_rigid(m, s, w, h)) return false;
    // An inexact solve is kept only if the step did not gain energy (implicit Euler's exact
    // step never does): the guard takes out what it added.
    if (!r.solve.converged && stepper.settings().integrator == Integrator::ImplicitEuler &&
        stepper.energy_guard_applies()) {
      double removed = 0;
      const int64_t g0 = steady_now_ns();
      // With rigid rows only a full step (from the tick's start, where the backups are) is
      // checked: the bodies' share of the account is the engine's.
      const bool rows = w.rigid_in.rows > 0 && h == m.fem_step;
      GuardRows g;
      if (rows) g = guard_rows(m, s, w, h);
      const EnergyLimit e = stepper.energy_guard(t, h, &removed, rows ? &g : nullptr);
      if (rows && e != EnergyLimit::None) follow_guard(m, s, w, g);
      w.guard_ns += (steady_now_ns() - g0 - w.guard_ns) / 8;  // what the tick keeps back for it
      if (e != EnergyLimit::None) {
        r.energy_limit = e;
        r.energy_removed += removed;
      }
    }
  }
  return sane_step(t, h, m.max_step_displacement);
}

/// How a tick's step ended, as the recovery policy left it (accounted by account_outcome).
enum class StepOutcome {
  FullStep,         ///< the full step, sane
  SubSteps,         ///< redone in r.substeps sane sub-steps
  SubStepsPartWay,  ///< out of time part-way up a level: the sane sub-steps done are kept
  Held,             ///< out of time with no sane step: rolled back, velocities zeroed
  RolledBack        ///< no sub-step division gave a sane step: rolled back, not advanced
};

/// The recovery policy after a failed full step: roll back and redo the tick in 2, 4, …
/// kMaxSubsteps sub-steps (a smaller step is both more stable and better conditioned), warm start
/// cleared; from kKeepCappedSubsteps on a capped solve is kept (a finite, advanced state beats
/// none); every level stops at the deadline. Without a sane level: hold still if out of time,
/// else roll back. Says what it did; the report's status and degradation are accounting's.
StepOutcome recover(const Model& m, State& s, TickWorkspace& w, TickReport& r, Deadline& deadline, bool cap_fails) {
  const double h = m.fem_step;
  for (int k = 2; k <= kMaxSubsteps; k *= 2) {
    if (deadline.past()) break;  // (a failed level that ran out of time ends here too)
    restore(s, w);
    bool ok = true;
    int done = 0;  // sane sub-steps of this level
    for (int i = 0; i < k && ok; ++i) {
      if (deadline.past()) break;
      ok = step(m, s, w, h / k, r, false, cap_fails && k < kKeepCappedSubsteps, deadline);
      done += ok;
    }
    r.substeps = k;
    if (ok) return done < k ? StepOutcome::SubStepsPartWay : StepOutcome::SubSteps;
  }
  restore(s, w);
  if (deadline.past()) {
    std::fill(s.tissue.v.begin(), s.tissue.v.end(), 0.0);
    return StepOutcome::Held;
  }
  return StepOutcome::RolledBack;
}

/// The step's accounting: its status and worst degradation from how it ended.
void account_outcome(StepOutcome o, TickReport& r) {
  switch (o) {
    case StepOutcome::FullStep: break;
    case StepOutcome::SubSteps: r.status = TickStatus::Recovered; break;
    case StepOutcome::SubStepsPartWay:  // maybe none done: then the tissue keeps its start state
      degrade(r, Degradation::LadderStopped);
      r.status = TickStatus::Recovered;
      break;
    case StepOutcome::Held:
      degrade(r, Degradation::Held);
      r.status = TickStatus::Recovered;
      break;
    case StepOutcome::RolledBack: r.status = TickStatus::NonFinite; break;
  }
}

}  // namespace

void step_with_recovery(const Model& m, State& s, TickWorkspace& w, TickReport& r, Deadline& deadline) {
  const double h = m.fem_step;  // = time_step unless the tissue steps every fem_every ticks
  // Rollback point: the tissue's positions and velocities (two copies of 3n doubles).
  std::copy(s.tissue.x.begin(), s.tissue.x.end(), w.backup_x.begin());
  std::copy(s.tissue.v.begin(), s.tissue.v.end(), w.backup_v.begin());
  std::copy(s.tissue.visco_q.begin(), s.tissue.visco_q.end(), w.backup_visco_q.begin());
  std::copy(s.tissue.visco_s0.begin(), s.tissue.visco_s0.end(), w.backup_visco_s0.begin());
  std::copy(s.rigid.begin(), s.rigid.end(), w.backup_rigid.begin());
  const bool cap_fails = m.substep_on_cg_cap;
  bool ok = step(m, s, w, h, r, true, cap_fails, deadline);
  // Speculative body contacts whose vertex never reached its face would pull it in: release them
  // and redo the step (only ticks where something is about to touch pay for this).
  // So are rigid bodies' (rigid/rigid_contact.hpp).
  auto release = [&]() {
    int n = 0;
    if (m.body_contact) n += release_pulling_contacts(w.backup_x.data(), s.tissue.x.data(), w.body_pairs, w.springs);
    if (!w.rigid_pairs.empty())
      n += release_pulling_rigid_contacts(w.backup_x.data(), s.tissue.x.data(), w.backup_rigid.data(), s.rigid.data(),
                                         w.row_body.data(), w.rigid_pairs, w.springs);
    if (!w.needle_slips.empty())  // a needle turned back against a sliding track point sticks it
      n += stick_reversed_slips(w.backup_x.data(), s.tissue.x.data(), w.backup_rigid.data(), s.rigid.data(),
                                w.row_body.data(), w.rigid_pairs, w.needle_slips, w.springs);
    // Threads' segments that went through each other within the step get their springs
    // (engine/thread_contact.hpp, thread_missed_self_contacts) — if a redo still fits before the
    // deadline (below): without one its springs would change nothing (counted: unchecked).
    const bool redo_fits = !deadline.past_in(r.stage_ns[size_t(Stage::Assemble)] / (1 + r.contact_releases));
    if (!m.fem.rods.empty() && !redo_fits) ++r.thread_contact.unchecked;
    if (!m.fem.rods.empty() && redo_fits) {
      StageTimer st(r, Stage::Collide);  // the continuous check is the collide stage's, after the step
      n += thread_missed_self_contacts(m, w.backup_x.data(), w.backup_v.data(), s.tissue.x.data(), w.segment_spheres,
                                       w.segment_order, w.self_spring_begin, w.springs, w.rigid_pairs,
                                       r.thread_contact);
      for (size_t k = 0; k < m.rigid_bodies.size(); ++k) {  // and through the rigid bodies
        const int32_t row = m.rigid_bodies[k].fixed ? -1 : w.body_row[k];
        if (!m.rigid_bodies[k].fixed && row < 0) continue;  // no row this step: not checked
        n += thread_missed_rigid_contacts(m, static_cast<int32_t>(k), w.backup_rigid[k], s.rigid[k], row,
                                          w.backup_x.data(), w.backup_v.data(), s.tissue.x.data(), w.springs,
                                          w.rigid_pairs, r.rigid_contact[k], r.thread_contact);
      }
    }
    return n;
  };
  while (ok && (m.body_contact || !w.rigid_pairs.empty() || !w.needle_slips.empty() || !m.fem.rods.empty()) &&
         r.contact_releases < kMaxContactReleases && release() > 0) {
    // Keep the step as solved, pulling contacts and all, if a redo would end past the deadline:
    // its assembly is not cut by it (only its solve is), so look ahead by one assembly as this
    // tick's passes measured it (on the fine liver ~0.3 ms: a redo begun just before the
    // deadline took served ticks 0.35 ms past it).
    const int64_t passes = 1 + r.contact_releases;
    if (deadline.past_in(r.stage_ns[size_t(Stage::Assemble)] / passes)) {
      degrade(r, Degradation::ReleasesSkipped);
      break;
    }
    ++r.contact_releases;
    restore(s, w);
    ok = step(m, s, w, h, r, false, cap_fails, deadline);
  }
  account_outcome(ok ? StepOutcome::FullStep : recover(m, s, w, r, deadline, cap_fails), r);
}

}  // namespace stroma
