// A prestretched body (docs/TISSUE.md, "Prestretch"): its mesh is the tissue as it is, its rest
// shape the mesh shrunk by 1/s per axis about its centroid. It starts as the mesh, under the
// stress of that stretch; let go it relaxes to the rest shape; held it keeps the tension.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>

#include "engine/cut_compile.hpp"
#include "engine/cut_swap.hpp"
#include "engine/model_check.hpp"
#include "engine/state.hpp"
#include "engine/tick.hpp"
#include "scene/compiled_scenario.hpp"
#include "scene/scenario_spec.hpp"
#include "tissue/cut_model.hpp"
#include "tests/input_error_message.hpp"
#include "tests/test_labels.hpp"

using namespace stroma;
using stroma::test_support::message_of;

namespace {

const std::string kSrc = STROMA_SOURCE_DIR;

/// The 50 mm cube (354 nodes) of 30 kPa tissue, no gravity, damped; `extra` adds to the body.
std::string cube_yaml(const std::string& prestretch, const std::string& extra = "") {
  return R"(name: prestretched_cube
time_step: 0.001
gravity: [0, 0, 0]
solver: {integrator: implicit_euler, preconditioner: block_jacobi, tolerance: 1.0e-10}
bodies:
  - name: block
    mesh: )" + kSrc + R"(/scenarios/meshes/cube_tet4_h8p333mm.msh
    prestretch: )" + prestretch + R"(
    material: {young_modulus: 3.0e4, poisson_ratio: 0.45, density: 1000, rayleigh_mass: 30}
)" + extra;
}

/// The extent of positions x (3 per node) along axis k.
double extent(const std::vector<double>& x, int k) {
  double lo = 1e300, hi = -1e300;
  for (size_t i = static_cast<size_t>(k); i < x.size(); i += 3) lo = std::min(lo, x[i]), hi = std::max(hi, x[i]);
  return hi - lo;
}

}  // namespace

// The state starts as the mesh (50 mm on every side) while the rest shape is the mesh shrunk
// about its centroid: 50/1.1 mm along x, 50/0.95 mm along z. Let go (nothing fixed), the body
// relaxes to its rest shape — a free body has no other equilibrium: every edge of every
// tetrahedron back to its rest length (a rigid motion aside) — and its centre of mass stays
// where it was (the stretch's forces sum to zero).
TEST(Prestretch, AFreeBodyStartsAsItsMeshAndRelaxesToItsRestShape) {
  STROMA_LONG_TEST();  // 22 s under the sanitizers (1.5 s of the block to 1e-10); they run the held bar
  std::shared_ptr<const Model> m = compile_model(parse_scenario(cube_yaml("[1.1, 1, 0.95]"), "cube.yaml", kSrc));
  std::string why;
  ASSERT_TRUE(model_invariants_hold(*m, &why)) << why;
  ASSERT_EQ(m->initial_x.size(), m->fem.rest.size());
  EXPECT_NEAR(extent(m->fem.rest, 0), 0.05 / 1.1, 1e-12);
  EXPECT_NEAR(extent(m->fem.rest, 1), 0.05, 1e-12);
  EXPECT_NEAR(extent(m->fem.rest, 2), 0.05 / 0.95, 1e-12);
  State s = State::initial(*m);
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(extent(s.tissue.x, k), 0.05, 1e-12) << "it starts as the mesh";
  auto centre_of_mass = [&](int k) {
    double c = 0, total = 0;
    for (int32_t n = 0; n < m->fem.num_nodes; ++n) c += m->fem.mass[size_t(n)] * s.tissue.x[size_t(3 * n + k)], total += m->fem.mass[size_t(n)];
    return c / total;
  };
  auto worst_edge = [&] {  // the largest relative change of an edge's length from its rest length
    double worst = 0;
    for (const ElementParams& e : m->fem.elements)
      for (int a = 0; a < 4; ++a)
        for (int b = a + 1; b < 4; ++b) {
          double l = 0, l0 = 0;
          for (int k = 0; k < 3; ++k) {
            const double d = s.tissue.x[size_t(3 * e.node[a] + k)] - s.tissue.x[size_t(3 * e.node[b] + k)];
            const double d0 = m->fem.rest[size_t(3 * e.node[a] + k)] - m->fem.rest[size_t(3 * e.node[b] + k)];
            l += d * d, l0 += d0 * d0;
          }
          worst = std::max(worst, std::abs(std::sqrt(l / l0) - 1));
        }
    return worst;
  };
  const double at_start = worst_edge();
  EXPECT_NEAR(at_start, 0.1, 1e-9) << "an edge along x starts 10 % longer than at rest";
  const double c0[3] = {centre_of_mass(0), centre_of_mass(1), centre_of_mass(2)};
  auto w = std::make_unique<TickWorkspace>(*m);
  for (int i = 0; i < 1500; ++i) ASSERT_TRUE(tick(*m, s, *w, nullptr, 0).status == TickStatus::Ok) << i;
  double speed = 0;
  for (const double v : s.tissue.v) speed = std::max(speed, std::abs(v));
  const double relaxed = worst_edge();
  std::printf("after 1.5 s: extents %.4f %.4f %.4f mm (rest %.4f %.4f %.4f); edges off their rest length by %.3g "
              "(at the start %.3g), speed %.3g m/s\n",
              1e3 * extent(s.tissue.x, 0), 1e3 * extent(s.tissue.x, 1), 1e3 * extent(s.tissue.x, 2),
              1e3 * extent(m->fem.rest, 0), 1e3 * extent(m->fem.rest, 1), 1e3 * extent(m->fem.rest, 2), relaxed,
              at_start, speed);
  EXPECT_LT(relaxed, 1e-6) << "relaxed to the rest shape";
  EXPECT_LT(speed, 1e-9);
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(centre_of_mass(k), c0[k], 1e-12) << "no net force";
}

