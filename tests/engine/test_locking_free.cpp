/// \file test_locking_free.cpp
/// Locking-free near-incompressible tetrahedra (`material.locking_free`, node smoothing,
/// tissue/nodal_smoothing.hpp):
///  - the patch test: a homogeneous strain gives exactly the continuum energy, no interior force;
///  - rigid motion is force- and energy-free (corotational);
///  - forces are minus the energy gradient, the rest tangent is their derivative, symmetric,
///    PSD with exactly six zero modes (no spurious zero-energy mode);
///  - the bonded ν = 0.49 block (refs/c) within 5 % of the converged force on the two coarsest
///    meshes, where plain tetrahedra are 36–53 % too stiff;
///  - a released near-incompressible block never gains energy;
///  - load errors name the field.
/// Each for both methods: node domains (node_smoothing) and element patches (element_patches,
/// F-bar-patch), whose partition is checked too (disjoint, covering, patches of at least k).

#include <gtest/gtest.h>

#include <Eigen/Dense>

#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "engine/model.hpp"
#include "engine/state.hpp"
#include "engine/tick.hpp"
#include "io/mesh_io.hpp"
#include "scene/compiled_scenario.hpp"
#include "scene/scenario_spec.hpp"
#include "tests/test_fem.hpp"
#include "tests/test_labels.hpp"
#include "tests/test_meshes.hpp"
#include "tests/test_scenarios.hpp"
#include "tissue/constraints.hpp"
#include "tissue/fem_build.hpp"
#include "tissue/fem_forces.hpp"
#include "tissue/input_error.hpp"
#include "tissue/mesh_prepare.hpp"
#include "tissue/nodal_smoothing.hpp"

using namespace stroma;
using namespace stroma::test_fem;
using namespace stroma::test_meshes;
using namespace stroma::test_scenarios;

namespace {

/// A 3×3×3-cell box (0.03 m), E 10 kPa, ν 0.49, locking-free with stabilisation `share`:
/// node domains (patch 0) or element patches of at least `patch` tetrahedra.
struct SmoothedBox {
  PreparedMesh mesh;
  FemModel fem;
  SmoothedBox(double share, ElementModel model = ElementModel::Corotational, double nu = 0.49, int patch = 0) {
    mesh.mesh = box_mesh(3, 3, 3, {0.03, 0.03, 0.03});
    FemBodyInput b = body_input(mesh, model, RotationMethod::Polar, 1e4, nu, 1000);
    b.locking_free_share = share;
    b.locking_free_patch = patch;
    if (patch > 0) b.locking_free_bulk = kDefaultElementBulk;
    fem = build_fem_model({b}, {0, 0, 0});
  }
};

/// The two methods at their defaults: node smoothing (s 0.1) and F-bar-patch (k 16, the
/// elements keeping 2 % of the bulk).
struct Method {
  double share;
  int patch;
};
const Method kMethods[] = {{0.1, 0}, {1.0, kDefaultPatchElements}};

double volume_of(const FemModel& m) {
  double v = 0;
  for (const ElementParams& e : m.elements) v += e.volume;
  return v;
}

/// Positions x = A·X (+ t) for every node.
std::vector<double> mapped(const FemModel& m, const Eigen::Matrix3d& A, const Eigen::Vector3d& t = Eigen::Vector3d::Zero()) {
  std::vector<double> x(m.rest.size());
  for (int32_t i = 0; i < m.num_nodes; ++i) {
    const Eigen::Vector3d X(m.rest[3 * i], m.rest[3 * i + 1], m.rest[3 * i + 2]);
    const Eigen::Vector3d y = A * X + t;
    for (int k = 0; k < 3; ++k) x[3 * i + k] = y[k];
  }
  return x;
}

bool on_boundary(const FemModel& m, int32_t i) {
  for (int k = 0; k < 3; ++k) {
    const double c = m.rest[3 * i + k];
    if (c < 1e-9 || c > 0.03 - 1e-9) return true;
  }
  return false;
}

}  // namespace

