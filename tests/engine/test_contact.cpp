// Tool–tissue contact (haptics/contact): no contact means zero
// force, and a sphere pressing a clamped beam reaches a global force equilibrium with the
// clamp's reaction.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <set>

#include "tests/cantilever_with_probe.hpp"
#include "collision/triangle_bvh.hpp"
#include "engine/model.hpp"
#include "engine/state.hpp"
#include "engine/tick.hpp"
#include "scene/compiled_scenario.hpp"
#include "tests/test_labels.hpp"
#include "tests/test_scenarios.hpp"

using namespace stroma;

namespace {

ScenarioSpec beam_with_probe() { return test_scenarios::cantilever_with_probe(); }

}  // namespace

TEST(Contact, NoContactNoForceButTheCollideStageRuns) {
  auto m = compile_model(beam_with_probe());
  ASSERT_TRUE(m->has_contact);
  State s = State::initial(*m);
  TickWorkspace w(*m);
  ToolInput in;
  in.pose.position = {0.05, 0.05, 0.005};  // 4 cm above the beam
  for (int k = 0; k < 20; ++k) {
    const TickReport r = tick(*m, s, w, &in, 1);
    EXPECT_TRUE(r.stage_ran[static_cast<int>(Stage::Collide)]);
  }
  EXPECT_EQ(w.report.tools[0].contacts, 0);
  EXPECT_EQ(s.tools[0].force, (Vec3{0, 0, 0}));
  for (double v : s.tissue.v) EXPECT_LT(std::fabs(v), 1e-12);  // nothing moved (round-off only)
}

TEST(Contact, SpherePressingTheBeamBalancesTheClampReaction) {
  STROMA_LONG_TEST();
  auto m = compile_model(beam_with_probe());
  State s = State::initial(*m);
  TickWorkspace w(*m);
  ToolInput in;
  // Sphere over the tip, 1 mm into the top face (y = 0.01).
  in.pose.position = {0.095, 0.01 + 0.003 - 0.001, 0.005};
  tick(*m, s, w, &in, 1);
  for (int k = 0; k < 3000; ++k) ASSERT_NE(tick(*m, s, w).status, TickStatus::NonFinite);
  const ToolOutput& ts = w.report.tools[0];
  ASSERT_GT(ts.contacts, 0);
  EXPECT_GT(ts.force[1], 0.0) << "the tissue pushes the tool up";
  const double F = std::sqrt(ts.force[0] * ts.force[0] + ts.force[1] * ts.force[1] + ts.force[2] * ts.force[2]);
  EXPECT_LT(std::fabs(ts.force[0]) + std::fabs(ts.force[2]), 0.2 * F);
  // Feedback stiffness dF/dx is negative semidefinite along the press direction.
  EXPECT_LT(ts.stiffness[4], 0.0);
  // The beam bent down under the probe.
  EXPECT_LT(probe_displacement(*m, s, m->probes[0])[1], -1e-4);

  // Global equilibrium at rest: clamp reaction (elastic force on the fixed nodes) + tool force.
  const double vmax = *std::max_element(s.tissue.v.begin(), s.tissue.v.end(),
                                        [](double a, double b) { return std::fabs(a) < std::fabs(b); });
  ASSERT_LT(std::fabs(vmax), 1e-5) << "not settled";
  std::vector<double> f(m->fem.dofs());
  w.stepper().elastic_force(s.tissue, f.data());
  Vec3 reaction{0, 0, 0};
  for (int32_t i : m->fem.constrained_nodes)
    for (int k = 0; k < 3; ++k) reaction[k] += f[3 * i + k];
  // Forces on the beam: contact (−tool force) + clamp support (−reaction) sum to zero.
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(-ts.force[k] - reaction[k], 0.0, 0.01 * F) << "component " << k;
}

namespace {
/// The liver with its probe, pressed `depth` below the top surface at (x, z) (mesh units).
struct LiverProbe {
  std::shared_ptr<const Model> m;
  State s;
  std::unique_ptr<TickWorkspace> w;
  LiverProbe() {
    ScenarioSpec spec = test_scenarios::liver();
    spec.tools.at(0).spec.timeout = 100;
    spec.tools.at(0).spec.max_speed = 1e3;
    m = compile_model(spec);
    s = State::initial(*m);
    w = std::make_unique<TickWorkspace>(*m);
  }
  const TickReport& step_to(double x, double y, double z) {
    ToolInput in;
    in.pose.position = {x, y, z};
    return tick(*m, s, *w, &in, 1);
  }
  double total_energy() const {
    const TimeStepper& st = w->stepper();
    return st.kinetic_energy(s.tissue) + st.elastic_energy(s.tissue) + st.external_potential(s.tissue) +
           w->report.tools[0].contact_energy;
  }
};
}  // namespace

