// Tool commands: the checks that keep bad device input out of physics, and scripted tools in
// headless runs.

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>

#include "engine/trajectory.hpp"
#include "haptics/tool.hpp"
#include "runtime/headless_runner.hpp"
#include "runtime/session_log.hpp"
#include "tests/test_labels.hpp"
#include "tests/test_scenarios.hpp"
#include "tissue/input_error.hpp"

using namespace stroma;
namespace fs = std::filesystem;
using test_scenarios::write_temp;

namespace {
ToolSpec limited(InvalidCommandPolicy p) {
  ToolSpec s;
  s.name = "probe";
  s.workspace_min = {-1, -1, -1};
  s.workspace_max = {1, 1, 1};
  s.max_speed = 2.0;
  s.on_invalid = p;
  return s;
}
ToolPose at(double x, double y, double z) {
  ToolPose p;
  p.position = {x, y, z};
  return p;
}
}  // namespace

TEST(ToolCheck, AcceptsValidCommandAndRenormalisesQuaternion) {
  ToolPose c = at(0.1, 0.2, 0.3);
  c.orientation = {1.0005, 0, 0, 0};
  const ToolCheck r = validate_tool_command(limited(InvalidCommandPolicy::Reject), at(0.1, 0.2, 0.3), 0.001, c);
  EXPECT_EQ(r.result, ToolCheck::Accepted);
  EXPECT_DOUBLE_EQ(r.pose.orientation[0], 1.0);
}

TEST(ToolCheck, RejectsNonFiniteAndNonUnitQuaternionUnderEitherPolicy) {
  for (auto policy : {InvalidCommandPolicy::Reject, InvalidCommandPolicy::Clamp}) {
    ToolPose nan = at(std::numeric_limits<double>::quiet_NaN(), 0, 0);
    EXPECT_EQ(validate_tool_command(limited(policy), at(0, 0, 0), 0.001, nan).result, ToolCheck::Rejected);
    ToolPose inf = at(0, 0, 0);
    inf.jaw = std::numeric_limits<double>::infinity();
    EXPECT_EQ(validate_tool_command(limited(policy), at(0, 0, 0), 0.001, inf).result, ToolCheck::Rejected);
    ToolPose q = at(0, 0, 0);
    q.orientation = {0.5, 0.5, 0, 0};  // |q| = 0.707
    const ToolCheck r = validate_tool_command(limited(policy), at(0, 0, 0), 0.001, q);
    EXPECT_EQ(r.result, ToolCheck::Rejected);
    EXPECT_STREQ(r.reason, "orientation is not a unit quaternion");
  }
}

TEST(ToolCheck, WorkspaceAndSpeedRejectOrClamp) {
  const ToolPose last = at(0, 0, 0);
  // Outside the workspace.
  EXPECT_EQ(validate_tool_command(limited(InvalidCommandPolicy::Reject), last, 0, at(1.5, 0, 0)).result,
            ToolCheck::Rejected);
  ToolCheck c = validate_tool_command(limited(InvalidCommandPolicy::Clamp), last, 0, at(1.5, 0, 0));
  EXPECT_EQ(c.result, ToolCheck::Clamped);
  EXPECT_DOUBLE_EQ(c.pose.position[0], 1.0);
  // 0.01 m in 1 ms = 10 m/s > 2 m/s.
  EXPECT_EQ(validate_tool_command(limited(InvalidCommandPolicy::Reject), last, 0.001, at(0.01, 0, 0)).result,
            ToolCheck::Rejected);
  c = validate_tool_command(limited(InvalidCommandPolicy::Clamp), last, 0.001, at(0.01, 0, 0));
  EXPECT_EQ(c.result, ToolCheck::Clamped);
  EXPECT_NEAR(c.pose.position[0], 0.002, 1e-15);  // max_speed × dt along the same direction
  // Just under the limit: accepted unchanged.
  c = validate_tool_command(limited(InvalidCommandPolicy::Reject), last, 0.001, at(0.0019, 0, 0));
  EXPECT_EQ(c.result, ToolCheck::Accepted);
  EXPECT_DOUBLE_EQ(c.pose.position[0], 0.0019);
}

