// Tests for tissue/visual_mapping: the barycentric mapping of a visual surface onto tetrahedra
// (agreement with the brute-force locator, exact reproduction of affine motions, Jᵀ as the true
// adjoint, known projections outside the mesh).
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <functional>
#include <map>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "tests/test_meshes.hpp"
#include "tissue/barycentric.hpp"
#include "tissue/input_error.hpp"
#include "io/mesh_io.hpp"
#include "tissue/mesh_prepare.hpp"
#include "io/surface_io.hpp"
#include "tissue/visual_mapping.hpp"

namespace stroma {
namespace {

std::string real_mesh(const std::string& name) {
  return std::string(STROMA_SOURCE_DIR) + "/scenarios/meshes/" + name;
}

// ---------------------------------------------------------------------------------------------
// VisualMapping
// ---------------------------------------------------------------------------------------------

/// The liver as the engine compiles it (load_tet_mesh + prepare_mesh keep the file's node and
/// tet numbering) and its visual surface.
struct Liver {
  PreparedMesh mesh;
  SurfaceMesh surface;
  VisualMapping map;
  double diag = 0;  // bounding-box diagonal of the tet mesh
};

const Liver& liver() {
  static const Liver l = [] {
    Liver l;
    l.mesh = prepare_mesh(load_tet_mesh(real_mesh("liver.msh")));
    l.surface = read_surface_mesh(real_mesh("liver-smooth.obj"));
    Vec3 lo = l.mesh.mesh.nodes[0], hi = lo;
    for (const Vec3& p : l.mesh.mesh.nodes)
      for (int a = 0; a < 3; ++a) {
        lo[a] = std::min(lo[a], p[a]);
        hi[a] = std::max(hi[a], p[a]);
      }
    l.diag = std::hypot(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]);
    const auto t0 = std::chrono::steady_clock::now();
    l.map = build_visual_mapping(l.mesh.mesh, l.surface.vertices, 0.1 * l.diag);
    const double ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    std::printf("[ liver    ] mapping %zu vertices into %zu tets: %.2f ms; %d outside, max "
                "distance %.4g (%.2f%% of the %.4g diagonal)\n",
                l.surface.vertices.size(), l.mesh.mesh.tets.size(), ms, l.map.outside,
                l.map.max_distance, 100 * l.map.max_distance / l.diag, l.diag);
    return l;
  }();
  return l;
}

std::vector<double> flatten(const std::vector<Vec3>& pts) {
  std::vector<double> x;
  for (const Vec3& p : pts) x.insert(x.end(), p.begin(), p.end());
  return x;
}

/// Rotation by `deg` degrees about `axis` (Rodrigues), row-major.
std::array<double, 9> rotation(Vec3 axis, double deg) {
  const double n = std::hypot(axis[0], axis[1], axis[2]);
  for (double& c : axis) c /= n;
  const double t = deg * M_PI / 180, c = std::cos(t), s = std::sin(t), C = 1 - c;
  const double x = axis[0], y = axis[1], z = axis[2];
  return {c + x * x * C,     x * y * C - z * s, x * z * C + y * s,
          y * x * C + z * s, c + y * y * C,     y * z * C - x * s,
          z * x * C - y * s, z * y * C + x * s, c + z * z * C};
}

/// x' = A x + b on every point of a flat xyz array.
std::vector<double> affine(const std::array<double, 9>& A, const Vec3& b,
                           const std::vector<double>& x) {
  std::vector<double> y(x.size());
  for (size_t i = 0; i < x.size(); i += 3)
    for (int r = 0; r < 3; ++r)
      y[i + r] = A[3 * r] * x[i] + A[3 * r + 1] * x[i + 1] + A[3 * r + 2] * x[i + 2] + b[r];
  return y;
}

TEST(VisualMapping, LiverWeightsAreAPartitionOfUnity) {
  const Liver& l = liver();
  const VisualMapping& m = l.map;
  ASSERT_EQ(m.size(), l.surface.vertices.size());
  ASSERT_EQ(m.w.size(), m.size());
  ASSERT_EQ(m.tet.size(), m.size());
  for (size_t v = 0; v < m.size(); ++v) {
    const auto& w = m.w[v];
    EXPECT_NEAR(w[0] + w[1] + w[2] + w[3], 1.0, 1e-12) << "vertex " << v;
    for (double wi : w) EXPECT_GE(wi, -1e-9) << "vertex " << v;
    ASSERT_TRUE(m.tet[v] >= 0 && m.tet[v] < static_cast<int32_t>(l.mesh.mesh.tets.size()));
    EXPECT_EQ(m.node[v], l.mesh.mesh.tets[m.tet[v]]) << "vertex " << v;
  }
  // SOFA maps this surface onto these tets: it should hug them (a few % of the mesh size).
  EXPECT_LT(m.outside, static_cast<int>(m.size()));
  EXPECT_LT(m.max_distance, 0.05 * l.diag);
}

TEST(VisualMapping, LiverAgreesWithBruteForceLocator) {
  const Liver& l = liver();
  const auto& nodes = l.mesh.mesh.nodes;
  int outside = 0;
  double max_distance = 0;
  for (size_t v = 0; v < l.map.size(); ++v) {
    const Vec3& p = l.surface.vertices[v];
    const BarycentricPoint ref = locate_point(l.mesh.mesh, p);
    if (ref.distance > 0) {
      ++outside;
      max_distance = std::max(max_distance, ref.distance);
    }
    // Both must land on the same point of the mesh (the tet may differ on shared faces/edges).
    Vec3 q{0, 0, 0}, q_ref{0, 0, 0};
    for (int i = 0; i < 4; ++i)
      for (int k = 0; k < 3; ++k) {
        q[k] += l.map.w[v][i] * nodes[l.map.node[v][i]][k];
        q_ref[k] += ref.w[i] * nodes[ref.node[i]][k];
      }
    const double d = std::hypot(q[0] - p[0], q[1] - p[1], q[2] - p[2]);
    EXPECT_NEAR(d, ref.distance, 1e-9) << "vertex " << v;
    EXPECT_NEAR(std::hypot(q[0] - q_ref[0], q[1] - q_ref[1], q[2] - q_ref[2]), 0.0, 1e-9)
        << "vertex " << v;
  }
  EXPECT_EQ(l.map.outside, outside);
  EXPECT_NEAR(l.map.max_distance, max_distance, 1e-12);
}

TEST(VisualMapping, RestPositionsReproduceInsideVertices) {
  const Liver& l = liver();
  const std::vector<double> q = flatten(l.mesh.mesh.nodes);
  std::vector<double> p(3 * l.map.size());
  l.map.apply(q.data(), p.data());
  int inside = 0;
  for (size_t v = 0; v < l.map.size(); ++v) {
    const Vec3& x = l.surface.vertices[v];
    const double d = std::hypot(p[3 * v] - x[0], p[3 * v + 1] - x[1], p[3 * v + 2] - x[2]);
    const auto& w = l.map.w[v];
    const bool clamped = std::min({w[0], w[1], w[2], w[3]}) >= 0 &&
                         std::count(w.begin(), w.end(), 0.0) > 0;
    if (d <= 1e-9) {
      ++inside;
    } else {
      // Only projected vertices may move, and then by their distance to the mesh, onto a face,
      // edge or corner of their tet (a zero weight).
      EXPECT_TRUE(clamped) << "vertex " << v << " moved by " << d;
      EXPECT_LE(d, l.map.max_distance * (1 + 1e-12)) << "vertex " << v;
    }
  }
  EXPECT_EQ(inside + l.map.outside, static_cast<int>(l.map.size()));
}

TEST(VisualMapping, AffineMotionIsReproducedExactly) {
  const Liver& l = liver();
  const std::vector<double> q = flatten(l.mesh.mesh.nodes);
  const std::array<double, 9> A = {1.3, 0.2, -0.4, 0.1, 0.8, 0.3, -0.25, 0.15, 1.1};
  const Vec3 b = {0.7, -1.9, 2.3};
  std::vector<double> p_rest(3 * l.map.size()), p(3 * l.map.size());
  l.map.apply(q.data(), p_rest.data());
  l.map.apply(affine(A, b, q).data(), p.data());
  const std::vector<double> expected = affine(A, b, p_rest);
  double scale = 0;
  for (double c : expected) scale = std::max(scale, std::fabs(c));
  for (size_t i = 0; i < p.size(); ++i)
    ASSERT_NEAR(p[i], expected[i], 1e-12 * scale) << "vertex " << i / 3 << " component " << i % 3;
}

TEST(VisualMapping, RigidMotionMovesTheSurfaceRigidly) {
  const Liver& l = liver();
  const std::vector<double> q = flatten(l.mesh.mesh.nodes);
  const std::array<double, 9> R = rotation({1, -2, 0.5}, 37);
  const Vec3 t = {3.5, -0.25, 10};
  std::vector<double> p0(3 * l.map.size()), p1(3 * l.map.size());
  l.map.apply(q.data(), p0.data());
  l.map.apply(affine(R, t, q).data(), p1.data());
  auto dist = [](const std::vector<double>& x, size_t i, size_t j) {
    return std::hypot(x[3 * i] - x[3 * j], x[3 * i + 1] - x[3 * j + 1],
                      x[3 * i + 2] - x[3 * j + 2]);
  };
  double worst = 0, moved = 0;
  for (size_t i = 0; i < l.map.size(); ++i) {
    moved = std::max(moved, std::hypot(p1[3 * i] - p0[3 * i], p1[3 * i + 1] - p0[3 * i + 1],
                                       p1[3 * i + 2] - p0[3 * i + 2]));
    for (size_t j = i + 1; j < l.map.size(); ++j)
      worst = std::max(worst, std::fabs(dist(p1, i, j) - dist(p0, i, j)));
  }
  EXPECT_GT(moved, 1.0);  // the motion really moved the surface
  EXPECT_LE(worst, 1e-9);
}

TEST(VisualMapping, TransposeIsTheAdjointAndAccumulates) {
  const Liver& l = liver();
  // Offsets as for a second body in the global arrays: indices shift, nothing else changes.
  const int32_t node_offset = 7, tet_offset = 11;
  const VisualMapping m = build_visual_mapping(l.mesh.mesh, l.surface.vertices, 0.1 * l.diag,
                                               node_offset, tet_offset, "liver-smooth.obj");
  ASSERT_EQ(m.size(), l.map.size());
  for (size_t v = 0; v < m.size(); ++v) {
    EXPECT_EQ(m.tet[v], l.map.tet[v] + tet_offset);
    for (int i = 0; i < 4; ++i) EXPECT_EQ(m.node[v][i], l.map.node[v][i] + node_offset);
  }
  const size_t n_global = l.mesh.mesh.nodes.size() + node_offset + 3;
  std::mt19937_64 rng(42);
  std::uniform_real_distribution<double> u(-1, 1);
  std::vector<double> x(3 * n_global), f(3 * m.size());
  for (double& c : x) c = u(rng);
  for (double& c : f) c = u(rng);
  std::vector<double> Jx(3 * m.size());
  m.apply(x.data(), Jx.data());
  // Start from non-zero values to check that Jᵀf is added, not assigned.
  std::vector<double> base(3 * n_global), JTf(3 * n_global);
  for (double& c : base) c = u(rng);
  JTf = base;
  m.apply_transpose(f.data(), JTf.data());
  double lhs = 0, rhs = 0, mag = 0;
  for (size_t i = 0; i < f.size(); ++i) {
    lhs += Jx[i] * f[i];
    mag += std::fabs(Jx[i] * f[i]);
  }
  for (size_t i = 0; i < x.size(); ++i) {
    const double jtf = JTf[i] - base[i];
    rhs += x[i] * jtf;
    if (i < 3 * static_cast<size_t>(node_offset)) {
      EXPECT_EQ(jtf, 0.0) << "dof " << i;
    }
  }
  EXPECT_NEAR(lhs, rhs, 1e-12 * mag);
  // Σ of nodal forces equals Σ of visual forces (weights sum to 1): nothing lost or created.
  for (int k = 0; k < 3; ++k) {
    double fv = 0, fn = 0;
    for (size_t v = 0; v < m.size(); ++v) fv += f[3 * v + k];
    for (size_t n = 0; n < n_global; ++n) fn += JTf[3 * n + k] - base[3 * n + k];
    EXPECT_NEAR(fn, fv, 1e-10);
  }
}

TEST(VisualMapping, FloatOutputMatchesDouble) {
  const Liver& l = liver();
  const std::vector<double> q = affine(rotation({0.3, 1, -0.2}, 20), {0.1, 0.2, 0.3},
                                       flatten(l.mesh.mesh.nodes));
  std::vector<double> pd(3 * l.map.size());
  std::vector<float> pf(3 * l.map.size());
  l.map.apply(q.data(), pd.data());
  l.map.apply(q.data(), pf.data());
  for (size_t i = 0; i < pd.size(); ++i)
    ASSERT_NEAR(pf[i], pd[i], 1e-7 * std::max(1.0, std::fabs(pd[i]))) << i;
}

TEST(VisualMapping, KnownProjectionsOutsideABox) {
  const TetMesh box = test_meshes::box_mesh(3, 2, 2);  // [0,1]³, 72 tets
  const std::vector<Vec3> pts = {{0.5, 0.5, 0.5},     // inside
                                 {1.0, 0.25, 0.75},   // on the boundary: inside
                                 {1.3, 0.5, 0.5},     // beyond the x = 1 face
                                 {-0.2, 1.2, 1.2},    // beyond the (0, 1, 1) corner
                                 {0.4, -0.25, 1.25}}; // beyond the y = 0, z = 1 edge
  const VisualMapping m = build_visual_mapping(box, pts, 0.5);
  const std::vector<Vec3> proj = {{0.5, 0.5, 0.5}, {1.0, 0.25, 0.75}, {1.0, 0.5, 0.5},
                                  {0.0, 1.0, 1.0}, {0.4, 0.0, 1.0}};
  std::vector<double> p(3 * pts.size());
  m.apply(flatten(box.nodes).data(), p.data());
  for (size_t v = 0; v < pts.size(); ++v)
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(p[3 * v + k], proj[v][k], 1e-12) << v << "," << k;
  EXPECT_EQ(m.outside, 3);
  EXPECT_NEAR(m.max_distance, std::sqrt(2 * 0.25 * 0.25), 1e-12);  // the edge case
}

TEST(VisualMapping, RandomPointsAgreeWithBruteForceLocator) {
  // A jittered box has a bumpy boundary, so nearest tets are not where the grid cell suggests.
  const TetMesh box = test_meshes::box_mesh(5, 4, 3, {2.0, 1.0, 1.5}, {-1, 0, 0}, 0.3);
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> ux(-2.0, 2.0), uy(-0.8, 1.8), uz(-0.5, 2.0);
  std::vector<Vec3> pts(600);
  for (Vec3& p : pts) p = {ux(rng), uy(rng), uz(rng)};
  const VisualMapping m = build_visual_mapping(box, pts, 10.0);
  int outside = 0;
  for (size_t v = 0; v < pts.size(); ++v) {
    const BarycentricPoint ref = locate_point(box, pts[v]);
    outside += ref.distance > 0;
    Vec3 q{0, 0, 0};
    for (int i = 0; i < 4; ++i)
      for (int k = 0; k < 3; ++k) q[k] += m.w[v][i] * box.nodes[m.node[v][i]][k];
    const double d = std::hypot(q[0] - pts[v][0], q[1] - pts[v][1], q[2] - pts[v][2]);
    EXPECT_NEAR(d, ref.distance, 1e-9) << "point " << v;
  }
  EXPECT_GT(outside, 100);  // the test does exercise the outside search
  EXPECT_EQ(m.outside, outside);
}

TEST(VisualMapping, FarVertexThrowsNamingIt) {
  const TetMesh box = test_meshes::box_mesh(2, 2, 2);
  const std::vector<Vec3> pts = {{0.5, 0.5, 0.5}, {0.2, 0.3, 0.4}, {10, 0.5, 0.5},
                                 {0.5, -3, 0.5}};
  try {
    build_visual_mapping(box, pts, 0.5, 0, 0, "probe.obj");
    ADD_FAILURE() << "no InputError";
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_EQ(e.file(), "probe.obj");
    EXPECT_EQ(e.line(), 0);
    EXPECT_EQ(what.rfind("probe.obj: visual vertex 2 (0-based) at (10, 0.5, 0.5) is 9 from", 0),
              0u)
        << what;
    EXPECT_NE(what.find("max_distance 0.5; 2 of 4 vertices are that far"), std::string::npos)
        << what;
  }
  // The same vertices pass with a large enough limit.
  EXPECT_EQ(build_visual_mapping(box, pts, 9.5).outside, 2);
}

TEST(VisualMapping, MeshWithoutTetsThrows) {
  TetMesh empty;
  empty.source = "empty.msh";
  empty.nodes = {{0, 0, 0}};
  try {
    build_visual_mapping(empty, {{0, 0, 0}}, 1.0, 0, 0, "surf.obj");
    ADD_FAILURE() << "no InputError";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()),
              "surf.obj: cannot map the surface onto 'empty.msh': it has no tetrahedra");
  }
}

