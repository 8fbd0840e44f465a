// A thread's contacts (issue 43; engine/thread_contact.hpp, docs/THREAD.md "Contact"): on a
// tissue's surface (resting, and sliding under Coulomb friction on a slope — the inclined-plane
// law), on a rigid body, on another thread, under a tool, and with itself: 10,000 seeded random
// motions of a coiled thread never let two segments pass through each other, checked by an
// independent continuous test of every segment pair over every tick.

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <set>
#include <string>

#include "engine/model_check.hpp"
#include "engine/state.hpp"
#include "engine/thread_contact.hpp"
#include "engine/tick.hpp"
#include "scene/compiled_scenario.hpp"
#include "scene/scenario_spec.hpp"
#include "tests/test_labels.hpp"
#include "tests/thread_crossing.hpp"
#include "tests/test_scenarios.hpp"

using namespace stroma;
using stroma::test_support::count_passes;
using stroma::test_support::segments_pass;

namespace {

const std::string kSrc = STROMA_SOURCE_DIR;
constexpr double kPi = 3.14159265358979323846;
constexpr double kD = 2.0e-4;  // the suture's diameter (USP 3-0)

/// A 50 mm block [0, 0.05]³, every node fixed (its surface a still table), E 30 kPa, under
/// gravity `g`; then `rest` (YAML from `rigid_bodies:` / `tools:` on).
std::string table_scene(const std::string& name, const std::string& g, const std::string& rest) {
  return "name: " + name + "\ntime_step: 0.001\ngravity: " + g + R"(
solver: {integrator: implicit_euler, preconditioner: block_jacobi, tolerance: 1.0e-10}
bodies:
  - name: block
    mesh: )" + kSrc + R"(/scenarios/meshes/cube_tet4_h8p333mm.msh
    material: {young_modulus: 3.0e4, poisson_ratio: 0.45, density: 1000}
    fixed:
      - box: {min: [-1, -1, -1], max: [1, 1, 1]}
)" + rest;
}

/// A thread entry: 0.2 mm, E 5 GPa, 1100 kg/m³, straight from `start` along `dir`.
std::string thread(const std::string& name, double length, int segments, const std::string& start,
                   const std::string& dir, const std::string& extra = "") {
  return "  - name: " + name + "\n    length: " + std::to_string(length) + "\n    segments: " + std::to_string(segments) +
         "\n    diameter: 2.0e-4\n    young_modulus: 5.0e9\n    density: 1100\n    start: " + start +
         "\n    direction: " + dir + "\n" + extra;
}

double com(const Model& m, const State& s, int axis, bool velocity) {
  const RodRange& r = m.fem.rods[0];
  double sum = 0, mass = 0;
  for (int32_t i = r.node_begin; i < r.node_end; ++i) {
    sum += m.fem.mass[i] * (velocity ? s.tissue.v : s.tissue.x)[size_t(3 * i + axis)];
    mass += m.fem.mass[i];
  }
  return sum / mass;
}

}  // namespace

// Dropped from 2 mm onto the table, a thread comes to rest on it: every node one radius above the
// surface (its penalty's sag, w/(100·E) per metre, is 1e-10 m here), still, and it never rises
// above where it fell from (no energy gained at impact).
TEST(ThreadContact, AThreadDroppedOnTissueRestsOnItsSurface) {
  const std::string yaml = table_scene("drop", "[0, -9.81, 0]",
                                       "threads:\n" + thread("suture", 0.03, 15, "[0.01, 0.052, 0.025]", "[1, 0, 0.3]",
                                                             "    damping: {rayleigh_mass: 5}\n"));
  const auto m = compile_model(parse_scenario(yaml, "drop.yaml", kSrc));
  std::string why;
  ASSERT_TRUE(model_invariants_hold(*m, &why)) << why;
  ASSERT_TRUE(m->has_contact);
  State s = State::initial(*m);
  TickWorkspace w(*m);
  const RodRange& r = m->fem.rods[0];
  double top = 0;
  for (int i = 0; i < 1000; ++i) {
    const TickReport& rep = tick(*m, s, w, nullptr, 0);
    ASSERT_TRUE(rep.status == TickStatus::Ok) << i;
    for (int32_t n = r.node_begin; n < r.node_end; ++n) top = std::max(top, s.tissue.x[size_t(3 * n + 1)]);
    EXPECT_EQ(rep.thread_contact.dropped, 0);
  }
  EXPECT_LE(top, 0.052 + 1e-9) << "never above where it fell from";
  EXPECT_GT(w.report.thread_contact.tissue, 0);
  for (int32_t n = r.node_begin; n < r.node_end; ++n) {
    EXPECT_NEAR(s.tissue.x[size_t(3 * n + 1)], 0.05 + 0.5 * kD, 1e-6) << "node " << n - r.node_begin;
    EXPECT_LT(std::abs(s.tissue.v[size_t(3 * n + 1)]), 1e-4);
  }
}

