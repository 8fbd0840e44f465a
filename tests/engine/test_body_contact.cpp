// Body–body contact (a body dropped onto a fixed one): a bar dropped onto a fixed
// block comes to rest on it carrying exactly its weight; bodies that miss each other fall
// freely (implicit Euler's exact free fall); two free bars colliding head-on bounce apart without
// passing through, conserving momentum; scenario errors name file, line and field.

#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include <fmt/format.h>

#include "engine/model.hpp"
#include "engine/state.hpp"
#include "engine/tick.hpp"
#include "scene/compiled_scenario.hpp"
#include "scene/scenario_spec.hpp"
#include "tests/test_labels.hpp"
#include "tissue/input_error.hpp"

using namespace stroma;

namespace {

const std::string kSrc = STROMA_SOURCE_DIR;

/// A fixed 50 mm cube (top face at y = 0.05) and a 40 × 4 × 4 mm bar (the cantilever mesh at
/// scale 0.4, 191 nodes) placed `gap` above it at x offset `dx`.
std::string drop_yaml(double gap, double dx, bool contact) {
  return fmt::format(R"(name: drop
time_step: 0.001
gravity: [0, -9.81, 0]
solver: {{integrator: implicit_euler, preconditioner: block_jacobi, tolerance: 1.0e-10, max_iterations: 1000}}
bodies:
  - name: base
    mesh: {0}/scenarios/meshes/cube_tet4_h5p000mm.msh
    material: {{young_modulus: 1.0e5, poisson_ratio: 0.3, density: 1000}}
    fixed:
      - box: {{min: [-1, -1, -1], max: [1, 1, 1]}}
  - name: bar
    mesh: {0}/scenarios/meshes/beam_tet4_h5p000mm.msh
    scale: 0.4
    translate: [{1}, {2}, 0.02]
    material: {{young_modulus: 1.0e5, poisson_ratio: 0.3, density: 1000, rayleigh_mass: 20}}
probes:
  - {{name: bottom, body: bar, point: [{3}, {2}, 0.022]}}
{4}
)",
                     kSrc, 0.005 + dx, 0.05 + gap, 0.025 + dx, contact ? "body_contact: {}" : "");
}

std::shared_ptr<const Model> compile_yaml(const std::string& yaml) {
  return compile_model(parse_scenario(yaml, "test.yaml", kSrc));
}

/// Sum of the contact forces on the vertices of body b (the vertex sides of the springs).
Vec3 force_on_body(const Model& m, const TickWorkspace& w, int b) {
  Vec3 f{0, 0, 0};
  const BodyRange& r = m.fem.bodies[b];
  for (const ContactSpring& sp : w.springs)
    for (int a = 0; a < 3; ++a)
      if (sp.node[a] >= r.node_begin && sp.node[a] < r.node_end)
        for (int k = 0; k < 3; ++k) f[k] += sp.w[a] * sp.force[k];
  return f;
}

double body_mass(const Model& m, int b) {
  double mass = 0;
  for (int32_t i = m.fem.bodies[b].node_begin; i < m.fem.bodies[b].node_end; ++i) mass += m.fem.mass[i];
  return mass;
}

}  // namespace

TEST(BodyContact, BarDroppedOntoAFixedBlockRestsOnItCarryingItsWeight) {
  STROMA_LONG_TEST();
  const double gap = 0.005;
  auto m = compile_yaml(drop_yaml(gap, 0.0, true));
  ASSERT_TRUE(m->body_contact.has_value());
  EXPECT_TRUE(m->fem.ranges[0].fixed);  // the block is an obstacle: the elastic pass skips it
  EXPECT_FALSE(m->fem.ranges[1].fixed);
  State s = State::initial(*m);
  TickWorkspace w(*m);
  double min_dy = 0;
  for (int k = 0; k < 400; ++k) {
    const TickReport& r = tick(*m, s, w);
    ASSERT_NE(r.status, TickStatus::NonFinite);
    min_dy = std::min(min_dy, probe_displacement(*m, s, m->probes[0])[1]);
  }
  const double weight = body_mass(*m, 1) * 9.81;
  const Vec3 f = force_on_body(*m, w, 1);
  // At rest the contact carries the weight, vertically.
  EXPECT_NEAR(f[1], weight, 0.01 * weight);
  EXPECT_LT(std::hypot(f[0], f[2]), 0.01 * weight);
  EXPECT_GT(w.report.body_contact.contacts, 0);
  // It rests on the top face: penetration δ > 0 but small (pressure ρgh over k), never fell in.
  const double dy = probe_displacement(*m, s, m->probes[0])[1];
  const double delta = -dy - gap;
  const double pressure = 1000 * 9.81 * 0.004;  // ρ g × the bar's thickness
  EXPECT_GT(delta, 0.0);
  EXPECT_LT(delta, 10 * pressure / m->body_contact->stiffness) << "δ " << delta;
  EXPECT_GT(min_dy, -gap - m->body_contact->body_depth[0]);
  EXPECT_NEAR(w.report.body_contact.max_depth, delta, 0.5 * delta);
  // The bar did not drift sideways off the block.
  const Vec3 u = probe_displacement(*m, s, m->probes[0]);
  EXPECT_LT(std::hypot(u[0], u[2]), 1e-4);
}