// Tool held still in contact for 10 s: the total energy (kinetic + elastic + gravity + contact
// potential) does not grow.
TEST(Contact, PassiveWhenTheToolIsHeldStill) {
  STROMA_LONG_TEST();
  LiverProbe lp;
  // Come down onto the upper surface at (-1.5, ·, 0.5) and press ~0.5 units in.
  for (int k = 0; k <= 1000; ++k) lp.step_to(-1.5, 6.0 - 1.2 * k / 1000.0, 0.5);
  ASSERT_GT(lp.w->report.tools[0].contacts, 0) << "probe did not reach the liver";
  for (int k = 0; k < 500; ++k) lp.step_to(-1.5, 4.8, 0.5);  // let the press transient pass
  const double e0 = lp.total_energy();
  double e_max = e0;
  for (int k = 0; k < 10000; ++k) {
    ASSERT_EQ(lp.step_to(-1.5, 4.8, 0.5).status == TickStatus::NonFinite, false);
    e_max = std::max(e_max, lp.total_energy());
  }
  const double scale = std::fabs(e0) + lp.w->report.tools[0].contact_energy + 1e-12;
  EXPECT_LE(e_max - e0, 1e-6 * scale) << "energy grew while the tool was held still";
  EXPECT_GT(lp.w->report.tools[0].contacts, 0);
}

// Sliding across the surface at constant height: the force changes smoothly from tick to tick.
TEST(Contact, ForceIsContinuousWhileSliding) {
  LiverProbe lp;
  for (int k = 0; k <= 1000; ++k) lp.step_to(-1.5, 6.0 - 1.2 * k / 1000.0, 0.5);
  for (int k = 0; k < 300; ++k) lp.step_to(-1.5, 4.8, 0.5);
  ASSERT_GT(lp.w->report.tools[0].contacts, 0);
  double prev = 0, max_jump = 0, sum = 0;
  int n = 0;
  for (int k = 0; k <= 1000; ++k) {  // 1 unit in 1 s along x (1 mm-scale per tick)
    lp.step_to(-1.5 + 1.0 * k / 1000.0, 4.8, 0.5);
    const Vec3& f = lp.s.tools[0].force;
    const double fm = std::sqrt(f[0] * f[0] + f[1] * f[1] + f[2] * f[2]);
    if (k > 0) max_jump = std::max(max_jump, std::fabs(fm - prev));
    prev = fm;
    sum += fm;
    ++n;
  }
  const double mean = sum / n;
  ASSERT_GT(mean, 0.0);
  // Stated bound: no tick-to-tick change larger than 5 % of the mean contact force.
  EXPECT_LT(max_jump, 0.05 * mean) << "max jump " << max_jump << ", mean force " << mean;
}

namespace {
/// Mean height (y) of the surface points a tool holds, at the state's positions.
double grasped_mean_height(const Model& m, const State& s, const ToolState& held) {
  double y = 0;
  for (int i = 0; i < held.grasped; ++i) {
    const auto& tri = m.collision_triangles[held.grasp_triangle[i]];
    const double u = held.grasp_uv[i][0], v = held.grasp_uv[i][1];
    y += (1 - u - v) * s.tissue.x[3 * tri[0] + 1] + u * s.tissue.x[3 * tri[1] + 1] + v * s.tissue.x[3 * tri[2] + 1];
  }
  return y / held.grasped;
}
}  // namespace