// Held at both ends (the x = 0 and x = 50 mm faces fixed where the mesh has them), a body
// stretched 5 % along x keeps its length and its tension: the free faces neck in (ν 0.45), the
// ends do not move, and the stretch holds at the centre of the bar.
TEST(Prestretch, ABodyHeldAtBothEndsKeepsItsLength) {
  const std::string fixed = R"(    fixed:
      - box: {min: [-1, -1, -1], max: [1.0e-9, 1, 1]}
      - box: {min: [0.0499999, -1, -1], max: [1, 1, 1]}
)";
  std::shared_ptr<const Model> m = compile_model(parse_scenario(cube_yaml("[1.05, 1, 1]", fixed), "cube.yaml", kSrc));
  State s = State::initial(*m);
  const std::vector<double> x0 = s.tissue.x;
  auto w = std::make_unique<TickWorkspace>(*m);
  for (int i = 0; i < 600; ++i) ASSERT_TRUE(tick(*m, s, *w, nullptr, 0).status == TickStatus::Ok) << i;
  double end_moved = 0;
  for (int32_t n = 0; n < m->fem.num_nodes; ++n)
    if (m->fem.constrained[size_t(n)] == 7)
      for (int k = 0; k < 3; ++k) end_moved = std::max(end_moved, std::abs(s.tissue.x[size_t(3 * n + k)] - x0[size_t(3 * n + k)]));
  EXPECT_EQ(end_moved, 0.0) << "the ends stay where the mesh has them";
  EXPECT_NEAR(extent(s.tissue.x, 0), 0.05, 1e-12);
  // The free faces neck in under the tension: the body is narrower at x = 25 mm than its ends.
  double lo = 1e300, hi = -1e300;
  for (int32_t n = 0; n < m->fem.num_nodes; ++n)
    if (std::abs(x0[size_t(3 * n)] - 0.025) < 1e-6) lo = std::min(lo, s.tissue.x[size_t(3 * n + 1)]), hi = std::max(hi, s.tissue.x[size_t(3 * n + 1)]);
  std::printf("width at mid-length %.4f mm (50 at the ends)\n", 1e3 * (hi - lo));
  EXPECT_LT(hi - lo, 0.05 * (1 - 0.3 * 0.45 * 0.05)) << "necked by the tension (Poisson)";
}

