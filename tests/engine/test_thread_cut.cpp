// Threads across a cut (issue 43; engine/thread_cut.hpp, docs/THREAD.md "Threads and cutting"):
// a cut model keeps the threads whole after the cut tissue's DOFs and carries what ties them to
// the tissue to the copies holding the same material.
//
// The rig: the tests' 100 × 10 × 10 mm beam clamped at x = 0 (E 1 MPa, ρ 1000, gravity −y) and
// a 40 mm suture anchored inside the beam at x = 64.5 mm — in the layer of tetrahedra between 60
// and 65 mm that the blade, swept up through the plane x = 62.5 mm, splits — hanging down through
// the bottom face, with a puncture at its node 1 (also in that layer). Asserted, against what the
// cut must keep:
//  - at every swap, the state carried over is the state before it: the thread's nodes bit for
//    bit, the anchor's and the puncture's material points (their weights on the new copies'
//    DOFs) where they were, within round-off; the total mass is the tissue's and the thread's;
//  - the anchor and the puncture land in the piece cut off (the copies holding their material
//    are on the free side of the cut, not the stub's): the piece falls, and the thread with it —
//    its anchored end stays at the anchor's material point, its node 1 at the puncture's (1 mm);
//  - a tool holding the thread's free end throughout keeps it: its held segment renumbered with
//    the thread at every swap, the end where the tool holds it after the fall.

#include <gtest/gtest.h>

#include <cmath>
#include <numeric>

#include "engine/cut_swap.hpp"
#include "engine/model_check.hpp"
#include "engine/state.hpp"
#include "engine/thread_attach.hpp"
#include "engine/tick.hpp"
#include "scene/compiled_scenario.hpp"
#include "tests/cut_rig.hpp"
#include "tests/test_scenarios.hpp"

using namespace stroma;

namespace {

constexpr double kCutX = 0.0625;
constexpr double kThreadX = 0.0645;

ScenarioSpec beam_with_thread_and_scalpel() {
  ScenarioSpec s = test_scenarios::cantilever_dynamic();
  s.bodies[0].material.young_modulus = 1e6;
  s.bodies[0].material.poisson_ratio = 0.45;
  s.bodies[0].material.rayleigh_mass = 5;
  s.solver.preconditioner = Preconditioner::BlockJacobi;  // the rod's rows: its band's factor
  s.solver.tolerance = 1e-9;
  s.solver.max_iterations = 2000;
  s.tools.push_back(test_support::scalpel(0.03));
  ToolEntry h = test_support::grasping_tip("holder", 0.001, 1);  // holding the thread's free end
  h.spec.grasp_stiffness = 1e4;
  s.tools.push_back(h);
  ProbeSpec pr = s.probes[0];
  pr.name = "node1";
  pr.point = {kThreadX, 0.002, 0.005};
  s.probes.push_back(pr);
  ThreadSpec th = test_support::anchored_suture("beam", 0.04, 20, {kThreadX, 0.004, 0.005}, {0, -1, 0});
  th.rayleigh_mass = 5;
  s.threads.push_back(th);
  // A needle, fixed, away from the beam: a model with needles compiles where each cut copy's
  // material lies (its planes), which carrying a puncture across a cut decides by.
  RigidBodySpec needle;
  needle.name = "needle";
  needle.shape = RigidShapeKind::Needle;
  needle.wire_radius = 4e-4;
  needle.length = 0.02;
  needle.density = 7800;
  needle.position = {0.05, 0.05, 0.05};
  needle.fixed = true;
  s.rigid_bodies.push_back(needle);
  return s;
}

/// The blade at height y in the cut plane x = kCutX, mid-depth of the beam.
ToolPose blade_at(double y) { return test_support::blade_pose(kCutX, y, 0.005); }

Vec3 material_point(const double* x, const int32_t* node, const double* w) {
  Vec3 p{0, 0, 0};
  for (int a = 0; a < 4; ++a)
    for (int k = 0; k < 3; ++k) p[k] += w[a] * x[3 * node[a] + k];
  return p;
}

double distance(const Vec3& a, const double* b) { return std::hypot(a[0] - b[0], a[1] - b[1], a[2] - b[2]); }

/// A mask of the DOFs in the piece holding the beam's free end (tests/cut_rig.hpp).
std::vector<char> in_free_piece(const Model& m) {
  std::vector<char> out(size_t(m.fem.num_nodes), 0);
  for (int32_t d : test_support::free_piece(m)) out[size_t(d)] = 1;
  return out;
}

}  // namespace