TEST(LockingFree, PatchTestHomogeneousStrainGivesTheContinuumEnergyAndNoInteriorForce) {
  for (const Method& me : kMethods)
  for (ElementModel model : {ElementModel::Linear, ElementModel::Corotational}) {
    SmoothedBox b(me.share, model, 0.49, me.patch);
    ASSERT_FALSE(b.fem.smoothing.empty());
    // A symmetric small strain (no rotation: the corotational element sees the same strain).
    Eigen::Matrix3d eps;
    eps << 1e-3, 2e-4, -3e-4, 2e-4, -5e-4, 1e-4, -3e-4, 1e-4, 4e-4;
    const std::vector<double> x = mapped(b.fem, Eigen::Matrix3d::Identity() + eps);
    std::vector<double> f;
    const double energy = energy_and_force(b.fem, x, &f);
    const double E = 1e4, nu = 0.49, mu = E / (2 * (1 + nu)), lambda = E * nu / ((1 + nu) * (1 - 2 * nu));
    const double psi = mu * (eps.array() * eps.array()).sum() + 0.5 * lambda * eps.trace() * eps.trace();
    if (model == ElementModel::Linear) {
      EXPECT_NEAR(energy, psi * volume_of(b.fem), 1e-12 * psi * volume_of(b.fem));
    } else {  // the polar rotation of a symmetric F is I only to O(ε²)… it is exactly I here
      EXPECT_NEAR(energy, psi * volume_of(b.fem), 1e-6 * psi * volume_of(b.fem));
    }
    double fmax = 0, interior = 0;
    for (int32_t i = 0; i < b.fem.num_nodes; ++i) {
      const double fi = std::hypot(f[3 * i], f[3 * i + 1], f[3 * i + 2]);
      fmax = std::max(fmax, fi);
      if (!on_boundary(b.fem, i)) interior = std::max(interior, fi);
    }
    EXPECT_GT(fmax, 0.0);
    EXPECT_LT(interior, 1e-9 * fmax) << "a homogeneous stress is in equilibrium inside (patch " << me.patch << ")";
  }
}

TEST(LockingFree, RigidMotionIsForceAndEnergyFree) {
  for (const Method& me : kMethods) {
  SmoothedBox b(me.share, ElementModel::Corotational, 0.49, me.patch);
  const Eigen::Matrix3d R = Eigen::AngleAxisd(0.9, Eigen::Vector3d(1, 2, -0.5).normalized()).toRotationMatrix();
  const std::vector<double> x = mapped(b.fem, R, Eigen::Vector3d(0.1, -0.2, 0.05));
  std::vector<double> f;
  const double energy = energy_and_force(b.fem, x, &f);
  EXPECT_LT(std::abs(energy), 1e-15);
  double fmax = 0;
  for (double v : f) fmax = std::max(fmax, std::abs(v));
  EXPECT_LT(fmax, 1e-9);
  // and the same rotation on a stretched body does produce forces (the test can fail)
  const std::vector<double> y = mapped(b.fem, R * Eigen::Vector3d(1.01, 1, 1).asDiagonal());
  energy_and_force(b.fem, y, &f);
  fmax = 0;
  for (double v : f) fmax = std::max(fmax, std::abs(v));
  EXPECT_GT(fmax, 1e-4);
  }
}

TEST(LockingFree, ForcesAreMinusTheEnergyGradient) {
  for (const Method& me : kMethods) {
  SmoothedBox b(me.share, ElementModel::Corotational, 0.49, me.patch);
  std::mt19937 g(7);
  std::uniform_real_distribution<double> u(-1.5e-3, 1.5e-3);  // 5 % of a cell: large rotations of patches
  const Eigen::Matrix3d R = Eigen::AngleAxisd(0.4, Eigen::Vector3d(0, 1, 1).normalized()).toRotationMatrix();
  std::vector<double> x = mapped(b.fem, R);
  for (double& v : x) v += u(g);
  std::vector<double> f;
  energy_and_force(b.fem, x, &f);
  const double h = 1e-8;
  double worst = 0, scale = 0;
  for (int32_t d = 0; d < 3 * b.fem.num_nodes; d += 7) {
    std::vector<double> xp = x, xm = x;
    xp[d] += h;
    xm[d] -= h;
    const double fd = -(energy_and_force(b.fem, xp, nullptr) - energy_and_force(b.fem, xm, nullptr)) / (2 * h);
    worst = std::max(worst, std::abs(fd - f[d]));
    scale = std::max(scale, std::abs(f[d]));
  }
  EXPECT_GT(scale, 1e-3);
  EXPECT_LT(worst, 1e-5 * scale) << "patch " << me.patch;
  }
}

