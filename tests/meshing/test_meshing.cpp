// `stroma mesh` underneath (tissue/meshing): synthetic phantoms the tests make themselves — an
// ellipsoid label with a spherical inclusion at 1 mm and at 0.8 x 0.8 x 2 mm voxels, a closed
// triangulated sphere and torus — meshed at the default size; region volumes against the
// analytic ones, the quality bound, the inclusion's tags; and every bad input refused.

#include <gtest/gtest.h>

#include <cmath>
#include <set>
#include <utility>

#include "tests/input_error_message.hpp"
#include "tissue/input_error.hpp"
#include "tissue/mesh_prepare.hpp"
#include "tissue/meshing/mesher.hpp"

using namespace stroma;
using stroma::test_support::message_of;
using namespace stroma::meshing;

namespace {

constexpr double kA = 0.024, kB = 0.019, kC = 0.017;  // ellipsoid semi-axes (m): 6 mm around the inclusion
constexpr double kR = 0.010;                          // inclusion radius (m)
const Vec3 kInclusion{0.008, 0.0, 0.0};               // inclusion centre (m)

/// Ellipsoid (label 1) with a spherical inclusion (label 2), voxel centres tested, the grid's
/// origin chosen so that the ellipsoid's centre is the world origin.
LabelImage phantom(double sx, double sy, double sz) {
  LabelImage im;
  const double ext[3] = {kA + 0.006, kB + 0.006, kC + 0.006};
  const double sp[3] = {sx, sy, sz};
  for (int a = 0; a < 3; ++a) {
    im.dims[size_t(a)] = int64_t(std::ceil(2 * ext[a] / sp[a]));
    im.spacing[size_t(a)] = sp[a];
    im.origin[size_t(a)] = -ext[a];
  }
  im.labels.resize(size_t(im.voxel_count()));
  for (int64_t k = 0; k < im.dims[2]; ++k)
    for (int64_t j = 0; j < im.dims[1]; ++j)
      for (int64_t i = 0; i < im.dims[0]; ++i) {
        const double x = -ext[0] + double(i) * sx, y = -ext[1] + double(j) * sy, z = -ext[2] + double(k) * sz;
        int32_t l = 0;
        if ((x / kA) * (x / kA) + (y / kB) * (y / kB) + (z / kC) * (z / kC) <= 1) l = 1;
        const double dx = x - kInclusion[0], dy = y - kInclusion[1], dz = z - kInclusion[2];
        if (dx * dx + dy * dy + dz * dz <= kR * kR) l = 2;
        im.labels[size_t(i + im.dims[0] * (j + im.dims[1] * k))] = l;
      }
  im.source = "phantom";
  return im;
}

Vec3 centroid(const TetMesh& m, const Tet& t) {
  Vec3 c{0, 0, 0};
  for (int32_t v : t)
    for (int a = 0; a < 3; ++a) c[size_t(a)] += m.nodes[size_t(v)][size_t(a)] / 4;
  return c;
}

void expect_quality(const MeshingResult& r, const MeshingOptions& o) {
  EXPECT_GE(r.quality.dihedral_min_deg, o.min_dihedral_deg);
  EXPECT_EQ(r.quality.slivers, 0);
  EXPECT_EQ(r.quality.inverted, 0);
  // What the engine will do with it: prepare_mesh keeps every element (none degenerate).
  const PreparedMesh p = prepare_mesh(r.mesh);
  EXPECT_EQ(p.mesh.tets.size(), r.mesh.tets.size());
}

void check_phantom(const LabelImage& im) {
  const MeshingOptions o;  // defaults
  const MeshingResult r = mesh_label_image(im, {{1, "liver"}, {2, "tumour"}}, o);
  expect_quality(r, o);
  ASSERT_EQ(r.quality.regions.size(), 2u);
  const double v_sphere = 4.0 / 3.0 * M_PI * kR * kR * kR;
  const double v_shell = 4.0 / 3.0 * M_PI * kA * kB * kC - v_sphere;
  EXPECT_EQ(r.quality.regions[0].name, "liver");
  EXPECT_NEAR(r.quality.regions[0].volume, v_shell, 0.02 * v_shell);
  EXPECT_NEAR(r.quality.regions[1].volume, v_sphere, 0.02 * v_sphere);
  // The inclusion's tetrahedra are tagged 2 and lie in the sphere, the others outside it (within
  // a voxel), and every tag is one of the two labels.
  const double slack = std::max({im.spacing[0], im.spacing[1], im.spacing[2]});
  int64_t tagged2 = 0;
  for (size_t t = 0; t < r.mesh.tets.size(); ++t) {
    const Vec3 c = centroid(r.mesh, r.mesh.tets[t]);
    const double d = std::hypot(c[0] - kInclusion[0], c[1] - kInclusion[1], c[2] - kInclusion[2]);
    const int32_t tag = r.mesh.tet_tags[t];
    ASSERT_TRUE(tag == 1 || tag == 2) << tag;
    if (tag == 2) {
      ++tagged2;
      EXPECT_LT(d, kR + slack);
    } else {
      EXPECT_GT(d, kR - slack);
    }
  }
  EXPECT_GT(tagged2, 100);
  // The element count asked for (5,000 by default), within 15 %.
  EXPECT_NEAR(double(r.mesh.tets.size()), double(o.target_tets), 0.15 * double(o.target_tets));
  EXPECT_EQ(r.mesh.tag_names, (std::vector<std::pair<int32_t, std::string>>{{1, "liver"}, {2, "tumour"}}));
  // Interfaces conform: every interior face is shared by exactly two elements, so the only
  // boundary is the outer one, whose area is the ellipsoid's (no gaps at the inclusion).
  EXPECT_LT(r.quality.hausdorff, 1.5 * slack);
}

SurfaceMesh sphere_surface(double R, int nu, int nv) {
  SurfaceMesh s;
  s.vertices.push_back({0, 0, R});
  for (int i = 1; i < nv; ++i)
    for (int j = 0; j < nu; ++j) {
      const double th = M_PI * i / nv, ph = 2 * M_PI * j / nu;
      s.vertices.push_back({R * std::sin(th) * std::cos(ph), R * std::sin(th) * std::sin(ph), R * std::cos(th)});
    }
  s.vertices.push_back({0, 0, -R});
  for (int j = 0; j < nu; ++j) s.triangles.push_back({0, 1 + j, 1 + (j + 1) % nu});
  for (int i = 0; i < nv - 2; ++i)
    for (int j = 0; j < nu; ++j) {
      const int a = 1 + i * nu + j, b = 1 + i * nu + (j + 1) % nu;
      s.triangles.push_back({a, a + nu, b + nu});
      s.triangles.push_back({a, b + nu, b});
    }
  const int last = int(s.vertices.size()) - 1, base = 1 + (nv - 2) * nu;
  for (int j = 0; j < nu; ++j) s.triangles.push_back({base + j, last, base + (j + 1) % nu});
  s.source = "sphere";
  return s;
}

SurfaceMesh torus_surface(double R, double r, int nu, int nv) {
  SurfaceMesh s;
  for (int i = 0; i < nu; ++i)
    for (int j = 0; j < nv; ++j) {
      const double u = 2 * M_PI * i / nu, v = 2 * M_PI * j / nv;
      s.vertices.push_back({(R + r * std::cos(v)) * std::cos(u), (R + r * std::cos(v)) * std::sin(u), r * std::sin(v)});
    }
  for (int i = 0; i < nu; ++i)
    for (int j = 0; j < nv; ++j) {
      const int a = i * nv + j, b = ((i + 1) % nu) * nv + j, c = ((i + 1) % nu) * nv + (j + 1) % nv, d = i * nv + (j + 1) % nv;
      s.triangles.push_back({a, b, c});
      s.triangles.push_back({a, c, d});
    }
  s.source = "torus";
  return s;
}

/// Volume enclosed by a fine triangulation inscribed in the analytic surface (what the mesher
/// is given): close to, and below, the analytic volume.
double enclosed(const SurfaceMesh& s) {
  double v = 0;
  for (const Tri& t : s.triangles) {
    const Vec3 &a = s.vertices[size_t(t[0])], &b = s.vertices[size_t(t[1])], &c = s.vertices[size_t(t[2])];
    v += (a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) + a[2] * (b[0] * c[1] - b[1] * c[0])) / 6;
  }
  return std::abs(v);
}

}  // namespace

