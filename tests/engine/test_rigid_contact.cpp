// Rigid bodies touching the tissue and each other (issue 42): their rows solved with the
// tissue's in one implicit step (tissue/rigid_rows.hpp), contacts as springs naming the rows
// (rigid/rigid_contact.hpp). Each test has an independent reference: a box resting on a tissue
// column on rollers compresses it by the uniaxial-stress value m·g·H/(E·A); a box dropped on
// tissue on its corner never gains energy and comes to rest on it; a box on a fixed slope sticks when
// μ > tan θ and slides with a = g (sin θ − μ cos θ) when μ < tan θ; the Schur-complement solve
// agrees with a dense solve of the whole system.

#include <gtest/gtest.h>
#include <fmt/format.h>

#include <Eigen/Dense>
#include <cmath>
#include <cstdio>
#include <map>
#include <string>

#include "engine/state.hpp"
#include "engine/tick.hpp"
#include "rigid/rigid_contact.hpp"
#include "scene/compiled_scenario.hpp"
#include "scene/scenario_spec.hpp"
#include "io/mesh_write.hpp"
#include "tests/test_labels.hpp"
#include "tests/test_meshes.hpp"
#include "tests/test_scenarios.hpp"
#include "tissue/rigid_rows.hpp"

using namespace stroma;
using stroma::test_meshes::box_mesh;
using stroma::test_scenarios::write_temp;

namespace {

const std::string kSrc = STROMA_SOURCE_DIR;
constexpr double kG = 9.81;

std::shared_ptr<const Model> compile_yaml(const std::string& yaml) {
  return compile_model(parse_scenario(yaml, "rigid_contact.yaml", kSrc));
}

/// A 20 mm tissue cube (the 50 mm cube mesh at scale 0.4, y from 0 to 0.02) fixed at its
/// bottom; `rigid` is the rigid_bodies list.
std::string column_yaml(double E, double rayleigh_mass, const std::string& rigid) {
  return fmt::format(R"(name: rigid_contact
time_step: 0.001
gravity: [0, -9.81, 0]
solver: {{integrator: implicit_euler, preconditioner: block_jacobi, tolerance: 1.0e-10, max_iterations: 2000}}
bodies:
  - name: column
    mesh: {0}/scenarios/meshes/cube_tet4_h5p000mm.msh
    scale: 0.4
    material: {{young_modulus: {1}, poisson_ratio: 0.45, density: 1000, rayleigh_mass: {2}}}
    fixed:
      - box: {{min: [-1, -1.0e-6, -1], max: [1, 1.0e-6, 1]}}
rigid_bodies:
{3}
)",
                     kSrc, E, rayleigh_mass, rigid);
}

}  // namespace

namespace {

/// A structured quarter (4 × 8 × 4 cells over [0, 0.01] × [0, 0.02] × [0, 0.01]) mirrored in
/// x = 0 and z = 0: a 20 mm cube whose mesh is symmetric about both mid-planes.
TetMesh mirrored_column() {
  const TetMesh q = box_mesh(4, 8, 4, {0.01, 0.02, 0.01});
  TetMesh m;
  m.source = "mirrored column";
  std::map<std::array<int64_t, 3>, int32_t> index;
  auto node = [&](const Vec3& p) {
    const std::array<int64_t, 3> key = {std::llround(p[0] * 1e9), std::llround(p[1] * 1e9), std::llround(p[2] * 1e9)};
    auto [it, added] = index.emplace(key, static_cast<int32_t>(m.nodes.size()));
    if (added) m.nodes.push_back(p);
    return it->second;
  };
  for (const double sx : {1.0, -1.0})
    for (const double sz : {1.0, -1.0})
      for (const Tet& t : q.tets) {
        Tet u;
        for (int a = 0; a < 4; ++a) {
          const Vec3& p = q.nodes[size_t(t[size_t(a)])];
          u[size_t(a)] = node({sx * p[0], p[1], sz * p[2]});
        }
        if (sx * sz < 0) std::swap(u[2], u[3]);  // one reflection turns it inside out
        m.tets.push_back(u);
      }
  return m;
}

/// That cube on rollers through its middle: bottom held in y, the x = 0 and z = 0 mid-planes
/// in x and z — so a uniform top load is uniaxial stress — with the same symmetry: a
/// frictionless box resting on it is laterally unstable (a shift tilts it, its tilted face
/// pushes it further: the growth rate here is ~9/s), so the symmetry keeps it where it is.
std::string centred_column_yaml(const std::string& rigid) {
  static const std::string mesh = [] {
    const std::string path = write_temp("mirrored_column.msh", "");
    write_tet_mesh(path, mirrored_column());
    return path;
  }();
  return fmt::format(R"(name: centred_column
time_step: 0.001
gravity: [0, -9.81, 0]
solver: {{integrator: implicit_euler, preconditioner: block_jacobi, tolerance: 1.0e-10, max_iterations: 2000}}
bodies:
  - name: column
    mesh: {0}
    material: {{young_modulus: 1.0e4, poisson_ratio: 0.45, density: 1000, rayleigh_mass: 30}}
    fixed:
      - {{box: {{min: [-1, -1.0e-6, -1], max: [1, 1.0e-6, 1]}}, axes: [y]}}
      - {{box: {{min: [-1.0e-6, -1, -1], max: [1.0e-6, 1, 1]}}, axes: [x]}}
      - {{box: {{min: [-1, -1, -1.0e-6], max: [1, 1, 1.0e-6]}}, axes: [z]}}
{1}
)",
                     mesh, rigid);
}