TEST(ThreadCut, AThreadAnchoredAndPuncturedInThePieceCutOffFallsWithIt) {
  std::shared_ptr<const Model> m = compile_model(beam_with_thread_and_scalpel());
  auto w = std::make_unique<TickWorkspace>(*m);
  State s = State::initial(*m);
  ASSERT_EQ(m->fem.rod_anchors.size(), 1u);
  ASSERT_TRUE(m->has_needles);
  const RodRange r0 = m->fem.rods[0];
  // The puncture at node 1 (σ = 1), at that node's material point.
  ASSERT_EQ(m->puncture_capacity, 0) << "(no needle: the test places its puncture by hand)";
  auto mm = std::make_shared<Model>(*m);  // a model with room for one puncture
  mm->puncture_capacity = 1;
  m = mm;
  w = std::make_unique<TickWorkspace>(*m);
  s = State::initial(*m);
  {
    const BarycentricPoint& bp = m->probes[1].where;  // node 1's material point
    RodPuncture& p = s.punctures[0];
    for (int a = 0; a < 4; ++a) p.node[a] = bp.node[size_t(a)], p.w[a] = bp.w[size_t(a)];
    p.sigma = 1;
    p.stiffness = 1000;
    s.puncture_count = 1;
  }
  const double uncut_mass = std::accumulate(m->fem.mass.begin(), m->fem.mass.end(), 0.0);
  // The holder closes on the thread's free end (40 mm below the anchor) and keeps it there.
  const Vec3 end_at{kThreadX, 0.004 - 0.04, 0.005};
  auto holder = [&](uint64_t seq) {
    ToolInput in;
    in.tool = 1;
    in.seq = seq;
    in.pose.position = end_at;
    in.pose.jaw = 0.0;
    return in;
  };
  for (int i = 0; i < 50; ++i) {
    const ToolInput in = holder(uint64_t(i + 1));
    ASSERT_NE(tick(*m, s, *w, &in, 1).status, TickStatus::NonFinite);
  }
  ASSERT_EQ(s.tools[1].grasped_segment, m->fem.rods[0].node_end - 2) << "the holder has the thread's last segment";
  int swaps = 0;
  for (int k = 0; k <= 20; ++k) {  // the blade up through the beam at 2 m/s
    ToolInput in[2];
    in[0].seq = static_cast<uint64_t>(k + 1);
    in[0].pose = blade_at(-0.01 + 0.002 * k);
    in[1] = holder(uint64_t(51 + k));
    const TickReport& rep = tick(*m, s, *w, in, 2);
    ASSERT_NE(rep.status, TickStatus::NonFinite);
    if (rep.cut_edges == 0) continue;
    const std::vector<double> rod_x(s.tissue.x.begin() + 3 * m->fem.rods[0].node_begin,
                                    s.tissue.x.begin() + 3 * m->fem.rods[0].node_end);
    const RodAnchor a0 = m->fem.rod_anchors[0];
    const Vec3 anchor_before = material_point(s.tissue.x.data(), a0.tissue, a0.w);
    const RodPuncture p0 = s.punctures[0];
    const Vec3 puncture_before = material_point(s.tissue.x.data(), p0.node, p0.w);
    CutBuild b = build_cut(*m, s.edge_cut);
    std::shared_ptr<const Model> before = m;
    if (!apply_cut(b, m, w, s)) continue;
    ++swaps;
    ASSERT_FALSE(m->element_plane_begin.empty()) << "the cut model knows where its copies' material lies";
    std::string why;
    ASSERT_TRUE(model_invariants_hold(*m, &why)) << why;
    const RodRange& r = m->fem.rods[0];
    ASSERT_EQ(r.nodes(), r0.nodes());
    EXPECT_EQ(r.node_begin, m->fem.bodies[0].node_end) << "the thread after the cut tissue's DOFs";
    EXPECT_EQ(std::vector<double>(s.tissue.x.begin() + 3 * r.node_begin, s.tissue.x.begin() + 3 * r.node_end), rod_x)
        << "the thread's nodes carried bit for bit";
    const RodAnchor& a = m->fem.rod_anchors[0];
    EXPECT_EQ(a.node, r.node_begin);
    EXPECT_EQ(s.tools[1].grasped_segment, r.node_end - 2) << "the holder's segment renumbered with the thread";
    EXPECT_LT(distance(anchor_before, material_point(s.tissue.x.data(), a.tissue, a.w).data()), 1e-12);
    ASSERT_EQ(s.puncture_count, 1);
    EXPECT_LT(distance(puncture_before, material_point(s.tissue.x.data(), s.punctures[0].node, s.punctures[0].w).data()),
              1e-12);
    const double thread_mass = std::accumulate(m->fem.mass.begin() + r.node_begin, m->fem.mass.begin() + r.node_end, 0.0);
    EXPECT_NEAR(std::accumulate(m->fem.mass.begin(), m->fem.mass.end(), 0.0), uncut_mass, 1e-12 * uncut_mass);
    EXPECT_GT(thread_mass, 0.9 * 1100 * 3.14159 * 1e-8 * 0.04);
  }
  ASSERT_GE(swaps, 1);
  // Separated: the anchor and the puncture are held by the piece cut off.
  const std::vector<char> free_dof = in_free_piece(*m);
  const RodAnchor& a = m->fem.rod_anchors[0];
  for (int q = 0; q < 4; ++q) {
    if (a.w[q] > 1e-9) EXPECT_TRUE(free_dof[a.tissue[q]]) << "the anchor's corner " << q << " is the stub's";
    if (s.punctures[0].w[q] > 1e-9) EXPECT_TRUE(free_dof[s.punctures[0].node[q]]) << "the puncture's corner " << q;
  }
  const Vec3 anchor_start = material_point(s.tissue.x.data(), a.tissue, a.w);
  for (int i = 0; i < 80; ++i) {
    const ToolInput in = holder(uint64_t(100 + i));
    ASSERT_NE(tick(*m, s, *w, &in, 1).status, TickStatus::NonFinite) << i;
  }
  const double* x = s.tissue.x.data();
  const Vec3 anchor_end = material_point(x, a.tissue, a.w);
  EXPECT_LT(anchor_end[1], anchor_start[1] - 0.02) << "the piece fell (½·g·t² = 31 mm in 80 ms)";
  EXPECT_LT(distance(anchor_end, x + 3 * a.node), 2e-4) << "the thread's end went with it";
  ASSERT_EQ(s.puncture_count, 1);
  const RodPuncture& p = s.punctures[0];
  const RodPoint rp = rod_point(m->fem.rods[0], p.sigma);
  Vec3 T{0, 0, 0};
  for (int k = 0; k < 3; ++k) T[k] = (1 - rp.u) * x[3 * rp.j + k] + rp.u * x[3 * rp.j + 3 + k];
  // (within 1 mm: the holder keeps the thread's end where it was while the piece falls, and the
  // puncture's spring, 1000 N/m, gives under that pull; the stub's side is 20+ mm away)
  EXPECT_LT(distance(material_point(x, p.node, p.w), T.data()), 1e-3) << "and passes through the puncture";
  EXPECT_LT(material_point(x, p.node, p.w)[1], 0.002 - 0.02) << "which fell with the piece";
  const int32_t last = m->fem.rods[0].node_end - 1;
  EXPECT_LT(distance(end_at, x + 3 * last), 1e-3) << "and the holder still has the thread's end";
}