TEST(MeshImage, EllipsoidWithInclusionAt1mm) { check_phantom(phantom(1e-3, 1e-3, 1e-3)); }

TEST(MeshImage, EllipsoidWithInclusionAtAnisotropicVoxels) { check_phantom(phantom(0.8e-3, 0.8e-3, 2e-3)); }

TEST(MeshImage, SizeIsTheMeanEdgeAndTetsTheCount) {
  const LabelImage im = phantom(1e-3, 1e-3, 1e-3);
  MeshingOptions o;
  o.size = 2.5e-3;
  MeshingResult r = mesh_label_image(im, {{1, "liver"}, {2, "tumour"}}, o);
  EXPECT_NEAR(mean_edge_length(r.mesh), o.size, 0.08 * o.size);
  EXPECT_DOUBLE_EQ(r.quality.edge_mean, mean_edge_length(r.mesh));
  expect_quality(r, o);
  o = MeshingOptions{};
  o.target_tets = 15000;
  r = mesh_label_image(im, {{1, "liver"}, {2, "tumour"}}, o);
  EXPECT_NEAR(double(r.mesh.tets.size()), 15000.0, 0.15 * 15000.0);
  expect_quality(r, o);
}

TEST(MeshImage, TheBoundaryFitKeepsCurvedVolumes) {
  // Facets as chords lose volume in a curved region; the fit (facets straddling the surface)
  // restores it. Same mesh with and without: the fitted volumes nearer the analytic ones, by at
  // least half the chords' loss, and within 2 %.
  const LabelImage im = phantom(1e-3, 1e-3, 1e-3);
  MeshingOptions o;
  o.target_tets = 3000;
  o.fit_boundary = false;
  const MeshingResult chords = mesh_label_image(im, {{2, "tumour"}}, o);
  o.fit_boundary = true;
  const MeshingResult fitted = mesh_label_image(im, {{2, "tumour"}}, o);
  EXPECT_EQ(chords.mesh.tets, fitted.mesh.tets);  // the fit moves vertices, never reconnects
  const double v = 4.0 / 3.0 * M_PI * kR * kR * kR;
  const double err_chords = chords.quality.regions.at(0).volume - v, err_fitted = fitted.quality.regions.at(0).volume - v;
  EXPECT_LT(err_chords, 0);  // chords of a convex region lie inside it
  EXPECT_LT(std::abs(err_fitted), 0.5 * std::abs(err_chords));
  EXPECT_LT(std::abs(err_fitted), 0.02 * v);
  EXPECT_GT(fitted.fit.vertices_moved, 0);
  EXPECT_EQ(fitted.quality.inverted, 0);
  EXPECT_GE(fitted.quality.dihedral_min_deg, o.min_dihedral_deg);
}