/// The area-weighted mean y of the column's top face (linear triangles: a third of each
/// triangle's area to each of its nodes — the nodal loads of a uniform pressure); the
/// triangles are those of model m (one with contact), the positions s's.
double top_mean_y(const Model& m, const State& s) {
  double sum = 0, area = 0;
  for (const auto& t : m.collision_triangles) {
    bool top = true;
    for (int32_t i : t) top = top && std::abs(m.fem.rest[3 * i + 1] - 0.02) < 1e-9;
    if (!top) continue;
    const double* p = &m.fem.rest[3 * t[0]];
    const double* q = &m.fem.rest[3 * t[1]];
    const double* r = &m.fem.rest[3 * t[2]];
    const double e1[3] = {q[0] - p[0], q[1] - p[1], q[2] - p[2]}, e2[3] = {r[0] - p[0], r[1] - p[1], r[2] - p[2]};
    const double ar = 0.5 * std::abs(e1[2] * e2[0] - e1[0] * e2[2]);
    for (int32_t i : t) sum += ar / 3 * s.tissue.x[3 * i + 1];
    area += ar;
  }
  return sum / area;
}

}  // namespace

TEST(RigidContact, ABoxRestingOnATissueColumnCompressesItByItsWeightOverEA) {
  STROMA_LONG_TEST();
  // A box 40 × 10 × 40 mm over the 20 × 20 mm top, frictionless: a rigid flat punch on a column
  // on rollers. In linear elasticity its sinking is the self-weight's top displacement averaged
  // over the top by area (Betti: the punch's uniaxial pressure is uniform) plus m·g·H/(E·A).
  // The self-weight part from a run without the box; both runs settle for 0.6 s (the tissue's
  // damping time is 67 ms).
  const double E = 1.0e4, H = 0.02, A = H * H, rho = 450 * 0.75;
  const double mass = rho * 0.04 * 0.01 * 0.04;
  const auto free = compile_yaml(centred_column_yaml(""));
  State s0 = State::initial(*free);
  TickWorkspace w0(*free);
  const int n = 600;
  for (int k = 0; k < n; ++k) ASSERT_TRUE(tick(*free, s0, w0).status == TickStatus::Ok);
  const auto m = compile_yaml(centred_column_yaml(fmt::format(R"(rigid_bodies:
  - name: box
    shape: {{type: box, size: [0.04, 0.01, 0.04]}}
    density: {}
    pose: {{position: [0, {}, 0]}}
    contact: {{friction: 0}}
)",
                                                              rho, H + 0.005 + 2e-4)));
  State s = State::initial(*m);
  TickWorkspace w(*m);
  for (int k = 0; k < n; ++k) {
    const TickReport& r = tick(*m, s, w);
    ASSERT_TRUE(r.status == TickStatus::Ok) << k << " " << static_cast<int>(r.status);
  }
  const double delta = mass * kG * H / (E * A);  // 0.20 mm: 1 % strain
  const RigidBodyModel& b = m->rigid_bodies[0];
  const double pen = mass * kG / A / b.contact_stiffness;  // the penalty's depth (0.5 µm)
  const double bottom = s.rigid[0].x[1] - 0.005;
  const double sink = top_mean_y(*m, s0) - (bottom + pen);
  EXPECT_NEAR(sink, delta, 0.02 * delta) << "the box sank " << sink << " m below the free top, uniaxial " << delta;
  std::printf("box sank %.4g m beyond the self-weight's top, m g H / (E A) = %.4g m (%+.2f %%)\n", sink, delta,
              100 * (sink / delta - 1));
  // The top under it is flat and the box on it.
  EXPECT_NEAR(top_mean_y(*m, s), bottom + pen, 0.02 * delta);
  EXPECT_LT(std::abs(s.rigid[0].v[1]), 1e-4);
  // Level, still and in the middle: the contact makes no lateral force or torque of its own.
  EXPECT_LT(std::abs(s.rigid[0].x[0]) + std::abs(s.rigid[0].x[2]), 1e-6);
  EXPECT_LT(std::abs(s.rigid[0].w[0]) + std::abs(s.rigid[0].w[2]), 1e-4);
  // The contacts' force on the box carries its weight.
  EXPECT_NEAR(w.report.rigid_contact[0].force[1], mass * kG, 0.01 * mass * kG);
}

