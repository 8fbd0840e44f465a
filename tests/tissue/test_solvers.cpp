// Tests for the block sparse matrix (tissue/bsr_matrix.cpp), the preconditioned conjugate
// gradient (tissue/cg_solver.cpp) and the CHOLMOD wrapper (tissue/cholmod_solver.cpp) on an
// implicit-Euler-like SPD system M + h²K of a small irregular tetrahedral mesh, checked against
// dense Eigen computations.

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <random>
#include <set>
#include <utility>
#include <vector>

#include "tests/test_meshes.hpp"
#include "tissue/bsr_matrix.hpp"
#include "tissue/cg_solver.hpp"
#include "tissue/cholmod_solver.hpp"
#include "tissue/fem_build.hpp"
#include "tissue/time_stepper.hpp"
#include "tissue/tissue_state.hpp"

namespace stroma {
namespace {

using test_meshes::body_input;
using test_meshes::box_mesh;
using test_meshes::bsr_to_dense;
using test_meshes::dense_to_bsr;

constexpr double kL = 0.1;  // m

/// The SPD system A = M + h²K(rest) of a jittered 2×2×2 box (27 nodes, 81 unknowns, no
/// constraints), with a random right-hand side and its dense reference solution.
struct System {
  PreparedMesh mesh;
  FemModel model;
  std::vector<double> A;       // BSR values
  Eigen::MatrixXd Ad;          // dense copy
  Eigen::VectorXd b, xref;     // right-hand side, LDLᵀ solution
  double cond = 0;             // 2-norm condition number of A
  Eigen::VectorXd eig;         // eigenvalues, ascending
  const BsrPattern& pattern() const { return model.pattern; }
  int32_t n3() const { return 3 * model.num_nodes; }
};

std::unique_ptr<System> make_system(uint64_t seed = 4242) {
  auto s = std::make_unique<System>();
  s->mesh = prepare_mesh(box_mesh(2, 2, 2, {kL, kL, kL}, {0, 0, 0}, 0.05));
  s->model = build_fem_model({body_input(s->mesh, ElementModel::Corotational, RotationMethod::Polar,
                                         1e4, 0.3, 1000)},
                             {0, 0, 0});
  TimeStepper ts(s->model, StepperSettings{});
  const TissueState st = TissueState::at_rest(s->model);
  ts.stiffness(st, s->A);
  const double h = 0.05;  // time step (s): h²K and M of comparable size → moderately conditioned
  for (double& v : s->A) v *= h * h;
  for (int32_t i = 0; i < s->model.num_nodes; ++i) {
    double* D = s->A.data() + 9 * s->model.pattern.diag[i];
    D[0] += s->model.mass[i];
    D[4] += s->model.mass[i];
    D[8] += s->model.mass[i];
  }
  s->Ad = bsr_to_dense(s->model.pattern, s->A.data());
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  s->b.resize(s->n3());
  for (Eigen::Index i = 0; i < s->b.size(); ++i) s->b(i) = u(rng);
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(s->Ad);
  s->eig = es.eigenvalues();
  s->cond = s->eig(s->eig.size() - 1) / s->eig(0);
  s->xref = s->Ad.ldlt().solve(s->b);
  return s;
}

double true_relative_residual(const System& s, const std::vector<double>& x) {
  const Eigen::Map<const Eigen::VectorXd> xv(x.data(), s.n3());
  return (s.b - s.Ad * xv).norm() / s.b.norm();
}

const char* name(Preconditioner p) {
  switch (p) {
    case Preconditioner::Jacobi: return "Jacobi";
    case Preconditioner::BlockJacobi: return "BlockJacobi";
    case Preconditioner::None: return "None";
    case Preconditioner::WarpedCholesky: return "WarpedCholesky";  // needs a factor: not in kAllPrec
  }
  return "?";
}

constexpr Preconditioner kAllPrec[] = {Preconditioner::Jacobi, Preconditioner::BlockJacobi,
                                       Preconditioner::None};

TEST(Bsr, SystemUnderTestIsSpd) {
  // Precondition of all solver tests below.
  auto s = make_system();
  EXPECT_LE((s->Ad - s->Ad.transpose()).cwiseAbs().maxCoeff(), 1e-12 * s->Ad.cwiseAbs().maxCoeff());
  EXPECT_GT(s->eig(0), 0.0);
  EXPECT_GT(s->cond, 10.0);  // not trivially diagonal: CG needs several iterations
  std::printf("  M + h^2 K: 81 unknowns, condition number %.3g\n", s->cond);
}

TEST(Bsr, PatternCouplesExactlyTheNodesOfEachTetrahedron) {
  const TetMesh mesh = box_mesh(2, 2, 2, {kL, kL, kL});
  const int32_t n = static_cast<int32_t>(mesh.nodes.size());
  std::vector<ElementSlots> slots;
  const BsrPattern p = build_bsr_pattern(n, mesh.tets, slots);
  ASSERT_EQ(p.n, n);
  ASSERT_EQ(static_cast<int32_t>(p.row_ptr.size()), n + 1);
  ASSERT_EQ(slots.size(), mesh.tets.size());

  std::set<std::pair<int32_t, int32_t>> expected;
  for (int32_t i = 0; i < n; ++i) expected.insert({i, i});
  for (const Tet& t : mesh.tets)
    for (int a = 0; a < 4; ++a)
      for (int b = 0; b < 4; ++b) expected.insert({std::min(t[a], t[b]), std::max(t[a], t[b])});  // upper only
  std::set<std::pair<int32_t, int32_t>> got;
  std::vector<int32_t> row_of(p.nnzb());
  for (int32_t i = 0; i < n; ++i) {
    for (int32_t s = p.row_ptr[i]; s < p.row_ptr[i + 1]; ++s) {
      got.insert({i, p.col[s]});
      row_of[s] = i;
      if (s > p.row_ptr[i]) {
        EXPECT_LT(p.col[s - 1], p.col[s]) << "row " << i << " not sorted";
      }
    }
    EXPECT_EQ(p.col[p.diag[i]], i);
    EXPECT_GE(p.diag[i], p.row_ptr[i]);
    EXPECT_LT(p.diag[i], p.row_ptr[i + 1]);
  }
  EXPECT_EQ(got, expected);
  EXPECT_EQ(p.nnzb(), static_cast<int32_t>(expected.size()));
  for (size_t e = 0; e < mesh.tets.size(); ++e)
    for (int a = 0; a < 4; ++a)
      for (int b = 0; b < 4; ++b) {
        const int32_t s = slots[e][4 * a + b];
        ASSERT_GE(s, 0);
        EXPECT_EQ(row_of[s], std::min(mesh.tets[e][a], mesh.tets[e][b]));
        EXPECT_EQ(p.col[s], std::max(mesh.tets[e][a], mesh.tets[e][b]));
      }
  // Pairs that share no tetrahedron are not in the pattern: opposite corners of the box.
  EXPECT_EQ(p.find(test_meshes::box_node(2, 2, 0, 0, 0), test_meshes::box_node(2, 2, 2, 2, 2)), -1);
}

TEST(Bsr, SpmvMatchesDenseProduct) {
  auto s = make_system();
  std::mt19937_64 rng(99);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  // The SPD system and arbitrary values on the same pattern (the symmetric matrix whose upper
  // triangle they are; diagonal blocks are used as stored).
  std::vector<double> R(s->A.size());
  for (double& v : R) v = u(rng);
  for (const std::vector<double>* vals : {&s->A, &R}) {
    const Eigen::MatrixXd D = bsr_to_dense(s->pattern(), vals->data());
    std::vector<double> x(s->n3()), y(s->n3(), std::numeric_limits<double>::quiet_NaN());
    for (double& v : x) v = u(rng);
    bsr_spmv(s->pattern(), vals->data(), x.data(), y.data());  // y overwritten, not accumulated
    const Eigen::Map<const Eigen::VectorXd> xv(x.data(), s->n3()), yv(y.data(), s->n3());
    const double scale = (D.cwiseAbs() * xv.cwiseAbs()).maxCoeff();
    EXPECT_LE((yv - D * xv).cwiseAbs().maxCoeff(), 1e-14 * scale);
  }
}

TEST(Cg, SolvesToRequestedRelativeToleranceWithEachPreconditioner) {
  auto s = make_system();
  CgSolver cg(s->model.num_nodes);
  for (Preconditioner prec : kAllPrec)
    for (double tol : {1e-6, 1e-10}) {
      std::vector<double> x(s->n3(), 0.0);
      const SolveStats st = cg.solve(s->pattern(), s->A.data(), s->b.data(), x.data(), prec, 1000, tol);
      const double rel = true_relative_residual(*s, x);
      std::printf("  CG %-11s tol %.0e: %3d iterations, reported %.3e, true %.3e\n", name(prec),
                  tol, st.iterations, st.relative_residual, rel);
      EXPECT_TRUE(st.converged) << name(prec) << " tol " << tol;
      EXPECT_GE(st.iterations, 1);
      EXPECT_LT(st.iterations, 1000);
      // Recursive and true residual agree to round-off (‖b‖ units).
      EXPECT_NEAR(st.relative_residual, rel, 1e-12) << name(prec) << " tol " << tol;
      EXPECT_LE(rel, tol + 1e-12) << name(prec) << " tol " << tol;
      // Forward error bound: ‖x − x*‖/‖x*‖ ≤ κ(A)·‖r‖/‖b‖.
      const Eigen::Map<const Eigen::VectorXd> xv(x.data(), s->n3());
      EXPECT_LE((xv - s->xref).norm() / s->xref.norm(), 1.01 * s->cond * rel + 1e-13);
    }
}

TEST(Cg, PreconditioningReducesIterations) {
  // A preconditioner that is SPD but wrong (e.g. D instead of D⁻¹) still lets PCG converge, only
  // slower; this is the test that notices. Diagonal scaling helps here because the diagonal of
  // M + h²K varies several-fold between corner, edge and interior nodes.
  auto s = make_system();
  CgSolver cg(s->model.num_nodes);
  int it[3];
  for (int k = 0; k < 3; ++k) {
    std::vector<double> x(s->n3(), 0.0);
    it[k] = cg.solve(s->pattern(), s->A.data(), s->b.data(), x.data(), kAllPrec[k], 1000, 1e-10).iterations;
  }
  EXPECT_LE(it[1], it[2]) << "BlockJacobi vs None";
  EXPECT_LE(it[0], it[2]) << "Jacobi vs None";
}

TEST(Cg, TinyValuedSystemStillIteratesAndConverges) {
  // SI-like magnitudes: A ~ 1e-9, b ~ 1e-12 (‖b‖ ~ 1e-11). An absolute stopping threshold would
  // return the initial guess x = 0 here. Scaling by powers of two is exact in floating point,
  // so the relative test must take exactly the same iterations and give exactly the scaled x.
  auto s = make_system();
  const double amax = s->Ad.cwiseAbs().maxCoeff(), bmax = s->b.cwiseAbs().maxCoeff();
  const double sa = std::ldexp(1.0, -30 - std::ilogb(amax));  // max|A| ∈ [2^-30, 2^-29) ≈ 1e-9
  const double sb = std::ldexp(1.0, -40 - std::ilogb(bmax));  // max|b| ∈ [2^-40, 2^-39) ≈ 1e-12
  std::vector<double> At = s->A;
  for (double& v : At) v *= sa;
  const Eigen::VectorXd bt = s->b * sb;
  CgSolver cg(s->model.num_nodes);
  for (Preconditioner prec : kAllPrec) {
    std::vector<double> x(s->n3(), 0.0), xt(s->n3(), 0.0);
    const SolveStats st = cg.solve(s->pattern(), s->A.data(), s->b.data(), x.data(), prec, 1000, 1e-8);
    const SolveStats stt = cg.solve(s->pattern(), At.data(), bt.data(), xt.data(), prec, 1000, 1e-8);
    EXPECT_GE(stt.iterations, 1) << name(prec);
    EXPECT_TRUE(stt.converged) << name(prec);
    EXPECT_EQ(stt.iterations, st.iterations) << name(prec);
    EXPECT_NEAR(stt.relative_residual, st.relative_residual, 1e-12) << name(prec);
    double worst = 0;
    for (int32_t i = 0; i < s->n3(); ++i) worst = std::max(worst, std::abs(xt[i] * sa / sb - x[i]));
    EXPECT_LE(worst, 1e-12 * s->xref.cwiseAbs().maxCoeff()) << name(prec);
    // True residual of the tiny system.
    const Eigen::MatrixXd Adt = s->Ad * sa;
    const Eigen::Map<const Eigen::VectorXd> xv(xt.data(), s->n3());
    EXPECT_LE((bt - Adt * xv).norm() / bt.norm(), 1e-8 + 1e-12) << name(prec);
  }
}

TEST(Cg, ZeroRightHandSideGivesZeroSolution) {
  auto s = make_system();
  CgSolver cg(s->model.num_nodes);
  const std::vector<double> b(s->n3(), 0.0);
  for (Preconditioner prec : kAllPrec) {
    std::vector<double> x(s->n3(), 1.5);  // a stale warm start must not survive
    const SolveStats st = cg.solve(s->pattern(), s->A.data(), b.data(), x.data(), prec, 100, 1e-8);
    EXPECT_EQ(st.iterations, 0);
    EXPECT_TRUE(st.converged);
    EXPECT_EQ(st.relative_residual, 0.0);
    for (double v : x) ASSERT_EQ(v, 0.0) << name(prec);
  }
}

TEST(Cg, IterationCapReportsNotConverged) {
  auto s = make_system();
  CgSolver cg(s->model.num_nodes);
  for (Preconditioner prec : kAllPrec)
    for (int cap : {0, 3}) {
      std::vector<double> x(s->n3(), 0.0);
      const SolveStats st = cg.solve(s->pattern(), s->A.data(), s->b.data(), x.data(), prec, cap, 1e-14);
      EXPECT_FALSE(st.converged) << name(prec) << " cap " << cap;
      EXPECT_EQ(st.iterations, cap) << name(prec);
      for (double v : x) ASSERT_TRUE(std::isfinite(v));
      const double rel = true_relative_residual(*s, x);
      EXPECT_GT(rel, 1e-14);
      EXPECT_NEAR(st.relative_residual, rel, 1e-12) << name(prec) << " cap " << cap;
    }
}

TEST(Cg, WarmStartFromExactSolutionConvergesImmediately) {
  // x0 = the (round-off accurate) solution: the relative test is already met, so the solver
  // takes at most one iteration (the contract allows zero when the warm start meets it) and
  // does not spoil x.
  auto s = make_system();
  CgSolver cg(s->model.num_nodes);
  for (Preconditioner prec : kAllPrec) {
    std::vector<double> x(s->xref.data(), s->xref.data() + s->n3());
    const double rel0 = true_relative_residual(*s, x);
    ASSERT_GT(rel0, 0.0) << "test assumes a round-off residual, not an exactly zero one";
    ASSERT_LT(rel0, 1e-8);
    const SolveStats st = cg.solve(s->pattern(), s->A.data(), s->b.data(), x.data(), prec, 100, 1e-8);
    EXPECT_TRUE(st.converged) << name(prec);
    EXPECT_LE(st.iterations, 1) << name(prec);
    EXPECT_LE(true_relative_residual(*s, x), 1e-8) << name(prec);
    EXPECT_NEAR(st.relative_residual, true_relative_residual(*s, x), 1e-12) << name(prec);
    const Eigen::Map<const Eigen::VectorXd> xv(x.data(), s->n3());
    EXPECT_LE((xv - s->xref).norm() / s->xref.norm(), 1e-10) << name(prec);
  }
}

TEST(Cg, WarmStartNearSolutionNeedsFewerIterations) {
  // A warm start that does not meet the tolerance is iterated (≥ 1) to the tolerance, and a
  // good one (relative error 1e-4) needs fewer iterations than a cold start.
  auto s = make_system();
  CgSolver cg(s->model.num_nodes);
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (Preconditioner prec : kAllPrec) {
    std::vector<double> cold(s->n3(), 0.0), warm(s->n3());
    const double amp = 1e-4 * s->xref.cwiseAbs().maxCoeff();
    for (int32_t i = 0; i < s->n3(); ++i) warm[i] = s->xref(i) + amp * u(rng);
    ASSERT_GT(true_relative_residual(*s, warm), 1e-10);
    const SolveStats sc = cg.solve(s->pattern(), s->A.data(), s->b.data(), cold.data(), prec, 1000, 1e-10);
    const SolveStats sw = cg.solve(s->pattern(), s->A.data(), s->b.data(), warm.data(), prec, 1000, 1e-10);
    EXPECT_TRUE(sw.converged) << name(prec);
    EXPECT_GE(sw.iterations, 1) << name(prec);
    EXPECT_LT(sw.iterations, sc.iterations) << name(prec);
    EXPECT_LE(true_relative_residual(*s, warm), 1e-10 + 1e-12) << name(prec);

    // A warm start that already meets a loose tolerance: done at once, and the reported
    // residual is still the relative one (‖b‖ ≈ 5 here, so an absolute one would differ).
    std::vector<double> near(s->n3());
    for (int32_t i = 0; i < s->n3(); ++i) near[i] = s->xref(i) + amp * u(rng);
    const double rel0 = true_relative_residual(*s, near);
    ASSERT_LT(rel0, 1e-2);
    const SolveStats sl = cg.solve(s->pattern(), s->A.data(), s->b.data(), near.data(), prec, 1000, 1e-2);
    EXPECT_TRUE(sl.converged) << name(prec);
    EXPECT_LE(sl.iterations, 1) << name(prec);
    const double rel1 = true_relative_residual(*s, near);
    EXPECT_LE(rel1, 1e-2) << name(prec);
    EXPECT_NEAR(sl.relative_residual, rel1, 1e-12) << name(prec);
  }
}

TEST(Cg, WarmStartWithExactlyZeroResidualReportsConverged) {
  // A = 2·I on the mesh pattern and x0 = b/2: b − A·x0 is exactly 0. The solver is already at
  // the solution and must say so (converged, residual 0, x unchanged) rather than report the
  // zero search direction as a breakdown.
  auto s = make_system();
  std::vector<double> A(s->A.size(), 0.0);
  for (int32_t i = 0; i < s->model.num_nodes; ++i) {
    double* D = A.data() + 9 * s->pattern().diag[i];
    D[0] = D[4] = D[8] = 2.0;
  }
  CgSolver cg(s->model.num_nodes);
  for (Preconditioner prec : kAllPrec) {
    std::vector<double> x(s->n3());
    for (int32_t i = 0; i < s->n3(); ++i) x[i] = 0.5 * s->b(i);
    const std::vector<double> x0 = x;
    const SolveStats st = cg.solve(s->pattern(), A.data(), s->b.data(), x.data(), prec, 100, 1e-8);
    EXPECT_TRUE(st.converged) << name(prec) << " (iterations " << st.iterations << ")";
    EXPECT_LE(st.iterations, 1) << name(prec);
    EXPECT_EQ(st.relative_residual, 0.0) << name(prec);
    EXPECT_EQ(x, x0) << name(prec);
  }
}

TEST(Cholmod, SolvesSpdSystem) {
  auto s = make_system();
  CholmodSolver chol(s->pattern());
  ASSERT_TRUE(chol.factor(s->A.data()));
  std::vector<double> x(s->n3(), 0.0);
  chol.solve(s->b.data(), x.data());
  const double rel = true_relative_residual(*s, x);
  std::printf("  CHOLMOD: relative residual %.3e\n", rel);
  EXPECT_LE(rel, 1e-10);
  const Eigen::Map<const Eigen::VectorXd> xv(x.data(), s->n3());
  EXPECT_LE((xv - s->xref).norm() / s->xref.norm(), 1e-10);

  // Refactor with other values on the same pattern (the BSR → CSC map is reused).
  Eigen::MatrixXd A2 = s->Ad;
  A2.diagonal().array() += 0.5 * s->Ad.diagonal().array();
  const std::vector<double> vals2 = dense_to_bsr(s->pattern(), A2);
  ASSERT_TRUE(chol.factor(vals2.data()));
  chol.solve(s->b.data(), x.data());
  const Eigen::VectorXd x2 = A2.ldlt().solve(s->b);
  EXPECT_LE((xv - x2).norm() / x2.norm(), 1e-10);
  EXPECT_LE((s->b - A2 * xv).norm() / s->b.norm(), 1e-10);
}

TEST(Cholmod, FactorFailsForIndefiniteMatrix) {
  auto s = make_system();
  CholmodSolver chol(s->pattern());
  // Shift by the median eigenvalue: half the spectrum negative.
  Eigen::MatrixXd Ai = s->Ad;
  Ai.diagonal().array() -= s->eig(s->eig.size() / 2);
  const std::vector<double> vi = dense_to_bsr(s->pattern(), Ai);
  EXPECT_FALSE(chol.factor(vi.data())) << "A - lambda_median I is indefinite";
  // Negative definite.
  std::vector<double> vn = s->A;
  for (double& v : vn) v = -v;
  EXPECT_FALSE(chol.factor(vn.data())) << "-A is negative definite";
  // The solver recovers on an SPD matrix after a failed factorisation.
  ASSERT_TRUE(chol.factor(s->A.data()));
  std::vector<double> x(s->n3(), 0.0);
  chol.solve(s->b.data(), x.data());
  EXPECT_LE(true_relative_residual(*s, x), 1e-10);
}

// A deadline stops CG at once; the iterate it returns is kept and reported as stopped.
TEST(Cg, DeadlineStopsTheSolveAndSaysSo) {
  auto s = make_system();
  CgSolver cg(s->model.num_nodes);
  std::vector<double> x(s->n3(), 0.0);
  Deadline past;
  past.at_ns = 1;  // long gone on the steady clock
  const SolveStats st = cg.solve(s->pattern(), s->A.data(), s->b.data(), x.data(), Preconditioner::Jacobi, 1000,
                                 1e-12, nullptr, &past);
  EXPECT_TRUE(st.budget_stopped);
  EXPECT_FALSE(st.converged);
  EXPECT_EQ(st.iterations, 1);  // the clock is read after each iteration
  // The one iteration done is kept: it lowered ½xᵀAx − bᵀx below its value at x = 0 (CG lowers
  // that quadratic, not necessarily the residual).
  const Eigen::Map<const Eigen::VectorXd> xv(x.data(), s->n3());
  EXPECT_LT(0.5 * xv.dot(s->Ad * xv) - s->b.dot(xv), 0.0);
}

// Safe start: an initial guess worse than zero in the quadratic ½xᵀAx − bᵀx is dropped, so a
// truncated solve is never worse than no correction; a good guess is kept.
TEST(Cg, SafeStartDropsAGuessWorseThanZero) {
  auto s = make_system();
  CgSolver cg(s->model.num_nodes);
  auto phi = [&](const std::vector<double>& x) {
    const Eigen::Map<const Eigen::VectorXd> xv(x.data(), s->n3());
    return 0.5 * xv.dot(s->Ad * xv) - s->b.dot(xv);
  };
  std::vector<double> bad(s->n3());
  for (int i = 0; i < s->n3(); ++i) bad[i] = -3.0 * s->xref(i);  // Φ(−3x*) = 7.5·|Φ(x*)| > 0
  ASSERT_GT(phi(bad), 0.0);
  std::vector<double> x = bad;
  SolveStats st = cg.solve(s->pattern(), s->A.data(), s->b.data(), x.data(), Preconditioner::Jacobi, 1, 1e-12,
                           nullptr, nullptr, true);
  EXPECT_TRUE(st.started_from_zero);
  EXPECT_LE(phi(x), 0.0) << "one iteration from zero lowers Φ below Φ(0) = 0";
  x = bad;
  cg.solve(s->pattern(), s->A.data(), s->b.data(), x.data(), Preconditioner::Jacobi, 1, 1e-12);
  EXPECT_GT(phi(x), 0.0) << "without the safe start one iteration from the bad guess stays above zero";
  std::vector<double> good(s->n3());
  for (int i = 0; i < s->n3(); ++i) good[i] = 0.9 * s->xref(i);
  x = good;
  st = cg.solve(s->pattern(), s->A.data(), s->b.data(), x.data(), Preconditioner::Jacobi, 1, 1e-12, nullptr, nullptr, true);
  EXPECT_FALSE(st.started_from_zero);
}

// The energy-norm error bound the time stepper reports: ½‖x − x*‖²_A ≤ ½ rᵀM⁻¹r for A = M + h²K
// (K PSD; r = A e, so the ratio lies in [1, λmax(M⁻¹A)]), for solves stopped after 1…20 iterations.
TEST(Cg, ResidualGivesAnEnergyNormErrorBound) {
  auto s = make_system();
  Eigen::VectorXd inv_sqrt_m(s->n3());
  for (int32_t i = 0; i < s->model.num_nodes; ++i)
    for (int k = 0; k < 3; ++k) inv_sqrt_m(3 * i + k) = 1.0 / std::sqrt(s->model.mass[i]);
  const Eigen::MatrixXd scaled = inv_sqrt_m.asDiagonal() * s->Ad * inv_sqrt_m.asDiagonal();
  const double lambda_max = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(scaled).eigenvalues().maxCoeff();
  CgSolver cg(s->model.num_nodes);
  for (int cap : {1, 2, 5, 10, 20}) {
    std::vector<double> x(s->n3(), 0.0);
    cg.solve(s->pattern(), s->A.data(), s->b.data(), x.data(), Preconditioner::Jacobi, cap, 1e-14);
    const double* r = cg.residual();
    double bound = 0;
    for (int32_t i = 0; i < s->model.num_nodes; ++i)
      for (int k = 0; k < 3; ++k) bound += 0.5 * r[3 * i + k] * r[3 * i + k] / s->model.mass[i];
    const Eigen::Map<const Eigen::VectorXd> xv(x.data(), s->n3());
    const Eigen::VectorXd e = xv - s->xref;
    const double actual = 0.5 * e.dot(s->Ad * e);
    EXPECT_LE(actual, bound * (1 + 1e-9)) << "cap " << cap;
    EXPECT_GE(actual, bound / lambda_max * (1 - 1e-9)) << "cap " << cap << ": no looser than M⁻¹A allows";
    EXPECT_GT(actual, 0.0);
  }
}

}  // namespace
}  // namespace stroma
