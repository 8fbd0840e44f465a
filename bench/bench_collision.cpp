/// \file bench_collision.cpp
/// The collide stage's broad phase, hand-written vs FCL, per tick: refit the surface BVH to the
/// deformed positions and find the surface triangles near a probe sphere. Meshes from small
/// (liver) to large (raptor 19k tets). FCL: BVHModel<AABB> over the surface (compact vertex
/// array), beginUpdateModel / updateVertex / endUpdateModel (bottom-up refit), then collide()
/// against an fcl::Sphere asking for all contacts. Ours: TriangleBvh::refit on the engine's
/// position array in place, then query_sphere.
/// Run: build/bench/stroma_bench_collision --benchmark_repetitions=5 --benchmark_report_aggregates_only=true

#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <random>
#include <string>

#include <fcl/fcl.h>

#include "collision/triangle_bvh.hpp"
#include "engine/model.hpp"
#include "scene/compiled_scenario.hpp"

using namespace stroma;

namespace {

const char* kMeshes[] = {"liver.msh", "Armadillo_Tetra_4406.vtu", "raptorTetra_8418.vtu", "raptorTetra_19409.vtu"};

struct Scene {
  std::shared_ptr<const Model> m;
  std::vector<double> x;  ///< deformed positions
  double c[3];            ///< probe centre (on the surface)
  double r;               ///< probe radius
};

Scene make_scene(int i) {
  ScenarioSpec s = load_scenario(std::string(STROMA_SOURCE_DIR) + "/scenarios/liver.yaml");
  s.bodies[0].mesh_path = std::string(STROMA_SOURCE_DIR) + "/scenarios/meshes/" + kMeshes[i];
  s.bodies[0].fixed.clear();
  s.probes.clear();
  Scene sc;
  sc.m = compile_model(s);
  const Model& m = *sc.m;
  sc.x = m.fem.rest;
  std::mt19937 g(1);
  std::uniform_real_distribution<double> u(-1, 1);
  double lo[3] = {1e300, 1e300, 1e300}, hi[3] = {-1e300, -1e300, -1e300};
  for (int32_t n = 0; n < m.fem.num_nodes; ++n)
    for (int k = 0; k < 3; ++k) {
      lo[k] = std::min(lo[k], m.fem.rest[3 * n + k]);
      hi[k] = std::max(hi[k], m.fem.rest[3 * n + k]);
    }
  const double diag = std::sqrt((hi[0] - lo[0]) * (hi[0] - lo[0]) + (hi[1] - lo[1]) * (hi[1] - lo[1]) + (hi[2] - lo[2]) * (hi[2] - lo[2]));
  for (double& v : sc.x) v += 0.002 * diag * u(g);  // a deformed state
  const int32_t n0 = m.collision_triangles[m.collision_triangles.size() / 3][0];
  for (int k = 0; k < 3; ++k) sc.c[k] = sc.x[3 * n0 + k];
  sc.r = 0.05 * diag;
  return sc;
}

void BM_Ours(benchmark::State& st) {
  Scene sc = make_scene(static_cast<int>(st.range(0)));
  TriangleBvh bvh;
  bvh.build(sc.m->collision_triangles, sc.m->fem.rest.data());
  int64_t found = 0;
  for (auto _ : st) {
    bvh.refit(sc.x.data());
    found = 0;
    bvh.query_sphere(sc.c, sc.r, sc.x.data(), [&](int32_t) { ++found; });
    benchmark::DoNotOptimize(found);
  }
  st.SetLabel(kMeshes[st.range(0)]);
  st.counters["triangles"] = static_cast<double>(sc.m->collision_triangles.size());
  st.counters["candidates"] = static_cast<double>(found);
}
BENCHMARK(BM_Ours)->DenseRange(0, 3)->Unit(benchmark::kMicrosecond);

void BM_Fcl(benchmark::State& st) {
  Scene sc = make_scene(static_cast<int>(st.range(0)));
  const Model& m = *sc.m;
  // Compact surface vertex array for FCL.
  std::vector<int32_t> local(m.fem.num_nodes, -1), surf;
  std::vector<fcl::Triangle> tris;
  for (const auto& t : m.collision_triangles) {
    int v[3];
    for (int a = 0; a < 3; ++a) {
      if (local[t[a]] < 0) {
        local[t[a]] = static_cast<int32_t>(surf.size());
        surf.push_back(t[a]);
      }
      v[a] = local[t[a]];
    }
    tris.emplace_back(v[0], v[1], v[2]);
  }
  std::vector<fcl::Vector3d> pts(surf.size());
  for (size_t i = 0; i < surf.size(); ++i) pts[i] = fcl::Vector3d(m.fem.rest[3 * surf[i]], m.fem.rest[3 * surf[i] + 1], m.fem.rest[3 * surf[i] + 2]);
  auto model = std::make_shared<fcl::BVHModel<fcl::AABBd>>();
  model->beginModel();
  model->addSubModel(pts, tris);
  model->endModel();
  fcl::CollisionObjectd body(model);
  auto sphere = std::make_shared<fcl::Sphered>(sc.r);
  fcl::CollisionObjectd probe(sphere, fcl::Transform3d(Eigen::Translation3d(sc.c[0], sc.c[1], sc.c[2])));
  fcl::CollisionRequestd req(100000, false);  // all contacts, no contact geometry
  int64_t found = 0;
  for (auto _ : st) {
    model->beginUpdateModel();
    for (size_t i = 0; i < surf.size(); ++i)
      model->updateVertex(fcl::Vector3d(sc.x[3 * surf[i]], sc.x[3 * surf[i] + 1], sc.x[3 * surf[i] + 2]));
    model->endUpdateModel(true, true);
    body.computeAABB();
    fcl::CollisionResultd res;
    fcl::collide(&probe, &body, req, res);
    found = static_cast<int64_t>(res.numContacts());
    benchmark::DoNotOptimize(found);
  }
  st.SetLabel(kMeshes[st.range(0)]);
  st.counters["triangles"] = static_cast<double>(tris.size());
  st.counters["contacts"] = static_cast<double>(found);
}
BENCHMARK(BM_Fcl)->DenseRange(0, 3)->Unit(benchmark::kMicrosecond);

}  // namespace

BENCHMARK_MAIN();
