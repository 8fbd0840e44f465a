// The one feedback path (haptics/feedback.hpp): the force a tool feels is the force of the solved
// step; headless ticks and the real-time loop hand the same feedback to clients; the clamp and
// the virtual coupling's torque.

#include <gtest/gtest.h>

#include "tissue/clock.hpp"

#include <atomic>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <thread>

#include "bench/accuracy/quarter_block_mesh.hpp"
#include "engine/tick.hpp"
#include "haptics/feedback.hpp"
#include "runtime/headless_runner.hpp"
#include "runtime/physics_loop.hpp"
#include "scene/compiled_scenario.hpp"
#include "tests/test_labels.hpp"
#include "tests/test_scenarios.hpp"

using namespace stroma;
namespace fs = std::filesystem;

namespace {

Vec3 cross(const Vec3& a, const Vec3& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
double norm(const Vec3& a) { return std::sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]); }

}  // namespace

// Without coupling the device renders the contact wrench, clamped as a whole to max_force.
TEST(Feedback, ClampScalesForceAndTorqueTogether) {
  ToolSpec spec;
  spec.max_force = 10;
  ToolState ts;
  ToolOutput out;
  out.force = {0, 0, 20};
  out.torque = {0.4, 0, 0};
  out.stiffness[8] = -300;
  const ToolFeedback fb = device_feedback(spec, ts, out, 1e-3);
  EXPECT_TRUE(fb.clamped);
  EXPECT_DOUBLE_EQ(fb.force[2], 10.0);
  EXPECT_DOUBLE_EQ(fb.torque[0], 0.2);
  EXPECT_DOUBLE_EQ(fb.stiffness[8], -300);
  out.force = {0, 0, 5};
  const ToolFeedback below = device_feedback(spec, ts, out, 1e-3);
  EXPECT_FALSE(below.clamped);
  EXPECT_DOUBLE_EQ(below.force[2], 5.0);
  EXPECT_DOUBLE_EQ(below.torque[0], 0.4);
}