namespace {

/// The drop of the two tests below: a 10 mm plastic cube (1.2 g) tilted 25° about x and 15°
/// about z, 10 mm above an undamped 10 kPa tissue cube fixed at its bottom (column_yaml) — its
/// solver line replaced by `solver` when given.
std::string tilted_cube_drop_yaml(const std::string& solver = "") {
  const double a = 0.01, rho = 1200, y0 = 0.02 + 0.01 + a;
  const double qx = std::sin(12.5 * M_PI / 180), qz = std::sin(7.5 * M_PI / 180);
  const double cx = std::cos(12.5 * M_PI / 180), cz = std::cos(7.5 * M_PI / 180);
  const double q[4] = {cz * cx, cz * qx, -qz * qx, qz * cx};  // q = q_z ⊗ q_x
  std::string yaml = column_yaml(1.0e4, 0, fmt::format(R"(  - name: cube
    shape: {{type: box, size: [{0}, {0}, {0}]}}
    density: {1}
    pose: {{position: [0.01, {2}, 0.01], orientation: [{3}, {4}, {5}, {6}]}}
)",
                                                       a, rho, y0, q[0], q[1], q[2], q[3]));
  if (!solver.empty()) {
    const size_t at = yaml.find("solver: "), end = yaml.find('\n', at);
    yaml.replace(at, end - at, solver);
  }
  return yaml;
}

/// The drop's energy but the contacts' penalty potential: the tissue's kinetic, elastic and
/// gravity's, the box's kinetic and gravity's.
double drop_energy(const Model& m, const State& s, const TickWorkspace& w) {
  const RigidBodyModel& b = m.rigid_bodies[0];
  const TimeStepper& st = w.stepper();
  return st.kinetic_energy(s.tissue) + st.elastic_energy(s.tissue) + st.external_potential(s.tissue) +
         rigid_kinetic_energy(b.mass.mass, b.mass.inertia, s.rigid[0]) + b.mass.mass * kG * s.rigid[0].x[1];
}

}  // namespace

