// Tests for the linear-tetrahedron element kernels (tissue/fem_forces.cpp through TimeStepper)
// and the model build (tissue/fem_build.cpp): rigid-motion invariance of the corotational
// kernels and the known failure of the linear one, the patch test, the stiffness at rest
// (symmetry, exactly six rigid-body zero modes), forces as the exact energy gradient (also for
// an inverted element), the tangent against finite differences, lumped mass and gravity.

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "tests/test_meshes.hpp"
#include "tissue/fem_build.hpp"
#include "tissue/fem_forces.hpp"
#include "tissue/fem_model.hpp"
#include "tissue/material.hpp"
#include "tissue/mesh_prepare.hpp"
#include "tissue/time_stepper.hpp"
#include "tissue/tissue_state.hpp"

namespace stroma {
namespace {

using test_meshes::body_input;
using test_meshes::box_mesh;
using test_meshes::bsr_to_dense;
using test_meshes::cube6;
using test_meshes::single_tet;

constexpr double kE = 1e4;      // Young's modulus (Pa)
constexpr double kNu = 0.3;
constexpr double kRho = 1000;   // density (kg/m³)
constexpr double kL = 0.1;      // mesh size (m): forces scale as E·L², energies as E·L³

/// The element kernels, as (model, rotation) pairs.
struct Kernel {
  ElementModel model;
  RotationMethod rotation;
  const char* name;
};
constexpr Kernel kLinear{ElementModel::Linear, RotationMethod::Polar, "linear"};
constexpr Kernel kPolar{ElementModel::Corotational, RotationMethod::Polar, "corotational polar"};
constexpr Kernel kQr{ElementModel::Corotational, RotationMethod::QR, "corotational QR"};

/// A prepared mesh and its compiled single-body model (the model does not point into the mesh,
/// but keeping both together keeps the fixture simple).
struct Body {
  PreparedMesh mesh;
  FemModel model;
};

std::unique_ptr<Body> make_body(TetMesh mesh, Kernel k, double nu = kNu, double rho = kRho,
                                Vec3 gravity = {0, 0, 0}) {
  auto b = std::make_unique<Body>();
  b->mesh = prepare_mesh(std::move(mesh));
  b->model = build_fem_model({body_input(b->mesh, k.model, k.rotation, kE, nu, rho)}, gravity);
  return b;
}

/// Energy, force and stiffness of a model at arbitrary positions.
class Eval {
 public:
  explicit Eval(const FemModel& m) : ts_(m, StepperSettings{}), s_(TissueState::at_rest(m)) {}
  double energy(const std::vector<double>& x) {
    s_.x = x;
    return ts_.elastic_energy(s_);
  }
  std::vector<double> force(const std::vector<double>& x) {
    s_.x = x;
    std::vector<double> f(x.size());
    ts_.elastic_force(s_, f.data());
    return f;
  }
  Eigen::MatrixXd stiffness(const std::vector<double>& x) {
    s_.x = x;
    std::vector<double> k;
    ts_.stiffness(s_, k);
    return bsr_to_dense(ts_.model().pattern, k.data());
  }