// A probe with a shaft, coupled to its device, laid onto the liver: the real-time loop (driven
// tick by tick through its lock-free ports, as the server drives it) publishes exactly the
// feedback the headless tick computes for the same commands; under coupling the torque is the
// coupling spring's about the device point, (proxy − device) × F, not the contacts' torque.
TEST(Feedback, ServedAndHeadlessGiveTheSameFeedbackAndTheCouplingsTorque) {
  ScenarioSpec spec = test_scenarios::liver();
  spec.bodies[0].visual.reset();
  ToolSpec& t = spec.tools.at(0).spec;
  t.timeout = 100;
  t.max_speed = 1e3;
  t.shape = ToolShape::Probe;
  t.shaft_radius = 0.2;
  t.shaft_length = 2.0;
  t.coupling_stiffness = 200;
  t.coupling_damping = 0.5;
  t.max_force = 1e4;
  auto m = compile_model(spec);

  auto command = [](int k) {
    ToolInput in;
    in.tool = 0;
    in.seq = static_cast<uint64_t>(k + 1);
    in.pose.orientation = {std::sqrt(0.5), 0, std::sqrt(0.5), 0};  // shaft along world +x
    in.pose.position = {-2.6, 6.0 - 1.8 * std::min(k, 250) / 250.0, 0.5};
    return in;
  };
  constexpr int kTicks = 320;

  // Headless.
  State s = State::initial(*m);
  TickWorkspace w(*m);
  std::vector<ToolFeedback> headless;
  int coupled_ticks = 0;
  double max_contact_torque_gap = 0;
  for (int k = 0; k < kTicks; ++k) {
    const ToolInput in = command(k);
    const TickReport& r = tick(*m, s, w, &in, 1);
    ASSERT_NE(r.status, TickStatus::NonFinite);
    const ToolFeedback& fb = r.tools[0].feedback;
    headless.push_back(fb);
    const ToolState& ts = s.tools[0];
    if (!ts.has_proxy || r.tools[0].contacts == 0) continue;
    ++coupled_ticks;
    const Vec3 stretch{ts.proxy[0] - ts.pose.position[0], ts.proxy[1] - ts.pose.position[1],
                       ts.proxy[2] - ts.pose.position[2]};
    const Vec3 expected = cross(stretch, fb.force);
    for (int i = 0; i < 3; ++i) EXPECT_NEAR(fb.torque[i], expected[i], 1e-12 * (1 + norm(expected))) << "tick " << k;
    Vec3 gap;
    for (int i = 0; i < 3; ++i) gap[i] = r.tools[0].torque[i] - fb.torque[i];
    max_contact_torque_gap = std::max(max_contact_torque_gap, norm(gap));
  }
  ASSERT_GT(coupled_ticks, 30) << "the probe never touched the liver";
  // The contacts' torque on the proxy is real and differs: sending it would fail the check above.
  EXPECT_GT(max_contact_torque_gap, 0.1);

  // Served: the loop starts paused; each command is published, then one Step control lets one
  // tick take it; the feedback batch of that tick is read back.
  PhysicsLoopOptions opt;
  opt.start_paused = true;
  opt.budget = false;  // a loaded test machine must not truncate a served solve the headless one converges
  PhysicsLoop loop(m, opt);
  std::atomic<bool> stop{false};
  std::thread physics([&] { loop.run(stop); });
  uint64_t seen = loop.feedback_published.load();
  for (int k = 0; k < kTicks; ++k) {
    // Through the commands port, as the server's input thread submits (the client's clock a
    // second per command: the speed limit is not what this test is about).
    const ToolInput in = command(k);
    ASSERT_NE(loop.commands().submit(0, in.pose, in.seq, (k + 1) * 1000000000LL, steady_now_ns()).result,
              ToolCheck::Rejected);
    ASSERT_TRUE(loop.controls.push({ControlEvent::Step, 1}));
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20);
    while (loop.feedback_published.load() == seen && std::chrono::steady_clock::now() < deadline)
      std::this_thread::sleep_for(std::chrono::microseconds(50));
    ASSERT_NE(loop.feedback_published.load(), seen) << "no tick at step " << k;
    seen = loop.feedback_published.load();
    ASSERT_TRUE(loop.feedback_out.update());
    const FeedbackBatch& b = loop.feedback_out.read_slot();
    ASSERT_EQ(b.count, 1);
    const ToolFeedbackFrame& f = b.frames[0];
    EXPECT_EQ(f.seq, static_cast<uint64_t>(k + 1));
    for (int i = 0; i < 3; ++i) {
      ASSERT_EQ(f.force[i], headless[k].force[i]) << "tick " << k << " axis " << i;
      ASSERT_EQ(f.torque[i], headless[k].torque[i]) << "tick " << k << " axis " << i;
    }
    for (int i = 0; i < 9; ++i) ASSERT_EQ(f.stiffness[i], headless[k].stiffness[i]) << "tick " << k;
  }
  ASSERT_TRUE(loop.controls.push({ControlEvent::Shutdown, 0}));
  physics.join();
  // The served hand-off (copies into the lock-free buffers) is timed under hand_off.
  EXPECT_GT(loop.stats().stage_ns_total[static_cast<int>(Stage::HandOff)], 0);
}

