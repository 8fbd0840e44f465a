/// \file bullet_indentation.cpp
/// Peer benchmark, problem "indentation": Bullet 3.24's FEM indented 1 mm by a rigid sphere
/// (refs/e): block [-0.05, 0.05]^2 x [0, 0.05], E = 5000 Pa, nu = 0.45, density 1000, no
/// gravity, bottom fixed; sphere R = 5 mm on the z axis, touching at t = 0, pushed down 1 mm.
///
/// Fairness choices:
///  - the same mesh as Stroma's: Stroma's quarter block (write_quarter_block, growth 1.3, the
///    first cells of its grading sweep) mirrored in x = 0 and y = 0 with the plane nodes welded,
///    because Bullet cannot hold single axes (Stroma uses the quarter with roller planes);
///  - the same material (Lame mu, lambda from E, nu), lumped masses rho*V/4, bottom fixed
///    (inverse mass 0);
///  - the force is the support reaction: minus the sum of Bullet's own elastic forces over the
///    fixed bottom nodes at rest (internal forces sum to zero, so at rest it equals the contact
///    force on the free nodes, i.e. the indenter force) — not the contact impulses / dt, which
///    stay inside Bullet's constraint solver.
/// What differs:
///  - contact: Bullet's deformable-rigid node contact (SDF_RD | SDF_RDN: the sphere's sampled
///    signed-distance field against the nodes, velocity-level constraint, frictionless kDF = 0)
///    against Stroma's penalty contact (1e9 Pa/m), so both have their own contact error;
///  - no static solve: the sphere (a kinematic btRigidBody) is lowered at constant speed over
///    kRamp s, then held while stiffness damping beta brings the block to rest;
///  - float (btScalar = float) against Stroma's double;
///  - peer B (classic btSoftBody) is not run: no material law, no force to measure.
///
/// Two settings make Bullet's contact hold the surface (measured 2026-12-01; without them the
/// sphere sank 1 mm into the block with a reaction of ~1e-6 N, docs/ACCURACY.md):
///  1. Contacts are detected at the nodes' current positions x_n (a near callback on the
///     dispatcher sets m_q = m_x around Bullet's own collision handler and restores m_q after).
///     In the default (explicit-elasticity) step Bullet detects node contacts at the predicted
///     x_n + dt v*, where v* = v_n + dt f_elastic(x_n)/m is the *undamped explicit* velocity
///     (btDeformableBodySolver::predictDeformableMotion: m_q = m_x + m_v * dt; CollideSDF_RD::DoNode
///     tests m_q). With dt = 5 ms on these nodes (explicit limit ~0.5 ms) that prediction moves a
///     pressed node 4-13 mm upward, i.e. out through the 10 mm sphere, so every node the sphere
///     pushes is dropped from the contact list the next step; the implicit damping solve then
///     keeps the real motion small, so the sphere just sinks in. Bullet's Newton mode
///     (setImplicit(true)) detects at x_n for this reason, but in 3.24 it diverges here (its
///     "effective mass" predictor blew a node velocity to 1e35 m/s on the 3 mm test mesh), so
///     the default step is kept and only the detection point is moved to x_n.
///  2. world.setUseProjection(true) (as Bullet's own deformable demos): contact constraints as
///     projections in the CG solve (m_cg, tightened by DeformableSolver::configure). The default
///     (false) adds them as Lagrange multipliers to a conjugate-residual solve (m_cr, Bullet's
///     default settings); with 1. alone that pushed the 3 mm test mesh's single contact node but
///     not the 6k-node mesh's 5-30 contact nodes (sphere 0.9 mm deep, reaction 1e-5 N).
///  Plus: node margin 1 um (the contact holds the nodes at ~margin from the sphere: 10 um gave
///  ~1 % less indentation) and m_deformable_erp 0.3 (Bullet's demos use 0.1-0.3; 0.06 creeps).
///  With these the top-centre node follows the sphere to within ~1 um. Still open: on a 3 mm
///  test mesh (one contact node) the reaction settles to |dF| < 5e-4 F (chatter ~1.5e-4), but on
///  the 0.8 mm mesh (19-21 contact nodes) rim nodes drop in and out of contact every few steps
///  and the reaction wanders by ~+-2-3 % through the whole hold (0.4 mm: ~+-6 %), so those rows
///  report "NOT at rest" and, while the last 0.25 s stay within +-10 % of their mean, that mean
///  as the value, with the band in the notes (looser CG: unstable; mass damping alpha 50/s,
///  erp 0.06, cfm 0, margin 10 um, no split impulse: still wandering).

