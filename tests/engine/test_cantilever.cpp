// Cantilever of ../shared/refs (copied into tests/data/refs): the engine against CalculiX
// linear tetrahedra (C3D4) on the very same meshes (static), and against the backward-Euler
// prediction for the mesh's own first frequency (dynamic).

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <string>
#include <vector>

#include <Eigen/Dense>
#include <nlohmann/json.hpp>

#include "engine/model.hpp"
#include "engine/state.hpp"
#include "engine/tick.hpp"
#include "runtime/headless_runner.hpp"
#include "scene/compiled_scenario.hpp"
#include "scene/scenario_spec.hpp"
#include "tests/test_scenarios.hpp"

using namespace stroma;

namespace {

const std::string kScenarios = std::string(STROMA_SOURCE_DIR) + "/scenarios/";

/// The CalculiX C3D4 tip-centre displacement (m) for the mesh of size tag `job`.
Vec3 c3d4_tip(const std::string& job) {
  std::ifstream f(std::string(STROMA_TEST_DATA) + "/refs/results_C3D4.json");
  const auto j = nlohmann::json::parse(f);
  for (const auto& r : j)
    if (r["job"] == job) return {r["uc"][0], r["uc"][1], r["uc"][2]};
  ADD_FAILURE() << "no reference " << job;
  return {0, 0, 0};
}

ScenarioSpec static_spec(const std::string& mesh, ElementModel model, LinearSolverKind ls) {
  ScenarioSpec s = load_scenario(kScenarios + "cantilever_static.yaml");
  s.bodies[0].mesh_path = kScenarios + "meshes/" + mesh;
  s.bodies[0].material.model = model;
  s.solver.linear_solver = ls;
  return s;
}

Vec3 run_static(const ScenarioSpec& spec) {
  const CompiledScenario sc_m = compile_scenario(spec);
  const auto& m = sc_m.model;
  RunOptions o;
  o.progress = false;
  const RunResult r = run_headless(sc_m, o);
  EXPECT_TRUE(r.static_converged);
  return probe_displacement(*m, r.final_state, m->probes.at(0));
}

struct MeshCase {
  const char* file;
  const char* job;
};
const MeshCase kMeshes[] = {{"beam_tet4_h5p000mm.msh", "o1_h5p000mm"},
                            {"beam_tet4_h3p333mm.msh", "o1_h3p333mm"},
                            {"beam_tet4_h2p500mm.msh", "o1_h2p500mm"}};

}  // namespace

// A correct linear-tet FEM has no discretisation gap to CalculiX C3D4 on the same mesh: the
// linear model must agree to the static solver's tolerance (1e-8 relative residual).
TEST(Cantilever, StaticLinearEqualsCalculixC3D4) {
  for (const auto& mc : kMeshes) {
    const Vec3 ref = c3d4_tip(mc.job);
    const Vec3 u = run_static(static_spec(mc.file, ElementModel::Linear, LinearSolverKind::Cholmod));
    EXPECT_NEAR(u[1], ref[1], 1e-5 * std::fabs(ref[1])) << mc.file;
    EXPECT_NEAR(u[2], ref[2], 1e-5 * std::fabs(ref[1])) << mc.file;
  }
}

// The corotational model (default) at 1.5 % tip deflection: within 0.5 % of C3D4 (the
// geometric nonlinearity it captures is ~0.1 % here).
TEST(Cantilever, StaticCorotationalWithinHalfPercentOfC3D4) {
  for (const auto& mc : kMeshes) {
    const Vec3 ref = c3d4_tip(mc.job);
    const Vec3 u = run_static(static_spec(mc.file, ElementModel::Corotational, LinearSolverKind::Cholmod));
    EXPECT_NEAR(u[1], ref[1], 5e-3 * std::fabs(ref[1])) << mc.file;
  }
}

// The same static problem through Newton + CG instead of CHOLMOD.
TEST(Cantilever, StaticWithCgMatchesCholmod) {
  const Vec3 ref = c3d4_tip("o1_h5p000mm");
  for (Preconditioner pc : {Preconditioner::Jacobi, Preconditioner::BlockJacobi, Preconditioner::WarpedCholesky}) {
    ScenarioSpec s = static_spec("beam_tet4_h5p000mm.msh", ElementModel::Linear, LinearSolverKind::CG);
    s.solver.preconditioner = pc;
    const Vec3 u = run_static(s);
    EXPECT_NEAR(u[1], ref[1], 1e-5 * std::fabs(ref[1])) << static_cast<int>(pc);
  }
}

