// What renderers are told of a cut tissue (server/state_publisher): the published surfaces
// follow each new topology — re-made for the frame's cut model, the wound's faces flagged and
// on vertices of their own, the visual mesh re-mapped into the copies that hold it — and go
// back to the scenario's surfaces after a Reset. No DDS here: the extractor is fed frames as
// the physics loop writes them.
//
// Asserted, and against what:
//  - beam cut through at x = 62.5 mm (between element layers): the wound's faces lie on that
//    plane at rest, their area is both lips' (2 × the model's cut area, to 1e-9), and once the
//    free piece has fallen half the wound's vertices moved with it and half stayed with the
//    clamped stub, as did the skin on each side;
//  - SOFA's liver with its 2,194-vertex visual surface, cut through by a plane: every visual
//    triangle that spans the plane is dropped (no skin stretched across the wound), nearly all
//    others are kept, and the visual vertices follow their own side;
//  - a frame of the uncut model brings the uncut surfaces back; a frame of a model no longer
//    registered is skipped, not guessed.

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <set>

#include "engine/cut_compile.hpp"
#include "engine/cut_registry.hpp"
#include "engine/cut_swap.hpp"
#include "engine/tick.hpp"
#include "runtime/physics_loop.hpp"
#include "scene/compiled_scenario.hpp"
#include "server/state_publisher.hpp"
#include "tests/cut_rig.hpp"

using namespace stroma;
using stroma::test_support::scalpel;

