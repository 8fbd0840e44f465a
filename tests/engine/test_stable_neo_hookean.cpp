// Stable Neo-Hookean elements: zero force and energy at rest and under rigid motion, forces are
// −∂E/∂x (central differences), the small-strain tangent equals linear elasticity with the same
// (E, ν), the projected tangent is PSD even for inverted elements, and a squashed, inverted
// element is pushed back to positive volume.

#include <gtest/gtest.h>

#include <Eigen/Dense>

#include <algorithm>
#include <array>
#include <cmath>
#include <random>

#include "engine/model.hpp"
#include "engine/state.hpp"
#include "engine/tick.hpp"
#include "scene/compiled_scenario.hpp"
#include "scene/scenario_spec.hpp"
#include "tests/test_fem.hpp"
#include "tissue/fem_forces.hpp"
#include "tissue/mesh_prepare.hpp"
#include "tissue/stable_neo_hookean.hpp"
#include "tests/test_scenarios.hpp"

using namespace stroma;
using test_fem::dense_stiffness;
using test_fem::energy_and_force;

namespace {

std::shared_ptr<const Model> beam(ElementModel model) {
  ScenarioSpec s = test_scenarios::cantilever_dynamic();
  s.bodies[0].material.model = model;
  s.bodies[0].material.young_modulus = 1e4;
  s.bodies[0].material.poisson_ratio = 0.45;
  return compile_model(s);
}

std::vector<double> randomly_deformed(const FemModel& fem, double amount, unsigned seed) {
  std::mt19937 g(seed);
  std::uniform_real_distribution<double> u(-amount, amount);
  std::vector<double> x = fem.rest;
  for (double& v : x) v += u(g);
  return x;
}

}  // namespace

TEST(StableNeoHookean, ZeroForceAndEnergyAtRestAndUnderRigidMotion) {
  auto m = beam(ElementModel::StableNeoHookean);
  std::vector<double> f;
  EXPECT_NEAR(energy_and_force(m->fem, m->fem.rest, &f), 0.0, 1e-15);
  double fmax = 0;
  for (double v : f) fmax = std::max(fmax, std::abs(v));
  EXPECT_LT(fmax, 1e-12);
  // Rotate by 1 rad about a skew axis and translate.
  const Eigen::Matrix3d R = Eigen::AngleAxisd(1.0, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  std::vector<double> x(m->fem.rest.size());
  for (size_t i = 0; i < x.size(); i += 3) {
    const Eigen::Vector3d p = R * Eigen::Vector3d(m->fem.rest[i], m->fem.rest[i + 1], m->fem.rest[i + 2]);
    for (int k = 0; k < 3; ++k) x[i + k] = p[k] + 0.3 * (k + 1);
  }
  EXPECT_NEAR(energy_and_force(m->fem, x, &f), 0.0, 1e-12);
  fmax = 0;
  for (double v : f) fmax = std::max(fmax, std::abs(v));
  EXPECT_LT(fmax, 1e-9);
}

TEST(StableNeoHookean, ForceIsMinusTheEnergyGradient) {
  auto m = beam(ElementModel::StableNeoHookean);
  // Large deformation (strains of order one, some elements inverted).
  const std::vector<double> x = randomly_deformed(m->fem, 3e-3, 3);
  std::vector<double> f;
  energy_and_force(m->fem, x, &f);
  const double h = 1e-8;
  double worst = 0, scale = 0;
  for (size_t d = 0; d < x.size(); d += 7) {
    std::vector<double> xp = x, xm = x;
    xp[d] += h;
    xm[d] -= h;
    const double g = (energy_and_force(m->fem, xp, nullptr) - energy_and_force(m->fem, xm, nullptr)) / (2 * h);
    worst = std::max(worst, std::abs(-g - f[d]));
    scale = std::max(scale, std::abs(f[d]));
  }
  EXPECT_LT(worst, 1e-5 * scale) << "scale " << scale;
}

TEST(StableNeoHookean, SmallStrainTangentIsLinearElasticity) {
  auto snh = beam(ElementModel::StableNeoHookean);
  auto lin = beam(ElementModel::Linear);
  const Eigen::MatrixXd Ks = dense_stiffness(snh->fem, snh->fem.rest);
  const Eigen::MatrixXd Kl = dense_stiffness(lin->fem, lin->fem.rest);
  EXPECT_LT((Ks - Kl).norm(), 1e-10 * Kl.norm());
}

TEST(StableNeoHookean, ProjectedTangentIsSymmetricPsdEvenWhenInverted) {
  auto m = beam(ElementModel::StableNeoHookean);
  std::vector<double> x = randomly_deformed(m->fem, 4e-3, 11);
  int inverted = 0;
  auto p = [&](int32_t n) { return Vec3{x[3 * n], x[3 * n + 1], x[3 * n + 2]}; };
  for (const ElementParams& e : m->fem.elements)
    inverted += signed_volume(p(e.node[0]), p(e.node[1]), p(e.node[2]), p(e.node[3])) < 0;
  ASSERT_GT(inverted, 10);  // the test must see inverted elements
  const Eigen::MatrixXd K = dense_stiffness(m->fem, x);
  EXPECT_LT((K - K.transpose()).norm(), 1e-12 * K.norm());
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(K);
  EXPECT_GT(eig.eigenvalues().minCoeff(), -1e-9 * eig.eigenvalues().maxCoeff());
}

TEST(StableNeoHookean, SoftBeamUnderItsOwnWeightEndsWithNoElementInverted) {
  // The stability suite's failing corotational case: a 1 kPa beam hanging under gravity (ρgL ≈
  // E). Corotational ends with inverted elements; stable Neo-Hookean must not.
  auto run = [](ElementModel model) {
    ScenarioSpec s = test_scenarios::cantilever_dynamic();
    s.bodies[0].material.model = model;
    s.bodies[0].material.young_modulus = 1e3;
    s.bodies[0].material.poisson_ratio = 0.49;
    s.time_step = 1e-3;
    auto m = compile_model(s);
    State st = State::initial(*m);
    TickWorkspace w(*m);
    for (int k = 0; k < 300; ++k) tick(*m, st, w);
    int inverted = 0;
    auto p = [&](int32_t n) { return Vec3{st.tissue.x[3 * n], st.tissue.x[3 * n + 1], st.tissue.x[3 * n + 2]}; };
    for (const ElementParams& e : m->fem.elements)
      inverted += signed_volume(p(e.node[0]), p(e.node[1]), p(e.node[2]), p(e.node[3])) < 0;
    return inverted;
  };
  EXPECT_GT(run(ElementModel::Corotational), 0);  // the failure this material exists for
  EXPECT_EQ(run(ElementModel::StableNeoHookean), 0);
}

// The analytic eigensystem (twist, flip and scaling modes from the SVD of F) must reproduce the
// exact 9×9 Hessian for any F — stretched, sheared, inverted, with repeated singular values —
// with orthonormal modes; otherwise the projected tangent is not the projection of the tangent.
TEST(StableNeoHookean, AnalyticEigensystemReproducesTheExactHessian) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<std::array<double, 9>> Fs = {
      {1, 0, 0, 0, 1, 0, 0, 0, 1},       // rest: repeated σ = 1
      {1, 0, 0, 0, 1, 0, 0, 0, -1},      // mirrored: inverted, |σ| repeated
      {0.5, 0, 0, 0, 0.5, 0, 0, 0, 2},   // two equal σ
      {1e-3, 0, 0, 0, 1, 0, 0, 0, 1},    // nearly flat
  };
  for (double eps : {1e-14, 1e-12, 1e-8}) {  // rest plus round-off: nearly repeated eigenvalues
    std::array<double, 9> F = {1, 0, 0, 0, 1, 0, 0, 0, 1};
    for (double& f : F) f += eps * u(rng);
    Fs.push_back(F);
  }
  for (int t = 0; t < 40; ++t) {
    std::array<double, 9> F;
    for (double& f : F) f = u(rng) * 1.5;
    Fs.push_back(F);
  }
  const double lambda = 9.0, mu = 1.0;  // nu = 0.45
  for (const auto& F : Fs) {
    double H[81], values[9], modes[81];
    stable_neo_hookean_hessian(F.data(), lambda, mu, H);
    stable_neo_hookean_eigensystem(F.data(), lambda, mu, values, modes);
    Eigen::Matrix<double, 9, 9> Q, Hr = Eigen::Matrix<double, 9, 9>::Zero(), He;
    for (int m = 0; m < 9; ++m)
      for (int r = 0; r < 9; ++r) Q(r, m) = modes[9 * m + r];
    for (int m = 0; m < 9; ++m) Hr += values[m] * Q.col(m) * Q.col(m).transpose();
    for (int r = 0; r < 81; ++r) He(r / 9, r % 9) = H[r];
    EXPECT_LT((Q.transpose() * Q - Eigen::Matrix<double, 9, 9>::Identity()).norm(), 1e-9);
    EXPECT_LT((Hr - He).norm(), 1e-9 * (1 + He.norm())) << "F0 " << F[0] << " F4 " << F[4] << " F8 " << F[8];
    // And its eigenvalues are the Hessian's (sorted comparison).
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 9, 9>> eig(He);
    std::vector<double> a(values, values + 9);
    std::sort(a.begin(), a.end());
    for (int m = 0; m < 9; ++m) EXPECT_NEAR(a[m], eig.eigenvalues()(m), 1e-9 * (1 + He.norm()));
  }
}