namespace {

/// First bending frequency in y of the engine's own discretisation: generalized eigenproblem
/// K φ = ω² M φ on the free DOFs with the engine's lumped M and rest stiffness K; the mode
/// chosen is the one gravity (−y) excites most.
double engine_bending_omega(const Model& m) {
  TimeStepper st(m.fem, m.stepper);
  const State s0 = State::initial(m);
  std::vector<double> kv;
  st.stiffness(s0.tissue, kv);
  std::vector<int> dof_of(m.fem.dofs(), -1);
  int nf = 0;
  for (int i = 0; i < m.fem.num_nodes; ++i)
    for (int k = 0; k < 3; ++k)
      if (!((m.fem.constrained[i] >> k) & 1)) dof_of[3 * i + k] = nf++;
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(nf, nf);
  Eigen::VectorXd minv_sqrt(nf), g(nf);
  const BsrPattern& p = m.fem.pattern;
  for (int i = 0; i < p.n; ++i)
    for (int sl = p.row_ptr[i]; sl < p.row_ptr[i + 1]; ++sl) {
      const int j = p.col[sl];
      for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b) {
          const int r = dof_of[3 * i + a], c = dof_of[3 * j + b];
          if (r >= 0 && c >= 0) A(r, c) = A(c, r) = kv[9 * sl + 3 * a + b];  // upper-triangle storage
        }
    }
  for (int i = 0; i < m.fem.num_nodes; ++i)
    for (int k = 0; k < 3; ++k)
      if (dof_of[3 * i + k] >= 0) {
        minv_sqrt[dof_of[3 * i + k]] = 1.0 / std::sqrt(m.fem.mass[i]);
        g[dof_of[3 * i + k]] = m.fem.f_ext[3 * i + k];
      }
  A = minv_sqrt.asDiagonal() * A * minv_sqrt.asDiagonal();
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(A);
  const Eigen::VectorXd gm = minv_sqrt.asDiagonal() * g;  // load in mass-normalised coordinates
  double best = -1, omega = 0;
  for (int k = 0; k < 10; ++k) {
    const double part = std::pow(es.eigenvectors().col(k).dot(gm), 2) / es.eigenvalues()[k];
    if (part > best) {
      best = part;
      omega = std::sqrt(es.eigenvalues()[k]);
    }
  }
  return omega;
}

}  // namespace