TEST(LockingFree, RestTangentIsTheForceDerivativeSymmetricWithSixZeroModes) {
  for (const Method& me : {Method{0.1, 0}, Method{0.0, 0}, Method{1.0, kDefaultPatchElements}, Method{0.5, 4}}) {
    const double share = me.share;
    SmoothedBox b(share, ElementModel::Corotational, 0.49, me.patch);
    const Eigen::MatrixXd K = dense_stiffness(b.fem, b.fem.rest);
    // Derivative of the forces at rest (central differences; linear there up to O(h²)).
    const double h = 1e-7;
    double worst = 0;
    for (int32_t d = 0; d < 3 * b.fem.num_nodes; d += 5) {
      std::vector<double> xp = b.fem.rest, xm = b.fem.rest, fp, fm;
      xp[d] += h;
      xm[d] -= h;
      energy_and_force(b.fem, xp, &fp);
      energy_and_force(b.fem, xm, &fm);
      for (int32_t r = 0; r < 3 * b.fem.num_nodes; ++r)
        worst = std::max(worst, std::abs(-(fp[r] - fm[r]) / (2 * h) - K(r, d)));
    }
    EXPECT_LT(worst, 1e-5 * K.cwiseAbs().maxCoeff()) << "share " << share << " patch " << me.patch;
    EXPECT_LT((K - K.transpose()).cwiseAbs().maxCoeff(), 1e-12 * K.cwiseAbs().maxCoeff());
    Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(K);
    const Eigen::VectorXd ev = es.eigenvalues();
    const double top = ev(ev.size() - 1);
    int zero = 0;
    for (int k = 0; k < ev.size(); ++k) {
      EXPECT_GT(ev(k), -1e-10 * top);
      if (ev(k) < 1e-8 * top) ++zero;
    }
    EXPECT_EQ(zero, 6) << "rigid modes only (share " << share << ", patch " << me.patch << "); smallest non-rigid "
                       << ev(6) / top;
  }
}

namespace {

/// Top force of the bonded ν = 0.49 block pressed 1 % (refs/c), static, on `mesh`.
/// `solver`: the linear solver's settings (CHOLMOD: node domains assembled; CG: matrix-free).
double block_force(const std::string& mesh, const std::string& locking_free,
                   const std::string& solver = "linear_solver: cholmod", bool expect_matrix_free = false) {
  const std::string yaml = R"(name: block
gravity: [0, 0, 0]
solver: {integrator: static, )" + solver + R"(, static_tolerance: 1.0e-10}
bodies:
  - name: block
    mesh: )" + std::string(STROMA_SOURCE_DIR) + "/scenarios/meshes/cube_tet4_h" + mesh + R"(mm.msh
    material: {model: corotational, young_modulus: 1.0e4, poisson_ratio: 0.49, density: 1000)" + locking_free + R"(}
    fixed:
      - box: {min: [-1, -1, -1.0e-7], max: [1, 1, 1.0e-7]}
      - box: {min: [-1, -1, 0.0499999], max: [1, 1, 1]}
)";
  auto m = compile_model(parse_scenario(yaml, "block.yaml", STROMA_SOURCE_DIR));
  EXPECT_EQ(m->fem.smoothing.matrix_free, expect_matrix_free);
  State s = State::initial(*m);
  std::vector<int32_t> top;
  for (int32_t i = 0; i < m->fem.num_nodes; ++i)
    if (m->fem.rest[3 * i + 2] > 0.0499999) {
      s.tissue.x[3 * i + 2] -= 5.0e-4;
      top.push_back(i);
    }
  TickWorkspace w(*m);
  EXPECT_TRUE(w.stepper().solve_static(s.tissue).converged);
  std::vector<double> f(m->fem.rest.size());
  w.stepper().elastic_force(s.tissue, f.data());
  double fz = 0;
  for (int32_t i : top) fz += f[3 * i + 2];
  return fz;
}

}  // namespace

TEST(LockingFree, BondedBlockWithinFivePercentOnTheTwoCoarsestMeshes) {
  constexpr double kConverged = 0.3049;  // N, refs/c (CalculiX C3D10, extrapolated)
  for (const std::string mesh : {"8p333", "6p250"}) {
    const double plain = block_force(mesh, "");
    const double smoothed = block_force(mesh, ", locking_free: node_smoothing");
    const double patches = block_force(mesh, ", locking_free: element_patches");
    EXPECT_GT(plain / kConverged - 1, 0.3) << mesh << ": plain tetrahedra lock";
    EXPECT_LT(std::abs(smoothed / kConverged - 1), 0.05) << mesh << ": " << smoothed << " N";
    EXPECT_LT(std::abs(patches / kConverged - 1), 0.05) << mesh << ": F-bar-patch " << patches << " N";
  }
  // Patches of two tetrahedra are too many volume constraints: they still lock (the test's
  // measure can tell the methods apart).
  EXPECT_GT(block_force("8p333", ", locking_free: {method: element_patches, patch_elements: 2}") / kConverged - 1, 0.1);
}