// On the table tilted by α (gravity turned): below the friction angle (tan α < μ = 0.2) the thread
// stays; above it, it slides down with the inclined plane's a = g·(sin α − μ·cos α), within 3 %
// — measured between 0.1 s and 0.2 s: the regularised friction is a damper set from the
// velocity at the start of each step, so while the thread speeds up it lags by the step's gain
// (over the first 0.2 s from rest that is ~4 % of v; from 0.1 s on, ~2 % of a).
TEST(ThreadContact, OnASlopeAThreadSticksBelowTheFrictionAngleAndSlidesAbove) {
  auto run = [&](double alpha_deg) {
    const double a = alpha_deg * kPi / 180;
    const std::string g = "[" + std::to_string(9.81 * std::sin(a)) + ", " + std::to_string(-9.81 * std::cos(a)) + ", 0]";
    const std::string yaml = table_scene("slope", g, "threads:\n" + thread("suture", 0.02, 10, "[0.005, 0.0501, 0.025]", "[1, 0, 0]"));
    const auto m = compile_model(parse_scenario(yaml, "slope.yaml", kSrc));
    State s = State::initial(*m);
    TickWorkspace w(*m);
    const double x0 = com(*m, s, 0, false);
    double v1 = 0;
    for (int i = 0; i < 200; ++i) {
      EXPECT_TRUE(tick(*m, s, w, nullptr, 0).status == TickStatus::Ok) << i;
      if (i == 99) v1 = com(*m, s, 0, true);
    }
    return std::array<double, 3>{com(*m, s, 0, false) - x0, v1, com(*m, s, 0, true)};
  };
  const auto still = run(8.0);  // tan 8° = 0.14 < 0.2
  EXPECT_LT(std::abs(still[0]), 1e-5) << "it sticks";
  const double a = 15.0 * kPi / 180;
  const double expect = 9.81 * (std::sin(a) - 0.2 * std::cos(a));  // 0.644 m/s²
  const auto slid = run(15.0);
  EXPECT_NEAR((slid[2] - slid[1]) / 0.1, expect, 0.03 * expect) << "sliding at the inclined plane's acceleration";
  EXPECT_NEAR(slid[0], 0.5 * expect * 0.04, 0.06 * 0.5 * expect * 0.04) << "and as far (the start's lag: 6 %)";
}

// On a rigid box, on another thread, under a tool: each holds it by contact.
TEST(ThreadContact, AThreadRestsOnARigidBoxAndOnAnotherThread) {
  const std::string yaml = test_scenarios::rigid_scene_head("box") + R"(rigid_bodies:
  - name: box
    shape: {type: box, size: [0.04, 0.01, 0.04]}
    density: 1000
    fixed: true
    pose: {position: [0, -0.005, 0]}
threads:
)" + thread("under", 0.03, 15, "[-0.015, 0.0001, 0.0]", "[1, 0, 0]", "    fixed: [first, last]\n") +
                           thread("over", 0.02, 10, "[0.0, 0.0004, -0.01]", "[0, 0, 1]", "    damping: {rayleigh_mass: 5}\n");
  const auto m = compile_model(parse_scenario(yaml, "box.yaml", kSrc));
  State s = State::initial(*m);
  TickWorkspace w(*m);
  for (int i = 0; i < 1500; ++i) ASSERT_TRUE(tick(*m, s, w, nullptr, 0).status == TickStatus::Ok) << i;
  const RodRange &under = m->fem.rods[0], &over = m->fem.rods[1];
  // "under" lies on the box (its ends fixed one radius above the top face).
  for (int32_t n = under.node_begin; n < under.node_end; ++n)
    EXPECT_NEAR(s.tissue.x[size_t(3 * n + 1)], 0.5 * kD, 2e-6) << "under, node " << n - under.node_begin;
  // "over" crosses it at its middle and rests there, one diameter higher (a 5 GPa suture is a
  // beam: its 10 mm halves droop by w·L⁴/(8·E·I) = 1 µm, so its ends stay in the air), still and
  // nowhere below the box's top.
  const int32_t mid = over.node_begin + 5;
  EXPECT_NEAR(s.tissue.x[size_t(3 * mid + 1)], 1.5 * kD, 5e-6) << "over rests on under";
  for (int32_t n = over.node_begin; n < over.node_end; ++n) {
    EXPECT_GT(s.tissue.x[size_t(3 * n + 1)], 0.5 * kD - 2e-6) << "over, node " << n - over.node_begin;
    EXPECT_LT(std::abs(s.tissue.v[size_t(3 * n + 1)]), 1e-4);
  }
  EXPECT_GT(w.report.thread_contact.self, 0);
  EXPECT_GT(w.report.thread_contact.rigid, 0);
}

