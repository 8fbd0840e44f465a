#include "bench/accuracy/accuracy_suite.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <stdexcept>
#include <utility>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "bench/accuracy/quarter_block_mesh.hpp"
#include "bench/accuracy/thick_ring.hpp"
#include "engine/model.hpp"
#include "engine/simulation.hpp"
#include "engine/state.hpp"
#include "engine/static_run.hpp"
#include "engine/tick.hpp"
#include "runtime/headless_runner.hpp"
#include "scene/compiled_scenario.hpp"
#include "scene/scenario_spec.hpp"

namespace stroma {

namespace fs = std::filesystem;

namespace {

constexpr double kStaticReference = -1.4735e-3;  // refs/a: tip u_y (m), converged C3D10
constexpr double kF1Reference = 16.100;          // refs/d: first bending frequency (Hz)

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

std::string mesh_path(const std::string& src, const std::string& tag) {
  return src + "/scenarios/meshes/beam_tet4_h" + tag + "mm.msh";
}

std::string tag_mm(const std::string& tag) {  // "3p333" → "3.333"
  std::string s = tag;
  std::replace(s.begin(), s.end(), 'p', '.');
  return s;
}

/// Runs a static model `runs` times headless; the value is measure(final state) of the last run,
/// the time the median solve; fills p's value, ok, error and s_per_sim_s.
void timed_static_runs(const CompiledScenario& sc, int runs, const std::function<double(const RunResult&)>& measure,
                       AccuracyPoint& p) {
  std::vector<double> secs;
  for (int r = 0; r < runs; ++r) {
    RunOptions o;
    o.progress = false;
    o.metrics = false;
    const RunResult res = run_headless(sc, o);
    secs.push_back(res.wall_seconds);
    p.value = measure(res);
    p.ok = res.static_converged;
    if (!p.ok) p.failure = "static Newton did not converge";
  }
  p.error = std::abs(p.value - p.reference) / std::abs(p.reference);
  p.s_per_sim_s = median(secs);
}

// ---------------------------------------------------------------------------------------------
// Static tip deflection (refs/a)

/// ", locking_free: {...}" for a material, or "" (share < 0: plain elements). patch ≥ 2: the
/// volumetric strain averaged over element patches of at least that many tetrahedra
/// (F-bar-patch, its default element bulk share; `share` unused); 0: node smoothing with
/// stabilisation `share`.
std::string locking_free_yaml(double share, int patch = 0) {
  if (share < 0) return "";
  if (patch > 0) return fmt::format(", locking_free: {{method: element_patches, patch_elements: {}}}", patch);
  return fmt::format(", locking_free: {{method: node_smoothing, stabilisation: {:g}}}", share);
}
std::string locking_free_label(double share, int patch = 0) {
  if (share < 0) return "";
  if (patch > 0) return fmt::format(", F-bar-patch {}", patch);
  return fmt::format(", node-smoothed s {:g}", share);
}
/// The scenario's locking_free for (share, patch), as locking_free_yaml gives it.
LockingFreeSpec locking_free_spec(double share, int patch) {
  if (patch > 0) {
    LockingFreeSpec l = LockingFreeSpec::element_patches();
    l.patch_elements = patch;
    return l;
  }
  return LockingFreeSpec{"node_smoothing", share, {}};
}

struct StaticConfig {
  std::string mesh, sweep, solver;  // solver: "cholmod" or "cg 1e-6"
  ElementModel model = ElementModel::Corotational;
  double tolerance = 1e-6;
  double locking_free = -1;  ///< ≥ 0: node smoothing with this stabilisation
  int patch = 0;             ///< ≥ 2: element patches (F-bar-patch) instead of node domains
};

const char* model_name(ElementModel m) {
  return m == ElementModel::Linear             ? "linear"
         : m == ElementModel::StableNeoHookean  ? "stable NH"
         : m == ElementModel::StVenantKirchhoff ? "StVK"
                                                : "corot.";
}

AccuracyPoint run_static(const std::string& src, const StaticConfig& c, int runs) {
  ScenarioSpec spec = load_scenario(src + "/scenarios/cantilever_static.yaml");
  spec.bodies[0].mesh_path = mesh_path(src, c.mesh);
  spec.bodies[0].material.model = c.model;
  if (c.locking_free >= 0) spec.bodies[0].material.locking_free = locking_free_spec(c.locking_free, c.patch);
  if (c.solver == "cholmod") {
    spec.solver.linear_solver = LinearSolverKind::Cholmod;
  } else {
    spec.solver.linear_solver = LinearSolverKind::CG;
    spec.solver.preconditioner = Preconditioner::WarpedCholesky;
    spec.solver.tolerance = c.tolerance;
    spec.solver.max_iterations = 2000;
  }
  const CompiledScenario sc = compile_scenario(spec);
  const auto& m = sc.model;
  AccuracyPoint p;
  p.problem = "cantilever_static";
  p.sweep = c.sweep;
  p.label = fmt::format("h {} mm, {}{}, {}", tag_mm(c.mesh), model_name(c.model), locking_free_label(c.locking_free, c.patch),
                        c.solver == "cholmod" ? "CHOLMOD" : fmt::format("CG {:.0e}", c.tolerance));
  p.nodes = m->fem.num_nodes;
  p.reference = kStaticReference;
  timed_static_runs(sc, runs, [&](const RunResult& r) { return probe_displacement(*m, r.final_state, m->probes[0])[1]; }, p);
  return p;
}

// ---------------------------------------------------------------------------------------------
// Bonded near-incompressible block pressed 1 % (refs/c)

constexpr double kBlockForce = 0.3049;  // N, converged C3D10 (refs/c)

/// CalculiX C3D4 top force on the same mesh (what an exact linear-tet FEM gives); 0 if absent.
double block_c3d4_force(const std::string& src, const std::string& tag) {
  std::ifstream f(src + "/tests/data/refs/c_results_full_C3D4_uniform.json");
  for (const auto& r : nlohmann::json::parse(f))
    if (r["job"] == "cube_o1_h" + tag + "mm") return -r["top_rf"][2].get<double>();
  return 0;
}

struct BlockConfig {
  std::string mesh, sweep;
  bool linear = false;
  bool cholmod = true;
  double tolerance = 1e-8;  ///< CG tolerance inside each Newton step (Newton itself to 1e-10)
  double locking_free = -1; ///< ≥ 0: node smoothing with this stabilisation (nodal_smoothing.hpp)
  int patch = 0;            ///< ≥ 2: element patches (F-bar-patch) instead of node domains
};


AccuracyPoint run_block(const std::string& src, const BlockConfig& c, int runs) {
  // E 1e4, nu 0.49, no gravity; bottom z = 0 held, top z = a held with u_z = −0.5 mm.
  const std::string yaml = fmt::format(R"(name: block_compression
gravity: [0, 0, 0]
solver: {{integrator: static, linear_solver: {}, preconditioner: warped_cholesky, tolerance: {:.1e},
          max_iterations: 5000, static_tolerance: 1.0e-10}}
bodies:
  - name: block
    mesh: {}
    material: {{model: {}, young_modulus: 1.0e4, poisson_ratio: 0.49, density: 1000{}}}
    fixed:
      - box: {{min: [-1, -1, -1.0e-7], max: [1, 1, 1.0e-7]}}
      - box: {{min: [-1, -1, 0.0499999], max: [1, 1, 1]}}
)", c.cholmod ? "cholmod" : "cg", c.tolerance, src + "/scenarios/meshes/cube_tet4_h" + c.mesh + "mm.msh",
                                       c.linear ? "linear" : "corotational", locking_free_yaml(c.locking_free, c.patch));
  auto m = compile_model(parse_scenario(yaml, "block_compression (accuracy suite)", src));
  AccuracyPoint p;
  p.problem = "block_compression";
  p.sweep = c.sweep;
  p.label = fmt::format("h {} mm, {}{}, {}", tag_mm(c.mesh), c.linear ? "linear" : "corot.",
                        locking_free_label(c.locking_free, c.patch), c.cholmod ? "CHOLMOD" : fmt::format("CG {:.0e}", c.tolerance));
  p.nodes = m->fem.num_nodes;
  p.reference = kBlockForce;
  std::vector<double> secs;
  std::vector<double> f(m->fem.rest.size());
  for (int r = 0; r < runs; ++r) {
    State s = State::initial(*m);
    std::vector<int32_t> top;
    for (int32_t i = 0; i < m->fem.num_nodes; ++i)
      if (m->fem.rest[3 * i + 2] > 0.0499999) {
        s.tissue.x[3 * i + 2] -= 5.0e-4;  // constrained nodes stay where they are put
        top.push_back(i);
      }
    TickWorkspace w(*m);
    const auto t0 = std::chrono::steady_clock::now();
    const StaticResult sr = w.stepper().solve_static(s.tissue);
    secs.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
    p.ok = sr.converged;
    w.stepper().elastic_force(s.tissue, f.data());
    double fz = 0;
    for (int32_t i : top) fz += f[3 * i + 2];
    p.value = fz;  // the block pushes the platen up: the force needed to hold it
  }
  p.error = std::abs(p.value - p.reference) / p.reference;
  p.s_per_sim_s = median(secs);
  p.time_error = block_c3d4_force(src, c.mesh);  // (reused column: C3D4 force on this mesh)
  return p;
}

/// The tick cost of the same block at 1 kHz (issue 17 §2's "≤ 2× the tick cost of plain
/// corotational"): the block, bottom held, sagging under gravity from rest (in SI: 50 mm,
/// E 10 kPa, ν 0.49, ρ 1000), implicit Euler at 1 ms, CG with the warped Cholesky
/// preconditioner — the plain element's best configuration here — to 1e-6, no budget; the
/// median over `runs` (at least 3) of each run's tick p50 over 300 ticks, in ms.
double block_tick_ms(const std::string& src, const std::string& mesh, const std::string& locking_free, int runs) {
  const std::string yaml = fmt::format(R"(name: block_tick
gravity: [0, 0, -9.81]
time_step: 0.001
solver: {{integrator: implicit_euler, linear_solver: cg, preconditioner: warped_cholesky, tolerance: 1.0e-6,
          max_iterations: 2000}}
bodies:
  - name: block
    mesh: {}
    material: {{model: corotational, young_modulus: 1.0e4, poisson_ratio: 0.49, density: 1000,
               rayleigh_mass: 1.0, rayleigh_stiffness: 0.005{}}}
    fixed:
      - box: {{min: [-1, -1, -1.0e-7], max: [1, 1, 1.0e-7]}}
)", src + "/scenarios/meshes/cube_tet4_h" + mesh + "mm.msh", locking_free);
  auto m = compile_model(parse_scenario(yaml, "block_tick (accuracy suite)", src));
  std::vector<double> p50s;
  for (int r = 0; r < std::max(runs, 3); ++r) {
    Simulation sim(m);
    std::vector<double> t;
    for (int k = 0; k < 300; ++k) t.push_back(static_cast<double>(sim.advance().total_ns) * 1e-6);
    p50s.push_back(median(t));
  }
  return median(p50s);
}

// ---------------------------------------------------------------------------------------------
// Sphere indentation (refs/e)

constexpr double kIndentForce = 0.019604;  // N, Hertz with the bonded-layer correction

struct IndentConfig {
  double h0 = 1e-4;            // first cell at the contact point
  double stiffness = 1e9;      // penalty (Pa/m)
  bool linear = true;
  std::string sweep;
  double locking_free = -1;  // ≥ 0: node smoothing with this stabilisation
  int patch = 0;             // ≥ 2: element patches (F-bar-patch) instead of node domains
};

AccuracyPoint run_indentation(const std::string& src, const std::string& out_dir, const IndentConfig& c, int runs) {
  const double a = 0.05, H = 0.05, R = 0.005, d = 0.001;
  const std::string mesh = write_quarter_block((fs::path(out_dir) / "indentation_block.msh").string(), a, H, c.h0, 1.3);
  const std::string traj = (fs::path(out_dir) / "indentation_sphere.csv").string();
  {
    std::ofstream f(traj);
    f << fmt::format("t,x,y,z\n0,0,0,{:.17g}\n", H + R - d);
  }
  const std::string yaml = fmt::format(R"(name: indentation
gravity: [0, 0, 0]
solver: {{integrator: static, linear_solver: cholmod, static_tolerance: 1.0e-9, static_max_newton: 40}}
bodies:
  - name: block
    mesh: {}
    material: {{model: {}, young_modulus: 5000, poisson_ratio: 0.45, density: 1000{}}}
    fixed:
      - box: {{min: [-1, -1, -1.0e-9], max: [1, 1, 1.0e-9]}}
      - {{box: {{min: [-1.0e-9, -1, -1], max: [1.0e-9, 1, 1]}}, axes: [x]}}
      - {{box: {{min: [-1, -1.0e-9, -1], max: [1, 1.0e-9, 1]}}, axes: [y]}}
tools:
  - name: sphere
    script: {}
    shape: {{type: sphere, radius: 0.005}}
    contact: {{stiffness: {:g}}}
)", mesh, c.linear ? "linear" : "corotational", locking_free_yaml(c.locking_free, c.patch), traj, c.stiffness);
  const CompiledScenario sc = compile_scenario(parse_scenario(yaml, "indentation (accuracy suite)", src));
  const auto& m = sc.model;
  AccuracyPoint p;
  p.problem = "indentation";
  p.sweep = c.sweep;
  p.label = fmt::format("first cell {:g} mm, penalty {:.0e}, {}{}", c.h0 * 1e3, c.stiffness,
                        c.linear ? "linear" : "corot.", locking_free_label(c.locking_free, c.patch));
  p.nodes = m->fem.num_nodes;
  p.reference = kIndentForce;
  // Force = 4 × the quarter model's.
  timed_static_runs(sc, runs, [](const RunResult& r) { return 4.0 * r.final_tools.at(0).force[2]; }, p);
  return p;
}

// ---------------------------------------------------------------------------------------------
// First frequency from the released beam (refs/d)

struct DynamicConfig {
  std::string mesh = "3p333", sweep;
  double dt = 1e-3;
  double tolerance = 1e-6;
  int cap = 200;
  /// The engine's default redoes a capped tick in sub-steps; the cap sweep turns that off so
  /// that it measures what a capped solve itself costs in accuracy (solver.on_cg_cap).
  bool substep_on_cap = true;
  Preconditioner pc = Preconditioner::WarpedCholesky;
  WarmStart warm = WarmStart::Extrapolate;
  ElementModel model = ElementModel::Corotational;
  bool symplectic = false;
  std::string label;
};

ScenarioSpec dynamic_spec(const std::string& src, const DynamicConfig& c) {
  ScenarioSpec spec = load_scenario(src + "/scenarios/cantilever_dynamic.yaml");
  spec.bodies[0].mesh_path = mesh_path(src, c.mesh);
  spec.bodies[0].material.model = c.model;
  spec.time_step = c.dt;
  spec.solver.integrator = c.symplectic ? Integrator::SymplecticEuler : Integrator::ImplicitEuler;
  spec.solver.tolerance = c.tolerance;
  spec.solver.max_iterations = c.cap;
  spec.solver.on_cg_cap = c.substep_on_cap ? CapPolicy::Substep : CapPolicy::Continue;
  spec.solver.preconditioner = c.pc;
  spec.solver.warm_start = c.warm;
  return spec;
}

/// Tip u_y every tick over `duration` s; returns false if the state went bad. `secs`: wall time.
bool simulate(const Model& m, double duration, std::vector<double>& u, double* secs) {
  State s = State::initial(m);
  TickWorkspace w(m);
  const long ticks = std::lround(duration / m.time_step);
  u.clear();
  u.reserve(static_cast<size_t>(ticks));
  const auto t0 = std::chrono::steady_clock::now();
  for (long k = 0; k < ticks; ++k) {
    const TickReport& r = tick(m, s, w);
    if (r.status == TickStatus::NonFinite) return false;
    u.push_back(probe_displacement(m, s, m.probes[0])[1]);
  }
  *secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  for (double v : u)
    if (!std::isfinite(v) || std::abs(v) > 50 * std::abs(kStaticReference)) return false;
  return true;
}

/// Frequency from downward crossings of the mean, with hysteresis (higher modes and round-off
/// do not count as crossings). 0 if fewer than two crossings.
double crossing_frequency(const std::vector<double>& u, double dt) {
  if (u.size() < 8) return 0;
  double mean = 0;
  for (double v : u) mean += v;
  mean /= static_cast<double>(u.size());
  double var = 0;
  for (double v : u) var += (v - mean) * (v - mean);
  const double band = 0.2 * std::sqrt(var / static_cast<double>(u.size()));
  std::vector<double> t_cross;
  bool above = u[0] > mean;
  for (size_t i = 1; i < u.size(); ++i) {
    if (!above && u[i] > mean + band) above = true;
    if (above && u[i] < mean && u[i - 1] >= mean) {
      const double f = (u[i - 1] - mean) / (u[i - 1] - u[i]);  // linear interpolation
      t_cross.push_back((static_cast<double>(i - 1) + f) * dt);
      above = false;
    }
  }
  if (t_cross.size() < 2) return 0;
  return static_cast<double>(t_cross.size() - 1) / (t_cross.back() - t_cross.front());
}

AccuracyPoint run_dynamic(const std::string& src, const DynamicConfig& c, int runs, double duration) {
  auto m = compile_model(dynamic_spec(src, c));
  AccuracyPoint p;
  p.problem = "cantilever_dynamic";
  p.sweep = c.sweep;
  p.label = c.label;
  p.nodes = m->fem.num_nodes;
  p.reference = kF1Reference;
  std::vector<double> secs, u;
  for (int r = 0; r < runs; ++r) {
    double s = 0;
    p.ok = simulate(*m, duration, u, &s);
    if (!p.ok) {
      p.failure = fmt::format("diverged or rolled back (after {} of {} ticks)", u.size(),
                              std::lround(duration / c.dt));
      break;
    }
    secs.push_back(s);
  }
  p.value = p.ok ? crossing_frequency(u, c.dt) : 0;
  if (p.ok && p.value <= 0) p.failure = "no oscillation found";
  p.ok = p.ok && p.value > 0;
  p.error = p.ok ? std::abs(p.value - p.reference) / p.reference : 0;
  const double sec = median(secs);
  p.s_per_sim_s = sec / duration;
  p.ms_per_tick = 1e3 * sec / std::round(duration / c.dt);
  return p;
}

/// The largest step at which symplectic Euler stays bounded on this mesh over `duration` (the
/// measurement's length; bisection in log dt), times 0.95.
double largest_stable_symplectic_step(const std::string& src, const std::string& mesh, double duration) {
  double lo = 1e-6, hi = 2e-4;
  for (int it = 0; it < 7; ++it) {
    const double mid = std::sqrt(lo * hi);
    DynamicConfig c;
    c.mesh = mesh;
    c.symplectic = true;
    c.dt = mid;
    auto m = compile_model(dynamic_spec(src, c));
    std::vector<double> u;
    double s = 0;
    const bool stable = simulate(*m, duration, u, &s);
    (stable ? lo : hi) = mid;
  }
  return 0.95 * lo;
}

// ---------------------------------------------------------------------------------------------

/// Splits one CSV line (fields may be double-quoted, without embedded quotes).
std::vector<std::string> csv_fields(const std::string& line) {
  std::vector<std::string> out;
  std::string cur;
  bool quoted = false;
  for (char ch : line) {
    if (ch == '"') quoted = !quoted;
    else if (ch == ',' && !quoted) {
      out.push_back(cur);
      cur.clear();
    } else {
      cur += ch;
    }
  }
  out.push_back(cur);
  return out;
}

/// The Bullet peers' points, per problem (sweeps "Bullet FEM (peer)", "Bullet soft body (peer)").
struct PeerPoints {
  std::vector<AccuracyPoint> cantilever_static, cantilever_dynamic, block, indentation;
};

/// Runs the Bullet peer program (only the indentation problem with --only indentation; its
/// quick mode with --quick) and turns its CSV rows (out_dir/bullet_<problem>.csv) into points.
/// Static problems: the time is the peer's wall time to rest (it has no static solve).
PeerPoints run_peers(const AccuracyOptions& o) {
  PeerPoints pp;
  const std::string log = (fs::path(o.out_dir) / "bullet_peers.log").string();
  const std::string problem = o.only.empty() ? "all" : o.only == "block_compression" ? "block" : o.only;
  if (o.progress) fmt::print(stderr, "  peers: {} --problem {} (all: about {} minutes)\n", o.peer_program, problem, o.quick ? 13 : 27);
  const int rc = std::system(fmt::format("'{}' --problem {} {}--out '{}' > '{}' 2>&1", o.peer_program, problem,
                                         o.quick ? "--quick " : "", o.out_dir, log).c_str());
  if (rc != 0) fmt::print(stderr, "  peers: {} failed (exit {}); see {}\n", o.peer_program, rc, log);
  // Columns: peer,mesh,nodes,dt,quantity,value,error_vs_reference,ms_per_step,s_per_simulated_s,
  // wall_s,steps,same_mesh,notes (bench/peers/bullet_common.cpp).
  auto read = [&](const std::string& name, const std::function<void(const std::vector<std::string>&, AccuracyPoint&)>& to) {
    std::ifstream f(fs::path(o.out_dir) / ("bullet_" + name + ".csv"));
    std::string line;
    std::getline(f, line);  // header (no file: no rows)
    while (std::getline(f, line)) {
      const auto c = csv_fields(line);
      if (c.size() < 13) continue;
      // Bullet's neo-Hookean force is drawn beside Stroma's stable neo-Hookean (both against the
      // same reference). Given μ, λ as they are it is 27 % softer than linear elasticity at rest,
      // where Stroma's equals it; "matched" passes Smith et al.'s re-parametrised μ', λ' (docs).
      AccuracyPoint p;
      p.sweep = c[0].find("neohookean matched") != std::string::npos ? "Bullet FEM neo-Hookean matched (peer)"
                : c[0].find("neohookean") != std::string::npos      ? "Bullet FEM neo-Hookean (peer)"
                : c[0].rfind("A ", 0) == 0                          ? "Bullet FEM (peer)"
                                                                    : "Bullet soft body (peer)";
      p.same_problem = p.sweep != "Bullet FEM neo-Hookean (peer)";
      p.nodes = std::stoi(c[2]);
      p.value = std::stod(c[5]);
      p.ok = std::isfinite(p.value);
      p.error = p.ok ? std::abs(std::stod(c[6])) : 0;
      p.ms_per_tick = std::stod(c[7]);
      p.s_per_sim_s = std::stod(c[9]);
      p.failure = c[12];
      const double dt_ms = 1e3 * std::stod(c[3]);
      p.label = fmt::format("{} {}, dt {:g} ms", c[0].substr(2), c[1], dt_ms);
      to(c, p);
    }
  };
  read("cantilever", [&](const std::vector<std::string>& c, AccuracyPoint& p) {
    const bool is_static = c[4].rfind("static", 0) == 0;
    p.problem = is_static ? "cantilever_static" : "cantilever_dynamic";
    p.reference = is_static ? kStaticReference : kF1Reference;
    p.label = fmt::format("{} h {} mm{}", c[0].substr(2), c[1].substr(1),
                          std::stod(c[3]) != 1e-3 ? fmt::format(", dt {:g} ms", 1e3 * std::stod(c[3])) : "");
    if (!p.same_problem) p.label += " (softer material)";
    (is_static ? pp.cantilever_static : pp.cantilever_dynamic).push_back(p);
  });
  read("block", [&](const std::vector<std::string>& c, AccuracyPoint& p) {
    p.problem = "block_compression";
    p.reference = kBlockForce;
    p.time_error = std::stod(c[11]);  // (reused column: C3D4 force on this mesh, as for Stroma)
    pp.block.push_back(p);
  });
  read("indentation", [&](const std::vector<std::string>&, AccuracyPoint& p) {
    p.problem = "indentation";
    p.reference = kIndentForce;
    pp.indentation.push_back(p);
  });
  return pp;
}

/// Pareto-optimal: no other point is at least as fast and at least as accurate, and better in
/// one. Errors within 1e-4 of each other (relative) count as equal: solver round-off in the
/// 6th digit must not make a slower point "more accurate". Points that do not solve the stated
/// problem (same_problem false) take no part.
void mark_pareto(std::vector<AccuracyPoint>& pts) {
  auto no_worse = [](double a, double b) { return a <= b * (1 + 1e-4) + 1e-12; };
  for (AccuracyPoint& p : pts) {
    p.pareto = p.ok && p.same_problem;
    for (const AccuracyPoint& q : pts) {
      if (&q == &p || !q.ok || !q.same_problem) continue;
      const bool err_no_worse = no_worse(q.error, p.error), err_better = !no_worse(p.error, q.error);
      if (q.s_per_sim_s <= p.s_per_sim_s && err_no_worse && (q.s_per_sim_s < p.s_per_sim_s || err_better))
        p.pareto = false;
    }
  }
}


void write_csv(const std::string& path, const std::vector<AccuracyPoint>& pts) {
  std::ofstream f(path);
  f << "problem,sweep,label,nodes,value,reference,error,ms_per_tick,s_per_sim_s,pareto,ok,time_error\n";
  for (const auto& p : pts)
    f << fmt::format("{},\"{}\",\"{}\",{},{:.8g},{:.8g},{:.6g},{:.6g},{:.6g},{},{},{:.6g}\n", p.problem, p.sweep, p.label,
                     p.nodes, p.value, p.reference, p.error, p.ms_per_tick, p.s_per_sim_s, p.pareto ? 1 : 0,
                     p.ok ? 1 : 0, p.time_error);
}

// ---------------------------------------------------------------------------------------------
// Running: one function per problem, each returning its points (the peers' join in reporting).

/// Keeps a finished configuration's point and reports it on stderr (with progress on).
void record(std::vector<AccuracyPoint>& pts, AccuracyPoint p, const AccuracyOptions& o) {
  pts.push_back(std::move(p));
  const AccuracyPoint& q = pts.back();
  if (o.progress)
    fmt::print(stderr, "  {} | {}: {} error {:.3g}, {:.4g} s per sim. s\n", q.problem, q.label,
               q.ok ? "" : "FAILED (" + q.failure + ")", q.error, q.s_per_sim_s);
}

/// Sphere indentation: mesh grading at the contact, penalty stiffness, element model.
std::vector<AccuracyPoint> run_indentation_problem(const AccuracyOptions& o, int runs) {
  const std::string& src = o.source_dir;
  std::vector<AccuracyPoint> in;
  for (double h0 : o.quick ? std::vector<double>{4e-4, 2e-4} : std::vector<double>{8e-4, 4e-4, 2e-4, 1e-4})
    record(in, run_indentation(src, o.out_dir, {h0, 1e9, true, "mesh grading (linear, penalty 1e9)"}, runs), o);
  for (double k : o.quick ? std::vector<double>{1e8} : std::vector<double>{1e8, 1e10})
    record(in, run_indentation(src, o.out_dir, {2e-4, k, true, "penalty stiffness (first cell 0.2 mm)"}, runs), o);
  record(in, run_indentation(src, o.out_dir, {2e-4, 1e9, false, "element model (first cell 0.2 mm)"}, runs), o);
  for (double h0 : o.quick ? std::vector<double>{4e-4, 2e-4} : std::vector<double>{8e-4, 4e-4, 2e-4, 1e-4})
    record(in, run_indentation(src, o.out_dir, {h0, 1e9, false, "locking-free (corot., penalty 1e9)", 0.1}, runs), o);
  for (double h0 : o.quick ? std::vector<double>{4e-4} : std::vector<double>{8e-4, 4e-4, 2e-4, 1e-4})
    for (int k : o.quick ? std::vector<int>{16} : std::vector<int>{12, 16, 24}) {
      IndentConfig c{h0, 1e9, false, "locking-free: F-bar-patch (corot., penalty 1e9)", 1.0};
      c.patch = k;
      record(in, run_indentation(src, o.out_dir, c, runs), o);
    }
  return in;
}

/// Bonded block, nu = 0.49: mesh × element × linear solver, then the CG tolerance inside Newton.
std::vector<AccuracyPoint> run_block_compression_problem(const AccuracyOptions& o, int runs) {
  const std::string& src = o.source_dir;
  std::vector<AccuracyPoint> bl;
  for (const std::string& mesh : o.quick ? std::vector<std::string>{"6p250", "5p000", "3p333"}
                                         : std::vector<std::string>{"8p333", "6p250", "5p000", "3p333", "2p500"})
    for (bool linear : {false, true})
      for (bool cholmod : {true, false}) {
        if (o.quick && !cholmod) continue;
        record(bl, run_block(src, {mesh, cholmod ? "mesh x element (CHOLMOD)" : "mesh x element (CG 1e-8)", linear, cholmod}, runs), o);
      }
  // CG tolerance inside Newton (corotational, warped-Cholesky PCG): the Newton test (1e-10)
  // decides the answer; a loose inner tolerance costs Newton iterations instead.
  for (double tol : o.quick ? std::vector<double>{1e-2, 1e-4} : std::vector<double>{1e-2, 1e-4, 1e-6}) {
    BlockConfig c{"3p333", "CG tolerance (warped Cholesky PCG, h 3.333 mm)", false, false, tol};
    record(bl, run_block(src, c, runs), o);
  }
  // Locking-free (node smoothing, default stabilisation 0.1) on every mesh, and its
  // stabilisation swept on the coarsest two (0: pure NS-FEM, 1: only the bulk smoothed).
  for (const std::string& mesh : o.quick ? std::vector<std::string>{"8p333", "6p250", "3p333"}
                                         : std::vector<std::string>{"8p333", "6p250", "5p000", "3p333", "2p500"})
    for (bool cholmod : {true, false}) {
      if (o.quick && !cholmod) continue;
      BlockConfig c{mesh, cholmod ? "locking-free (CHOLMOD)" : "locking-free (CG 1e-8)", false, cholmod};
      c.locking_free = 0.1;
      record(bl, run_block(src, c, runs), o);
    }
  for (const char* mesh : {"8p333", "6p250"})
    for (double share : o.quick ? std::vector<double>{0.0, 1.0} : std::vector<double>{0.0, 0.05, 0.2, 0.5, 1.0}) {
      BlockConfig c{mesh, "locking-free stabilisation (CHOLMOD)", false, true};
      c.locking_free = share;
      record(bl, run_block(src, c, runs), o);
    }
  // §2's cost goal, beside its accuracy goal: the tick of the same block at 1 kHz, plain and
  // locking-free, each pair in one run (the ratio in the label; ms_per_tick holds the tick).
  for (const char* mesh : {"8p333", "6p250"}) {
    const double plain_ms = block_tick_ms(src, mesh, "", runs);
    // plain; node smoothing s 0.1; element patches at their defaults
    for (const auto& [share, patch] : {std::pair{-1.0, 0}, std::pair{0.1, 0}, std::pair{1.0, kDefaultPatchElements}}) {
      BlockConfig c{mesh, "tick at 1 kHz (warped CG 1e-6) vs plain", false, true};
      c.locking_free = share;
      c.patch = patch;
      AccuracyPoint p = run_block(src, c, runs);
      p.ms_per_tick = share < 0 ? plain_ms : block_tick_ms(src, mesh, locking_free_yaml(share, patch), runs);
      p.label += fmt::format(", tick p50 {:.3f} ms = {:.2f}x plain", p.ms_per_tick, p.ms_per_tick / plain_ms);
      record(bl, p, o);
    }
  }
  // The other method (docs/TISSUE.md, "Candidates"): F-bar-patch, the volumetric strain
  // averaged over disjoint patches of at least k tetrahedra (the elements keep the deviatoric
  // part and 2 % of the bulk).
  for (const std::string& mesh : o.quick ? std::vector<std::string>{"8p333", "6p250"}
                                         : std::vector<std::string>{"8p333", "6p250", "5p000", "3p333", "2p500"})
    for (int k : o.quick ? std::vector<int>{16} : std::vector<int>{2, 4, 8, 12, 16, 24, 32}) {
      BlockConfig c{mesh, "locking-free: F-bar-patch (CHOLMOD)", false, true};
      c.locking_free = 1.0;
      c.patch = k;
      record(bl, run_block(src, c, runs), o);
    }
  return bl;
}

/// Static deflection: mesh × element model (CHOLMOD), and warped-Cholesky PCG tolerances.
std::vector<AccuracyPoint> run_cantilever_static_problem(const AccuracyOptions& o, int runs) {
  const std::string& src = o.source_dir;
  std::vector<AccuracyPoint> st;
  const std::vector<std::string> static_meshes = o.quick ? std::vector<std::string>{"5p000", "3p333", "2p500", "2p000"}
                                                         : std::vector<std::string>{"5p000", "3p333", "2p500", "2p000", "1p667"};
  for (const std::string& mesh : static_meshes) {
    // Stable neo-Hookean is on its own sweep: its peer is Bullet's neo-Hookean force.
    for (ElementModel model : {ElementModel::Corotational, ElementModel::Linear, ElementModel::StableNeoHookean,
                               ElementModel::StVenantKirchhoff}) {
      if (o.quick && model != ElementModel::Corotational && mesh != "5p000" && mesh != "2p000") continue;
      const char* sweep = model == ElementModel::StableNeoHookean    ? "stable neo-Hookean (CHOLMOD)"
                          : model == ElementModel::StVenantKirchhoff ? "St. Venant-Kirchhoff (CHOLMOD)"
                                                                     : "mesh x element (CHOLMOD)";
      record(st, run_static(src, {mesh, sweep, "cholmod", model, 0}, runs), o);
    }
    // Locking-free: bending must not get worse than the plain corotational element's.
    record(st, run_static(src, {mesh, "locking-free (CHOLMOD)", "cholmod", ElementModel::Corotational, 0, 0.1}, runs), o);
    for (int k : o.quick ? std::vector<int>{16} : std::vector<int>{12, 16, 24}) {
      StaticConfig c{mesh, "locking-free: F-bar-patch (CHOLMOD)", "cholmod", ElementModel::Corotational, 0, 1.0};
      c.patch = k;
      record(st, run_static(src, c, runs), o);
    }
    for (double tol : o.quick ? std::vector<double>{1e-4} : std::vector<double>{1e-3, 1e-4, 1e-6})
      record(st, run_static(src, {mesh, "CG tolerance (warped Cholesky PCG)", "cg", ElementModel::Corotational, tol}, runs), o);
  }
  return st;
}

/// Dynamic, first frequency: mesh × dt (with the time step's share of the error), CG tolerance,
/// CG iteration cap, warm start, element model, symplectic Euler at its largest stable step.
std::vector<AccuracyPoint> run_cantilever_dynamic_problem(const AccuracyOptions& o, int runs) {
  const std::string& src = o.source_dir;
  std::vector<AccuracyPoint> dy;
  const double T = 0.3;
  const std::vector<std::string> meshes = o.quick ? std::vector<std::string>{"5p000", "3p333"}
                                                  : std::vector<std::string>{"5p000", "3p333", "2p500", "2p000"};
  const std::vector<double> dts = o.quick ? std::vector<double>{0.5e-3, 1e-3, 5e-3}
                                          : std::vector<double>{0.25e-3, 0.5e-3, 1e-3, 2e-3, 5e-3};
  for (const std::string& mesh : meshes)
    for (double dt : dts) {
      DynamicConfig c;
      c.mesh = mesh;
      c.dt = dt;
      c.sweep = "mesh x dt (implicit Euler)";
      c.label = fmt::format("h {} mm, dt {:g} ms", tag_mm(mesh), dt * 1e3);
      record(dy, run_dynamic(src, c, runs, T), o);
    }
  // The time integrator's own error: against the same mesh at the smallest step (the mesh's
  // error and backward Euler's period elongation have opposite signs and can cancel).
  for (AccuracyPoint& p : dy) {
    const AccuracyPoint* finest = nullptr;
    for (const AccuracyPoint& q : dy)
      if (q.ok && q.nodes == p.nodes && (!finest || q.s_per_sim_s > finest->s_per_sim_s)) finest = &q;
    if (p.ok && finest) p.time_error = std::abs(p.value - finest->value) / finest->value;
  }
  for (double tol : o.quick ? std::vector<double>{1e-2, 1e-4, 1e-8} : std::vector<double>{1e-2, 1e-3, 1e-4, 1e-6, 1e-8}) {
    DynamicConfig c;
    c.pc = Preconditioner::Jacobi;
    c.cap = 1000;
    c.tolerance = tol;
    c.sweep = "CG tolerance (Jacobi)";
    c.label = fmt::format("Jacobi CG {:.0e}", tol);
    record(dy, run_dynamic(src, c, runs, T), o);
  }
  for (int cap : o.quick ? std::vector<int>{5, 50} : std::vector<int>{5, 20, 50, 100, 400}) {
    DynamicConfig c;
    c.pc = Preconditioner::Jacobi;
    c.tolerance = 1e-10;
    c.cap = cap;
    c.substep_on_cap = false;
    c.sweep = "CG iteration cap (Jacobi)";
    c.label = fmt::format("Jacobi cap {}", cap);
    record(dy, run_dynamic(src, c, runs, T), o);
  }
  for (WarmStart ws : {WarmStart::Off, WarmStart::Previous, WarmStart::Extrapolate}) {
    if (o.quick && ws == WarmStart::Previous) continue;
    DynamicConfig c;
    c.pc = Preconditioner::Jacobi;
    c.cap = 1000;
    c.tolerance = 1e-6;
    c.warm = ws;
    c.sweep = "warm start (Jacobi CG 1e-6)";
    c.label = fmt::format("warm start {}", ws == WarmStart::Off ? "off" : ws == WarmStart::Previous ? "previous" : "extrapolate");
    record(dy, run_dynamic(src, c, runs, T), o);
  }
  for (ElementModel model : {ElementModel::Linear, ElementModel::StableNeoHookean, ElementModel::StVenantKirchhoff}) {
    DynamicConfig c;
    c.model = model;
    c.sweep = "element model";
    c.label = fmt::format("{} elements, h 3.333 mm, dt 1 ms",
                          model == ElementModel::Linear             ? "linear"
                          : model == ElementModel::StableNeoHookean ? "stable neo-Hookean"
                                                                    : "St. Venant-Kirchhoff");
    record(dy, run_dynamic(src, c, runs, T), o);
  }
  // Symplectic Euler needs ~100x more ticks (its stable step is ~0.01 ms here): the finest mesh
  // is left out to keep the full run near ten minutes.
  for (const std::string& mesh : o.quick ? std::vector<std::string>{"5p000"}
                                         : std::vector<std::string>{"5p000", "3p333", "2p500"}) {
    DynamicConfig c;
    c.mesh = mesh;
    c.symplectic = true;
    c.dt = largest_stable_symplectic_step(src, mesh, T);
    c.sweep = "symplectic Euler (largest stable dt)";
    c.label = fmt::format("symplectic h {} mm, dt {:.2g} ms", tag_mm(mesh), c.dt * 1e3);
    record(dy, run_dynamic(src, c, runs, T), o);
  }
  return dy;
}

// ---------------------------------------------------------------------------------------------
// Visco-elastic bar: the complex modulus under sinusoidal strain against the lecture's closed form.

constexpr double kViscoE0 = 1e4, kViscoG = 0.5, kViscoTau = 0.1;  // SLS: E0 10 kPa, g 0.5, tau 0.1 s

struct ViscoConfig {
  std::string sweep, label;
  double omega_tau = 1;
  int per_period = 32;
  std::string model = "corotational";
};

/// E0·[1 − g + g·iωτ/(1 + iωτ)]: the standard linear solid's complex modulus (storage, loss).
std::pair<double, double> sls_complex_modulus(double wt) {
  return {kViscoE0 * (1 - kViscoG + kViscoG * wt * wt / (1 + wt * wt)), kViscoE0 * kViscoG * wt / (1 + wt * wt)};
}

/// A 10 × 10 × 40 mm bar along z (2 × 2 × 8 cells), ν = 0, quasi-static (ρ = 1e-6 kg/m³: the
/// closed form has no inertia), its ends driven to ε(t) = ε₀ sin ωt. The stress is the top
/// face's elastic force over the area; E′ and E″ its projections on sin and cos over two
/// periods after 8τ of transient. Error: |E*_measured − E*| / |E*|.
AccuracyPoint run_visco(const std::string& out_dir, const ViscoConfig& c, int runs) {
  constexpr double a = 0.01, L = 0.04, eps0 = 1e-3;
  const std::string mesh = write_quarter_block((fs::path(out_dir) / "visco_bar.msh").string(), a, L, 0.005, 1.0);
  const double omega = c.omega_tau / kViscoTau, T = 2 * std::acos(-1.0) / omega, h = T / c.per_period;
  const std::string yaml = fmt::format(
      "name: visco_bar\ntime_step: {:.17g}\ngravity: [0, 0, 0]\nsolver: {{integrator: implicit_euler, linear_solver: cholmod}}\n"
      "bodies:\n  - name: bar\n    mesh: {}\n    material:\n      model: {}\n      young_modulus: {}\n"
      "      poisson_ratio: 0\n      density: 1.0e-6\n      viscoelastic: {{model: standard_linear_solid, g: {}, tau: {}}}\n"
      "    fixed:\n      - {{box: {{min: [-1, -1, -1.0e-6], max: [1, 1, 1.0e-6]}}, axes: [z]}}\n"
      "      - {{box: {{min: [-1.0e-6, -1.0e-6, -1.0e-6], max: [1.0e-6, 1.0e-6, 1.0e-6]}}}}\n"
      "      - {{box: {{min: [0.009999, -1.0e-6, -1.0e-6], max: [0.010001, 1.0e-6, 1.0e-6]}}, axes: [y]}}\n"
      "      - {{box: {{min: [-1, -1, 0.039999], max: [1, 1, 0.040001]}}, axes: [z]}}\n",
      h, mesh, c.model, kViscoE0, kViscoG, kViscoTau);
  const std::string yaml_path = (fs::path(out_dir) / "visco_bar.yaml").string();
  std::ofstream(yaml_path) << yaml;
  const auto m = compile_model(load_scenario(yaml_path));
  AccuracyPoint p;
  p.problem = "viscoelastic";
  p.sweep = c.sweep;
  p.label = c.label;
  p.nodes = m->fem.num_nodes;
  const auto [ref_storage, ref_loss] = sls_complex_modulus(c.omega_tau);
  p.reference = std::hypot(ref_storage, ref_loss);
  const int settle = c.per_period * static_cast<int>(std::ceil(8 * kViscoTau / T)), measure = 2 * c.per_period;
  std::vector<double> secs, f(m->fem.rest.size());
  double storage = 0, loss = 0;
  p.ok = true;
  for (int run = 0; run < runs && p.ok; ++run) {
    State s = State::initial(*m);
    TickWorkspace w(*m);
    double ss = 0, sc = 0, wall = 0;
    for (int k = 1; k <= settle + measure; ++k) {
      const double t = k * h, eps = eps0 * std::sin(omega * t);
      for (int32_t i = 0; i < m->fem.num_nodes; ++i) s.tissue.x[3 * i + 2] = m->fem.rest[3 * i + 2] * (1 + eps);
      const auto t0 = std::chrono::steady_clock::now();
      const TickReport& r = tick(*m, s, w);
      wall += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      if (r.status == TickStatus::NonFinite) {
        p.ok = false;
        p.failure = fmt::format("rolled back at tick {}", k);
        break;
      }
      if (k <= settle) continue;
      w.stepper().elastic_force(s.tissue, f.data());
      double fz = 0;
      for (int32_t i = 0; i < m->fem.num_nodes; ++i)
        if (std::abs(m->fem.rest[3 * i + 2] - L) < 1e-9) fz += f[3 * i + 2];
      const double sigma = -fz / (a * a);
      ss += sigma * std::sin(omega * t) * h;
      sc += sigma * std::cos(omega * t) * h;
    }
    secs.push_back(wall);
    storage = 2 * ss / (measure * h * eps0);
    loss = 2 * sc / (measure * h * eps0);
  }
  p.value = std::hypot(storage, loss);
  p.error = p.ok ? std::hypot(storage - ref_storage, loss - ref_loss) / p.reference : 0;
  const double sec = median(secs);
  p.s_per_sim_s = sec / ((settle + measure) * h);
  p.ms_per_tick = 1e3 * sec / (settle + measure);
  return p;
}

/// Steps per period at ωτ = 1 (the time step's error), the frequency over three decades, and
/// the element model (stable Neo-Hookean: the hyperelastic spring with corotational branches).
std::vector<AccuracyPoint> run_visco_problem(const AccuracyOptions& o, int runs) {
  std::vector<AccuracyPoint> vi;
  for (int n : o.quick ? std::vector<int>{8, 32} : std::vector<int>{4, 8, 16, 32, 64, 128})
    record(vi, run_visco(o.out_dir, {"steps per period (corotational, omega tau 1)", fmt::format("{} steps a period", n), 1.0, n}, runs), o);
  for (double wt : o.quick ? std::vector<double>{0.1, 10} : std::vector<double>{0.1, 10, 100})
    record(vi, run_visco(o.out_dir, {"omega tau (corotational, 32 steps a period)", fmt::format("omega tau {:g}", wt), wt, 32}, runs), o);
  for (int n : o.quick ? std::vector<int>{32} : std::vector<int>{8, 32})
    record(vi, run_visco(o.out_dir, {"stable neo-Hookean (omega tau 1)", fmt::format("{} steps a period", n), 1.0, n, "stable_neo_hookean"}, runs), o);
  return vi;
}

// ---------------------------------------------------------------------------------------------
// Fibre-reinforced bar: uniaxial stress–stretch along and across the fibres against the closed form.

constexpr double kFibreE = 1e4, kFibreNu = 0.45, kFibreK1 = 5e4, kFibreK2 = 8;  // tendon-like (docs/TISSUE.md)

/// The closed-form uniaxial nominal stress P_zz of the stable Neo-Hookean matrix (E 10 kPa,
/// ν 0.45) with HGO fibres (k1 50 kPa, k2 8) along the load (`along`) or across it, at stretch s:
/// the lateral stretch t makes the lateral stresses vanish, μ + λ′·s·(s·t² − α) = 0, with
/// λ′ = λ + μ, α = 1 + μ/λ′ (Smith et al.'s reparametrisation); a fibre along adds 2ψ′(s²)·s.
double fibre_uniaxial_stress(double s, bool along) {
  const double lambda = kFibreE * kFibreNu / ((1 + kFibreNu) * (1 - 2 * kFibreNu)), mu = kFibreE / (2 * (1 + kFibreNu));
  const double lp = lambda + mu, alpha = 1 + mu / lp;
  const double t2 = (alpha - mu / (lp * s)) / s;
  double p = mu * s + lp * (s * t2 - alpha) * t2;
  if (along && s > 1) {
    const double x = s * s - 1;
    p += 2 * kFibreK1 * x * std::exp(kFibreK2 * x * x) * s;
  }
  return p;
}

struct FibreConfig {
  std::string sweep, label;
  double stretch = 1.2;  ///< the target: the load is the closed form's stress there
  bool along = true;
  double h = 0.01;       ///< cell size of the 20 × 20 × 100 mm bar (m)
};

/// Solves `m` statically from rest to its full load `runs` times (at least once), timing each
/// (p.s_per_sim_s: the median); the last solve's state goes to `out`. A solve that does not
/// converge marks `p` failed and stops. Returns p.ok.
bool timed_static_solves(const Model& m, int runs, AccuracyPoint& p, State& out) {
  std::vector<double> secs;
  for (int run = 0; run < std::max(1, runs); ++run) {
    out = State::initial(m);
    TickWorkspace w(m);
    StaticParameters from, to;
    from.load = 0;
    to.load = 1;
    const auto t0 = std::chrono::steady_clock::now();
    const StaticOutcome o = solve_equilibrium(m, out, w, from, to);
    secs.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
    if (!o.converged) {
      p.ok = false;
      p.failure = "Newton did not converge";
      break;
    }
  }
  p.s_per_sim_s = median(secs);
  return p.ok;
}

/// The bar [0, 20 mm]² × [0, 100 mm] (cells of h, six tetrahedra each), fibres along z (along)
/// or x (across), its end z = 0 sliding on its plane, pulled at z = L by a consistent nominal
/// traction P(target stretch): a homogeneous state. Static Newton with CHOLMOD from rest in load
/// steps. value: the end face's mean stretch; reference: the target; error: the closed form's
/// stress at the stretch reached against the applied P (|P(s)/P − 1|).
AccuracyPoint run_fibre(const std::string& out_dir, const FibreConfig& c, int runs) {
  constexpr double a = 0.02, L = 0.1;
  const std::string mesh =
      write_quarter_block((fs::path(out_dir) / fmt::format("fibre_bar_{}.msh", std::lround(c.h * 1e4))).string(), a, L, c.h, 1.0);
  const std::string yaml = fmt::format(
      "name: fibre_bar\ntime_step: 0.001\ngravity: [0, 0, 0]\n"
      "solver: {{integrator: static, linear_solver: cholmod, static_tolerance: 1.0e-10}}\n"
      "bodies:\n  - name: bar\n    mesh: {}\n    material:\n      model: stable_neo_hookean\n"
      "      young_modulus: {}\n      poisson_ratio: {}\n      density: 1000\n"
      "      fibres: {{direction: {}, k1: {}, k2: {}}}\n"
      "    fixed:\n      - {{box: {{min: [-1, -1, -1.0e-6], max: [1, 1, 1.0e-6]}}, axes: [z]}}\n"
      "      - {{box: {{min: [-1.0e-6, -1.0e-6, -1.0e-6], max: [1.0e-6, 1.0e-6, 1.0e-6]}}}}\n"
      "      - {{box: {{min: [0.019999, -1.0e-6, -1.0e-6], max: [0.020001, 1.0e-6, 1.0e-6]}}, axes: [y]}}\n"
      "run: {{steps: 1}}\n",
      mesh, kFibreE, kFibreNu, c.along ? "[0, 0, 1]" : "[1, 0, 0]", kFibreK1, kFibreK2);
  const std::string yaml_path = (fs::path(out_dir) / "fibre_bar.yaml").string();
  std::ofstream(yaml_path) << yaml;
  Model m = *compile_model(load_scenario(yaml_path));
  const double P = fibre_uniaxial_stress(c.stretch, c.along);
  std::fill(m.fem.f_ext.begin(), m.fem.f_ext.end(), 0.0);
  for (const Tri& t : m.fem.bodies[0].boundary) {  // P × a third of each end triangle's area
    bool end = true;
    for (int32_t n : t) end &= std::abs(m.fem.rest[3 * n + 2] - L) < 1e-9;
    if (!end) continue;
    const double* A = &m.fem.rest[3 * t[0]];
    const double* B = &m.fem.rest[3 * t[1]];
    const double* C = &m.fem.rest[3 * t[2]];
    const double u[3] = {B[0] - A[0], B[1] - A[1], B[2] - A[2]}, v[3] = {C[0] - A[0], C[1] - A[1], C[2] - A[2]};
    const double area = 0.5 * std::sqrt(std::pow(u[1] * v[2] - u[2] * v[1], 2) + std::pow(u[2] * v[0] - u[0] * v[2], 2) +
                                        std::pow(u[0] * v[1] - u[1] * v[0], 2));
    for (int32_t n : t) m.fem.f_ext[3 * n + 2] += P * area / 3.0;
  }
  AccuracyPoint p;
  p.problem = "fibres";
  p.sweep = c.sweep;
  p.label = c.label;
  p.nodes = m.fem.num_nodes;
  p.reference = c.stretch;
  State s;
  if (timed_static_solves(m, runs, p, s)) {
    double stretch = 0;
    int n = 0;
    for (int32_t i = 0; i < m.fem.num_nodes; ++i)
      if (std::abs(m.fem.rest[3 * i + 2] - L) < 1e-9) {
        stretch += s.tissue.x[3 * i + 2] / L;
        ++n;
      }
    p.value = stretch / n;
  }
  p.error = p.ok ? std::abs(fibre_uniaxial_stress(p.value, c.along) / P - 1) : 0;
  return p;
}

}  // namespace

