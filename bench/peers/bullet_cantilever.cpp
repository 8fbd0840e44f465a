/// \file bullet_cantilever.cpp
/// Peer benchmark, problem "cantilever": Bullet Physics 3.24 (system libbullet, default
/// single-precision build) solving Stroma's cantilever (refs/a, refs/d) on the same meshes.
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

#include "bullet_problems.hpp"

#include <BulletSoftBody/btDeformableGravityForce.h>
#include <BulletSoftBody/btDeformableLinearElasticityForce.h>
#include <BulletSoftBody/btDeformableNeoHookeanForce.h>
#include <BulletSoftBody/btSoftRigidDynamicsWorld.h>

#include <algorithm>
#include <chrono>
#include <fstream>
#include <memory>
#include <set>
#include <utility>

namespace peers {
namespace {

constexpr double kE = 1e7, kNu = 0.3, kRho = 1000.0, kG = 9.81;
constexpr double kMu = kE / (2 * (1 + kNu));
constexpr double kLambda = kE * kNu / ((1 + kNu) * (1 - 2 * kNu));
constexpr double kRefUy = -1.4735e-3;     // converged static tip deflection [m]
constexpr double kRefF1 = 16.100;         // converged first bending frequency [Hz]
constexpr double kLinTetH5Uy = -8.146e-4; // exact linear-tet FEM on h5 (for comparison in notes)

/// The beam mesh (clamped at x = 0) and the tip probe P in it.
struct Beam {
  Mesh m;
  std::array<int, 4> ptet{};  // tet containing P and P's barycentric weights in it
  std::array<double, 4> pw{};
};

/// Reads the beam; finds the tet around P = (0.1, 0.005, 0.005) (largest smallest weight).
Beam prepare(const std::string& path, const std::string& name) {
  Beam b;
  b.m = load_mesh(path, name, kRho, [](double x, double, double) { return x < 1e-6; });
  const std::array<double, 3> P{0.1, 0.005, 0.005};
  std::vector<std::array<double, 3>> nodes;
  std::vector<std::array<int, 4>> raw;
  read_mesh(path, nodes, raw);  // double coordinates, as the weights were computed before
  double best = -1e300;
  for (const auto& t : b.m.tets) {
    std::array<std::array<double, 3>, 4> v;
    for (int k = 0; k < 4; ++k) v[k] = nodes[t[k]];
    auto e = [](const std::array<std::array<double, 3>, 4>& q, int k) {
      return std::array<double, 3>{q[k][0] - q[0][0], q[k][1] - q[0][1], q[k][2] - q[0][2]};
    };
    const double v6 = det3(e(v, 1), e(v, 2), e(v, 3));
    std::array<double, 4> w{};
    for (int i = 0; i < 4; ++i) {
      auto q = v;
      q[i] = P;
      w[i] = det3(e(q, 1), e(q, 2), e(q, 3)) / v6;
    }
    const double wmin = *std::min_element(w.begin(), w.end());
    if (wmin > best) { best = wmin; b.ptet = t; b.pw = w; }
  }
  std::printf("mesh %s: %zu nodes, %zu tets, P in tet with min barycentric weight %.2e\n", name.c_str(),
              b.m.x.size(), b.m.tets.size(), best);
  return b;
}

/// Tip u_y, interpolated in the tet around P.
double tip_uy(const btSoftBody* sb, const Beam& b) {
  double u = 0;
  for (int i = 0; i < 4; ++i) u += b.pw[i] * (double(sb->m_nodes[b.ptet[i]].m_x.y()) - double(b.m.x[b.ptet[i]].y()));
  return u;
}

/// Bullet's neo-Hookean force is Smith et al. 2018's stable neo-Hookean with the log term,
/// Ψ = μ/2 (I_C − 3) + λ/2 (J − 1 − ¾ μ/λ)² − μ/2 log(I_C + 1), and takes μ, λ as they are:
/// linearised at rest that is linear elasticity with μ_eff = ¾ μ and λ_eff = λ − ⅝ μ (27 %
/// softer than E for ν = 0.3). The paper's re-parametrisation μ' = 4/3 μ, λ' = λ + 5/6 μ
/// restores μ, λ at rest: NeoHookeanMatched passes those (what a user who read the paper does).
enum class Law { Linear, NeoHookean, NeoHookeanMatched };

/// Peer A: Bullet's deformable FEM world (default, non-Newton step; see the \file comment).
Run run_deformable(const Beam& b, Law law, double dt, double beta, int max_steps, bool stop_at_rest) {
  const btVector3 g(0, btScalar(-kG), 0);
  DeformableWorld w(g);
  btSoftBody* sb = w.add_body(b.m);
  btDeformableGravityForce gravity(g);
  w.world.addForce(sb, &gravity);
  std::unique_ptr<btDeformableLagrangianForce> elastic;
  if (law == Law::Linear)
    elastic = std::make_unique<btDeformableLinearElasticityForce>(btScalar(kMu), btScalar(kLambda), btScalar(0), btScalar(beta));
  else if (law == Law::NeoHookean)
    elastic = std::make_unique<btDeformableNeoHookeanForce>(btScalar(kMu), btScalar(kLambda), btScalar(beta));
  else  // (damping: Bullet scales μ', λ' by beta, so beta keeps its meaning up to the 4/3)
    elastic = std::make_unique<btDeformableNeoHookeanForce>(btScalar(4.0 / 3.0 * kMu), btScalar(kLambda + 5.0 / 6.0 * kMu),
                                                            btScalar(beta));
  w.world.addForce(sb, elastic.get());

  // float: ~1e-6 jitter, hence 1e-5.
  Run r = drive(max_steps, stop_at_rest, 1e-5, [&] { w.world.stepSimulation(btScalar(dt), 1, btScalar(dt)); },
                [&] { return tip_uy(sb, b); });
  w.world.removeSoftBody(sb);
  delete sb;
  return r;
}

struct PbdParams {
  int piterations = 1;
  double kLST = 1.0;
  double kDP = 0.0;
};

/// Peer B: classic position-based btSoftBody, links on the tet edges.
Run run_pbd(const Beam& b, const PbdParams& p, double dt, int max_steps, bool stop_at_rest) {
  btSoftBodyRigidBodyCollisionConfiguration cc;
  btCollisionDispatcher disp(&cc);
  btDbvtBroadphase bp;
  btSequentialImpulseConstraintSolver cs;
  btSoftRigidDynamicsWorld world(&disp, &bp, &cs, &cc);
  const btVector3 g(0, btScalar(-kG), 0);
  world.setGravity(g);
  world.getWorldInfo().m_gravity = g;

  const Mesh& m = b.m;
  auto* sb = new btSoftBody(&world.getWorldInfo(), int(m.x.size()), m.x.data(), m.mass.data());
  sb->m_materials[0]->m_kLST = btScalar(p.kLST);
  std::set<std::pair<int, int>> edges;
  for (const auto& t : m.tets)
    for (int i = 0; i < 4; ++i)
      for (int j = i + 1; j < 4; ++j) edges.insert({std::min(t[i], t[j]), std::max(t[i], t[j])});
  for (const auto& [e0, e1] : edges) sb->appendLink(e0, e1);
  sb->m_cfg.piterations = p.piterations;
  sb->m_cfg.kDP = btScalar(p.kDP);
  sb->m_cfg.collisions = 0;
  sb->setActivationState(DISABLE_DEACTIVATION);
  world.addSoftBody(sb);

  Run r = drive(max_steps, stop_at_rest, 1e-5, [&] { world.stepSimulation(btScalar(dt), 1, btScalar(dt)); },
                [&] { return tip_uy(sb, b); });
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

/// "at rest after N steps" or "NOT at rest ..." for the notes column.
std::string rest(const Run& r) {
  return r.rest_step > 0 ? fmt("at rest after %.0f steps", r.rest_step)
                         : fmt("NOT at rest (|du|<1e-5|u|) after %.0f steps", double(r.q.size()));
}

/// Peer A on one beam: static deflection (damped run to rest) and f1 (least stable damping).
void peer_a(Table& t, const Beam& b, Law law, double dt) {
  const Mesh& m = b.m;
  const std::string peer = law == Law::Linear       ? "A bullet-fem linear"
                           : law == Law::NeoHookean ? "A bullet-fem neohookean"
                                                    : "A bullet-fem neohookean matched";
  const double beta = 0.015;  // ~critical for mode 1 (zeta = beta*omega/2)
  Run s = run_deformable(b, law, dt, beta, 5000, true);
  const double uy = s.q.empty() ? NAN : s.q.back();
  t.add(peer, m, dt, "static u_y [m]", uy, kRefUy, s,
        (s.rest_step > 0 ? fmt("at rest after %.0f steps (damping beta=%.3g s)", s.rest_step, beta)
                       : fmt("NOT at rest after %.0f steps", double(s.q.size()))) +
          fmt("; vs linear-tet FEM h5 %.4g", kLinTetH5Uy));
  // Damping 0 diverges (Bullet's non-Newton step treats elasticity explicitly; only the
  // damping matrix beta*K is implicit), so f1 uses the smallest beta that stays stable.
  const int n = int(std::lround(0.3 / dt));
  Run d0 = run_deformable(b, law, dt, 0.0, n, false);
  const bool undamped_ok = !d0.q.empty() && std::isfinite(d0.q.back()) && std::abs(d0.q.back()) < 0.01;
  double fb = 0;
  Run d = d0;
  for (double bd : {0.0, 2.5e-4, 5e-4, 1e-3, 2e-3}) {
    if (bd == 0.0 && !undamped_ok) continue;
    if (bd > 0.0) d = run_deformable(b, law, dt, bd, n, false);
    if (!d.q.empty() && std::isfinite(d.q.back()) && std::abs(d.q.back()) < 0.01) { fb = bd; break; }
    fb = -1;
  }
  const double f = fb < 0 ? NAN : frequency(d.q, dt);
  if (const char* dump = std::getenv("STROMA_BULLET_DUMP")) {  // tip series, for inspection
    std::ofstream o(std::string(dump) + "/" + m.name +
                    (law == Law::Linear ? "_linear" : law == Law::NeoHookean ? "_neohookean" : "_neohookean_matched") + ".txt");
    for (double v : d.q) o << v << '\n';
  }
  t.add(peer, m, dt, "f1 [Hz]", f, kRefF1, d,
      (undamped_ok ? std::string("damping 0") : std::string("damping 0 DIVERGES; ")) +
          fmt("beta=%.2g s (zeta1~%.1f%%), downward crossings over 0.3 s", fb, 100 * fb * M_PI * f));
}

/// Peer B: static deflection, run to rest with velocity damping kDP = 0.02.
double pbd_static(const Beam& b, PbdParams p, double dt, Run* out = nullptr) {
  const Mesh& m = b.m;
  p.kDP = 0.02;  // velocity damping to reach rest
  Run r = run_pbd(b, p, dt, int(std::lround(3.0 / dt)), true);  // at most 3 simulated s
  if (out) *out = r;
  std::printf("    pbd %s dt=%g piterations=%d kLST=%.5f: u_y=%.5g, rest step %d, %.3g ms/step\n", m.name.c_str(), dt,
              p.piterations, p.kLST, r.q.empty() ? NAN : r.q.back(), r.rest_step, median(r.step_ms));
  std::fflush(stdout);
  return r.q.empty() ? NAN : r.q.back();
}

/// What tuning peer B to a target deflection found, and what the search cost.
struct Tuned {
  PbdParams p;
  int runs = 0;         // runs to rest the search needed
  double seconds = 0;   // their wall time
};

/// Tunes B on one beam to the target deflection: kLST <= 1, so stiffness comes from piterations
/// (doubling, then integer bisection), then kLST softens to hit the target.
Tuned tune_pbd(const Beam& b, double target, double dt) {
  Tuned t;
  const auto t0 = std::chrono::steady_clock::now();
  auto too_soft = [&](PbdParams q) {
    ++t.runs;
    return std::abs(pbd_static(b, q, dt)) > std::abs(target);
  };
  int lo = 1, hi = 1;
  while (too_soft({hi, 1.0, 0}) && hi < 4096) { lo = hi; hi *= 2; }
  while (hi - lo > 1) {
    const int mid = (lo + hi) / 2;
    (too_soft({mid, 1.0, 0}) ? lo : hi) = mid;
  }
  double klo = 0.0, khi = 1.0;  // deflection too large at klo, too small at khi
  for (int it = 0; it < 12; ++it) {
    const double k = 0.5 * (klo + khi);
    (too_soft({hi, k, 0}) ? klo : khi) = k;
  }
  t.p = {hi, khi, 0};
  t.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::printf("  tuned B on %s to %.4g: piterations=%d kLST=%.5f (%d runs, %.1f s)\n", b.m.name.c_str(), target,
              t.p.piterations, t.p.kLST, t.runs, t.seconds);
  return t;
}

/// Peer B at defaults; then tuned on each mesh to the reference deflection (the tuning's cost
/// in the notes), and each mesh's tuning tried on the other mesh and at dt/2.
void peer_b(Table& t, const Beam& h5, const Beam& h3, double dt) {
  const std::string peer = "B bullet-pbd";
  Run r;
  PbdParams def;
  double u = pbd_static(h5, def, dt, &r);
  t.add(peer + " default", h5.m, dt, "static u_y [m]", u, kRefUy, r,
      fmt("piterations=1 kLST=1 (defaults), kDP=0.02 to rest after %.0f steps; %.1fx softer than linear-tet h5", r.rest_step,
          u / kLinTetH5Uy));
  u = pbd_static(h3, def, dt, &r);
  t.add(peer + " default", h3.m, dt, "static u_y [m]", u, kRefUy, r, "defaults; " + rest(r));
  for (const Beam* on : {&h5, &h3}) {
    const Beam* other = on == &h5 ? &h3 : &h5;
    const Tuned tu = tune_pbd(*on, kRefUy, dt);
    const std::string name = "tuned on " + on->m.name;
    const std::string cost = fmt("; tuning: %.0f runs to rest, %.0f s", tu.runs, tu.seconds);
    u = pbd_static(*on, tu.p, dt, &r);
    t.add(peer + " " + name, on->m, dt, "static u_y [m]", u, kRefUy, r,
          fmt("piterations=%.0f kLST=%.4f to hit the reference %.4g", tu.p.piterations, tu.p.kLST, kRefUy) + cost + "; " + rest(r));
    u = pbd_static(*other, tu.p, dt, &r);
    t.add(peer + " " + name, other->m, dt, "static u_y [m]", u, kRefUy, r,
          "the " + on->m.name + " tuning carried over: " + fmt("%.3gx the reference; ", u / kRefUy) + rest(r));
    u = pbd_static(*on, tu.p, dt / 2, &r);
    t.add(peer + " " + name, on->m, dt / 2, "static u_y [m]", u, kRefUy, r,
          fmt("the dt=1ms tuning at dt=0.5ms: %.3gx the reference; ", u / kRefUy) + rest(r));
  }
}

}  // namespace

Table run_cantilever(const std::string& root, bool run_a, bool run_b) {
  Table t;
  t.problem = "cantilever";
  const Beam h5 = prepare(root + "/scenarios/meshes/beam_tet4_h5p000mm.msh", "h5");
  const Beam h3 = prepare(root + "/scenarios/meshes/beam_tet4_h3p333mm.msh", "h3.333");
  const double dt = 1e-3;
  if (run_a) {
    for (const Beam* b : {&h5, &h3}) peer_a(t, *b, Law::Linear, dt);
    for (const Beam* b : {&h5, &h3}) peer_a(t, *b, Law::NeoHookean, dt);
    for (const Beam* b : {&h5, &h3}) peer_a(t, *b, Law::NeoHookeanMatched, dt);
  }
  if (run_b) peer_b(t, h5, h3, dt);
  return t;
}

}  // namespace peers