TEST(BodyContact, ImpactAtLargeStepsStoresNoPenaltyEnergyAboveTheKineticEnergy) {
  // 20 mm drop at dt = 10 ms: the bar covers 6 mm in the impact step. Without speculative
  // contacts it would sink that far unopposed, storing ½kAδ² ≈ 80× the impact energy.
  ScenarioSpec spec = parse_scenario(drop_yaml(0.02, 0.0, true), "test.yaml", kSrc);
  spec.time_step = 0.01;
  auto m = compile_model(spec);
  State s = State::initial(*m);
  TickWorkspace w(*m);
  const double impact = body_mass(*m, 1) * 9.81 * 0.02;  // m g H
  double worst = 0;
  for (int k = 0; k < 40; ++k) {
    tick(*m, s, w);
    worst = std::max(worst, w.report.body_contact.energy);  // penetration at the start of each tick
  }
  EXPECT_GT(w.report.body_contact.contacts, 0);
  EXPECT_LT(worst, 0.05 * impact) << "penalty energy " << worst << " J vs impact " << impact << " J";
  const BodyRange& bar = m->fem.bodies[1];
  double lowest = 1e300;
  for (int32_t i = bar.node_begin; i < bar.node_end; ++i) lowest = std::min(lowest, s.tissue.x[3 * i + 1]);
  EXPECT_NEAR(lowest, 0.05, 1e-5);  // resting on the top face
}

TEST(BodyContact, BodiesThatMissEachOtherFallExactlyAsImplicitEulerFreeFall) {
  // The bar is 0.1 m to the side of the block: contact is on but finds nothing.
  auto m = compile_yaml(drop_yaml(0.005, 0.1, true));
  State s = State::initial(*m);
  TickWorkspace w(*m);
  const double h = m->time_step, g = 9.81;
  const int n = 150;
  for (int k = 0; k < n; ++k) tick(*m, s, w);
  EXPECT_EQ(w.report.body_contact.contacts, 0);
  EXPECT_TRUE(w.springs.empty());
  // Backward Euler free fall with Rayleigh mass damping α: v ← (v − g h)/(1 + α h).
  const double alpha = 20;
  double v = 0, y = 0;
  for (int k = 0; k < n; ++k) {
    v = (v - g * h) / (1 + alpha * h);
    y += v * h;
  }
  EXPECT_NEAR(probe_displacement(*m, s, m->probes[0])[1], y, 1e-9);
}

TEST(BodyContact, WithoutTheSectionTwoBodiesPayNothingAndPassThrough) {
  auto m = compile_yaml(drop_yaml(0.005, 0.0, false));
  EXPECT_FALSE(m->has_contact);
  EXPECT_FALSE(m->body_contact.has_value());
  State s = State::initial(*m);
  TickWorkspace w(*m);
  TickReport r;
  for (int k = 0; k < 100; ++k) r = tick(*m, s, w);
  EXPECT_FALSE(r.stage_ran[static_cast<int>(Stage::Collide)]);
  EXPECT_LT(probe_displacement(*m, s, m->probes[0])[1], -0.005 - 0.004);  // through the block
}

