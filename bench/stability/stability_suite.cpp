#include "bench/stability/stability_suite.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <numbers>
#include <random>

#include <unistd.h>

#include <fmt/format.h>

#include "engine/model.hpp"
#include "engine/simulation.hpp"
#include "engine/state.hpp"
#include "engine/tick.hpp"
#include "haptics/contact.hpp"
#include "io/mesh_io.hpp"
#include "scene/compiled_scenario.hpp"
#include "scene/scenario_spec.hpp"
#include "tissue/fem_forces.hpp"
#include "tissue/mesh_prepare.hpp"

namespace stroma {

namespace fs = std::filesystem;

namespace {

/// How a case starts and what drives it.
struct CaseSetup {
  std::string name, group;
  ScenarioSpec spec;
  double duration = 0.5;
  std::function<void(const Model&, State&)> init;            ///< initial state changes
  std::function<bool(const Model&, State&, ToolInput*, int*)> drive;  ///< per tick; false with its last command
  std::function<std::string(const Model&, const State&)> check;      ///< case-specific failure at the end, or ""
};

double elapsed(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

/// V/V₀ of every element at positions x; returns the smallest and counts the inverted.
double volume_ratios(const Model& m, const std::vector<double>& x, int* inverted) {
  double worst = 1e300;
  int inv = 0;
  auto p = [&](int32_t n) { return Vec3{x[3 * n], x[3 * n + 1], x[3 * n + 2]}; };
  for (const ElementParams& e : m.fem.elements) {
    const double r = signed_volume(p(e.node[0]), p(e.node[1]), p(e.node[2]), p(e.node[3])) / e.volume;
    worst = std::min(worst, r);
    inv += r < 0;
  }
  *inverted = inv;
  return worst;
}

/// Contact penalty energy (tools and body–body) at the state's current positions. The tick
/// computes contacts at the start of the step; pairing that with the kinetic energy after the
/// step would count the penetration of the step just solved (or, for a tool that just moved,
/// the penetration its move made before the tissue answered), which the step itself removed.
/// Tools are evaluated on copies of their states: the proxy and friction history stay as the
/// tick left them.
double contact_energy(const Model& m, const State& s, TickWorkspace& w) {
  if (!m.body_contact && m.tools.empty()) return 0;
  static thread_local std::vector<ContactSpring> springs;
  static thread_local std::vector<BodyContactPair> pairs;
  springs.clear();
  springs.reserve(TickWorkspace::kMaxContacts);
  pairs.reserve(TickWorkspace::kMaxContacts / 2);
  // Surface points of an uncut mesh are its nodes (the suite's scenes are not cut).
  w.bvh.refit(s.tissue.x.data());  // (the next tick's collide refits again)
  const ContactSurface surf{m.collision_triangles, m.collision_dofs, m.collision_edge,
                            s.face_active.empty() ? nullptr : s.face_active.data()};
  double energy = 0;
  for (size_t k = 0; k < m.tools.size(); ++k) {
    ToolState ts = s.tools[k];
    ToolOutput out;
    springs.clear();
    tool_contact(m.tools[k], ts, out, surf, w.bvh, s.tissue.x.data(), nullptr, 0.0, springs);
    energy += out.contact_energy;
  }
  if (m.body_contact) {
    springs.clear();
    BodyContactOutput out;
    body_contact(*m.body_contact, surf, w.bvh, s.tissue.x.data(), nullptr, 0.0, nullptr, w.body_boxes.data(), springs,
                 pairs, out);
    energy += out.energy;
  }
  return energy;
}

/// Total mechanical energy: kinetic + elastic + gravity/load potential + contact penalty (*ce).
double total_energy(const Model& m, TickWorkspace& w, const State& s, double* ke, double* ee, double* pe,
                    double* ce) {
  *ke = w.stepper().kinetic_energy(s.tissue);
  *ee = w.stepper().free_energy(s.tissue);  // visco-elastic bodies: long-term part + branches
  *pe = w.stepper().external_potential(s.tissue);
  *ce = contact_energy(m, s, w);
  return *ke + *ee + *pe + *ce;
}

StabilityResult run_case(const CaseSetup& c) {
  StabilityResult res;
  res.name = c.name;
  res.group = c.group;
  const auto t0 = std::chrono::steady_clock::now();
  std::shared_ptr<const Model> m;
  try {
    m = compile_model(c.spec);
  } catch (const std::exception& e) {
    res.why = std::string("did not load: ") + e.what();
    return res;
  }
  State start = State::initial(*m);
  if (c.init) {
    c.init(*m, start);
    // The body was put there instantaneously: visco-elastic branches take the step at h = 0
    // (their overstress gᵢ·σ₀), so the start's free energy counts them.
    viscous_update(m->fem, start.tissue.x.data(), nullptr, 0.0, start.tissue.visco_q.data(),
                   start.tissue.visco_s0.data());
  }
  // Driven as every front end drives the engine (engine/simulation.hpp): the case's start state
  // restored, its drive's commands passed as a replay's (trusted: the suite tests the solver on
  // poses beyond any device's limits, not the commands port).
  Simulation sim(m);
  sim.restore(m, start);
  State& s = sim.state();
  TickWorkspace& w = sim.workspace();
  double ke, ee, pe, ce;
  const double e0 = total_energy(*m, w, s, &ke, &ee, &pe, &ce);
  double scale = std::max({std::abs(e0), ke, ee, std::abs(pe), ce});
  res.min_volume_ratio = volume_ratios(*m, s.tissue.x, &res.inverted_start);
  // The bound: the energy at the start (or after the drive's last command) plus 1 % of the
  // energies seen.
  double reference = e0, worst_excess = -1e300;
  bool driving = static_cast<bool>(c.drive), last_command = false;
  const int ticks = std::max(10, static_cast<int>(std::lround(c.duration / m->time_step)));
  ToolInput inputs[4];
  for (int k = 0; k < ticks; ++k) {
    int n_in = 0;
    if (driving) last_command = !c.drive(*m, s, inputs, &n_in);
    const TickReport& r = sim.step({}, inputs, n_in);
    ++res.ticks;
    res.max_cg_iterations = std::max(res.max_cg_iterations, r.solve.iterations);
    res.cg_capped += r.status == TickStatus::SolverNotConverged;
    res.recovered += r.status == TickStatus::Recovered;
    res.rolled_back += r.status == TickStatus::NonFinite;
    for (double v : s.tissue.x) res.finite &= std::isfinite(v);
    for (double v : s.tissue.v) res.finite &= std::isfinite(v);
    if (!res.finite) break;
    int inv = 0;
    res.min_volume_ratio = std::min(res.min_volume_ratio, volume_ratios(*m, s.tissue.x, &inv));
    res.inverted_end = inv;
    const double e = total_energy(*m, w, s, &ke, &ee, &pe, &ce);
    scale = std::max({scale, ke, ee, std::abs(pe), ce});
    if (last_command) {  // the tick that applied the drive's last command is over: from here the
      reference = e;     // energy may only go down
      driving = last_command = false;
    } else if (!driving) {
      worst_excess = std::max(worst_excess, e - reference);
    }
  }
  res.energy_ratio = worst_excess > -1e300 ? worst_excess / std::max(scale, 1e-300) : 0.0;
  std::vector<std::string> why;
  if (!res.finite) why.push_back("NaN/Inf in the state");
  if (res.energy_ratio > 0.01) why.push_back(fmt::format("energy grew by {:.3g} of its scale", res.energy_ratio));
  if (res.inverted_end > 0) why.push_back(fmt::format("{} elements still inverted", res.inverted_end));
  if (res.rolled_back > 0) why.push_back(fmt::format("{} ticks could not advance", res.rolled_back));
  if (c.check && res.finite)
    if (std::string w = c.check(*m, s); !w.empty()) why.push_back(w);
  for (size_t i = 0; i < why.size(); ++i) res.why += (i ? "; " : "") + why[i];
  res.pass = why.empty();
  res.wall_seconds = elapsed(t0);
  return res;
}

/// The good beam mesh with slivers: nodes pushed at random (fixed seed) as far as their
/// elements allow while keeping every element at ≥ 0.2 % of its volume; written as legacy VTK.
std::string make_sliver_mesh(const std::string& good, const std::string& out_path, double* worst_ratio) {
  PreparedMesh pm = prepare_mesh(load_tet_mesh(good));
  TetMesh mesh = pm.mesh;
  std::vector<std::vector<int32_t>> node_tets(mesh.nodes.size());
  for (size_t t = 0; t < mesh.tets.size(); ++t)
    for (int32_t n : mesh.tets[t]) node_tets[n].push_back(static_cast<int32_t>(t));
  std::vector<double> v0(mesh.tets.size());
  auto vol = [&](size_t t) {
    const Tet& q = mesh.tets[t];
    return signed_volume(mesh.nodes[q[0]], mesh.nodes[q[1]], mesh.nodes[q[2]], mesh.nodes[q[3]]);
  };
  for (size_t t = 0; t < mesh.tets.size(); ++t) v0[t] = vol(t);
  std::mt19937 rng(12345);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const double h = 0.005;  // the mesh size
  for (int pass = 0; pass < 4; ++pass)
    for (size_t n = 0; n < mesh.nodes.size(); ++n) {
      if (mesh.nodes[n][0] < 1e-6) continue;  // keep the clamped face flat
      const Vec3 old = mesh.nodes[n];
      for (int k = 0; k < 3; ++k) mesh.nodes[n][k] += 0.35 * h * u(rng);
      bool ok = true;
      for (int32_t t : node_tets[n]) ok &= vol(t) >= 0.002 * v0[t];
      if (!ok) mesh.nodes[n] = old;
    }
  double worst = 1e300;
  for (size_t t = 0; t < mesh.tets.size(); ++t) worst = std::min(worst, vol(t) / v0[t]);
  *worst_ratio = worst;
  std::ofstream f(out_path);
  f << "# vtk DataFile Version 2.0\nbeam with slivers (stroma bench stability)\nASCII\nDATASET UNSTRUCTURED_GRID\n";
  f << "POINTS " << mesh.nodes.size() << " double\n";
  f.precision(17);
  for (const Vec3& p : mesh.nodes) f << p[0] << ' ' << p[1] << ' ' << p[2] << '\n';
  f << "CELLS " << mesh.tets.size() << ' ' << 5 * mesh.tets.size() << '\n';
  for (const Tet& t : mesh.tets) f << "4 " << t[0] << ' ' << t[1] << ' ' << t[2] << ' ' << t[3] << '\n';
  f << "CELL_TYPES " << mesh.tets.size() << '\n';
  for (size_t t = 0; t < mesh.tets.size(); ++t) f << "10\n";
  return out_path;
}

/// Mirrors the free end (x > 80 % of the length) through the beam's mid-plane z: every element
/// there starts inverted, those across the cut badly distorted.
void invert_free_end(const Model& m, State& s) {
  double zlo = 1e300, zhi = -1e300, xhi = -1e300;
  for (size_t i = 0; i < m.fem.rest.size(); i += 3) {
    zlo = std::min(zlo, m.fem.rest[i + 2]);
    zhi = std::max(zhi, m.fem.rest[i + 2]);
    xhi = std::max(xhi, m.fem.rest[i]);
  }
  const double zc = 0.5 * (zlo + zhi);
  for (size_t i = 0; i < m.fem.rest.size(); i += 3)
    if (m.fem.rest[i] > 0.8 * xhi) s.tissue.x[i + 2] = 2 * zc - m.fem.rest[i + 2];
}

ScenarioSpec cantilever(const std::string& src, double dt, double E, double nu, const std::string& mesh) {
  ScenarioSpec spec = load_scenario(src + "/scenarios/cantilever_dynamic.yaml");
  spec.time_step = dt;
  spec.bodies[0].mesh_path = mesh;
  spec.bodies[0].material.young_modulus = E;
  spec.bodies[0].material.poisson_ratio = nu;
  spec.solver.tolerance = 1e-6;
  spec.solver.max_iterations = 200;
  return spec;
}

std::string fmt_si(double v) {
  if (v >= 1e6) return fmt::format("{:g}M", v / 1e6);
  if (v >= 1e3) return fmt::format("{:g}k", v / 1e3);
  return fmt::format("{:g}", v);
}

void print_row(const StabilityResult& r, bool markdown) {
  if (markdown) {
    fmt::print("| {} | {} | {:.2g} | {} | {} | {} | {:.3g} | {} → {} | {} |\n", r.name, r.pass ? "pass" : "**FAIL**",
               r.energy_ratio, r.max_cg_iterations, r.cg_capped, r.recovered, r.min_volume_ratio, r.inverted_start,
               r.inverted_end, r.why.empty() ? "" : r.why);
  } else {
    fmt::print("{:<52} {:<4} energy {:+.2e}  CG max {:>3} capped {:>3}  recovered {:>3}  min V/V0 {:+.3f}  inverted {}→{}  {:.1f} s{}{}\n",
               r.name, r.pass ? "ok" : "FAIL", r.energy_ratio, r.max_cg_iterations, r.cg_capped, r.recovered,
               r.min_volume_ratio, r.inverted_start, r.inverted_end, r.wall_seconds, r.why.empty() ? "" : "  ", r.why);
  }
  std::fflush(stdout);
}

/// The grid: time step × E × ν × mesh (good, slivers, initially inverted) with the corotational
/// model, then its soft half (E ≤ 10 kPa, where corotational elements end inverted) again with
/// stable Neo-Hookean, the material for that, and with St. Venant–Kirchhoff, to show its known
/// failure (an inverted element is a mirrored rest state to it: nothing pushes it back).
void add_grid_cases(const StabilityOptions& o, const std::string& good, const std::string& slivers,
                    std::vector<CaseSetup>& cases) {
  const std::string& src = o.source_dir;
  const std::vector<double> dts = o.quick ? std::vector<double>{1e-3, 33e-3} : std::vector<double>{0.5e-3, 1e-3, 5e-3, 10e-3, 33e-3};
  const std::vector<double> Es = o.quick ? std::vector<double>{1e3, 1e6} : std::vector<double>{1e3, 1e4, 1e5, 1e6};
  const std::vector<double> nus = o.quick ? std::vector<double>{0.3, 0.499} : std::vector<double>{0.3, 0.45, 0.49, 0.499};
  const double T = o.quick ? 0.2 : 0.5;
  for (const ElementModel model : {ElementModel::Corotational, ElementModel::StableNeoHookean, ElementModel::StVenantKirchhoff})
    for (double dt : dts)
      for (double E : Es)
        for (double nu : nus)
          for (int mesh = 0; mesh < 3; ++mesh) {
            const bool snh = model == ElementModel::StableNeoHookean, stvk = model == ElementModel::StVenantKirchhoff;
            if (snh && (E > 1e4 || (o.quick && (dt > 1e-3 || mesh != 0)))) continue;
            if (stvk && (E > 1e4 || (o.quick && (dt > 1e-3 || mesh == 1)))) continue;
            CaseSetup c;
            c.group = "grid";
            const char* mname = mesh == 0 ? "good" : mesh == 1 ? "slivers" : "inverted";
            c.name = fmt::format("dt {:g} ms, E {}Pa, nu {}, {}{}", dt * 1e3, fmt_si(E), nu, mname,
                                 snh ? ", stable neo-Hookean" : stvk ? ", St. Venant-Kirchhoff" : "");
            c.spec = cantilever(src, dt, E, nu, mesh == 1 ? slivers : good);
            c.spec.bodies[0].material.model = model;
            c.duration = T;
            if (mesh == 2) c.init = invert_free_end;
            cases.push_back(std::move(c));
          }
}

/// Fibre-reinforced tissue (tissue/fibre.hpp): the soft beam as a tendon — stable Neo-Hookean
/// matrix with exponential fibres along its axis (k1 = 50 kPa, k2 = 8, so the fibres stiffen
/// ~50× between 1 % and 20 % stretch) — on the good mesh and with its free end inverted.
void add_fibre_cases(const StabilityOptions& o, const std::string& good, std::vector<CaseSetup>& cases) {
  const std::vector<double> dts = o.quick ? std::vector<double>{1e-3} : std::vector<double>{1e-3, 10e-3, 33e-3};
  const std::vector<double> Es = o.quick ? std::vector<double>{1e3} : std::vector<double>{1e3, 1e4};
  for (double dt : dts)
    for (double E : Es)
      for (double nu : {0.45, 0.499})
        for (int mesh : {0, 2}) {
          CaseSetup c;
          c.group = "grid";
          c.name = fmt::format("dt {:g} ms, E {}Pa, nu {}, {}, fibres", dt * 1e3, fmt_si(E), nu, mesh == 0 ? "good" : "inverted");
          c.spec = cantilever(o.source_dir, dt, E, nu, good);
          MaterialSpec& mat = c.spec.bodies[0].material;
          mat.model = ElementModel::StableNeoHookean;
          FibreSpec f;
          f.direction = {1, 0, 0};
          f.k1 = 5e4;
          f.k2 = 8;
          mat.fibres = f;
          c.duration = o.quick ? 0.2 : 0.5;
          if (mesh == 2) c.init = invert_free_end;
          cases.push_back(std::move(c));
        }
}

/// Visco-elastic tissue (tissue/viscoelastic.hpp): the soft beam with a two-branch Prony series
/// (g 0.3, τ 10 ms: faster than a step at 33 ms; g 0.4, τ 1 s: slower than the run), on
/// corotational and stable Neo-Hookean elements, good mesh and inverted free end. The energy
/// watched is the free energy (long-term part + the branches' stored energy): a wrong history
/// or tangent shows as growth.
void add_visco_cases(const StabilityOptions& o, const std::string& good, std::vector<CaseSetup>& cases) {
  const std::vector<double> dts = o.quick ? std::vector<double>{1e-3, 33e-3} : std::vector<double>{1e-3, 10e-3, 33e-3};
  const std::vector<double> Es = o.quick ? std::vector<double>{1e3} : std::vector<double>{1e3, 1e4};
  for (const ElementModel model : {ElementModel::Corotational, ElementModel::StableNeoHookean})
    for (double dt : dts)
      for (double E : Es)
        for (double nu : {0.45, 0.499})
          for (int mesh : {0, 2}) {
            if (o.quick && (nu == 0.45 || (mesh == 2 && model == ElementModel::Corotational))) continue;
            const bool snh = model == ElementModel::StableNeoHookean;
            CaseSetup c;
            c.group = "grid";
            c.name = fmt::format("dt {:g} ms, E {}Pa, nu {}, {}, visco{}", dt * 1e3, fmt_si(E), nu,
                                 mesh == 0 ? "good" : "inverted", snh ? ", stable neo-Hookean" : "");
            c.spec = cantilever(o.source_dir, dt, E, nu, good);
            MaterialSpec& mat = c.spec.bodies[0].material;
            mat.model = model;
            ViscoSpec v;
            v.model = "prony";
            v.series.terms = 2;
            v.series.g[0] = 0.3;
            v.series.tau[0] = 0.01;
            v.series.g[1] = 0.4;
            v.series.tau[1] = 1.0;
            mat.viscoelastic = v;
            c.duration = o.quick ? 0.2 : 0.5;
            if (mesh == 2) c.init = invert_free_end;
            cases.push_back(std::move(c));
          }
}

/// Locking-free near-incompressible elements (tissue/nodal_smoothing.hpp, at their defaults:
/// node smoothing s 0.1, and element patches of at least 16 tetrahedra keeping 2 % of the bulk on
/// each element, "F-bar-patch"): the
/// beam at ν 0.49 and 0.499 on the good, sliver and inverted-end meshes. Smoothing leaves less
/// stiffness on the elements, so a spurious soft mode or a wrong tangent would show here first
/// as energy growth.
void add_locking_free_cases(const StabilityOptions& o, const std::string& good, const std::string& slivers,
                            std::vector<CaseSetup>& cases) {
  const std::vector<double> dts = o.quick ? std::vector<double>{1e-3} : std::vector<double>{1e-3, 10e-3, 33e-3};
  const std::vector<double> Es = o.quick ? std::vector<double>{1e5} : std::vector<double>{1e3, 1e5};
  for (bool patches : {false, true})
    for (double dt : dts)
      for (double E : Es)
        for (double nu : {0.49, 0.499})
          for (int mesh = 0; mesh < 3; ++mesh) {
            if (o.quick && (mesh == 1 || nu == 0.49)) continue;
            CaseSetup c;
            c.group = "grid";
            const char* mname = mesh == 0 ? "good" : mesh == 1 ? "slivers" : "inverted";
            c.name = fmt::format("dt {:g} ms, E {}Pa, nu {}, {}, locking-free{}", dt * 1e3, fmt_si(E), nu, mname,
                                 patches ? " F-bar-patch" : "");
            c.spec = cantilever(o.source_dir, dt, E, nu, mesh == 1 ? slivers : good);
            c.spec.bodies[0].material.locking_free = patches ? LockingFreeSpec::element_patches() : LockingFreeSpec{};
            c.duration = o.quick ? 0.2 : 0.5;
            if (mesh == 2) c.init = invert_free_end;
            cases.push_back(std::move(c));
          }
}

/// Extreme loads: the clamp turned 180°, random initial velocities, the tool at 5 m/s into the
/// liver, a bar dropped onto a fixed block.
void add_extreme_cases(const StabilityOptions& o, const std::string& good, std::vector<CaseSetup>& cases) {
  const std::string& src = o.source_dir;
  {  // The clamped end turned 180° about the beam's axis in 0.1 s, then held.
    CaseSetup c;
    c.group = "extreme";
    c.name = "clamp turned 180° in 0.1 s (E 10 MPa, dt 1 ms)";
    c.spec = cantilever(src, 1e-3, 1e7, 0.3, good);
    c.duration = o.quick ? 0.2 : 0.4;
    c.drive = [](const Model& m, State& s, ToolInput*, int*) {
      const double th = std::numbers::pi * std::min(1.0, s.time / 0.1);
      const double cy = 0.005, cz = 0.005;
      for (int32_t i = 0; i < m.fem.num_nodes; ++i)
        if (m.fem.constrained[i]) {
          const double y = m.fem.rest[3 * i + 1] - cy, z = m.fem.rest[3 * i + 2] - cz;
          s.tissue.x[3 * i + 1] = cy + std::cos(th) * y - std::sin(th) * z;
          s.tissue.x[3 * i + 2] = cz + std::sin(th) * y + std::cos(th) * z;
        }
      return s.time < 0.1;
    };
    cases.push_back(std::move(c));
  }
  for (double speed : {10.0, 100.0}) {  // every free node thrown at random velocities
    CaseSetup c;
    c.group = "extreme";
    c.name = fmt::format("random initial velocities ±{:g} m/s (E 100 kPa, dt 10 ms)", speed);
    c.spec = cantilever(src, 10e-3, 1e5, 0.45, good);
    c.duration = o.quick ? 0.2 : 0.5;
    c.init = [speed](const Model& m, State& s) {
      std::mt19937 rng(7);
      std::uniform_real_distribution<double> u(-speed, speed);
      for (int32_t i = 0; i < m.fem.num_nodes; ++i)
        if (!m.fem.constrained[i])
          for (int k = 0; k < 3; ++k) s.tissue.v[3 * i + k] = u(rng);
    };
    cases.push_back(std::move(c));
  }
  {  // The probe driven at 5 m/s (500 liver units/s) 3 units deep into the liver, then held.
    CaseSetup c;
    c.group = "extreme";
    c.name = "tool at 5 m/s into the liver, then held (dt 1 ms)";
    c.spec = load_scenario(src + "/scenarios/liver.yaml");
    c.spec.bodies[0].visual.reset();
    c.duration = o.quick ? 0.3 : 0.6;
    c.drive = [](const Model&, State& s, ToolInput* in, int* n) {
      const double y = std::max(3.0, 7.0 - 500.0 * s.time);  // liver top near y = 5.2
      in[0].tool = 0;
      in[0].seq = static_cast<uint64_t>(s.step + 1);
      in[0].pose.position = {-1.5, y, 0.5};
      *n = 1;
      return y > 3.0;
    };
    cases.push_back(std::move(c));
  }
  // A soft bar dropped from 20 mm onto a fixed block (body contact): it must come to rest on
  // the block's top face, not in it or through it.
  const std::vector<double> drop_dts = o.quick ? std::vector<double>{1e-3, 10e-3} : std::vector<double>{1e-3, 10e-3, 33e-3};
  const std::vector<double> drop_Es = o.quick ? std::vector<double>{1e5} : std::vector<double>{1e4, 1e5, 1e6};
  for (double dt : drop_dts)
    for (double E : drop_Es) {
      CaseSetup c;
      c.group = "extreme";
      c.name = fmt::format("bar dropped 20 mm onto a fixed block (E {}Pa, dt {:g} ms)", fmt_si(E), dt * 1e3);
      c.spec = load_scenario(src + "/scenarios/drop_on_block.yaml");
      c.spec.time_step = dt;
      c.spec.bodies[1].translate[1] += 0.015;  // the scenario's 5 mm gap → 20 mm
      c.spec.probes[0].point[1] += 0.015;
      c.spec.bodies[1].material.young_modulus = E;
      c.duration = o.quick ? 0.3 : 0.6;
      c.check = [](const Model& m, const State& s) -> std::string {
        // Lowest bar node vs the block's top face (y = 0.05): resting means within a millimetre.
        const BodyRange& bar = m.fem.bodies[1];
        double lowest = 1e300;
        for (int32_t i = bar.node_begin; i < bar.node_end; ++i) lowest = std::min(lowest, s.tissue.x[3 * i + 1]);
        const double below = 0.05 - lowest;
        if (below > 1e-3) return fmt::format("the bar ended {:.3g} mm below the block's top face", below * 1e3);
        if (below < -1e-3) return fmt::format("the bar ended {:.3g} mm above the block", -below * 1e3);
        return "";
      };
      cases.push_back(std::move(c));
    }
}

void write_csv(const std::string& path, const std::vector<StabilityResult>& results) {
  std::ofstream f(path);
  f << "group,case,pass,why,ticks,finite,energy_ratio,max_cg_iterations,cg_capped,recovered,rolled_back,"
       "min_volume_ratio,inverted_start,inverted_end,wall_seconds\n";
  for (const auto& r : results)
    f << fmt::format("{},\"{}\",{},\"{}\",{},{},{:.6g},{},{},{},{},{:.6g},{},{},{:.3f}\n", r.group, r.name, r.pass, r.why,
                     r.ticks, r.finite, r.energy_ratio, r.max_cg_iterations, r.cg_capped, r.recovered, r.rolled_back,
                     r.min_volume_ratio, r.inverted_start, r.inverted_end, r.wall_seconds);
}

}  // namespace

std::vector<StabilityResult> run_stability_suite(const StabilityOptions& o) {
  const std::string good = o.source_dir + "/scenarios/meshes/beam_tet4_h5p000mm.msh";
  const fs::path tmp = fs::temp_directory_path() / fmt::format("stroma_stability_{}", ::getpid());
  fs::create_directories(tmp);
  double sliver_ratio = 0;
  const std::string slivers = make_sliver_mesh(good, (tmp / "beam_slivers.vtk").string(), &sliver_ratio);
  std::vector<CaseSetup> cases;
  add_grid_cases(o, good, slivers, cases);
  add_fibre_cases(o, good, cases);
  add_visco_cases(o, good, cases);
  add_locking_free_cases(o, good, slivers, cases);
  add_extreme_cases(o, good, cases);
  if (o.newton_iterations > 0)
    for (CaseSetup& c : cases) c.spec.solver.newton_iterations = o.newton_iterations;
  if (!o.only.empty())
    std::erase_if(cases, [&](const CaseSetup& c) { return c.name.find(o.only) == std::string::npos; });
  if (o.progress && !o.markdown)
    fmt::print("{} cases ({}); the sliver mesh's worst element has {:.4f} of its regular volume\n", cases.size(),
               o.quick ? "quick subset" : "full grid", sliver_ratio);
  if (o.markdown) {
    fmt::print("| case | result | energy growth / scale | CG iterations max | ticks at CG cap | ticks redone in sub-steps | worst V/V₀ | inverted start → end | why |\n");
    fmt::print("|---|---|---|---|---|---|---|---|---|\n");
  }
  std::vector<StabilityResult> results;
  for (const CaseSetup& c : cases) {
    results.push_back(run_case(c));
    print_row(results.back(), o.markdown);
  }
  if (!o.csv.empty()) write_csv(o.csv, results);
  std::error_code ec;
  fs::remove_all(tmp, ec);
  return results;
}

}  // namespace stroma