// Grasp-and-lift keeps hold; opening the jaws lets go.
TEST(Contact, GraspAndLiftHoldsAndReleaseLetsGo) {
  STROMA_LONG_TEST();  // 22-27 s under ASan; the shorter cut and contact tests cover its code there
  ScenarioSpec spec = test_scenarios::liver();
  spec.tools.at(0).spec.timeout = 100;
  spec.tools.at(0).spec.max_speed = 1e3;
  spec.tools.at(0).spec.can_grasp = true;
  auto m = compile_model(spec);
  State s = State::initial(*m);
  TickWorkspace w(*m);
  auto step = [&](double y, double jaw) {
    ToolInput in;
    in.pose.position = {-1.5, y, 0.5};
    in.pose.jaw = jaw;
    ASSERT_NE(tick(*m, s, w, &in, 1).status, TickStatus::NonFinite);
  };
  for (int k = 0; k <= 1000; ++k) step(6.0 - 1.2 * k / 1000.0, 0.3);  // press, jaws open
  for (int k = 0; k < 300; ++k) step(4.8, 0.3);
  ASSERT_GT(w.report.tools[0].contacts, 0);
  EXPECT_EQ(s.tools[0].grasped, 0) << "open jaws hold nothing";
  step(4.8, 0.0);  // close
  const int held = s.tools[0].grasped;
  ASSERT_GT(held, 0) << "closing on tissue grasps surface nodes";
  const ToolState grasped = s.tools[0];
  auto mean_y = [&] { return grasped_mean_height(*m, s, grasped); };
  const double y0 = mean_y();
  const double lift = 1.0;
  for (int k = 1; k <= 500; ++k) step(4.8 + lift * k / 500.0, 0.0);  // lift 1 unit in 0.5 s
  for (int k = 0; k < 500; ++k) step(4.8 + lift, 0.0);
  EXPECT_EQ(s.tools[0].grasped, held) << "hold kept while lifting";
  EXPECT_GT(mean_y() - y0, 0.7 * lift) << "grasped tissue follows the lift";
  EXPECT_LT(s.tools[0].force[1], 0.0) << "the lifted tissue pulls the tool down";
  const double lifted = mean_y() - y0;
  for (int k = 0; k < 4000; ++k) step(4.8 + lift, 0.3);  // open and wait (the liver is heavily damped)
  EXPECT_EQ(s.tools[0].grasped, 0);
  // Released, the tissue falls back towards its free shape (which is above y0: y0 was measured
  // while the probe pressed it down), dropping well below the lifted height.
  EXPECT_LT(mean_y() - y0, 0.5 * lifted) << "released tissue falls back";
}

// A probe with a shaft lying on the liver: the shaft touches where the tip alone would not,
// and the tissue's push on the shaft gives the torque r × F about the tip.
TEST(Contact, ProbeShaftContactsAndTorque) {
  auto run = [](ToolShape shape) {
    ScenarioSpec spec = test_scenarios::liver();
    ToolSpec& t = spec.tools.at(0).spec;
    t.timeout = 100;
    t.max_speed = 1e3;
    t.shape = shape;
    t.shaft_radius = 0.2;
    t.shaft_length = shape == ToolShape::Probe ? 2.0 : 0.0;
    auto m = compile_model(spec);
    State s = State::initial(*m);
    TickWorkspace w(*m);
    ToolInput in;
    in.pose.orientation = {std::sqrt(0.5), 0, std::sqrt(0.5), 0};  // +z of the tool → world +x
    for (int k = 0; k <= 800; ++k) {
      in.pose.position = {-2.6, 6.0 - 1.3 * k / 800.0, 0.5};  // lay it down onto the top
      tick(*m, s, w, &in, 1);
    }
    return w.report.tools[0];
  };
  const ToolOutput sphere = run(ToolShape::Sphere);
  const ToolOutput probe = run(ToolShape::Probe);
  EXPECT_GT(probe.contacts, sphere.contacts) << "the shaft touches too";
  ASSERT_GT(probe.force[1], 0.0);
  // Force on the shaft (x > tip) pushing up: torque about the tip along +z.
  EXPECT_GT(probe.torque[2], 0.0);
  // |τ_z| ≤ |F|·(L + r): the lever arm cannot exceed the tool's length.
  const double F = std::sqrt(probe.force[0] * probe.force[0] + probe.force[1] * probe.force[1] + probe.force[2] * probe.force[2]);
  EXPECT_LE(std::fabs(probe.torque[2]), F * (2.0 + 0.3));
}