TEST(ThreadContact, AToolPushesAThreadAndFeelsIt) {
  const std::string yaml = test_scenarios::rigid_scene_head("push") + R"(tools:
  - name: probe
    shape: {type: sphere, radius: 0.002}
    max_speed: 1.0
    pose: {position: [0, 0.005, 0]}
threads:
)" + thread("line", 0.04, 20, "[-0.02, 0, 0]", "[1, 0, 0]", "    fixed: [first, last]\n    damping: {rayleigh_mass: 20}\n");
  const auto m = compile_model(parse_scenario(yaml, "push.yaml", kSrc));
  State s = State::initial(*m);
  TickWorkspace w(*m);
  const RodRange& r = m->fem.rods[0];
  double y = 0.005;
  for (int i = 0; i < 1500; ++i) {
    y = std::max(-0.003, 0.005 - 0.01 * 0.001 * i);  // down at 10 mm/s to 3 mm below the line
    ToolInput in;
    in.tool = 0;
    in.seq = uint64_t(i + 1);
    in.pose.position = {0, y, 0};
    ASSERT_TRUE(tick(*m, s, w, &in, 1).status == TickStatus::Ok) << i;
  }
  const double* mid = s.tissue.x.data() + 3 * (r.node_begin + 10);
  // The line wraps the sphere's bottom: its middle one radius below the sphere (the penalty's
  // give at this tension within 2 % of the radius sum).
  EXPECT_NEAR(mid[1], y - 0.002 - 0.5 * kD, 0.02 * (0.002 + 0.5 * kD));
  EXPECT_GT(w.report.tools[0].force[1], 0) << "the thread pushes the probe back up";
  // Its tension T: the two straight halves from (±20 mm, 0) to the sphere pull it down by 2·T·sinθ.
  EXPECT_GT(w.report.thread_contact.tools, 0);
}


// The checker itself: two segments swapping sides pass; two sliding by each other's ends do not.
TEST(ThreadContact, TheCrossingCheckSeesAPassThrough) {
  const double a0[3] = {-1, 0, 0}, a1[3] = {1, 0, 0};
  const double b0[3] = {0, 1, -1}, b1[3] = {0, 1, 1}, B0[3] = {0, -1, -1}, B1[3] = {0, -1, 1};
  EXPECT_TRUE(segments_pass(a0, a1, b0, b1, a0, a1, B0, B1));
  const double c0[3] = {3, 1, -1}, c1[3] = {3, 1, 1}, C0[3] = {3, -1, -1}, C1[3] = {3, -1, 1};
  EXPECT_FALSE(segments_pass(a0, a1, c0, c1, a0, a1, C0, C1));
}

