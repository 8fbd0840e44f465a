// Rods (suture threads, tissue/rod.hpp) against independent expectations: the pass's forces are
// the energy's gradient and its tangent the forces' derivative (finite differences); a thread
// hanging between two points is the extensible catenary (closed form, Irvine 1981); a clamped
// thread under its weight and an end load is the elastica (a shooting solution of the rod's
// equations, itself checked against the small-deflection formula); a swinging thread never gains
// energy.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <random>
#include <vector>

#include "tissue/bsr_matrix.hpp"
#include "tissue/cg_solver.hpp"
#include "tissue/constraints.hpp"
#include "tissue/fem_build.hpp"
#include "tissue/fem_forces.hpp"
#include "tissue/time_stepper.hpp"
#include "tissue/tissue_state.hpp"
#include "tests/test_fem.hpp"
#include "tests/test_meshes.hpp"
#include "tissue/mesh_prepare.hpp"

using namespace stroma;
using stroma::test_fem::energy_and_force;

namespace {

constexpr double kPi = 3.14159265358979323846;

FemModel rod_model(const FemRodInput& rod, const Vec3& gravity) { return build_fem_model({}, gravity, false, {rod}); }

/// A rod of segments of length `l` (Young's modulus E, diameter d, density ρ) with its nodes at
/// x = l·i for i in [first, last], along x, nothing fixed.
FemRodInput straight_rod(double l, double E, double d, double rho, int first, int last) {
  FemRodInput in;
  in.name = "thread";
  in.segment_length = l;
  in.young_modulus = E;
  in.diameter = d;
  in.density = rho;
  for (int i = first; i <= last; ++i) in.nodes.push_back({l * i, 0, 0});
  return in;
}

/// Bisection for the root of a monotone function on [lo, hi].
double bisect(const std::function<double(double)>& g, double lo, double hi) {
  const double glo = g(lo);
  for (int i = 0; i < 200; ++i) {
    const double mid = 0.5 * (lo + hi);
    if ((g(mid) > 0) == (glo > 0)) lo = mid;
    else hi = mid;
  }
  return 0.5 * (lo + hi);
}

/// Expects the element pass's forces at x to be −∂E/∂x (within 1e-6 of the largest) and its
/// assembled tangent −∂f/∂x along a random direction (within 1e-5), by central differences.
void expect_forces_and_tangent_are_the_energys(const FemModel& m, const std::vector<double>& x, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(-1, 1);
  std::vector<double> f;
  energy_and_force(m, x, &f);
  const double eps = 1e-7;
  double worst_f = 0, fmax = 0;
  for (size_t d = 0; d < x.size(); ++d) {
    std::vector<double> xp = x, xm = x;
    xp[d] += eps;
    xm[d] -= eps;
    const double g = (energy_and_force(m, xp, nullptr) - energy_and_force(m, xm, nullptr)) / (2 * eps);
    worst_f = std::max(worst_f, std::abs(f[d] + g));
    fmax = std::max(fmax, std::abs(f[d]));
  }
  EXPECT_LT(worst_f, 1e-6 * fmax) << "f = −∂E/∂x";

  std::vector<double> K(9 * m.pattern.nnzb(), 0.0);
  ElasticPass p;
  p.x = x.data();
  p.kvals = K.data();
  p.k_const = 1.0;
  elastic_pass(m, p);
  std::vector<double> dir(x.size()), Kd(x.size(), 0.0);
  for (double& v : dir) v = u(rng);
  bsr_spmv(m.pattern, K.data(), dir.data(), Kd.data());
  std::vector<double> xp = x, xm = x, fp, fm;
  for (size_t d = 0; d < x.size(); ++d) xp[d] += eps * dir[d], xm[d] -= eps * dir[d];
  energy_and_force(m, xp, &fp);
  energy_and_force(m, xm, &fm);
  double worst_k = 0, kmax = 0;
  for (size_t d = 0; d < x.size(); ++d) {
    worst_k = std::max(worst_k, std::abs(Kd[d] + (fp[d] - fm[d]) / (2 * eps)));
    kmax = std::max(kmax, std::abs(Kd[d]));
  }
  EXPECT_LT(worst_k, 1e-5 * kmax) << "K = −∂f/∂x";
}

}  // namespace

