// Mass properties of rigid bodies' shapes (issue 42): the closed forms against the divergence
// theorem over fine triangulations of the same shapes (two independent computations), the
// polyhedral one exact on a box, moved and turned boxes, either orientation, and bad input.

#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>

#include "rigid/mass_properties.hpp"

using namespace stroma;

namespace {

using Tris = std::vector<std::array<int32_t, 3>>;

/// A box of full sizes s centred at c, turned by R (row-major), as 12 outward triangles.
void box_surface(const Vec3& s, const Vec3& c, const double* R, std::vector<Vec3>& v, Tris& t) {
  v.clear();
  t.clear();
  for (int k = 0; k < 8; ++k) {
    const double p[3] = {((k & 1) ? 0.5 : -0.5) * s[0], ((k & 2) ? 0.5 : -0.5) * s[1], ((k & 4) ? 0.5 : -0.5) * s[2]};
    Vec3 q;
    for (int i = 0; i < 3; ++i) q[size_t(i)] = c[size_t(i)] + R[3 * i] * p[0] + R[3 * i + 1] * p[1] + R[3 * i + 2] * p[2];
    v.push_back(q);
  }
  t = {{0, 2, 3}, {0, 3, 1}, {4, 5, 7}, {4, 7, 6}, {0, 1, 5}, {0, 5, 4},
       {2, 6, 7}, {2, 7, 3}, {0, 4, 6}, {0, 6, 2}, {1, 3, 7}, {1, 7, 5}};
}

/// A capsule (radius r, cylinder length L along z) or, with L = 0, a sphere: latitude rings on
/// the two hemispheres, nu around, nv per hemisphere; outward.
void capsule_surface(double r, double L, int nu, int nv, std::vector<Vec3>& v, Tris& t) {
  v.clear();
  t.clear();
  v.push_back({0, 0, 0.5 * L + r});
  std::vector<int> ring_start;
  for (int half = 0; half < 2; ++half)
    for (int i = (half ? 0 : 1); i <= (half ? nv - 1 : nv); ++i) {
      // half 0: polar angle from the top pole to the equator; half 1: equator to the bottom.
      const double th = half ? M_PI / 2 + M_PI / 2 * i / nv : M_PI / 2 * i / nv;
      const double zc = half ? -0.5 * L : 0.5 * L;
      ring_start.push_back(int(v.size()));
      for (int j = 0; j < nu; ++j) {
        const double ph = 2 * M_PI * j / nu;
        v.push_back({r * std::sin(th) * std::cos(ph), r * std::sin(th) * std::sin(ph), zc + r * std::cos(th)});
      }
    }
  v.push_back({0, 0, -0.5 * L - r});
  const int last = int(v.size()) - 1;
  for (int j = 0; j < nu; ++j) t.push_back({0, ring_start[0] + j, ring_start[0] + (j + 1) % nu});
  for (size_t k = 0; k + 1 < ring_start.size(); ++k)
    for (int j = 0; j < nu; ++j) {
      const int a = ring_start[k] + j, b = ring_start[k] + (j + 1) % nu;
      const int c = ring_start[k + 1] + j, d = ring_start[k + 1] + (j + 1) % nu;
      t.push_back({a, c, d});
      t.push_back({a, d, b});
    }
  const int base = ring_start.back();
  for (int j = 0; j < nu; ++j) t.push_back({base + j, last, base + (j + 1) % nu});
}

void expect_close(const MassProperties& a, const MassProperties& b, double rel) {
  EXPECT_NEAR(a.mass, b.mass, rel * b.mass);
  const double scale = b.inertia[0] + b.inertia[4] + b.inertia[8];
  for (size_t i = 0; i < 9; ++i) EXPECT_NEAR(a.inertia[i], b.inertia[i], rel * scale) << "entry " << i;
}

}  // namespace

