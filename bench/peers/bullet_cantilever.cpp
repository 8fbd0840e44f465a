/// \file bullet_cantilever.cpp
/// Peer benchmark: Bullet Physics 3.24 (system libbullet, default single-precision build)
/// solving Stroma's cantilever (refs/a, refs/d) on the same tetrahedral meshes.
///
/// Fairness choices (kept equal to Stroma's cantilever run):
///  - same mesh files, read with Stroma's own reader; tets re-ordered to positive volume;
///  - same material (E = 1e7 Pa, nu = 0.3 -> Lame mu, lambda), same density 1000 kg/m^3,
///    same lumped masses (rho*V/4 per tet node), same clamp (x < 1e-6 m: mass 0 = fixed),
///    same gravity (9.81 m/s^2 in -y switched on at t = 0 from rest), same dt (1 ms);
///  - the tip value is interpolated barycentrically in the tet containing P = (0.1, 0.005, 0.005).
/// What differs:
///  - Bullet's default build uses float (btScalar = float); Stroma uses double;
///  - A (btDeformableMultiBodyDynamicsWorld): the Newton path (world.setImplicit(true)) leaves
///    the body frozen in 3.24, so Bullet's default step is used: one CG solve per step (CG
///    tolerance tightened to 1e-10, see DeformableSolver) in which the damping is implicit but
///    the elastic force is not; it diverges at dt = 1 ms with damping 0, so f1 is measured with
///    the smallest stiffness-proportional damping beta that stays stable (5e-4 s, ~3% of
///    critical for mode 1). Its "linear elasticity" is corotated (same at these small strains);
///  - A static: reached by running with beta = 0.015 s (~critical for mode 1) until the tip
///    stops (|du| < 1e-5 |u| for 20 steps), not by a static solve;
///  - B (classic btSoftBody): position-based links on tet edges, no material law at all:
///    stiffness comes from kLST and piterations, so E/nu are not inputs (only masses are).

#include "tissue/mesh_io.hpp"

#include <btBulletDynamicsCommon.h>
#include <BulletSoftBody/btDeformableBodySolver.h>
#include <BulletSoftBody/btDeformableGravityForce.h>
#include <BulletSoftBody/btDeformableLinearElasticityForce.h>
#include <BulletSoftBody/btDeformableMultiBodyConstraintSolver.h>
#include <BulletSoftBody/btDeformableMultiBodyDynamicsWorld.h>
#include <BulletSoftBody/btDeformableNeoHookeanForce.h>
#include <BulletSoftBody/btSoftBodyRigidBodyCollisionConfiguration.h>
#include <BulletSoftBody/btSoftRigidDynamicsWorld.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <set>
#include <string>
#include <utility>
#include <vector>

namespace {

constexpr double kE = 1e7, kNu = 0.3, kRho = 1000.0, kG = 9.81;
constexpr double kMu = kE / (2 * (1 + kNu));
constexpr double kLambda = kE * kNu / ((1 + kNu) * (1 - 2 * kNu));
constexpr double kRefUy = -1.4735e-3;     // converged static tip deflection [m]
constexpr double kRefF1 = 16.100;         // converged first bending frequency [Hz]
constexpr double kLinTetH5Uy = -8.146e-4; // exact linear-tet FEM on h5 (tuning target of B)

struct Mesh {
  std::string name;
  std::vector<btVector3> x;
  std::vector<std::array<int, 4>> tets;
  std::vector<btScalar> mass;  // lumped, 0 for clamped nodes
  std::array<int, 4> ptet{};   // tet containing P and P's barycentric weights in it
  std::array<double, 4> pw{};
};

double det3(const std::array<double, 3>& a, const std::array<double, 3>& b, const std::array<double, 3>& c) {
  return a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) + a[2] * (b[0] * c[1] - b[1] * c[0]);
}