// A sphere indenting a soft block slowly (1 µm per tick, a haptic device at 1 mm/s): the force
// reported every tick is the force of the solved step and follows the quasi-static force curve
// (static equilibria at the same depths, same mesh) within a few per cent. The force found at
// the start of the tick — this tick's tool motion pressed into last tick's surface — would read
// tens of per cent high here.
TEST(Feedback, SlowIndenterFollowsTheQuasiStaticForceCurve) {
  STROMA_LONG_TEST();
  const double a = 0.05, H = 0.05, R = 0.005, speed = 1e-3;  // m, m/s
  const std::string mesh =
      write_quarter_block((fs::temp_directory_path() / "stroma_feedback_block.msh").string(), a, H, 5e-4, 1.5);
  auto scenario = [&](const std::string& solver, const std::string& script) {
    return test_scenarios::indentation_block_yaml(mesh, script, solver, "corotational", ", rayleigh_mass: 20",
                                                  "    max_speed: 1\n    timeout: 100\n");
  };
  const std::string dyn_traj = (fs::temp_directory_path() / "stroma_slow_indent.csv").string();
  {
    std::FILE* f = std::fopen(dyn_traj.c_str(), "w");
    std::fprintf(f, "t,x,y,z\n0,0,0,%.17g\n1,0,0,%.17g\n", H + R, H + R - speed * 1.0);
    std::fclose(f);
  }
  const std::vector<double> depths = {2e-4, 4e-4, 6e-4};
  // Quasi-static curve: one static run through the depths (continuation from one to the next).
  const std::string static_traj = (fs::temp_directory_path() / "stroma_static_indent.csv").string();
  {
    std::FILE* f = std::fopen(static_traj.c_str(), "w");
    std::fprintf(f, "t,x,y,z\n");
    for (size_t i = 0; i < depths.size(); ++i) std::fprintf(f, "%zu,0,0,%.17g\n", i, H + R - depths[i]);
    std::fclose(f);
  }
  ScenarioSpec sspec = parse_scenario(
      scenario("{integrator: static, linear_solver: cholmod, static_tolerance: 1.0e-10}", static_traj), "s.yaml", "");
  sspec.time_step = 1.0;  // one equilibrium per keyframe
  const CompiledScenario ssc = compile_scenario(sspec);
  const fs::path sdir = fs::temp_directory_path() / "stroma_static_indent_out";
  RunOptions so;
  so.progress = false;
  so.steps = static_cast<long>(depths.size()) - 1;
  so.out_dir = sdir.string();
  const RunResult sr = run_headless(ssc, so);
  ASSERT_TRUE(sr.ok) << sr.failure;
  // metrics.csv: one row per equilibrium with the tool's force.
  std::vector<double> static_force;
  {
    std::FILE* f = std::fopen((sdir / "metrics.csv").c_str(), "r");
    ASSERT_NE(f, nullptr);
    char line[8192];
    ASSERT_NE(std::fgets(line, sizeof line, f), nullptr);
    const std::string header(line);
    int col = 0;
    size_t pos = 0, fz = std::string::npos;
    for (size_t i = 0; i <= header.size(); ++i)
      if (i == header.size() || header[i] == ',') {
        if (header.compare(pos, i - pos, "sphere_fz") == 0) fz = static_cast<size_t>(col);
        ++col;
        pos = i + 1;
      }
    ASSERT_NE(fz, std::string::npos);
    while (std::fgets(line, sizeof line, f)) {
      std::string l(line);
      size_t c = 0, p = 0;
      while (c < fz) {
        p = l.find(',', p) + 1;
        ++c;
      }
      static_force.push_back(4.0 * std::stod(l.substr(p)));
    }
    std::fclose(f);
  }
  ASSERT_EQ(static_force.size(), depths.size());
  for (size_t i = 1; i < depths.size(); ++i) EXPECT_GT(static_force[i], static_force[i - 1]);

  const CompiledScenario dsc = compile_scenario(
      parse_scenario(scenario("{integrator: implicit_euler, linear_solver: cg, tolerance: 1.0e-8, max_iterations: 2000}",
                              dyn_traj),
                     "d.yaml", ""));
  const Model& m = *dsc.model;
  State s = State::initial(m);
  TickWorkspace w(m);
  size_t next = 0;
  const int ticks = static_cast<int>(std::lround(depths.back() / speed / m.time_step)) + 1;
  for (int k = 0; k < ticks && next < depths.size(); ++k) {
    ToolInput in;
    in.seq = static_cast<uint64_t>(k + 1);
    in.pose = dsc.tool_scripts[0].sample(s.time);  // applied at the start of tick k
    const double depth = H + R - in.pose.position[2];
    const TickReport& r = tick(m, s, w, &in, 1);
    ASSERT_NE(r.status, TickStatus::NonFinite);
    if (std::abs(depth - depths[next]) < 1e-9) {
      const double F = 4.0 * r.tools[0].force[2];
      // The springs as found at the start of the tick (before the solve moved the surface).
      double F_start = 0;
      for (int32_t i = r.tools[0].spring_begin; i < r.tools[0].spring_end; ++i) F_start -= 4.0 * w.springs[i].force[2];
      std::printf("depth %.2f mm: force per tick %.5f N, quasi-static %.5f N (%+.2f %%); at the tick's start %.5f N "
                  "(%+.1f %%)\n",
                  depth * 1e3, F, static_force[next], 100 * (F / static_force[next] - 1), F_start,
                  100 * (F_start / static_force[next] - 1));
      EXPECT_NEAR(F, static_force[next], 0.05 * static_force[next]) << "depth " << depth;
      // This test tells the two apart: the start-of-tick force is far off the curve.
      EXPECT_GT(std::abs(F_start / static_force[next] - 1), 0.2) << "depth " << depth;
      ++next;
    }
  }
  EXPECT_EQ(next, depths.size());
}