TEST(MassProperties, TheBoxsTriangulationGivesTheClosedFormExactly) {
  const double I3[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  std::vector<Vec3> v;
  Tris t;
  box_surface({0.03, 0.02, 0.01}, {0, 0, 0}, I3, v, t);
  const MassProperties m = mesh_mass_properties(v, t, 1000), c = box_mass_properties({0.03, 0.02, 0.01}, 1000);
  expect_close(m, c, 1e-12);
  EXPECT_NEAR(m.volume, 6e-6, 1e-18);
  std::string why;
  EXPECT_TRUE(is_physical(m, &why)) << why;
}

TEST(MassProperties, AMovedAndTurnedBoxHasItsCentreThereAndItsInertiaTurned) {
  const double a = 0.7, b = -0.4;  // R = Rz(a) Rx(b)
  const double R[9] = {std::cos(a), -std::sin(a) * std::cos(b), std::sin(a) * std::sin(b),
                       std::sin(a), std::cos(a) * std::cos(b),  -std::cos(a) * std::sin(b),
                       0,           std::sin(b),                std::cos(b)};
  std::vector<Vec3> v;
  Tris t;
  box_surface({0.05, 0.02, 0.01}, {0.1, -0.2, 0.3}, R, v, t);
  const MassProperties m = mesh_mass_properties(v, t, 1060);
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(m.centre[size_t(i)], (Vec3{0.1, -0.2, 0.3})[size_t(i)], 1e-12);
  const MassProperties body = box_mass_properties({0.05, 0.02, 0.01}, 1060);
  // R I Rᵀ
  double RI[9], RIRt[9];
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) {
      RI[3 * i + j] = 0;
      for (int k = 0; k < 3; ++k) RI[3 * i + j] += R[3 * i + k] * body.inertia[size_t(3 * k + j)];
    }
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) {
      RIRt[3 * i + j] = 0;
      for (int k = 0; k < 3; ++k) RIRt[3 * i + j] += RI[3 * i + k] * R[3 * j + k];
    }
  const double scale = body.inertia[0] + body.inertia[4] + body.inertia[8];
  for (int i = 0; i < 9; ++i) EXPECT_NEAR(m.inertia[size_t(i)], RIRt[i], 1e-12 * scale) << i;
}

TEST(MassProperties, SphereAndCapsuleClosedFormsMatchFineTriangulations) {
  std::vector<Vec3> v;
  Tris t;
  // The inscribed polyhedron converges as 1/n²: 256 × 128 is within 0.05 % in volume.
  capsule_surface(0.01, 0.0, 256, 64, v, t);
  expect_close(mesh_mass_properties(v, t, 1000), sphere_mass_properties(0.01, 1000), 2e-3);
  capsule_surface(0.002, 0.03, 256, 64, v, t);
  const MassProperties m = mesh_mass_properties(v, t, 7800), c = capsule_mass_properties(0.002, 0.03, 7800);
  expect_close(m, c, 2e-3);
  EXPECT_NEAR(m.centre[2], 0.0, 1e-9);
  std::string why;
  EXPECT_TRUE(is_physical(c, &why)) << why;
}

TEST(MassProperties, EitherOrientationOfTheSurfaceGivesTheSameSolid) {
  std::vector<Vec3> v;
  Tris t;
  capsule_surface(0.01, 0.02, 32, 8, v, t);
  const MassProperties out = mesh_mass_properties(v, t, 1000);
  for (auto& tri : t) std::swap(tri[1], tri[2]);
  const MassProperties in = mesh_mass_properties(v, t, 1000);
  expect_close(in, out, 1e-12);
}

TEST(MassProperties, BadShapesAndDensitiesAreRefused) {
  EXPECT_THROW(sphere_mass_properties(0, 1000), std::invalid_argument);
  EXPECT_THROW(sphere_mass_properties(0.01, -1), std::invalid_argument);
  EXPECT_THROW(box_mass_properties({0.01, 0, 0.01}, 1000), std::invalid_argument);
  EXPECT_THROW(capsule_mass_properties(0.01, -0.1, 1000), std::invalid_argument);
  // A flat surface encloses nothing.
  const std::vector<Vec3> v = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 0}};
  const Tris t = {{0, 1, 2}, {1, 3, 2}, {0, 2, 1}, {1, 2, 3}};
  EXPECT_THROW(mesh_mass_properties(v, t, 1000), std::invalid_argument);
  // The invariants' check sees a tensor no solid has.
  MassProperties p = sphere_mass_properties(0.01, 1000);
  p.inertia[8] = 3 * p.inertia[0];
  std::string why;
  EXPECT_FALSE(is_physical(p, &why));
  EXPECT_NE(why.find("triangle inequality"), std::string::npos) << why;
}
