// St. Venant–Kirchhoff and fibre-reinforced (Holzapfel–Gasser–Ogden type) tissue (issue 17 §3,
// §4).
//
// Asserted, and against what:
//  - St. Venant–Kirchhoff: P = ∂Ψ/∂F (central differences); the analytic eigensystem rebuilds
//    the exact Hessian (central differences of P) at stretched, compressed, sheared and
//    inverted F, including repeated singular values; zero energy and force under rigid rotation;
//    at small strain it is linear elasticity with the same (E, ν); its uniaxial nominal stress at
//    ν = 0 is μ(s³ − s), which turns over at s = 1/√3 — the known compression failure;
//  - the fibre term: forces are −∂E/∂x; its tangent is the finite difference of its forces; the
//    whole projected tangent is symmetric PSD; a rigid rotation gives zero force; a compressed
//    fibre carries nothing;
//  - a fibre-reinforced bar (stable Neo-Hookean matrix, ν = 0.45) under consistent end loads
//    follows the closed-form uniaxial stress–stretch curve along and across its fibres within
//    1 % (a homogeneous state, which linear tetrahedra represent exactly: what is left is the
//    static solver's tolerance);
//  - fibres from the mesh (VTU cell data) equal the same fibres given in the scenario;
//  - bad fibres are load errors naming the line and the field.

#include <gtest/gtest.h>

#include <Eigen/Dense>

#include <cmath>
#include <random>
#include <sstream>
#include <string>

#include "engine/model.hpp"
#include "engine/state.hpp"
#include "engine/static_run.hpp"
#include "engine/tick.hpp"
#include "scene/compiled_scenario.hpp"
#include "scene/scenario_spec.hpp"
#include "tests/test_fem.hpp"
#include "tests/test_meshes.hpp"
#include "tests/test_scenarios.hpp"
#include "tissue/fem_forces.hpp"
#include "tissue/fibre.hpp"
#include "tissue/input_error.hpp"
#include "tissue/st_venant_kirchhoff.hpp"
#include "tissue/stable_neo_hookean.hpp"

using namespace stroma;
using test_scenarios::write_temp;
using test_fem::dense_stiffness;
using test_fem::energy_and_force;

namespace {

/// Row-major 3×3 product.
void mul(const double* A, const double* B, double* C) {
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) C[3 * i + j] = A[3 * i] * B[j] + A[3 * i + 1] * B[3 + j] + A[3 * i + 2] * B[6 + j];
}

/// A rotation about a unit axis.
void rotation(const double* n, double angle, double* R) {
  const double c = std::cos(angle), s = std::sin(angle), t = 1 - c;
  const double x = n[0], y = n[1], z = n[2];
  const double M[9] = {t * x * x + c, t * x * y - s * z, t * x * z + s * y, t * x * y + s * z, t * y * y + c,
                       t * y * z - s * x, t * x * z - s * y, t * y * z + s * x, t * z * z + c};
  for (int k = 0; k < 9; ++k) R[k] = M[k];
}

/// Deformation gradients the tests sweep: stretched, compressed, sheared, repeated singular
/// values, nearly flat and inverted.
std::vector<std::array<double, 9>> test_gradients() {
  std::vector<std::array<double, 9>> out = {
      {1.2, 0, 0, 0, 0.9, 0, 0, 0, 0.95},   {0.6, 0.1, 0, 0, 0.7, 0.05, 0, 0, 0.8},
      {1.1, 0, 0, 0, 1.1, 0, 0, 0, 0.9},    {1, 0.4, 0.1, 0, 1, 0.3, 0, 0, 1},
      {0.3, 0, 0, 0, 1.0, 0, 0, 0, 1.0},    {1, 0, 0, 0, 1, 0, 0, 0, -0.4},
      {0.9, 0.2, -0.1, 0.1, 1.15, 0.05, -0.2, 0.1, 0.7}};
  std::mt19937 g(7);
  std::uniform_real_distribution<double> u(-0.3, 0.3);
  for (int k = 0; k < 5; ++k) {
    std::array<double, 9> F = {1, 0, 0, 0, 1, 0, 0, 0, 1};
    for (double& v : F) v += u(g);
    out.push_back(F);
  }
  return out;
}