// A loop of thread (64 mm, its ends fixed 4 mm apart; E 1 MPa, an elastic thread: its contact —
// as stiff as its segments' axial springs, 15 N/m — is soft, the harder case), no gravity:
// 10,000 seeded random motions, each throwing two random stretches of the loop (five nodes
// each, at least four segments apart) at each other at 0.15..0.3 m/s (up to 1.5 diameters a
// tick each: three between them) with a random spread of 0.05 m/s per node, then 3 ticks. The
// loop crumples and folds on itself; no two segments that share no node ever pass through each
// other over any tick (an independent continuous check of every pair).
TEST(ThreadContact, TenThousandRandomMotionsNeverPassAThreadThroughItself) {
  STROMA_LONG_TEST();
  const int segs = 32;
  const double len = 0.064, gap = 0.004, R = (len + gap) / (2 * kPi);  // a circle with a 4 mm gap
  std::string path = "[";
  const int pts = 320;
  double total = 0, prev[3] = {0, 0, 0};
  const double phi0 = 0.5 * gap / R;
  for (int i = 0; i <= pts; ++i) {
    const double phi = phi0 + (2 * kPi - 2 * phi0) * i / pts;
    const double p[3] = {R * std::sin(phi), 0.1, R * (1 - std::cos(phi))};
    if (i > 0) total += std::sqrt(std::pow(p[0] - prev[0], 2) + std::pow(p[1] - prev[1], 2) + std::pow(p[2] - prev[2], 2));
    std::copy(p, p + 3, prev);
    char buf[128];
    std::snprintf(buf, sizeof buf, "%s[%.12g, %.12g, %.12g]", i ? ", " : "", p[0], p[1], p[2]);
    path += buf;
  }
  path += "]";
  char lenbuf[64];
  std::snprintf(lenbuf, sizeof lenbuf, "%.12g", total);
  const std::string yaml = table_scene("loop", "[0, 0, 0]", R"(threads:
  - name: loop
    length: )" + std::string(lenbuf) + "\n    segments: " + std::to_string(segs) + R"(
    diameter: 2.0e-4
    young_modulus: 1.0e6
    density: 1100
    damping: {rayleigh_mass: 20}
    fixed: [first, last]
    path: )" + path + "\n");
  const auto m = compile_model(parse_scenario(yaml, "loop.yaml", kSrc));
  State s = State::initial(*m);
  TickWorkspace w(*m);
  const RodRange& r = m->fem.rods[0];
  std::mt19937 rng(20261207);
  std::uniform_real_distribution<double> U(-1.0, 1.0);
  std::uniform_int_distribution<int32_t> node(r.node_begin + 2, r.node_end - 3);
  std::vector<double> x0(s.tissue.x.size());
  int passes = 0, self_springs = 0, ticks = 0, not_ok = 0, touching = 0;
  for (int motion = 0; motion < 10000; ++motion) {
    int32_t a = node(rng), b = node(rng);
    while (std::abs(a - b) < 4) b = node(rng);
    double dir[3], n2 = 0;
    for (int k = 0; k < 3; ++k) dir[k] = s.tissue.x[size_t(3 * b + k)] - s.tissue.x[size_t(3 * a + k)], n2 += dir[k] * dir[k];
    const double speed = 0.225 + 0.075 * U(rng), inv = n2 > 0 ? 1 / std::sqrt(n2) : 0;
    for (int32_t c = -2; c <= 2; ++c)
      for (int k = 0; k < 3; ++k) {
        if (!m->fem.constrained[size_t(a + c)]) s.tissue.v[size_t(3 * (a + c) + k)] = speed * dir[k] * inv + 0.05 * U(rng);
        if (!m->fem.constrained[size_t(b + c)]) s.tissue.v[size_t(3 * (b + c) + k)] = -speed * dir[k] * inv + 0.05 * U(rng);
      }
    for (int t = 0; t < 3; ++t) {
      std::copy(s.tissue.x.begin(), s.tissue.x.end(), x0.begin());
      const TickReport& rep = tick(*m, s, w, nullptr, 0);
      ++ticks;
      if (rep.status != TickStatus::Ok && rep.status != TickStatus::SolverNotConverged) ++not_ok;
      self_springs += rep.thread_contact.self;
      touching += rep.thread_contact.self > 0;
      passes += count_passes(*m, x0, s.tissue.x.data());
    }
  }
  std::printf("  %d ticks (%d with segments touching), %d self-contact springs, %d ticks not ok, %d pass-throughs\n",
              ticks, touching, self_springs, not_ok, passes);
  EXPECT_GT(touching, ticks / 4) << "the loop folded on itself";
  EXPECT_EQ(passes, 0);
  EXPECT_EQ(not_ok, 0);
}