TEST(RigidContact, ABoxDroppedOnTissueOnItsEdgeNeverGainsEnergyAndComesToRestOnIt) {
  STROMA_LONG_TEST();
  // The tilted cube dropped on the tissue: it lands on a corner, turns and settles. Energy:
  // drop_energy and the contacts' penalty potential (reported by the next tick's collide, at
  // the state it starts from). (A ball would roll away: on an elastic surface rolling costs
  // nothing.)
  const double a = 0.01;
  const auto m = compile_yaml(tilted_cube_drop_yaml());
  State s = State::initial(*m);
  TickWorkspace w(*m);
  const RigidBodyModel& b = m->rigid_bodies[0];
  const double mb = b.mass.mass;
  auto energy_without_contact = [&]() { return drop_energy(*m, s, w); };
  const double scale = mb * kG * 0.01;  // the drop's energy
  double e_state = energy_without_contact();
  const double e0 = e_state;
  double max_gain = -1e300, max_step_gain = -1e300, e_last = e0;
  bool touched = false;
  const int n = 1000;
  double mean_force = 0;  // over the last 500 ticks: the undamped tissue still rings
  for (int k = 0; k < n; ++k) {
    const TickReport& rep = tick(*m, s, w);
    ASSERT_TRUE(rep.status == TickStatus::Ok) << k;
    if (k >= n - 500) mean_force += rep.rigid_contact[0].force[1] / 500;
    // The state before this tick, its contacts' potential included.
    const double e_before = e_state + rep.rigid_contact[0].energy;
    max_gain = std::max(max_gain, e_before - e0);
    max_step_gain = std::max(max_step_gain, e_before - e_last);
    e_last = e_before;
    touched = touched || rep.rigid_contact[0].contacts > 0;
    e_state = energy_without_contact();
  }
  EXPECT_TRUE(touched);
  EXPECT_LT(max_gain, 1e-3 * scale) << "energy rose above its start by " << max_gain << " J (drop " << scale << " J)";
  EXPECT_LT(max_step_gain, 1e-2 * scale) << "largest gain in one tick " << max_step_gain << " J";
  std::printf("drop %.3g J; largest rise above the start %.3g J, in one tick %.3g J; left %.3g J\n", scale, max_gain,
              max_step_gain, e_last - e0);
  // At rest on the tissue, on a face: its lowest corner at the top surface, level, still.
  const auto R = rotation_of(s.rigid[0].q);
  EXPECT_GT(std::abs(R[4]), 0.995) << "not resting on a face";  // its y axis vertical
  const double bottom = s.rigid[0].x[1] - 0.5 * a;
  EXPECT_GT(bottom, 0.019);
  EXPECT_LT(bottom, 0.0201);
  EXPECT_LT(std::abs(s.rigid[0].v[1]) + std::abs(s.rigid[0].v[0]) + std::abs(s.rigid[0].v[2]), 0.01);
  EXPECT_NEAR(mean_force, mb * kG, 0.05 * mb * kG);
}

// The same drop with CG cut to two iterations a step and the capped steps kept (what a budget
// does on a loaded machine): an inexact step may gain energy, and with a body in the step's
// rows the energy guard's account takes in the body's kinetic and gravitational energy and the
// contact springs' potential with the box's points moving (engine/step_with_recovery.cpp,
// guard_rows) — the box and the tissue together never gain energy: the guard takes it out
// where a step would.
// The same drop redone in sub-steps at every tick (`on_cg_cap: substep`, CG capped at 2: the
// tick's step and the 2-, 4- and 8-sub-step levels capped, so 16 sub-steps whose capped solves
// are kept). The springs are found at the tick's start; each sub-step evaluates them where it
// starts (f − K·d). Before, a sub-step was asked to close a speculative spring's whole gap and
// every tick from the landing on was rolled back unadvanced (548 of 600). Now no tick fails and
// the box stays on the tissue — but not where the full steps put it: it sinks up to 4 mm deeper
// and keeps rocking ±1.3 mm (docs/RIGID.md: not yet understood), so the bound here is loose.
TEST(RigidContact, ABoxDroppedOnTissueInSubStepsAdvancesEveryTickAndStaysOnIt) {
  STROMA_LONG_TEST();  // ~10 s
  auto run = [](const std::string& solver, std::vector<double>& height, int& failed, int& substepped) {
    const auto m = compile_yaml(tilted_cube_drop_yaml(solver));
    State s = State::initial(*m);
    TickWorkspace w(*m);
    failed = substepped = 0;
    for (int k = 0; k < 300; ++k) {
      const TickReport& rep = tick(*m, s, w);
      failed += rep.status == TickStatus::NonFinite;
      substepped += rep.substeps > 1 && rep.rigid_contact[0].contacts > 0;
      height.push_back(s.rigid[0].x[1]);
    }
  };
  std::vector<double> full, sub;
  int full_failed = 0, sub_failed = 0, full_sub = 0, sub_sub = 0;
  run("solver: {integrator: implicit_euler, preconditioner: block_jacobi, tolerance: 1.0e-10, max_iterations: 500}",
      full, full_failed, full_sub);
  run("solver: {integrator: implicit_euler, preconditioner: block_jacobi, tolerance: 1.0e-10, max_iterations: 2, "
      "on_cg_cap: substep}",
      sub, sub_failed, sub_sub);
  EXPECT_EQ(full_failed, 0);
  EXPECT_EQ(sub_failed, 0) << "ticks rolled back unadvanced";
  EXPECT_GT(sub_sub, 100) << "ticks in contact redone in sub-steps";
  double worst = 0, drop = full.front() - *std::min_element(full.begin(), full.end());
  for (size_t k = 0; k < full.size(); ++k) worst = std::max(worst, std::abs(sub[k] - full[k]));
  std::printf("box height, sub-steps against converged full steps: at most %.3g mm apart (it fell %.3g mm)\n",
              1e3 * worst, 1e3 * drop);
  ASSERT_GT(drop, 0.009) << "it fell onto the tissue and pressed it";
  EXPECT_LT(worst, 0.5 * drop);
}