namespace {

/// Tip deflection (u_y at the tip-face centre) of refs/a's cantilever (0.1 x 0.01 x 0.01 m,
/// E 1e7, clamped at x = 0, gravity) at nu 0.49, static, on beam mesh `mesh`.
/// The static equilibrium of a scenario (text) and its first probe's displacement there.
Vec3 static_probe_displacement(const std::string& yaml, const std::string& name) {
  auto m = compile_model(parse_scenario(yaml, name, STROMA_SOURCE_DIR));
  State s = State::initial(*m);
  TickWorkspace w(*m);
  EXPECT_TRUE(w.stepper().solve_static(s.tissue, 1.0).converged) << name;
  return probe_displacement(*m, s, m->probes.at(0));
}

double cantilever_tip(const std::string& mesh, const std::string& locking_free) {
  const std::string yaml = R"(name: beam
gravity: [0, -9.81, 0]
solver: {integrator: static, linear_solver: cholmod, static_tolerance: 1.0e-6}
bodies:
  - name: beam
    mesh: )" + std::string(STROMA_SOURCE_DIR) + "/scenarios/meshes/beam_tet4_h" + mesh + R"(mm.msh
    material: {model: corotational, young_modulus: 1.0e7, poisson_ratio: 0.49, density: 1000)" + locking_free + R"(}
    fixed:
      - box: {min: [-1.0e-6, -1, -1], max: [1.0e-6, 1, 1]}
probes:
  - {name: tip, body: beam, point: [0.1, 0.005, 0.005]}
)";
  return static_probe_displacement(yaml, "beam.yaml")[1];
}

/// Centre deflection (mid-plane) of a circular plate (radius 30 mm, thickness 3 mm) clamped on
/// its rim and bent by its weight, at nu 0.49.
double clamped_plate_centre(const std::string& mesh, const std::string& locking_free, double nu = 0.49) {
  // The fine mesh is made at build time from disc.geo (tests/CMakeLists.txt), the coarse one kept.
  const std::string path = (mesh == "lc1p0" ? std::string(STROMA_GENERATED_DATA) + "/plate/disc_a30_t3_"
                                            : std::string(STROMA_SOURCE_DIR) + "/tests/data/meshes/plate/disc_a30_t3_") +
                           mesh + ".msh";
  const TetMesh tm = load_tet_mesh(path);
  std::string rim;
  for (size_t i = 0; i < tm.nodes.size(); ++i)
    if (std::hypot(tm.nodes[i][0], tm.nodes[i][1]) > 0.03 - 1e-7) rim += (rim.empty() ? "" : ", ") + std::to_string(i);
  const std::string yaml = R"(name: plate
gravity: [0, 0, -9.81]
solver: {integrator: static, linear_solver: cholmod, static_tolerance: 1.0e-6}
bodies:
  - name: plate
    mesh: )" + path + R"(
    material: {model: corotational, young_modulus: 1.0e7, poisson_ratio: )" + std::to_string(nu) + R"(, density: 1000)" + locking_free + R"(}
    fixed:
      - nodes: [)" + rim + R"(]
probes:
  - {name: centre, body: plate, point: [0, 0, 0.0015]}
)";
  return static_probe_displacement(yaml, "plate.yaml")[2];
}

/// Mindlin's clamped circular plate under a uniform load q = rho g t: Kirchhoff's q a^4 / (64 D)
/// plus the shear term q a^2 / (4 kappa G t), kappa 5/6 (Reddy, Theory and Analysis of Elastic
/// Plates, §4: the Mindlin-Kirchhoff relation for axisymmetric clamped plates).
double clamped_plate_reference(double nu = 0.49) {
  const double E = 1.0e7, a = 0.03, t = 0.003, q = 1000 * 9.81 * t;
  const double D = E * t * t * t / (12 * (1 - nu * nu)), G = E / (2 * (1 + nu));
  return -(q * a * a * a * a / (64 * D) + q * a * a / (4 * (5.0 / 6.0) * G * t));
}

}  // namespace

