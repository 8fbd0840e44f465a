// Threads in the scenario (issue 43; docs/THREAD.md): `threads:` compiles into a rod of the FEM
// node space (tissue/rod.hpp) beside the tissue, steps in the same Simulation, snapshots and
// restores with the state; bad input is refused with file:line:field.

#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "engine/model_check.hpp"
#include "engine/simulation.hpp"
#include "engine/state.hpp"
#include "scene/compiled_scenario.hpp"
#include "scene/scenario_spec.hpp"
#include "tests/input_error_message.hpp"

using namespace stroma;
using stroma::test_support::message_of;

namespace {

const std::string kSrc = STROMA_SOURCE_DIR;
constexpr double kPi = 3.14159265358979323846;

/// A fixed 50 mm cube of tissue and a 0.1 m thread (0.2 mm, 50 segments) from above its corner
/// along x, its first end fixed; `thread` replaces or adds thread keys (YAML lines at 4 spaces).
std::string scene_yaml(const std::string& thread = "    segments: 50\n") {
  return R"(name: thread_scene
time_step: 0.001
gravity: [0, -9.81, 0]
solver: {integrator: implicit_euler, linear_solver: cholmod}
bodies:
  - name: block
    mesh: )" + kSrc + R"(/scenarios/meshes/cube_tet4_h8p333mm.msh
    material: {young_modulus: 3.0e4, poisson_ratio: 0.45, density: 1000}
    fixed:
      - box: {min: [-1, -1, -1], max: [1, 1, 1]}
threads:
  - name: suture
    length: 0.1
    diameter: 2.0e-4
    young_modulus: 5.0e9
    density: 1100
    start: [0, 0.1, 0]
    direction: [1, 0, 0]
    fixed: [first]
)" + thread;
}

}  // namespace

// The thread's nodes follow the tissue's: straight from its start along its direction, ρ·A·L of
// mass, its first node fixed; the model's invariants hold.
TEST(Thread, CompilesIntoARodAfterTheTissuesNodes) {
  std::shared_ptr<const Model> m = compile_model(parse_scenario(scene_yaml(), "thread.yaml", kSrc));
  std::string why;
  ASSERT_TRUE(model_invariants_hold(*m, &why)) << why;
  ASSERT_EQ(m->fem.rods.size(), 1u);
  const RodRange& r = m->fem.rods[0];
  EXPECT_EQ(r.name, "suture");
  EXPECT_EQ(r.node_begin, m->fem.bodies[0].node_end);
  EXPECT_EQ(r.nodes(), 51);
  EXPECT_EQ(r.node_end, m->fem.num_nodes);
  EXPECT_DOUBLE_EQ(r.segment_length, 0.002);
  double mass = 0;
  for (int32_t i = r.node_begin; i < r.node_end; ++i) {
    const double* X = m->fem.rest.data() + 3 * i;
    EXPECT_NEAR(X[0], 0.002 * (i - r.node_begin), 1e-15);
    EXPECT_EQ(X[1], 0.1);
    mass += m->fem.mass[i];
  }
  EXPECT_NEAR(mass, 1100 * kPi * 4e-8 / 4 * 0.1, 1e-18);
  EXPECT_EQ(m->fem.constrained[r.node_begin], 7);
  EXPECT_EQ(m->fem.constrained[r.node_begin + 1], 0);
}

// In the one Simulation: the thread swings down under gravity from its fixed end while the
// fixed tissue stays; a snapshot restored replays the same ticks bit for bit.
TEST(Thread, SwingsInTheSimulationAndReplaysFromASnapshot) {
  std::shared_ptr<const Model> m = compile_model(parse_scenario(scene_yaml(), "thread.yaml", kSrc));
  Simulation sim(m);
  for (int i = 0; i < 200; ++i) sim.advance();
  const RodRange& r = m->fem.rods[0];
  const std::vector<double>& x = sim.state().tissue.x;
  EXPECT_LT(x[3 * (r.node_end - 1) + 1], 0.1 - 0.01) << "the free end fell";
  EXPECT_EQ(x[3 * r.node_begin + 1], 0.1) << "the fixed end stayed";
  const State snap = sim.state();
  for (int i = 0; i < 100; ++i) sim.advance();
  const std::vector<double> after = sim.state().tissue.x;
  sim.restore(m, snap);
  for (int i = 0; i < 100; ++i) sim.advance();
  EXPECT_EQ(sim.state().tissue.x, after);
}