TEST(RigidContact, ABoxDroppedOnTissueWithItsSolvesCutShortNeverGainsEnergy) {
  const auto m = compile_yaml(tilted_cube_drop_yaml(
      "solver: {integrator: implicit_euler, preconditioner: block_jacobi, tolerance: 1.0e-10, max_iterations: 2, "
      "on_cg_cap: continue}"));
  State s = State::initial(*m);
  TickWorkspace w(*m);
  const double mb = m->rigid_bodies[0].mass.mass;
  auto energy_without_contact = [&]() { return drop_energy(*m, s, w); };
  const double scale = mb * kG * 0.01;  // the drop's energy
  double e_state = energy_without_contact();
  const double e0 = e_state;
  double max_gain = -1e300, max_step_gain = -1e300, e_last = e0;
  int touching = 0, limited = 0;
  for (int k = 0; k < 600; ++k) {
    const TickReport& rep = tick(*m, s, w);
    ASSERT_TRUE(rep.status == TickStatus::Ok || rep.status == TickStatus::SolverNotConverged) << k;
    const double e_before = e_state + rep.rigid_contact[0].energy;
    max_gain = std::max(max_gain, e_before - e0);
    max_step_gain = std::max(max_step_gain, e_before - e_last);
    e_last = e_before;
    touching += rep.rigid_contact[0].contacts > 0;
    limited += rep.energy_limit != EnergyLimit::None && rep.rigid_contact[0].contacts > 0;
    e_state = energy_without_contact();
  }
  EXPECT_GT(touching, 100) << "the box lands";
  EXPECT_GT(limited, 0) << "the guard acted on steps with the box in the rows";
  EXPECT_LT(max_gain, 1e-3 * scale) << "energy rose above its start by " << max_gain << " J (drop " << scale << " J)";
  // (Without the bodies in the account — the guard off while they have rows, as before — the
  // largest gain in a tick was 4.6e-3 of the drop; with them 1e-4, the contact potential
  // reported at the next collide against the step's linear one.)
  EXPECT_LT(max_step_gain, 1e-3 * scale) << "largest gain in one tick " << max_step_gain << " J";
  std::printf("CG capped at 2: drop %.3g J; largest rise above the start %.3g J, in one tick %.3g J; %d ticks in "
              "contact, %d limited by the guard\n",
              scale, max_gain, max_step_gain, touching, limited);
}

namespace {

/// A 20 mm box resting on a fixed slab tilted by θ about z, friction μ on both.
std::string slope_yaml(double theta, double mu) {
  const double c = std::cos(theta / 2), sn = std::sin(theta / 2);
  // The slab's top face (its local +y) through the origin; the box on it, its bottom touching.
  const double ny[2] = {-std::sin(theta), std::cos(theta)};
  const double slab_c[2] = {-0.005 * ny[0], -0.005 * ny[1]};
  const double box_c[2] = {0.01 * ny[0], 0.01 * ny[1]};
  return test_scenarios::rigid_scene_head("slope") + fmt::format(R"(rigid_bodies:
  - name: slab
    shape: {{type: box, size: [0.4, 0.01, 0.1]}}
    density: 1000
    pose: {{position: [{0}, {1}, 0], orientation: [{2}, 0, 0, {3}]}}
    fixed: true
    contact: {{stiffness: 1.0e7, friction: {4}}}
  - name: box
    shape: {{type: box, size: [0.02, 0.02, 0.02]}}
    density: 1000
    pose: {{position: [{5}, {6}, 0], orientation: [{2}, 0, 0, {3}]}}
    contact: {{stiffness: 1.0e7, friction: {4}}}
)",
                     slab_c[0], slab_c[1], c, sn, mu, box_c[0], box_c[1]);
}

