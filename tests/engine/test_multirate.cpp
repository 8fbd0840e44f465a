// Multirate haptics (engine/multirate.hpp): the tissue stepped every N ticks, the tools
// rendered every tick from the last finished step's local model.

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <thread>
#include <cmath>
#include <vector>

#include "tests/cantilever_with_probe.hpp"
#include "engine/model.hpp"
#include "engine/multirate.hpp"
#include "engine/simulation.hpp"
#include "engine/state.hpp"
#include "engine/tick.hpp"
#include "haptics/tool_shape.hpp"
#include "scene/compiled_scenario.hpp"
#include "tests/test_labels.hpp"
#include "tissue/input_error.hpp"

using namespace stroma;

namespace {

/// The damped cantilever with its 3 mm probe (cantilever_with_probe.hpp), multirate.
ScenarioSpec beam_with_probe(int fem_every, bool secant = true) {
  ScenarioSpec s = test_scenarios::cantilever_with_probe();
  s.solver.newton_iterations = 1;
  s.solver.fem_every = fem_every;
  s.solver.haptic_secant = secant;
  return s;
}

/// The probe over the beam's tip, `depth` into its top face (y = 0.01).
ToolInput press(double depth) {
  ToolInput in;
  in.pose.position = {0.095, 0.01 + 0.003 - depth, 0.005};
  return in;
}

}  // namespace

// Tissue steps happen every N ticks; the ticks render the model of the step that has finished:
// the one started N ticks before (the served pipeline), never the one just started.
TEST(Multirate, TicksRenderTheModelOfTheStepThatHasFinished) {
  auto m = compile_model(beam_with_probe(5));
  ASSERT_EQ(m->fem_every, 5);
  ASSERT_DOUBLE_EQ(m->fem_step, 5 * m->time_step);
  State s = State::initial(*m);
  TickWorkspace w(*m);
  HapticModel pending, current;  // what the last step made; what must be rendered now
  for (int k = 0; k < 60; ++k) {
    ToolInput in = press(0.0002 + 1e-5 * k);  // pressing slowly deeper
    const TickReport& r = tick(*m, s, w, &in, 1);
    EXPECT_EQ(r.tissue_stepped, k % 5 == 0) << k;
    if (r.tissue_stepped) {
      current = pending;  // the step started 5 ticks ago has finished
      pending = s.tools[0].haptic_next;
      EXPECT_TRUE(pending.valid);
    } else {
      EXPECT_EQ(r.solve.iterations, 0) << k;
    }
    const HapticModel& hm = s.tools[0].haptic;
    ASSERT_EQ(hm.valid, current.valid) << k;
    if (!hm.valid) {
      EXPECT_LT(k, 5) << "a model from tick 0 on";
      EXPECT_EQ(r.tools[0].force, (Vec3{0, 0, 0}));
      continue;
    }
    EXPECT_EQ(hm.center, current.center) << k;
    EXPECT_EQ(hm.force, current.force) << k;
    EXPECT_EQ(hm.stiffness, current.stiffness) << k;
    // Rendered: the model's force plus its stiffness times the tool's motion since (zero
    // where that would pull instead of push).
    const Vec3 p = tool_center(m->tools[0], s.tools[0]);
    Vec3 f;
    for (int i = 0; i < 3; ++i) {
      f[i] = hm.force[i];
      for (int j = 0; j < 3; ++j) f[i] += hm.stiffness[3 * i + j] * (p[j] - hm.center[j]);
    }
    if (f[0] * hm.force[0] + f[1] * hm.force[1] + f[2] * hm.force[2] < 0) f = {0, 0, 0};
    for (int i = 0; i < 3; ++i) EXPECT_NEAR(r.tools[0].force[i], f[i], 1e-15) << k;
  }
  EXPECT_GT(s.tools[0].haptic.force[1], 0.0) << "the probe touched the beam";
  EXPECT_LT(s.tools[0].haptic.stiffness[4], 0.0);
}

// A probe pressing steadily deeper, touching from tick ~75 on (the beam then relaxes from the
// impact for ~250 ticks: the force falls while the probe goes deeper). Once the press is
// steady, when a new step's model takes over the force the device feels jumps by what the old
// model missed: the secant model (force + measured stiffness × motion since) keeps those jumps
// smaller than holding the force (measured: by a third).
TEST(Multirate, SecantModelSmoothsTheForceBetweenSteps) {
  STROMA_LONG_TEST();
  auto run = [](bool secant) {
    ScenarioSpec spec = beam_with_probe(10, secant);
    // A finer beam (2 mm elements) under a 6 mm sphere: enough contact points that the steps'
    // own force is smooth.
    spec.bodies[0].mesh_path = std::string(STROMA_SOURCE_DIR) + "/scenarios/meshes/beam_tet4_h2p000mm.msh";
    spec.tools[0].spec.radius = 0.006;
    auto m = compile_model(spec);
    State s = State::initial(*m);
    TickWorkspace w(*m);
    std::vector<double> fy;
    for (int k = 0; k < 560; ++k) {
      ToolInput in = press(-0.0003 + 4e-6 * k);  // 2.1 mm into the beam at the end
      in.pose.position[1] += 0.003;               // the larger sphere's centre
      fy.push_back(tick(*m, s, w, &in, 1).tools[0].force[1]);
    }
    return fy;
  };
  const std::vector<double> secant = run(true), hold = run(false);
  // The jumps at each update over the steady part of the press; their median (at this step
  // size the FEM's own force can jump now and then, as contact points enter the sphere).
  std::vector<double> jumps_secant, jumps_hold;
  double peak = 0;
  for (size_t k = 400; k < secant.size(); ++k) {
    peak = std::max(peak, std::fabs(hold[k]));
    if (k % 10 == 0) {  // a new model takes over
      jumps_secant.push_back(std::fabs(secant[k] - secant[k - 1]));
      jumps_hold.push_back(std::fabs(hold[k] - hold[k - 1]));
    }
  }
  auto median = [](std::vector<double> v) {
    std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
    return v[v.size() / 2];
  };
  ASSERT_GT(peak, 1e-3) << "the probe pressed the beam";
  EXPECT_GT(median(jumps_hold), 0.01 * peak) << "a held force must step at each update";
  EXPECT_LT(median(jumps_secant), 0.8 * median(jumps_hold))
      << "secant " << median(jumps_secant) << " hold " << median(jumps_hold);
}