AccuracyPoint run_fibre_ring(const std::string& out_dir, const ThickRing& ring, int nr, int ntheta, int runs) {
  const double layer = (ring.B - ring.A) / nr;  // cells about as thick as they are deep
  const std::string mesh = write_quarter_ring_vtu(
      (fs::path(out_dir) / fmt::format("fibre_ring_{}x{}.vtu", nr, ntheta)).string(), ring, layer, nr, ntheta, 1);
  const double e = 1e-9;
  const std::string yaml = fmt::format(
      "name: fibre_ring\ntime_step: 0.001\ngravity: [0, 0, 0]\n"
      "solver: {{integrator: static, linear_solver: cholmod, static_tolerance: 1.0e-10}}\n"
      "bodies:\n  - name: ring\n    mesh: {}\n    material:\n      model: stable_neo_hookean\n"
      "      young_modulus: {}\n      poisson_ratio: {}\n      density: 1000\n"
      "      fibres: {{direction: mesh, k1: {}, k2: {}}}\n"
      "    fixed:\n"
      "      - {{box: {{min: [-{e}, -1, -1], max: [{e}, 1, 1]}}, axes: [x]}}\n"
      "      - {{box: {{min: [-1, -{e}, -1], max: [1, {e}, 1]}}, axes: [y]}}\n"
      "      - {{box: {{min: [-1, -1, -{e}], max: [1, 1, {e}]}}, axes: [z]}}\n"
      "      - {{box: {{min: [-1, -1, {zl}], max: [1, 1, {zh}]}}, axes: [z]}}\n"
      "run: {{steps: 1}}\n",
      mesh, ring.E, ring.nu, ring.k1, ring.k2, fmt::arg("e", e), fmt::arg("zl", layer - e), fmt::arg("zh", layer + e));
  const std::string yaml_path = (fs::path(out_dir) / "fibre_ring.yaml").string();
  std::ofstream(yaml_path) << yaml;
  Model m = *compile_model(load_scenario(yaml_path));
  // The dead pressure: p0 × each inner facet's rest area, along its normal away from the axis,
  // a third to each of its nodes.
  auto radius = [&](const double* p) { return std::hypot(p[0], p[1]); };
  auto inner = [&](int32_t n) { return std::abs(radius(&m.fem.rest[3 * n]) - ring.A) < 1e-9 * ring.A; };
  std::fill(m.fem.f_ext.begin(), m.fem.f_ext.end(), 0.0);
  for (const Tri& t : m.fem.bodies[0].boundary) {
    if (!inner(t[0]) || !inner(t[1]) || !inner(t[2])) continue;
    const double* P = &m.fem.rest[3 * t[0]];
    const double* Q = &m.fem.rest[3 * t[1]];
    const double* S = &m.fem.rest[3 * t[2]];
    const double u[3] = {Q[0] - P[0], Q[1] - P[1], Q[2] - P[2]}, v[3] = {S[0] - P[0], S[1] - P[1], S[2] - P[2]};
    double n[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};  // 2·area·normal
    if (n[0] * (P[0] + Q[0] + S[0]) + n[1] * (P[1] + Q[1] + S[1]) < 0)
      for (double& c : n) c = -c;
    for (int32_t node : t)
      for (int k = 0; k < 3; ++k) m.fem.f_ext[3 * node + k] += ring.p0 * 0.5 * n[k] / 3.0;
  }
  AccuracyPoint p;
  p.problem = "fibre_ring";
  p.sweep = "mesh (linear tetrahedra, CHOLMOD Newton)";
  p.label = fmt::format("{} x {} cells", nr, ntheta);
  p.nodes = m.fem.num_nodes;
  p.reference = solve_thick_ring(ring).u_inner;
  State s;
  if (timed_static_solves(m, runs, p, s)) {
    double u = 0;
    int n = 0;
    for (int32_t i = 0; i < m.fem.num_nodes; ++i)
      if (inner(i)) {
        u += radius(&s.tissue.x[3 * i]) - ring.A;
        ++n;
      }
    p.value = u / n;
  }
  p.error = p.ok ? std::abs(p.value / p.reference - 1) : 0;
  return p;
}

