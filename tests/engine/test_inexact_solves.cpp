// Inexact solves that never gain energy (issue 14, §2): SOFA's beam k6 and the Armadillo at
// physical scale, with CG capped at 5, 10 and 25 iterations (the capped step kept) and with tick
// budgets of 0.3, 0.6 and 0.9 ms, run for 1 s: the total mechanical energy (kinetic + elastic +
// gravity) never rises above its running maximum, and the state never diverges. Before the safe
// warm start and the energy guard, SOFA's settings (cap 25) sent the beam's tip 9.4 cm off and
// caps of 10 raised the Armadillo's energy by 37 % of its scale. No timed assertions: where a
// budget stops CG changes from run to run; no energy gain must hold wherever it stops.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>

#include "engine/tick.hpp"
#include "scene/compiled_scenario.hpp"
#include "tests/test_labels.hpp"

using namespace stroma;

namespace {

struct InexactCase {
  std::string scene;      ///< under scenarios/physical/
  int cap = 0;            ///< CG iteration cap (0: 2000, converging within the budget if it can)
  double budget_ms = 0;   ///< tick budget (0: none)
};

std::string case_name(const testing::TestParamInfo<InexactCase>& p) {
  std::string s = p.param.scene.substr(0, p.param.scene.find('.'));
  s += p.param.cap ? "_cap" + std::to_string(p.param.cap) : "_budget" + std::to_string(int(p.param.budget_ms * 1000)) + "us";
  return s;
}

class InexactSolve : public testing::TestWithParam<InexactCase> {};

TEST_P(InexactSolve, NeverGainsEnergyAndNeverDiverges) {
  STROMA_LONG_TEST();
  const InexactCase& c = GetParam();
  ScenarioSpec spec = load_scenario(std::string(STROMA_SOURCE_DIR) + "/scenarios/physical/" + c.scene);
  spec.solver.on_cg_cap = CapPolicy::Continue;  // keep capped steps: what is under test
  spec.solver.tolerance = 1e-10;
  spec.solver.max_iterations = c.cap > 0 ? c.cap : 2000;
  spec.solver.time_budget = c.budget_ms * 1e-3;
  const CompiledScenario sc = compile_scenario(spec);
  const Model& m = *sc.model;
  State s = State::initial(m);
  TickWorkspace w(m);
  const TimeStepper& st = w.stepper();
  auto energy = [&] { return st.kinetic_energy(s.tissue) + st.elastic_energy(s.tissue) + st.external_potential(s.tissue); };
  double e_max = energy(), scale = std::abs(e_max), worst_rise = -1e300;
  int capped = 0, guarded = 0;
  const int ticks = static_cast<int>(std::lround(1.0 / m.time_step));
  for (int k = 0; k < ticks; ++k) {
    const TickReport& r = tick(m, s, w);
    ASSERT_NE(r.status, TickStatus::NonFinite) << "tick " << k;
    capped += !r.solve.converged;
    guarded += r.energy_limit != EnergyLimit::None;
    const double e = energy();
    ASSERT_TRUE(std::isfinite(e)) << "tick " << k;
    scale = std::max(scale, std::abs(e));
    worst_rise = std::max(worst_rise, e - e_max);
    e_max = std::max(e_max, e);
  }
  std::printf("%s cap %d budget %.1f ms: %d of %d ticks inexact, %d limited by the energy guard, worst energy rise "
              "%.2e of %.2e J\n",
              c.scene.c_str(), c.cap, c.budget_ms, capped, ticks, guarded, worst_rise, scale);
  EXPECT_GT(capped, ticks / 10) << "the case must exercise inexact solves";
  EXPECT_LE(worst_rise, 1e-9 * scale) << "energy rose above its running maximum";
  // Never diverged: every node within twice the scene's size of where it started (the soft
  // Armadillo folds over its fixed feet, its head falling ~0.24 m, as the converged run does).
  for (size_t d = 0; d < s.tissue.x.size(); ++d)
    ASSERT_LT(std::abs(s.tissue.x[d] - m.fem.rest[d]), 4.0 * m.max_step_displacement) << "dof " << d;
}

INSTANTIATE_TEST_SUITE_P(PhysicalScenes, InexactSolve,
                         testing::Values(InexactCase{"beam_k6_sofa.yaml", 5, 0}, InexactCase{"beam_k6_sofa.yaml", 10, 0},
                                         InexactCase{"beam_k6_sofa.yaml", 25, 0},
                                         InexactCase{"beam_k6_sofa.yaml", 0, 0.3},
                                         InexactCase{"beam_k6_sofa.yaml", 0, 0.6},
                                         InexactCase{"beam_k6_sofa.yaml", 0, 0.9},
                                         InexactCase{"armadillo_0p15m.yaml", 5, 0},
                                         InexactCase{"armadillo_0p15m.yaml", 10, 0},
                                         InexactCase{"armadillo_0p15m.yaml", 25, 0},
                                         InexactCase{"armadillo_0p15m.yaml", 0, 0.3},
                                         InexactCase{"armadillo_0p15m.yaml", 0, 0.6},
                                         InexactCase{"armadillo_0p15m.yaml", 0, 0.9}),
                         case_name);

}  // namespace