// Released from rest under gravity, undamped: backward Euler multiplies the amplitude by
// 1/sqrt(1 + (ω dt)²) per step and advances the phase by atan(ω dt) per step
// (refs/d_cantilever_dynamic). The engine must reproduce both for its own ω.
TEST(Cantilever, ImplicitEulerPeriodAndDecayMatchBackwardEulerTheory) {
  ScenarioSpec spec = test_scenarios::cantilever_dynamic();
  spec.solver.tolerance = 1e-10;
  spec.solver.max_iterations = 2000;
  auto m = compile_model(spec);
  const double dt = m->time_step;
  const double w = engine_bending_omega(*m);
  // Sanity: lumped-mass linear tets on this coarse mesh are stiff (C3D4 consistent: 21.6 Hz).
  EXPECT_GT(w / (2 * M_PI), 15.0);
  EXPECT_LT(w / (2 * M_PI), 30.0);

  // Static deflection of the same mesh (the oscillation's centre).
  ScenarioSpec sspec = spec;
  sspec.solver.integrator = Integrator::Static;
  sspec.solver.linear_solver = LinearSolverKind::Cholmod;
  const CompiledScenario sc_ms = compile_scenario(sspec);
  const auto& ms = sc_ms.model;
  RunOptions so;
  so.progress = false;
  const double u_static = probe_displacement(*ms, run_headless(sc_ms, so).final_state, ms->probes[0])[1];

  State s = State::initial(*m);
  TickWorkspace ws(*m);
  const int steps = static_cast<int>(std::lround(0.35 / dt));
  std::vector<double> y(steps + 1, 0.0);
  for (int k = 1; k <= steps; ++k) {
    const TickReport r = tick(*m, s, ws);
    ASSERT_EQ(r.status, TickStatus::Ok) << "tick " << k;
    y[k] = probe_displacement(*m, s, m->probes[0])[1] - u_static;
  }
  // Extrema of the oscillation about the static value (skip the first half period, where
  // higher modes still contribute).
  std::vector<double> t_ext, a_ext;
  for (int k = 1; k < steps; ++k)
    if ((y[k] > y[k - 1] && y[k] >= y[k + 1]) || (y[k] < y[k - 1] && y[k] <= y[k + 1])) {
      // Parabolic interpolation of the extremum.
      const double d = 0.5 * (y[k - 1] - y[k + 1]) / (y[k - 1] - 2 * y[k] + y[k + 1]);
      t_ext.push_back((k + d) * dt);
      a_ext.push_back(std::fabs(y[k] - 0.25 * (y[k - 1] - y[k + 1]) * d));
    }
  ASSERT_GE(t_ext.size(), 8u);
  const double period = 2.0 * (t_ext.back() - t_ext[1]) / static_cast<double>(t_ext.size() - 2);
  const double wdt = w * dt;
  const double period_theory = 2 * M_PI * dt / std::atan(wdt);
  EXPECT_NEAR(period, period_theory, 0.01 * period_theory)
      << "f_engine = " << w / (2 * M_PI) << " Hz";
  // Decay rate per second from the amplitude envelope (log-linear fit over the extrema).
  double sx = 0, sy = 0, sxx = 0, sxy = 0;
  const int n = static_cast<int>(t_ext.size()) - 1;
  for (size_t i = 1; i < t_ext.size(); ++i) {
    const double lx = t_ext[i], ly = std::log(a_ext[i]);
    sx += lx; sy += ly; sxx += lx * lx; sxy += lx * ly;
  }
  const double slope = (n * sxy - sx * sy) / (n * sxx - sx * sx);
  const double rate_theory = 0.5 * std::log(1.0 + wdt * wdt) / dt;
  EXPECT_NEAR(-slope, rate_theory, 0.05 * rate_theory);
}

// Undamped implicit Euler is dissipative: the total energy (kinetic + elastic + potential of
// gravity) never increases from one tick to the next.
TEST(Cantilever, UndampedImplicitEulerNeverGainsEnergy) {
  for (ElementModel model : {ElementModel::Linear, ElementModel::Corotational}) {
    ScenarioSpec spec = test_scenarios::cantilever_dynamic();
    spec.solver.tolerance = 1e-10;
    spec.solver.max_iterations = 2000;
    spec.bodies[0].material.model = model;
    // Softer beam for the corotational case: large rotation (tip sags ~40 % of the length).
    if (model == ElementModel::Corotational) spec.bodies[0].material.young_modulus = 3e5;
    auto m = compile_model(spec);
    State s = State::initial(*m);
    TickWorkspace ws(*m);
    const TimeStepper& st = ws.stepper();
    auto total = [&] {
      return st.kinetic_energy(s.tissue) + st.elastic_energy(s.tissue) + st.external_potential(s.tissue);
    };
    double e_prev = total();
    double scale = 0, max_rise = -1e300;
    double max_sag = 0;
    for (int k = 0; k < 300; ++k) {
      ASSERT_NE(tick(*m, s, ws).status, TickStatus::NonFinite);
      const double e = total();
      scale = std::max(scale, std::fabs(e));
      max_rise = std::max(max_rise, e - e_prev);
      e_prev = e;
      max_sag = std::max(max_sag, -probe_displacement(*m, s, m->probes[0])[1]);
    }
    EXPECT_LE(max_rise, 1e-9 * scale) << (model == ElementModel::Linear ? "linear" : "corotational")
                                      << ", max sag " << max_sag;
    if (model == ElementModel::Corotational) {
      EXPECT_GT(max_sag, 0.02);  // really large rotation
    }
  }
}