// A wound gapes where the tissue is under tension: the bar held at both ends, stretched 5 % along
// x, cut through across x = 25 mm (every edge crossing the plane; the cut model swapped in as
// every front end does). Each half is then held at one end only and relaxes to its rest shape
// there: a material point at x (the mesh) ends at x / s from the x = 0 end, or L − (L − x) / s
// from the other, whatever the cut surface's shape — the lips part by L (1 − 1/s) = 2.38 mm.
// (Exactly: every material DOF is there to round-off.)
TEST(Prestretch, ACutAcrossABodyUnderTensionGapesByItsRetraction) {
  STROMA_LONG_TEST();  // 24 s under the sanitizers; they run the cut swap in the cut and needle tests
  const std::string fixed_and_scalpel = R"(    fixed:
      - box: {min: [-1, -1, -1], max: [1.0e-9, 1, 1]}
      - box: {min: [0.0499999, -1, -1], max: [1, 1, 1]}
tools:
  - name: scalpel
    shape: {type: blade, radius: 0.0005, length: 0.03}
    pose: {position: [0.5, 0.5, 0.5]}
    cut: {toughness: 200}
)";
  std::shared_ptr<const Model> m =
      compile_model(parse_scenario(cube_yaml("[1.05, 1, 1]", fixed_and_scalpel), "cube.yaml", kSrc));
  auto w = std::make_unique<TickWorkspace>(*m);
  State s = State::initial(*m);
  const double L = 0.05, sx = 1.05, at = 0.026;  // (between the mesh's node layers)
  for (int i = 0; i < 200; ++i) ASSERT_TRUE(tick(*m, s, *w, nullptr, 0).status == TickStatus::Ok);
  // Through the whole bar: every edge crossing x = at in the mesh (the state's start), its cut
  // point where it crosses.
  const CutBase& base = m->cutting->base;
  const std::vector<double> X = m->initial_x;  // the mesh, per node
  s.edge_cut.assign(base.adj.edges.size(), kEdgeUncut);
  for (size_t e = 0; e < base.adj.edges.size(); ++e) {
    const double xa = X[size_t(3 * base.adj.edges[e][0])], xb = X[size_t(3 * base.adj.edges[e][1])];
    if ((xa - at) * (xb - at) >= 0) continue;
    s.edge_cut[e] = std::clamp((at - xa) / (xb - xa), base.min_fraction[e], 1 - base.min_fraction[e]);
  }
  CutBuild b = build_cut(*m, s.edge_cut);
  ASSERT_TRUE(apply_cut(b, m, w, s));
  ASSERT_GT(m->cut_stats.faces_created, 20);
  for (int i = 0; i < 1500; ++i) ASSERT_TRUE(tick(*m, s, *w, nullptr, 0).status == TickStatus::Ok) << i;
  const CutTopology& topo = *m->topology;
  double worst = 0, near_lip = -1e300, far_lip = 1e300;
  int checked = 0;
  for (int32_t d = 0; d < topo.num_dofs; ++d) {
    if (!topo.dof_material[size_t(d)]) continue;  // a virtual node: no material there
    const int32_t n = topo.dof_node[size_t(d)];
    const double x_mesh = X[size_t(3 * n)];
    // Which half holds it: the DOF's side of the plane (a node on the plane's either side).
    const double want = x_mesh < at ? x_mesh / sx : L - (L - x_mesh) / sx;
    worst = std::max(worst, std::abs(s.tissue.x[size_t(3 * d)] - want));
    for (int k = 1; k < 3; ++k) worst = std::max(worst, std::abs(s.tissue.x[size_t(3 * d + k)] - X[size_t(3 * n + k)]));
    if (x_mesh < at) near_lip = std::max(near_lip, s.tissue.x[size_t(3 * d)]);
    else far_lip = std::min(far_lip, s.tissue.x[size_t(3 * d)]);
    ++checked;
  }
  const double gap_nodes = (far_lip - near_lip), gap_nodes_mesh = [&] {
    double lo = -1e300, hi = 1e300;
    for (int32_t n = 0; n < m->cutting->uncut.num_nodes; ++n) {
      const double x = X[size_t(3 * n)];
      if (x < at) lo = std::max(lo, x); else hi = std::min(hi, x);
    }
    return hi - lo;
  }();
  std::printf("%d material DOFs within %.3g m of each half's rest shape; the node layers beside the cut %.3f mm apart "
              "(%.3f in the mesh): opened by %.3f mm; the lips by L (1 - 1/s) = %.3f mm\n",
              checked, worst, 1e3 * gap_nodes, 1e3 * gap_nodes_mesh, 1e3 * (gap_nodes - gap_nodes_mesh), 1e3 * L * (1 - 1 / sx));
  EXPECT_GT(checked, 300);
  EXPECT_LT(worst, 1e-6) << "each half at its rest shape, held at its end";
  // The node layers on either side of the cut part by the retraction of the tissue outside them,
  // (L − their distance) (1 − 1/s); the lips themselves by L (1 − 1/s).
  EXPECT_NEAR(gap_nodes - gap_nodes_mesh, (L - gap_nodes_mesh) * (1 - 1 / sx), 1e-9) << "the wound gapes by the retraction";
}

// Errors name the file, line and field.
TEST(Prestretch, AStretchOutOfRangeIsRefusedWithItsLine) {
  const std::string msg = message_of([] { parse_scenario(cube_yaml("[1.1, 0, 1]"), "cube.yaml", kSrc); });
  EXPECT_NE(msg.find("cube.yaml:8: bodies[0].prestretch"), std::string::npos) << msg;
  EXPECT_NE(msg.find("prestretch y = 0 is out of range"), std::string::npos) << msg;
  const std::string msg2 = message_of([] { parse_scenario(cube_yaml("3"), "cube.yaml", kSrc); });
  EXPECT_NE(msg2.find("prestretch x = 3 is out of range"), std::string::npos) << msg2;
  const std::string msg3 = message_of([] { parse_scenario(cube_yaml("[1.1, 1]"), "cube.yaml", kSrc); });
  EXPECT_NE(msg3.find("bodies[0].prestretch"), std::string::npos) << msg3;
}