constexpr double kLambda = 3.0e4, kMu = 1.2e4;  // Pa

}  // namespace

TEST(StVenantKirchhoff, StressIsTheEnergyGradient) {
  for (const auto& F0 : test_gradients()) {
    double P[9];
    st_venant_kirchhoff_stress(F0.data(), kLambda, kMu, P);
    for (int k = 0; k < 9; ++k) {
      auto F = F0;
      const double h = 1e-6;
      double Pd[9];
      F[k] += h;
      const double ep = st_venant_kirchhoff_stress(F.data(), kLambda, kMu, Pd);
      F[k] -= 2 * h;
      const double em = st_venant_kirchhoff_stress(F.data(), kLambda, kMu, Pd);
      EXPECT_NEAR(P[k], (ep - em) / (2 * h), 1e-6 * (std::abs(P[k]) + kMu));
    }
  }
}

TEST(StVenantKirchhoff, AnalyticEigensystemReproducesTheExactHessian) {
  for (const auto& F0 : test_gradients()) {
    // Exact Hessian by central differences of the (exact) stress.
    Eigen::Matrix<double, 9, 9> H;
    for (int c = 0; c < 9; ++c) {
      auto F = F0;
      const double h = 1e-6;
      double Pp[9], Pm[9];
      F[c] += h;
      st_venant_kirchhoff_stress(F.data(), kLambda, kMu, Pp);
      F[c] -= 2 * h;
      st_venant_kirchhoff_stress(F.data(), kLambda, kMu, Pm);
      for (int r = 0; r < 9; ++r) H(r, c) = (Pp[r] - Pm[r]) / (2 * h);
    }
    double values[9], modes[81];
    st_venant_kirchhoff_eigensystem(F0.data(), kLambda, kMu, values, modes);
    Eigen::Matrix<double, 9, 9> Hr = Eigen::Matrix<double, 9, 9>::Zero();
    for (int m = 0; m < 9; ++m) {
      Eigen::Map<const Eigen::Matrix<double, 9, 1>> q(modes + 9 * m);
      EXPECT_NEAR(q.norm(), 1.0, 1e-9);
      Hr += values[m] * q * q.transpose();
    }
    EXPECT_LT((Hr - H).norm(), 1e-6 * H.norm()) << "F = " << F0[0] << " " << F0[4] << " " << F0[8];
  }
}

