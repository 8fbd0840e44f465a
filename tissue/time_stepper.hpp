#pragma once
/// \file time_stepper.hpp
/// Time integration of the FEM system, split into the stages the tick pipeline times
/// separately: assemble (element pass + right-hand side), solve (linear system), integrate
/// (velocity and position update). Owns all scratch memory: no allocation after construction.
///
/// Implicit Euler, linearised (one Newton step per tick), Rayleigh damping C = αM + βK:
///   (M + hC + h²K) Δv = h (f_ext + f(x) − C v − h K v),   v ← v + Δv,   x ← x + h v.
/// Symplectic Euler: v ← v + h M⁻¹ (f_ext + f(x) − C v),   x ← x + h v.
/// Static: Newton on f_ext + f(x) = 0 with the tangent R·Ke·Rᵀ.

#include <functional>
#include <memory>
#include <vector>

#include "tissue/cg_solver.hpp"
#include "tissue/cholmod_solver.hpp"
#include "tissue/contact_spring.hpp"
#include "tissue/fem_model.hpp"
#include "tissue/options.hpp"
#include "tissue/tissue_state.hpp"

namespace stroma {

/// Solver settings (from the scenario's `solver:` section).
struct StepperSettings {
  Integrator integrator = Integrator::ImplicitEuler;
  LinearSolverKind linear_solver = LinearSolverKind::CG;
  Preconditioner preconditioner = Preconditioner::Jacobi;
  int max_iterations = 200;
  double tolerance = 1e-6;
  WarmStart warm_start = WarmStart::Extrapolate;
  double static_tolerance = 1e-8;
  int static_max_newton = 50;
  /// Implicit Euler: Newton iterations per step (1: the linearised step alone). Further
  /// iterations re-linearise at the iterate and are kept only if they lower the residual
  /// (backtracking line search); they stop once ‖residual‖ ≤ newton_tolerance × the step's scale.
  int newton_iterations = 1;
  double newton_tolerance = 1e-3;
};

/// What the Newton iterations after the linearised step did (TimeStepper::newton).
struct NewtonStats {
  int iterations = 1;              ///< linear solves in the step, the first (linearised) included
  int linear_iterations = 0;       ///< CG iterations of the extra solves
  double relative_residual = 0;    ///< ‖R(Δv)‖ / scale at exit (0: not measured, iterations = 1)
  int line_search_halvings = 0;    ///< step halvings the line search needed, summed
};

/// Result of a static solve.
struct StaticResult {
  int newton_iterations = 0;
  int linear_iterations = 0;      ///< CG iterations summed (0 with CHOLMOD)
  double relative_residual = 0;   ///< ‖f_ext + f(x)‖ / ‖f_ext‖ on free DOFs at exit
  bool converged = false;
};

/// Stages of one time step over a FemModel. Not thread-safe; one per physics thread.
class TimeStepper {
 public:
  TimeStepper(const FemModel& model, const StepperSettings& settings);
  ~TimeStepper();

  /// Load-time work that depends on the step size (the warped preconditioner's rest-pose
  /// factorisation), so the first tick is not slower than the others. Optional.
  void prepare(double h);

  /// Contact springs for the next assemble (the collide stage's output). The array must stay
  /// valid until assemble() has run; n = 0 clears them.
  void set_contact_springs(const ContactSpring* springs, int n) {
    springs_ = springs;
    n_springs_ = n;
  }

  /// Per-element damage d (stiffness × (1 − d)) for the following assemblies; null = none.
  void set_element_damage(const float* damage) { damage_ = damage; }
  /// Current lumped masses (damage removes ruptured elements' mass); null = the model's.
  /// Gravity follows the current mass.
  void set_node_mass(const double* mass) { mass_ = mass; }

  /// Stage "assemble": element pass at the current state and the step's right-hand side.
  /// Returns the elastic energy at s.x (before the step).
  double assemble(const TissueState& s, double h);
  /// Stage "solve": Δv (implicit Euler) into s.dv. No-op for symplectic Euler.
  SolveStats solve(TissueState& s);
  /// Newton iterations on the implicit-Euler equations after solve() (StepperSettings::
  /// newton_iterations > 1; no-op otherwise): R(Δv) = h(f_ext + f(x) + f_c − αMv − βK(x)v)
  /// − M Δv with v = v₀ + Δv and x = x₀ + h v (contacts as linearised at x₀, the same springs).
  /// Refines s.dv in place; s.x and s.v are not touched (integrate() applies the result).
  NewtonStats newton(TissueState& s, double h);
  /// Stage "integrate": update v and x; constrained nodes keep v = 0.
  void integrate(TissueState& s, double h);