// The warped rest-pose Cholesky preconditioner (z = R A₀⁻¹ Rᵀ r) gives the same trajectory as
// Jacobi-PCG, in a small fraction of the iterations, also when the beam rotates a lot (its
// per-node rotations keep the rest factor relevant).
TEST(Cantilever, WarpedCholeskyPreconditionerMatchesJacobiInFewIterations) {
  for (double E : {1e7, 3e5}) {
    auto run = [&](Preconditioner pc, int& max_iters) {
      ScenarioSpec spec = test_scenarios::cantilever_dynamic();
      spec.bodies[0].material.young_modulus = E;
      spec.solver.preconditioner = pc;
      spec.solver.tolerance = 1e-10;
      spec.solver.max_iterations = 5000;
      auto m = compile_model(spec);
      State s = State::initial(*m);
      TickWorkspace w(*m);
      max_iters = 0;
      for (int k = 0; k < 150; ++k) {
        const TickReport r = tick(*m, s, w);
        EXPECT_EQ(r.status, TickStatus::Ok);
        max_iters = std::max(max_iters, r.solve.iterations);
      }
      return probe_displacement(*m, s, m->probes[0]);
    };
    int it_j = 0, it_w = 0;
    const Vec3 uj = run(Preconditioner::Jacobi, it_j);
    const Vec3 uw = run(Preconditioner::WarpedCholesky, it_w);
    const double scale = std::fabs(uj[1]);
    EXPECT_GT(scale, 1e-4);
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(uw[k], uj[k], 1e-6 * scale) << "E = " << E;
    EXPECT_LT(it_w * 10, it_j) << "E = " << E << ": warped " << it_w << " vs Jacobi " << it_j;
  }
}

// Per-axis constraints: the beam stood on its end (gravity along −x) on a frictionless floor
// (x fixed on the face x = 0, sliding in y and z; two nodes remove the remaining rigid motions).
// A bar compressed by its own weight with free lateral expansion: u_x(L) = −ρ g L² / (2E)
// whatever ν.
TEST(Cantilever, SelfWeightOnASlidingBaseMatchesTheBarSolution) {
  ScenarioSpec s = static_spec("beam_tet4_h5p000mm.msh", ElementModel::Linear, LinearSolverKind::Cholmod);
  const double E = 1e5, rho = 1000, g = 9.81, L = 0.1;
  s.bodies[0].material.young_modulus = E;
  s.gravity = {-g, 0, 0};
  s.bodies[0].fixed.clear();
  NodeSelection floor;
  floor.box = BoxSpec{{-1e-6, -1, -1}, {1e-6, 1, 1}};
  floor.axes = 1;  // x only
  NodeSelection corner;
  corner.box = BoxSpec{{-1e-6, -1e-6, -1e-6}, {1e-6, 1e-6, 1e-6}};  // (0, 0, 0): all axes
  NodeSelection twist;
  twist.box = BoxSpec{{-1e-6, 0.01 - 1e-6, -1e-6}, {1e-6, 0.01 + 1e-6, 1e-6}};  // (0, 0.01, 0)
  twist.axes = 4;  // z: no rotation about x
  s.bodies[0].fixed = {floor, corner, twist};
  const CompiledScenario sc_m = compile_scenario(s);
  const auto& m = sc_m.model;
  RunOptions o;
  o.progress = false;
  const RunResult r = run_headless(sc_m, o);
  ASSERT_TRUE(r.static_converged);
  // Mean u_x over the top face x = L, and the base really slid (Poisson expansion).
  double ux = 0, spread = 0;
  int n = 0;
  for (int32_t i = 0; i < m->fem.num_nodes; ++i) {
    if (std::fabs(m->fem.rest[3 * i] - L) < 1e-9) {
      ux += r.final_state.tissue.x[3 * i] - L;
      ++n;
    }
    if (std::fabs(m->fem.rest[3 * i]) < 1e-9)
      spread = std::max(spread, std::fabs(r.final_state.tissue.x[3 * i + 1] - m->fem.rest[3 * i + 1]));
  }
  ASSERT_GT(n, 0);
  ux /= n;
  const double expected = -rho * g * L * L / (2 * E);
  EXPECT_NEAR(ux, expected, 0.02 * std::fabs(expected));
  EXPECT_GT(spread, 1e-8) << "the base must slide sideways (only x is fixed there)";
}
