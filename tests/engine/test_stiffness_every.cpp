// `solver.stiffness_every: N` (StepperSettings::stiffness_every): each element's stiffness blocks
// made once every N implicit steps (a 1/N share of the batches a step), the steps solving with
// the last complete set (a lagged tangent). Checked here against what must hold whatever N is:
// the forces are the step's own, so a damped body comes to rest at the same static equilibrium
// (solve_static, an independent Newton solve) as with a fresh tangent every step; the undamped
// swing never gains energy; one step makes them all, the rest use kept ones (counters); a
// completed set is the full tangent of the positions its shares were made at; the kept blocks
// are state, so a snapshot taken mid-cycle replays bit for bit, also through the state's bytes.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "engine/model.hpp"
#include "engine/state.hpp"
#include "engine/state_bytes.hpp"
#include "engine/tick.hpp"
#include "scene/compiled_scenario.hpp"
#include "scene/scenario_spec.hpp"
#include "tests/test_scenarios.hpp"

using namespace stroma;

namespace {

/// The tests' cantilever made soft (E 300 kPa: a large, swinging sag), Jacobi CG to 1e-10.
ScenarioSpec soft_cantilever(int stiffness_every, double rayleigh_mass) {
  ScenarioSpec spec = test_scenarios::cantilever_dynamic();
  spec.bodies[0].material.young_modulus = 3e5;
  spec.bodies[0].material.rayleigh_mass = rayleigh_mass;
  spec.solver.preconditioner = Preconditioner::Jacobi;
  spec.solver.tolerance = 1e-10;
  spec.solver.max_iterations = 5000;
  spec.solver.stiffness_every = stiffness_every;
  return spec;
}

double total_energy(const TimeStepper& st, const TissueState& s) {
  return st.kinetic_energy(s) + st.free_energy(s) + st.external_potential(s);
}

double max_abs_diff(const std::vector<double>& a, const std::vector<double>& b) {
  double d = 0;
  for (size_t i = 0; i < a.size(); ++i) d = std::max(d, std::abs(a[i] - b[i]));
  return d;
}

/// The largest displacement from the rest positions.
double max_displacement(const FemModel& fem, const std::vector<double>& x) { return max_abs_diff(x, fem.rest); }

}  // namespace

// Heavily damped (α = 60 /s), 1.5 s: the body settles where the forces vanish, and the forces
// are each step's own — so with the tangent made every 4th step it settles at the static
// equilibrium Newton finds, as it does with a fresh tangent every step.
TEST(StiffnessEvery, SettlesAtTheStaticEquilibrium) {
  for (const int every : {1, 4}) {
    const CompiledScenario sc = compile_scenario(soft_cantilever(every, 60.0));
    SCOPED_TRACE("corotational, stiffness_every " + std::to_string(every));
    const Model& m = *sc.model;
    State s = State::initial(m);
    TickWorkspace w(m);
    for (int k = 0; k < 1500; ++k) ASSERT_EQ(tick(m, s, w, nullptr, 0).status, TickStatus::Ok) << "tick " << k;
    TissueState eq = s.tissue;
    const StaticResult r = w.stepper().solve_static(eq);
    ASSERT_TRUE(r.converged);
    const double sag = max_displacement(m.fem, eq.x);
    ASSERT_GT(sag, 1e-3) << "a sag large enough to rotate the elements";
    std::printf("  stiffness_every %d: sag %.4g m, %.3g m from the static equilibrium\n", every, sag,
                max_abs_diff(s.tissue.x, eq.x));
    EXPECT_LE(max_abs_diff(s.tissue.x, eq.x), 1e-4 * sag) << "stiffness_every " << every;
    if (every == 4) {
      EXPECT_EQ(w.stepper().stiffness_refreshes(), 1);  // the first step
      EXPECT_EQ(w.stepper().stiffness_reuses(), 1499);
    } else {
      EXPECT_EQ(w.stepper().stiffness_reuses(), 0);
    }
  }
}

