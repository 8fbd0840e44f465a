/// \file bullet_common.cpp
/// Shared pieces of the Bullet peer benchmark (see bullet_common.hpp).

#include "bullet_common.hpp"

#include "io/mesh_io.hpp"

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <utility>

namespace peers {

double det3(const std::array<double, 3>& a, const std::array<double, 3>& b, const std::array<double, 3>& c) {
  return a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) + a[2] * (b[0] * c[1] - b[1] * c[0]);
}

void read_mesh(const std::string& path, std::vector<std::array<double, 3>>& nodes, std::vector<std::array<int, 4>>& tets) {
  const stroma::TetMesh tm = stroma::load_tet_mesh(path);
  nodes.clear();
  tets.clear();
  for (const auto& p : tm.nodes) nodes.push_back({p[0], p[1], p[2]});
  for (const auto& t : tm.tets) tets.push_back({int(t[0]), int(t[1]), int(t[2]), int(t[3])});
}

Mesh make_mesh(const std::string& name, const std::vector<std::array<double, 3>>& nodes,
               std::vector<std::array<int, 4>> tets, double rho, const std::vector<bool>& fixed) {
  Mesh m;
  m.name = name;
  std::vector<double> mass(nodes.size(), 0.0);
  for (auto& t : tets) {
    auto d = [&](int i) {
      const auto& p = nodes[t[i]];
      const auto& o = nodes[t[0]];
      return std::array<double, 3>{p[0] - o[0], p[1] - o[1], p[2] - o[2]};
    };
    double v6 = det3(d(1), d(2), d(3));
    if (v6 < 0) { std::swap(t[1], t[2]); v6 = -v6; }
    for (int i = 0; i < 4; ++i) mass[t[i]] += rho * v6 / 6.0 / 4.0;
  }
  m.tets = std::move(tets);
  for (std::size_t i = 0; i < nodes.size(); ++i) {
    m.x.emplace_back(btScalar(nodes[i][0]), btScalar(nodes[i][1]), btScalar(nodes[i][2]));
    m.mass.push_back(fixed[i] ? btScalar(0) : btScalar(mass[i]));
  }
  return m;
}

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

std::string fmt(const char* f, double a, double b, double c) {
  char buf[256];
  std::snprintf(buf, sizeof buf, f, a, b, c);
  return buf;
}

DeformableWorld::DeformableWorld(const btVector3& g) : world(&disp, &bp, &cs, &cc, &solver) {
  cs.setDeformableSolver(&solver);
  world.setGravity(g);
  world.getWorldInfo().m_gravity = g;
  // world.setImplicit(true) (Newton) leaves the body frozen in 3.24 (zero motion; the world
  // overwrites the solver's own flag each step), so the default is kept: one linearised
  // backward-Euler step per dt, elastic Hessian + damping in a CG solve.
  world.setImplicit(false);
  solver.configure();
}

btSoftBody* DeformableWorld::add_body(const Mesh& m) {
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
  return sb;
}

std::vector<btVector3> elastic_forces(btSoftBody* sb, btDeformableLinearElasticityForce& force) {
  const int n = sb->m_nodes.size();
  std::vector<btVector3> q(n);
  for (int i = 0; i < n; ++i) {
    q[i] = sb->m_nodes[i].m_q;
    sb->m_nodes[i].m_q = sb->m_nodes[i].m_x;
    sb->m_nodes[i].index = i;  // the force indexes its output by node.index
  }
  sb->updateDeformation();
  btAlignedObjectArray<btVector3> f;
  f.resize(n, btVector3(0, 0, 0));
  force.addScaledElasticForce(1, f);
  for (int i = 0; i < n; ++i) sb->m_nodes[i].m_q = q[i];
  sb->updateDeformation();
  std::vector<btVector3> out(n);
  for (int i = 0; i < n; ++i) out[i] = f[i];
  return out;
}

void Table::add(const std::string& peer, const Mesh& m, double dt, const std::string& quantity, double value,
                double ref, const Run& r, const std::string& notes, double same_mesh) {
  double total = 0;
  for (double v : r.step_ms) total += v;
  const double per_sim_s = total * 1e-3 / (double(r.step_ms.size()) * dt);
  const bool is_static = quantity.rfind("f1", 0) != 0;
  const int steps = r.rest_step > 0 ? r.rest_step : int(r.step_ms.size());
  rows.push_back({peer, m.name, int(m.x.size()), dt, quantity, value, (value - ref) / ref, median(r.step_ms), per_sim_s,
                  is_static ? steps * median(r.step_ms) * 1e-3 : per_sim_s, steps, same_mesh, notes});
  std::printf("  %s %s dt=%g %s = %.5g (%s)\n", peer.c_str(), m.name.c_str(), dt, quantity.c_str(), value, notes.c_str());
  std::fflush(stdout);
}

void Table::print() const {
  std::printf("\n%s\n\n| peer | mesh | nodes | dt | quantity | value | error vs reference | vs C3D4 same mesh | ms per step "
              "| steps | wall s | notes |\n|---|---|---|---|---|---|---|---|---|---|---|---|\n",
              problem.c_str());
  for (const auto& r : rows)
    std::printf("| %s | %s | %d | %g | %s | %.5g | %+.1f%% | %s | %.3g | %d | %.3g | %s |\n", r.peer.c_str(),
                r.mesh.c_str(), r.nodes, r.dt, r.quantity.c_str(), r.value, 100 * r.error,
                r.same_mesh != 0 ? fmt("%+.2f%%", 100 * (r.value / r.same_mesh - 1)).c_str() : "", r.ms_per_step,
                r.steps, r.wall_s, r.notes.c_str());
  std::fflush(stdout);
}

void Table::write(const std::string& dir) const {
  std::filesystem::create_directories(dir);
  std::ofstream csv(std::filesystem::path(dir) / ("bullet_" + problem + ".csv"));
  // wall_s: the wall time to the answer — static rows: the steps to rest; f1 rows: per
  // simulated second (the x axes of stroma bench accuracy's plots). same_mesh: 0 = none.
  csv << "peer,mesh,nodes,dt,quantity,value,error_vs_reference,ms_per_step,s_per_simulated_s,wall_s,steps,same_mesh,notes\n";
  for (const auto& r : rows)
    csv << '"' << r.peer << "\"," << r.mesh << ',' << r.nodes << ',' << r.dt << ",\"" << r.quantity << "\","
        << r.value << ',' << r.error << ',' << r.ms_per_step << ',' << r.s_per_sim_s << ',' << r.wall_s << ','
        << r.steps << ',' << r.same_mesh << ",\"" << r.notes << "\"\n";
}

}  // namespace peers
