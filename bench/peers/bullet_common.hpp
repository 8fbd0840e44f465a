#pragma once
/// \file bullet_common.hpp
/// Shared pieces of the Bullet 3.24 peer benchmark (stroma_bench_bullet): meshes read with
/// Stroma's reader and lumped the way Stroma lumps them, Bullet's deformable (FEM) world set up
/// the same way for every problem, the run-to-rest driver and the result table/CSV.

#include <btBulletDynamicsCommon.h>
#include <BulletSoftBody/btDeformableBodySolver.h>
#include <BulletSoftBody/btDeformableLinearElasticityForce.h>
#include <BulletSoftBody/btDeformableMultiBodyConstraintSolver.h>
#include <BulletSoftBody/btDeformableMultiBodyDynamicsWorld.h>
#include <BulletSoftBody/btSoftBodyRigidBodyCollisionConfiguration.h>

#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

namespace peers {

/// A tet mesh in Bullet's types: positively oriented tets, lumped masses rho*V/4 (0 = fixed).
struct Mesh {
  std::string name;
  std::vector<btVector3> x;
  std::vector<std::array<int, 4>> tets;
  std::vector<btScalar> mass;
};

/// Non-template core of load_mesh: raw nodes and tets in, oriented and lumped mesh out.
Mesh make_mesh(const std::string& name, const std::vector<std::array<double, 3>>& nodes,
               std::vector<std::array<int, 4>> tets, double rho, const std::vector<bool>& fixed);

/// The Stroma tet mesh at `path` as raw arrays (Stroma's own reader).
void read_mesh(const std::string& path, std::vector<std::array<double, 3>>& nodes, std::vector<std::array<int, 4>>& tets);

/// Reads a Gmsh file with Stroma's reader; tets re-ordered to positive volume, masses lumped
/// with density rho; nodes for which fixed(x, y, z) holds get mass 0 (Bullet's "fixed").
template <class Fixed>
Mesh load_mesh(const std::string& path, const std::string& name, double rho, Fixed&& fixed) {
  std::vector<std::array<double, 3>> nodes;
  std::vector<std::array<int, 4>> tets;
  read_mesh(path, nodes, tets);
  std::vector<bool> fix(nodes.size());
  for (std::size_t i = 0; i < nodes.size(); ++i) fix[i] = fixed(nodes[i][0], nodes[i][1], nodes[i][2]);
  return make_mesh(name, nodes, std::move(tets), rho, fix);
}

double det3(const std::array<double, 3>& a, const std::array<double, 3>& b, const std::array<double, 3>& c);
double median(std::vector<double> v);
/// snprintf into a std::string (up to three numbers).
std::string fmt(const char* f, double a, double b = 0, double c = 0);

/// Exposes the deformable solver's protected CG settings.
struct DeformableSolver : btDeformableBodySolver {
  /// CG tolerance 1e-10 (Bullet's default ~1.2e-7 is loose for statics), at most 2000 iterations.
  void configure() {
    m_cg.setTolerance(btScalar(1e-10));
    m_cg.m_maxIterations = 2000;
  }
};

/// Bullet's deformable FEM world with Bullet's default (non-Newton) step, no gravity unless set.
struct DeformableWorld {
  btSoftBodyRigidBodyCollisionConfiguration cc;
  btCollisionDispatcher disp{&cc};
  btDbvtBroadphase bp;
  DeformableSolver solver;
  btDeformableMultiBodyConstraintSolver cs;
  btDeformableMultiBodyDynamicsWorld world;
  /// gravity g in m/s^2 (also Bullet's soft-body world info).
  explicit DeformableWorld(const btVector3& g);
  /// Adds the mesh as a volumetric soft body (Dm^-1 at the rest shape, no self-collision).
  btSoftBody* add_body(const Mesh& m);
};

/// Nodal elastic forces of `force` at the nodes' current positions m_x (Bullet evaluates its
/// deformation gradients at m_q; swapped in and back so the next step is not disturbed).
std::vector<btVector3> elastic_forces(btSoftBody* sb, btDeformableLinearElasticityForce& force);

/// Per-step wall times and a scalar per step; rest_step > 0 once the scalar settled.
struct Run {
  std::vector<double> q;        // the monitored quantity after each step
  std::vector<double> step_ms;  // wall time per step (the monitor not included)
  int rest_step = -1;           // first step at which the run was at rest (static runs)
};

/// Steps until |dq| < tol*|q| for 20 consecutive steps from step settle_from on (stop_at_rest)
/// or max_steps; the monitor q() runs after each step and is not timed.
template <class Step, class Monitor>
Run drive(int max_steps, bool stop_at_rest, double tol, Step&& step, Monitor&& q, int settle_from = 0) {
  Run r;
  int calm = 0;
  for (int s = 0; s < max_steps; ++s) {
    const auto t0 = std::chrono::steady_clock::now();
    step();
    const auto t1 = std::chrono::steady_clock::now();
    r.step_ms.push_back(std::chrono::duration<double, std::milli>(t1 - t0).count());
    r.q.push_back(q());
    if (!std::isfinite(r.q.back())) break;
    if (stop_at_rest && s > settle_from) {
      const double dq = std::abs(r.q[s] - r.q[s - 1]);
      calm = (dq < tol * std::abs(r.q[s])) ? calm + 1 : 0;
      if (calm >= 20) { r.rest_step = s + 1; break; }
    }
  }
  return r;
}

/// One result row (a line of the problem's CSV).
struct Row {
  std::string peer, mesh;
  int nodes;
  double dt;
  std::string quantity;
  double value, error;     // error: (value - reference) / reference
  double ms_per_step, s_per_sim_s;
  double wall_s;           // to the answer: static = the steps to rest; f1 = per simulated second
  int steps;               // steps run (static: to rest)
  double same_mesh;        // exact linear-tet FEM (CalculiX C3D4) value on this mesh; 0: none
  std::string notes;
};

/// The rows of one problem: printed as Markdown and written as CSV.
struct Table {
  std::string problem;
  std::vector<Row> rows;
  /// Adds a row from a run (static quantities: wall time = steps to rest x median step).
  void add(const std::string& peer, const Mesh& m, double dt, const std::string& quantity, double value, double ref,
           const Run& r, const std::string& notes, double same_mesh = 0);
  void print() const;
  /// Writes DIR/bullet_<problem>.csv.
  void write(const std::string& dir) const;
};

}  // namespace peers