namespace {

/// Stretch along and across the fibres (1.03 … 1.3: the exponential's toe to its stiff part),
/// and the mesh at 1.2 along.
std::vector<AccuracyPoint> run_fibre_problem(const AccuracyOptions& o, int runs) {
  std::vector<AccuracyPoint> fi;
  const std::vector<double> stretches = o.quick ? std::vector<double>{1.1, 1.3} : std::vector<double>{1.03, 1.1, 1.2, 1.3};
  for (const bool along : {true, false})
    for (double st : stretches)
      record(fi, run_fibre(o.out_dir, {along ? "along the fibres (h 10 mm)" : "across the fibres (h 10 mm)",
                                       fmt::format("stretch {:g} {}", st, along ? "along" : "across"), st, along, 0.01},
                           runs), o);
  for (double h : o.quick ? std::vector<double>{0.005} : std::vector<double>{0.005, 0.0025})
    record(fi, run_fibre(o.out_dir, {"mesh (stretch 1.2 along)", fmt::format("h {:g} mm", h * 1e3), 1.2, true, h}, runs), o);
  return fi;
}

/// Inhomogeneous: the inflated ring with circumferential fibres against its 1-D reference, the
/// mesh refined (cells of 2.5 mm down to 0.31 mm through the 5 mm wall).
std::vector<AccuracyPoint> run_fibre_ring_problem(const AccuracyOptions& o, int runs) {
  std::vector<AccuracyPoint> ri;
  for (int nr : o.quick ? std::vector<int>{4, 8} : std::vector<int>{2, 4, 8, 16})
    record(ri, run_fibre_ring(o.out_dir, ThickRing{}, nr, 4 * nr, runs), o);
  return ri;
}

// ---------------------------------------------------------------------------------------------
// Reporting: peers' points, Pareto front, CSV, plot, Markdown tables (nothing here runs a model).

const char* const kToAnswer = "wall time to the answer (s): static solve; peers: the run to rest";

/// What a problem's plot and tables show: the sweeps are the plot's series, in legend order.
struct ProblemReport {
  std::string name, title, xlabel;
  std::string time_heading;  ///< the time column of the Pareto number table
  std::vector<std::string> sweeps;
};

const ProblemReport& problem_report(const std::string& name) {
  static const std::vector<ProblemReport> reports = {
      {"cantilever_static", "Cantilever (refs/a): static tip deflection vs -1.4735e-3 m", kToAnswer, "s to answer",
       {"mesh x element (CHOLMOD)", "CG tolerance (warped Cholesky PCG)", "stable neo-Hookean (CHOLMOD)",
        "St. Venant-Kirchhoff (CHOLMOD)", "Bullet FEM (peer)",
        "Bullet FEM neo-Hookean (peer)", "Bullet FEM neo-Hookean matched (peer)", "Bullet soft body (peer)"}},
      {"cantilever_dynamic", "Cantilever (refs/d): first frequency from the released tip vs 16.100 Hz",
       "wall seconds per simulated second", "s per sim. s",
       {"mesh x dt (implicit Euler)", "CG tolerance (Jacobi)", "CG iteration cap (Jacobi)", "warm start (Jacobi CG 1e-6)",
        "element model", "symplectic Euler (largest stable dt)", "Bullet FEM (peer)", "Bullet FEM neo-Hookean (peer)",
        "Bullet FEM neo-Hookean matched (peer)"}},
      {"block_compression", "Bonded block, nu 0.49, pressed 1 % (refs/c): top force vs 0.3049 N", kToAnswer, "s to answer",
       {"mesh x element (CHOLMOD)", "mesh x element (CG 1e-8)", "CG tolerance (warped Cholesky PCG, h 3.333 mm)",
        "Bullet FEM (peer)"}},
      {"viscoelastic", "Visco-elastic bar (SLS, E0 10 kPa, g 0.5, tau 0.1 s): E* vs E0[1 - g + g iwt/(1 + iwt)]",
       "wall seconds per simulated second", "s per sim. s",
       {"steps per period (corotational, omega tau 1)", "omega tau (corotational, 32 steps a period)",
        "stable neo-Hookean (omega tau 1)"}},
      {"fibres", "Fibre-reinforced bar (stable neo-Hookean + HGO fibres): uniaxial stress vs the closed form", kToAnswer,
       "s to answer", {"along the fibres (h 10 mm)", "across the fibres (h 10 mm)", "mesh (stretch 1.2 along)"}},
      {"fibre_ring", "Inflated ring, circumferential HGO fibres (plane strain, p 5 kPa): inner displacement vs the 1-D reference",
       kToAnswer, "s to answer", {"mesh (linear tetrahedra, CHOLMOD Newton)"}},
      {"indentation", "Sphere indentation (refs/e): force at 1 mm vs 0.019604 N", kToAnswer, "s to answer",
       {"mesh grading (linear, penalty 1e9)", "penalty stiffness (first cell 0.2 mm)", "element model (first cell 0.2 mm)",
        "Bullet FEM (peer)"}},
  };
  for (const ProblemReport& r : reports)
    if (r.name == name) return r;
  throw std::invalid_argument("accuracy suite: no problem named " + name);
}

/// A point a log–log plot can show (a time or error of 0 cannot be).
bool drawable(const AccuracyPoint& p) { return p.ok && p.s_per_sim_s > 0 && p.error > 0; }

/// The Pareto front in time order (fastest first, the less accurate first among equal times):
/// indices into pts. The plot's labels and the number table are 1 + the position here.
std::vector<size_t> pareto_front(const std::vector<AccuracyPoint>& pts) {
  std::vector<size_t> front;
  for (size_t i = 0; i < pts.size(); ++i)
    if (pts[i].pareto) front.push_back(i);
  std::stable_sort(front.begin(), front.end(), [&](size_t a, size_t b) {
    return pts[a].s_per_sim_s < pts[b].s_per_sim_s || (pts[a].s_per_sim_s == pts[b].s_per_sim_s && pts[a].error > pts[b].error);
  });
  return front;
}

/// The Markdown table mapping the plot's numbers to the configurations of the Pareto front.
std::string pareto_table(const std::vector<AccuracyPoint>& pts, const std::vector<size_t>& front, const ProblemReport& r) {
  std::string s = fmt::format("| # | sweep | configuration | nodes | error | {} |\n|---|---|---|---|---|---|\n", r.time_heading);
  for (size_t k = 0; k < front.size(); ++k) {
    const AccuracyPoint& p = pts[front[k]];
    s += fmt::format("| {} | {} | {} | {} | {:.2f} % | {:.4g}{} |\n", k + 1, p.sweep, p.label, p.nodes, 100 * p.error,
                     p.s_per_sim_s, drawable(p) ? "" : " (not drawn: 0 on a log axis)");
  }
  return s;
}

/// A log–log plot of run time against error with gnuplot (skipped, with a note, without it): one
/// series per sweep (the legend), the Pareto front drawn and its points numbered in time order
/// (the numbers' table: pareto_table; coinciding points share a label, "2, 3"); other points carry
/// no label. The script is written to gp.
void plot(const std::string& csv, const std::string& gp, const std::string& png, const ProblemReport& r,
          const std::vector<AccuracyPoint>& pts, const std::vector<size_t>& front) {
  std::ofstream f(gp);
  f << "set terminal pngcairo size 1200,800 font 'DejaVu Sans,10'\n";
  f << fmt::format("set output '{}'\n", png);
  f << "set datafile separator ','\nset logscale xy\nset grid\nset key top right\n";
  f << fmt::format("set title \"{}\"\nset xlabel \"{}\"\nset ylabel 'relative error against the reference'\n", r.title, r.xlabel);
  f << "set format y '%.0e'\n";
  // Whole decades, with at least 0.1 decade of room around the points: the labels, which sit
  // below and left of their points, stay inside the frame.
  double xlo = HUGE_VAL, xhi = 0, ylo = HUGE_VAL, yhi = 0;
  for (const AccuracyPoint& p : pts)
    if (drawable(p)) {
      xlo = std::min(xlo, p.s_per_sim_s);
      xhi = std::max(xhi, p.s_per_sim_s);
      ylo = std::min(ylo, p.error);
      yhi = std::max(yhi, p.error);
    }
  auto below = [](double v) { return std::pow(10.0, std::floor(std::log10(v / 1.25))); };
  auto above = [](double v) { return std::pow(10.0, std::ceil(std::log10(v * 1.25))); };
  if (xlo <= xhi)
    f << fmt::format("set xrange [{:g}:{:g}]\nset yrange [{:g}:{:g}]\n", below(xlo), above(xhi), below(ylo), above(yhi));
  f << "set style textbox opaque noborder margins 1,1\n";
  // The front in time order: time, error, label. Points that would be drawn on top of each other
  // (within 0.03 decades on both axes of the group's first point) share one label, "2, 3".
  std::vector<std::pair<size_t, std::string>> rows;  // (index into pts, label: "" when it joins the one before)
  size_t group = 0;
  for (size_t k = 0; k < front.size(); ++k) {
    const AccuracyPoint& p = pts[front[k]];
    if (!drawable(p)) continue;
    const bool joins = !rows.empty() && std::abs(std::log10(p.s_per_sim_s / pts[rows[group].first].s_per_sim_s)) < 0.03 &&
                       std::abs(std::log10(p.error / pts[rows[group].first].error)) < 0.03;
    if (joins) {
      rows[group].second += fmt::format(", {}", k + 1);
      rows.emplace_back(front[k], "");
    } else {
      group = rows.size();
      rows.emplace_back(front[k], fmt::format("{}", k + 1));
    }
  }
  f << "$front << EOD\n";
  for (const auto& [i, label] : rows) f << fmt::format("{:.6g},{:.6g},\"{}\"\n", pts[i].s_per_sim_s, pts[i].error, label);
  f << "EOD\n";
  f << "plot ";
  // gnuplot splits quoted fields right but its strcol() stops at a comma even inside quotes:
  // a sweep is matched by its name up to the first comma.
  for (size_t i = 0; i < r.sweeps.size(); ++i)
    f << fmt::format("'{}' skip 1 using (strcol(2) eq '{}' && $11 == 1 ? $9 : NaN):7 with points pt {} ps 1.4 title '{}', \\\n",
                     csv, r.sweeps[i].substr(0, r.sweeps[i].find(',')), 5 + 2 * static_cast<int>(i), r.sweeps[i]);
  f << "$front using 1:2 with lines lw 2 lc rgb '#444444' title 'Pareto front', \\\n";
  // Below and left of a front point there is no other valid point (it would dominate it) and no
  // part of the front's line: the numbers go there.
  f << "$front using 1:2:3 with labels boxed right font ',10' offset char -0.7,-0.9 notitle\n";
  f.close();
  const int rc = std::system(fmt::format("gnuplot '{}' 2>/dev/null", gp).c_str());
  if (rc != 0) fmt::print("(gnuplot not found or failed: {} not drawn; scripts/setup.sh installs gnuplot-nox)\n", png);
}

std::string replace_extension(const std::string& path, const std::string& ext) {
  return fs::path(path).replace_extension(ext).string();
}

/// The outputs that depend on the points alone: beside the CSV the Pareto number table
/// (<stem>_pareto.md) and the gnuplot script (<stem>.gp), and the plot png. Returns the table.
std::string draw_problem(const std::string& csv, const std::string& png, const std::vector<AccuracyPoint>& pts,
                         const ProblemReport& r) {
  const std::vector<size_t> front = pareto_front(pts);
  const std::string table = pareto_table(pts, front, r);
  const fs::path md = fs::path(csv).parent_path() / (fs::path(csv).stem().string() + "_pareto.md");
  std::ofstream(md) << fmt::format("# {}: Pareto front\n\nThe numbers on the plot {}, in time order along the front "
                                   "(fastest first); every point is in {}.\n\n{}",
                                   r.name, fs::path(png).filename().string(), fs::path(csv).filename().string(), table);
  plot(csv, replace_extension(csv, ".gp"), png, r, pts, front);
  return table;
}

void print_problem_table(const std::string& name, const std::vector<AccuracyPoint>& pts) {
  if (name == "cantilever_dynamic") {
    fmt::print("| sweep | configuration | nodes | f1 (Hz) | error | time-step share | ms/tick | s per sim. s | Pareto |\n|---|---|---|---|---|---|---|---|---|\n");
    for (const auto& p : pts)
      fmt::print("| {} | {} | {} | {} | {} | {} | {:.3f} | {:.3f} | {} |\n", p.sweep, p.label, p.nodes,
                 p.ok ? fmt::format("{:.3f}", p.value) : "—", p.ok ? fmt::format("{:.2f} %", 100 * p.error) : "failed: " + p.failure,
                 p.time_error >= 0 ? fmt::format("{:.2f} %", 100 * p.time_error) : "",
                 p.ms_per_tick, p.s_per_sim_s, p.pareto ? "●" : "");
  } else if (name == "cantilever_static") {
    fmt::print("| sweep | configuration | nodes | tip u_y (mm) | error | solve s | Pareto |\n|---|---|---|---|---|---|---|\n");
    for (const auto& p : pts)
      fmt::print("| {} | {} | {} | {:.5f} | {:.2f} % | {:.4f} | {} |\n", p.sweep, p.label, p.nodes, 1e3 * p.value,
                 100 * p.error, p.s_per_sim_s, p.pareto ? "●" : "");
  } else if (name == "block_compression") {
    fmt::print("| sweep | configuration | nodes | top force (N) | error | C3D4 same mesh (N) | engine vs C3D4 | s to answer | Pareto |\n|---|---|---|---|---|---|---|---|---|\n");
    for (const auto& p : pts)
      fmt::print("| {} | {} | {} | {} | {} | {:.5f} | {} | {:.3f} | {} |\n", p.sweep, p.label, p.nodes,
                 p.ok ? fmt::format("{:.5f}", p.value) : "—", p.ok ? fmt::format("{:.2f} %", 100 * p.error) : "failed: " + p.failure,
                 p.time_error, p.ok && p.time_error > 0 ? fmt::format("{:+.3f} %", 100 * (p.value / p.time_error - 1)) : "",
                 p.s_per_sim_s, p.pareto ? "●" : "");
  } else if (name == "viscoelastic") {
    fmt::print("| sweep | configuration | nodes | abs(E*) (Pa) | abs(E* - closed form) / abs(E*) | ms/tick | s per sim. s | Pareto |\n|---|---|---|---|---|---|---|---|\n");
    for (const auto& p : pts)
      fmt::print("| {} | {} | {} | {} | {} | {:.3f} | {:.4f} | {} |\n", p.sweep, p.label, p.nodes,
                 p.ok ? fmt::format("{:.1f}", p.value) : "—", p.ok ? fmt::format("{:.3f} %", 100 * p.error) : "failed: " + p.failure,
                 p.ms_per_tick, p.s_per_sim_s, p.pareto ? "●" : "");
  } else if (name == "fibres") {
    fmt::print("| sweep | configuration | nodes | stretch reached | target | abs(P(stretch) / P - 1) | s to answer | Pareto |\n|---|---|---|---|---|---|---|---|\n");
    for (const auto& p : pts)
      fmt::print("| {} | {} | {} | {} | {:g} | {} | {:.3f} | {} |\n", p.sweep, p.label, p.nodes,
                 p.ok ? fmt::format("{:.6f}", p.value) : "—", p.reference,
                 p.ok ? fmt::format("{:.2e}", p.error) : "failed: " + p.failure, p.s_per_sim_s, p.pareto ? "●" : "");
  } else if (name == "fibre_ring") {
    fmt::print("| sweep | configuration | nodes | inner displacement (mm) | 1-D reference (mm) | error | s to answer | Pareto |\n|---|---|---|---|---|---|---|---|\n");
    for (const auto& p : pts)
      fmt::print("| {} | {} | {} | {} | {:.6f} | {} | {:.3f} | {} |\n", p.sweep, p.label, p.nodes,
                 p.ok ? fmt::format("{:.6f}", 1e3 * p.value) : "—", 1e3 * p.reference,
                 p.ok ? fmt::format("{:.2f} %", 100 * p.error) : "failed: " + p.failure, p.s_per_sim_s, p.pareto ? "●" : "");
  } else {  // indentation
    fmt::print("| sweep | configuration | nodes | force (N) | error | s to answer | Pareto |\n|---|---|---|---|---|---|---|\n");
    for (const auto& p : pts)
      fmt::print("| {} | {} | {} | {} | {} | {:.3f} | {} |\n", p.sweep, p.label, p.nodes,
                 p.ok ? fmt::format("{:.6f}", p.value) : "—",
                 p.ok ? fmt::format("{:+.2f} %", 100 * (p.value / p.reference - 1)) : "failed: " + p.failure,
                 p.s_per_sim_s, p.pareto ? "●" : "");
  }
}

void print_pareto_table(const std::string& table, const std::string& md) {
  fmt::print("\nPareto front: the numbers on the plot, in time order ({}):\n\n{}", md, table);
  std::fflush(stdout);
}

/// The last steps every problem shares: the peers' points join the engine's, the Pareto front is
/// marked, the CSV written (out_dir/<name>.csv), the plot drawn and the Pareto number table
/// written beside it, and the Markdown tables printed.
void finish_problem(const std::string& out_dir, const std::string& name, std::vector<AccuracyPoint>& pts,
                    const std::vector<AccuracyPoint>& peer_points) {
  const ProblemReport& r = problem_report(name);
  pts.insert(pts.end(), peer_points.begin(), peer_points.end());
  mark_pareto(pts);
  const std::string csv = (fs::path(out_dir) / (name + ".csv")).string();
  write_csv(csv, pts);
  const std::string table = draw_problem(csv, (fs::path(out_dir) / (name + ".png")).string(), pts, r);
  fmt::print("\n### {} ({})\n\n", name, csv);
  print_problem_table(name, pts);
  print_pareto_table(table, (fs::path(out_dir) / (name + "_pareto.md")).string());
}

/// Reads a CSV of write_csv's format back (empty numeric fields read as 0).
std::vector<AccuracyPoint> read_csv(const std::string& path) {
  std::vector<AccuracyPoint> pts;
  std::ifstream f(path);
  std::string line;
  std::getline(f, line);  // header
  auto num = [](const std::string& s) { return s.empty() ? 0.0 : std::stod(s); };
  while (std::getline(f, line)) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty()) continue;
    const auto c = csv_fields(line);
    if (c.size() < 12) throw std::runtime_error(fmt::format("{}: expected 12 columns: {}", path, line));
    AccuracyPoint p;
    p.problem = c[0];
    p.sweep = c[1];
    p.label = c[2];
    p.nodes = static_cast<int>(num(c[3]));
    p.value = num(c[4]);
    p.reference = num(c[5]);
    p.error = num(c[6]);
    p.ms_per_tick = num(c[7]);
    p.s_per_sim_s = num(c[8]);
    p.pareto = c[9] == "1";
    p.ok = c[10] == "1";
    p.time_error = c[11].empty() ? -1 : num(c[11]);
    pts.push_back(p);
  }
  return pts;
}

}  // namespace