// The forces are −∂E/∂x and the assembled tangent is −∂f/∂x (central differences, a stretched
// and bent rod in 3-D, so the geometric part of the stretching tangent is exercised).
TEST(Rod, ForcesAreTheEnergysGradientAndTheTangentTheirDerivative) {
  const FemModel m = rod_model(straight_rod(0.01, 2e6, 1e-3, 1100, 0, 5), {0, 0, 0});
  ASSERT_EQ(m.rods.size(), 1u);
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-1, 1);
  std::vector<double> x = m.rest;
  for (size_t i = 0; i < x.size(); ++i) x[i] = 1.5 * x[i] + 1e-3 * u(rng);  // every segment stretched
  EXPECT_GT(energy_and_force(m, x, nullptr), 0);
  expect_forces_and_tangent_are_the_energys(m, x, rng);

  // The mass: ρ·A·L in all, half a segment's on each end node.
  const double A = kPi * 1e-6 / 4;
  double total = 0;
  for (double mi : m.mass) total += mi;
  EXPECT_NEAR(total, 1100 * A * 0.05, 1e-15);
  EXPECT_NEAR(m.mass[0], 1100 * A * 0.005, 1e-16);
}

// An anchor (RodAnchor: a rod's end tied to a material point of a tetrahedron) joins the same
// pass: with a linear tetrahedron beside it (whose forces are exactly its energy's gradient),
// the total force is −∂E/∂x and the assembled tangent −∂f/∂x by central differences; the
// pattern couples the rod's end and the tetrahedron's nodes.
TEST(Rod, AnAnchorsForcesAndTangentAreItsEnergys) {
  TetMesh tet;
  tet.nodes = {{0, 0, 0}, {0.01, 0, 0}, {0, 0.01, 0}, {0, 0, 0.01}};
  tet.tets = {{0, 1, 2, 3}};
  const PreparedMesh pm = prepare_mesh(tet);
  const FemBodyInput b = test_meshes::body_input(pm, ElementModel::Linear, RotationMethod::Polar, 1e3, 0.45, 1000);
  FemRodInput rod = straight_rod(0.01, 2e6, 1e-3, 1100, 0, 5);
  for (Vec3& p : rod.nodes) p[0] += 0.003, p[1] += 0.002, p[2] += 0.001;  // the first node inside the tet
  RodAnchor an;
  an.node = 0;
  for (int a = 0; a < 4; ++a) an.tissue[a] = a;
  const double w[4] = {0.4, 0.3, 0.2, 0.1};
  for (int a = 0; a < 4; ++a) an.w[a] = w[a];
  an.stiffness = 500;
  rod.anchors.push_back(an);
  const FemModel m = build_fem_model({b}, {0, 0, 0}, false, {rod});
  ASSERT_EQ(m.rod_anchors.size(), 1u);
  EXPECT_EQ(m.rod_anchors[0].node, 4);
  for (int a = 0; a < 4; ++a) EXPECT_GE(m.pattern.find_upper(a, 4), 0) << "tissue node " << a << " and the rod's end";
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-1, 1);
  std::vector<double> x = m.rest;
  for (int32_t i = 5; i < m.num_nodes; ++i) x[3 * i] += 0.005 * (i - 4);  // every segment stretched (the
  for (double& v : x) v += 1e-3 * u(rng);  // compressed tangent is projected, not the derivative)
  expect_forces_and_tangent_are_the_energys(m, x, rng);
}