// A second bending problem at nu 0.49 (issue 41 §7): a circular plate clamped on its rim, bent
// by its weight, 3 mm thick and 30 mm in radius, meshed by gmsh with ~3 elements through the
// thickness (11,290 nodes). Mindlin's closed form is the reference to ~2 % (Timoshenko's
// thick-plate correction differs by 1.6 %). Plain tetrahedra lock; node smoothing is softer than
// the exact solution (NS-FEM bounds the energy from above); element patches hold within 10 %.
// docs/TISSUE.md gives the table at two meshes.
TEST(LockingFree, OnAClampedPlateAtNu049LockingFreeOptionsHoldWithinTenPercent) {
  STROMA_LONG_TEST();  // three static solves of 11,290 nodes: 9 s in Release; the cantilever covers the code
  const double ref = clamped_plate_reference();
  const double plain = clamped_plate_centre("lc1p0", "") / ref - 1;
  const double smoothed = clamped_plate_centre("lc1p0", ", locking_free: node_smoothing") / ref - 1;
  const double patches = clamped_plate_centre("lc1p0", ", locking_free: element_patches") / ref - 1;
  EXPECT_LT(plain, -0.4) << "plain tetrahedra lock in bending";
  EXPECT_GT(smoothed, 0.0) << "node smoothing is soft";
  EXPECT_LT(smoothed, 0.10) << smoothed;
  EXPECT_LT(std::abs(patches), 0.10) << patches;
}

// Bending at nu 0.49 (issue 41 §7): a slender cantilever's deflection hardly depends on nu, so
// refs/a's CalculiX result at nu 0.3 (-1.4735e-3 m), with Timoshenko's shear term for nu 0.49
// (+0.15 %), is the reference to about 1 %. Node smoothing holds within 5 % from 594 nodes (what
// docs/TISSUE.md recommends for bending-dominated near-incompressible parts); element patches
// (k 16) stay 9-13 % too stiff there — the limit the docs state — and plain tetrahedra lock.
TEST(LockingFree, InBendingAtNu049NodeSmoothingHoldsAndPatchesAreStiffAsDocumented) {
  constexpr double kReference = -1.4735e-3 * 1.0015;
  for (const std::string mesh : {"3p333", "2p000"}) {
    SCOPED_TRACE(mesh);
    const double plain = cantilever_tip(mesh, "") / kReference - 1;
    const double smoothed = cantilever_tip(mesh, ", locking_free: node_smoothing") / kReference - 1;
    const double patches = cantilever_tip(mesh, ", locking_free: element_patches") / kReference - 1;
    EXPECT_LT(plain, -0.3) << "plain tetrahedra lock in bending";
    EXPECT_LT(std::abs(smoothed), 0.05) << smoothed;
    EXPECT_LT(patches, -0.05) << "element patches are stiff in bending (docs/TISSUE.md): " << patches;
    EXPECT_GT(patches, -0.15) << patches;
  }
}