// Virtual coupling: the device is pushed 1.5 units below the liver's surface; the proxy (the
// simulated tool) stays near the surface instead of sinking through, and at rest the device
// feels the coupling spring, which balances the tissue's push on the proxy.
TEST(Contact, VirtualCouplingProxyDoesNotSinkAndBalancesTheTissue) {
  ScenarioSpec spec = test_scenarios::liver();
  ToolSpec& t = spec.tools.at(0).spec;
  t.timeout = 100;
  t.max_speed = 1e3;
  t.coupling_stiffness = 200;
  t.max_force = 1e4;  // no clamp: compare the coupling spring itself with the tissue's force
  auto m = compile_model(spec);
  State s = State::initial(*m);
  TickWorkspace w(*m);
  ToolInput in;
  double first_contact_y = 0;
  for (int k = 0; k <= 3000; ++k) {
    in.pose.position = {-1.5, 6.0 - 2.5 * std::min(k, 1500) / 1500.0, 0.5};  // device to y = 3.5
    ASSERT_NE(tick(*m, s, w, &in, 1).status, TickStatus::NonFinite);
    if (first_contact_y == 0 && w.report.tools[0].contacts > 0) first_contact_y = s.tools[0].proxy[1];
  }
  const ToolState& ts = s.tools[0];
  ASSERT_GT(first_contact_y, 0.0);
  const double device_depth = first_contact_y - in.pose.position[1];
  const double proxy_depth = first_contact_y - ts.proxy[1];
  EXPECT_GT(device_depth, 1.5);
  EXPECT_LT(proxy_depth, 0.5 * device_depth) << "the proxy must not follow the device through the tissue";
  // Device force: the spring pulls the device up toward the proxy…
  const ToolFeedback& fb = w.report.tools[0].feedback;
  EXPECT_GT(fb.force[1], 0.0);
  // …and balances the tissue's force on the proxy at rest (quasi-static).
  for (int i = 0; i < 3; ++i)
    EXPECT_NEAR(fb.force[i], ts.force[i], 0.05 * std::fabs(ts.force[1]) + 1e-9) << "axis " << i;
}

// Blade (an edge along the tool's x) and grasper (two jaws from the hinge along the tool's z,
// opened by ±jaw/2): pressed into the liver they touch it and are pushed back; above it they
// touch nothing. An open grasper spans wider than a closed one.
TEST(Contact, BladeAndGrasperShapesTouchTheSurface) {
  auto press = [](ToolShape shape, double jaw, double y_end, double* x_extent) {
    ScenarioSpec spec = test_scenarios::liver();
    ToolSpec& t = spec.tools.at(0).spec;
    t.timeout = 100;
    t.max_speed = 1e3;
    t.shape = shape;
    t.radius = 0.1;
    t.shaft_length = 1.0;
    auto m = compile_model(spec);
    State s = State::initial(*m);
    TickWorkspace w(*m);
    ToolInput in;
    // Blade: edge along world x. Grasper: jaws pointing down (tool +z → world −y).
    in.pose.orientation = shape == ToolShape::Grasper ? std::array<double, 4>{std::sqrt(0.5), std::sqrt(0.5), 0, 0}
                                                      : std::array<double, 4>{1, 0, 0, 0};
    in.pose.jaw = jaw;
    const double y0 = shape == ToolShape::Grasper ? 7.0 : 6.0;
    for (int k = 0; k <= 600; ++k) {
      in.pose.position = {-1.5, y0 + (y_end - y0) * k / 600.0, 0.5};
      tick(*m, s, w, &in, 1);
    }
    // Spread in x of the contact springs' nodes (how wide the tool touches).
    double lo = 1e300, hi = -1e300;
    for (const ContactSpring& sp : w.springs)
      for (int a = 0; a < 3; ++a) {
        lo = std::min(lo, s.tissue.x[3 * sp.node[a]]);
        hi = std::max(hi, s.tissue.x[3 * sp.node[a]]);
      }
    if (x_extent) *x_extent = w.springs.empty() ? 0.0 : hi - lo;
    return w.report.tools[0];
  };
  double ext_open = 0, ext_closed = 0;
  const ToolOutput blade = press(ToolShape::Blade, 0, 4.9, nullptr);
  EXPECT_GT(blade.contacts, 0);
  EXPECT_GT(blade.force[1], 0.0);
  EXPECT_EQ(press(ToolShape::Blade, 0, 7.5, nullptr).contacts, 0) << "above the liver";
  const ToolOutput open = press(ToolShape::Grasper, 1.2, 5.4, &ext_open);
  const ToolOutput closed = press(ToolShape::Grasper, 0.0, 5.4, &ext_closed);
  EXPECT_GT(open.contacts, 0);
  EXPECT_GT(closed.contacts, 0);
  EXPECT_GT(open.force[1], 0.0);
  EXPECT_GT(ext_open, ext_closed) << "open jaws touch a wider region";
}