// A thread at rest driven through another within one step. A suture ("over") lies 0.4 mm above
// a second one ("under", its ends fixed, in a viscous medium: mass damping 10⁴/s) that it
// crosses; both at rest, under a gravity of 1000 m/s² — standing for any force within the step
// that the velocities at its start do not show (a knot's bending springing open, a grasper's
// jerk). From rest "over" falls 1 mm in the first step, "under" 0.09 mm. No speculative spring
// joins the two (nothing approaches at the tick's start), so without more "over" would go
// through "under"; the continuous check after the step sees the two meet, adds their spring and
// the step is redone. Over 30 ticks no two segments pass through each other (the independent
// crossing check) and "over" stays on "under" where they cross, one diameter above it.
TEST(ThreadContact, AThreadDrivenThroughAnotherWithinOneStepIsStoppedByTheContinuousCheck) {
  std::string yaml = test_scenarios::rigid_scene_head("drop") + R"(threads:
)" + thread("under", 0.03, 15, "[-0.015, 0, 0.0001]", "[1, 0, 0]",
                                "    fixed: [first, last]\n    damping: {rayleigh_mass: 1.0e4}\n") +
                     thread("over", 0.02, 10, "[0.0001, 0.0006, -0.01]", "[0, 0, 1]");
  yaml.replace(yaml.find("gravity: [0, -9.81, 0]"), 22, "gravity: [0, -1000, 0]");
  const auto m = compile_model(parse_scenario(yaml, "drop.yaml", kSrc));
  State s = State::initial(*m);
  TickWorkspace w(*m);
  const RodRange &under = m->fem.rods[0], &over = m->fem.rods[1];
  // Where a thread crosses the plane `axis` = 0.0001 (its segment's straddling points): its y.
  auto y_at = [&](const RodRange& r, int axis) {
    for (int32_t n = r.node_begin; n + 1 < r.node_end; ++n) {
      const double* p = s.tissue.x.data() + 3 * n;
      if (p[axis] <= 0.0001 && p[3 + axis] >= 0.0001)
        return p[1] + (p[4] - p[1]) * (0.0001 - p[axis]) / (p[3 + axis] - p[axis]);
    }
    return std::nan("");
  };
  std::vector<double> x0(s.tissue.x.size());
  int passes = 0, first_missed = 0;
  for (int i = 0; i < 30; ++i) {
    std::copy(s.tissue.x.begin(), s.tissue.x.end(), x0.begin());
    const TickReport& rep = tick(*m, s, w, nullptr, 0);
    ASSERT_TRUE(rep.status == TickStatus::Ok || rep.status == TickStatus::SolverNotConverged) << i;
    if (i == 0) first_missed = rep.thread_contact.missed;
    passes += count_passes(*m, x0, s.tissue.x.data());
  }
  EXPECT_EQ(passes, 0);
  EXPECT_GT(first_missed, 0) << "the first step met the thread below without a spring";
  EXPECT_NEAR(y_at(over, 2) - y_at(under, 0), kD, 0.1 * kD) << "over rests on under";
}

// The same through a rigid body: a suture 0.3 mm above a fixed 2 mm rod (a capsule across it),
// at rest, under 1000 m/s²: it falls 1 mm in the first step, through the rod but for the
// continuous check, which gives the points that met it their springs; it drapes over the rod.
// The thread's points never enter the rod (its distance to the rod's axis, at every node and
// tick, stays above the rod's radius less a twentieth of the thread's).
TEST(ThreadContact, AThreadDrivenThroughARigidRodWithinOneStepIsStoppedByTheContinuousCheck) {
  std::string yaml = test_scenarios::rigid_scene_head("rod") + R"(rigid_bodies:
  - name: rod
    shape: {type: capsule, radius: 0.001, length: 0.1}
    density: 1000
    fixed: true
threads:
)" + thread("over", 0.02, 40, "[-0.01, 0.0014, 0.0001]", "[1, 0, 0]");
  yaml.replace(yaml.find("gravity: [0, -9.81, 0]"), 22, "gravity: [0, -1000, 0]");
  const auto m = compile_model(parse_scenario(yaml, "rod.yaml", kSrc));
  State s = State::initial(*m);
  TickWorkspace w(*m);
  const RodRange& r = m->fem.rods[0];
  int first_missed = -1;
  double closest = 1;
  for (int i = 0; i < 30; ++i) {
    const TickReport& rep = tick(*m, s, w, nullptr, 0);
    ASSERT_TRUE(rep.status == TickStatus::Ok || rep.status == TickStatus::SolverNotConverged) << i;
    if (i == 0) first_missed = rep.thread_contact.missed;
    for (int32_t n = r.node_begin; n < r.node_end; ++n)
      closest = std::min(closest, std::hypot(s.tissue.x[size_t(3 * n)], s.tissue.x[size_t(3 * n + 1)]));
  }
  EXPECT_GT(first_missed, 0) << "the first step met the rod without a spring";
  EXPECT_GT(closest, 0.001 + 0.45 * kD) << "no point of the thread went into the rod";
  const int32_t mid = r.node_begin + 20;
  EXPECT_GT(s.tissue.x[size_t(3 * mid + 1)], 0.001) << "it lies over the rod";
}

