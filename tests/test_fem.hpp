#pragma once
/// \file test_fem.hpp
/// Helpers shared by the material tests (test_stable_neo_hookean.cpp, test_hyperelastic.cpp,
/// test_regions.cpp, test_viscoelastic.cpp): the elastic pass as energy and forces or as a
/// dense stiffness, a mesh as gmsh 2.2 text, and a consistent end traction on a bar.

#include <Eigen/Dense>

#include <cmath>
#include <functional>
#include <sstream>
#include <string>
#include <vector>

#include "tissue/fem_forces.hpp"
#include "tissue/fem_model.hpp"
#include "tissue/tet_mesh.hpp"

namespace stroma::test_fem {

/// Elastic energy at x (instantaneous: no visco-elastic history) and, when f is given, forces.
inline double energy_and_force(const FemModel& fem, const std::vector<double>& x, std::vector<double>* f) {
  ElasticPass p;
  p.x = x.data();
  if (f) {
    f->assign(x.size(), 0.0);
    p.force = f->data();
  }
  return elastic_pass(fem, p);
}

/// Dense stiffness of the whole mesh at x (kvals with k_const = 1, expanded from the upper
/// triangle the BSR pattern stores).
inline Eigen::MatrixXd dense_stiffness(const FemModel& fem, const std::vector<double>& x) {
  std::vector<double> vals(9 * fem.pattern.col.size(), 0.0);
  ElasticPass p;
  p.x = x.data();
  p.kvals = vals.data();
  p.k_const = 1.0;
  elastic_pass(fem, p);
  const int n = fem.num_nodes;
  Eigen::MatrixXd K = Eigen::MatrixXd::Zero(3 * n, 3 * n);
  for (int i = 0; i < n; ++i)
    for (int s = fem.pattern.row_ptr[i]; s < fem.pattern.row_ptr[i + 1]; ++s)
      for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b) {
          const int j = fem.pattern.col[s];
          K(3 * i + a, 3 * j + b) = vals[9 * s + 3 * a + b];
          if (j != i) K(3 * j + b, 3 * i + a) = vals[9 * s + 3 * a + b];
        }
  return K;
}

/// The mesh as gmsh 2.2 text; `tag(e)` > 0 puts tetrahedron e in that physical group, and
/// `names` ("$PhysicalNames" lines "3 TAG \"NAME\"") names them.
inline std::string gmsh22(const TetMesh& m, const std::function<int(size_t)>& tag = {},
                          const std::vector<std::string>& names = {}) {
  std::ostringstream o;
  o.precision(17);
  o << "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n";
  if (!names.empty()) {
    o << "$PhysicalNames\n" << names.size() << "\n";
    for (const std::string& n : names) o << n << "\n";
    o << "$EndPhysicalNames\n";
  }
  o << "$Nodes\n" << m.nodes.size() << "\n";
  for (size_t i = 0; i < m.nodes.size(); ++i) o << i + 1 << " " << m.nodes[i][0] << " " << m.nodes[i][1] << " " << m.nodes[i][2] << "\n";
  o << "$EndNodes\n$Elements\n" << m.tets.size() << "\n";
  for (size_t e = 0; e < m.tets.size(); ++e) {
    const int t = tag ? tag(e) : 0;
    o << e + 1 << " 4 " << (t > 0 ? "2 " + std::to_string(t) + " " + std::to_string(t) : "0");
    for (int32_t n : m.tets[e]) o << " " << n + 1;
    o << "\n";
  }
  o << "$EndElements\n";
  return o.str();
}

/// Adds a consistent axial traction `sigma` (Pa, along x) on body 0's boundary faces at x =
/// x_end to f_ext: each node gets sigma × a third of the area of its face triangles. Returns the
/// loaded area.
inline double add_end_traction(FemModel& m, double x_end, double sigma) {
  double total = 0;
  for (const Tri& t : m.bodies[0].boundary) {
    bool end = true;
    for (int32_t n : t) end &= std::abs(m.rest[3 * n] - x_end) < 1e-9;
    if (!end) continue;
    const double* a = &m.rest[3 * t[0]];
    const double* b = &m.rest[3 * t[1]];
    const double* c = &m.rest[3 * t[2]];
    const double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, v[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    const double area = 0.5 * std::sqrt(std::pow(u[1] * v[2] - u[2] * v[1], 2) + std::pow(u[2] * v[0] - u[0] * v[2], 2) +
                                        std::pow(u[0] * v[1] - u[1] * v[0], 2));
    total += area;
    for (int32_t n : t) m.f_ext[3 * n] += sigma * area / 3.0;
  }
  return total;
}

}  // namespace stroma::test_fem