TEST(LockingFree, ElementPatchesAreDisjointCoverEveryElementAndHoldAtLeastK) {
  PreparedMesh mesh;
  mesh.mesh = box_mesh(5, 4, 3, {0.05, 0.04, 0.03});
  FemBodyInput b = body_input(mesh, ElementModel::Corotational, RotationMethod::Polar, 1e4, 0.49, 1000);
  const FemModel plain = build_fem_model({b}, {0, 0, 0});
  for (int k : {2, 4, 8, 12, 16}) {
    const std::vector<int32_t> pid =
        partition_element_patches(plain, 0, static_cast<int32_t>(plain.elements.size()), 0, plain.num_nodes, k);
    ASSERT_EQ(pid.size(), plain.elements.size());
    const int32_t np = *std::max_element(pid.begin(), pid.end()) + 1;
    std::vector<int> size(np, 0);
    for (int32_t p : pid) {
      ASSERT_GE(p, 0);
      ++size[p];
    }
    for (int32_t p = 0; p < np; ++p) EXPECT_GE(size[p], k) << "patch " << p << " of k " << k;
    EXPECT_LE(np, static_cast<int32_t>(plain.elements.size()) / k);
    EXPECT_GT(np, 1);
    // Every patch is connected through shared faces or edges (a patch grows around a node).
    for (int32_t p = 0; p < np; ++p) {
      std::vector<int32_t> els, seen;
      for (size_t e = 0; e < pid.size(); ++e)
        if (pid[e] == p) els.push_back(static_cast<int32_t>(e));
      seen.push_back(els[0]);
      for (size_t q = 0; q < seen.size(); ++q)
        for (int32_t f : els) {
          if (std::find(seen.begin(), seen.end(), f) != seen.end()) continue;
          int shared = 0;
          for (int32_t x : plain.elements[seen[q]].node)
            for (int32_t y : plain.elements[f].node) shared += x == y;
          if (shared >= 1) seen.push_back(f);
        }
      EXPECT_EQ(seen.size(), els.size()) << "patch " << p << " of k " << k << " is in pieces";
    }
    // Deterministic: the same mesh gives the same patches.
    EXPECT_EQ(pid, partition_element_patches(plain, 0, static_cast<int32_t>(plain.elements.size()), 0, plain.num_nodes, k));
  }
  // The model's domains are the patches: as many, each element in exactly one.
  b.locking_free_share = 1.0;
  b.locking_free_patch = 8;
  b.locking_free_bulk = 0.02;
  const FemModel m = build_fem_model({b}, {0, 0, 0});
  std::vector<int> count(m.elements.size(), 0);
  for (int32_t e : m.smoothing.element) ++count[e];
  for (int c : count) EXPECT_EQ(c, 1);
  EXPECT_EQ(m.smoothing.element_ptr.size(), static_cast<size_t>(m.smoothing.domains()) + 1);
  for (int32_t d = 0; d < m.smoothing.domains(); ++d) {
    EXPECT_DOUBLE_EQ(m.smoothing.mu[d], 0.0) << "bulk only";
    const double E = 1e4, nu = 0.49, kappa = E / (3 * (1 - 2 * nu));
    EXPECT_NEAR(m.smoothing.lambda[d], 0.98 * kappa, 1e-9 * kappa) << "98 % of the bulk on the patch";
    double v = 0;
    for (int32_t q = m.smoothing.element_ptr[d]; q < m.smoothing.element_ptr[d + 1]; ++q)
      v += m.elements[m.smoothing.element[q]].volume;
    EXPECT_NEAR(m.smoothing.volume[d], v, 1e-12 * v) << "a patch counts its elements whole";
  }
}

TEST(LockingFree, MatrixFreeNodeDomainsApplyTheAssembledTangent) {
  // The same box assembled (two-ring pattern) and matrix-free (elements' pattern + NodalSystem),
  // deformed and rotated, with a partly constrained node: A_bsr·x + A_n·x equals the assembled
  // matrix's product, constrained rows and columns zero; the diagonal blocks agree too.
  SmoothedBox assembled(0.1);
  PreparedMesh mesh;
  // (100 nodes: the product's and the assembly's batches of 8 domains end with a partial one.)
  mesh.mesh = box_mesh(4, 4, 3, {0.04, 0.04, 0.03});
  FemBodyInput b = body_input(mesh, ElementModel::Corotational, RotationMethod::Polar, 1e4, 0.49, 1000);
  b.locking_free_share = 0.1;
  b.fixed = {{0, 7}, {5, 2}};
  assembled.fem = build_fem_model({b}, {0, 0, 0});
  const FemModel mf = build_fem_model({b}, {0, 0, 0}, true);
  ASSERT_TRUE(mf.smoothing.matrix_free);
  ASSERT_LT(mf.pattern.nnzb(), assembled.fem.pattern.nnzb()) << "the matrix-free pattern is the elements' one-ring";
  std::mt19937 g(3);
  std::uniform_real_distribution<double> u(-1e-3, 1e-3);
  const Eigen::Matrix3d R = Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 0, 1).normalized()).toRotationMatrix();
  std::vector<double> x = mapped(mf, R);
  for (double& v : x) v += u(g);
  auto system = [&](const FemModel& m, NodalSystem* ns, std::vector<double>& vals) {
    vals.assign(9 * static_cast<size_t>(m.pattern.nnzb()), 0.0);
    ElasticPass p;
    p.x = x.data();
    p.kvals = vals.data();
    p.k_beta = 0.001;
    p.k_const = 1e-6;
    p.nodal_system = ns;
    if (ns) ns->begin();
    elastic_pass(m, p);
    project_constraints(m, vals.data(), 1.0, true);
    if (ns) ns->finish();
  };
  std::vector<double> va, vm;
  system(assembled.fem, nullptr, va);
  NodalSystem ns(mf);
  system(mf, &ns, vm);
  std::vector<double> xin(x.size()), ya(x.size()), ym(x.size());
  for (double& v : xin) v = u(g);
  bsr_spmv(assembled.fem.pattern, va.data(), xin.data(), ya.data());
  bsr_spmv(mf.pattern, vm.data(), xin.data(), ym.data());
  ns.apply(xin.data(), ym.data());
  double worst = 0, scale = 0;
  for (size_t d = 0; d < ya.size(); ++d) {
    worst = std::max(worst, std::abs(ya[d] - ym[d]));
    scale = std::max(scale, std::abs(ya[d]));
  }
  EXPECT_GT(scale, 0.0);
  EXPECT_LT(worst, 1e-12 * scale);
  double dworst = 0;
  for (int32_t i = 0; i < mf.num_nodes; ++i)
    for (int k = 0; k < 9; ++k)
      dworst = std::max(dworst, std::abs(va[9 * assembled.fem.pattern.diag[i] + k] -
                                         (vm[9 * mf.pattern.diag[i] + k] + ns.diag()[9 * i + k])));
  EXPECT_LT(dworst, 1e-12 * scale / 1e-3);
}