// A spring joining two parts the pattern does not couple (a rod's node and a tetrahedron's
// point: ContactSpring with signed weights, its cross pairs kSlotMatrixFree, applied in each
// CG product) steps exactly as the same zero-length spring assembled into the pattern (the
// model's RodAnchor): a linear spring linearised at the step's start is the spring itself, so
// the two trajectories agree to the solves' tolerance — under CG with Jacobi, block Jacobi
// (the rod's band), and CHOLMOD (the factor of the assembled part preconditioning CG).
TEST(Rod, ASpringAcrossPartsAppliedMatrixFreeStepsAsTheAssembledAnchor) {
  TetMesh tet;
  tet.nodes = {{0, 0, 0}, {0.01, 0, 0}, {0, 0.01, 0}, {0, 0, 0.01}};
  tet.tets = {{0, 1, 2, 3}};
  const PreparedMesh pm = prepare_mesh(tet);
  FemBodyInput b = test_meshes::body_input(pm, ElementModel::Corotational, RotationMethod::Polar, 3e3, 0.45, 1000);
  b.fixed = {{0, 7}};  // one corner held: the tetrahedron hangs and turns
  FemRodInput rod = straight_rod(0.002, 5e7, 2e-4, 1100, 0, 10);
  for (Vec3& p : rod.nodes) p[0] += 0.003, p[1] += 0.002, p[2] += 0.001;  // its first node inside the tet
  const double w[4] = {0.4, 0.3, 0.2, 0.1};
  RodAnchor an;
  for (int a = 0; a < 4; ++a) an.tissue[a] = a, an.w[a] = w[a];
  an.stiffness = 300;
  FemRodInput anchored = rod;
  anchored.anchors.push_back(an);
  const FemModel with = build_fem_model({b}, {0, -9.81, 0}, false, {anchored});
  const FemModel without = build_fem_model({b}, {0, -9.81, 0}, false, {rod});
  const int32_t r0 = without.rods[0].node_begin;
  for (const LinearSolverKind solver : {LinearSolverKind::CG, LinearSolverKind::Cholmod})
    for (const Preconditioner prec : {Preconditioner::Jacobi, Preconditioner::BlockJacobi}) {
      if (solver == LinearSolverKind::Cholmod && prec == Preconditioner::BlockJacobi) continue;
      StepperSettings set;
      set.linear_solver = solver;
      set.preconditioner = prec;
      set.tolerance = 1e-12;
      set.max_iterations = 500;
      TimeStepper ta(with, set), tb(without, set);
      TissueState sa = TissueState::at_rest(with), sb = TissueState::at_rest(without);
      const double h = 1e-3;
      double worst = 0, scale = 0;
      for (int step = 0; step < 300; ++step) {
        ta.assemble(sa, h, {});
        ASSERT_TRUE(ta.solve(sa).converged);
        ta.integrate(sa, h);
        ContactSpring sp;
        sp.n = 5;
        const int32_t nodes[5] = {r0, 0, 1, 2, 3};
        const double c[5] = {1.0, -w[0], -w[1], -w[2], -w[3]};
        for (int a = 0; a < 5; ++a) sp.node[a] = nodes[a], sp.w[a] = c[a];
        for (int a = 0; a < 5; ++a)
          for (int q = 0; q < 5; ++q) {
            const int32_t sl = without.pattern.find_upper(nodes[a], nodes[q]);
            sp.slot[spring_slot(a, q)] = sl < 0 ? kSlotMatrixFree : (nodes[a] <= nodes[q] ? sl : -1);
          }
        sp.matrix_free = 1;
        double d[3];
        spring_point(sp, sb.x.data(), d);
        for (int k = 0; k < 3; ++k) sp.force[k] = -an.stiffness * d[k], sp.K[4 * k] = an.stiffness;
        StepInputs in;
        in.springs = &sp;
        in.spring_count = 1;
        in.contact_origin = sb.x.data();
        tb.assemble(sb, h, in);
        ASSERT_TRUE(tb.solve(sb).converged);
        tb.integrate(sb, h);
        for (size_t i = 0; i < sb.x.size(); ++i) {
          worst = std::max(worst, std::abs(sa.x[i] - sb.x[i]));
          scale = std::max(scale, std::abs(sa.x[i] - with.rest[i]));
        }
      }
      EXPECT_GT(scale, 1e-3) << "it moved";
      EXPECT_LT(worst, 1e-9 * scale) << "solver " << int(solver) << ", preconditioner " << int(prec);
    }
}

