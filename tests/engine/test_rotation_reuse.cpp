// The energy guard's element rotations reused by the next assemble (TimeStepper::end_rot_):
// the guard evaluates the step's end, which is where the next step starts, so the polar
// decompositions need not be done twice. Checked here: an element pass given rotations
// (ElasticPass::rotations_in) computes the same forces, tangent and energy as one that
// computes them, and actually uses what it is given; the stepper reuses the guard's rotations
// exactly when the positions are those the guard saw, never after they moved.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "engine/model.hpp"
#include "engine/state.hpp"
#include "engine/tick.hpp"
#include "scene/compiled_scenario.hpp"
#include "scene/scenario_spec.hpp"
#include "tests/test_labels.hpp"
#include "tissue/fem_forces.hpp"
#include "tests/test_scenarios.hpp"

using namespace stroma;

namespace {

std::shared_ptr<const Model> cantilever() {
  ScenarioSpec spec = test_scenarios::cantilever_dynamic();
  return compile_model(spec);
}

/// Positions rotated by 0.6 rad about z plus 0.3 mm of random noise: large element rotations.
std::vector<double> deformed(const FemModel& fem) {
  std::vector<double> x(fem.rest);
  uint32_t seed = 4242;
  auto rnd = [&] { seed = seed * 1664525u + 1013904223u; return double(seed) / 4294967296.0 - 0.5; };
  const double c = std::cos(0.6), s = std::sin(0.6);
  for (int32_t i = 0; i < fem.num_nodes; ++i) {
    double* p = &x[3 * i];
    const double px = p[0], py = p[1];
    p[0] = c * px - s * py + 3e-4 * rnd();
    p[1] = s * px + c * py + 3e-4 * rnd();
    p[2] += 3e-4 * rnd();
  }
  return x;
}

double max_abs_diff(const std::vector<double>& a, const std::vector<double>& b) {
  double d = 0;
  for (size_t i = 0; i < a.size(); ++i) d = std::max(d, std::abs(a[i] - b[i]));
  return d;
}

double max_abs(const std::vector<double>& a) {
  double d = 0;
  for (double v : a) d = std::max(d, std::abs(v));
  return d;
}

}  // namespace

TEST(RotationReuse, GivenRotationsGiveTheSamePassAndAreUsed) {
  auto m = cantilever();
  const FemModel& fem = m->fem;
  ASSERT_EQ(fem.ranges.at(0).kernel, ElementKernel::CorotationalPolar);
  const std::vector<double> x = deformed(fem);
  const size_t n3 = x.size(), ne = fem.elements.size(), nb = 9 * fem.pattern.nnzb();

  auto full_pass = [&](const double* rotations_in, std::vector<double>& f, std::vector<double>& k,
                       std::vector<double>& rot) {
    f.assign(n3, 0.0);
    k.assign(nb, 0.0);
    rot.assign(9 * ne, 0.0);
    ElasticPass p;
    p.x = x.data();
    p.force = f.data();
    p.kvals = k.data();
    p.k_const = 1.0;
    p.rotations = rot.data();
    p.rotations_in = rotations_in;
    return elastic_pass(fem, p);
  };
  std::vector<double> f0, k0, r0;
  const double e0 = full_pass(nullptr, f0, k0, r0);

  // The energy-only pass (the guard's) hands out the rotations it computed.
  std::vector<double> r_energy(9 * ne, -7.0);
  ElasticPass pe;
  pe.x = x.data();
  pe.rotations = r_energy.data();
  const double e_energy = elastic_pass(fem, pe);
  EXPECT_NEAR(e_energy, e0, 1e-12 * std::abs(e0));
  EXPECT_LT(max_abs_diff(r_energy, r0), 1e-14);
  EXPECT_GT(max_abs_diff(r0, std::vector<double>(9 * ne, 0.0)), 0.5) << "rotations were not written";

  // Given those rotations, the pass computes what it computed on its own.
  std::vector<double> f1, k1, r1;
  const double e1 = full_pass(r_energy.data(), f1, k1, r1);
  EXPECT_NEAR(e1, e0, 1e-12 * std::abs(e0));
  EXPECT_LT(max_abs_diff(f1, f0), 1e-12 * max_abs(f0));
  EXPECT_LT(max_abs_diff(k1, k0), 1e-12 * max_abs(k0));
  EXPECT_LT(max_abs_diff(r1, r0), 1e-14);

  // And it does use them: identity rotations give a different (wrong) pass.
  std::vector<double> identity(9 * ne, 0.0);
  for (size_t e = 0; e < ne; ++e) identity[9 * e] = identity[9 * e + 4] = identity[9 * e + 8] = 1.0;
  std::vector<double> f2, k2, r2;
  full_pass(identity.data(), f2, k2, r2);
  EXPECT_GT(max_abs_diff(f2, f0), 0.1 * max_abs(f0));
  EXPECT_EQ(r2, identity);
}

