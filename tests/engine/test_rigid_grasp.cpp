// A tool's grasp of a rigid body (issue 42; engine/rigid_grasp.hpp): in one scripted run a
// grasper closes on a box resting on a fixed slab, lifts it (the box follows, the tool feels its
// weight), opens (the box falls back and rests on the slab), closes on it again and lifts it
// again.

#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "engine/state.hpp"
#include "engine/tick.hpp"
#include "scene/compiled_scenario.hpp"
#include "scene/scenario_spec.hpp"
#include "tests/test_scenarios.hpp"

using namespace stroma;

namespace {

const std::string kSrc = STROMA_SOURCE_DIR;
constexpr double kG = 9.81;

std::string grasp_yaml() {
  return test_scenarios::rigid_scene_head("grasp") + R"(tools:
  - name: grasper
    shape: {type: grasper, radius: 0.002, length: 0.01}
    grasp: {close: 0.05, open: 0.1}
    pose: {position: [0, 0.03, 0], orientation: [0.7071067811865476, 0.7071067811865476, 0, 0]}
rigid_bodies:
  - name: slab
    shape: {type: box, size: [0.1, 0.01, 0.1]}
    density: 1000
    pose: {position: [0, -0.005, 0]}
    fixed: true
  - name: box
    shape: {type: box, size: [0.01, 0.01, 0.01]}
    density: 1000
    pose: {position: [0, 0.005, 0]}
)";
}

/// The grasper's centre height and jaw at time t (s): hover, descend, close, lift, hold, open,
/// descend again, close, lift. Its jaws point down (tool z = world −y), so the grasp centre is
/// half a jaw (5 mm) below the centre: at c = 10 mm it is the resting box's centre.
void script(double t, double* y, double* jaw) {
  auto ramp = [](double t, double t0, double t1, double a, double b) {
    return t <= t0 ? a : (t >= t1 ? b : a + (b - a) * (t - t0) / (t1 - t0));
  };
  *jaw = 0.3;
  if (t < 0.3) {
    *y = ramp(t, 0.1, 0.3, 0.03, 0.01);
  } else if (t < 0.8) {
    *y = ramp(t, 0.35, 0.65, 0.01, 0.03);
    if (t >= 0.31) *jaw = 0.0;
  } else if (t < 1.3) {
    *y = ramp(t, 1.1, 1.3, 0.03, 0.01);
  } else {
    *y = ramp(t, 1.35, 1.65, 0.01, 0.03);
    if (t >= 1.31) *jaw = 0.0;
  }
}

}  // namespace

TEST(RigidGrasp, AGrasperLiftsABoxReleasesItAndGraspsItAgain) {
  const auto m = compile_model(parse_scenario(grasp_yaml(), "grasp.yaml", kSrc));
  State s = State::initial(*m);
  TickWorkspace w(*m);
  const double mb = m->rigid_bodies[1].mass.mass;  // 1 g
  auto run_until = [&](double t_end) {
    while (s.time < t_end - 1e-9) {
      ToolInput in;
      in.tool = 0;
      in.seq = static_cast<uint64_t>(s.step + 1);
      in.pose.orientation = {std::sqrt(0.5), std::sqrt(0.5), 0, 0};
      script(s.time, &in.pose.position[1], &in.pose.jaw);
      const TickReport& r = tick(*m, s, w, &in, 1);
      ASSERT_TRUE(r.status == TickStatus::Ok) << s.time;
    }
  };
  // Resting on the slab before the grasp.
  run_until(0.3);
  EXPECT_NEAR(s.rigid[1].x[1], 0.005, 1e-4);
  EXPECT_EQ(s.tools[0].grasped_body, -1);
  // Closed at 0.31 s, lifted 20 mm by 0.65 s, held still to 0.8 s: the box hangs from the jaws
  // (its centre at the grasp centre, 5 mm below the tool, sagging by its weight over the hold's
  // three springs) and the tool feels its weight.
  run_until(0.8);
  EXPECT_EQ(s.tools[0].grasped_body, 1);
  EXPECT_EQ(w.report.tools[0].holding_body, 1);
  const double k = m->tools[0].grasp_stiffness;
  EXPECT_NEAR(s.rigid[1].x[1], 0.025 - mb * kG / (3 * k), 2e-5);
  EXPECT_NEAR(w.report.tools[0].force[1], -mb * kG, 0.02 * mb * kG);
  EXPECT_LT(std::abs(w.report.tools[0].force[0]) + std::abs(w.report.tools[0].force[2]), 0.02 * mb * kG);
  // Opened at 0.8 s: it falls 20 mm and rests on the slab again by 1.1 s.
  run_until(1.1);
  EXPECT_EQ(s.tools[0].grasped_body, -1);
  EXPECT_EQ(w.report.tools[0].holding_body, -1);
  EXPECT_NEAR(s.rigid[1].x[1], 0.005, 2e-4);
  EXPECT_LT(std::abs(s.rigid[1].v[1]), 0.01);
  EXPECT_NEAR(w.report.tools[0].force[1], 0.0, 1e-9);
  // Grasped again at 1.31 s and lifted by 1.65 s.
  run_until(1.8);
  EXPECT_EQ(s.tools[0].grasped_body, 1);
  EXPECT_NEAR(s.rigid[1].x[1], 0.025 - mb * kG / (3 * k), 2e-4);
  EXPECT_NEAR(w.report.tools[0].force[1], -mb * kG, 0.02 * mb * kG);
}