// A thread of length L = 1 m hanging under its weight between two fixed points 0.8 m apart at
// the same height, soft enough to stretch ~5 %: the static solution against the extensible
// catenary, x(σ) = Hσ/EA + (H/w)·asinh(wσ/H), y(σ) = wσ²/(2EA) + (H/w)(√(1 + (wσ/H)²) − 1),
// σ the unstretched arc length from the lowest point, H from the span. Within 1 % of the sag at
// every node; the inextensible catenary is further off than that (the test can tell them apart).
TEST(Rod, AHangingThreadIsTheExtensibleCatenary) {
  const double L = 1.0, D = 0.8, d = 1e-3, E = 1e5, rho = 1000, g = 9.81;
  const int N = 40;
  FemRodInput in = straight_rod(L / N, E, d, rho, 0, -1);  // (its nodes below)
  // Start on the circular arc of length L through the two supports.
  const double phi = bisect([&](double p) { return std::sin(p) / p - D / L; }, 1e-6, kPi - 1e-6);
  const double R = L / (2 * phi);
  for (int i = 0; i <= N; ++i) {
    const double a = -phi + 2 * phi * i / N;
    in.nodes.push_back({R * std::sin(a), -(R * std::cos(a) - R * std::cos(phi)), 0});
  }
  in.fixed = {{0, 7}, {N, 7}};
  const FemModel m = rod_model(in, {0, -g, 0});
  TissueState s = TissueState::at_rest(m);
  StepperSettings set;
  set.linear_solver = LinearSolverKind::Cholmod;
  set.static_tolerance = 1e-10;
  TimeStepper ts(m, set);
  for (int k = 1; k <= 4; ++k) ASSERT_TRUE(ts.solve_static(s, 0.25 * k).converged) << "load step " << k;

  const double A = kPi * d * d / 4, EA = E * A, w = rho * A * g;
  auto x_of = [&](double H, double sg) { return H * sg / EA + H / w * std::asinh(w * sg / H); };
  auto y_of = [&](double H, double sg) { return w * sg * sg / (2 * EA) + H / w * (std::sqrt(1 + std::pow(w * sg / H, 2)) - 1); };
  const double H = bisect([&](double h) { return 2 * x_of(h, L / 2) - D; }, 1e-8, 10.0);
  const double sag = y_of(H, L / 2);
  // The inextensible catenary's H for the same span (EA → ∞).
  const double Hi = bisect([&](double h) { return 2 * h / w * std::asinh(w * L / 2 / h) - D; }, 1e-8, 10.0);
  double worst = 0, worst_inextensible = 0;
  for (int i = 0; i <= N; ++i) {
    const double sg = -L / 2 + L * i / N;
    const double xr = x_of(H, sg), yr = y_of(H, sg) - sag;  // supports at y = 0
    const double xi = Hi / w * std::asinh(w * sg / Hi);
    const double yi = Hi / w * (std::sqrt(1 + std::pow(w * sg / Hi, 2)) - std::sqrt(1 + std::pow(w * L / 2 / Hi, 2)));
    const double* p = s.x.data() + 3 * i;
    worst = std::max(worst, std::hypot(p[0] - xr, p[1] - yr));
    worst_inextensible = std::max(worst_inextensible, std::hypot(p[0] - xi, p[1] - yi));
    EXPECT_NEAR(p[2], 0.0, 1e-12);
  }
  EXPECT_LT(worst, 0.01 * sag) << "sag " << sag << " m, H " << H << " N";
  EXPECT_GT(worst_inextensible, 0.01 * sag) << "the inextensible catenary is distinguishable";
  // The stretch: the end segments carry the largest tension T = √(H² + (wL/2)²), strain T/EA.
  const double* a = s.x.data();
  const double end_strain = std::hypot(a[3] - a[0], a[4] - a[1]) / (L / N) - 1;
  EXPECT_NEAR(end_strain, std::hypot(H, w * (L / 2 - L / N / 2)) / EA, 0.02 * end_strain);
}

