#pragma once
/// \file test_meshes.hpp
/// Small generated meshes and helpers shared by the tissue unit tests (test_element.cpp,
/// test_solvers.cpp, test_mesh_prepare.cpp): a single irregular tetrahedron, a box split into
/// Kuhn tetrahedra (6 per cell), a FemBodyInput builder and BSR → dense conversion.

#include <Eigen/Dense>

#include <array>
#include <cstdint>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "tissue/bsr_matrix.hpp"
#include "tissue/fem_build.hpp"
#include "tissue/mesh_prepare.hpp"
#include "tissue/tet_mesh.hpp"

namespace stroma::test_meshes {

/// One irregular, positively oriented tetrahedron of size ~L (no right angles, no symmetry).
inline TetMesh single_tet(double L = 1.0) {
  TetMesh m;
  m.nodes = {Vec3{0.0, 0.0, 0.0}, Vec3{1.0 * L, 0.1 * L, -0.05 * L},
             Vec3{0.2 * L, 0.9 * L, 0.1 * L}, Vec3{0.1 * L, 0.2 * L, 0.8 * L}};
  m.tets = {Tet{0, 1, 2, 3}};
  m.source = "single_tet";
  return m;
}

/// Node index of grid point (i, j, k) in box_mesh(nx, ny, nz, ...).
inline int32_t box_node(int nx, int ny, int i, int j, int k) {
  return i + (nx + 1) * (j + (ny + 1) * k);
}

/// Box [origin, origin + size] with nx × ny × nz cells, each split into the 6 Kuhn tetrahedra
/// around its main diagonal (conforming across cells). All tetrahedra are positively oriented
/// (orientation decided on the regular grid). If `jitter` > 0, every node is then moved by a
/// uniform random offset of at most jitter × cell size per coordinate (fixed `seed`).
inline TetMesh box_mesh(int nx, int ny, int nz, Vec3 size = {1.0, 1.0, 1.0},
                        Vec3 origin = {0.0, 0.0, 0.0}, double jitter = 0.0,
                        uint64_t seed = 12345) {
  TetMesh m;
  m.source = "box_mesh";
  const double h[3] = {size[0] / nx, size[1] / ny, size[2] / nz};
  for (int k = 0; k <= nz; ++k)
    for (int j = 0; j <= ny; ++j)
      for (int i = 0; i <= nx; ++i)
        m.nodes.push_back({origin[0] + i * h[0], origin[1] + j * h[1], origin[2] + k * h[2]});
  static constexpr int kPerm[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2},
                                      {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
  for (int k = 0; k < nz; ++k)
    for (int j = 0; j < ny; ++j)
      for (int i = 0; i < nx; ++i)
        for (const auto& p : kPerm) {
          int c[3] = {i, j, k};
          Tet t{};
          t[0] = box_node(nx, ny, c[0], c[1], c[2]);
          for (int s = 0; s < 3; ++s) {
            ++c[p[s]];
            t[s + 1] = box_node(nx, ny, c[0], c[1], c[2]);
          }
          if (signed_volume(m.nodes[t[0]], m.nodes[t[1]], m.nodes[t[2]], m.nodes[t[3]]) < 0)
            std::swap(t[2], t[3]);
          m.tets.push_back(t);
        }
  if (jitter > 0) {
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> u(-jitter, jitter);
    for (Vec3& p : m.nodes)
      for (int d = 0; d < 3; ++d) p[d] += u(rng) * h[d];
  }
  return m;
}

/// Unit cube [0,1]³ split into 6 tetrahedra, optionally scaled by L.
inline TetMesh cube6(double L = 1.0) { return box_mesh(1, 1, 1, {L, L, L}); }

/// A body of homogeneous material on a prepared mesh.
inline FemBodyInput body_input(const PreparedMesh& mesh, ElementModel model, RotationMethod rot,
                               double E, double nu, double density, std::string name = "body") {
  FemBodyInput b;
  b.name = std::move(name);
  b.mesh = &mesh;
  b.model = model;
  b.rotation = rot;
  b.young_modulus = E;
  b.poisson_ratio = nu;
  b.density = density;
  return b;
}

/// Dense copy of a BSR matrix (3n × 3n).
inline Eigen::MatrixXd bsr_to_dense(const BsrPattern& p, const double* vals) {
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(3 * p.n, 3 * p.n);
  for (int32_t i = 0; i < p.n; ++i)
    for (int32_t s = p.row_ptr[i]; s < p.row_ptr[i + 1]; ++s) {
      const int32_t j = p.col[s];
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) {
          A(3 * i + r, 3 * j + c) += vals[9 * s + 3 * r + c];
          if (j != i) A(3 * j + c, 3 * i + r) += vals[9 * s + 3 * r + c];  // the unstored transpose
        }
    }
  return A;
}

/// BSR values of a dense matrix on pattern p (entries outside the pattern are dropped).
inline std::vector<double> dense_to_bsr(const BsrPattern& p, const Eigen::MatrixXd& A) {
  std::vector<double> vals(9 * static_cast<size_t>(p.nnzb()), 0.0);
  for (int32_t i = 0; i < p.n; ++i)
    for (int32_t s = p.row_ptr[i]; s < p.row_ptr[i + 1]; ++s) {
      const int32_t j = p.col[s];
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) vals[9 * s + 3 * r + c] = A(3 * i + r, 3 * j + c);
    }
  return vals;
}

}  // namespace stroma::test_meshes