// Friction: dragging the probe along the surface, the tissue resists the motion with about
// μ times the normal force (slip); without friction the drag is much smaller.
TEST(Contact, CoulombFrictionResistsSliding) {
  STROMA_LONG_TEST();  // 22-27 s under ASan; the shorter cut and contact tests cover its code there
  auto drag = [](double mu, double* fx_mean, double* fy_mean) {
    ScenarioSpec spec = test_scenarios::liver();
    ToolSpec& t = spec.tools.at(0).spec;
    t.timeout = 100;
    t.max_speed = 1e3;
    t.friction = mu;
    auto m = compile_model(spec);
    State s = State::initial(*m);
    TickWorkspace w(*m);
    ToolInput in;
    for (int k = 0; k <= 1000; ++k) {
      in.pose.position = {-1.5, 6.0 - 0.95 * k / 1000.0, 0.5};
      tick(*m, s, w, &in, 1);
    }
    for (int k = 0; k < 300; ++k) tick(*m, s, w, &in, 1);
    double fx = 0, fy = 0;
    int n = 0;
    for (int k = 0; k <= 1000; ++k) {  // 1 unit along +x in 1 s
      in.pose.position = {-1.5 + 1.0 * k / 1000.0, 5.05, 0.5};
      tick(*m, s, w, &in, 1);
      if (k > 300) {  // steady sliding
        fx += s.tools[0].force[0];
        fy += s.tools[0].force[1];
        ++n;
      }
    }
    *fx_mean = fx / n;
    *fy_mean = fy / n;
  };
  double fx0, fy0, fx1, fy1;
  drag(0.0, &fx0, &fy0);
  drag(0.5, &fx1, &fy1);
  std::printf("friction: mu 0: fx %.3f fy %.3f; mu 0.5: fx %.3f fy %.3f\n", fx0, fy0, fx1, fy1);
  ASSERT_GT(fy0, 0.0);
  ASSERT_GT(fy1, 0.0);
  // The surface slopes, so even frictionless sliding has a tangential component: compare the
  // friction's share, fx(μ) − fx(0), with μ times the normal force.
  const double mu = 0.5, extra = fx1 - fx0;
  EXPECT_LT(extra, -0.3 * mu * std::min(fy0, fy1)) << "friction drags the tool back";
  EXPECT_GT(extra, -1.5 * mu * std::max(fy0, fy1)) << "by no more than about μ·|F_n|";
}

// The grasper holds what is between its jaws: jaws pointing down into the surface, closing
// grasps, lifting pulls the tissue up.
TEST(Contact, GrasperJawsGraspBetweenThemAndLift) {
  ScenarioSpec spec = test_scenarios::liver();
  ToolSpec& t = spec.tools.at(0).spec;
  t.timeout = 100;
  t.max_speed = 1e3;
  t.shape = ToolShape::Grasper;
  t.radius = 0.08;
  t.shaft_length = 0.6;
  t.can_grasp = true;
  auto m = compile_model(spec);
  State s = State::initial(*m);
  TickWorkspace w(*m);
  ToolInput in;
  in.pose.orientation = {std::sqrt(0.5), std::sqrt(0.5), 0, 0};  // jaws along world −y
  auto step = [&](double y, double jaw) {
    in.pose.position = {-1.5, y, 0.5};
    in.pose.jaw = jaw;
    ASSERT_NE(tick(*m, s, w, &in, 1).status, TickStatus::NonFinite);
  };
  for (int k = 0; k <= 800; ++k) step(6.5 - 1.0 * k / 800.0, 0.8);  // open jaws down into the tissue
  ASSERT_GT(w.report.tools[0].contacts, 0);
  step(5.5, 0.0);  // close
  const int held = s.tools[0].grasped;
  ASSERT_GT(held, 0);
  const ToolState g = s.tools[0];
  auto mean_y = [&] { return grasped_mean_height(*m, s, g); };
  const double y0 = mean_y();
  for (int k = 1; k <= 500; ++k) step(5.5 + 0.8 * k / 500.0, 0.0);
  for (int k = 0; k < 300; ++k) step(6.3, 0.0);
  EXPECT_GT(mean_y() - y0, 0.5 * 0.8) << "held tissue follows the lift";
}