 private:
  TimeStepper ts_;
  TissueState s_;
};

Eigen::Map<const Eigen::VectorXd> vec(const std::vector<double>& v) {
  return Eigen::Map<const Eigen::VectorXd>(v.data(), static_cast<Eigen::Index>(v.size()));
}

double max_abs(const std::vector<double>& v) {
  double m = 0;
  for (double a : v) m = std::max(m, std::abs(a));
  return m;
}

/// Largest nodal force magnitude.
double max_nodal_norm(const std::vector<double>& f) {
  double m = 0;
  for (size_t i = 0; i < f.size(); i += 3) m = std::max(m, std::hypot(f[i], f[i + 1], f[i + 2]));
  return m;
}

Eigen::Vector3d centroid(const std::vector<double>& X) {
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  for (size_t i = 0; i < X.size(); i += 3) c += Eigen::Vector3d(X[i], X[i + 1], X[i + 2]);
  return c / static_cast<double>(X.size() / 3);
}

/// x_i = Q·(X_i − c) + c + t for every node (c: centroid of the rest positions).
std::vector<double> rigid(const std::vector<double>& X, const Eigen::Matrix3d& Q,
                          const Eigen::Vector3d& t) {
  const Eigen::Vector3d c = centroid(X);
  std::vector<double> x(X.size());
  for (size_t i = 0; i < X.size(); i += 3) {
    const Eigen::Vector3d p = Q * (Eigen::Vector3d(X[i], X[i + 1], X[i + 2]) - c) + c + t;
    x[i] = p(0), x[i + 1] = p(1), x[i + 2] = p(2);
  }
  return x;
}

Eigen::Matrix3d rotation(double degrees, Eigen::Vector3d axis) {
  return Eigen::AngleAxisd(degrees * M_PI / 180.0, axis.normalized()).toRotationMatrix();
}

/// A large, generic deformation: rest positions jittered by up to `amp` (m) per coordinate,
/// then rotated by 120° about an oblique axis and translated.
std::vector<double> deformed(const std::vector<double>& X, double amp, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-amp, amp);
  std::vector<double> y = X;
  for (double& v : y) v += u(rng);
  return rigid(y, rotation(120, {0.3, -1.0, 0.7}), {0.02, 0.05, -0.03});
}

double total_volume(const TetMesh& m) {
  double v = 0;
  for (const Tet& t : m.tets) v += std::abs(signed_volume(m.nodes[t[0]], m.nodes[t[1]], m.nodes[t[2]], m.nodes[t[3]]));
  return v;
}

/// Strain energy density μ ε:ε + λ/2 tr²ε.
double energy_density(const Eigen::Matrix3d& eps, double nu) {
  const Lame l = lame_from_young_poisson(kE, nu);
  return l.mu * eps.cwiseProduct(eps).sum() + 0.5 * l.lambda * eps.trace() * eps.trace();
}

double von_mises(const Eigen::Matrix3d& eps, double nu) {
  const Lame l = lame_from_young_poisson(kE, nu);
  const Eigen::Matrix3d s = 2 * l.mu * eps + l.lambda * eps.trace() * Eigen::Matrix3d::Identity();
  const Eigen::Matrix3d dev = s - s.trace() / 3.0 * Eigen::Matrix3d::Identity();
  return std::sqrt(1.5 * dev.cwiseProduct(dev).sum());
}

/// Central-difference gradient of the energy, step h.
Eigen::VectorXd fd_gradient(Eval& ev, const std::vector<double>& x, double h) {
  Eigen::VectorXd g(x.size());
  std::vector<double> y = x;
  for (size_t d = 0; d < x.size(); ++d) {
    y[d] = x[d] + h;
    const double ep = ev.energy(y);
    y[d] = x[d] - h;
    const double em = ev.energy(y);
    y[d] = x[d];
    g(d) = (ep - em) / (2 * h);
  }
  return g;
}

/// Central-difference Jacobian of the force, ∂f/∂x (column d = derivative w.r.t. x_d).
Eigen::MatrixXd fd_force_jacobian(Eval& ev, const std::vector<double>& x, double h) {
  const auto n = static_cast<Eigen::Index>(x.size());
  Eigen::MatrixXd J(n, n);
  std::vector<double> y = x;
  for (Eigen::Index d = 0; d < n; ++d) {
    y[d] = x[d] + h;
    const Eigen::VectorXd fp = vec(ev.force(y));
    y[d] = x[d] - h;
    const Eigen::VectorXd fm = vec(ev.force(y));
    y[d] = x[d];
    J.col(d) = (fp - fm) / (2 * h);
  }
  return J;
}

/// Block-diagonal matrix with Q on each of the n 3×3 diagonal blocks.
Eigen::MatrixXd block_rotation(const Eigen::Matrix3d& Q, int n) {
  Eigen::MatrixXd B = Eigen::MatrixXd::Zero(3 * n, 3 * n);
  for (int i = 0; i < n; ++i) B.block<3, 3>(3 * i, 3 * i) = Q;
  return B;
}

struct NamedMesh {
  const char* name;
  TetMesh mesh;
};
std::vector<NamedMesh> test_meshes_list() {
  return {{"single tet", single_tet(kL)},
          {"cube (6 tets)", cube6(kL)},
          // 36 tetrahedra: four full batches of the 8-wide rotation kernel and a partial one.
          {"jittered 3x2x1 box (36 tets)", box_mesh(3, 2, 1, {1.5 * kL, kL, 0.5 * kL}, {0.3, -0.1, 0.2}, 0.05)}};
}

// ---------------------------------------------------------------------------------------------
// Rigid motions
// ---------------------------------------------------------------------------------------------

TEST(Element, CorotationalRigidMotionGivesZeroForceAndEnergy) {
  // Tolerances correspond to a spurious strain of 1e-9: force E·1e-9·L², energy E·(1e-9)²·V.
  const double ftol = 1e-9 * kE * kL * kL;
  struct Motion {
    const char* name;
    Eigen::Matrix3d Q;
    Eigen::Vector3d t;
  };
  const Motion motions[] = {
      {"translation", Eigen::Matrix3d::Identity(), {0.3, -0.2, 0.7}},
      {"90 deg oblique", rotation(90, {1, 2, 3}), {0.01, 0.02, -0.03}},
      {"170 deg oblique", rotation(170, {-1, 0.5, 2}), {-0.05, 0.0, 0.04}},
      {"180 deg about x", rotation(180, {1, 0, 0}), {0, 0, 0}}};
  for (const Kernel& k : {kPolar, kQr})
    for (NamedMesh& nm : test_meshes_list()) {
      auto b = make_body(nm.mesh, k);
      Eval ev(b->model);
      const double etol = kE * 1e-18 * total_volume(b->mesh.mesh);
      for (const Motion& mo : motions) {
        const std::vector<double> x = rigid(b->model.rest, mo.Q, mo.t);
        const std::vector<double> f = ev.force(x);
        const double e = ev.energy(x);
        EXPECT_LE(max_abs(f), ftol) << k.name << ", " << nm.name << ", " << mo.name;
        EXPECT_LE(std::abs(e), etol) << k.name << ", " << nm.name << ", " << mo.name;
      }
    }
}

TEST(Element, LinearModelGivesZeroForceUnderTranslationOnly) {
  auto b = make_body(cube6(kL), kLinear);
  Eval ev(b->model);
  const std::vector<double> x = rigid(b->model.rest, Eigen::Matrix3d::Identity(), {0.3, -0.2, 0.7});
  EXPECT_LE(max_abs(ev.force(x)), 1e-9 * kE * kL * kL);
  EXPECT_LE(ev.energy(x), kE * 1e-18 * total_volume(b->mesh.mesh));
}

TEST(Element, LinearModelFailsUnderRigidRotation) {
  // Why corotational exists: for a rotation Q by θ about n, the linear small strain
  // ε = sym(Q) − I = (cos θ − 1)(I − n nᵀ) is not zero, giving the spurious energy
  // 2V(μ + λ)(1 − cos θ)² and large forces (here at θ = 90°: ~2V(μ + λ), of order E·V).
  const Lame l = lame_from_young_poisson(kE, kNu);
  for (NamedMesh& nm : test_meshes_list()) {
    auto b = make_body(nm.mesh, kLinear);
    auto bc = make_body(nm.mesh, kPolar);
    Eval ev(b->model), evc(bc->model);
    for (double deg : {90.0, 170.0}) {
      const std::vector<double> x = rigid(b->model.rest, rotation(deg, {1, 2, 3}), {0.01, 0, 0});
      const double c = std::cos(deg * M_PI / 180.0);
      const double expected = 2 * total_volume(b->mesh.mesh) * (l.mu + l.lambda) * (1 - c) * (1 - c);
      EXPECT_NEAR(ev.energy(x), expected, 1e-10 * expected) << nm.name << ", " << deg;
      const double fmax = max_nodal_norm(ev.force(x));
      EXPECT_GT(fmax, 0.1 * kE * kL * kL) << nm.name << ", " << deg;
      // The corotational kernel at the same configuration: no force.
      EXPECT_LE(max_nodal_norm(evc.force(x)), 1e-9 * kE * kL * kL) << nm.name << ", " << deg;
      std::printf("  linear, %s, %.0f deg: max nodal force %.3g N (E L^2 = %.3g N)\n", nm.name,
                  deg, fmax, kE * kL * kL);
    }
  }
}

// ---------------------------------------------------------------------------------------------
// Patch test
// ---------------------------------------------------------------------------------------------

class ElementPatch : public ::testing::TestWithParam<double> {};

TEST_P(ElementPatch, LinearDisplacementFieldIsReproduced) {
  // u = A·X + c on every node of an irregular mesh with one interior node: every element has
  // the same uniform strain, so the interior node is in equilibrium (its elements' forces
  // cancel) and each element's strain equals sym(A).
  const double nu = GetParam();
  Eigen::Matrix3d A;
  A << 0.8, -0.3, 0.5, 0.2, -0.6, 0.1, -0.4, 0.7, 0.3;
  A *= 1e-3;
  const Eigen::Vector3d c(1e-3, -2e-3, 5e-4);
  const Eigen::Matrix3d eps = 0.5 * (A + A.transpose());
  const TetMesh mesh = box_mesh(2, 2, 2, {kL, kL, kL}, {0.3, -0.1, 0.2}, 0.05);
  const int32_t interior = test_meshes::box_node(2, 2, 1, 1, 1);
  const double V = total_volume(mesh);

  for (const Kernel& k : {kLinear, kPolar}) {
    auto b = make_body(mesh, k, nu);
    ASSERT_TRUE(b->mesh.reoriented.empty()) << "jitter must keep the mesh valid";
    Eval ev(b->model);
    std::vector<double> x = b->model.rest;
    for (size_t i = 0; i < x.size(); i += 3) {
      const Eigen::Vector3d X(x[i], x[i + 1], x[i + 2]);
      const Eigen::Vector3d p = X + A * X + c;
      x[i] = p(0), x[i + 1] = p(1), x[i + 2] = p(2);
    }
    const std::vector<double> f = ev.force(x);
    const double fscale = max_nodal_norm(f);
    ASSERT_GT(fscale, 0.0);
    const double fi = std::hypot(f[3 * interior], f[3 * interior + 1], f[3 * interior + 2]);
    EXPECT_LE(fi, 1e-10 * fscale) << k.name << ": interior node force";
    for (int d = 0; d < 3; ++d) {
      double sum = 0;
      for (size_t i = d; i < f.size(); i += 3) sum += f[i];
      EXPECT_LE(std::abs(sum), 1e-10 * fscale) << k.name << ": net force, component " << d;
    }

    const double expected_energy = V * energy_density(eps, nu);
    std::vector<double> vm(b->model.elements.size());
    element_von_mises(b->model, x.data(), vm.data());
    const double vm_expected = von_mises(eps, nu);
    if (k.model == ElementModel::Linear) {
      EXPECT_NEAR(ev.energy(x), expected_energy, 1e-10 * expected_energy);
      for (size_t e = 0; e < vm.size(); ++e)
        EXPECT_NEAR(vm[e], vm_expected, 1e-9 * vm_expected) << "element " << e;
    } else {
      // Corotational strain S − I differs from sym(A) at second order: relative O(|A|).
      const double tol = 5 * A.norm();
      EXPECT_NEAR(ev.energy(x), expected_energy, tol * expected_energy);
      for (size_t e = 0; e < vm.size(); ++e) {
        EXPECT_NEAR(vm[e], vm_expected, tol * vm_expected) << "element " << e;
        EXPECT_NEAR(vm[e], vm[0], 1e-9 * vm[0]) << "uniform F → identical strain, element " << e;
      }
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Element, ElementPatch, ::testing::Values(0.3, 0.45));

// ---------------------------------------------------------------------------------------------
// Stiffness at rest
// ---------------------------------------------------------------------------------------------

class ElementStiffness : public ::testing::TestWithParam<double> {};

TEST_P(ElementStiffness, AtRestIsSymmetricPsdWithSixRigidModes) {
  const double nu = GetParam();
  for (NamedMesh& nm : test_meshes_list()) {
    Eigen::MatrixXd K_linear;
    for (const Kernel& k : {kLinear, kPolar, kQr}) {
      auto b = make_body(nm.mesh, k, nu);
      Eval ev(b->model);
      const Eigen::MatrixXd K = ev.stiffness(b->model.rest);
      const double kmax = K.cwiseAbs().maxCoeff();
      ASSERT_GT(kmax, 0.0);
      EXPECT_LE((K - K.transpose()).cwiseAbs().maxCoeff(), 1e-12 * kmax) << k.name << ", " << nm.name;

      const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(0.5 * (K + K.transpose()));
      const Eigen::VectorXd lam = es.eigenvalues();  // ascending
      const double lmax = lam(lam.size() - 1);
      EXPECT_GE(lam(0), -1e-9 * lmax) << k.name << ", " << nm.name;
      int zeros = 0;
      for (Eigen::Index i = 0; i < lam.size(); ++i) zeros += std::abs(lam(i)) < 1e-9 * lmax;
      EXPECT_EQ(zeros, 6) << k.name << ", " << nm.name;
      // The 7th eigenvalue is a real deformation mode: far above round-off.
      EXPECT_GT(lam(6), 1e-6 * lmax) << k.name << ", " << nm.name;

      // The null space is the rigid motions: translations and infinitesimal rotations ω × X.
      const std::vector<double>& X = b->model.rest;
      const int n = b->model.num_nodes;
      for (int a = 0; a < 3; ++a) {
        Eigen::VectorXd t = Eigen::VectorXd::Zero(3 * n), r(3 * n);
        Eigen::Vector3d w = Eigen::Vector3d::Zero();
        w(a) = 1.0;
        for (int i = 0; i < n; ++i) {
          t(3 * i + a) = 1.0;
          r.segment<3>(3 * i) = w.cross(Eigen::Vector3d(X[3 * i], X[3 * i + 1], X[3 * i + 2]));
        }
        EXPECT_LE((K * t).norm(), 1e-12 * kmax * t.norm()) << k.name << ", " << nm.name;
        EXPECT_LE((K * r).norm(), 1e-12 * kmax * r.norm()) << k.name << ", " << nm.name;
      }
      // At rest R = I: every kernel has the same (linear) stiffness.
      if (k.model == ElementModel::Linear) K_linear = K;
      else EXPECT_LE((K - K_linear).cwiseAbs().maxCoeff(), 1e-12 * kmax) << k.name << ", " << nm.name;
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Element, ElementStiffness, ::testing::Values(0.3, 0.45));

TEST(Element, CorotationalStiffnessRotatesWithBody) {
  // Under a rigid rotation Q the warped stiffness is R·Ke·Rᵀ = (⊕Q)·K0·(⊕Q)ᵀ.
  const Eigen::Matrix3d Q = rotation(170, {-1, 0.5, 2});
  for (const Kernel& k : {kPolar, kQr})
    for (NamedMesh& nm : test_meshes_list()) {
      auto b = make_body(nm.mesh, k);
      Eval ev(b->model);
      const Eigen::MatrixXd K0 = ev.stiffness(b->model.rest);
      const Eigen::MatrixXd KQ = ev.stiffness(rigid(b->model.rest, Q, {0.1, 0.2, 0.3}));
      const Eigen::MatrixXd B = block_rotation(Q, b->model.num_nodes);
      EXPECT_LE((KQ - B * K0 * B.transpose()).cwiseAbs().maxCoeff(), 1e-12 * K0.cwiseAbs().maxCoeff())
          << k.name << ", " << nm.name;
    }
}

// ---------------------------------------------------------------------------------------------
// Force = −∇energy
// ---------------------------------------------------------------------------------------------

TEST(Element, ForceIsMinusEnergyGradientAtLargeRotation) {
  // The polar kernel's force −V·R·σ·g is the exact gradient of Σ V ψ(sym(RᵀF) − I) (the R
  // variation drops out because RᵀF is symmetric and commutes with σ); the linear one trivially.
  for (const Kernel& k : {kPolar, kLinear})
    for (NamedMesh& nm : test_meshes_list()) {
      auto b = make_body(nm.mesh, k);
      Eval ev(b->model);
      const std::vector<double> x = deformed(b->model.rest, 0.12 * kL, 77);
      const Eigen::VectorXd f = vec(ev.force(x));
      const Eigen::VectorXd g = fd_gradient(ev, x, 1e-6 * kL);
      const double rel = (f + g).norm() / f.norm();
      std::printf("  %s, %s: |f + grad E| / |f| = %.2e\n", k.name, nm.name, rel);
      EXPECT_LT(rel, 1e-6) << k.name << ", " << nm.name;
    }
}

TEST(Element, PolarForceIsEnergyGradientForInvertedElement) {
  // Push node 3 of a single tetrahedron through the opposite face (0, 1, 2): det F < 0.
  // Irving's rotation keeps R ∈ SO(3), the energy stays finite and smooth, force = −∇E.
  auto b = make_body(single_tet(kL), kPolar);
  Eval ev(b->model);
  std::vector<double> x = b->model.rest;
  const Eigen::Vector3d X0(x[0], x[1], x[2]), X1(x[3], x[4], x[5]), X2(x[6], x[7], x[8]),
      X3(x[9], x[10], x[11]);
  const Eigen::Vector3d n = (X1 - X0).cross(X2 - X0).normalized();  // points to node 3's side
  const double h = n.dot(X3 - X0);
  ASSERT_GT(h, 0);
  const Eigen::Vector3d x3 = X3 - 1.6 * h * n + 0.05 * kL * (X1 - X0).normalized();
  x[9] = x3(0), x[10] = x3(1), x[11] = x3(2);
  ASSERT_LT(signed_volume({x[0], x[1], x[2]}, {x[3], x[4], x[5]}, {x[6], x[7], x[8]},
                          {x[9], x[10], x[11]}), 0.0);

  const double e = ev.energy(x);
  EXPECT_TRUE(std::isfinite(e));
  EXPECT_GT(e, 0.0);
  const std::vector<double> fv = ev.force(x);
  for (double v : fv) ASSERT_TRUE(std::isfinite(v));
  const Eigen::VectorXd f = vec(fv);
  const Eigen::VectorXd g = fd_gradient(ev, x, 1e-6 * kL);
  const double rel = (f + g).norm() / f.norm();
  std::printf("  inverted tet, polar: |f + grad E| / |f| = %.2e\n", rel);
  EXPECT_LT(rel, 1e-6);
  // The force pushes node 3 back towards its side of the face.
  EXPECT_GT(n.dot(Eigen::Vector3d(fv[9], fv[10], fv[11])), 0.0);

  // The element rotation is proper (det R = +1).
  std::vector<double> rot(9);
  ElasticPass p;
  p.x = x.data();
  p.rotations = rot.data();
  elastic_pass(b->model, p);
  const Eigen::Matrix<double, 3, 3, Eigen::RowMajor> R(rot.data());
  EXPECT_NEAR(R.determinant(), 1.0, 1e-12);
  EXPECT_LE((R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff(), 1e-12);
}

// ---------------------------------------------------------------------------------------------
// Tangent stiffness
// ---------------------------------------------------------------------------------------------

TEST(Element, LinearTangentEqualsForceJacobian) {
  // f = −K (x − X) exactly: the FD Jacobian is −K at any state, up to round-off.
  for (NamedMesh& nm : test_meshes_list()) {
    auto b = make_body(nm.mesh, kLinear);
    Eval ev(b->model);
    const std::vector<double> x = deformed(b->model.rest, 0.12 * kL, 78);
    const Eigen::MatrixXd K = ev.stiffness(x);
    const Eigen::MatrixXd J = fd_force_jacobian(ev, x, 1e-6 * kL);
    const double rel = (K + J).cwiseAbs().maxCoeff() / K.cwiseAbs().maxCoeff();
    std::printf("  linear, %s: max|K + df/dx| / max|K| = %.2e\n", nm.name, rel);
    EXPECT_LT(rel, 1e-6) << nm.name;
  }
}

TEST(Element, CorotationalTangentIsExactAtRestAndUnderRigidRotation) {
  // Where σ = 0 (rest, or any rigid motion) the terms of the exact Hessian that involve ∂R
  // vanish, so the warped stiffness R·Ke·Rᵀ equals −∂f/∂x there.
  for (const Kernel& k : {kPolar, kQr})
    for (NamedMesh& nm : test_meshes_list()) {
      auto b = make_body(nm.mesh, k);
      Eval ev(b->model);
      for (const std::vector<double>& x :
           {b->model.rest, rigid(b->model.rest, rotation(170, {-1, 0.5, 2}), {0.1, 0, 0})}) {
        const Eigen::MatrixXd K = ev.stiffness(x);
        const Eigen::MatrixXd J = fd_force_jacobian(ev, x, 1e-6 * kL);
        const double rel = (K + J).cwiseAbs().maxCoeff() / K.cwiseAbs().maxCoeff();
        EXPECT_LT(rel, 1e-6) << k.name << ", " << nm.name;
      }
    }
}

TEST(Element, CorotationalTangentIsStiffnessWarpedNotExactHessian) {
  // Away from rigid motions the corotational tangent is the stiffness-warped approximation
  // R·Ke·Rᵀ: it omits the ∂R/∂x·σ terms, so it differs from the true Jacobian of the force.
  // (The true Jacobian is still symmetric, being the Hessian of the energy.) Documents the
  // approximation; if the exact Hessian is ever implemented this test must change.
  auto b = make_body(cube6(kL), kPolar);
  Eval ev(b->model);
  const Eigen::Matrix3d Q = rotation(60, {1, 1, 0});
  const Eigen::Vector3d c = centroid(b->model.rest);
  std::vector<double> x = b->model.rest;
  const Eigen::Matrix3d F = Q * Eigen::Vector3d(1.2, 0.9, 1.1).asDiagonal();
  for (size_t i = 0; i < x.size(); i += 3) {
    const Eigen::Vector3d p = F * (Eigen::Vector3d(x[i], x[i + 1], x[i + 2]) - c) + c;
    x[i] = p(0), x[i + 1] = p(1), x[i + 2] = p(2);
  }
  const Eigen::MatrixXd K = ev.stiffness(x);
  const Eigen::MatrixXd J = fd_force_jacobian(ev, x, 1e-6 * kL);
  const double kmax = K.cwiseAbs().maxCoeff();
  const double rel = (K + J).cwiseAbs().maxCoeff() / kmax;
  std::printf("  polar, stretched cube: max|K + df/dx| / max|K| = %.3f (warped approximation)\n", rel);
  EXPECT_GT(rel, 1e-3);
  EXPECT_LE((K - K.transpose()).cwiseAbs().maxCoeff(), 1e-12 * kmax);
  EXPECT_LE((J - J.transpose()).cwiseAbs().maxCoeff(), 1e-6 * kmax);
}

// ---------------------------------------------------------------------------------------------
// Mass and gravity
// ---------------------------------------------------------------------------------------------

TEST(Element, LumpedMassIsQuarterOfElementMassPerNode) {
  // Two bodies (node offsets), different densities, and one node no tetrahedron uses.
  TetMesh tet = single_tet(kL);
  tet.nodes.push_back({5.0, 5.0, 5.0});  // unused
  const TetMesh box = box_mesh(2, 2, 2, {kL, 2 * kL, kL}, {1, 0, 0}, 0.05);
  const PreparedMesh pbox = prepare_mesh(box), ptet = prepare_mesh(tet);
  const double rho_box = 1000, rho_tet = 1100;
  const FemModel m = build_fem_model(
      {body_input(pbox, kPolar.model, kPolar.rotation, kE, kNu, rho_box, "box"),
       body_input(ptet, kLinear.model, kLinear.rotation, kE, kNu, rho_tet, "tet")},
      {0, 0, 0});
  const int32_t nbox = static_cast<int32_t>(box.nodes.size());
  ASSERT_EQ(m.num_nodes, nbox + static_cast<int32_t>(tet.nodes.size()));

  std::vector<double> expected(m.num_nodes, 0.0);
  for (const Tet& t : box.tets) {
    const double v = signed_volume(box.nodes[t[0]], box.nodes[t[1]], box.nodes[t[2]], box.nodes[t[3]]);
    for (int a = 0; a < 4; ++a) expected[t[a]] += rho_box * v / 4;
  }
  for (const Tet& t : tet.tets) {
    const double v = signed_volume(tet.nodes[t[0]], tet.nodes[t[1]], tet.nodes[t[2]], tet.nodes[t[3]]);
    for (int a = 0; a < 4; ++a) expected[nbox + t[a]] += rho_tet * v / 4;
  }
  for (int32_t i = 0; i < m.num_nodes; ++i)
    EXPECT_NEAR(m.mass[i], expected[i], 1e-12 * expected[i]) << "node " << i;

  double mbox = 0, mtet = 0;
  for (int32_t i = 0; i < m.num_nodes; ++i) (i < nbox ? mbox : mtet) += m.mass[i];
  EXPECT_NEAR(mbox, rho_box * total_volume(box), 1e-12 * mbox);
  EXPECT_NEAR(mtet, rho_tet * total_volume(tet), 1e-12 * mtet);

  // Undistorted cube: Σ m = ρ L³ exactly (up to round-off).
  const PreparedMesh pcube = prepare_mesh(cube6(kL));
  const FemModel mc = build_fem_model({body_input(pcube, kPolar.model, kPolar.rotation, kE, kNu, rho_box)}, {0, 0, 0});
  double mcube = 0;
  for (double mi : mc.mass) mcube += mi;
  EXPECT_NEAR(mcube, rho_box * kL * kL * kL, 1e-12 * mcube);

  const int32_t unused = nbox + 4;
  EXPECT_EQ(m.mass[unused], 0.0);
  EXPECT_EQ(m.constrained[unused], 7);  // all three DOFs fixed
  EXPECT_EQ(m.inv_mass[unused], 0.0);
  for (int32_t i = 0; i < m.num_nodes; ++i)
    if (i != unused) {
      EXPECT_NEAR(m.inv_mass[i], 1.0 / m.mass[i], 1e-12 / m.mass[i]);
    }
}

TEST(Element, GravityForceIsMassTimesG) {
  const Vec3 g{0.3, -9.81, 1.2};
  const TetMesh box = box_mesh(2, 2, 2, {kL, kL, kL}, {0, 0, 0}, 0.05);
  auto b = make_body(box, kPolar, kNu, kRho, g);
  const FemModel& m = b->model;
  double M = 0;
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (int32_t i = 0; i < m.num_nodes; ++i) {
    M += m.mass[i];
    for (int d = 0; d < 3; ++d) {
      EXPECT_NEAR(m.f_ext[3 * i + d], m.mass[i] * g[d], 1e-12 * m.mass[i] * 10) << "node " << i;
      sum(d) += m.f_ext[3 * i + d];
    }
  }
  const double Mexp = kRho * total_volume(box);
  EXPECT_NEAR(M, Mexp, 1e-12 * Mexp);
  for (int d = 0; d < 3; ++d) EXPECT_NEAR(sum(d), Mexp * g[d], 1e-12 * Mexp * 10) << d;
}

}  // namespace
}  // namespace stroma