TEST(MeshImage, OrientationOfTheImageIsApplied) {
  // The same phantom with a rotated, reflected grid: the mesh is the rotated one, positively oriented.
  LabelImage im = phantom(1e-3, 1e-3, 1e-3);
  im.direction = {0, 1, 0, 1, 0, 0, 0, 0, 1};  // swap x and y: a reflection
  const MeshingOptions o;
  const MeshingResult r = mesh_label_image(im, {{2, "tumour"}}, o);
  EXPECT_EQ(r.quality.inverted, 0);
  // The inclusion's centre moves from (8, 0, 0) mm in grid terms to y = 8 mm - ... i.e. world
  // (y_grid, x_grid, z) relative to the swapped origin.
  Vec3 c{0, 0, 0};
  for (const Vec3& p : r.mesh.nodes)
    for (int a = 0; a < 3; ++a) c[size_t(a)] += p[size_t(a)] / double(r.mesh.nodes.size());
  const double gx = kInclusion[0] - im.origin[0], gy = kInclusion[1] - im.origin[1];
  EXPECT_NEAR(c[0], im.origin[0] + gy, 1e-3);
  EXPECT_NEAR(c[1], im.origin[1] + gx, 1e-3);
}

TEST(MeshSurface, SphereAndTorusAtTheDefaultSize) {
  const MeshingOptions o;
  for (const SurfaceMesh& s : {sphere_surface(0.05, 96, 48), torus_surface(0.04, 0.015, 96, 48)}) {
    SCOPED_TRACE(s.source);
    const MeshingResult r = mesh_surface(s, 1.0, o);
    expect_quality(r, o);
    const double analytic = s.source == "sphere" ? 4.0 / 3.0 * M_PI * 0.05 * 0.05 * 0.05
                                                 : 2 * M_PI * M_PI * 0.04 * 0.015 * 0.015;
    EXPECT_NEAR(enclosed(s), analytic, 0.005 * analytic);  // the input is a fine triangulation
    EXPECT_NEAR(r.quality.regions.at(0).volume, analytic, 0.02 * analytic);
    EXPECT_NEAR(r.quality.regions.at(0).input_volume, enclosed(s), 1e-9 * analytic);
    // The boundary fit keeps the input's volume to second order: facets straddle the surface.
    EXPECT_NEAR(r.quality.regions.at(0).volume, enclosed(s), 0.005 * enclosed(s));
    EXPECT_LT(r.quality.hausdorff, r.size / 4);
    // The element count asked for (5,000), within 15 %.
    EXPECT_NEAR(double(r.mesh.tets.size()), 5000.0, 750.0);
  }
}