Mesh prepare(const std::string& path, const std::string& name) {
  const stroma::TetMesh tm = stroma::load_tet_mesh(path);
  Mesh m;
  m.name = name;
  std::vector<double> mass(tm.nodes.size(), 0.0);
  const std::array<double, 3> P{0.1, 0.005, 0.005};
  double best = -1e300;
  for (auto t : tm.tets) {
    auto d = [&](int i, const std::array<double, 3>& o) {
      const auto& p = tm.nodes[t[i]];
      return std::array<double, 3>{p[0] - o[0], p[1] - o[1], p[2] - o[2]};
    };
    const auto& x0 = tm.nodes[t[0]];
    double v6 = det3(d(1, x0), d(2, x0), d(3, x0));
    if (v6 < 0) { std::swap(t[1], t[2]); v6 = -v6; }
    for (int i = 0; i < 4; ++i) mass[t[i]] += kRho * v6 / 6.0 / 4.0;
    m.tets.push_back({t[0], t[1], t[2], t[3]});
    // Barycentric weights of P; keep the tet whose smallest weight is largest.
    std::array<double, 4> w{};
    for (int i = 0; i < 4; ++i) {
      std::array<std::array<double, 3>, 4> q;
      for (int k = 0; k < 4; ++k) q[k] = (k == i) ? P : tm.nodes[t[k]];
      auto e = [&](int k) { return std::array<double, 3>{q[k][0] - q[0][0], q[k][1] - q[0][1], q[k][2] - q[0][2]}; };
      w[i] = det3(e(1), e(2), e(3)) / v6;
    }
    const double wmin = *std::min_element(w.begin(), w.end());
    if (wmin > best) { best = wmin; m.ptet = {t[0], t[1], t[2], t[3]}; m.pw = w; }
  }
  for (std::size_t i = 0; i < tm.nodes.size(); ++i) {
    const auto& p = tm.nodes[i];
    m.x.emplace_back(btScalar(p[0]), btScalar(p[1]), btScalar(p[2]));
    m.mass.push_back(p[0] < 1e-6 ? btScalar(0) : btScalar(mass[i]));
  }
  std::printf("mesh %s: %zu nodes, %zu tets, P in tet with min barycentric weight %.2e\n", name.c_str(),
              m.x.size(), m.tets.size(), best);
  return m;
}

double tip_uy(const btSoftBody* sb, const Mesh& m) {
  double u = 0;
  for (int i = 0; i < 4; ++i) u += m.pw[i] * (double(sb->m_nodes[m.ptet[i]].m_x.y()) - double(m.x[m.ptet[i]].y()));
  return u;
}

/// Exposes the deformable solver's protected Newton / CG settings.
struct DeformableSolver : btDeformableBodySolver {
  void configure() {
    m_cg.setTolerance(btScalar(kCgTol));
    m_cg.m_maxIterations = 2000;
  }
  static inline double kCgTol = 1e-10;
};

struct Run {
  std::vector<double> uy;       // tip u_y after each step
  std::vector<double> step_ms;  // wall time per step
  int rest_step = -1;           // first step at which the tip was at rest (static runs)
};

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

/// Stops when |du| < 1e-5*|u| for 20 consecutive steps (static runs) or after max_steps.
template <class Step>
Run drive(const btSoftBody* sb, const Mesh& m, int max_steps, bool stop_at_rest, Step&& step) {
  Run r;
  int calm = 0;
  for (int s = 0; s < max_steps; ++s) {
    const auto t0 = std::chrono::steady_clock::now();
    step();
    const auto t1 = std::chrono::steady_clock::now();
    r.step_ms.push_back(std::chrono::duration<double, std::milli>(t1 - t0).count());
    r.uy.push_back(tip_uy(sb, m));
    if (!std::isfinite(r.uy.back())) break;
    if (stop_at_rest && s > 0) {
      const double du = std::abs(r.uy[s] - r.uy[s - 1]);
      calm = (du < 1e-5 * std::abs(r.uy[s])) ? calm + 1 : 0;  // float: ~1e-6 jitter
      if (calm >= 20) { r.rest_step = s + 1; break; }
    }
  }
  return r;
}

enum class Law { Linear, NeoHookean };