TEST(LockingFree, MatrixFreeCgAndAssembledCholmodGiveTheSameStaticBlock) {
  // Node domains are matrix-free under CG; element patches are assembled there too (their
  // pattern grows little): either way the same force as CHOLMOD's.
  for (const auto& [lf, matrix_free] : {std::pair<std::string, bool>{", locking_free: node_smoothing", true},
                                        std::pair<std::string, bool>{", locking_free: element_patches", false}}) {
    const double direct = block_force("8p333", lf);
    const double fz = block_force(
        "8p333", lf, "linear_solver: cg, preconditioner: warped_cholesky, tolerance: 1.0e-10, max_iterations: 5000",
        matrix_free);
    EXPECT_NEAR(fz, direct, 1e-7 * direct) << lf;
  }
}

TEST(LockingFree, ReleasedNearIncompressibleBlockNeverGainsEnergy) {
  STROMA_LONG_TEST();
  // A twisted-and-squeezed free block released at rest, no damping: implicit Euler may only lose
  // energy. A spurious low-energy mode or a wrong tangent would show as growth or blow-up.
  for (const std::string lf : {"{method: node_smoothing, stabilisation: 0.05}", "element_patches"}) {
  const std::string yaml = R"(name: released
gravity: [0, 0, 0]
time_step: 0.001
solver: {integrator: implicit_euler, linear_solver: cg, tolerance: 1.0e-10, max_iterations: 2000}
bodies:
  - name: block
    mesh: )" + std::string(STROMA_SOURCE_DIR) + R"(/scenarios/meshes/cube_tet4_h8p333mm.msh
    material: {model: corotational, young_modulus: 1.0e4, poisson_ratio: 0.49, density: 1000,
               locking_free: )" + lf + R"(}
)";
  auto m = compile_model(parse_scenario(yaml, "released.yaml", STROMA_SOURCE_DIR));
  State s = State::initial(*m);
  for (int32_t i = 0; i < m->fem.num_nodes; ++i) {
    const double* X = &m->fem.rest[3 * i];
    const double a = 8.0 * (X[2] - 0.025);  // twist about z, up to 0.2 rad
    const double cx = X[0] - 0.025, cy = X[1] - 0.025;
    s.tissue.x[3 * i] = 0.025 + std::cos(a) * cx - std::sin(a) * cy;
    s.tissue.x[3 * i + 1] = 0.025 + std::sin(a) * cx + std::cos(a) * cy;
    s.tissue.x[3 * i + 2] = 0.025 + 0.97 * (X[2] - 0.025);
  }
  TickWorkspace w(*m);
  auto total = [&] {
    double kin = 0;
    for (int32_t i = 0; i < m->fem.num_nodes; ++i)
      for (int k = 0; k < 3; ++k) kin += 0.5 * m->fem.mass[i] * s.tissue.v[3 * i + k] * s.tissue.v[3 * i + k];
    return kin + energy_and_force(m->fem, s.tissue.x, nullptr);
  };
  const double e0 = total();
  ASSERT_GT(e0, 0);
  double prev = e0, max_kin_seen = 0;
  for (int t = 0; t < 300; ++t) {
    tick(*m, s, w);
    const double e = total();
    ASSERT_TRUE(std::isfinite(e));
    EXPECT_LE(e, prev * (1 + 1e-9)) << "tick " << t;
    max_kin_seen = std::max(max_kin_seen, e - energy_and_force(m->fem, s.tissue.x, nullptr));
    prev = e;
  }
  EXPECT_GT(max_kin_seen, 0.05 * e0) << "the block did move (" << lf << ")";
  }
}