TEST(MeshSurface, ScaleAndSizeAreHonoured) {
  // --size is the mean edge length of the mesh (its distinct edges), met within 8 %.
  MeshingOptions o;
  o.size = 0.01;
  const MeshingResult r = mesh_surface(sphere_surface(50, 64, 32), 1e-3, o);  // mm to m
  EXPECT_NEAR(r.quality.regions.at(0).volume, 4.0 / 3.0 * M_PI * 1.25e-4, 0.03 * 4.0 / 3.0 * M_PI * 1.25e-4);
  double sum = 0;
  std::set<std::pair<int32_t, int32_t>> seen;
  for (const Tet& t : r.mesh.tets)
    for (int a = 0; a < 4; ++a)
      for (int b = a + 1; b < 4; ++b) {
        if (!seen.insert(std::minmax(t[size_t(a)], t[size_t(b)])).second) continue;
        const Vec3 &p = r.mesh.nodes[size_t(t[size_t(a)])], &q = r.mesh.nodes[size_t(t[size_t(b)])];
        sum += std::hypot(p[0] - q[0], p[1] - q[1], p[2] - q[2]);
      }
  const double mean = sum / double(seen.size());
  EXPECT_NEAR(mean, o.size, 0.08 * o.size);
  EXPECT_NEAR(r.quality.edge_mean, mean, 1e-12);
  EXPECT_GE(r.size_passes, 1);
  EXPECT_LE(r.size_passes, 4);
}

TEST(MeshSurface, SameSeedSameMesh) {
  MeshingOptions o;
  o.target_tets = 3000;
  const SurfaceMesh s = torus_surface(0.04, 0.015, 48, 24);
  const MeshingResult a = mesh_surface(s, 1.0, o), b = mesh_surface(s, 1.0, o);
  EXPECT_EQ(a.mesh.nodes, b.mesh.nodes);
  EXPECT_EQ(a.mesh.tets, b.mesh.tets);
}

TEST(MeshErrors, OpenNonManifoldAndSelfIntersectingSurfacesAreRefused) {
  SurfaceMesh open = sphere_surface(0.05, 24, 12);
  open.triangles.erase(open.triangles.begin() + 40);
  std::string m = message_of([&] { mesh_surface(open, 1.0, MeshingOptions{}); });
  EXPECT_NE(m.find("3 boundary edges"), std::string::npos) << m;
  EXPECT_NE(m.find("nothing written"), std::string::npos) << m;

  // Two spheres overlapping: triangles of one cross the other's.
  SurfaceMesh two = sphere_surface(0.05, 24, 12);
  const SurfaceMesh other = sphere_surface(0.05, 24, 12);
  const int32_t base = int32_t(two.vertices.size());
  for (Vec3 v : other.vertices) {
    v[0] += 0.03;
    two.vertices.push_back(v);
  }
  for (const Tri& t : other.triangles) two.triangles.push_back({t[0] + base, t[1] + base, t[2] + base});
  m = message_of([&] { mesh_surface(two, 1.0, MeshingOptions{}); });
  EXPECT_NE(m.find("intersects itself"), std::string::npos) << m;
  EXPECT_NE(m.find("triangles "), std::string::npos) << m;
}

TEST(MeshErrors, BadLabelsAndSizesAreRefused) {
  const LabelImage im = phantom(2e-3, 2e-3, 2e-3);
  std::string m = message_of([&] { mesh_label_image(im, {{1, "liver"}, {3, "vessel"}}, MeshingOptions{}); });
  EXPECT_NE(m.find("label 3 (vessel) is not in the image; the image has labels 0"), std::string::npos) << m;
  LabelImage empty = im;
  std::fill(empty.labels.begin(), empty.labels.end(), 0);
  m = message_of([&] { mesh_label_image(empty, {{1, "liver"}}, MeshingOptions{}); });
  EXPECT_NE(m.find("label 1 (liver) is not in the image"), std::string::npos) << m;
  MeshingOptions neg;
  neg.size = -0.001;
  m = message_of([&] { mesh_label_image(im, {{1, "liver"}}, neg); });
  EXPECT_NE(m.find("--size"), std::string::npos) << m;
  m = message_of([&] { mesh_surface(sphere_surface(0.05, 24, 12), 1.0, neg); });
  EXPECT_NE(m.find("--size"), std::string::npos) << m;
}