// The same with a hyperelastic body (stable Neo-Hookean: its own pass, the same shares).
TEST(StiffnessEvery, AHyperelasticBodySettlesAtTheStaticEquilibriumToo) {
  ScenarioSpec spec = soft_cantilever(3, 60.0);
  spec.bodies[0].material.model = ElementModel::StableNeoHookean;
  const CompiledScenario sc = compile_scenario(spec);
  const Model& m = *sc.model;
  ASSERT_EQ(m.fem.ranges.at(0).kernel, ElementKernel::StableNeoHookean);
  State s = State::initial(m);
  TickWorkspace w(m);
  for (int k = 0; k < 1500; ++k) ASSERT_EQ(tick(m, s, w, nullptr, 0).status, TickStatus::Ok) << "tick " << k;
  TissueState eq = s.tissue;
  ASSERT_TRUE(w.stepper().solve_static(eq).converged);
  const double sag = max_displacement(m.fem, eq.x);
  ASSERT_GT(sag, 1e-3);
  EXPECT_LE(max_abs_diff(s.tissue.x, eq.x), 1e-4 * sag);
  EXPECT_EQ(w.stepper().stiffness_reuses(), 1499);
}

// Undamped, from rest under gravity: implicit Euler loses energy every step; with the tangent
// kept for 4 steps the step is still implicit in the forces, and the total (kinetic + elastic
// + gravity's) never exceeds the last step's.
TEST(StiffnessEvery, TheUndampedSwingNeverGainsEnergy) {
  const CompiledScenario sc = compile_scenario(soft_cantilever(4, 0.0));
  const Model& m = *sc.model;
  State s = State::initial(m);
  TickWorkspace w(m);
  double last = total_energy(w.stepper(), s.tissue), lost = 0, worst = 0;
  double scale = 0;  // the largest kinetic energy: the swing's scale
  for (int k = 0; k < 400; ++k) {
    ASSERT_EQ(tick(m, s, w, nullptr, 0).status, TickStatus::Ok) << "tick " << k;
    const double e = total_energy(w.stepper(), s.tissue);
    worst = std::max(worst, e - last);
    lost += std::max(0.0, last - e);
    last = e;
    scale = std::max(scale, w.stepper().kinetic_energy(s.tissue));
  }
  ASSERT_GT(scale, 0);
  std::printf("  largest gain in a step %.3g of the swing's kinetic energy %.3g J; lost %.3g J\n", worst / scale, scale,
              lost);
  EXPECT_GT(w.stepper().stiffness_reuses(), 250);
  EXPECT_LE(worst, 1e-9 * scale) << "the largest gain in a step";
  EXPECT_GT(lost, 0) << "implicit Euler damps";
}

// A snapshot between two refreshes (the kept blocks one step old) replays bit for bit — as a
// copy of the state and through its bytes — where without the kept blocks it would not.
TEST(StiffnessEvery, ASnapshotBetweenRefreshesReplaysBitForBit) {
  const CompiledScenario sc = compile_scenario(soft_cantilever(3, 0.0));
  const Model& m = *sc.model;
  State s = State::initial(m);
  TickWorkspace w(m);
  for (int k = 0; k < 40; ++k) ASSERT_EQ(tick(m, s, w, nullptr, 0).status, TickStatus::Ok);
  // Tick 0 made them all; ticks 1, 2, 3 made one share each, and so on: mid-cycle now.
  ASSERT_EQ(s.tissue.solver.element_blocks_phase, 0);
  ASSERT_EQ(tick(m, s, w, nullptr, 0).status, TickStatus::Ok);
  ASSERT_EQ(s.tissue.solver.element_blocks_phase, 1);
  const State snap = s;
  const uint64_t fp = model_fingerprint(m);
  const std::string bytes = encode_state(snap, fp);
  for (int k = 0; k < 30; ++k) ASSERT_EQ(tick(m, s, w, nullptr, 0).status, TickStatus::Ok);
  const std::vector<double> reference = s.tissue.x;

  State again = snap;
  TickWorkspace w2(m);
  for (int k = 0; k < 30; ++k) ASSERT_EQ(tick(m, again, w2, nullptr, 0).status, TickStatus::Ok);
  EXPECT_EQ(again.tissue.x, reference);

  uint64_t fp_read = 0;
  State decoded = decode_state(bytes, &fp_read);
  ASSERT_EQ(fp_read, fp);
  EXPECT_EQ(decoded.tissue.solver.element_blocks, snap.tissue.solver.element_blocks);
  EXPECT_EQ(encode_state(decoded, fp), bytes);
  TickWorkspace w3(m);
  for (int k = 0; k < 30; ++k) ASSERT_EQ(tick(m, decoded, w3, nullptr, 0).status, TickStatus::Ok);
  EXPECT_EQ(decoded.tissue.x, reference);

  // The kept blocks matter: the same snapshot without them (made anew at its first step) ends
  // elsewhere.
  State fresh = snap;
  fresh.tissue.solver.element_blocks_phase = -1;
  TickWorkspace w4(m);
  for (int k = 0; k < 30; ++k) ASSERT_EQ(tick(m, fresh, w4, nullptr, 0).status, TickStatus::Ok);
  EXPECT_NE(fresh.tissue.x, reference);
}