/// Peer A: Bullet's deformable FEM world (default, non-Newton step; see the \file comment).
Run run_deformable(const Mesh& m, Law law, double dt, double beta, int max_steps, bool stop_at_rest) {
  btSoftBodyRigidBodyCollisionConfiguration cc;
  btCollisionDispatcher disp(&cc);
  btDbvtBroadphase bp;
  DeformableSolver solver;
  btDeformableMultiBodyConstraintSolver cs;
  cs.setDeformableSolver(&solver);
  btDeformableMultiBodyDynamicsWorld world(&disp, &bp, &cs, &cc, &solver);
  const btVector3 g(0, btScalar(-kG), 0);
  world.setGravity(g);
  world.getWorldInfo().m_gravity = g;
  // world.setImplicit(true) (Newton) leaves the body frozen in 3.24 (zero motion; the world
  // overwrites the solver's own flag each step), so the default is kept: one linearised
  // backward-Euler step per dt, elastic Hessian + damping in a CG solve (stable at dt = 1 ms).
  world.setImplicit(false);
  solver.configure();

  auto* sb = new btSoftBody(&world.getWorldInfo(), int(m.x.size()), m.x.data(), m.mass.data());
  for (const auto& t : m.tets) sb->appendTetra(t[0], t[1], t[2], t[3]);
  sb->initializeDmInverse();
  sb->m_tetraScratches.resize(sb->m_tetras.size());
  sb->m_tetraScratchesTn.resize(sb->m_tetras.size());
  sb->setSelfCollision(false);
  sb->m_sleepingThreshold = 0;
  sb->setDampingCoefficient(0);
  sb->setActivationState(DISABLE_DEACTIVATION);
  world.addSoftBody(sb);

  btDeformableGravityForce gravity(g);
  world.addForce(sb, &gravity);
  std::unique_ptr<btDeformableLagrangianForce> elastic;
  if (law == Law::Linear)
    elastic = std::make_unique<btDeformableLinearElasticityForce>(btScalar(kMu), btScalar(kLambda), btScalar(0), btScalar(beta));
  else
    elastic = std::make_unique<btDeformableNeoHookeanForce>(btScalar(kMu), btScalar(kLambda), btScalar(beta));
  world.addForce(sb, elastic.get());

  Run r = drive(sb, m, max_steps, stop_at_rest, [&] { world.stepSimulation(btScalar(dt), 1, btScalar(dt)); });
  world.removeSoftBody(sb);
  delete sb;
  return r;
}

struct PbdParams {
  int piterations = 1;
  double kLST = 1.0;
  double kDP = 0.0;
};

/// Peer B: classic position-based btSoftBody, links on the tet edges.
Run run_pbd(const Mesh& m, const PbdParams& p, double dt, int max_steps, bool stop_at_rest) {
  btSoftBodyRigidBodyCollisionConfiguration cc;
  btCollisionDispatcher disp(&cc);
  btDbvtBroadphase bp;
  btSequentialImpulseConstraintSolver cs;
  btSoftRigidDynamicsWorld world(&disp, &bp, &cs, &cc);
  const btVector3 g(0, btScalar(-kG), 0);
  world.setGravity(g);
  world.getWorldInfo().m_gravity = g;

  auto* sb = new btSoftBody(&world.getWorldInfo(), int(m.x.size()), m.x.data(), m.mass.data());
  sb->m_materials[0]->m_kLST = btScalar(p.kLST);
  std::set<std::pair<int, int>> edges;
  for (const auto& t : m.tets)
    for (int i = 0; i < 4; ++i)
      for (int j = i + 1; j < 4; ++j) edges.insert({std::min(t[i], t[j]), std::max(t[i], t[j])});
  for (const auto& [a, b] : edges) sb->appendLink(a, b);
  sb->m_cfg.piterations = p.piterations;
  sb->m_cfg.kDP = btScalar(p.kDP);
  sb->m_cfg.collisions = 0;
  sb->setActivationState(DISABLE_DEACTIVATION);
  world.addSoftBody(sb);

  Run r = drive(sb, m, max_steps, stop_at_rest, [&] { world.stepSimulation(btScalar(dt), 1, btScalar(dt)); });
  world.removeSoftBody(sb);
  delete sb;
  return r;
}

/// f1 from downward crossings of the tip signal's mean (linear interpolation in time).
double frequency(const std::vector<double>& u, double dt) {
  double mean = 0;
  for (double v : u) mean += v;
  mean /= double(u.size());
  std::vector<double> tc;
  for (std::size_t i = 1; i < u.size(); ++i)
    if (u[i - 1] >= mean && u[i] < mean) tc.push_back(dt * (double(i - 1) + (u[i - 1] - mean) / (u[i - 1] - u[i])));
  if (tc.size() < 2) return 0;
  return double(tc.size() - 1) / (tc.back() - tc.front());
}

struct Row {
  std::string peer, mesh;
  double dt;
  std::string quantity;
  double value, error;
  double ms_per_step, s_per_sim_s;
  double wall_s;  // to the answer: static = the run to rest; f1 = per simulated second
  std::string notes;
};
std::vector<Row> rows;

void add(const std::string& peer, const Mesh& m, double dt, const std::string& q, double value, double ref,
         const Run& r, const std::string& notes) {
  double total = 0;
  for (double v : r.step_ms) total += v;
  const double per_sim_s = total * 1e-3 / (double(r.step_ms.size()) * dt);
  const bool is_static = q.rfind("static", 0) == 0;
  const double steps_to_answer = r.rest_step > 0 ? r.rest_step : double(r.step_ms.size());
  rows.push_back({peer, m.name, dt, q, value, (value - ref) / ref, median(r.step_ms), per_sim_s,
                  is_static ? steps_to_answer * median(r.step_ms) * 1e-3 : per_sim_s, notes});
  std::printf("  %s %s dt=%g %s = %.5g (%s)\n", peer.c_str(), m.name.c_str(), dt, q.c_str(), value, notes.c_str());
  std::fflush(stdout);
}