namespace {

/// The elastica of a cantilever of length L, clamped horizontally at s = 0, under a distributed
/// weight q (N/m) and a vertical end load P (N, both downward): EI·θ'' = (P + q(L − s))·cos θ,
/// θ(0) = 0, θ'(L) = 0 (no moment at the free end), shot on θ'(0) with RK4 over `steps` steps.
/// Returns the tip's (x, y).
std::array<double, 2> elastica_tip(double L, double EI, double q, double P, int steps = 4000) {
  auto shoot = [&](double c, double* tip_x, double* tip_y) {
    double th = 0, om = c, x = 0, y = 0;
    const double h = L / steps;
    auto rhs = [&](double s, double t, double o, double* dt, double* dom, double* dx, double* dy) {
      *dt = o;
      *dom = (P + q * (L - s)) * std::cos(t) / EI;
      *dx = std::cos(t);
      *dy = std::sin(t);
    };
    for (int i = 0; i < steps; ++i) {
      const double s = i * h;
      double k1[4], k2[4], k3[4], k4[4];
      rhs(s, th, om, &k1[0], &k1[1], &k1[2], &k1[3]);
      rhs(s + h / 2, th + h / 2 * k1[0], om + h / 2 * k1[1], &k2[0], &k2[1], &k2[2], &k2[3]);
      rhs(s + h / 2, th + h / 2 * k2[0], om + h / 2 * k2[1], &k3[0], &k3[1], &k3[2], &k3[3]);
      rhs(s + h, th + h * k3[0], om + h * k3[1], &k4[0], &k4[1], &k4[2], &k4[3]);
      th += h / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0]);
      om += h / 6 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1]);
      x += h / 6 * (k1[2] + 2 * k2[2] + 2 * k3[2] + k4[2]);
      y += h / 6 * (k1[3] + 2 * k2[3] + 2 * k3[3] + k4[3]);
    }
    if (tip_x) *tip_x = x, *tip_y = y;
    return om;  // θ'(L): zero at the solution
  };
  const double scale = (P * L + q * L * L / 2) / EI;  // |θ'(0)| of the linear solution
  const double c = bisect([&](double c0) { return shoot(c0, nullptr, nullptr); }, -2 * scale - 1e-12, 0.0);
  std::array<double, 2> tip{};
  shoot(c, &tip[0], &tip[1]);
  return tip;
}

}  // namespace

