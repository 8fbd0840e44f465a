/// \file bullet_block.cpp
/// Peer benchmark, problem "block": Bullet 3.24's FEM on the bonded near-incompressible block
/// (refs/c): cube [0, 0.05]^3, E = 1e4 Pa, nu = 0.49, density 1000, no gravity; bottom face
/// fixed, top face moved down 0.5 mm and fixed; quantity: the total top force.
///
/// Fairness choices (equal to Stroma's run_block in the accuracy suite):
///  - the same mesh files (cube_tet4_h{5p000,3p333,2p500}mm.msh), Stroma's reader, lumped
///    masses rho*V/4; fixed nodes = inverse mass 0 (the top ones moved first, so every dof of
///    both faces is prescribed, as in Stroma and CalculiX);
///  - the force is Bullet's own: the sum over the top nodes of its elastic force
///    (btDeformableLinearElasticityForce::addScaledElasticForce) at the final state;
///  - compared with the C3D10 reference and with CalculiX C3D4 on the same mesh (the exact
///    linear-tet answer, locking included, which Bullet's linear tets should reproduce).
/// What differs:
///  - Bullet has no static solve: the answer is the state reached by running with stiffness
///    damping beta until the force stops changing (|dF| < 1e-5 |F| for 20 steps; float jitter
///    is ~3e-6 of F);
///  - its elastic force is explicit and only the damping beta*K is implicit, so dt is stable
///    only up to ~2*beta (stiff modes); the dt sweep on h5 finds where it breaks (32 ms here);
///  - float (btScalar = float) against Stroma's double;
///  - peer B (classic btSoftBody) is not run: it has no material law and no force output.

#include "bullet_problems.hpp"

#include <BulletSoftBody/btDeformableLinearElasticityForce.h>

#include <algorithm>
#include <fstream>

#include <nlohmann/json.hpp>

namespace peers {
namespace {

constexpr double kE = 1e4, kNu = 0.49, kRho = 1000.0;
constexpr double kMu = kE / (2 * (1 + kNu));
constexpr double kLambda = kE * kNu / ((1 + kNu) * (1 - 2 * kNu));
constexpr double kA = 0.05, kDelta = 5e-4;
constexpr double kRefForce = 0.3049;  // N, converged C3D10 (refs/c)
constexpr double kBeta = 0.02;        // s: ~critical damping of the lowest (shear) mode, ~18 Hz

/// CalculiX C3D4 top force on the same mesh (tests/data/refs); 0 if absent.
double c3d4_force(const std::string& root, const std::string& tag) {
  std::ifstream f(root + "/tests/data/refs/c_results_full_C3D4_uniform.json");
  for (const auto& r : nlohmann::json::parse(f))
    if (r["job"] == "cube_o1_h" + tag + "mm") return -r["top_rf"][2].get<double>();
  return 0;
}

/// One run to rest at step dt; returns the run (q = top force after each step).
Run press(const Mesh& m, double dt, int max_steps) {
  DeformableWorld w(btVector3(0, 0, 0));
  btSoftBody* sb = w.add_body(m);
  std::vector<int> top;
  for (int i = 0; i < sb->m_nodes.size(); ++i)
    if (m.x[i].z() > btScalar(kA - 1e-7)) {
      top.push_back(i);
      sb->m_nodes[i].m_x.setZ(sb->m_nodes[i].m_x.z() - btScalar(kDelta));  // Dm^-1 already at rest
      sb->m_nodes[i].m_q = sb->m_nodes[i].m_x;
    }
  btDeformableLinearElasticityForce elastic(btScalar(kMu), btScalar(kLambda), btScalar(0), btScalar(kBeta));
  w.world.addForce(sb, &elastic);
  auto top_force = [&] {
    const std::vector<btVector3> f = elastic_forces(sb, elastic);
    double fz = 0;
    for (int i : top) fz += double(f[i].z());
    return std::abs(fz) < 1e4 * kRefForce ? fz : NAN;  // blown up (the first steps reach ~100x): unstable
  };
  Run r = drive(max_steps, true, 1e-5, [&] { w.world.stepSimulation(btScalar(dt), 1, btScalar(dt)); }, top_force);
  w.world.removeSoftBody(sb);
  delete sb;
  return r;
}

/// Runs mesh `tag` at dt and adds the row; returns the steps to rest (0: unstable / not at rest).
int row(Table& t, const std::string& root, const Mesh& m, const std::string& tag, double dt) {
  const int max_steps = int(std::lround(2.0 / dt)) + 200;  // 2 simulated s: 100 beta
  const Run r = press(m, dt, max_steps);
  const double f = r.q.empty() ? NAN : r.q.back();
  const bool ok = r.rest_step > 0 && std::isfinite(f);
  t.add("A bullet-fem linear", m, dt, "top force [N]", ok ? f : NAN, kRefForce, r,
        (ok ? fmt("at rest after %.0f steps", r.rest_step)
            : std::isfinite(f) ? fmt("NOT at rest after %.0f steps (last %.4g N, previous %.4g N)", double(r.q.size()), f,
                                     r.q.size() > 1 ? r.q[r.q.size() - 2] : NAN)
                               : fmt("DIVERGED at step %.0f", double(r.q.size()))) +
            fmt(" (damping beta=%.3g s); C3D4 same mesh %.5g N", kBeta, c3d4_force(root, tag)),
        c3d4_force(root, tag));
  return ok ? r.rest_step : 0;
}

}  // namespace

Table run_block(const std::string& root) {
  Table t;
  t.problem = "block";
  auto fixed = [](double, double, double z) { return z < 1e-7 || z > kA - 1e-7; };
  auto mesh = [&](const std::string& tag) {
    std::string name = "h" + tag;  // "h5p000" -> "h5.000", as the accuracy suite labels it
    std::replace(name.begin(), name.end(), 'p', '.');
    Mesh m = load_mesh(root + "/scenarios/meshes/cube_tet4_h" + tag + "mm.msh", name, kRho, fixed);
    std::printf("mesh %s: %zu nodes, %zu tets\n", m.name.c_str(), m.x.size(), m.tets.size());
    return m;
  };
  // dt sweep on the coarsest mesh: 1 ms (Stroma's dynamic step) doubling up to the first
  // failure. Small steps stall short of equilibrium in float (x += dt*v rounds away once dt*v
  // is below half an ulp of x, and stiffness damping makes v that small early), so the rest
  // value moves with dt; the finer meshes run at the dt that reached rest in the fewest steps.
  const Mesh h5 = mesh("5p000");
  double largest = 0, fastest = 0;
  int fewest = 1 << 30;
  for (double dt = 1e-3; dt < 0.5; dt *= 2) {
    const int steps = row(t, root, h5, "5p000", dt);
    if (steps == 0) break;
    largest = dt;
    if (steps < fewest) { fewest = steps; fastest = dt; }
  }
  std::printf("  h5: largest stable dt %g s, fewest steps to rest at dt %g s\n", largest, fastest);
  if (fastest == 0) return t;
  for (const std::string tag : {"3p333", "2p500"}) row(t, root, mesh(tag), tag, fastest);
  return t;
}

}  // namespace peers