// Damage scales λ and μ by (1 − d); a ruptured element (d = 1) has no material left and must
// contribute nothing — not a NaN from α = 1 + μ/λ' with λ' = 0.
TEST(StableNeoHookean, RupturedElementsContributeNothingAndStayFinite) {
  auto m = beam(ElementModel::StableNeoHookean);
  const std::vector<double> x = randomly_deformed(m->fem, 1e-3, 5);
  std::vector<float> damage(m->fem.elements.size(), 1.0f);
  damage[0] = 0.0f;  // one intact element: the others must add nothing to it
  std::vector<double> f(x.size(), 0.0), vals(9 * m->fem.pattern.col.size(), 0.0);
  ElasticPass p;
  p.x = x.data();
  p.force = f.data();
  p.kvals = vals.data();
  p.k_const = 1.0;
  p.damage = damage.data();
  const double e = elastic_pass(m->fem, p);
  EXPECT_TRUE(std::isfinite(e));
  for (double v : f) ASSERT_TRUE(std::isfinite(v));
  for (double v : vals) ASSERT_TRUE(std::isfinite(v));
  // Only element 0's four nodes feel a force; its energy is the whole energy.
  const auto& n0 = m->fem.elements[0].node;
  for (int32_t i = 0; i < m->fem.num_nodes; ++i) {
    const bool in0 = i == n0[0] || i == n0[1] || i == n0[2] || i == n0[3];
    if (!in0) EXPECT_EQ(f[3 * i] * f[3 * i] + f[3 * i + 1] * f[3 * i + 1] + f[3 * i + 2] * f[3 * i + 2], 0.0) << i;
  }
  damage[0] = 1.0f;
  std::fill(f.begin(), f.end(), 0.0);
  EXPECT_EQ(elastic_pass(m->fem, p), 0.0);
  for (double v : f) EXPECT_EQ(v, 0.0);
}