// A thread clamped horizontally at one end (two fixed nodes: a clamp holds the tangent of its
// fixed segment, at that segment's middle) drooping under its weight and an end load: the
// large-deflection elastica from the clamp (shooting solution, above; the shooting itself
// reproduces P·L³/(3EI) at a small load to 0.1 %). The tip within 2 % of its deflection at a load
// that bends it ~20° at the tip's chord, and second-order convergence: halving the segments
// divides the error by more than 3.
TEST(Rod, AClampedThreadUnderItsWeightAndAnEndLoadIsTheElastica) {
  const double L = 0.1, d = 1e-3, E = 1e8, rho = 1000, g = 9.81;
  const double I = kPi * std::pow(d, 4) / 64, EI = E * I, q = rho * kPi * d * d / 4 * g;
  const double P = 0.5 * EI / (L * L);
  {  // the reference at a small end load, no weight: the linear cantilever
    const double p = 1e-3 * EI / (L * L);
    const std::array<double, 2> t = elastica_tip(L, EI, 0.0, p);
    ASSERT_NEAR(-t[1], p * L * L * L / (3 * EI), 1e-3 * p * L * L * L / (3 * EI));
  }
  // The thread: N segments from the clamp node at x = 0 to the tip at x = L, a ghost node one
  // segment behind; the clamp is at x = −ℓ/2, so the elastica's length is L + ℓ/2.
  auto tip_error = [&](int N, double* deflection) {
    const double l = L / N;
    std::array<double, 2> ref = elastica_tip(L + l / 2, EI, q, P);
    ref[0] -= l / 2;
    FemRodInput in = straight_rod(l, E, d, rho, -1, N);
    in.fixed = {{0, 7}, {1, 7}};  // the ghost node and the clamp node
    in.nodal_forces = {{N + 1, {0, -P, 0}}};
    const FemModel m = rod_model(in, {0, -g, 0});
    TissueState s = TissueState::at_rest(m);
    StepperSettings set;
    set.linear_solver = LinearSolverKind::Cholmod;
    set.static_tolerance = 1e-7;  // (the residual's round-off floor is ~5e-9 here: EA/ℓ is 4e4 N/m)
    TimeStepper ts(m, set);
    for (int k = 1; k <= 10; ++k) {
      const StaticResult r = ts.solve_static(s, 0.1 * k);
      EXPECT_TRUE(r.converged) << "N " << N << ", load step " << k << ": residual " << r.relative_residual;
    }
    const double* tip = s.x.data() + 3 * (N + 1);
    *deflection = std::hypot(ref[0] + l / 2 - L, ref[1]);
    EXPECT_GT(std::atan2(-ref[1], ref[0] + l / 2), 0.3) << "a large deflection";
    return std::hypot(tip[0] - ref[0], tip[1] - ref[1]);
  };
  double deflection = 0;
  const double e25 = tip_error(25, &deflection), e50 = tip_error(50, &deflection);
  EXPECT_LT(e50, 0.02 * deflection) << "2 mm segments";
  EXPECT_LT(e25, 0.02 * deflection) << "4 mm segments";
  EXPECT_GT(e25 / e50, 3.0) << "second order: " << e25 << " m, then " << e50 << " m";
}

// A 15 cm suture (0.2 mm, E 5 GPa, 75 segments of 2 mm) fixed at one end and let go
// horizontally swings under gravity, stepped by implicit Euler at dt = 1 ms with CG (block
// Jacobi, the rod's rows by its band): its mechanical energy (kinetic + gravity's potential +
// elastic) never grows from one step to the next, it stretches less than 1 % while it swings,
// and every solve converges within 10 iterations.
TEST(Rod, ASwingingThreadNeverGainsEnergy) {
  const int N = 75;
  FemRodInput in = straight_rod(0.002, 5e9, 2e-4, 1100, 0, N);
  in.fixed = {{0, 7}};
  const FemModel m = rod_model(in, {0, -9.81, 0});
  TissueState s = TissueState::at_rest(m);
  StepperSettings set;
  set.preconditioner = Preconditioner::BlockJacobi;  // CG (the default), the rod's rows by its band
  TimeStepper ts(m, set);
  const double h = 1e-3;
  ts.prepare(h);
  auto energy = [&] { return ts.kinetic_energy(s) + ts.external_potential(s) + ts.elastic_energy(s); };
  double last = energy(), max_strain = 0;
  int max_iterations = 0;
  double weight = 0;
  for (double mi : m.mass) weight += mi * 9.81;
  const double scale = weight * 0.002 * N;  // the thread's weight × its length (J)
  for (int step = 0; step < 1500; ++step) {
    ts.assemble(s, h, StepInputs{});
    const SolveStats st = ts.solve(s);
    ASSERT_TRUE(st.converged) << "step " << step;
    max_iterations = std::max(max_iterations, st.iterations);
    ts.integrate(s, h);
    const double now = energy();
    ASSERT_LE(now, last + 1e-9 * scale) << "step " << step;
    last = now;
    for (int i = 0; i < N; ++i) {
      const double* a = s.x.data() + 3 * i;
      max_strain = std::max(max_strain, std::hypot(a[3] - a[0], a[4] - a[1], a[5] - a[2]) / 0.002 - 1);
    }
  }
  EXPECT_LT(s.x[3 * N + 1], -0.05) << "it swung down";
  EXPECT_LT(max_strain, 0.01);
  EXPECT_LE(max_iterations, 10) << "CG with the rod's band";
}