/// The box's speed down the slope over [t0, t1] (s): its mean acceleration along it.
double slope_acceleration(double theta, double mu, double* creep = nullptr) {
  const auto m = compile_yaml(slope_yaml(theta, mu));
  State s = State::initial(*m);
  TickWorkspace w(*m);
  const double down[2] = {-std::cos(theta), -std::sin(theta)};
  auto along = [&]() { return s.rigid[1].v[0] * down[0] + s.rigid[1].v[1] * down[1]; };
  for (int k = 0; k < 100; ++k) EXPECT_TRUE(tick(*m, s, w).status == TickStatus::Ok);
  const double v0 = along();
  for (int k = 0; k < 200; ++k) EXPECT_TRUE(tick(*m, s, w).status == TickStatus::Ok);
  if (creep) *creep = along();
  EXPECT_GT(w.report.rigid_contact[1].contacts, 0);
  return (along() - v0) / 0.2;
}

}  // namespace

TEST(RigidContact, ABoxOnASlopeSlidesAtGTimesSinMinusMuCosAndSticksWhenMuExceedsTheTangent) {
  const double theta = 30 * M_PI / 180;
  const double a = slope_acceleration(theta, 0.2);
  const double expect = kG * (std::sin(theta) - 0.2 * std::cos(theta));  // 3.21 m/s²
  EXPECT_NEAR(a, expect, 0.03 * expect);
  std::printf("slope 30 deg, mu 0.2: a = %.4g m/s^2, g (sin - mu cos) = %.4g (%+.2f %%)\n", a, expect, 100 * (a / expect - 1));
  double creep = 0;
  const double a_stick = slope_acceleration(20 * M_PI / 180, 0.6, &creep);  // tan 20° = 0.36 < 0.6
  EXPECT_LT(std::abs(a_stick), 0.01);
  EXPECT_LT(std::abs(creep), 1e-3);  // the regularised stick creeps at most at its slip speed
  std::printf("slope 20 deg, mu 0.6: a = %.3g m/s^2, creep %.3g m/s\n", a_stick, creep);
}

