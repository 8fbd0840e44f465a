// A free rigid body's step (issue 42): free fall against the implicit Euler's exact discrete
// solution and the continuous one; a torque-free asymmetric box spun near its intermediate axis
// (it tumbles: the Dzhanibekov effect) for 10 s — energy and |L| kept to the solve's tolerance,
// the angular momentum's direction in space within the midpoint rule's second-order error, and
// the body-frame angular velocity against an independent RK4 integration at a 100× finer step.

#include <gtest/gtest.h>

#include <cmath>

#include "rigid/rigid_motion.hpp"

using namespace stroma;

namespace {

double norm(const Vec3& a) { return std::sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]); }

/// Euler's equations in the body frame, dω/dt = I⁻¹(−ω × Iω), for a diagonal I, by RK4.
Vec3 rk4_euler(const Vec3& I, Vec3 w, double t, double dt) {
  auto f = [&](const Vec3& x) {
    return Vec3{(I[1] - I[2]) / I[0] * x[1] * x[2], (I[2] - I[0]) / I[1] * x[2] * x[0], (I[0] - I[1]) / I[2] * x[0] * x[1]};
  };
  const int n = int(std::llround(t / dt));
  for (int k = 0; k < n; ++k) {
    const Vec3 k1 = f(w);
    Vec3 a;
    for (int i = 0; i < 3; ++i) a[size_t(i)] = w[size_t(i)] + 0.5 * dt * k1[size_t(i)];
    const Vec3 k2 = f(a);
    for (int i = 0; i < 3; ++i) a[size_t(i)] = w[size_t(i)] + 0.5 * dt * k2[size_t(i)];
    const Vec3 k3 = f(a);
    for (int i = 0; i < 3; ++i) a[size_t(i)] = w[size_t(i)] + dt * k3[size_t(i)];
    const Vec3 k4 = f(a);
    for (int i = 0; i < 3; ++i)
      w[size_t(i)] += dt / 6 * (k1[size_t(i)] + 2 * k2[size_t(i)] + 2 * k3[size_t(i)] + k4[size_t(i)]);
  }
  return w;
}

Vec3 body_w(const RigidState& s) {
  const auto R = rotation_of(s.q);
  return {R[0] * s.w[0] + R[3] * s.w[1] + R[6] * s.w[2], R[1] * s.w[0] + R[4] * s.w[1] + R[7] * s.w[2],
          R[2] * s.w[0] + R[5] * s.w[1] + R[8] * s.w[2]};
}

}  // namespace

TEST(RigidMotion, FreeFallIsTheImplicitEulersExactDiscreteSolution) {
  const MassProperties p = sphere_mass_properties(0.01, 1000);
  const Vec3 g{0, 0, -9.81}, v0{0.2, -0.1, 0.5}, x0{0.01, 0.02, 0.3};
  RigidState s;
  s.x = x0;
  s.v = v0;
  const double h = 1e-3;
  const int n = 1000;
  for (int k = 0; k < n; ++k) step_free_rigid(p.inertia, g, h, s);
  const double t = n * h;
  for (int i = 0; i < 3; ++i) {
    // v_k = v0 + k h g, x_n = x0 + Σ h v_k (k = 1..n) = x0 + v0 t + g h² n(n+1)/2.
    const double exact_discrete = x0[size_t(i)] + v0[size_t(i)] * t + g[size_t(i)] * h * h * n * (n + 1) / 2.0;
    const double continuous = x0[size_t(i)] + v0[size_t(i)] * t + 0.5 * g[size_t(i)] * t * t;
    EXPECT_NEAR(s.x[size_t(i)], exact_discrete, 1e-12);
    EXPECT_NEAR(s.x[size_t(i)], continuous, 0.5 * std::abs(g[size_t(i)]) * h * t + 1e-12);
    EXPECT_NEAR(s.v[size_t(i)], v0[size_t(i)] + g[size_t(i)] * t, 1e-12);
  }
}

TEST(RigidMotion, ATorqueFreeAsymmetricBodyKeepsItsEnergyAndMomentumWhileItTumbles) {
  const Vec3 size{0.05, 0.03, 0.01};
  const MassProperties p = box_mass_properties(size, 1000);  // three distinct moments, y intermediate
  const Vec3 I{p.inertia[0], p.inertia[4], p.inertia[8]};
  RigidState s;
  s.q = {std::cos(0.3), std::sin(0.3) / std::sqrt(3.0), std::sin(0.3) / std::sqrt(3.0), std::sin(0.3) / std::sqrt(3.0)};
  const Vec3 wb0{0.02, 5.0, 0.02};  // near the unstable intermediate axis
  const auto R0 = rotation_of(s.q);
  for (int i = 0; i < 3; ++i) s.w[size_t(i)] = R0[size_t(3 * i)] * wb0[0] + R0[size_t(3 * i + 1)] * wb0[1] + R0[size_t(3 * i + 2)] * wb0[2];
  const double h = 1e-3;
  const double E0 = rigid_kinetic_energy(p.mass, p.inertia, s);
  const Vec3 L0 = rigid_angular_momentum(p.inertia, s);
  double E_prev = E0, worst_dE = 0, worst_dL = 0, worst_dir = 0, min_wy = 1e9;
  for (int k = 1; k <= 10000; ++k) {
    const RigidStepReport r = step_free_rigid(p.inertia, {0, 0, 0}, h, s);
    ASSERT_LT(r.newton_iterations, 10);
    const double E = rigid_kinetic_energy(p.mass, p.inertia, s);
    EXPECT_LE(E, E_prev * (1 + 1e-12)) << "energy grew at step " << k;
    E_prev = E;
    const Vec3 L = rigid_angular_momentum(p.inertia, s);
    worst_dE = std::max(worst_dE, std::abs(E / E0 - 1));
    worst_dL = std::max(worst_dL, std::abs(norm(L) / norm(L0) - 1));
    const double c = (L[0] * L0[0] + L[1] * L0[1] + L[2] * L0[2]) / (norm(L) * norm(L0));
    worst_dir = std::max(worst_dir, std::acos(std::min(1.0, c)));
    min_wy = std::min(min_wy, body_w(s)[1]);
    if (k == 2000) {  // against RK4 at 10 µs from the same start, 2 s in
      const Vec3 ref = rk4_euler(I, wb0, 2.0, 1e-5), got = body_w(s);
      for (int i = 0; i < 3; ++i) EXPECT_NEAR(got[size_t(i)], ref[size_t(i)], 2e-2 * norm(ref)) << "component " << i;
    }
  }
  EXPECT_LT(worst_dE, 1e-9) << "energy";
  EXPECT_LT(worst_dL, 1e-9) << "|L|";
  // The direction of L in space: the midpoint rule's local error is O((hω)³); 10,000 steps at
  // hω = 5e-3 bound its drift near 1e-4 rad.
  EXPECT_LT(worst_dir, 1e-3) << "direction of L (rad)";
  EXPECT_LT(min_wy, -4.0) << "the body tumbles: its spin about the intermediate axis reverses";
  std::printf("10 s: |dE/E| %.2e, |d|L|/|L|| %.2e, L direction %.2e rad\n", worst_dE, worst_dL, worst_dir);
}
