/// \file accuracy_cantilever.cpp
/// Accuracy of the engine on the cantilever of refs/a and refs/d (tests/data/refs):
///  - static tip deflection, linear and corotational, against CalculiX C3D4 on the same mesh
///    and against the converged reference (−1.4735e-3 m);
///  - the mesh's own first bending frequency (lumped mass, by shift-invert power iteration with
///    CHOLMOD) against the C3D4 (consistent mass) and C3D10 reference (16.100 Hz);
///  - implicit Euler released under gravity: measured period and decay rate against the
///    backward-Euler prediction for that frequency.
/// Usage: stroma_accuracy_cantilever [--dt 0.001] MESH_TAG...   (tags like h5p000)

#include <chrono>
#include <cmath>
#include <fstream>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "engine/model.hpp"
#include "engine/state.hpp"
#include "engine/tick.hpp"
#include "runtime/headless_runner.hpp"
#include "scene/compiled_scenario.hpp"
#include "scene/scenario_spec.hpp"
#include "tissue/cholmod_solver.hpp"
#include "tissue/constraints.hpp"

using namespace stroma;

namespace {

const std::string kRoot = STROMA_SOURCE_DIR;
constexpr double kReference = -1.4735e-3;  // refs/a, converged C3D10
constexpr double kF1Reference = 16.100;    // refs/d

double c3d4_tip(const std::string& tag) {
  std::ifstream f(kRoot + "/tests/data/refs/results_C3D4.json");
  for (const auto& r : nlohmann::json::parse(f))
    if (r["job"] == "o1_" + tag + "mm") return r["uc"][1];
  return NAN;
}
double c3d4_f1(const std::string& tag) {
  std::ifstream f(kRoot + "/tests/data/refs/results_freq_C3D4.json");
  for (const auto& r : nlohmann::json::parse(f))
    if (r["job"] == "freq_o1_" + tag + "mm") return r["freqs_hz"][0];
  return NAN;
}

ScenarioSpec spec_for(const std::string& tag, const std::string& base) {
  ScenarioSpec s = load_scenario(kRoot + "/scenarios/" + base);
  s.bodies[0].mesh_path = kRoot + "/scenarios/meshes/beam_tet4_" + tag + "mm.msh";
  return s;
}

double static_tip(ScenarioSpec s, ElementModel model) {
  s.bodies[0].material.model = model;
  s.solver.integrator = Integrator::Static;
  s.solver.linear_solver = LinearSolverKind::Cholmod;
  const CompiledScenario sc_m = compile_scenario(s);
  const auto& m = sc_m.model;
  RunOptions o;
  o.progress = false;
  const RunResult r = run_headless(sc_m, o);
  return probe_displacement(*m, r.final_state, m->probes[0])[1];
}

/// Lowest bending frequency excited by gravity: power iteration on K⁻¹M started from the
/// gravity load (orthogonal to bending in z), on the free DOFs.
double bending_f1(const Model& m) {
  TimeStepper st(m.fem, m.stepper);
  std::vector<double> K;
  st.stiffness(State::initial(m).tissue, K);
  const FemModel& f = m.fem;
  project_constraints(f, K.data(), 1.0, false);
  CholmodSolver chol(f.pattern);
  chol.factor(K.data());
  std::vector<double> x(f.f_ext), y(x.size());
  double lambda = 0;
  for (int it = 0; it < 200; ++it) {
    for (int32_t i = 0; i < f.num_nodes; ++i)
      for (int k = 0; k < 3; ++k) y[3 * i + k] = dof_constrained(f, i, k) ? 0.0 : f.mass[i] * x[3 * i + k];
    chol.solve(y.data(), x.data());
    // Rayleigh-type estimate of ω² from two successive iterates.
    double num = 0, den = 0;
    for (int32_t i = 0; i < f.num_nodes; ++i)
      for (int k = 0; k < 3; ++k) {
        num += x[3 * i + k] * y[3 * i + k];
        den += f.mass[i] * x[3 * i + k] * x[3 * i + k];
      }
    const double l = num / den;  // x ≈ K⁻¹M x_prev = x_prev/ω², so num/den → ω²
    double nrm = std::sqrt(den);
    for (double& v : x) v /= nrm;
    if (it > 5 && std::fabs(l - lambda) < 1e-13 * std::fabs(l)) {
      lambda = l;
      break;
    }
    lambda = l;
  }
  return std::sqrt(lambda) / (2 * M_PI);
}

struct Dynamic {
  double period, period_theory, rate, rate_theory, wall_ms_per_tick;
};

Dynamic dynamic_response(ScenarioSpec s, double f1, double dt, double u_static) {
  s.time_step = dt;
  s.solver.tolerance = 1e-10;
  s.solver.max_iterations = 5000;
  auto m = compile_model(s);
  State st = State::initial(*m);
  TickWorkspace w(*m);
  const int steps = static_cast<int>(std::lround(0.4 / dt));
  std::vector<double> y(steps + 1, 0.0);
  const auto t0 = std::chrono::steady_clock::now();
  for (int k = 1; k <= steps; ++k) {
    tick(*m, st, w);
    y[k] = probe_displacement(*m, st, m->probes[0])[1] - u_static;
  }
  const double wall = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  std::vector<double> te, ae;
  for (int k = 1; k < steps; ++k)
    if ((y[k] > y[k - 1] && y[k] >= y[k + 1]) || (y[k] < y[k - 1] && y[k] <= y[k + 1])) {
      const double d = 0.5 * (y[k - 1] - y[k + 1]) / (y[k - 1] - 2 * y[k] + y[k + 1]);
      te.push_back((k + d) * dt);
      ae.push_back(std::fabs(y[k] - 0.25 * (y[k - 1] - y[k + 1]) * d));
    }
  Dynamic r{};
  const double w1 = 2 * M_PI * f1;
  r.period_theory = 2 * M_PI * dt / std::atan(w1 * dt);
  r.rate_theory = 0.5 * std::log(1 + w1 * w1 * dt * dt) / dt;
  r.wall_ms_per_tick = wall / steps;
  if (te.size() < 4) return r;
  r.period = 2.0 * (te.back() - te[1]) / static_cast<double>(te.size() - 2);
  double sx = 0, sy = 0, sxx = 0, sxy = 0;
  const int n = static_cast<int>(te.size()) - 1;
  for (size_t i = 1; i < te.size(); ++i) {
    sx += te[i]; sy += std::log(ae[i]); sxx += te[i] * te[i]; sxy += te[i] * std::log(ae[i]);
  }
  r.rate = -(n * sxy - sx * sy) / (n * sxx - sx * sx);
  return r;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Cantilever accuracy against CalculiX and backward-Euler theory"};
  std::vector<std::string> tags{"h5p000", "h3p333", "h2p500", "h2p000", "h1p667"};
  double dt = 0.001;
  bool dynamic = true;
  std::string pc = "warped_cholesky";
  app.add_option("tags", tags, "Mesh size tags (beam_tet4_<tag>mm.msh in scenarios/meshes)");
  app.add_option("--dt", dt, "Time step of the dynamic check")->capture_default_str();
  app.add_flag("!--no-dynamic", dynamic, "Skip the dynamic check");
  app.add_option("--preconditioner", pc, "CG preconditioner of the dynamic runs")
      ->check(CLI::IsMember({"jacobi", "block_jacobi", "warped_cholesky"}))->capture_default_str();
  CLI11_PARSE(app, argc, argv);

  fmt::print("| mesh | nodes | Stroma linear [mm] | CalculiX C3D4 [mm] | diff | Stroma corotational [mm] | error vs reference (corot.) |\n|---|---|---|---|---|---|---|\n");
  std::vector<std::pair<std::string, double>> f1s;
  for (const auto& tag : tags) {
    const ScenarioSpec s = spec_for(tag, "cantilever_static.yaml");
    const double ul = static_tip(s, ElementModel::Linear);
    const double uc = static_tip(s, ElementModel::Corotational);
    const double ref = c3d4_tip(tag);
    auto m = compile_model(s);
    fmt::print("| {} | {} | {:.6f} | {:.6f} | {:+.2e} | {:.6f} | {:+.2f} % |\n", tag, m->fem.num_nodes, -ul * 1e3,
               -ref * 1e3, (ul - ref) / ref, -uc * 1e3, 100 * (uc - kReference) / kReference);
  }
  if (!dynamic) return 0;
  fmt::print("\n| mesh | f1 Stroma (lumped) [Hz] | f1 C3D4 (consistent) [Hz] | error vs 16.100 Hz | period: measured / backward-Euler theory [ms] | decay rate: measured / theory [1/s] | ms per tick |\n|---|---|---|---|---|---|---|\n");
  for (const auto& tag : tags) {
    ScenarioSpec s = spec_for(tag, "cantilever_dynamic.yaml");
    s.solver.preconditioner = pc == "jacobi" ? Preconditioner::Jacobi
                              : pc == "block_jacobi" ? Preconditioner::BlockJacobi
                                                     : Preconditioner::WarpedCholesky;
    auto m = compile_model(s);
    const double f1 = bending_f1(*m);
    const double us = static_tip(s, ElementModel::Corotational);
    const Dynamic d = dynamic_response(s, f1, dt, us);
    fmt::print("| {} | {:.3f} | {:.3f} | {:+.1f} % | {:.3f} / {:.3f} ({:+.2f} %) | {:.3f} / {:.3f} ({:+.1f} %) | {:.3f} |\n", tag, f1,
               c3d4_f1(tag), 100 * (f1 - kF1Reference) / kF1Reference, d.period * 1e3,
               d.period_theory * 1e3, 100 * (d.period / d.period_theory - 1), d.rate, d.rate_theory,
               100 * (d.rate / d.rate_theory - 1), d.wall_ms_per_tick);
  }
  return 0;
}
