// The tick's time budget (solver.time_budget headless; the period minus a margin in serve):
// nothing the engine does by itself runs past it, what does not fit degrades stably and is
// counted, and every tick reports bounds on its solution error. No timed assertions: these tests
// use budgets so small that every tick must degrade, and check what it degraded to.

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "engine/tick.hpp"
#include "runtime/headless_runner.hpp"
#include "scene/compiled_scenario.hpp"
#include "tissue/input_error.hpp"
#include "tests/test_scenarios.hpp"

using namespace stroma;

namespace {
const std::string kDir = std::string(STROMA_SOURCE_DIR) + "/scenarios/";

bool finite(const std::vector<double>& a) {
  for (double v : a)
    if (!std::isfinite(v)) return false;
  return true;
}
}  // namespace

TEST(TimeBudget, LoaderTakesSecondsOrNoneAndRejectsTheRest) {
  const std::string base = "name: b\ntime_step: 0.001\nsolver: {time_budget: ";
  const std::string body = "}\nbodies:\n  - {name: b, mesh: m.msh, material: {young_modulus: 1, poisson_ratio: 0.3, density: 1}}\n";
  EXPECT_DOUBLE_EQ(parse_scenario(base + "0.0008" + body, "s.yaml", "").solver.time_budget, 0.0008);
  EXPECT_DOUBLE_EQ(parse_scenario(base + "none" + body, "s.yaml", "").solver.time_budget, 0.0);
  for (const char* bad : {"0", "-0.001", "fast"}) {
    try {
      parse_scenario(base + bad + body, "s.yaml", "");
      ADD_FAILURE() << "accepted time_budget " << bad;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("s.yaml:3: solver.time_budget"), std::string::npos) << e.what();
    }
  }
}

// The stiff cantilever needs ~220 Jacobi-PCG iterations per tick; with a budget of 2 µs each
// solve is cut after its first iteration: every tick degrades (SolveTruncated), none stops the
// run, the state stays finite, and the counts reach summary.json's fields.
TEST(TimeBudget, TinyBudgetTruncatesEverySolveAndTheRunGoesOn) {
  ScenarioSpec spec = test_scenarios::cantilever_dynamic();
  spec.solver.preconditioner = Preconditioner::Jacobi;
  spec.solver.max_iterations = 1000;
  spec.solver.time_budget = 2e-6;
  const CompiledScenario sc = compile_scenario(spec);
  RunOptions o;
  o.steps = 200;
  o.progress = false;
  const RunResult r = run_headless(sc, o);
  ASSERT_TRUE(r.ok) << r.failure;
  EXPECT_EQ(r.steps, 200);
  EXPECT_EQ(r.ticks_degraded, 200);
  EXPECT_EQ(r.ticks_non_finite, 0);
  EXPECT_TRUE(finite(r.final_state.tissue.x));
  EXPECT_GT(r.residual_max, 1e-3) << "truncated solves are far from converged, and say so";
  EXPECT_GT(r.error_energy_max, 0.0);

  // Without a budget the same scene converges every tick and reports a tiny error bound.
  ScenarioSpec free_spec = spec;
  free_spec.solver.time_budget = 0;
  const RunResult f = run_headless(compile_scenario(free_spec), o);
  EXPECT_EQ(f.ticks_degraded, 0);
  EXPECT_EQ(f.ticks_over_budget, 0);
  EXPECT_LT(f.residual_max, 1.01e-6);
  EXPECT_LT(f.error_position_max, 1e-3 * r.error_position_max);
}

// A tick whose step cannot be made sane and whose budget is spent holds the tissue still
// (rolled back, velocities zeroed, time advanced) instead of faulting; without a budget the
// same tick is rolled back unadvanced (NonFinite), as before.
TEST(TimeBudget, NoSaneStepInTimeHoldsTheTissueStill) {
  auto m = compile_model(load_scenario(kDir + "liver.yaml"));
  State s = State::initial(*m);
  TickWorkspace w(*m);
  for (int k = 0; k < 10; ++k) tick(*m, s, w);
  State broken = s;
  broken.tissue.v[3 * 10 + 1] = std::numeric_limits<double>::quiet_NaN();
  State a = broken;
  Deadline past;
  past.at_ns = 1;  // long gone on the steady clock
  const TickReport& held = tick(*m, a, w, nullptr, 0, past);
  EXPECT_EQ(held.degradation, Degradation::Held);
  EXPECT_NE(held.status, TickStatus::NonFinite);
  EXPECT_EQ(a.step, s.step + 1);
  EXPECT_EQ(a.tissue.x, s.tissue.x) << "positions rolled back";
  for (double v : a.tissue.v) EXPECT_EQ(v, 0.0);
  State b = broken;
  EXPECT_EQ(tick(*m, b, w).status, TickStatus::NonFinite);
  EXPECT_EQ(b.step, s.step);
}