  /// Newton iterations to static equilibrium from s.x (velocities zeroed). `before_iteration`,
  /// if given, runs before each iteration's assembly with the current iterate — the engine
  /// uses it to recompute contacts (set_contact_springs) as the active set changes.
  StaticResult solve_static(TissueState& s,
                            const std::function<void(const TissueState&)>& before_iteration = {});

  /// ½ vᵀ M v.
  double kinetic_energy(const TissueState& s) const;
  /// Potential of the constant external forces: −f_extᵀ (x − X).
  double external_potential(const TissueState& s) const;
  /// Elastic energy at s.x (a separate element pass; not for the hot loop).
  double elastic_energy(const TissueState& s) const;
  /// Elastic force at s.x into `f` (3n), for tests and diagnostics.
  void elastic_force(const TissueState& s, double* f) const;
  /// The implicit-Euler step's incremental potential Φ(Δv) (the merit newton()'s line search
  /// descends) and, into R (3n), its negative gradient R(Δv), for tests and diagnostics.
  /// Contacts: the springs of the last set_contact_springs. Uses the Newton scratch.
  double implicit_step_merit(const TissueState& s, double h, const double* dv, double* R) {
    double phi = 0;
    implicit_residual(s, h, dv, false, R, &phi);
    return phi;
  }
  /// Assembled tangent stiffness K(x) (unscaled, unprojected) into BSR values, for tests.
  void stiffness(const TissueState& s, std::vector<double>& kvals) const;

  const FemModel& model() const { return m_; }
  const StepperSettings& settings() const { return cfg_; }
  /// The element rotations of the last assemble (9 per element), for stress output.
  const std::vector<double>& rotations() const { return rot_; }

 private:
  void project_constraints(double* A, double diag_scale);
  /// R(dv) of the implicit-Euler equations into R (see newton()); with `matrix`, also A at the
  /// iterate (A_, its constraints projected; node rotations updated). Returns ‖R‖. `merit`:
  /// the incremental potential Φ(Δv) whose gradient is −R (up to a constant; damping and
  /// contact stiffness frozen as in R): ½ΔvᵀMΔv + U(x + h·v') − h·f_ext·v' + ½h·α·v'ᵀMv'
  /// + ½v'ᵀ(hβK)v' + the linearised contacts' potential, v' = v + Δv. The line search of
  /// newton() descends it, so an accepted iteration never adds energy the equations lack.
  double implicit_residual(const TissueState& s, double h, const double* dv, bool matrix, double* R,
                           double* merit = nullptr);
  /// Factors A₀ = (1 + h_mass·α)·M + (k_beta·β + k_const)·K(rest) for the warped
  /// preconditioner (h_mass < 0: no mass term, for static solves).
  void build_rest_factor(double h_mass, double k_beta, double k_const);
  /// Per-node rotations (9 per node) from the element rotations of the last element pass.
  void update_node_rotations();
  static void apply_warped(void* self, const double* r, double* z);
  const FemModel& m_;
  StepperSettings cfg_;
  bool any_beta_ = false;
  const float* damage_ = nullptr;
  const double* mass_ = nullptr;
  double mass(int32_t i) const { return mass_ ? mass_[i] : m_.mass[i]; }
  const ContactSpring* springs_ = nullptr;
  int n_springs_ = 0;
  std::vector<double> force_, kv_, rhs_, A_, rot_, tmp_;
  std::vector<double> newton_x_, newton_v_, newton_r_, newton_trial_r_, newton_delta_, newton_dv_;  // Newton scratch
  CgSolver cg_;
  std::unique_ptr<CholmodSolver> cholmod_;
  // Warped rest-pose Cholesky preconditioner (only when selected).
  std::unique_ptr<CholmodSolver> rest_factor_;
  double rest_factor_key_[3] = {-1, -1, -1};  // coefficients it was built with
  std::vector<int32_t> node_element_;          // an element incident to each node (−1: none)
  std::vector<double> node_rot_, warp_a_, warp_b_;
  ExternalPreconditioner warp_op_;
};

}  // namespace stroma