TEST(ScriptedTool, HeadlessRunFollowsTheTrajectoryAndGoesIdleAfterTimeout) {
  ScenarioSpec spec = test_scenarios::liver();
  spec.tools.at(0).script = std::string(STROMA_SOURCE_DIR) + "/scenarios/trajectories/liver_press.yaml";
  const CompiledScenario sc_m = compile_scenario(spec);
  RunOptions o;
  o.steps = 1500;
  o.progress = false;
  o.metrics = false;
  const RunResult r = run_headless(sc_m, o);
  const ToolState& t = r.final_state.tools.at(0);
  EXPECT_TRUE(t.active);
  EXPECT_EQ(t.seq, 1500u);
  // Applied at the start of the last tick: the script sampled at t = 1.499 s.
  const ToolPose want = sc_m.tool_scripts[0].sample(1.499);
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(t.pose.position[k], want.position[k], 1e-12);

  // The same scene driven by a session log that stops commanding: idle after `timeout`.
  SessionEvent cmd;
  cmd.kind = SessionEvent::Tool;
  cmd.tick = 0;
  cmd.input.pose = want;
  SessionEvent end;
  end.kind = SessionEvent::End;
  end.tick = 400;  // 0.4 s < timeout 0.5 s
  o.replay = write_temp("stroma_idle.log", std::string(kSessionLogHeader) + format_session_event(cmd) + format_session_event(end));
  EXPECT_TRUE(run_headless(sc_m, o).final_state.tools[0].active);
  end.tick = 700;  // 0.7 s > timeout: idle, pose held
  o.replay = write_temp("stroma_idle.log", std::string(kSessionLogHeader) + format_session_event(cmd) + format_session_event(end));
  const RunResult idle = run_headless(sc_m, o);
  EXPECT_FALSE(idle.final_state.tools[0].active);
  EXPECT_EQ(idle.final_state.tools[0].pose.position, want.position);
}

namespace {

/// Largest nodal distance between two position arrays.
double max_distance(const std::vector<double>& a, const std::vector<double>& b) {
  double worst = 0;
  for (size_t i = 0; i + 2 < a.size(); i += 3)
    worst = std::max(worst, std::hypot(a[i] - b[i], a[i + 1] - b[i + 1], a[i + 2] - b[i + 2]));
  return worst;
}

}  // namespace

// A client that dies mid-press (issue 15 §3): its tool held the press for ever — the tissue's
// energy stayed at the pressed level. After `timeout` the idle tool lets go and the tissue
// returns to where it rests without a tool.
TEST(ScriptedTool, IdleToolReleasesTheTissueAfterItsTimeout) {
  STROMA_LONG_TEST();
  ScenarioSpec spec = load_scenario(std::string(STROMA_SOURCE_DIR) + "/scenarios/physical/liver_16cm.yaml");
  const CompiledScenario sc = compile_scenario(spec);
  ASSERT_DOUBLE_EQ(sc.model->tools.at(0).timeout, 0.5);
  const Trajectory press = load_trajectory(std::string(STROMA_SOURCE_DIR) + "/scenarios/trajectories/physical_liver_press.yaml");
  const double dt = sc.model->time_step;
  // The client commands the press for 2 s (12 mm into the 16 cm liver), then dies.
  std::string log = kSessionLogHeader;
  for (int k = 0; k < 2000; ++k) {
    SessionEvent e;
    e.kind = SessionEvent::Tool;
    e.tick = k;
    e.input.seq = static_cast<uint64_t>(k + 1);
    e.input.pose = press.sample(k * dt);
    log += format_session_event(e);
  }
  auto run_to = [&](int64_t ticks, const std::string& body) {
    SessionEvent end;
    end.kind = SessionEvent::End;
    end.tick = ticks;
    RunOptions o;
    o.progress = false;
    o.metrics = false;
    o.replay = write_temp("stroma_dead_client.log", body + format_session_event(end));
    return run_headless(sc, o);
  };
  const RunResult pressed = run_to(2000, log);
  ASSERT_GT(std::hypot(pressed.final_state.tools[0].force[0], pressed.final_state.tools[0].force[1], pressed.final_state.tools[0].force[2]), 0.1) << "the probe is not pressing";
  const RunResult rest_pressed = run_to(2000, kSessionLogHeader);  // the same ticks, no tool
  const double press_depth = max_distance(pressed.final_state.tissue.x, rest_pressed.final_state.tissue.x);
  ASSERT_GT(press_depth, 0.005);  // m
  // 0.5 s of silence → idle; then 2 s to relax.
  const RunResult released = run_to(4500, log);
  const RunResult rest = run_to(4500, kSessionLogHeader);
  const ToolState& t = released.final_state.tools[0];
  EXPECT_FALSE(t.active);
  EXPECT_EQ(t.grasped, 0);
  EXPECT_EQ(t.force, (Vec3{0, 0, 0}));
  EXPECT_EQ(t.pose.position, pressed.final_state.tools[0].pose.position);  // the pose is held, not used
  EXPECT_LT(max_distance(released.final_state.tissue.x, rest.final_state.tissue.x), 0.05 * press_depth);
}