namespace {

/// Ticks as `stroma run` makes them: a cut model built and swapped in after a tick that cut.
struct CutSession {
  CompiledScenario sc;
  std::shared_ptr<const Model> m;
  std::unique_ptr<TickWorkspace> w;
  State s;
  explicit CutSession(const ScenarioSpec& spec)
      : sc(compile_scenario(spec)), m(sc.model), w(std::make_unique<TickWorkspace>(*m)), s(State::initial(*m)) {}
  void step(const ToolInput* in = nullptr, int n = 0) {
    const TickReport& r = tick(*m, s, *w, in, n);
    ASSERT_NE(r.status, TickStatus::NonFinite);
    if (r.cut_edges > 0) {
      CutBuild b = build_cut(*m, s.edge_cut);
      apply_cut(b, m, w, s);
    }
  }
  StateFrame frame() const {
    StateFrame f;
    f.x = s.tissue.x;
    f.dofs = static_cast<size_t>(m->fem.num_nodes);
    f.cut_serial = m->cut_serial;
    f.topology_version = m->topology_version;
    return f;
  }
};

/// The blade with its edge along world z and its normal along world x, at (x, y, z): swept up
/// (+y) it cuts the plane at x.
ToolInput blade(uint64_t seq, double x, double y, double z) {
  ToolInput in;
  in.seq = seq;
  in.pose = test_support::blade_pose(x, y, z);
  return in;
}

double tri_area(const float* a, const float* b, const float* c) {
  const double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, v[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
  const double n[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
  return 0.5 * std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
}

}  // namespace

TEST(StatePublisher, SurfacesFollowACutBeamAndComeBackAfterAReset) {
  constexpr double kCutX = 0.0625;
  ScenarioSpec spec = load_scenario(std::string(STROMA_SOURCE_DIR) + "/scenarios/cantilever_dynamic.yaml");
  spec.bodies[0].material.young_modulus = 1e8;  // stiff and a thin blade: cut, not lifted
  spec.bodies[0].material.poisson_ratio = 0.45;
  spec.solver.preconditioner = Preconditioner::Jacobi;
  spec.solver.tolerance = 1e-9;
  spec.solver.max_iterations = 2000;
  spec.tools.push_back(scalpel(0.03));
  spec.tools[0].spec.radius = 2e-5;
  CutSession run(spec);
  CutModelRegistry registry;
  SurfaceExtractor ex(run.sc, &registry);
  ASSERT_TRUE(ex.update(run.frame()));
  EXPECT_FALSE(ex.topology_changed());
  const size_t uncut_triangles = ex.surfaces()[0].triangles.size();
  EXPECT_TRUE(ex.surfaces()[0].cut_faces.empty());

  for (int k = 0; k <= 20; ++k) {
    const ToolInput in = blade(static_cast<uint64_t>(k + 1), kCutX, -0.01 + 0.002 * k, 0.005);
    run.step(&in, 1);
  }
  ASSERT_GT(run.m->topology_version, 0) << "the blade cut nothing";
  registry.add(run.m);
  ASSERT_TRUE(ex.update(run.frame()));
  ASSERT_TRUE(ex.topology_changed());
  const PublishedSurface& s = ex.surfaces()[0];
  EXPECT_EQ(s.topology_version, static_cast<uint32_t>(run.m->topology_version));
  ASSERT_EQ(s.cut_faces.size(), s.triangles.size() / 3);
  // The wound: on the blade's plane at rest, both lips' area, on vertices of its own.
  double wound_area = 0;
  std::vector<uint8_t> wound_vertex(s.rest.size() / 3, 0), skin_vertex(s.rest.size() / 3, 0);
  for (size_t t = 0; t < s.cut_faces.size(); ++t) {
    const uint32_t* v = &s.triangles[3 * t];
    for (int k = 0; k < 3; ++k) (s.cut_faces[t] ? wound_vertex : skin_vertex)[v[k]] = 1;
    if (!s.cut_faces[t]) continue;
    // (the mesh has nodes on the plane: cut points keep 5 % of an edge, ≤ 0.45 mm, from a node)
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(s.rest[3 * v[k]], kCutX, 4.5e-4);
    wound_area += tri_area(&s.rest[3 * v[0]], &s.rest[3 * v[1]], &s.rest[3 * v[2]]);
  }
  EXPECT_NEAR(wound_area, 2 * run.m->cut_stats.cut_area, 1e-5 * wound_area);
  EXPECT_NEAR(wound_area, 2 * 0.01 * 0.01, 1e-5) << "two lips of the 10 × 10 mm section";
  for (size_t v = 0; v < wound_vertex.size(); ++v) EXPECT_FALSE(wound_vertex[v] && skin_vertex[v]) << v;
  EXPECT_GT(s.triangles.size(), uncut_triangles);

  // The free piece falls: half the wound and the skin beyond the cut go with it.
  const std::vector<float> rest = s.rest;
  for (int k = 0; k < 100; ++k) {
    const ToolInput in = blade(static_cast<uint64_t>(100 + k), kCutX, 0.05, 0.005);  // out of the way
    run.step(&in, 1);
  }
  ASSERT_TRUE(ex.update(run.frame()));
  const double drop = 0.5 * 9.81 * 0.1 * 0.1;  // ≈ 49 mm after 0.1 s of free fall
  int wound_fell = 0, wound_stayed = 0;
  for (size_t v = 0; v < wound_vertex.size(); ++v) {
    const double dy = s.positions[3 * v + 1] - rest[3 * v + 1];
    const bool fell = dy < -0.5 * drop, stayed = std::abs(dy) < 0.1 * drop;
    EXPECT_TRUE(fell || stayed) << "vertex " << v << " moved " << dy;
    if (wound_vertex[v]) {
      (fell ? wound_fell : wound_stayed) += 1;
    } else if (rest[3 * v] > kCutX + 5e-4) {
      EXPECT_TRUE(fell) << "skin of the free piece, vertex " << v;
    } else if (rest[3 * v] < kCutX - 5e-4) {
      EXPECT_TRUE(stayed) << "skin of the stub, vertex " << v;
    }
  }
  EXPECT_GT(wound_fell, 0);
  EXPECT_EQ(wound_fell, wound_stayed) << "each lip has its own vertices";

  // A frame of a model no longer registered is skipped; the uncut model's brings its surfaces back.
  StateFrame gone = run.frame();
  gone.cut_serial += 1000;
  EXPECT_FALSE(ex.update(gone));
  EXPECT_EQ(ex.skipped_frames(), 1u);
  StateFrame uncut;
  uncut.x = run.sc.model->fem.rest;
  uncut.dofs = static_cast<size_t>(run.sc.model->fem.num_nodes);
  ASSERT_TRUE(ex.update(uncut));
  EXPECT_TRUE(ex.topology_changed());
  EXPECT_EQ(ex.surfaces()[0].topology_version, 0u);
  EXPECT_TRUE(ex.surfaces()[0].cut_faces.empty());
  EXPECT_EQ(ex.surfaces()[0].triangles.size(), uncut_triangles);
}

TEST(StatePublisher, AVisualSurfaceIsRemappedAcrossTheCut) {
  ScenarioSpec spec = load_scenario(std::string(STROMA_SOURCE_DIR) + "/scenarios/liver.yaml");
  spec.tools.clear();
  spec.gravity = {0, 0, 0};
  CutSession probe_bounds(spec);
  const std::vector<double>& X = probe_bounds.m->fem.rest;
  double lo[3] = {1e30, 1e30, 1e30}, hi[3] = {-1e30, -1e30, -1e30};
  for (size_t i = 0; i < X.size(); ++i) {
    lo[i % 3] = std::min(lo[i % 3], X[i]);
    hi[i % 3] = std::max(hi[i % 3], X[i]);
  }
  // A plane through the middle of the liver, off its nodes.
  const double cut_x = 0.5 * (lo[0] + hi[0]) + 0.0123;
  spec.tools.push_back(scalpel(2.0 * (hi[2] - lo[2])));
  CutSession run(spec);
  CutModelRegistry registry;
  SurfaceExtractor ex(run.sc, &registry);
  const int sweeps = 40;
  for (int k = 0; k <= sweeps; ++k) {
    const double y = lo[1] - 0.5 + (hi[1] - lo[1] + 1.0) * k / sweeps;
    const ToolInput in = blade(static_cast<uint64_t>(k + 1), cut_x, y, 0.5 * (lo[2] + hi[2]));
    run.step(&in, 1);
  }
  ASSERT_GT(run.m->topology_version, 0);
  registry.add(run.m);
  ASSERT_TRUE(ex.update(run.frame()));
  ASSERT_TRUE(ex.topology_changed());
  const PublishedSurface& s = ex.surfaces()[0];
  ASSERT_TRUE(s.visual);
  const VisualModel& vis = *run.sc.visuals[0];
  const size_t nv = vis.rest.size();
  // The cut surface is within 5 % of an edge of the blade's plane (cut points keep that far from
  // nodes; the liver's edges are ≤ ~1 unit) and was cut on the deformed liver: a vertex is on a
  // side when it is more than kMargin from the plane.
  constexpr double kMargin = 0.06;
  // The skin: the visual triangles kept, then the wound's.
  size_t kept = 0, spanning = 0, spanning_kept = 0, far_dropped = 0;
  for (size_t t = 0; t < s.cut_faces.size(); ++t)
    if (!s.cut_faces[t]) ++kept;
  std::set<std::array<uint32_t, 3>> kept_set;
  for (size_t t = 0; t < kept; ++t) kept_set.insert({s.triangles[3 * t], s.triangles[3 * t + 1], s.triangles[3 * t + 2]});
  for (size_t i = 0; i < vis.triangles.size(); i += 3) {
    const uint32_t* v = &vis.triangles[i];
    int left = 0, right = 0;
    for (int k = 0; k < 3; ++k) {
      left += vis.rest[v[k]][0] < cut_x - kMargin;
      right += vis.rest[v[k]][0] > cut_x + kMargin;
    }
    const bool spans = left > 0 && right > 0;
    spanning += spans;
    far_dropped += (left == 3 || right == 3) && !kept_set.count({v[0], v[1], v[2]});
    spanning_kept += spans && kept_set.count({v[0], v[1], v[2]});
  }
  EXPECT_GT(spanning, 10u);
  EXPECT_EQ(spanning_kept, 0u) << "skin stretched across the wound";
  EXPECT_EQ(far_dropped, 0u) << "skin away from the cut dropped";
  EXPECT_LT(kept, vis.triangles.size() / 3);
  EXPECT_GT(s.cut_faces.size() - kept, 0u);
  // The visual vertices where the uncut mapping has them (vertices outside the tetrahedra are
  // at their projections).
  std::vector<double> mapped(3 * nv);
  vis.mapping.apply(run.sc.model->fem.rest.data(), mapped.data());
  for (size_t v = 0; v < nv; ++v)
    for (int k = 0; k < 3; ++k) ASSERT_NEAR(s.rest[3 * v + k], mapped[3 * v + k], 1e-5) << "visual vertex " << v;
  // Pull the two sides apart: each visual vertex follows the side it is on.
  StateFrame f = run.frame();
  for (int32_t d = 0; d < run.m->fem.num_nodes; ++d) {
    // A DOF's side: where its copies' material is — the mean rest x of the copies using it.
    double acc = 0;
    int n = 0;
    for (int32_t j = run.m->fem.node_element_ptr[d]; j < run.m->fem.node_element_ptr[d + 1]; ++j) {
      const ElementCopy& c = run.m->topology->copies[run.m->fem.node_element[j]];
      for (int k = 0; k < 4; ++k)
        if (c.material >> k & 1) {
          acc += run.m->cutting->uncut.rest[3 * run.m->cutting->base.tets[c.tet][k]];
          ++n;
        }
    }
    f.x[3 * d + 1] += n && acc / n < cut_x ? -1.0 : 1.0;
  }
  ASSERT_TRUE(ex.update(f));
  int wrong = 0;
  for (size_t v = 0; v < nv; ++v) {
    if (std::abs(vis.rest[v][0] - cut_x) < kMargin) continue;
    const double dy = s.positions[3 * v + 1] - mapped[3 * v + 1];
    wrong += std::abs(dy - (vis.rest[v][0] < cut_x ? -1.0 : 1.0)) > 1e-3;
  }
  EXPECT_EQ(wrong, 0) << "visual vertices that did not follow their side";
}

// A thread in a scenario that is cut (engine/thread_cut.hpp): the publisher is given the
// scenario's model and frames of the cut one, whose tissue has more DOFs — the thread's
// positions it publishes are its nodes in the frame (the last DOFs of every model of the
// scenario), not the tissue's DOFs that now sit where the uncut model had the thread.
TEST(StatePublisher, AThreadsNodesArePublishedFromAFrameOfACutModel) {
  constexpr double kCutX = 0.0625;
  ScenarioSpec spec = load_scenario(std::string(STROMA_SOURCE_DIR) + "/scenarios/cantilever_dynamic.yaml");
  spec.bodies[0].material.young_modulus = 1e8;
  spec.bodies[0].material.poisson_ratio = 0.45;
  spec.solver.preconditioner = Preconditioner::BlockJacobi;
  spec.solver.tolerance = 1e-9;
  spec.solver.max_iterations = 2000;
  spec.tools.push_back(scalpel(0.03));
  spec.tools[0].spec.radius = 2e-5;
  spec.threads.push_back(test_support::anchored_suture("beam", 0.02, 10, {0.09, 0.0, 0.005}, {0, -1, 0}));
  CutSession run(spec);
  for (int k = 0; k <= 20; ++k) {
    const ToolInput in = blade(static_cast<uint64_t>(k + 1), kCutX, -0.01 + 0.002 * k, 0.005);
    run.step(&in, 1);
  }
  ASSERT_GT(run.m->topology_version, 0) << "the blade cut nothing";
  ASSERT_GT(run.m->fem.num_nodes, run.sc.model->fem.num_nodes);
  StateFrame f = run.frame();
  std::vector<float> positions, punctures;
  const stroma_ThreadState msg = thread_state_message(*run.sc.model, 0, f, 1, positions, punctures);
  const RodRange& r = run.m->fem.rods[0];
  ASSERT_EQ(msg.positions._length, static_cast<uint32_t>(3 * r.nodes()));
  for (int32_t i = 0; i < r.nodes(); ++i)
    for (int k = 0; k < 3; ++k)
      EXPECT_EQ(msg.positions._buffer[3 * i + k], static_cast<float>(run.s.tissue.x[3 * size_t(r.node_begin + i) + k]))
          << "node " << i;
  EXPECT_NEAR(msg.length, 0.02, 2e-4);
}