std::vector<AccuracyPoint> run_accuracy_suite(const AccuracyOptions& o) {
  fs::create_directories(o.out_dir);
  const int runs = std::max(1, o.runs);
  auto wanted = [&](const char* problem) { return o.only.empty() || o.only == problem; };
  std::vector<AccuracyPoint> all;
  auto keep = [&all](const std::vector<AccuracyPoint>& pts) { all.insert(all.end(), pts.begin(), pts.end()); };
  // The peers run first: their points join each problem's table, CSV and plot.
  const PeerPoints peers = o.peer_program.empty() ? PeerPoints{} : run_peers(o);

  if (wanted("indentation")) {
    std::vector<AccuracyPoint> in = run_indentation_problem(o, runs);
    finish_problem(o.out_dir, "indentation", in, peers.indentation);
    keep(in);
    if (!o.only.empty()) return all;
  }
  if (wanted("block_compression")) {
    std::vector<AccuracyPoint> bl = run_block_compression_problem(o, runs);
    finish_problem(o.out_dir, "block_compression", bl, peers.block);
    keep(bl);
    if (!o.only.empty()) return all;
  }
  if (wanted("viscoelastic")) {
    std::vector<AccuracyPoint> vi = run_visco_problem(o, runs);
    finish_problem(o.out_dir, "viscoelastic", vi, {});
    keep(vi);
    if (!o.only.empty()) return all;
  }
  if (wanted("fibres")) {
    std::vector<AccuracyPoint> fi = run_fibre_problem(o, runs);
    finish_problem(o.out_dir, "fibres", fi, {});
    keep(fi);
    if (!o.only.empty()) return all;
  }
  if (wanted("fibre_ring")) {
    std::vector<AccuracyPoint> fi = run_fibre_ring_problem(o, runs);
    finish_problem(o.out_dir, "fibre_ring", fi, {});
    keep(fi);
    if (!o.only.empty()) return all;
  }
  std::vector<AccuracyPoint> st = run_cantilever_static_problem(o, runs);
  std::vector<AccuracyPoint> dy = run_cantilever_dynamic_problem(o, runs);
  finish_problem(o.out_dir, "cantilever_static", st, peers.cantilever_static);
  finish_problem(o.out_dir, "cantilever_dynamic", dy, peers.cantilever_dynamic);
  keep(st);
  keep(dy);
  return all;
}

std::vector<AccuracyPoint> replot_accuracy_csvs(const std::string& csv_dir, const std::string& png_dir) {
  std::vector<AccuracyPoint> all;
  for (const char* name : {"cantilever_static", "cantilever_dynamic", "block_compression", "indentation", "viscoelastic", "fibres", "fibre_ring"}) {
    for (const std::string& stem : {std::string(name), "accuracy_" + std::string(name)}) {
      const fs::path csv = fs::path(csv_dir) / (stem + ".csv");
      if (!fs::exists(csv)) continue;
      const std::vector<AccuracyPoint> pts = read_csv(csv.string());
      const std::string table = draw_problem(csv.string(), (fs::path(png_dir) / (stem + ".png")).string(), pts, problem_report(name));
      fmt::print("\n### {} ({})\n", name, csv.string());
      print_pareto_table(table, (fs::path(csv_dir) / (stem + "_pareto.md")).string());
      all.insert(all.end(), pts.begin(), pts.end());
    }
  }
  return all;
}

}  // namespace stroma