TEST(VisualMapping, RaptorSurfacesSpeed) {
  // The boundary vertices of a 19k-tet mesh lie on its tets: all inside, none projected.
  const PreparedMesh pm = prepare_mesh(load_tet_mesh(real_mesh("raptorTetra_19409.vtu")));
  std::vector<char> on_boundary(pm.mesh.nodes.size(), 0);
  for (const Tri& t : pm.boundary)
    for (int32_t n : t) on_boundary[n] = 1;
  std::vector<Vec3> pts;
  for (size_t n = 0; n < pm.mesh.nodes.size(); ++n)
    if (on_boundary[n]) pts.push_back(pm.mesh.nodes[n]);
  auto t0 = std::chrono::steady_clock::now();
  const VisualMapping m = build_visual_mapping(pm.mesh, pts, 0.0);
  const double ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  EXPECT_EQ(m.outside, 0);
  std::printf("[ raptor   ] mapping %zu boundary vertices into %zu tets: %.2f ms\n", pts.size(),
              pm.mesh.tets.size(), ms);

  // A 50k-vertex visual surface: points on the boundary triangles, pushed in or out along the
  // normal by up to 1 % of the mesh size, as a finer smooth surface would lie.
  Vec3 lo = pm.mesh.nodes[0], hi = lo;
  for (const Vec3& p : pm.mesh.nodes)
    for (int a = 0; a < 3; ++a) {
      lo[a] = std::min(lo[a], p[a]);
      hi[a] = std::max(hi[a], p[a]);
    }
  const double diag = std::hypot(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]);
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u01(0, 1), off(-0.01 * diag, 0.01 * diag);
  std::uniform_int_distribution<size_t> pick(0, pm.boundary.size() - 1);
  std::vector<Vec3> surface(50000);
  for (Vec3& p : surface) {
    const Tri& t = pm.boundary[pick(rng)];
    const Vec3 &a = pm.mesh.nodes[t[0]], &b = pm.mesh.nodes[t[1]], &c = pm.mesh.nodes[t[2]];
    double r1 = u01(rng), r2 = u01(rng);
    if (r1 + r2 > 1) r1 = 1 - r1, r2 = 1 - r2;
    const Vec3 e1 = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
    const Vec3 e2 = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    Vec3 n = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2],
              e1[0] * e2[1] - e1[1] * e2[0]};
    const double len = std::hypot(n[0], n[1], n[2]), h = off(rng);
    for (int k = 0; k < 3; ++k) p[k] = a[k] + r1 * e1[k] + r2 * e2[k] + h * n[k] / len;
  }
  t0 = std::chrono::steady_clock::now();
  const VisualMapping ms_map = build_visual_mapping(pm.mesh, surface, 0.02 * diag);
  const double ms_surface =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  std::printf("[ raptor   ] mapping a %zu-vertex surface (%d outside, max distance %.3g%% of the "
              "diagonal) into %zu tets: %.2f ms\n",
              surface.size(), ms_map.outside, 100 * ms_map.max_distance / diag,
              pm.mesh.tets.size(), ms_surface);
  EXPECT_GT(ms_map.outside, 10000);  // about half the points lie outside
  EXPECT_LE(ms_map.max_distance, 0.01 * diag * (1 + 1e-9));

  // Worst case: 20k points scattered over the bounding box, most far outside this thin body.
  std::vector<Vec3> cloud(20000);
  for (Vec3& p : cloud)
    for (int a = 0; a < 3; ++a) p[a] = lo[a] + u01(rng) * (hi[a] - lo[a]);
  t0 = std::chrono::steady_clock::now();
  const VisualMapping mc = build_visual_mapping(pm.mesh, cloud, 1e300);
  const double ms_cloud =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  std::printf("[ raptor   ] mapping %zu points in the bounding box (%d outside) into %zu tets: "
              "%.2f ms\n",
              cloud.size(), mc.outside, pm.mesh.tets.size(), ms_cloud);
  // Spot-check the cloud against the brute-force locator.
  for (size_t v = 0; v < cloud.size(); v += 1000) {
    const BarycentricPoint ref = locate_point(pm.mesh, cloud[v]);
    Vec3 q{0, 0, 0};
    for (int i = 0; i < 4; ++i)
      for (int k = 0; k < 3; ++k) q[k] += mc.w[v][i] * pm.mesh.nodes[mc.node[v][i]][k];
    EXPECT_NEAR(std::hypot(q[0] - cloud[v][0], q[1] - cloud[v][1], q[2] - cloud[v][2]),
                ref.distance, 1e-9)
        << "point " << v;
  }
}

}  // namespace
}  // namespace stroma
