#include "engine/tick.hpp"
#include "engine/model_check.hpp"
#include "tissue/demand.hpp"

#include <algorithm>
#include <cmath>

#include "engine/cut_compile.hpp"
#include "engine/damage.hpp"
#include "engine/multirate.hpp"
#include "engine/needle_mesh.hpp"
#include "engine/rigid_grasp.hpp"
#include "engine/thread_attach.hpp"
#include "engine/thread_contact.hpp"
#include "engine/stage_timer.hpp"
#include "engine/step_with_recovery.hpp"
#include "haptics/contact.hpp"
#include "haptics/feedback.hpp"
#include "haptics/tool_shape.hpp"
#include "tissue/cut_blade.hpp"
#include "tissue/fem_forces.hpp"

namespace stroma {

std::string_view degradation_name(Degradation d) {
  switch (d) {
    case Degradation::None: return "none";
    case Degradation::ReleasesSkipped: return "releases_skipped";
    case Degradation::NewtonStopped: return "newton_stopped";
    case Degradation::SolveTruncated: return "solve_truncated";
    case Degradation::LadderStopped: return "ladder_stopped";
    case Degradation::Held: return "held";
  }
  return "?";
}

std::string_view stage_name(Stage s) {
  switch (s) {
    case Stage::ReadInputs: return "read_inputs";
    case Stage::Collide: return "collide";
    case Stage::Assemble: return "assemble";
    case Stage::Solve: return "solve";
    case Stage::Integrate: return "integrate";
    case Stage::Damage: return "damage";
    case Stage::HandOff: return "hand_off";
    case Stage::Cut: return "cut";
    case Stage::Count: break;
  }
  return "?";
}

TickWorkspace::TickWorkspace(const Model& m) : stepper_(m.fem, m.stepper) {
  stepper_.prepare(m.fem_step);
  backup_x.resize(m.fem.rest.size());
  backup_v.resize(m.fem.rest.size());
  backup_visco_q.resize(static_cast<size_t>(m.fem.visco_q_size));
  backup_visco_s0.resize(static_cast<size_t>(m.fem.visco_s0_size));
  report.tools.resize(m.tools.size());
  if (m.has_damage) report.damage_records.reserve(kMaxDamageRecords);
  if (m.has_contact) {  // pay only for use: no tool shape, no BVH
    if (m.collision_embedded.empty()) {
      bvh.build(m.collision_triangles, m.fem.rest.data());
    } else {  // a cut surface: its points beyond the DOFs are filled per tick (collide)
      const size_t points = static_cast<size_t>(m.fem.num_nodes) + m.collision_embedded.size();
      surface_x.resize(3 * points);
      if (m.body_contact) surface_v.resize(3 * points);
      surface_positions(m.fem.rest.data(), m.fem.num_nodes, m.collision_embedded, surface_x.data());
      bvh.build(m.collision_triangles, surface_x.data());
    }
    springs.reserve(kMaxContacts);
    // Touch the capacity now (construct, then clear: no reallocation), so the first ticks with
    // many contacts do not page-fault their way through it — a cut model's workspace is made
    // off the physics thread and its first tick is a served one (measured: 7–11 ms first ticks
    // after a swap).
    springs.resize(kMaxContacts);
    springs.clear();
  }
  if (!m.rigid_bodies.empty()) {
    const size_t nb = m.rigid_bodies.size();
    row_body.assign(nb, -1);
    body_row.assign(nb, -1);
    row_mass.assign(nb, 0.0);
    row_inertia.assign(9 * nb, 0.0);
    row_u0.assign(6 * nb, 0.0);
    row_force.assign(6 * nb, 0.0);
    row_du.assign(6 * nb, 0.0);
    backup_rigid.resize(nb);
    hold_begin.assign(m.tools.size(), 0);
    hold_end.assign(m.tools.size(), 0);
    rigid_in.mass = row_mass.data();
    rigid_in.inertia = row_inertia.data();
    rigid_in.u0 = row_u0.data();
    rigid_in.force = row_force.data();
    rigid_in.du = row_du.data();
    report.rigid_contact.resize(nb);
    report.needles.resize(nb);
    tip_spring.assign(nb, -1);
    tip_element.assign(nb, -1);
    size_t slip_capacity = 0;
    for (const RigidBodyModel& b : m.rigid_bodies) slip_capacity += size_t(b.track_capacity) + 1;
    needle_slips.reserve(slip_capacity);
    stepper_.reserve_rigid_rows(static_cast<int32_t>(nb));
  }
  if (!m.rigid_bodies.empty() || !m.fem.rods.empty()) {  // speculative contacts of bodies and threads
    rigid_pairs.resize(kMaxContacts / 2);  // touched now, as the springs
    rigid_pairs.clear();
  }
  if (!m.fem.rods.empty()) {  // the self-contact broad phase's scratch: one entry per segment
    size_t segments = 0;
    for (const RodRange& r : m.fem.rods) segments += size_t(r.segments());
    segment_spheres.resize(segments);  // touched now
    segment_spheres.clear();
    segment_order.resize(segments);
  }
  if (m.body_contact) {
    body_boxes.resize(6 * m.fem.bodies.size());
    body_pairs.resize(kMaxContacts / 2);  // touched now, as the springs
    body_pairs.clear();
  }
  substep_force.assign(3 * springs.capacity(), 0.0);  // touched now
  if (m.stepper.integrator == Integrator::ImplicitEuler && !m.fem.elements.empty() &&
      stepper_.energy_guard_applies()) {
    guard_ns = stepper_.time_energy_guard_pass(m.fem.rest.data());  // the guard's pass, rotation store included
  }
}

StepInputs step_inputs(const Model& m, const State& s, const TickWorkspace& w) {
  StepInputs in;
  in.springs = w.springs.data();
  in.spring_count = static_cast<int>(w.springs.size());
  in.damage = m.has_damage ? s.damage.data() : nullptr;
  in.node_mass = m.has_damage ? s.node_mass.data() : nullptr;
  in.contact_origin = w.springs.empty() ? nullptr : w.backup_x.data();
  in.rigid = w.rigid_in.rows > 0 ? &w.rigid_in : nullptr;
  return in;
}

/// Collide stage: refit the surface BVH, then each tool's coupling, grasp and contact
/// (haptics/contact.hpp) and body–body contact (collision/body_contact.hpp); the springs are
/// this tick's step inputs.
namespace {

/// cut stage (after collide): each cutting blade's edge, swept from where it was at the end of
/// the last tick to where it is now (tissue/cut_blade.hpp, blade_step), cuts the uncut edges it
/// crosses (s.edge_cut; the Simulation's cut stage swaps in the new topology:
/// engine/cut_swap.hpp). Its resistance (cut_resistance) is smoothed over kCutForceTime into the
/// tool's state.
void cut_with_blades(const Model& m, State& s, TickWorkspace& w) {
  const CutSupport& cs = *m.cutting;
  for (size_t k = 0; k < m.tools.size(); ++k) {
    const ToolSpec& spec = m.tools[k];
    ToolState& ts = s.tools[k];
    ToolOutput& out = w.report.tools[k];
    out.cut_edges = 0;
    if (!spec.cuts) continue;
    if (!ts.active || ts.last_command_time < 0) {
      ts.has_blade = false;
      ts.cut_force = {0, 0, 0};
      continue;
    }
    Capsule cap[kMaxCapsules];
    tool_capsules(spec, ts.pose, tool_center(spec, ts).data(), cap);
    const Vec3 a{cap[0].a[0], cap[0].a[1], cap[0].a[2]}, b{cap[0].b[0], cap[0].b[1], cap[0].b[2]};
    Vec3 f_now{0, 0, 0};
    if (ts.has_blade) {
      // The blade's frame: its normal (local y) and the way its edge faces (local z).
      double R[9];
      quaternion_to_matrix(ts.pose.orientation, R);
      const double normal[3] = {R[1], R[4], R[7]}, forward[3] = {R[2], R[5], R[8]};
      const BladeStep st = blade_step(ts.blade_a, ts.blade_b, a, b, normal, forward, spec.radius);
      const int n = st.forward ? cut_edges(s.tissue.x.data(), cs.base.adj, m.cut_edge_dofs, st.sweep, s.edge_cut,
                                           cs.base.min_fraction.data())
                               : 0;
      out.cut_edges = n;
      w.report.cut_edges += n;
      f_now = cut_resistance(n, cs.edges_per_area, spec.cut_toughness, st.travel, st.travel_len2);
    }
    const double alpha = std::min(1.0, m.fem_step / kCutForceTime);
    for (int i = 0; i < 3; ++i) {
      ts.cut_force[i] += alpha * (f_now[i] - ts.cut_force[i]);
      // A resistance decayed below a piconewton is none (left alone the decay ends in
      // subnormal numbers: stroma run reported a blade's force as −9.9e-324 N).
      if (std::abs(ts.cut_force[i]) < 1e-12) ts.cut_force[i] = 0.0;
    }
    ts.blade_a = a;
    ts.blade_b = b;
    ts.has_blade = true;
  }
}

}  // namespace

namespace {

/// The rigid bodies' contacts (rigid/rigid_contact.hpp) with the tissue's surface and with each
/// other; a free body that touches something gets a row in the step (tissue/rigid_rows.hpp).
void rigid_contacts(const Model& m, State& s, TickWorkspace& w, const ContactSurface& surf, const double* x,
                    const double* px, const double* v) {
  const int32_t nb = static_cast<int32_t>(m.rigid_bodies.size());
  std::fill(w.body_row.begin(), w.body_row.end(), -1);
  int32_t rows = 0;
  // A row for body k if it is free; kept only if its contacts made springs.
  auto tentative = [&](int32_t k, int32_t extra) {
    if (m.rigid_bodies[size_t(k)].fixed) return -1;
    return w.body_row[size_t(k)] >= 0 ? w.body_row[size_t(k)] : rows + extra;
  };
  auto commit = [&](int32_t k) {
    if (m.rigid_bodies[size_t(k)].fixed || w.body_row[size_t(k)] >= 0) return;
    w.body_row[size_t(k)] = rows;
    w.row_body[size_t(rows++)] = k;
  };
  for (RigidContactOutput& o : w.report.rigid_contact) o = RigidContactOutput{};
  w.needle_slips.clear();
  for (int32_t k = 0; k < nb; ++k) {
    const RigidBodyModel& b = m.rigid_bodies[size_t(k)];
    const NeedleState& ns = s.needles[size_t(k)];
    const size_t before = w.springs.size();
    // A needle (rigid/needle_track.hpp): its tip has a contact of its own, and the tissue none
    // around its holes once it is in.
    const bool needle = b.shape == RigidShape::Needle;
    w.tip_spring[size_t(k)] = w.tip_element[size_t(k)] = -1;
    if (needle && ns.phase != NeedlePhase::Inserted) {  // outside, or exited: its tip may bite again
      int32_t tri = -1;
      w.tip_spring[size_t(k)] = needle_tip_contact(b, s.rigid[size_t(k)], tentative(k, 0), s.needles[size_t(k)], surf,
                                                   w.bvh, px, m.fem_step, w.springs, w.rigid_pairs,
                                                   w.report.rigid_contact[size_t(k)], &tri);
      if (tri >= 0 && size_t(tri) < m.collision_tri_elem.size()) w.tip_element[size_t(k)] = m.collision_tri_elem[size_t(tri)];
    }
    double holes[3 * kMaxNeedleHoles];
    const ContactExclusion ex =
        needle ? needle_contact_exclusion(b, ns, px, ns.tissue_body >= 0 ? m.needle_tissue[size_t(ns.tissue_body)].track_spacing : 0.0,
                                          w.tip_spring[size_t(k)] >= 0, holes)
               : ContactExclusion{};
    rigid_tissue_contact(b, s.rigid[size_t(k)], tentative(k, 0), surf, w.bvh, px, v, m.fem.constrained.data(),
                         m.fem_step, m.fem.gravity, w.springs, w.rigid_pairs, w.report.rigid_contact[size_t(k)], ex);
    if (needle && ns.phase != NeedlePhase::Outside)
      needle_track_springs(b, s.rigid[size_t(k)], tentative(k, 0), ns, m.needle_tissue, m.fem,
                           x, m.fem_step, w.springs, w.rigid_pairs, w.needle_slips);
    if (!m.fem.rods.empty())  // threads against it (engine/thread_contact.hpp)
      thread_rigid_contact(m, k, s.rigid[size_t(k)], tentative(k, 0), x, v, w.springs, w.rigid_pairs,
                           w.report.rigid_contact[size_t(k)], w.report.thread_contact);
    if (w.springs.size() > before) commit(k);
  }
  for (int32_t i = 0; i < nb; ++i)
    for (int32_t j = i + 1; j < nb; ++j) {
      const RigidBodyModel &bi = m.rigid_bodies[size_t(i)], &bj = m.rigid_bodies[size_t(j)];
      if (bi.fixed && bj.fixed) continue;
      // The smaller body's samples against the larger's shape.
      const bool i_samples = bi.bounding_radius <= bj.bounding_radius;
      const int32_t a = i_samples ? i : j, b = i_samples ? j : i;
      const int32_t ra = tentative(a, 0);
      const int32_t rb = tentative(b, ra == rows ? 1 : 0);
      const size_t before = w.springs.size();
      rigid_rigid_contact(m.rigid_bodies[size_t(a)], s.rigid[size_t(a)], ra, m.rigid_bodies[size_t(b)],
                          s.rigid[size_t(b)], rb, m.fem_step, m.fem.gravity, w.springs, w.rigid_pairs,
                          w.report.rigid_contact[size_t(a)], w.report.rigid_contact[size_t(b)]);
      if (w.springs.size() > before) {
        commit(a);  // in this order: a took `rows`, b the one after when both were new
        commit(b);
      }
    }
  // Tools holding a body (engine/rigid_grasp.hpp).
  for (size_t t = 0; t < m.tools.size(); ++t) {
    const int32_t k = s.tools[t].grasped_body;
    w.hold_begin[t] = w.hold_end[t] = static_cast<int32_t>(w.springs.size());
    if (k < 0) continue;
    if (rigid_grasp_springs(m.tools[t], s.tools[t], s.rigid[size_t(k)], tentative(k, 0), w.springs) > 0) commit(k);
    w.hold_end[t] = static_cast<int32_t>(w.springs.size());
  }
  // Threads tied to needles' tails (engine/thread_attach.hpp).
  for (const Model::ThreadTie& tie : m.thread_ties)
    if (thread_tie_spring(tie, s.rigid[size_t(tie.body)], tentative(tie.body, 0), x, m.fem.pattern, w.springs) > 0)
      commit(tie.body);
  w.rigid_in.rows = rows;
}

}  // namespace

void collide(const Model& m, State& s, TickWorkspace& w) {
  // Surface points (collision/contact_surface.hpp): the DOFs themselves on an uncut mesh; on a
  // cut one, the DOFs then the embedded points of the cut faces, filled here once per tick.
  const double* x = s.tissue.x.data();
  const double* v = s.tissue.v.data();
  const double* px = x;
  const double* pv = v;
  if (!m.collision_embedded.empty()) {
    surface_positions(x, m.fem.num_nodes, m.collision_embedded, w.surface_x.data());
    px = w.surface_x.data();
    if (m.body_contact) {
      surface_positions(v, m.fem.num_nodes, m.collision_embedded, w.surface_v.data());
      pv = w.surface_v.data();
    }
  }
  w.bvh.refit(px);
  w.springs.clear();  // keeps its capacity: no allocation
  w.rigid_pairs.clear();
  w.report.thread_contact = ThreadContactOutput{};
  update_rigid_grasps(m, s);  // before the tools' own grasps: a jaw closing on a body holds it
  update_thread_grasps(m, s);  // then on a thread
  const ContactSurface surf{m.collision_triangles, m.collision_dofs, m.collision_edge,
                            s.face_active.empty() ? nullptr : s.face_active.data(),
                            m.collision_cut_face.empty() ? nullptr : m.collision_cut_face.data()};
  for (size_t k = 0; k < m.tools.size(); ++k) {
    tool_contact(m.tools[k], s.tools[k], w.report.tools[k], surf, w.bvh, px, v, m.fem_step, w.springs);
    thread_grasp_springs(m, m.tools[k], s.tools[k], x, w.report.tools[k], w.springs);
    thread_tool_contact(m, m.tools[k], s.tools[k], x, w.report.tools[k], w.springs, w.report.thread_contact);
  }
  if (m.body_contact)
    body_contact(*m.body_contact, surf, w.bvh, px, pv, m.fem_step, m.fem.gravity.data(), w.body_boxes.data(),
                 w.springs, w.body_pairs, w.report.body_contact);
  if (!m.rigid_bodies.empty()) rigid_contacts(m, s, w, surf, x, px, v);
  // Threads through the tissue and against it and themselves, last: the springs with matrix-free
  // pairs close the list.
  thread_punctures_before_step(m, s);
  if (!m.fem.rods.empty()) {
    thread_tissue_contact(m, s, surf, w.bvh, px, v, w.springs, w.rigid_pairs, w.report.thread_contact);
    w.self_spring_begin = w.springs.size();
    thread_self_contact(m, x, v, w.segment_spheres, w.segment_order, w.springs, w.rigid_pairs, w.report.thread_contact);
  }
  for (int32_t i = 0; i < s.puncture_count; ++i) thread_puncture_spring(m.fem, s.punctures[size_t(i)], x, w.springs);
}

namespace {

/// read_inputs stage: each command takes effect (pose, seq, timestamps); a tool whose client
/// fell silent holds its last accepted pose, then goes idle after its timeout.
void read_inputs(const Model& m, State& s, const ToolInput* inputs, int input_count) {
  for (int i = 0; i < input_count; ++i) {
    const ToolInput& in = inputs[i];
    ToolState& ts = s.tools[in.tool];
    ts.pose = in.pose;
    ts.seq = in.seq;
    ts.client_time_ns = in.client_time_ns;
    ts.last_command_time = s.time;
    ts.active = true;
  }
  for (size_t k = 0; k < s.tools.size(); ++k)
    if (s.tools[k].active && s.time - s.tools[k].last_command_time > m.tools[k].timeout) s.tools[k].active = false;
}

/// damage stage: thresholds against the new state; events name a tool touching tissue then.
void damage(const Model& m, State& s, TickWorkspace& w) {
  TickReport& r = w.report;
  r.damage_records.clear();
  r.damage_events = update_damage(m, s, &r.damage_records);
  int32_t touching = -1;
  for (size_t t = 0; t < r.tools.size() && touching < 0; ++t)
    if (r.tools[t].contacts > 0) touching = static_cast<int32_t>(t);
  for (DamageEventRecord& e : r.damage_records) e.tool = touching;
}

/// hand_off stage: each tool's force as the solved step applied it (the contact springs at the
/// step's end state) and what its device renders (haptics/feedback.hpp). The coupling's next
/// step starts from this force.
void hand_off(const Model& m, State& s, TickWorkspace& w) {
  for (size_t k = 0; k < m.tools.size(); ++k) {
    ToolOutput& out = w.report.tools[k];
    ToolState& ts = s.tools[k];
    tool_force_after_step(w.springs.data(), w.backup_x.data(), s.tissue.x.data(), s.tissue.v.data(),
                          tool_center(m.tools[k], ts), out);
    if (m.tools[k].cuts)  // the cutting resistance (no torque: it acts along the edge's middle)
      for (int i = 0; i < 3; ++i) out.force[i] += ts.cut_force[i];
    out.holding_body = ts.grasped_body;
    if (ts.grasped_body >= 0 && w.hold_end[k] > w.hold_begin[k])  // the body it holds pulls on it
      rigid_grasp_feedback(w.springs.data(), w.hold_begin[k], w.hold_end[k], w.backup_rigid[size_t(ts.grasped_body)],
                           s.rigid[size_t(ts.grasped_body)], tool_center(m.tools[k], ts), out);
    ts.force = out.force;
    ts.stiffness = out.stiffness;
    out.feedback = device_feedback(m.tools[k], ts, out, m.time_step);
  }
}

}  // namespace

void begin_report(TickReport& r) {
  r.degradation = Degradation::None;
  r.energy_limit = EnergyLimit::None;
  r.energy_removed = 0;
  r.status = TickStatus::Ok;
  r.solve = SolveStats{};
  r.newton = NewtonStats{};
  r.stage_ns.fill(0);
  r.stage_ran.fill(false);
  r.substeps = 1;
  r.contact_releases = 0;
  r.damage_events = 0;
  r.damage_records.clear();
  r.deadline_check = -1;
  r.refresh_wait_ns = 0;
  r.tissue_stepped = false;
  r.cut_edges = 0;
}

void apply_tool_inputs(const Model& m, State& s, TickReport& r, const ToolInput* inputs, int input_count) {
  if (m.tools.empty()) return;
  StageTimer t(r, Stage::ReadInputs);
  read_inputs(m, s, inputs, input_count);
}

bool step_tissue(const Model& m, State& s, TickWorkspace& w, Deadline deadline, int ticks) {
  TickReport& r = w.report;
  r.tissue_stepped = true;
  if (m.has_contact) {
    StageTimer t(r, Stage::Collide);
    collide(m, s, w);
  }
  if (m.cutting) {
    StageTimer t(r, Stage::Cut);
    cut_with_blades(m, s, w);
  }
  // The step's own work stops early enough to leave the energy guard its time.
  if (deadline.at_ns > 0) deadline.at_ns = std::max<int64_t>(1, deadline.at_ns - (w.guard_ns + w.guard_ns / 4));
  step_with_recovery(m, s, w, r, deadline);  // times assemble, solve and integrate itself
  r.deadline_check = deadline.expired_at;
  if (r.status == TickStatus::NonFinite) return false;  // rolled back, not advanced
  if (!m.rigid_bodies.empty())  // the contacts' forces on the bodies as the step applied them
    rigid_forces_after_step(w.backup_x.data(), s.tissue.x.data(), s.tissue.v.data(), w.backup_rigid.data(),
                            s.rigid.data(), w.row_body.data(), w.springs.data(), static_cast<int>(w.springs.size()),
                            r.rigid_contact.data(), static_cast<int>(m.rigid_bodies.size()));
  if (m.has_needles) {  // the needles' insertion after the step (rigid/needle_track.hpp)
    StageTimer t(r, Stage::Integrate);
    for (size_t k = 0; k < m.rigid_bodies.size(); ++k)
      if (m.rigid_bodies[k].shape == RigidShape::Needle)
        needle_after_step(m.rigid_bodies[k], static_cast<int32_t>(k), w.backup_rigid.data(), s.rigid.data(),
                          w.row_body.data(), w.springs.data(), w.tip_spring[k], w.tip_element[k], m.needle_tissue,
                          m.fem, needle_walk_mesh(m), m.node_tet.data(), w.backup_x.data(), s.tissue.x.data(),
                          s.tissue.v.data(), s.needles[k], r.needles[k]);
  }
  r.punctures_made = 0;
  if (m.puncture_capacity > 0)  // threads slide through their punctures; new ones where tails passed
    r.punctures_made = thread_punctures_after_step(m, s, s.tissue.x.data(), s.tissue.v.data(), r.needles.data(),
                                                   &r.punctures_dropped);
  s.step += ticks;
  s.time = static_cast<double>(s.step) * m.time_step;
  if (m.has_damage) {
    StageTimer t(r, Stage::Damage);
    damage(m, s, w);
  }
  if (!m.tools.empty()) {
    StageTimer t(r, Stage::HandOff);
    hand_off(m, s, w);
    if (m.fem_every > 1) capture_haptic_models(m, s, w);
  }
  if (r.status == TickStatus::Ok && !r.solve.converged) r.status = TickStatus::SolverNotConverged;
  return true;
}

const TickReport& tick(const Model& m, State& s, TickWorkspace& w, const ToolInput* inputs, int input_count,
                       Deadline deadline) {
  STROMA_DEMAND(state_sized_for(m, s), "tick: the state does not fit the model (engine/model_check.hpp)");
  TickReport& r = w.report;
  const int64_t t0 = steady_now_ns();
  if (!deadline.active() && m.time_budget > 0) deadline.at_ns = t0 + static_cast<int64_t>(m.time_budget * 1e9);
  r.budget_ns = deadline.at_ns > 0 ? deadline.at_ns - t0 : 0;
  begin_report(r);
  apply_tool_inputs(m, s, r, inputs, input_count);
  // Multirate (engine/multirate.hpp): the tissue steps every fem_every ticks; every tick renders
  // the tools from the model of the step that has finished by now (the one started fem_every
  // ticks ago: what a served pipeline feels).
  const bool multirate = m.fem_every > 1;
  const int64_t tick_deadline = deadline.at_ns;
  if (!multirate || s.step % m.fem_every == 0) {
    if (multirate)
      for (ToolState& ts : s.tools) ts.haptic = ts.haptic_next;
    if (!step_tissue(m, s, w, deadline, 1)) {
      close_report(r, t0, tick_deadline);
      return r;
    }
  } else {
    s.time = static_cast<double>(s.step + 1) * m.time_step;
    ++s.step;
  }
  if (multirate && !m.tools.empty()) {
    StageTimer t(r, Stage::HandOff);
    render_haptic_models(m, s, r.tools);
  }
  close_report(r, t0, tick_deadline);
  return r;
}

}  // namespace stroma