std::string fmt(const char* f, double a, double b = 0, double c = 0) {
  char buf[256];
  std::snprintf(buf, sizeof buf, f, a, b, c);
  return buf;
}

std::string rest(const Run& r) {
  return r.rest_step > 0 ? fmt("at rest after %.0f steps", r.rest_step)
                         : fmt("NOT at rest (|du|<1e-5|u|) after %.0f steps", double(r.uy.size()));
}

void peer_a(const Mesh& m, Law law, double dt) {
  const std::string peer = law == Law::Linear ? "A bullet-fem linear" : "A bullet-fem neohookean";
  const double beta = 0.015;  // ~critical for mode 1 (zeta = beta*omega/2)
  Run s = run_deformable(m, law, dt, beta, 5000, true);
  const double uy = s.uy.empty() ? NAN : s.uy.back();
  add(peer, m, dt, "static u_y [m]", uy, kRefUy, s,
      (s.rest_step > 0 ? fmt("at rest after %.0f steps (damping beta=%.3g s)", s.rest_step, beta)
                       : fmt("NOT at rest after %.0f steps", double(s.uy.size()))) +
          fmt("; vs linear-tet FEM h5 %.4g", kLinTetH5Uy));
  // Damping 0 diverges (Bullet's non-Newton step treats elasticity explicitly; only the
  // damping matrix beta*K is implicit), so f1 uses the smallest beta that stays stable.
  const int n = int(std::lround(0.3 / dt));
  Run d0 = run_deformable(m, law, dt, 0.0, n, false);
  const bool undamped_ok = !d0.uy.empty() && std::isfinite(d0.uy.back()) && std::abs(d0.uy.back()) < 0.01;
  double fb = 0;
  Run d = d0;
  for (double b : {0.0, 2.5e-4, 5e-4, 1e-3, 2e-3}) {
    if (b == 0.0 && !undamped_ok) continue;
    if (b > 0.0) d = run_deformable(m, law, dt, b, n, false);
    if (!d.uy.empty() && std::isfinite(d.uy.back()) && std::abs(d.uy.back()) < 0.01) { fb = b; break; }
    fb = -1;
  }
  const double f = fb < 0 ? NAN : frequency(d.uy, dt);
  if (const char* dump = std::getenv("STROMA_BULLET_DUMP")) {  // tip series, for inspection
    std::ofstream o(std::string(dump) + "/" + m.name + (law == Law::Linear ? "_linear" : "_neohookean") + ".txt");
    for (double v : d.uy) o << v << '\n';
  }
  add(peer, m, dt, "f1 [Hz]", f, kRefF1, d,
      (undamped_ok ? std::string("damping 0") : std::string("damping 0 DIVERGES; ")) +
          fmt("beta=%.2g s (zeta1~%.1f%%), downward crossings over 0.3 s", fb, 100 * fb * M_PI * f));
}

double pbd_static(const Mesh& m, PbdParams p, double dt, Run* out = nullptr) {
  p.kDP = 0.02;  // velocity damping to reach rest
  Run r = run_pbd(m, p, dt, int(std::lround(3.0 / dt)), true);  // at most 3 simulated s
  if (out) *out = r;
  std::printf("    pbd %s dt=%g piterations=%d kLST=%.5f: u_y=%.5g, rest step %d, %.3g ms/step\n", m.name.c_str(), dt,
              p.piterations, p.kLST, r.uy.empty() ? NAN : r.uy.back(), r.rest_step, median(r.step_ms));
  std::fflush(stdout);
  return r.uy.empty() ? NAN : r.uy.back();
}