#include "bullet_problems.hpp"

#include "bench/accuracy/quarter_block_mesh.hpp"

#include <BulletSoftBody/btDeformableLinearElasticityForce.h>

#include <algorithm>
#include <filesystem>
#include <map>
#include <set>
#include <utility>

namespace peers {
namespace {

constexpr double kE = 5000, kNu = 0.45, kRho = 1000.0;
constexpr double kMu = kE / (2 * (1 + kNu));
constexpr double kLambda = kE * kNu / ((1 + kNu) * (1 - 2 * kNu));
constexpr double kA = 0.05, kH = 0.05, kR = 0.005, kD = 0.001;
constexpr double kRefForce = 0.019604;  // N, Hertz with the bonded-layer correction (refs/e)
constexpr double kBeta = 0.05;          // s: ~critical damping of the block's lowest mode (~6 Hz)
constexpr double kRamp = 0.5;           // s to lower the sphere: > 3 periods of the lowest mode
constexpr double kHold = 1.0;           // s at most of holding before giving up on rest
constexpr double kErp = 0.3;            // contact position correction per step (Bullet default 0.06)
constexpr double kRestTol = 5e-4;       // |dF| < kRestTol*F for 20 steps: above the float chatter

/// Dispatcher near callback: Bullet's own collision handling, with the soft bodies' m_q set to
/// their current positions m_x while it runs (see the header: detection at x_n, not at the
/// explicit prediction), m_q restored afterwards so the rest of Bullet's step is unchanged.
void near_callback_at_current_positions(btBroadphasePair& pair, btCollisionDispatcher& dispatcher,
                                        const btDispatcherInfo& info) {
  btSoftBody* soft[2] = {btSoftBody::upcast(static_cast<btCollisionObject*>(pair.m_pProxy0->m_clientObject)),
                         btSoftBody::upcast(static_cast<btCollisionObject*>(pair.m_pProxy1->m_clientObject))};
  std::vector<btVector3> q[2];
  for (int k = 0; k < 2; ++k)
    if (soft[k])
      for (int i = 0; i < soft[k]->m_nodes.size(); ++i) {
        q[k].push_back(soft[k]->m_nodes[i].m_q);
        soft[k]->m_nodes[i].m_q = soft[k]->m_nodes[i].m_x;
      }
  btCollisionDispatcher::defaultNearCallback(pair, dispatcher, info);
  for (int k = 0; k < 2; ++k)
    if (soft[k])
      for (int i = 0; i < soft[k]->m_nodes.size(); ++i) soft[k]->m_nodes[i].m_q = q[k][i];
}

/// Stroma's graded quarter block (first cell h0) mirrored into the full block.
Mesh full_block(const std::string& dir, double h0) {
  std::filesystem::create_directories(dir);
  const std::string q = stroma::write_quarter_block(
      (std::filesystem::path(dir) / fmt("bullet_indentation_quarter_%gmm.msh", h0 * 1e3)).string(), kA, kH, h0, 1.3);
  std::vector<std::array<double, 3>> qn, nodes;
  std::vector<std::array<int, 4>> qt, tets;
  read_mesh(q, qn, qt);
  std::map<std::array<double, 3>, int> index;  // exact coordinates: mirrored plane nodes coincide
  for (double sx : {1.0, -1.0})
    for (double sy : {1.0, -1.0}) {
      std::vector<int> map(qn.size());
      for (std::size_t i = 0; i < qn.size(); ++i) {
        const std::array<double, 3> p{qn[i][0] == 0 ? 0.0 : sx * qn[i][0], qn[i][1] == 0 ? 0.0 : sy * qn[i][1], qn[i][2]};
        const auto [it, added] = index.emplace(p, int(nodes.size()));
        if (added) nodes.push_back(p);
        map[i] = it->second;
      }
      for (const auto& t : qt) tets.push_back({map[t[0]], map[t[1]], map[t[2]], map[t[3]]});  // make_mesh re-orients
    }
  std::vector<bool> fixed(nodes.size());
  for (std::size_t i = 0; i < nodes.size(); ++i) fixed[i] = nodes[i][2] < 1e-9;
  Mesh m = make_mesh(fmt("first cell %g mm", h0 * 1e3), nodes, tets, kRho, fixed);
  std::printf("mesh %s: quarter %zu nodes -> full %zu nodes, %zu tets\n", m.name.c_str(), qn.size(), m.x.size(),
              m.tets.size());
  std::fflush(stdout);
  return m;
}

/// z of the node at (0, 0, H) now: how deep it went against the sphere's lowest point.
double top_centre_z(const btSoftBody* sb, const Mesh& m) {
  for (int i = 0; i < sb->m_nodes.size(); ++i)
    if (m.x[i].x() == 0 && m.x[i].y() == 0 && m.x[i].z() > btScalar(kH - 1e-7)) return sb->m_nodes[i].m_x.z();
  return NAN;
}

/// What one indentation run ended with.
struct Indent {
  Run run;
  double centre_z = NAN;  // the top-centre node at the end
  int contacts = 0;       // Bullet's node-rigid contacts in the last step
};

/// Lowers the sphere over kRamp, holds it until the bottom reaction is at rest (q per step).
Indent indent(const Mesh& m, double dt, double margin, double voxel) {
  DeformableWorld w(btVector3(0, 0, 0));
  w.world.getWorldInfo().m_sparsesdf.setDefaultVoxelsz(btScalar(voxel));
  w.world.getWorldInfo().m_sparsesdf.Reset();
  btSoftBody* sb = w.add_body(m);
  // Contact: rigid vs deformable nodes through the sphere's signed-distance field, full
  // hardness for kinematic contacts, no friction (refs/e is frictionless).
  sb->getCollisionShape()->setMargin(btScalar(margin));
  sb->m_cfg.collisions = btSoftBody::fCollision::SDF_RD | btSoftBody::fCollision::SDF_RDN;
  sb->m_cfg.kKHR = 1;
  sb->m_cfg.kCHR = 1;
  sb->m_cfg.kDF = 0;
  // The two settings of the header: contacts detected at x_n, constraints as CG projections.
  w.disp.setNearCallback(near_callback_at_current_positions);
  w.world.setUseProjection(true);
  w.world.getSolverInfo().m_deformable_erp = btScalar(kErp);
  // The contact setup builds Bullet's node tree bottom-up from the link graph; without links it
  // takes minutes on 6k nodes, so the tet edges go in as links (the FEM forces ignore links).
  // No boundary faces: node contacts (SDF_RDN) do not use them.
  std::set<std::pair<int, int>> edges;
  for (const auto& t : m.tets)
    for (int i = 0; i < 4; ++i)
      for (int j = i + 1; j < 4; ++j) edges.insert({std::min(t[i], t[j]), std::max(t[i], t[j])});
  for (const auto& [a, b] : edges) sb->appendLink(a, b);
  std::vector<int> bottom;
  for (int i = 0; i < sb->m_nodes.size(); ++i)
    if (m.mass[i] == 0) bottom.push_back(i);
  btDeformableLinearElasticityForce elastic(btScalar(kMu), btScalar(kLambda), btScalar(0), btScalar(kBeta));
  w.world.addForce(sb, &elastic);

  btSphereShape sphere{btScalar(kR)};
  auto at = [](double z) { return btTransform(btQuaternion::getIdentity(), btVector3(0, 0, btScalar(z))); };
  btDefaultMotionState motion(at(kH + kR));
  btRigidBody body(btRigidBody::btRigidBodyConstructionInfo(0, &motion, &sphere));
  body.setCollisionFlags(body.getCollisionFlags() | btCollisionObject::CF_KINEMATIC_OBJECT);
  body.setActivationState(DISABLE_DEACTIVATION);
  body.setFriction(0);
  w.world.addRigidBody(&body);

  const int ramp = int(std::lround(kRamp / dt));
  int s = 0;
  auto step = [&] {
    ++s;  // kinematic: Bullet reads the motion state each step and derives the velocity
    motion.setWorldTransform(at(kH + kR - kD * std::min(1.0, double(s) / ramp)));
    w.world.stepSimulation(btScalar(dt), 1, btScalar(dt));
  };
  auto reaction = [&] {
    const std::vector<btVector3> f = elastic_forces(sb, elastic);
    double fz = 0;
    for (int i : bottom) fz -= double(f[i].z());
    return std::abs(fz) < 1e3 * kRefForce ? fz : NAN;  // blown up: stop as unstable
  };
  // Rest only counts once the ramp is over (a force that stalls during it is no answer).
  Indent out;
  out.run = drive(ramp + int(std::lround(kHold / dt)), true, kRestTol, step, reaction, ramp);
  out.centre_z = top_centre_z(sb, m);
  out.contacts = sb->m_nodeRigidContacts.size();
  std::printf("    dt=%g margin=%g voxel=%g: F=%.6g N, rest step %d, %.3g ms/step; top centre node at z=%.6g "
              "(sphere bottom at %.6g), %d node contacts\n", dt, margin, voxel,
              out.run.q.empty() ? NAN : out.run.q.back(), out.run.rest_step, median(out.run.step_ms), out.centre_z,
              kH - kD, out.contacts);
  std::fflush(stdout);
  w.world.removeRigidBody(&body);
  w.world.removeSoftBody(sb);
  delete sb;
  return out;
}

}  // namespace

Table run_indentation(const std::string& work_dir, bool quick) {
  Table t;
  t.problem = "indentation";
  // dt 5 ms: stable with beta = 50 ms (explicit elasticity needs dt < ~2 beta); the sphere moves
  // 10 um per step. Margin 1 um (0.1 % of d) and SDF voxels 0.25 mm (the sphere's distance field
  // sampled finer than the smallest cell).
  const double dt = 5e-3, margin = 1e-6, voxel = 2.5e-4;
  for (double h0 : quick ? std::vector<double>{8e-4, 4e-4} : std::vector<double>{8e-4, 4e-4, 2e-4}) {
    const Mesh m = full_block(work_dir, h0);
    const Indent in = indent(m, dt, margin, voxel);
    const Run& r = in.run;
    const double f = r.q.empty() ? NAN : r.q.back();
    // Mean and range of the last 0.25 s: what a not-at-rest run's reaction wanders within.
    const std::size_t tail = std::min(r.q.size(), std::size_t(std::lround(0.25 / dt)));
    double mean = 0, lo = INFINITY, hi = -INFINITY;
    for (std::size_t i = r.q.size() - tail; i < r.q.size(); ++i) {
      mean += r.q[i] / double(tail);
      lo = std::min(lo, r.q[i]);
      hi = std::max(hi, r.q[i]);
    }
    // A reaction that never settles but wanders within ±10 % of its mean over the last 0.25 s
    // is reported as that mean (the notes say so and give the band); wider: no answer (NaN).
    const bool banded = r.rest_step <= 0 && std::isfinite(mean) && mean > 0 && hi - lo < 0.2 * mean;
    const double value = r.rest_step > 0 ? f : banded ? mean : NAN;
    t.add("A bullet-fem linear", m, dt, "indenter force [N]", value, kRefForce, r,
          (r.rest_step > 0 ? fmt("at rest after %.0f steps", r.rest_step)
                           : fmt("NOT at rest after %.0f steps (last %.4g N", double(r.q.size()), f) +
                                 fmt(", last 0.25 s: mean %.4g N, range %.4g..%.4g N", mean, lo, hi) +
                                 (banded ? "; value = that mean)" : ")")) +
              fmt(" (ramp %.2g s, beta=%.3g s, rest |dF|<%.0e F); ", kRamp, kBeta, kRestTol) +
              fmt("top centre node moved %.3g mm of the sphere's 1 mm, %.0f node contacts; ", 1e3 * (kH - in.centre_z),
                  in.contacts) +
              fmt("margin %g m, SDF voxel %g m, erp %g; ", margin, voxel, kErp) + "contacts detected at x_n, setUseProjection(true)");
  }
  return t;
}

}  // namespace peers