TEST(Thread, BadInputIsRefusedWithFileLineAndField) {
  auto msg = [](const std::string& thread) {
    return message_of([&] { compile_model(parse_scenario(scene_yaml(thread), "thread.yaml", kSrc)); });
  };
  // The scene with `from` replaced by `to`.
  auto edited = [](const std::string& from, const std::string& to) {
    std::string y = scene_yaml();
    y.replace(y.find(from), from.size(), to);
    return message_of([&] { compile_model(parse_scenario(y, "thread.yaml", kSrc)); });
  };
  std::string e = msg("    segments: 1\n");
  EXPECT_NE(e.find("thread.yaml:20: threads[0].segments"), std::string::npos) << e;
  EXPECT_NE(e.find("at least 2 segments"), std::string::npos) << e;
  e = edited("diameter: 2.0e-4", "diameter: 0");
  EXPECT_NE(e.find("thread.yaml:14: threads[0].diameter"), std::string::npos) << e;
  e = edited("young_modulus: 5.0e9", "young_modulus: -1");
  EXPECT_NE(e.find("threads[0].young_modulus"), std::string::npos) << e;
  e = msg("    segments: 4\n");  // 25 mm segments of a 0.2 mm thread: 125 diameters
  EXPECT_NE(e.find("threads[0].segments"), std::string::npos) << e;
  EXPECT_NE(e.find("125 diameters"), std::string::npos) << e;
  EXPECT_NE(e.find("at least 5 segments"), std::string::npos) << e;
  e = edited("    start: [0, 0.1, 0]\n    direction: [1, 0, 0]\n", "    path: [[0, 0, 0], [0.05, 0, 0]]\n");
  EXPECT_NE(e.find("threads[0].path"), std::string::npos) << e;
  EXPECT_NE(e.find("0.05 m long, the thread 0.1 m"), std::string::npos) << e;
  e = edited("fixed: [first]", "fixed: [first]\n    contact_stiffness: -1");
  EXPECT_NE(e.find("threads[0].contact_stiffness"), std::string::npos) << e;
  // A flexural rigidity above the solid rod's (E·π·d⁴/64 = 3.9e-7 N·m² here), and segments too
  // long for a braid's (2 mm of a thread with EI 1e-9: at most 4·100·√(EI/EA) = 1.0 mm).
  e = edited("fixed: [first]", "fixed: [first]\n    bending_stiffness: 1.0e-6");
  EXPECT_NE(e.find("threads[0].bending_stiffness"), std::string::npos) << e;
  EXPECT_NE(e.find("more than a solid rod"), std::string::npos) << e;
  e = edited("fixed: [first]", "fixed: [first]\n    bending_stiffness: -1");
  EXPECT_NE(e.find("threads[0].bending_stiffness"), std::string::npos) << e;
  e = edited("fixed: [first]", "fixed: [first]\n    bending_stiffness: 1.0e-9");
  EXPECT_NE(e.find("threads[0].segments"), std::string::npos) << e;
  EXPECT_NE(e.find("at least 100 segments"), std::string::npos) << e;
  e = edited("fixed: [first]", "fixed: [middle]");
  EXPECT_NE(e.find("expected first or last"), std::string::npos) << e;
  e = message_of([&] {
    parse_scenario(scene_yaml() + "  - {name: block, length: 0.1, segments: 50, diameter: 2.0e-4, young_modulus: 5.0e9, "
                                  "density: 1100, start: [0, 0.2, 0]}\n",
                   "thread.yaml", kSrc);
  });
  EXPECT_NE(e.find("threads[1].name"), std::string::npos) << e;
  EXPECT_NE(e.find("already the name"), std::string::npos) << e;
}