TEST(Multirate, LoadRejectsWhatItCannotRun) {
  ScenarioSpec s = beam_with_probe(4);
  s.solver.integrator = Integrator::SymplecticEuler;
  EXPECT_THROW(
      {
        try {
          compile_model(s);
        } catch (const InputError& e) {
          EXPECT_EQ(e.field(), "solver.fem_every");
          EXPECT_NE(std::string(e.what()).find("implicit_euler"), std::string::npos) << e.what();
          throw;
        }
      },
      InputError);
  ScenarioSpec c = beam_with_probe(4);
  c.tools[0].spec.coupling_stiffness = 500;
  EXPECT_THROW(
      {
        try {
          compile_model(c);
        } catch (const InputError& e) {
          EXPECT_NE(std::string(e.what()).find("virtually coupled"), std::string::npos) << e.what();
          throw;
        }
      },
      InputError);
}

// The served pipeline (engine/multirate_worker.hpp, driven through Simulation as `serve` drives
// it): every finished tissue step is handed off once, spanning fem_every ticks when the worker
// keeps up, the tissue's clock advancing by fem_every ticks per step; when it kept up every
// time, the tissue is the headless emulation's (tick()) bit for bit — the two are one pipeline.
// A Reset returns the tissue to its initial state at the next step.
TEST(Multirate, TheServedWorkerIsTheHeadlessPipelineWhenItKeepsUp) {
  auto m = compile_model(beam_with_probe(4));
  SimulationOptions o;
  o.multirate_on_worker = true;
  Simulation served(m, o);
  ASSERT_NE(served.multirate(), nullptr);
  served.multirate()->start();
  State headless = State::initial(*m);
  TickWorkspace w(*m);
  int handed = 0;
  int64_t spanned = 0;
  const int ticks = 200;
  for (int k = 0; k < ticks; ++k) {
    const ToolInput in = press(0.0002 + 5e-6 * k);
    served.commands().submit(0, in.pose, static_cast<uint64_t>(k + 1), 0, 0);
    served.step_multirate({}, [&](const TickReport& step, const State& tissue, int64_t n, const TickReport&) {
      ++handed;
      spanned += n;
      EXPECT_GE(n, m->fem_every);
      EXPECT_EQ(tissue.step, static_cast<int64_t>(handed) * m->fem_every) << "the tissue's clock, in ticks";
      EXPECT_TRUE(step.tissue_stepped);
    });
    tick(*m, headless, w, &in, 1);
    // Give the worker its period (a served tick is 1 ms apart): a step takes well under fem_every ms.
    std::this_thread::sleep_for(std::chrono::microseconds(1000));
  }
  served.multirate()->stop();
  EXPECT_EQ(served.state().step, ticks);
  // How many steps the worker finishes depends on the machine (under TSan it fell to half of
  // the ticks' worth: timing is the benchmarks'): that it made progress, and that the steps it
  // handed off never span more ticks than passed, hold at any speed.
  EXPECT_GT(handed, 0);
  EXPECT_LE(spanned, ticks);
  EXPECT_EQ(served.multirate()->steps(), static_cast<uint64_t>(handed));
  if (served.multirate()->steps_late() == 0) {
    // Every step on time: the worker's tissue after its last step is the emulation's at that tick.
    State replay = State::initial(*m);
    TickWorkspace w2(*m);
    const int64_t at = served.tissue_state().step;
    for (int64_t k = 0; k < at; ++k) {  // its last step at tick at − fem_every, the ones after hold
      const ToolInput in = press(0.0002 + 5e-6 * static_cast<double>(k));
      tick(*m, replay, w2, &in, 1);
    }
    EXPECT_EQ(replay.tissue.x, served.tissue_state().tissue.x);
  }
  // Reset: the haptic-rate state at once, the tissue at the next step — the first step handed
  // off after it is the tissue's first from its initial state.
  ASSERT_TRUE(served.reset());
  EXPECT_EQ(served.state().step, 0);
  served.multirate()->start();
  int64_t first_after_reset = -1;
  const auto capture = [&](const TickReport&, const State& tissue, int64_t, const TickReport&) {
    if (first_after_reset < 0) first_after_reset = tissue.step;
  };
  for (int k = 0; k < 500 && first_after_reset < 0; ++k) {
    served.step_multirate({}, capture);
    std::this_thread::sleep_for(std::chrono::microseconds(1000));
  }
  served.multirate()->stop();
  EXPECT_EQ(first_after_reset, m->fem_every) << "the tissue started again from its initial state";
  EXPECT_EQ(served.tissue_state().step % m->fem_every, 0);
}
