// A needle's wire against a coarse tissue surface (rigid/wire_contact.hpp): lying on a slope of
// a 100 mm block whose surface triangles have 16.7 mm edges (20× the 0.8 mm wire), it slides as
// Coulomb's law says — a = g (sin θ − μ cos θ) — and sticks when μ exceeds tan θ, without
// slipping between samples of the surface. The block is held in place, so the slope is exact.

#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "engine/state.hpp"
#include "engine/tick.hpp"
#include "scene/compiled_scenario.hpp"
#include "scene/scenario_spec.hpp"

namespace stroma {
namespace {

const std::string kSrc = STROMA_SOURCE_DIR;
constexpr double kG = 9.81;

/// The 50 mm cube mesh scaled to 100 mm, every node held; gravity tilted by theta in the x–y
/// plane (down the slope is +x); a straight 40 mm needle lying along x on the top face (y = 0.1),
/// across the mesh's node lines (z = 43.7 mm), its tail at x = 30 mm.
std::string slope_yaml(double theta, double mu) {
  const double gx = kG * std::sin(theta), gy = -kG * std::cos(theta);
  return R"(name: needle_on_a_slope
time_step: 0.001
gravity: [)" + std::to_string(gx) + ", " + std::to_string(gy) + R"(, 0]
solver: {integrator: implicit_euler, preconditioner: block_jacobi, tolerance: 1.0e-10}
bodies:
  - name: block
    mesh: )" + kSrc + R"(/scenarios/meshes/cube_tet4_h8p333mm.msh
    scale: 2.0
    material: {young_modulus: 3.0e4, poisson_ratio: 0.45, density: 1000}
    fixed:
      - box: {min: [-1, -1, -1], max: [1, 1, 1]}
rigid_bodies:
  - name: needle
    shape: {type: needle, wire_radius: 0.0004, length: 0.04}
    density: 7800
    contact: {friction: )" + std::to_string(mu) + R"(}
    pose: {position: [0.03, 0.1004, 0.0437], orientation: [0.7071067811865476, 0, 0.7071067811865476, 0]}
)";
}

struct SlopeRun {
  double a = 0;          ///< m/s²: down the slope, from the velocities at 0.05 and 0.1 s (its tip 16 mm on)
  double max_sink = 0;   ///< m: deepest the wire's axis came below r above the face
  double off_line = 0;   ///< m: largest |z| drift and |rotation| × half length
};

SlopeRun slide(double theta, double mu) {
  std::shared_ptr<const Model> m = compile_model(parse_scenario(slope_yaml(theta, mu), "slope.yaml", kSrc));
  TickWorkspace w(*m);
  State s = State::initial(*m);
  SlopeRun out;
  double v1 = 0;
  while (s.time < 0.1 - 1e-9) {
    const TickReport& r = tick(*m, s, w, nullptr, 0);
    EXPECT_TRUE(r.status == TickStatus::Ok) << s.time;
    const RigidState& b = s.rigid[0];
    if (s.time > 0.01) out.max_sink = std::max(out.max_sink, 0.1004 - b.x[1]);
    out.off_line = std::max(out.off_line, std::abs(b.x[2] - 0.0437));
    if (std::abs(s.time - 0.05) < 1e-9) v1 = b.v[0];
  }
  out.a = (s.rigid[0].v[0] - v1) / 0.05;
  return out;
}

TEST(WireContact, ANeedleOnACoarseSlopeSlidesAtGTimesSinMinusMuCosAndSticksWhenMuExceedsTheTangent) {
  const double theta = 30 * M_PI / 180;
  const SlopeRun sl = slide(theta, 0.2);
  const double expect = kG * (std::sin(theta) - 0.2 * std::cos(theta));  // 3.21 m/s²
  std::printf("needle on a 30 deg slope, mu 0.2: a = %.4g m/s^2, g (sin - mu cos) = %.4g (%+.2f %%); sank %.3g m, "
              "drifted %.3g m across\n", sl.a, expect, 100 * (sl.a / expect - 1), sl.max_sink, sl.off_line);
  EXPECT_NEAR(sl.a, expect, 0.02 * expect);
  // It rests on the face: its penalty depth under its weight is m g cos θ / (k · 2r · L), with
  // k = 100 E / r (the automatic stiffness): 1.5e-8 m — it never falls between samples.
  EXPECT_LT(sl.max_sink, 1e-5);
  EXPECT_LT(sl.off_line, 1e-4) << "sliding along its axis, it stays on its line";
  const SlopeRun st = slide(theta, 0.7);  // tan 30° = 0.58 < 0.7: it sticks
  std::printf("mu 0.7: a = %.3g m/s^2, sank %.3g m\n", st.a, st.max_sink);
  EXPECT_LT(std::abs(st.a), 0.01);
  EXPECT_LT(st.max_sink, 1e-5);
}

}  // namespace
}  // namespace stroma