// A capped solve (2 CG iterations) is not converged, so the guard runs after every step; the
// next assemble starts at the guard's positions and takes its rotations — the same rotations a
// fresh stepper computes there. Moved positions (here: by 1e-12 m at one node) are never
// served from the cache.
TEST(RotationReuse, TheNextAssembleTakesTheGuardsRotationsOnlyWherePositionsAreTheGuards) {
  ScenarioSpec spec = test_scenarios::cantilever_dynamic();
  spec.solver.max_iterations = 2;
  spec.solver.tolerance = 1e-12;
  auto m = compile_model(spec);
  State s = State::initial(*m);
  TickWorkspace w(*m);
  TimeStepper& st = w.stepper();
  const double h = m->time_step;
  const StepInputs none{};
  // A guard leaves its last evaluated positions except when it holds the step (back to the
  // start positions, which it did not evaluate): those are the assembles that may reuse.
  int reusable = 0;
  bool last_reusable = false;
  for (int k = 0; k < 20; ++k) {
    st.assemble(s.tissue, h, none);
    const SolveStats ss = st.solve(s.tissue);
    ASSERT_FALSE(ss.converged);
    st.integrate(s.tissue, h);
    double removed = 0;
    if (last_reusable) ++reusable;
    last_reusable = st.energy_guard(s.tissue, h, &removed) != EnergyLimit::Held;
  }
  ASSERT_GT(reusable, 10);
  EXPECT_EQ(st.rotations_reused(), reusable);

  ASSERT_TRUE(last_reusable);
  st.assemble(s.tissue, h, none);
  EXPECT_EQ(st.rotations_reused(), reusable + 1);
  TickWorkspace fresh_w(*m);
  TimeStepper& fresh = fresh_w.stepper();
  fresh.assemble(s.tissue, h, none);
  EXPECT_EQ(fresh.rotations_reused(), 0);
  EXPECT_LT(max_abs_diff(st.rotations(), fresh.rotations()), 1e-14);

  // One more guarded step, then a node moves: the cache must not be used.
  st.solve(s.tissue);
  st.integrate(s.tissue, h);
  double removed = 0;
  st.energy_guard(s.tissue, h, &removed);
  const int32_t free_node = [&] {
    for (int32_t i = 0; i < m->fem.num_nodes; ++i)
      if (m->fem.constrained[i] == 0) return i;
    return int32_t{-1};
  }();
  ASSERT_GE(free_node, 0);
  s.tissue.x[3 * free_node] += 1e-12;
  const int64_t before = st.rotations_reused();
  st.assemble(s.tissue, h, none);
  EXPECT_EQ(st.rotations_reused(), before);
  // A second assemble at the same positions has no guard before it: computed again.
  st.assemble(s.tissue, h, none);
  EXPECT_EQ(st.rotations_reused(), before);
}

// Whole ticks, reuse on against off: a polar corotational body beside a stable neo-Hookean one
// (whose pass writes no rotations), CG capped at 3 iterations so that the guard runs every tick
// and the sub-step ladder redoes ticks that hit the cap. The trajectories agree to round-off;
// the reuse happened in one run and not in the other.
TEST(RotationReuse, TicksWithAndWithoutReuseFollowTheSameTrajectory) {
  STROMA_LONG_TEST();
  ScenarioSpec spec = test_scenarios::cantilever_dynamic();
  BodySpec second = spec.bodies[0];
  second.name = "neo_hookean";
  second.material.model = ElementModel::StableNeoHookean;
  second.translate = {0, 0.5, 0};
  spec.bodies.push_back(second);
  spec.probes.clear();
  spec.solver.max_iterations = 3;
  spec.solver.tolerance = 1e-8;
  spec.solver.on_cg_cap = CapPolicy::Substep;
  auto m = compile_model(spec);
  ASSERT_EQ(m->fem.ranges.size(), 2u);

  auto run = [&](bool reuse, int* substepped, int64_t* reused) {
    State s = State::initial(*m);
    TickWorkspace w(*m);
    w.stepper().set_rotation_reuse(reuse);
    *substepped = 0;
    for (int k = 0; k < 30; ++k)  // 30 ms: most ticks walk the sub-step ladder (a minute under ASan at 120)
      if (tick(*m, s, w).substeps > 1) ++*substepped;
    *reused = w.stepper().rotations_reused();
    return s.tissue.x;
  };
  int sub_on = 0, sub_off = 0;
  int64_t reused_on = 0, reused_off = 0;
  const std::vector<double> x_on = run(true, &sub_on, &reused_on);
  const std::vector<double> x_off = run(false, &sub_off, &reused_off);
  EXPECT_GT(reused_on, 20);
  EXPECT_EQ(reused_off, 0);
  EXPECT_GT(sub_on, 0) << "no tick went down the sub-step ladder";
  EXPECT_EQ(sub_on, sub_off);
  double moved = 0;
  for (size_t i = 0; i < x_on.size(); ++i) moved = std::max(moved, std::abs(x_on[i] - m->fem.rest[i]));
  ASSERT_GT(moved, 1e-4) << "the bodies did not move";
  EXPECT_LT(max_abs_diff(x_on, x_off), 1e-9 * moved);
}