// Budgets the Newton iterations too: a large step with four Newton iterations asked for and a
// spent budget keeps the linearised step (its first solve is truncated as well).
TEST(TimeBudget, NewtonIterationsStopAtTheBudget) {
  ScenarioSpec spec = test_scenarios::cantilever_dynamic();
  spec.time_step = 0.01;
  spec.solver.newton_iterations = 4;
  spec.solver.newton_tolerance = 1e-12;
  auto m = compile_model(spec);
  State s = State::initial(*m);
  TickWorkspace w(*m);
  for (int k = 0; k < 5; ++k) {
    Deadline past;
    past.at_ns = 1;
    const TickReport& r = tick(*m, s, w, nullptr, 0, past);
    EXPECT_NE(r.degradation, Degradation::None);
    EXPECT_LE(r.newton.iterations, 1) << "no Newton iteration after the deadline";
    EXPECT_TRUE(finite(s.tissue.x));
  }
  const TickReport& free_tick = tick(*m, s, w);
  EXPECT_EQ(free_tick.degradation, Degradation::None);
  EXPECT_GT(free_tick.newton.iterations, 1);
}

// A budgeted run replays bit for bit: each tick that ran out of time records the deadline check
// at which it did (TickReport::deadline_check, a session log's `deadline` event), and the replay
// expires that tick's deadline at the same check whatever its own clock says.
TEST(TimeBudget, BudgetCutsReplayBitForBit) {
  ScenarioSpec spec = test_scenarios::cantilever_dynamic();
  spec.solver.preconditioner = Preconditioner::Jacobi;
  spec.solver.max_iterations = 1000;
  spec.solver.time_budget = 80e-6;  // cuts CG somewhere in its ~220 iterations, differently each tick
  auto m = compile_model(spec);
  State live = State::initial(*m);
  TickWorkspace wl(*m);
  std::vector<int64_t> cuts;
  for (int k = 0; k < 100; ++k) cuts.push_back(tick(*m, live, wl).deadline_check);
  int cut_ticks = 0;
  for (int64_t c : cuts) cut_ticks += c >= 0;
  ASSERT_GT(cut_ticks, 50) << "the budget must cut most ticks";
  State replay = State::initial(*m);
  TickWorkspace wr(*m);
  for (int k = 0; k < 100; ++k) {
    Deadline d;
    d.expire_at_check = cuts[k] >= 0 ? cuts[k] : std::numeric_limits<int64_t>::max();
    EXPECT_EQ(tick(*m, replay, wr, nullptr, 0, d).deadline_check, cuts[k]) << "tick " << k;
  }
  EXPECT_EQ(replay.tissue.x, live.tissue.x);
  EXPECT_EQ(replay.tissue.v, live.tissue.v);
}

// A budgeted tick keeps the energy guard's time back from its solve (TickWorkspace::guard_ns):
// with a reserve longer than the whole budget the solve is cut at once (and the guard still
// runs); with no reserve the same tick, with the same deadline, converges.
TEST(TimeBudget, SolveLeavesTheEnergyGuardItsTime) {
  auto m = compile_model(load_scenario(kDir + "liver.yaml"));
  State s = State::initial(*m);
  TickWorkspace w(*m);
  EXPECT_GT(w.guard_ns, 0) << "implicit Euler: the guard's cost is measured at load";
  for (int k = 0; k < 10; ++k) tick(*m, s, w);
  auto run = [&](int64_t reserve) {
    State a = s;
    w.guard_ns = reserve;
    Deadline d;
    d.at_ns = steady_now_ns() + 1'000'000'000;  // one second: ample for a liver tick
    const TickReport& r = tick(*m, a, w, nullptr, 0, d);
    return std::make_pair(r.degradation, r.solve.converged);
  };
  const auto [cut, cut_converged] = run(2'000'000'000);
  EXPECT_EQ(cut, Degradation::SolveTruncated);
  EXPECT_FALSE(cut_converged);
  const auto [free, free_converged] = run(0);
  EXPECT_EQ(free, Degradation::None);
  EXPECT_TRUE(free_converged);
}