TEST(BodyContact, TwoFreeBarsCollideHeadOnBounceApartAndConserveMomentum) {
  const std::string yaml = fmt::format(R"(name: head_on
time_step: 0.001
gravity: [0, 0, 0]
solver: {{integrator: implicit_euler, preconditioner: block_jacobi, tolerance: 1.0e-10, max_iterations: 1000}}
bodies:
  - name: left
    mesh: {0}/scenarios/meshes/beam_tet4_h5p000mm.msh
    scale: 0.4
    material: {{young_modulus: 1.0e5, poisson_ratio: 0.3, density: 1000}}
  - name: right
    mesh: {0}/scenarios/meshes/beam_tet4_h5p000mm.msh
    scale: 0.4
    translate: [0.042, 0.001, 0.001]
    material: {{young_modulus: 1.0e5, poisson_ratio: 0.3, density: 1000}}
body_contact: {{}}
)",
                                       kSrc);
  auto m = compile_yaml(yaml);
  State s = State::initial(*m);
  // m/s each, towards each other along x: 0.3 mm per tick closing, within the resolvable depth
  // (1 mm: a quarter of the bars' thickness).
  const double v0 = 0.15;
  const BodyRange &L = m->fem.bodies[0], &R = m->fem.bodies[1];
  for (int32_t i = L.node_begin; i < L.node_end; ++i) s.tissue.v[3 * i] = v0;
  for (int32_t i = R.node_begin; i < R.node_end; ++i) s.tissue.v[3 * i] = -v0;
  TickWorkspace w(*m);
  auto momentum = [&](const BodyRange& b) {
    Vec3 p{0, 0, 0};
    for (int32_t i = b.node_begin; i < b.node_end; ++i)
      for (int k = 0; k < 3; ++k) p[k] += m->fem.mass[i] * s.tissue.v[3 * i + k];
    return p;
  };
  auto max_x = [&](const BodyRange& b) {
    double v = -1e300;
    for (int32_t i = b.node_begin; i < b.node_end; ++i) v = std::max(v, s.tissue.x[3 * i]);
    return v;
  };
  auto min_x = [&](const BodyRange& b) {
    double v = 1e300;
    for (int32_t i = b.node_begin; i < b.node_end; ++i) v = std::min(v, s.tissue.x[3 * i]);
    return v;
  };
  const double p0 = momentum(L)[0];
  bool touched = false;
  double worst_overlap = 0;
  for (int k = 0; k < 150; ++k) {
    tick(*m, s, w);
    touched |= w.report.body_contact.contacts > 0;
    worst_overlap = std::max(worst_overlap, max_x(L) - min_x(R));
  }
  ASSERT_TRUE(touched);
  // Never passed through: the overlap stays within the resolvable depth.
  EXPECT_LT(worst_overlap, m->body_contact->body_depth[1]);
  // They separated, moving apart (implicit Euler dissipates part of the impact).
  EXPECT_LT(momentum(L)[0], -0.2 * p0);
  EXPECT_GT(momentum(R)[0], 0.2 * p0);
  EXPECT_EQ(w.report.body_contact.contacts, 0);
  // Total momentum: zero before; the exchange is antisymmetric up to the one-tick lag of the
  // cross-body stiffness coupling.
  const Vec3 pl = momentum(L), pr = momentum(R);
  for (int k = 0; k < 3; ++k) EXPECT_LT(std::abs(pl[k] + pr[k]), 0.02 * p0) << "axis " << k;
  std::printf("head-on: momentum after %.4g %.4g (before %.4g), worst overlap %.3g mm\n", pl[0], pr[0], p0,
              worst_overlap * 1e3);
}

TEST(BodyContact, ScenarioErrorsNameTheField) {
  auto fails_with = [](const std::string& yaml, const std::string& what) {
    try {
      parse_scenario(yaml, "s.yaml", kSrc);
      ADD_FAILURE() << "no error for: " << what;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(what), std::string::npos) << e.what();
    }
  };
  const std::string one_body = R"(name: x
bodies:
  - name: a
    mesh: m.msh
    material: {young_modulus: 1.0e5, poisson_ratio: 0.3, density: 1000}
)";
  fails_with(one_body + "body_contact: {}\n", "s.yaml:6: body_contact: body_contact needs at least two bodies");
  const std::string two = one_body + R"(  - name: b
    mesh: m.msh
    translate: [0, 1]
    material: {young_modulus: 1.0e5, poisson_ratio: 0.3, density: 1000}
)";
  fails_with(two, "s.yaml:8: bodies[1].translate");
  const std::string two_ok = one_body + R"(  - name: b
    mesh: m.msh
    material: {young_modulus: 1.0e5, poisson_ratio: 0.3, density: 1000}
)";
  fails_with(two_ok + "body_contact: {stiffness: -1}\n", "s.yaml:9: body_contact.stiffness");
  fails_with(two_ok + "body_contact: {stifness: 1}\n", "did you mean 'stiffness'");
}