// CG on a rod's implicit system (M + h²K, dt = 1 ms, a suture's stiffness: h²K/M ~ 10⁶) converges
// in a handful of iterations under block Jacobi and Jacobi: the rod's rows are preconditioned by
// the exact Cholesky factor of its band (CgSolver::set_rods); without it, the chain's
// conditioning caps CG. Two shapes of a 75-segment thread: wavy (segments stretched, compressed,
// bent), and straight with its first segment tilted by 10 µm (its node's block nearly singular
// across the axis: a 3×3-block L·D·Lᵀ lost half the solution's accuracy by the chain's end).
TEST(Rod, ItsBandPreconditionerSolvesItsRowsInAFewIterations) {
  const int N = 75;
  FemRodInput in = straight_rod(0.0025, 5e9, 2e-4, 1100, 0, N);
  in.fixed = {{0, 7}};
  const FemModel m = rod_model(in, {0, -9.81, 0});
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(-1, 1);
  for (const bool wavy : {true, false}) {
    std::vector<double> x = m.rest;
    for (int i = 1; i <= N; ++i) {
      if (wavy) {
        x[3 * i + 1] = 0.01 * std::sin(0.3 * i) + 2e-4 * u(rng);
        x[3 * i] = 0.0025 * i * (1 + 0.003 * std::sin(0.7 * i));
      } else {
        x[3 * i + 1] -= 1e-5;
      }
    }
    const double h = 1e-3;
    std::vector<double> A(9 * m.pattern.nnzb(), 0.0);
    ElasticPass p;
    p.x = x.data();
    p.kvals = A.data();
    p.k_const = h * h;
    elastic_pass(m, p);
    add_mass_diagonal(m, A.data(), h, m.mass.data());
    project_constraints(m, A.data(), 1.0, true);
    std::vector<double> b(3 * m.num_nodes);
    for (int32_t i = 0; i < m.num_nodes; ++i)
      for (int k = 0; k < 3; ++k) b[3 * i + k] = (m.constrained[i] ? 0.0 : u(rng) * 1e-6);
    for (Preconditioner prec : {Preconditioner::BlockJacobi, Preconditioner::Jacobi}) {
      CgSolver with(m.num_nodes), without(m.num_nodes);
      with.set_rods(m.pattern, m.rods);
      std::vector<double> x1(b.size(), 0.0), x2(b.size(), 0.0);
      const SolveStats a = with.solve(m.pattern, A.data(), b.data(), x1.data(), prec, 200, 1e-10);
      const SolveStats c = without.solve(m.pattern, A.data(), b.data(), x2.data(), prec, 200, 1e-10);
      EXPECT_TRUE(a.converged) << (wavy ? "wavy: " : "tilted: ") << a.relative_residual << " after " << a.iterations;
      EXPECT_LE(a.iterations, 3) << (wavy ? "wavy" : "tilted") << ", with the rod's band";
      EXPECT_GT(c.iterations, 50) << (wavy ? "wavy" : "tilted") << ", without it (the Jacobi blocks alone)";
    }
  }
}