TEST(StVenantKirchhoff, RigidRotationIsStressFreeAndSmallStrainIsLinearElasticity) {
  const double axis[3] = {0.48, 0.6, 0.64};
  double R[9], P[9];
  rotation(axis, 1.1, R);
  EXPECT_NEAR(st_venant_kirchhoff_stress(R, kLambda, kMu, P), 0.0, 1e-20 * kMu);
  for (double v : P) EXPECT_NEAR(v, 0.0, 1e-10 * kMu);
  // Small strain ε: P → σ(ε) = λ tr(ε) I + 2μ ε, to second order in ε.
  const double e = 1e-6;
  const double eps[9] = {e, 0.3 * e, 0, 0.3 * e, -0.5 * e, 0.2 * e, 0, 0.2 * e, 0.7 * e};
  double F[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  for (int k = 0; k < 9; ++k) F[k] += eps[k];
  st_venant_kirchhoff_stress(F, kLambda, kMu, P);
  const double tr = eps[0] + eps[4] + eps[8];
  for (int k = 0; k < 9; ++k) {
    const double sigma = 2 * kMu * eps[k] + (k % 4 == 0 ? kLambda * tr : 0.0);
    EXPECT_NEAR(P[k], sigma, 1e-5 * kMu * e);
  }
}

TEST(StVenantKirchhoff, UniaxialCompressionTurnsOverAtOneOverRootThree) {
  // ν = 0 (λ = 0): lateral stretch 1, nominal stress μ(s³ − s). Its resistance peaks at
  // s = 1/√3 and falls to zero as the element flattens: the model's known failure.
  const double mu = 1e4;
  double worst = 0, s_peak = 1, p_peak = 0;
  for (double s = 1.0; s > 0.0; s -= 0.001) {
    const double F[9] = {s, 0, 0, 0, 1, 0, 0, 0, 1};
    double P[9];
    st_venant_kirchhoff_stress(F, 0.0, mu, P);
    worst = std::max(worst, std::abs(P[0] - mu * (s * s * s - s)));
    if (-P[0] > p_peak) {
      p_peak = -P[0];
      s_peak = s;
    }
  }
  EXPECT_LT(worst, 1e-9 * mu);
  EXPECT_NEAR(s_peak, 1 / std::sqrt(3.0), 1e-3);
  const double flat[9] = {1e-9, 0, 0, 0, 1, 0, 0, 0, 1};
  double P[9];
  st_venant_kirchhoff_stress(flat, 0.0, mu, P);
  EXPECT_LT(std::abs(P[0]), 1e-8 * mu) << "a flattened element pushes back with (almost) nothing";
  // Stable Neo-Hookean with the same μ keeps pushing back at the same flattening.
  stable_neo_hookean_stress(flat, 0.0, mu, P);
  EXPECT_LT(P[0], -0.5 * mu);
}

namespace {

/// The dynamic cantilever's beam (SI, 0.1 m) with a hyperelastic material, optionally fibres.
std::shared_ptr<const Model> fibre_beam(ElementModel model, std::optional<FibreSpec> fibres) {
  ScenarioSpec s = test_scenarios::cantilever_dynamic();
  s.bodies[0].material.model = model;
  s.bodies[0].material.young_modulus = 1e4;
  s.bodies[0].material.poisson_ratio = 0.45;
  s.bodies[0].material.fibres = fibres;
  return compile_model(s);
}

FibreSpec fibres_along(Vec3 d, double k1, double k2) {
  FibreSpec f;
  const double n = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
  f.direction = {d[0] / n, d[1] / n, d[2] / n};
  f.k1 = k1;
  f.k2 = k2;
  return f;
}

/// The rest positions stretched by `s` along x about the origin, squeezed 1/√s across, plus a
/// seeded perturbation: the fibres along the beam are stretched.
std::vector<double> stretched(const FemModel& fem, double s, double noise, unsigned seed) {
  std::mt19937 g(seed);
  std::uniform_real_distribution<double> u(-noise, noise);
  std::vector<double> x = fem.rest;
  for (int32_t i = 0; i < fem.num_nodes; ++i) {
    x[3 * i] *= s;
    x[3 * i + 1] /= std::sqrt(s);
    x[3 * i + 2] /= std::sqrt(s);
  }
  for (double& v : x) v += u(g);
  return x;
}

}  // namespace

TEST(FibreModel, ForcesAreMinusTheEnergyGradientAndTheTangentIsTheirDerivative) {
  for (ElementModel model : {ElementModel::StableNeoHookean, ElementModel::StVenantKirchhoff}) {
    const auto with = fibre_beam(model, fibres_along({1, 0.3, 0.2}, 5e4, 8));
    const auto without = fibre_beam(model, std::nullopt);
    ASSERT_EQ(with->fem.fibres.size(), with->fem.elements.size());
    EXPECT_TRUE(without->fem.fibres.empty());
    const FemModel& fw = with->fem;
    const std::vector<double> x = stretched(fw, 1.15, 2e-4, 3);
    std::vector<double> f;
    const double e_with = energy_and_force(fw, x, &f);
    EXPECT_GT(e_with, energy_and_force(without->fem, x, nullptr)) << "stretched fibres store energy";
    // −∂E/∂x by central differences on a sample of DOFs.
    double fmax = 0;
    for (double v : f) fmax = std::max(fmax, std::abs(v));
    for (int32_t d = 0; d < fw.dofs(); d += 7) {
      std::vector<double> xp = x, xm = x;
      const double h = 1e-7;
      xp[d] += h;
      xm[d] -= h;
      const double grad = (energy_and_force(fw, xp, nullptr) - energy_and_force(fw, xm, nullptr)) / (2 * h);
      EXPECT_NEAR(f[d], -grad, 1e-5 * fmax) << "dof " << d;
    }
    // The fibre term's tangent (K with fibres − K without: the matrix's projection is the same
    // in both) against central differences of the fibre term's forces.
    const Eigen::MatrixXd Kf = dense_stiffness(fw, x) - dense_stiffness(without->fem, x);
    auto fibre_force = [&](const std::vector<double>& y) {
      std::vector<double> a, b;
      energy_and_force(fw, y, &a);
      energy_and_force(without->fem, y, &b);
      Eigen::VectorXd out(a.size());
      for (size_t k = 0; k < a.size(); ++k) out[k] = a[k] - b[k];
      return out;
    };
    std::mt19937 g(11);
    std::uniform_real_distribution<double> u(-1, 1);
    Eigen::VectorXd dx(fw.dofs());
    for (int k = 0; k < dx.size(); ++k) dx[k] = u(g);
    const double h = 1e-7;
    std::vector<double> xp = x, xm = x;
    for (int k = 0; k < dx.size(); ++k) {
      xp[k] += h * dx[k];
      xm[k] -= h * dx[k];
    }
    const Eigen::VectorXd df = -(fibre_force(xp) - fibre_force(xm)) / (2 * h);
    const Eigen::VectorXd Kdx = Kf * dx;
    EXPECT_LT((Kdx - df).norm(), 1e-5 * Kdx.norm());
    EXPECT_GT(Kdx.norm(), 0.0);
    // The whole tangent: symmetric and PSD after projection.
    const Eigen::MatrixXd K = dense_stiffness(fw, x);
    EXPECT_LT((K - K.transpose()).norm(), 1e-12 * K.norm());
    const double min_eig = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(K).eigenvalues().minCoeff();
    EXPECT_GT(min_eig, -1e-9 * K.norm());
  }
}

TEST(FibreModel, RigidRotationGivesZeroForceAndCompressedFibresCarryNothing) {
  const auto beam = fibre_beam(ElementModel::StableNeoHookean, fibres_along({1, 0, 0}, 5e4, 8));
  const FemModel& fem = beam->fem;
  const double axis[3] = {0.36, 0.48, 0.8};
  double R[9];
  rotation(axis, 2.0, R);
  std::vector<double> x(fem.rest.size());
  for (int32_t i = 0; i < fem.num_nodes; ++i)
    for (int r = 0; r < 3; ++r)
      x[3 * i + r] = R[3 * r] * fem.rest[3 * i] + R[3 * r + 1] * fem.rest[3 * i + 1] + R[3 * r + 2] * fem.rest[3 * i + 2] + 0.05;
  std::vector<double> f;
  EXPECT_NEAR(energy_and_force(fem, x, &f), 0.0, 1e-12);
  for (double v : f) EXPECT_NEAR(v, 0.0, 1e-9);
  // Compressed along the fibres: the fibre term adds nothing (energy equal to the matrix's).
  const auto matrix = fibre_beam(ElementModel::StableNeoHookean, std::nullopt);
  const std::vector<double> xc = stretched(fem, 0.9, 0.0, 1);
  std::vector<double> fc, fm;
  EXPECT_DOUBLE_EQ(energy_and_force(fem, xc, &fc), energy_and_force(matrix->fem, xc, &fm));
  for (size_t k = 0; k < fc.size(); ++k) EXPECT_DOUBLE_EQ(fc[k], fm[k]);
  // The fibre response of one F: P_f = 2ψ′ b⊗a, objective.
  const FibreParams fp{{1, 0, 0}, 5e4, 8};
  double F[9] = {1.2, 0, 0, 0, 0.9, 0, 0, 0, 0.9}, P[9] = {}, RF[9], RP[9] = {}, RPx[9];
  const double psi = fibre_stress(F, fp, P);
  mul(R, F, RF);
  EXPECT_NEAR(fibre_stress(RF, fp, RP), psi, 1e-12 * psi);
  mul(R, P, RPx);
  for (int k = 0; k < 9; ++k) EXPECT_NEAR(RP[k], RPx[k], 1e-9 * std::abs(P[0]));
}

TEST(FibreModel, TheResponseStaysSmoothWhereTheExponentialEnds) {
  // Past k2·x² = kFibreMaxExponent the energy continues as its Taylor expansion: ψ, ψ′ and ψ″
  // continuous there, ψ′ the derivative of ψ on both sides, and finite at absurd stretches.
  const FibreParams fp{{0, 0, 1}, 5e4, 8};
  const double xc = std::sqrt(kFibreMaxExponent / fp.k2);
  auto at = [&](double x) {  // the response at I4 = 1 + x (stretch along the fibre)
    const double s = std::sqrt(1 + x);
    const double F[9] = {1, 0, 0, 0, 1, 0, 0, 0, s};
    return fibre_response(F, fp, 1.0);
  };
  const double e = 1e-9;
  const FibreResponse below = at(xc - e), above = at(xc + e);
  EXPECT_NEAR(below.psi, above.psi, 1e-6 * below.psi);
  EXPECT_NEAR(below.d1, above.d1, 1e-6 * below.d1);
  EXPECT_NEAR(below.d2, above.d2, 1e-6 * below.d2);
  for (double x : {0.3, xc - 0.05, xc + 0.05, 3.0, 50.0}) {
    const double h = 1e-6 * x;
    EXPECT_NEAR(at(x).d1, (at(x + h).psi - at(x - h).psi) / (2 * h), 1e-6 * at(x).d1) << x;
    EXPECT_NEAR(at(x).d2, (at(x + h).d1 - at(x - h).d1) / (2 * h), 1e-6 * at(x).d2) << x;
  }
  EXPECT_TRUE(std::isfinite(at(1e6).psi));
  EXPECT_EQ(at(-0.2).psi, 0.0) << "a compressed fibre stores nothing";
}

namespace {

constexpr double kL = 0.1, kW = 0.02;   // bar 100 × 20 × 20 mm
constexpr double kE = 1e4, kNu = 0.45;  // matrix: stable Neo-Hookean, soft tissue
constexpr double kK1 = 5e4, kK2 = 8;    // fibres: tendon-like exponential stiffening

/// The bar as a gmsh 2.2 file, and as VTU with a fibre direction per cell.
std::string bar_msh() { return test_fem::gmsh22(test_meshes::box_mesh(10, 2, 2, {kL, kW, kW})); }

std::string bar_vtu(Vec3 fibre) {
  const TetMesh m = test_meshes::box_mesh(10, 2, 2, {kL, kW, kW});
  std::ostringstream o;
  o.precision(17);
  o << "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"1.0\">\n<UnstructuredGrid>\n"
    << "<Piece NumberOfPoints=\"" << m.nodes.size() << "\" NumberOfCells=\"" << m.tets.size() << "\">\n"
    << "<Points><DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">";
  for (const Vec3& p : m.nodes) o << p[0] << " " << p[1] << " " << p[2] << " ";
  o << "</DataArray></Points>\n<Cells><DataArray type=\"Int32\" Name=\"connectivity\" format=\"ascii\">";
  for (const Tet& t : m.tets) o << t[0] << " " << t[1] << " " << t[2] << " " << t[3] << " ";
  o << "</DataArray><DataArray type=\"Int32\" Name=\"offsets\" format=\"ascii\">";
  for (size_t e = 0; e < m.tets.size(); ++e) o << 4 * (e + 1) << " ";
  o << "</DataArray><DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">";
  for (size_t e = 0; e < m.tets.size(); ++e) o << "10 ";
  o << "</DataArray></Cells>\n<CellData><DataArray type=\"Float64\" Name=\"fibres\" NumberOfComponents=\"3\" "
       "format=\"ascii\">";
  for (size_t e = 0; e < m.tets.size(); ++e) o << fibre[0] << " " << fibre[1] << " " << fibre[2] << " ";
  o << "</DataArray></CellData>\n</Piece>\n</UnstructuredGrid>\n</VTKFile>\n";
  return o.str();
}

/// The bar pulled along x: the end x = 0 slides on its plane (x fixed), the origin is pinned
/// and two corners stop the rigid rotation about x — lateral contraction is free everywhere,
/// so a uniform end traction gives a homogeneous state.
std::string bar_yaml(const std::string& mesh, const std::string& fibres) {
  return "name: fibre_bar\ntime_step: 0.001\ngravity: [0, 0, 0]\n"
         "solver: {integrator: static, linear_solver: cholmod, static_tolerance: 1.0e-10}\n"
         "bodies:\n"
         "  - name: bar\n"
         "    mesh: " + mesh + "\n"
         "    material:\n"
         "      model: stable_neo_hookean\n"
         "      young_modulus: 10000\n"
         "      poisson_ratio: 0.45\n"
         "      density: 1000\n" + fibres +
         "    fixed:\n"
         "      - {box: {min: [-1.0e-6, -1, -1], max: [1.0e-6, 1, 1]}, axes: [x]}\n"
         "      - {box: {min: [-1.0e-6, -1.0e-6, -1.0e-6], max: [1.0e-6, 1.0e-6, 1.0e-6]}}\n"
         "      - {box: {min: [-1.0e-6, 0.019999, -1.0e-6], max: [1.0e-6, 0.020001, 1.0e-6]}, axes: [z]}\n"
         "run: {steps: 1}\n";
}

/// The closed-form uniaxial nominal stress P11 of the stable Neo-Hookean matrix (Lamé λ, μ)
/// with fibres of stiffness (k1, k2) along x (`along`) or across, at stretch s; the lateral
/// stretch t makes P22 = P33 = 0: μ + λ'·s·(s·t² − α) = 0.
double uniaxial_stress(double s, bool along) {
  const double lambda = kE * kNu / ((1 + kNu) * (1 - 2 * kNu)), mu = kE / (2 * (1 + kNu));
  const double lp = lambda + mu, alpha = 1 + mu / lp;
  const double t2 = (alpha - mu / (lp * s)) / s;
  double p = mu * s + lp * (s * t2 - alpha) * t2;
  if (along && s > 1) {  // I4 = s²: P_f = 2ψ′(s²)·s
    const double x = s * s - 1;
    p += 2 * kK1 * x * std::exp(kK2 * x * x) * s;
  }
  return p;
}

struct Pulled {
  double stretch;  // mean end-face stretch
  bool converged;
};

/// The bar under a consistent end traction P (nominal, Pa) along x.
Pulled pull(const Model& model, double P) {
  Model m = model;
  const FemModel& f = model.fem;
  std::fill(m.fem.f_ext.begin(), m.fem.f_ext.end(), 0.0);
  test_fem::add_end_traction(m.fem, kL, P);
  State s = State::initial(m);
  TickWorkspace w(m);
  StaticParameters from, to;
  from.load = 0;
  to.load = 1;
  const StaticOutcome out = solve_equilibrium(m, s, w, from, to);
  double stretch = 0;
  int n = 0;
  for (int32_t i = 0; i < f.num_nodes; ++i)
    if (std::abs(f.rest[3 * i] - kL) < 1e-9) {
      stretch += s.tissue.x[3 * i] / kL;
      ++n;
    }
  return {stretch / n, out.converged};
}

}  // namespace

TEST(FibreModel, UniaxialStressStretchAlongAndAcrossTheFibresMatchesTheClosedForm) {
  const std::string mesh = write_temp("fibre_bar.msh", bar_msh());
  auto bar = [&](const std::string& dir) {
    return compile_model(load_scenario(write_temp(
        "fibre_bar.yaml", bar_yaml(mesh, "      fibres: {direction: " + dir + ", k1: 50000, k2: 8}\n"))));
  };
  const auto along = bar("[1, 0, 0]");
  const auto across = bar("[0, 1, 0]");
  double worst = 0;
  for (double target : {1.03, 1.1, 1.2, 1.3}) {
    for (bool is_along : {true, false}) {
      const double P = uniaxial_stress(target, is_along);
      const Pulled r = pull(is_along ? *along : *across, P);
      ASSERT_TRUE(r.converged) << "stretch " << target;
      // The stress the closed form gives at the stretch the FEM reached, against the load.
      const double err = uniaxial_stress(r.stretch, is_along) / P - 1;
      EXPECT_LT(std::abs(err), 0.01) << (is_along ? "along" : "across") << " s = " << r.stretch << " (target " << target
                                     << ")";
      EXPECT_NEAR(r.stretch, target, 0.005 * target);
      worst = std::max(worst, std::abs(err));
    }
  }
  RecordProperty("worst_relative_stress_error", std::to_string(worst));
  // The fibres made the difference: at the same load the bar stretches far less along them.
  const double P = uniaxial_stress(1.2, false);
  EXPECT_LT(pull(*along, P).stretch - 1, 0.5 * (pull(*across, P).stretch - 1));
}

TEST(FibreModel, FibresFromTheMeshEqualTheSameFibresInTheScenario) {
  const auto from_mesh = compile_model(load_scenario(write_temp(
      "fibre_bar_vtu.yaml", bar_yaml(write_temp("fibre_bar.vtu", bar_vtu({0, 2, 0})),
                                     "      fibres: {direction: mesh, k1: 50000, k2: 8}\n"))));
  const auto given = compile_model(load_scenario(write_temp(
      "fibre_bar_given.yaml", bar_yaml(write_temp("fibre_bar.msh", bar_msh()), "      fibres: {direction: [0, 1, 0], k1: 50000, k2: 8}\n"))));
  ASSERT_EQ(from_mesh->fem.fibres.size(), given->fem.fibres.size());
  std::mt19937 g(5);
  std::uniform_real_distribution<double> u(-2e-3, 2e-3);
  std::vector<double> x = given->fem.rest;
  for (double& v : x) v += u(g);
  std::vector<double> fa, fb;
  const double ea = energy_and_force(from_mesh->fem, x, &fa);
  EXPECT_EQ(ea, energy_and_force(given->fem, x, &fb));
  EXPECT_EQ(fa, fb);
  EXPECT_GT(ea, 0);
}

TEST(FibreModel, BadFibresAreLoadErrorsNamingTheField) {
  const std::string mesh = write_temp("fibre_bar.msh", bar_msh());
  auto error_of = [&](const std::string& yaml) {
    try {
      compile_model(load_scenario(write_temp("bad_fibres.yaml", yaml)));
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  std::string e = error_of(bar_yaml(mesh, "      fibres: {direction: [0, 0, 0], k1: 50000, k2: 8}\n"));
  EXPECT_NE(e.find("fibres.direction"), std::string::npos) << e;
  EXPECT_NE(e.find("non-zero"), std::string::npos) << e;
  EXPECT_NE(e.find(":13:"), std::string::npos) << "the scenario line: " << e;
  e = error_of(bar_yaml(mesh, "      fibres: {direction: [1, 0, 0], k1: -5, k2: 8}\n"));
  EXPECT_NE(e.find("fibres.k1"), std::string::npos) << e;
  e = error_of(bar_yaml(mesh, "      fibres: {direction: [1, 0, 0], k1: 50000, k2: -1}\n"));
  EXPECT_NE(e.find("fibres.k2"), std::string::npos) << e;
  e = error_of(bar_yaml(mesh, "      fibres: {direction: along, k1: 50000}\n"));
  EXPECT_NE(e.find("'mesh'"), std::string::npos) << e;
  e = error_of(bar_yaml(mesh, "      fibres: {direction: mesh, k1: 50000}\n"));
  EXPECT_NE(e.find("has no fibre directions"), std::string::npos) << e;
  // Fibres on a corotational (linear) matrix: refused, naming the fibres.
  std::string yaml = bar_yaml(mesh, "      fibres: {direction: [1, 0, 0], k1: 50000}\n");
  yaml.replace(yaml.find("stable_neo_hookean"), 18, "corotational");
  e = error_of(yaml);
  EXPECT_NE(e.find("hyperelastic matrix"), std::string::npos) << e;
  EXPECT_NE(e.find("material.fibres"), std::string::npos) << e;
}