// SOFA's CG settings on its liver (scenarios/liver_sofa_settings.yaml: cap 25, tolerance 1e-9),
// the probe pressing it (trajectories/liver_press.yaml): Jacobi-PCG is capped on every tick
// there; the scene's refreshed warped Cholesky preconditioner meets SOFA's tolerance within
// SOFA's cap on every tick, contact and all, so no tick needs the energy guard or a recovery —
// the reason the scene ships with it. Checked on both, so the test shows the difference it
// relies on.
TEST(SofaSettingsLiver, TheWarpedPreconditionerMeetsSofasToleranceWithinItsCapEveryTick) {
  STROMA_LONG_TEST();
  for (Preconditioner prec : {Preconditioner::Jacobi, Preconditioner::WarpedCholesky}) {
    ScenarioSpec spec = load_scenario(std::string(STROMA_SOURCE_DIR) + "/scenarios/liver_sofa_settings.yaml");
    ASSERT_EQ(spec.solver.max_iterations, 25);
    ASSERT_EQ(spec.solver.tolerance, 1e-9);
    ASSERT_EQ(spec.solver.preconditioner, Preconditioner::WarpedCholesky);
    spec.solver.preconditioner = prec;
    spec.tools.at(0).script = std::string(STROMA_SOURCE_DIR) + "/scenarios/trajectories/liver_press.yaml";
    const CompiledScenario sc = compile_scenario(spec);
    const Model& m = *sc.model;
    State s = State::initial(m);
    TickWorkspace w(m);
    int converged = 0, guarded = 0, recovered = 0, most = 0, contact_ticks = 0;
    const int ticks = 2500;
    ToolInput in;
    for (int k = 0; k < ticks; ++k) {
      in.seq = static_cast<uint64_t>(k + 1);
      in.pose = sc.tool_scripts.at(0).sample(s.time);
      const TickReport& r = tick(m, s, w, &in, 1);
      contact_ticks += r.tools.at(0).contacts > 0;
      ASSERT_NE(r.status, TickStatus::NonFinite) << "tick " << k;
      converged += r.solve.converged;
      guarded += r.energy_limit != EnergyLimit::None;
      recovered += r.status == TickStatus::Recovered;
      most = std::max(most, r.solve.iterations);
    }
    EXPECT_GT(contact_ticks, ticks / 4) << "the probe must press the liver";
    if (prec == Preconditioner::Jacobi) {
      EXPECT_EQ(converged, 0) << "Jacobi-PCG was expected to be capped here";
    } else {
      EXPECT_EQ(converged, ticks);
      EXPECT_EQ(guarded, 0);
      EXPECT_EQ(recovered, 0);
      EXPECT_LE(most, 12);
    }
  }
}