void peer_b(const Mesh& h5, const Mesh& h3, double dt) {
  const std::string peer = "B bullet-pbd";
  Run r;
  PbdParams def;
  double u = pbd_static(h5, def, dt, &r);
  add(peer + " default", h5, dt, "static u_y [m]", u, kRefUy, r,
      fmt("piterations=1 kLST=1 (defaults), kDP=0.02 to rest after %.0f steps; %.1fx softer than linear-tet h5", r.rest_step,
          u / kLinTetH5Uy));
  // Tune: kLST <= 1, so stiffen with piterations (doubling, then integer bisection),
  // then soften with kLST to hit the h5 linear-tet deflection.
  PbdParams p;
  int lo = 1, hi = 1;
  while (std::abs(pbd_static(h5, {hi, 1.0, 0}, dt)) > std::abs(kLinTetH5Uy) && hi < 4096) { lo = hi; hi *= 2; }
  while (hi - lo > 1) {
    const int mid = (lo + hi) / 2;
    (std::abs(pbd_static(h5, {mid, 1.0, 0}, dt)) > std::abs(kLinTetH5Uy) ? lo : hi) = mid;
  }
  p.piterations = hi;
  double klo = 0.0, khi = 1.0;  // deflection too large at klo, too small at khi
  for (int it = 0; it < 12; ++it) {
    const double k = 0.5 * (klo + khi);
    (std::abs(pbd_static(h5, {hi, k, 0}, dt)) > std::abs(kLinTetH5Uy) ? klo : khi) = k;
  }
  p.kLST = khi;
  std::printf("  tuned B: piterations=%d kLST=%.5f\n", p.piterations, p.kLST);
  const std::string tuned = fmt("tuned piterations=%.0f kLST=%.4f", p.piterations, p.kLST);
  u = pbd_static(h5, p, dt, &r);
  add(peer + " tuned", h5, dt, "static u_y [m]", u, kRefUy, r,
      tuned + fmt(" on h5 to hit %.4g; ", kLinTetH5Uy) + rest(r));
  u = pbd_static(h3, p, dt, &r);
  add(peer + " tuned", h3, dt, "static u_y [m]", u, kRefUy, r,
      tuned + fmt(" (from h5); %.3gx the h5 target; ", u / kLinTetH5Uy) + rest(r));
  u = pbd_static(h5, p, dt / 2, &r);
  add(peer + " tuned", h5, dt / 2, "static u_y [m]", u, kRefUy, r,
      tuned + fmt(" (from dt=1ms); %.3gx the h5 target; ", u / kLinTetH5Uy) + rest(r));
  u = pbd_static(h3, def, dt, &r);
  add(peer + " default", h3, dt, "static u_y [m]", u, kRefUy, r,
      "defaults; " + rest(r));
}

}  // namespace

int main(int argc, char** argv) {
  const std::string root = STROMA_SOURCE_DIR;
  // Usage: stroma_bench_bullet [A|B] [--out FILE.csv]   (stroma bench accuracy --peers runs it)
  bool only_a = false, only_b = false;
  std::filesystem::path csv_path = root + "/out/bench/peers/bullet_cantilever.csv";
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "A") only_a = true;
    else if (a == "B") only_b = true;
    else if (a == "--out" && i + 1 < argc) csv_path = argv[++i];
    else {
      std::fprintf(stderr, "usage: stroma_bench_bullet [A|B] [--out FILE.csv]\n");
      return 2;
    }
  }
  const Mesh h5 = prepare(root + "/scenarios/meshes/beam_tet4_h5p000mm.msh", "h5");
  const Mesh h3 = prepare(root + "/scenarios/meshes/beam_tet4_h3p333mm.msh", "h3.333");
  const double dt = 1e-3;
  std::printf("btScalar is %zu bytes\n", sizeof(btScalar));
  if (!only_b) {
    for (const Mesh* m : {&h5, &h3}) peer_a(*m, Law::Linear, dt);
    for (const Mesh* m : {&h5, &h3}) peer_a(*m, Law::NeoHookean, dt);
  }
  if (!only_a) peer_b(h5, h3, dt);

  std::printf("\n| peer | mesh | dt | quantity | value | error vs reference | ms per step | s per simulated s | notes |\n");
  std::printf("|---|---|---|---|---|---|---|---|---|\n");
  for (const auto& r : rows)
    std::printf("| %s | %s | %g | %s | %.5g | %+.1f%% | %.3g | %.3g | %s |\n", r.peer.c_str(), r.mesh.c_str(), r.dt,
                r.quantity.c_str(), r.value, 100 * r.error, r.ms_per_step, r.s_per_sim_s, r.notes.c_str());
  if (csv_path.has_parent_path()) std::filesystem::create_directories(csv_path.parent_path());
  std::ofstream csv(csv_path);
  // wall_s: the wall time to the answer — static rows: the steps to rest; f1 rows: per
  // simulated second (the x axes of stroma bench accuracy's plots).
  csv << "peer,mesh,dt,quantity,value,error_vs_reference,ms_per_step,s_per_simulated_s,wall_s,notes\n";
  for (const auto& r : rows)
    csv << '"' << r.peer << "\"," << r.mesh << ',' << r.dt << ",\"" << r.quantity << "\"," << r.value << ','
        << r.error << ',' << r.ms_per_step << ',' << r.s_per_sim_s << ',' << r.wall_s << ",\"" << r.notes << "\"\n";
  return 0;
}