TEST(LockingFree, BadOptionsAreLoadErrorsNamingTheField) {
  auto error_of = [&](const std::string& material) {
    const std::string yaml = R"(name: bad
bodies:
  - name: block
    mesh: )" + std::string(STROMA_SOURCE_DIR) + R"(/scenarios/meshes/cube_tet4_h8p333mm.msh
    material: )" + material + "\n";
    try {
      compile_model(load_scenario(write_temp("bad_locking_free.yaml", yaml)));
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  const std::string base = "{model: corotational, young_modulus: 1.0e4, poisson_ratio: 0.49, density: 1000, ";
  std::string e = error_of(base + "locking_free: fbar}");
  EXPECT_NE(e.find("locking_free"), std::string::npos) << e;
  EXPECT_NE(e.find("node_smoothing"), std::string::npos) << e;
  EXPECT_NE(e.find(":5:"), std::string::npos) << "the scenario line: " << e;
  e = error_of(base + "locking_free: {method: node_smoothing, stabilisation: 1.5}}");
  EXPECT_NE(e.find("stabilisation"), std::string::npos) << e;
  e = error_of(base + "locking_free: {method: node_smoothing, stabilisation: -0.1}}");
  EXPECT_NE(e.find("stabilisation"), std::string::npos) << e;
  e = error_of(base + "locking_free: {method: node_smoothing, share: 0.1}}");
  EXPECT_NE(e.find("share"), std::string::npos) << e;
  e = error_of("{model: stable_neo_hookean, young_modulus: 1.0e4, poisson_ratio: 0.49, density: 1000, "
               "locking_free: node_smoothing}");
  EXPECT_NE(e.find("corotational or linear"), std::string::npos) << e;
  e = error_of(base + "locking_free: node_smoothing, viscoelastic: {model: maxwell, tau: 0.1}}");
  EXPECT_NE(e.find("Prony"), std::string::npos) << e;
  e = error_of(base + "locking_free: {method: node_smoothing, patch_elements: 8}}");
  EXPECT_NE(e.find("patch_elements belongs to method element_patches"), std::string::npos) << e;
  for (const char* bad : {"1", "65", "7.5", "many"}) {
    e = error_of(base + "locking_free: {method: element_patches, patch_elements: " + bad + "}}");
    EXPECT_NE(e.find("patch_elements"), std::string::npos) << bad << ": " << e;
    EXPECT_NE(e.find(":5:"), std::string::npos) << bad << ": " << e;
  }
  e = error_of(base + "locking_free: node_smoothing}");
  EXPECT_EQ(e, "no error");
  e = error_of(base + "locking_free: {method: element_patches, patch_elements: 8, element_bulk: 0.05}}");
  EXPECT_EQ(e, "no error");
  for (const char* bad : {"1", "-0.1", "1.5"}) {
    e = error_of(base + "locking_free: {method: element_patches, element_bulk: " + bad + "}}");
    EXPECT_NE(e.find("element_bulk"), std::string::npos) << bad << ": " << e;
  }
  e = error_of(base + "locking_free: {method: node_smoothing, element_bulk: 0.02}}");
  EXPECT_NE(e.find("element_bulk belongs to method element_patches"), std::string::npos) << e;
  e = error_of(base + "locking_free: {method: element_patches, stabilisation: 0.1}}");
  EXPECT_NE(e.find("stabilisation belongs to method node_smoothing"), std::string::npos) << e;
  // A scalpel that cuts it: refused (a cut would split node domains and create energy).
  ScenarioSpec spec = load_scenario(write_temp("lf_cut.yaml", R"(name: bad
bodies:
  - name: block
    mesh: )" + std::string(STROMA_SOURCE_DIR) + R"(/scenarios/meshes/cube_tet4_h8p333mm.msh
    material: )" + base + "locking_free: node_smoothing}\n"));
  ToolEntry t;
  t.spec.name = "scalpel";
  t.spec.shape = ToolShape::Blade;
  t.spec.cuts = true;
  spec.tools.push_back(t);
  try {
    compile_model(spec);
    ADD_FAILURE() << "cutting a locking-free body compiled";
  } catch (const InputError& err) {
    const std::string what = err.what();
    EXPECT_NE(what.find("bodies[0].material.locking_free"), std::string::npos) << what;
    EXPECT_NE(what.find("create energy"), std::string::npos) << what;
  }
}
