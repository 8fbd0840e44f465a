// The tick pipeline: stages a scene does not need are skipped; a non-finite solve never enters
// the state.

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "engine/model.hpp"
#include "engine/state.hpp"
#include "engine/tick.hpp"
#include "scene/compiled_scenario.hpp"
#include "tests/test_scenarios.hpp"

using namespace stroma;

namespace {
const std::string kDir = std::string(STROMA_SOURCE_DIR) + "/scenarios/";
}

TEST(Tick, SceneWithoutToolsSkipsInputAndCollisionStages) {
  auto m = compile_model(load_scenario(kDir + "regression/liver_damped.yaml"));
  ASSERT_TRUE(m->tools.empty());
  State s = State::initial(*m);
  TickWorkspace w(*m);
  const TickReport r = tick(*m, s, w);  // a copy: the second model's tick below must not overwrite it
  EXPECT_FALSE(r.stage_ran[static_cast<int>(Stage::ReadInputs)]);
  EXPECT_FALSE(r.stage_ran[static_cast<int>(Stage::Collide)]);
  EXPECT_EQ(r.stage_ns[static_cast<int>(Stage::Collide)], 0);
  EXPECT_TRUE(r.stage_ran[static_cast<int>(Stage::Assemble)]);
  EXPECT_TRUE(r.stage_ran[static_cast<int>(Stage::Solve)]);
  EXPECT_TRUE(r.stage_ran[static_cast<int>(Stage::Integrate)]);

  auto mt = compile_model(load_scenario(kDir + "liver.yaml"));
  ASSERT_FALSE(mt->tools.empty());
  State st = State::initial(*mt);
  TickWorkspace wt(*mt);
  const TickReport& rt = tick(*mt, st, wt);
  EXPECT_TRUE(rt.stage_ran[static_cast<int>(Stage::ReadInputs)]);
  // hand_off runs when there are tools (their end-of-step force and feedback) and is timed.
  EXPECT_TRUE(rt.stage_ran[static_cast<int>(Stage::HandOff)]);
  EXPECT_GT(rt.stage_ns[static_cast<int>(Stage::HandOff)], 0);
  EXPECT_FALSE(r.stage_ran[static_cast<int>(Stage::HandOff)]) << "no tools: nothing to hand off";
}

// With Newton iterations the element passes of the iterations are counted under assemble and
// only their linear solves under solve.
TEST(Tick, NewtonElementPassesCountAsAssembly) {
  ScenarioSpec spec = test_scenarios::cantilever_dynamic();
  spec.time_step = 0.01;
  spec.solver.newton_iterations = 4;
  spec.solver.newton_tolerance = 1e-12;  // always iterate
  auto m = compile_model(spec);
  State s = State::initial(*m);
  TickWorkspace w(*m);
  int64_t newton_passes = 0, assemble = 0;
  for (int k = 0; k < 5; ++k) {
    const TickReport& r = tick(*m, s, w);
    ASSERT_NE(r.status, TickStatus::NonFinite);
    EXPECT_GT(r.newton.iterations, 1);
    newton_passes += r.newton.element_pass_ns;
    assemble += r.stage_ns[static_cast<int>(Stage::Assemble)];
    EXPECT_GE(r.stage_ns[static_cast<int>(Stage::Assemble)], r.newton.element_pass_ns);
  }
  EXPECT_GT(newton_passes, 0);
  EXPECT_GT(assemble, newton_passes) << "the first assembly is counted too";
}

TEST(Tick, NonFiniteSolveLeavesTheStateUnadvanced) {
  auto m = compile_model(load_scenario(kDir + "liver.yaml"));
  State s = State::initial(*m);
  TickWorkspace w(*m);
  for (int k = 0; k < 10; ++k) tick(*m, s, w);
  // Corrupt one velocity (as a broken input would): the solve turns non-finite.
  s.tissue.v[3 * 10 + 1] = std::numeric_limits<double>::quiet_NaN();
  const std::vector<double> x_before = s.tissue.x;
  const int64_t step_before = s.step;
  const TickReport r = tick(*m, s, w);
  EXPECT_EQ(r.status, TickStatus::NonFinite);
  EXPECT_EQ(s.tissue.x, x_before) << "positions must not take a NaN step";
  EXPECT_EQ(s.step, step_before);
  for (double d : s.tissue.dv) EXPECT_TRUE(std::isfinite(d)) << "warm start cleared";
}