TEST(RigidRows, TheEliminatedSolveIsTheWholeSystemsSolve) {
  // Two tissue nodes (free), one body; three springs: node–body, node–body at another arm, and
  // body–fixed anchor. The Schur-complement path against a dense solve of the 12×12 system.
  FemModel fm;
  fm.num_nodes = 2;
  fm.constrained.assign(2, 0);
  const double h = 1e-3;
  std::vector<ContactSpring> sp(3);
  auto set_k = [](ContactSpring& c, double k, double cdamp, const double* n) {
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b) {
        c.K[3 * a + b] = k * n[a] * n[b] + (a == b ? 0.1 * k : 0.0);
        c.C[3 * a + b] = cdamp * (a == b ? 1.0 : 0.0);
      }
  };
  const double n0[3] = {0, 1, 0}, n1[3] = {0.6, 0.8, 0}, n2[3] = {0, 0, 1};
  sp[0].n = 1, sp[0].node[0] = 0, sp[0].w[0] = 1, sp[0].row_n = 0;
  sp[0].arm_n[0] = 0.01, sp[0].arm_n[1] = -0.005, sp[0].arm_n[2] = 0.002;
  set_k(sp[0], 500, 0.3, n0);
  sp[0].force[1] = 0.2;
  sp[1].n = 2, sp[1].node[0] = 0, sp[1].node[1] = 1, sp[1].w[0] = 0.3, sp[1].w[1] = 0.7, sp[1].row_n = 0;
  sp[1].arm_n[0] = -0.01, sp[1].arm_n[2] = 0.004;
  set_k(sp[1], 800, 0.1, n1);
  sp[1].force[0] = 0.05;
  sp[2].n = 0, sp[2].row_p = 0;
  sp[2].arm_p[1] = 0.003;
  set_k(sp[2], 300, 0.0, n2);
  sp[2].force[2] = -0.1;
  const double mt[2] = {0.002, 0.003}, vt0[6] = {0.1, -0.2, 0.05, 0, 0.3, -0.1};
  double mass = 0.01, I[9] = {2e-6, 1e-7, 0, 1e-7, 3e-6, 0, 0, 0, 2.5e-6}, u0[6] = {0.05, -0.4, 0.1, 2, -1, 0.5};
  double force[6] = {0, -mass * kG, 0, 0, 0, 0}, du[6];
  RigidRowsInput in;
  in.rows = 1, in.mass = &mass, in.inertia = I, in.u0 = u0, in.force = force, in.du = du;
  // The dense system, from the definitions: G = [W, −J] per spring (tissue/body) or [+J] (body–fixed).
  Eigen::MatrixXd Mfull = Eigen::MatrixXd::Zero(12, 12), Kfull = Eigen::MatrixXd::Zero(12, 12);
  Eigen::VectorXd u = Eigen::VectorXd::Zero(12), f = Eigen::VectorXd::Zero(12);
  for (int i = 0; i < 2; ++i)
    for (int k = 0; k < 3; ++k) Mfull(3 * i + k, 3 * i + k) = mt[i], u(3 * i + k) = vt0[3 * i + k];
  for (int k = 0; k < 3; ++k) Mfull(6 + k, 6 + k) = mass;
  for (int a = 0; a < 3; ++a)
    for (int b = 0; b < 3; ++b) Mfull(9 + a, 9 + b) = I[3 * a + b];
  for (int k = 0; k < 6; ++k) u(6 + k) = u0[k], f(6 + k) = force[k];
  for (const ContactSpring& c : sp) {
    Eigen::MatrixXd G = Eigen::MatrixXd::Zero(3, 12);
    for (int a = 0; a < c.n; ++a) G.block(0, 3 * c.node[a], 3, 3) += c.w[a] * Eigen::Matrix3d::Identity();
    auto J = [](const double* r) {
      Eigen::MatrixXd j(3, 6);
      j << 1, 0, 0, 0, r[2], -r[1], 0, 1, 0, -r[2], 0, r[0], 0, 0, 1, r[1], -r[0], 0;
      return j;
    };
    if (c.row_p >= 0) G.block(0, 6, 3, 6) += J(c.arm_p);
    if (c.row_n >= 0) G.block(0, 6, 3, 6) -= J(c.arm_n);
    const Eigen::Matrix3d K = Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(c.K);
    const Eigen::Matrix3d C = Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(c.C);
    const Eigen::Vector3d fs(c.force[0], c.force[1], c.force[2]);
    Kfull += G.transpose() * (h * h * K + h * C) * G;
    f += G.transpose() * fs;
  }
  const Eigen::MatrixXd A = Mfull + Kfull;
  const Eigen::VectorXd b = h * f - Kfull * u;
  const Eigen::VectorXd x = A.ldlt().solve(b);
  // The rows' path: the tissue's own part as the stepper forms it, then the Schur complement.
  RigidRows rows;
  rows.reserve(1);
  Eigen::VectorXd rhs_t(6);
  Eigen::MatrixXd Att = Mfull.block(0, 0, 6, 6);
  for (const ContactSpring& c : sp) {
    if (c.n == 0) continue;
    Eigen::MatrixXd W = Eigen::MatrixXd::Zero(3, 6);
    for (int a = 0; a < c.n; ++a) W.block(0, 3 * c.node[a], 3, 3) += c.w[a] * Eigen::Matrix3d::Identity();
    const Eigen::Matrix3d K = Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(c.K);
    const Eigen::Matrix3d C = Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(c.C);
    Att += W.transpose() * (h * h * K + h * C) * W;
  }
  Eigen::VectorXd ft = Eigen::VectorXd::Zero(6);
  for (const ContactSpring& c : sp)
    for (int a = 0; a < c.n; ++a)
      for (int k = 0; k < 3; ++k) ft(3 * c.node[a] + k) += c.w[a] * c.force[k];
  rhs_t = h * ft + Mfull.block(0, 0, 6, 6) * u.head(6) - Att * u.head(6);
  ASSERT_TRUE(rows.assemble(in, sp.data(), 3, h, vt0, rhs_t.data(), fm));
  rows.reduce_rhs(rhs_t.data());
  // S = A_tt − B A⁻¹ Bᵀ, column by column through apply().
  Eigen::MatrixXd S(6, 6);
  for (int j = 0; j < 6; ++j) {
    Eigen::VectorXd e = Eigen::VectorXd::Unit(6, j), y = Att * e;
    rows.apply(e.data(), y.data());
    S.col(j) = y;
  }
  EXPECT_LT((S - S.transpose()).norm(), 1e-12 * S.norm());
  const Eigen::VectorXd dv = S.ldlt().solve(rhs_t);
  rows.back_substitute(dv.data());
  for (int k = 0; k < 6; ++k) EXPECT_NEAR(dv(k), x(k), 1e-10 * (1 + x.head(6).norm())) << k;
  for (int k = 0; k < 6; ++k) EXPECT_NEAR(du[k], x(6 + k), 1e-10 * (1 + x.tail(6).norm())) << k;
}