// A completed set, at rest (every share made at the same positions), is the full tangent: the
// blocks a fresh assembly makes, to round-off. And a state whose phase is out of the cycle is
// refused as another model's.
TEST(StiffnessEvery, ACompletedSetIsTheFullTangent) {
  for (const ElementModel model : {ElementModel::Corotational, ElementModel::StableNeoHookean}) {
  SCOPED_TRACE(model == ElementModel::Corotational ? "corotational" : "stable Neo-Hookean");
  ScenarioSpec fixed_spec = soft_cantilever(3, 0.0);
  fixed_spec.gravity = {0, 0, 0};  // nothing moves: every share is made at the rest positions
  fixed_spec.bodies[0].material.model = model;
  const CompiledScenario still = compile_scenario(fixed_spec);
  const Model& m = *still.model;
  State s = State::initial(m);
  TickWorkspace w(m);
  for (int k = 0; k < 4; ++k) ASSERT_EQ(tick(m, s, w, nullptr, 0).status, TickStatus::Ok);
  ASSERT_EQ(s.tissue.solver.element_blocks_phase, 0);  // swapped at the end of tick 3
  const std::vector<double>& kept = s.tissue.solver.element_blocks;
  std::vector<double> full;
  w.stepper().stiffness(s.tissue, full);
  const double h = m.time_step;
  double scale = 0, diff = 0;
  for (size_t i = 0; i < full.size(); ++i) {
    // kept = h(β + h)·K with β = 0 here (the cantilever is undamped).
    scale = std::max(scale, std::abs(h * h * full[i]));
    diff = std::max(diff, std::abs(kept[i] - h * h * full[i]));
  }
  ASSERT_GT(scale, 0);
  EXPECT_LE(diff, 1e-12 * scale);
  for (const double v : s.tissue.solver.element_blocks_next) ASSERT_EQ(v, 0.0) << "the next set starts empty";

  State odd = s;
  odd.tissue.solver.element_blocks_phase = 3;
  std::string why;
  EXPECT_FALSE(state_fits_model(odd, m, &why));
  EXPECT_NE(why.find("stiffness phase"), std::string::npos) << why;
  EXPECT_TRUE(state_fits_model(s, m, &why)) << why;
  }
}

// The setting is part of the model: a state of another stiffness_every is another model's.
TEST(StiffnessEvery, IsPartOfTheModelsFingerprint) {
  const CompiledScenario a = compile_scenario(soft_cantilever(1, 0.0));
  const CompiledScenario b = compile_scenario(soft_cantilever(2, 0.0));
  EXPECT_NE(model_fingerprint(*a.model), model_fingerprint(*b.model));
  EXPECT_TRUE(State::initial(*a.model).tissue.solver.element_blocks.empty());
  EXPECT_EQ(State::initial(*b.model).tissue.solver.element_blocks.size(), 9 * size_t(b.model->fem.pattern.nnzb()));
}