// The self-contact's broad phase (a sweep of the segments' bounding spheres) finds every pair the
// all-pairs scan would: 200 seeded random crumpled threads (two threads of 40 segments, random
// walks in a 6 mm box, at rest) — the self-contact springs made are exactly the segment pairs,
// sharing no node, whose centrelines are closer than a diameter plus the speculative margin of
// an eighth of it (at rest nothing approaches; closest points computed here pair by pair); none
// is missed: as many springs as such pairs, each between the two segments of one.
TEST(ThreadContact, TheSelfContactSweepFindsEveryTouchingPair) {
  const std::string yaml = table_scene("crumple", "[0, 0, 0]", "threads:\n" +
                                       thread("a", 0.04, 40, "[0.1, 0.1, 0.1]", "[1, 0, 0]") +
                                       thread("b", 0.04, 40, "[0.1, 0.2, 0.1]", "[1, 0, 0]"));
  const auto m = compile_model(parse_scenario(yaml, "crumple.yaml", kSrc));
  TickWorkspace w(*m);
  std::vector<double> x(m->fem.rest), v(x.size(), 0.0);
  std::mt19937 rng(43);
  std::uniform_real_distribution<double> U(-1.0, 1.0);
  int total = 0;
  for (int trial = 0; trial < 200; ++trial) {
    for (const RodRange& r : m->fem.rods) {  // a random walk of 1 mm steps, folded into a 6 mm box
      double p[3] = {0.1, 0.1, 0.1};
      for (int32_t i = r.node_begin; i < r.node_end; ++i) {
        for (int k = 0; k < 3; ++k) {
          x[3 * size_t(i) + k] = p[k];
          p[k] += 1e-3 * U(rng);
          // Reflected at the box's walls (clamped, nodes would pile up in its corners: segments
          // of zero length, whose contact normal is undefined and which make no spring).
          if (std::abs(p[k] - 0.1) > 3e-3) p[k] = 0.1 + std::copysign(6e-3 - std::abs(p[k] - 0.1), p[k] - 0.1);
        }
      }
    }
    std::vector<ContactSpring> springs;
    springs.reserve(TickWorkspace::kMaxContacts);
    std::vector<RigidContactPair> pairs;
    pairs.reserve(TickWorkspace::kMaxContacts);
    ThreadContactOutput out;
    thread_self_contact(*m, x.data(), v.data(), w.segment_spheres, w.segment_order, springs, pairs, out);
    ASSERT_EQ(out.dropped, 0);
    std::set<std::pair<int32_t, int32_t>> expected;
    std::vector<int32_t> seg;
    for (const RodRange& r : m->fem.rods)
      for (int32_t i = r.node_begin; i + 1 < r.node_end; ++i) seg.push_back(i);
    for (size_t a = 0; a < seg.size(); ++a)
      for (size_t b = a + 1; b < seg.size(); ++b) {
        const int32_t i = seg[a], j = seg[b];
        if (j - i < 2) continue;  // neighbours on one thread share a node (a thread's last and the next's first do not: j − i ≥ 2 then)
        double s, t;
        const double d2 = segment_closest_points(&x[3 * size_t(i)], &x[3 * size_t(i) + 3], &x[3 * size_t(j)],
                                                 &x[3 * size_t(j) + 3], &s, &t);
        if (d2 < std::pow(1.125 * kD, 2)) expected.insert({i, j});
      }
    // One spring per touching pair, each between the two segments of one of them (its nodes of
    // positive weight on one segment, of negative weight on the other; a closest point at a
    // segment's end leaves that end's other node out).
    EXPECT_EQ(springs.size(), expected.size()) << "trial " << trial;
    for (const ContactSpring& sp : springs) {
      bool found = false;
      for (const auto& [i, j] : expected) {
        bool a_ok = true, b_ok = true, a_sw = true, b_sw = true;
        for (int q = 0; q < sp.n; ++q) {
          const int32_t nd = sp.node[q];
          const bool on_i = nd == i || nd == i + 1, on_j = nd == j || nd == j + 1;
          if (sp.w[q] > 0) a_ok &= on_i, a_sw &= on_j;
          if (sp.w[q] < 0) b_ok &= on_j, b_sw &= on_i;
        }
        if ((a_ok && b_ok) || (a_sw && b_sw)) found = true;
      }
      EXPECT_TRUE(found) << "trial " << trial << ": a spring between segments that do not touch";
    }
    total += static_cast<int>(expected.size());
  }
  std::printf("  %d touching pairs over 200 crumpled pairs of threads\n", total);
  EXPECT_GT(total, 1000) << "the configurations touch";
}