// The engine defends itself: a step that moves a node by more than half the scene in one step
// (here: a node thrown very fast) is rolled back and redone in sub-steps; if even the smallest
// sub-step cannot make it sane, the state is rolled back unadvanced. Never a NaN in the state.
TEST(Tick, DivergedStepIsRolledBackAndRedoneInSubsteps) {
  // The liver, free and weightless, moving rigidly: no elastic force, so each (sub-)step moves
  // every node by h·v (Rayleigh mass damping shaves off 0.01 %).
  ScenarioSpec spec = load_scenario(kDir + "liver.yaml");
  spec.bodies[0].fixed.clear();
  spec.gravity = {0, 0, 0};
  auto m = compile_model(spec);
  State s = State::initial(*m);
  TickWorkspace w(*m);
  const double L = m->max_step_displacement;
  ASSERT_GT(L, 1.0);  // half the liver's bounding-box diagonal, in mesh units
  const double h = m->time_step;
  auto throw_at = [&](double speed) {
    State t = s;
    for (size_t i = 0; i < t.tissue.v.size(); i += 3) t.tissue.v[i] = speed;
    return t;
  };
  // 1.5 L per full step: too far for one step, fine for two half steps.
  State a = throw_at(1.5 * L / h);
  const TickReport r = tick(*m, a, w);
  EXPECT_EQ(r.status, TickStatus::Recovered);
  EXPECT_EQ(r.substeps, 2);
  EXPECT_EQ(a.step, s.step + 1);
  EXPECT_NEAR(a.tissue.x[0] - s.tissue.x[0], 1.5 * L, 1e-3 * L) << "the step was really taken, in full";
  for (double x : a.tissue.x) ASSERT_TRUE(std::isfinite(x));
  // 20 L per step: 16 sub-steps still move 1.25 L each; 32 move 0.625 L: recovered there.
  State d = throw_at(20 * L / h);
  const TickReport rd = tick(*m, d, w);
  EXPECT_EQ(rd.status, TickStatus::Recovered);
  EXPECT_EQ(rd.substeps, 32);
  EXPECT_NEAR(d.tissue.x[0] - s.tissue.x[0], 20 * L, 1e-2 * L);
  // 200 L per step: even 64 sub-steps move 3.1 L each: rolled back, not advanced.
  State b = throw_at(200 * L / h);
  const std::vector<double> x0 = b.tissue.x, v0 = b.tissue.v;
  const TickReport rb = tick(*m, b, w);
  EXPECT_EQ(rb.status, TickStatus::NonFinite);
  EXPECT_EQ(rb.substeps, kMaxSubsteps);
  EXPECT_EQ(b.step, s.step);
  EXPECT_EQ(b.tissue.x, x0);
  EXPECT_EQ(b.tissue.v, v0);
  // Just below the limit: an ordinary tick.
  State c = throw_at(0.9 * L / h);
  const TickReport rc = tick(*m, c, w);
  EXPECT_EQ(rc.status, TickStatus::Ok);
  EXPECT_EQ(rc.substeps, 1);
}

// A stiff body at a huge explicit step explodes within a few ticks; every tick either advances
// finitely (possibly in sub-steps) or is rolled back: no NaN/Inf ever reaches the state.
TEST(Tick, ExplicitBlowUpNeverPutsANaNInTheState) {
  ScenarioSpec spec = test_scenarios::cantilever_dynamic();
  spec.solver.integrator = Integrator::SymplecticEuler;
  spec.time_step = 5e-3;  // ~50x the explicit stability limit of this beam
  auto m = compile_model(spec);
  State s = State::initial(*m);
  TickWorkspace w(*m);
  int recovered = 0, rolled_back = 0;
  for (int k = 0; k < 300; ++k) {
    const TickReport r = tick(*m, s, w);
    recovered += r.status == TickStatus::Recovered;
    rolled_back += r.status == TickStatus::NonFinite;
    for (double x : s.tissue.x) ASSERT_TRUE(std::isfinite(x)) << "tick " << k;
    for (double v : s.tissue.v) ASSERT_TRUE(std::isfinite(v)) << "tick " << k;
  }
  EXPECT_GT(recovered + rolled_back, 0) << "the blow-up was not detected at all";
}

// solver.on_cg_cap: `substep` (the default) redoes a capped tick in sub-steps (each better
// conditioned, so fewer iterations suffice); `continue` keeps the capped step.
TEST(Tick, CappedSolveIsRedoneInSubstepsWhenTold) {
  ScenarioSpec spec = test_scenarios::cantilever_dynamic();
  spec.solver.preconditioner = Preconditioner::Jacobi;
  spec.solver.max_iterations = 12;
  spec.solver.tolerance = 1e-8;
  spec.time_step = 0.004;
  auto run = [&](bool substep) {
    spec.solver.on_cg_cap = substep ? CapPolicy::Substep : CapPolicy::Continue;
    auto m = compile_model(spec);
    State s = State::initial(*m);
    TickWorkspace w(*m);
    return tick(*m, s, w);
  };
  const TickReport kept = run(false);
  EXPECT_EQ(kept.status, TickStatus::SolverNotConverged);
  EXPECT_EQ(kept.substeps, 1);
  const TickReport redone = run(true);
  EXPECT_EQ(redone.status, TickStatus::Recovered);
  EXPECT_GT(redone.substeps, 1);
}

TEST(Tick, SnapshotAndRestoreIsACopyAndReproducesBitForBit) {
  auto m = compile_model(load_scenario(kDir + "liver.yaml"));
  State s = State::initial(*m);
  TickWorkspace w(*m);
  for (int k = 0; k < 50; ++k) tick(*m, s, w);
  const State snapshot = s;
  for (int k = 0; k < 50; ++k) tick(*m, s, w);
  const std::vector<double> first = s.tissue.x;
  s = snapshot;  // roll back
  for (int k = 0; k < 50; ++k) tick(*m, s, w);
  EXPECT_EQ(s.tissue.x, first);
  EXPECT_EQ(s.step, 100);
}
