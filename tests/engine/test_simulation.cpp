// The one Simulation every front end drives (engine/simulation.hpp): tool commands checked and
// counted by its commands port whatever sent them, the hold policies, reset and restore.

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>

#include "engine/simulation.hpp"
#include "runtime/headless_runner.hpp"
#include "scene/compiled_scenario.hpp"
#include "scene/scenario_spec.hpp"
#include "tests/test_scenarios.hpp"

namespace stroma {
namespace {

const std::string kSrc = STROMA_SOURCE_DIR;

/// A 50 mm cube (5 kPa, ν 0.45, ρ 1000, bottom bonded) and a 5 mm sphere probe; `tool_extra`:
/// more lines of the tool (limits, script), `tail`: more top-level sections.
std::string probe_yaml(const std::string& tool_extra, const std::string& tail = "") {
  return "name: probe\n"
         "bodies:\n"
         "  - name: cube\n"
         "    mesh: " + kSrc + "/scenarios/meshes/cube_tet4_h5p000mm.msh\n"
         "    material: {young_modulus: 5000, poisson_ratio: 0.45, density: 1000}\n"
         "    fixed:\n"
         "      - box: {min: [-1, -1, -1], max: [1, 1.0e-9, 1]}\n"
         "tools:\n"
         "  - name: probe\n"
         "    shape: {type: sphere, radius: 0.005}\n"
         "    contact: {stiffness: 1.0e4}\n" + tool_extra + tail;
}

/// The probe scene's model with `limits` (workspace, max_speed, on_invalid) on the probe.
std::shared_ptr<const Model> probe_model(const std::string& limits) {
  return compile_scenario(parse_scenario(probe_yaml(limits), "probe.yaml", kSrc)).model;
}

ToolPose at(double x, double y, double z) {
  ToolPose p;
  p.position = {x, y, z};
  return p;
}

int64_t ns(const Simulation& sim) { return std::llround(sim.state().time * 1e9); }

TEST(SimulationCommands, NonFiniteAndNonUnitQuaternionAreRefusedCountedAndNeverApplied) {
  Simulation sim(probe_model(""));
  ToolCommandPort& port = sim.commands();
  ASSERT_EQ(port.submit(0, at(0.025, 0.08, 0.025), 1, ns(sim), ns(sim)).result, ToolCheck::Accepted);
  sim.advance();
  const Vec3 before = sim.state().tools[0].pose.position;
  ToolPose nan = at(0.025, std::numeric_limits<double>::quiet_NaN(), 0.025);
  EXPECT_EQ(port.submit(0, nan, 2, ns(sim), ns(sim)).result, ToolCheck::Rejected);
  ToolPose zero_q = at(0.025, 0.08, 0.025);
  zero_q.orientation = {0, 0, 0, 0};
  EXPECT_EQ(port.submit(0, zero_q, 3, ns(sim), ns(sim)).result, ToolCheck::Rejected);
  ToolPose long_q = at(0.025, 0.08, 0.025);
  long_q.orientation = {1.1, 0, 0, 0};
  EXPECT_EQ(port.submit(0, long_q, 4, ns(sim), ns(sim)).result, ToolCheck::Rejected);
  sim.advance();
  EXPECT_EQ(sim.state().tools[0].pose.position, before) << "a refused command is never applied";
  EXPECT_EQ(sim.state().tools[0].seq, 1u);
  EXPECT_EQ(port.counters().rejected.load(), 3u);
  EXPECT_EQ(port.counters().accepted.load(), 1u);
  EXPECT_EQ(port.counters().received(), 4u);
}

TEST(SimulationCommands, AJumpTenTimesTheSpeedLimitIsRefusedOrClampedToIt) {
  for (const bool clamp : {false, true}) {
    Simulation sim(probe_model(std::string("    max_speed: 0.5\n    on_invalid: ") + (clamp ? "clamp\n" : "reject\n")));
    ToolCommandPort& port = sim.commands();
    ASSERT_EQ(port.submit(0, at(0.025, 0.08, 0.025), 1, ns(sim), ns(sim)).result, ToolCheck::Accepted);
    sim.advance();
    // 10 × 0.5 m/s over one 1 ms tick: 5 mm.
    const double dt = sim.model().time_step, jump = 10 * 0.5 * dt;
    const ToolCheck c = port.submit(0, at(0.025, 0.08 - jump, 0.025), 2, ns(sim), ns(sim));
    sim.advance();
    const double y = sim.state().tools[0].pose.position[1];
    if (clamp) {
      EXPECT_EQ(c.result, ToolCheck::Clamped);
      EXPECT_NEAR(0.08 - y, 0.5 * dt, 1e-12) << "moved by the speed limit × the tick";
      EXPECT_EQ(port.counters().clamped.load(), 1u);
    } else {
      EXPECT_EQ(c.result, ToolCheck::Rejected);
      EXPECT_EQ(y, 0.08) << "the tool stays where it was";
      EXPECT_EQ(port.counters().rejected.load(), 1u);
    }
  }
}

TEST(SimulationCommands, TwoCommandsWithTheSameClockAreStillSpeedChecked) {
  // A sender whose clock does not advance (two commands before one tick) gets no free jump:
  // the interval is taken as one tick.
  Simulation sim(probe_model("    max_speed: 0.5\n"));
  ToolCommandPort& port = sim.commands();
  ASSERT_EQ(port.submit(0, at(0.025, 0.08, 0.025), 1, 0, 0).result, ToolCheck::Accepted);
  EXPECT_EQ(port.submit(0, at(0.025, 0.06, 0.025), 2, 0, 0).result, ToolCheck::Rejected);
  EXPECT_EQ(port.submit(0, at(0.025, 0.0799, 0.025), 3, 0, 0).result, ToolCheck::Accepted);
}

TEST(SimulationCommands, OutsideTheWorkspaceIsRefusedOrClampedToItsEdge) {
  for (const bool clamp : {false, true}) {
    Simulation sim(probe_model(std::string("    workspace: {min: [-0.1, 0.06, -0.1], max: [0.1, 0.2, 0.1]}\n"
                                           "    on_invalid: ") + (clamp ? "clamp\n" : "reject\n")));
    const ToolCheck c = sim.commands().submit(0, at(0.025, 0.05, 0.025), 1, 0, 0);
    sim.advance();
    if (clamp) {
      ASSERT_EQ(c.result, ToolCheck::Clamped);
      EXPECT_EQ(sim.state().tools[0].pose.position[1], 0.06);
    } else {
      EXPECT_EQ(c.result, ToolCheck::Rejected);
      EXPECT_LT(sim.state().tools[0].last_command_time, 0) << "never commanded";
    }
  }
}

TEST(SimulationCommands, RepeatHoldsAnAcceptedPoseTimeoutLetsTheToolGoIdle) {
  const std::shared_ptr<const Model> m = probe_model("    timeout: 0.01\n");
  for (const ToolHold hold : {ToolHold::Timeout, ToolHold::Repeat}) {
    SimulationOptions o;
    o.hold = hold;
    Simulation sim(m, o);
    ASSERT_EQ(sim.commands().submit(0, at(0.025, 0.08, 0.025), 1, 0, 0).result, ToolCheck::Accepted);
    for (int k = 0; k < 30; ++k) sim.advance();
    EXPECT_EQ(sim.state().tools[0].active, hold == ToolHold::Repeat) << "after 30 ms, timeout 10 ms";
    EXPECT_EQ(sim.commands().counters().accepted.load(), 1u) << "a held pose is one command";
  }
}

TEST(SimulationCommands, RestoringAStateChecksTheNextCommandFromThatStatesPose) {
  Simulation sim(probe_model("    max_speed: 0.5\n"));
  ToolCommandPort& port = sim.commands();
  ASSERT_EQ(port.submit(0, at(0.025, 0.08, 0.025), 1, ns(sim), ns(sim)).result, ToolCheck::Accepted);
  sim.advance();
  const State early = sim.state();
  // Walk the tool 0.4 mm per tick (0.4 m/s) down 10 ticks: 4 mm from where the snapshot has it.
  for (int k = 1; k <= 10; ++k) {
    ASSERT_EQ(port.submit(0, at(0.025, 0.08 - 4e-4 * k, 0.025), k + 1, ns(sim), ns(sim)).result, ToolCheck::Accepted);
    sim.advance();
  }
  sim.restore(sim.model_ptr(), early);
  // From the restored state a step of 0.4 mm is within the limit (it was not from the pose the
  // port saw last, 4 mm away, at a later client time).
  EXPECT_EQ(port.submit(0, at(0.025, 0.08 - 4e-4, 0.025), 20, ns(sim), ns(sim)).result, ToolCheck::Accepted);
  EXPECT_EQ(port.submit(0, at(0.025, 0.08 - 4e-3, 0.025), 21, ns(sim), ns(sim)).result, ToolCheck::Rejected);
}

TEST(SimulationCommands, StromaRunCountsItsScriptedCommandsAndRefusesOnesOutsideTheLimits) {
  // A script that leaves the workspace halfway: the ticks after are refused and counted, the tool
  // holds its last accepted pose (then times out), and summary's counters add up.
  const std::string script = test_scenarios::write_temp("leaving_script.yaml",
                                                        "keyframes:\n"
                                                        "  - {t: 0.0, position: [0.025, 0.09, 0.025]}\n"
                                                        "  - {t: 0.02, position: [0.025, 0.05, 0.025]}\n");
  const std::string yaml = probe_yaml("    workspace: {min: [-0.1, 0.07, -0.1], max: [0.1, 0.2, 0.1]}\n"
                                      "    script: " + script + "\n",
                                      "run: {steps: 20}\n");
  const CompiledScenario sc = compile_scenario(parse_scenario(yaml, "scripted.yaml", kSrc));
  RunOptions o;
  o.progress = false;
  o.metrics = false;
  const RunResult r = run_headless(sc, o);
  // y(t) = 0.09 − 2 t: inside (y ≥ 0.07) for t ≤ 0.01 s, i.e. ticks 0..10.
  EXPECT_EQ(r.commands_accepted, 11u);
  EXPECT_EQ(r.commands_rejected, 9u);
  EXPECT_EQ(r.commands_accepted + r.commands_clamped + r.commands_rejected, 20u);
  EXPECT_NEAR(r.final_state.tools[0].pose.position[1], 0.07, 1e-12);
}

}  // namespace
}  // namespace stroma