TEST(RigidContact, AnImpactOnACoarseBlockNeverTakesTheEnergyAboveItsStart) {
  // The contact path in a few ticks (also under the sanitizers): a 10 mm cube tilted on its edge
  // falls 2 mm onto a 4³-cell, 20 mm block (125 nodes) and bounces; the energy of the state each
  // tick starts from (tissue, body, the contacts' penalty) never rises above its start. (Tick to
  // tick it may, on a mesh this coarse: by up to 2 % of the drop's energy when a step keeps
  // speculative contacts after its releases — docs/RIGID.md; the fine-mesh test above holds it
  // tick to tick.)
  static const std::string mesh = [] {
    const std::string path = write_temp("coarse_block.msh", "");
    write_tet_mesh(path, box_mesh(4, 4, 4, {0.02, 0.02, 0.02}));
    return path;
  }();
  const double c = std::cos(10 * M_PI / 180), sn = std::sin(10 * M_PI / 180);
  const auto m = compile_yaml(fmt::format(R"(name: coarse_impact
time_step: 0.001
gravity: [0, -9.81, 0]
solver: {{integrator: implicit_euler, preconditioner: block_jacobi, tolerance: 1.0e-10, max_iterations: 1000}}
bodies:
  - name: block
    mesh: {0}
    material: {{young_modulus: 1.0e4, poisson_ratio: 0.45, density: 1000}}
    fixed:
      - box: {{min: [-1, -1.0e-6, -1], max: [1, 1.0e-6, 1]}}
rigid_bodies:
  - name: cube
    shape: {{type: box, size: [0.01, 0.01, 0.01]}}
    density: 1200
    pose: {{position: [0.01, 0.0291, 0.01], orientation: [{1}, {2}, 0, 0]}}
)",
                                          mesh, c, sn));
  State s = State::initial(*m);
  TickWorkspace w(*m);
  const RigidBodyModel& b = m->rigid_bodies[0];
  auto energy = [&]() {
    const TimeStepper& st = w.stepper();
    return st.kinetic_energy(s.tissue) + st.elastic_energy(s.tissue) + st.external_potential(s.tissue) +
           rigid_kinetic_energy(b.mass.mass, b.mass.inertia, s.rigid[0]) + b.mass.mass * kG * s.rigid[0].x[1];
  };
  double e_state = energy(), e_last = e_state, max_rise = -1e300, max_above = -1e300;
  const double e0 = e_state;
  int touching = 0;
  for (int k = 0; k < 120; ++k) {
    const TickReport& r = tick(*m, s, w);
    ASSERT_TRUE(r.status == TickStatus::Ok) << k;
    const double e_before = e_state + r.rigid_contact[0].energy;
    max_rise = std::max(max_rise, e_before - e_last);
    max_above = std::max(max_above, e_before - e0);
    e_last = e_before;
    e_state = energy();
    touching += r.rigid_contact[0].contacts > 0;
  }
  EXPECT_GT(touching, 20);
  const double drop = b.mass.mass * kG * 0.002;
  EXPECT_LT(max_above, 1e-6 * drop) << "energy rose above its start by " << max_above << " J";
  EXPECT_LT(max_rise, 0.05 * drop) << "energy rose by " << max_rise << " J in one tick";
  std::printf("coarse impact: drop %.3g J, largest rise above the start %.3g J, in one tick %.3g J\n", drop, max_above,
              max_rise);
  EXPECT_GT(s.rigid[0].x[1], 0.02);  // on the block, not through it
}
