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

#include <algorithm>
#include <cstdint>
#include <functional>
#include <memory>
#include <vector>

#include "tissue/cg_solver.hpp"
#include "tissue/cholmod_solver.hpp"
#include "tissue/contact_spring.hpp"
#include "tissue/fem_model.hpp"
#include "tissue/options.hpp"
#include "tissue/rigid_rows.hpp"
#include "tissue/solver_costs.hpp"
#include "tissue/tissue_state.hpp"
#include "tissue/warped_preconditioner.hpp"

namespace stroma {

/// Solver settings (from the scenario's `solver:` section). Invariants (the loader checks
/// them): max_iterations, static_max_newton, newton_iterations ≥ 1 (`auto` resolved at compile);
/// 0 < tolerance, newton_tolerance < 1; static_tolerance > 0.
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
  /// Warped Cholesky with implicit Euler: refresh its factor from the system of a recent step
  /// on a worker thread every this many steps (0: never, the rest-pose factor throughout;
  /// −1: auto — auto_refresh_period(), at prepare()).
  int preconditioner_refresh = 0;
  /// `preconditioner_refresh: auto` resolved (compile): the period above is the first, and the
  /// stepper re-evaluates it from the running mean of its warped iterations (auto_refresh_period).
  bool refresh_follows_pace = false;
  /// Implicit Euler: each element's stiffness blocks R·Ke·Rᵀ are made once every this many
  /// steps (1, the default: every step). With N > 1 each step makes those of a 1/N share of the
  /// element batches, into a matrix that replaces the one in use once all N shares are in it,
  /// and solves with the one in use (made over the N steps before the last N): the same work
  /// every step, no step that makes them all. The forces, the rods', node domains' and contacts'
  /// stiffness are of the step's own positions. A lagged tangent: the step stays implicit, its
  /// system symmetric positive definite (each element's share is), and a body comes to rest
  /// where the forces balance, as with a fresh one; what it costs in accuracy and saves in time
  /// is in docs/PERFORMANCE.md ("Stiffness every N steps"). The state keeps both matrices
  /// (SolverHistory::element_blocks). A step of another length (a sub-step) makes its own.
  int stiffness_every = 1;
};


/// What the Newton iterations after the linearised step did (TimeStepper::newton).
struct NewtonStats {
  int iterations = 1;              ///< linear solves in the step, the first (linearised) included
  int linear_iterations = 0;       ///< CG iterations of the extra solves
  double relative_residual = 0;    ///< ‖R(Δv)‖ / scale at exit (0: not measured, iterations = 1)
  int line_search_halvings = 0;    ///< step halvings the line search needed, summed
  int64_t element_pass_ns = 0;     ///< wall time of its element passes (residuals, assemblies)
  bool budget_stopped = false;     ///< stopped by the deadline before converging
};

/// What a step is solved against besides the state: the collide stage's contact springs and
/// the damage stage's element damage and current lumped masses. Pointers (may be null: none /
/// the model's masses) must stay valid until the step's integrate() has run.
struct StepInputs {
  const ContactSpring* springs = nullptr;  ///< this tick's contacts
  int spring_count = 0;
  const float* damage = nullptr;       ///< per element d ∈ [0, 1]: stiffness × (1 − d)
  const double* node_mass = nullptr;   ///< current lumped masses (gravity follows them)
  /// Positions the springs were found at (their linearisation point); null: no contact energy.
  const double* contact_origin = nullptr;
  /// Rigid bodies touching something this step: their rows join the step's system
  /// (tissue/rigid_rows.hpp) and the solve fills their Δu. Null: none.
  const RigidRowsInput* rigid = nullptr;
  /// 3 per spring: each spring's force where this step starts, when that is not where the
  /// springs were found — a sub-step after the first: f − K·d, d the spring's relative
  /// displacement since (the springs are linear about where they were found). Null: the
  /// springs' own `force` (a step from where they were found). The energy guard's potential
  /// keeps measuring from contact_origin with the springs' own force, as before.
  const double* spring_force = nullptr;
};

/// What energy_guard() did to a step.
enum class EnergyLimit : uint8_t {
  None,            ///< the step did not gain energy
  VelocityScaled,  ///< the velocities were scaled down to the energy the step started with
  PositionsPulled, ///< the positions were pulled back along the step (then velocities scaled)
  Held             ///< back to the start positions, velocities zero
};

/// The rigid rows' share of a step's energy, for energy_guard() (the engine fills it: tissue/
/// knows no bodies' states). In: the bodies that had rows in the step — their kinetic energy at
/// the step's start and end, their gravitational potential (−m·g·x) at start and end — and the
/// springs that name a row, as the step linearised them: along the step (a fraction θ of it)
/// their potential is θ·spring_linear + θ²·spring_quadratic (−f·d and ½dᵀKd at the step's end, d
/// the point's displacement less its anchor's, both sides moving). Out: what the guard did, for
/// the bodies to follow — their poses θ of the way along the step (1: kept), their velocities
/// × velocity_scale.
struct GuardRows {
  double kinetic0 = 0, kinetic1 = 0, gravity0 = 0, gravity1 = 0;
  double spring_linear = 0, spring_quadratic = 0;
  double theta = 1, velocity_scale = 1;
};

/// Result of a static solve.
struct StaticResult {
  int newton_iterations = 0;
  int linear_iterations = 0;      ///< CG iterations summed (0 with CHOLMOD)
  double relative_residual = 0;   ///< ‖f_ext + f(x)‖ / ‖f_ext‖ on free DOFs at exit
  bool converged = false;
  /// Newton stopped gaining below kStaticRoundoffLevel: kStaticStallIterations iterations in a
  /// row without halving the best residual there — the round-off floor of the problem (the
  /// tolerance asked is not attainable), not a load step too large.
  bool stalled = false;
  double best_residual = 0;       ///< the smallest relative residual reached
};

/// Newton iterations without halving the best residual that count as a stall.
inline constexpr int kStaticStallIterations = 4;
/// A stall below this relative residual is round-off: smaller load increments do not help.
inline constexpr double kStaticRoundoffLevel = 1e-6;

/// Stages of one time step over a FemModel. Not thread-safe; one per physics thread.
///
/// Invariant (the order of a step): assemble(s, h, inputs) fixes the step's inputs; solve(),
/// newton(), integrate() and the energy queries (kinetic_energy, elastic_energy) use the inputs
/// of the last assemble() until the next one. Before the first assemble() the inputs are none
/// (no contact, no damage, the model's masses).
class TimeStepper {
 public:
  TimeStepper(const FemModel& model, const StepperSettings& settings);
  ~TimeStepper();

  /// Load-time work that depends on the step size (the warped preconditioner's rest-pose
  /// factorisation; resolving and starting its refresh), so the first tick is not slower than
  /// the others. Without it the rest factor is made at the first step and never refreshed.
  void prepare(double h);
  /// Real-time mode (`stroma serve`): an asynchronous preconditioner refresh is swapped in as
  /// soon as it is ready and the physics thread never waits for it. Default (headless, replay):
  /// swapped in on a fixed schedule, so a run's results depend only on its inputs.
  void set_realtime(bool realtime);
  /// Refreshed preconditioner factors swapped in so far (0 without a refresh).
  int64_t preconditioner_refreshes() const { return warped_ ? warped_->refreshes() : 0; }
  /// The refresh worker's time for those factors (ns): summed, and the longest.
  int64_t preconditioner_refresh_ns_total() const { return warped_ ? warped_->refresh_factor_ns_total() : 0; }
  int64_t preconditioner_refresh_ns_max() const { return warped_ ? warped_->refresh_factor_ns_max() : 0; }
  /// Time the last assemble() waited for a late preconditioner refresh (headless, whose swap
  /// is deterministic; 0 in real time, which never waits).
  int64_t last_refresh_wait_ns() const { return warped_ ? warped_->last_wait_ns() : 0; }
  /// The steps between refreshes in use now (0: no refresh); `auto` re-evaluates it as it goes.
  int preconditioner_refresh_period(const TissueState& s) const {
    return warped_ && warped_->refreshing() ? s.solver.period : 0;
  }
  /// Refreshed factors remade from a restored state's history (WarpedPreconditioner::sync).
  int64_t preconditioner_factors_remade() const { return warped_ ? warped_->remade() : 0; }
  /// Rest-pose factorisations of the warped preconditioner so far (1 after prepare()).
  int64_t preconditioner_rest_factorizations() const { return warped_ ? warped_->rest_factorizations() : 0; }

  /// Room for `rows` rigid rows per step (StepInputs::rigid); load time.
  void reserve_rigid_rows(int32_t rows) { rows_.reserve(rows); }
  /// Rigid rows in the last assembled step (0: the tissue's alone).
  int32_t rigid_rows() const { return rows_.rows(); }

  /// Stage "assemble": element pass at the current state and the step's right-hand side, with
  /// this step's inputs (kept for the rest of the step). Returns the elastic energy at s.x.
  /// Moves the warped factor's refresh schedule on in s.solver (the state's SolverHistory), and
  /// first makes the factor in use the one that history names (after a restore).
  double assemble(TissueState& s, double h, const StepInputs& inputs);
  /// Stage "solve": Δv (implicit Euler) into s.dv. No-op for symplectic Euler. CG stops at
  /// `deadline` (null: none). The warm start extrapolates the last two increments
  /// only when the last solve converged; after a capped or truncated one it starts from that
  /// increment, or from zero if that is worse (no extrapolation from unconverged increments).
  /// Fills the error bounds of SolveStats.
  SolveStats solve(TissueState& s, Deadline* deadline = nullptr);
  /// Newton iterations on the implicit-Euler equations after solve() (StepperSettings::
  /// newton_iterations > 1; no-op otherwise): R(Δv) = h(f_ext + f(x) + f_c − αMv − βK(x)v)
  /// − M Δv with v = v₀ + Δv and x = x₀ + h v (contacts as linearised at x₀, the same springs).
  /// Refines s.dv in place; s.x and s.v are not touched (integrate() applies the result).
  /// Stops iterating at `deadline` (null: none), keeping the last accepted iterate.
  NewtonStats newton(TissueState& s, double h, Deadline* deadline = nullptr);
  /// Stage "integrate": update v and x; constrained nodes keep v = 0.
  void integrate(TissueState& s, double h);

  /// After integrate() of an implicit-Euler step whose linear solve did not converge (capped or
  /// truncated): makes sure the step did not gain mechanical energy. The energy E = ½vᵀMv +
  /// U(x) − f_ext·(x − X) + the contact springs' potential (linear as the step used them; with
  /// the tool fixed during the step it does no work) is compared before and after the step
  /// (the start state is recovered as v − Δv, x − h·v). If it grew, the velocities are scaled
  /// down so that it did not; if the positions alone hold more than the start energy, they are
  /// pulled back along the step (halving, up to 6 times; then the start positions, at rest).
  /// Costs one elastic-energy element pass, only when called. Returns what it did; `removed`
  /// gets the energy taken out (J). A step with rigid rows is checked only with their share
  /// (`rows`: the bodies' energies and the springs to them join the account, the springs to
  /// them leave the tissue's; the bodies are to follow what it did) — without it, None.
  EnergyLimit energy_guard(TissueState& s, double h, double* removed, GuardRows* rows = nullptr);
  /// Whether energy_guard() means anything for this model: its elastic forces are the gradient
  /// of the energy it measures. Not so with QR-rotation corotational elements (SOFA's "large"
  /// frame: the rotation is not the polar one, the force not −∂E/∂x), where an exact step can
  /// raise that energy as well: the guard would hold such a body still for good (SOFA's liver
  /// demo, imported: frozen from its 200th step). Their inexact steps are kept as solved, as
  /// SOFA keeps them.
  bool energy_guard_applies() const { return guard_applies_; }
  /// Load time: the median of three runs (ns) of the element pass energy_guard() makes, at
  /// positions x, with the rotation store it has in a step. Leaves nothing for the next step.
  int64_t time_energy_guard_pass(const double* x);

  /// Newton iterations to static equilibrium of load_factor·f_ext + f(x) + f_c(x) = 0 from s.x
  /// (velocities zeroed; tissue/static_solve.cpp). `inputs_at`, if given, returns the inputs
  /// (contacts found at that iterate, damage, masses) before each iteration's assembly — the
  /// engine recomputes contacts as the active set changes. Stops early (not converged) when
  /// the residual turns non-finite or grows beyond kStaticDivergence × its start.
  StaticResult solve_static(TissueState& s, double load_factor = 1.0,
                            const std::function<StepInputs(const TissueState&)>& inputs_at = {});

  /// ½ vᵀ M v.
  double kinetic_energy(const TissueState& s) const;
  /// Potential of the constant external forces: −f_extᵀ (x − X).
  double external_potential(const TissueState& s) const;
  /// Elastic energy at s.x with the last step's damage (a separate element pass; not for the hot loop).
  double elastic_energy(const TissueState& s) const;
  /// Free energy at s.x: the elastic energy, with visco-elastic bodies counted as their
  /// long-term part (1 − Σgᵢ)·Ψ₀ plus the energy stored in their branches
  /// (viscous_stored_energy) — what kinetic + free + external energy must never exceed its
  /// past value by. = elastic_energy without visco-elastic bodies. Not for the hot loop.
  double free_energy(const TissueState& s) const;
  /// Elastic force at s.x into `f` (3n), for tests and diagnostics.
  void elastic_force(const TissueState& s, double* f) const;
  /// The implicit-Euler step's incremental potential Φ(Δv) (the merit newton()'s line search
  /// descends) and, into R (3n), its negative gradient R(Δv), for tests and diagnostics.
  /// Contacts: the springs of the last assemble(). Uses the Newton scratch.
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
  /// Assembles that took the energy guard's rotations instead of recomputing them (end_rot_).
  int64_t rotations_reused() const { return rotations_reused_; }
  /// Implicit steps that made all their elements' stiffness blocks (every one when
  /// StepperSettings::stiffness_every is 1; else the first, sub-steps and after a cut) and
  /// steps that solved with kept ones.
  int64_t stiffness_refreshes() const { return stiffness_refreshes_; }
  int64_t stiffness_reuses() const { return stiffness_reuses_; }
  /// Off: every assemble computes its rotations (the reuse's A/B, in tests and benchmarks).
  /// Results agree to round-off either way.
  void set_rotation_reuse(bool on) { reuse_rotations_ = on; }

 private:
  void project_constraints(double* A, double diag_scale);
  /// Adds (1 + h·α_i)·m_i to each node's diagonal block of A (the step's mass term).
  void add_mass_diagonal(double* A, double h) const;
  /// Adds each contact spring's w_a·f to `force` and, with A, w_a w_b (k_scale·K + c_scale·C)
  /// to its blocks. With velocities v (explicit integration), f includes the damping −C·v_p.
  void scatter_springs(double* force, double* A, double k_scale, double c_scale, const double* v = nullptr) const;
  /// Spring c's force where the step starts (StepInputs::spring_force, else its own).
  const double* spring_force(int c) const { return in_.spring_force ? in_.spring_force + 3 * c : in_.springs[c].force; }
  /// R(dv) of the implicit-Euler equations into R (see newton()); with `matrix`, also A at the
  /// iterate (A_, its constraints projected; node rotations updated). Returns ‖R‖. `merit`:
  /// the incremental potential Φ(Δv) whose gradient is −R (up to a constant; damping and
  /// contact stiffness frozen as in R): ½ΔvᵀMΔv + U(x + h·v') − h·f_ext·v' + ½h·α·v'ᵀMv'
  /// + ½v'ᵀ(hβK)v' + the linearised contacts' potential, v' = v + Δv. The line search of
  /// newton() descends it, so an accepted iteration never adds energy the equations lack.
  double implicit_residual(const TissueState& s, double h, const double* dv, bool matrix, double* R,
                           double* merit = nullptr);
  /// implicit_residual, timed into st.element_pass_ns.
  double timed_residual(NewtonStats& st, const TissueState& s, double h, const double* dv, bool matrix, double* R,
                        double* merit);
  const FemModel& m_;
  StepperSettings cfg_;  ///< preconditioner_refresh resolved by prepare()
  bool realtime_ = false;
  StepInputs in_;  ///< the inputs of the last assemble()
  double h_ = 0;  ///< the step of the last assemble()
  /// The springs of in_ with matrix-free pairs (ContactSpring::matrix_free) lie in
  /// [cross_begin_, cross_end_) (empty: none): their cross terms are applied in each product.
  int cross_begin_ = 0, cross_end_ = 0;
  bool has_cross() const { return cross_end_ > cross_begin_; }
  /// y += Σ over the matrix-free pairs (a, b) of those springs w_a w_b (h²K + hC) x_b, on free DOFs.
  void apply_cross(const double* x, double* y) const;
  double u_start_ = 0;  ///< elastic energy at the last assemble()'s positions
  /// The visco-elastic state at the last assemble() (integrate() moves the state's on): the
  /// energy guard measures the step's own potential c·Ψ₀ + H:ε with it, before and after.
  std::vector<double> visco_q_start_, visco_s0_start_;
  /// The step's potential at positions x: the elastic energy with the step's visco-elastic
  /// history (= elastic_energy without visco-elastic bodies). Keeps the element rotations it
  /// computed, with a copy of x, in end_rot_ (see there).
  double step_potential(const double* x);
  /// The visco-elastic internal variables stepped again from the step's start to the state's
  /// (changed) positions, after the energy guard moved them.
  void redo_viscous_update(TissueState& s) const;
  /// −f_ext·(x − X) (gravity following the current masses) plus the contact springs' potential
  /// relative to their origin, at positions x.
  /// `skip_rows`: without the springs that name a rigid row (the engine's GuardRows has them).
  double potential_terms(const double* x, bool skip_rows = false) const;
  /// ½ rᵀM_eff⁻¹r and the position bound for SolveStats (r: the CG residual; M_eff = (1 + hα)M).
  void error_bounds(const double* r, double h, SolveStats& st) const;
  double mass(int32_t i) const { return in_.node_mass ? in_.node_mass[i] : m_.mass[i]; }
  std::vector<double> force_, kv_, rhs_, A_, rot_, tmp_;
  /// The element rotations of the energy guard's last pass (step_potential) and the positions
  /// they belong to. The guard evaluates the step's end, which is where the next assemble()
  /// starts: when its positions are bit for bit end_rot_x_, it takes these rotations instead of
  /// recomputing them (the polar decompositions are a third of the element pass). Rotations
  /// depend on the positions alone (not on damage or visco-elastic history), and m_ never
  /// changes under a stepper, so equal positions are the whole validity test. Empty when no
  /// range is corotational.
  std::vector<double> end_rot_, end_rot_x_;
  bool end_rot_valid_ = false;
  bool guard_applies_ = true;  ///< see energy_guard_applies()
  int64_t rotations_reused_ = 0;
  int64_t stiffness_refreshes_ = 0, stiffness_reuses_ = 0;
  /// The implicit step's element pass into A_ (overwritten here) with stiffness_every > 1: the
  /// kept element blocks copied in and this step's share made into the next ones (or, with
  /// none kept, all made and kept); then the rest (node domains, rods) as usual. Returns the
  /// elastic energy.
  double lagged_elastic_pass(TissueState& s, ElasticPass p, double h);
  double lag_h_ = 0;  ///< the step the kept element blocks are for (prepare(), else the first)
  bool reuse_rotations_ = true;  ///< see set_rotation_reuse()
  std::vector<double> newton_x_, newton_v_, newton_r_, newton_trial_r_, newton_delta_, newton_dv_;  // Newton scratch
  CgSolver cg_;
  std::unique_ptr<CholmodSolver> cholmod_;
  std::unique_ptr<WarpedPreconditioner> warped_;  ///< only when selected
  /// The factor's stored entries, with which `auto` re-evaluates the refresh period from the
  /// history's running mean of warped iterations (SolverHistory::pace_iterations).
  double refresh_entries_ = 0;
  const ExternalPreconditioner* external() const { return warped_ ? warped_->op() : nullptr; }
  /// Locking-free bodies under CG: the node domains' matrix-free part of A_ (nodal_smoothing.hpp).
  std::unique_ptr<NodalSystem> nodal_;
  /// The step's rigid rows (tissue/rigid_rows.hpp), eliminated into the tissue's system.
  RigidRows rows_;
  /// The matrix-free part of the system: the node domains' and the rigid rows' Schur term.
  ExtraOperator extra_op_;
  static void extra_apply(void* self, const double* x, double* y);
  const ExtraOperator* extra() const {
    if (rows_.rows() > 0 || has_cross()) return &extra_op_;
    return nodal_ ? nodal_->op() : nullptr;
  }
};

/// A static Newton attempt whose residual grows beyond this multiple of its starting value is
/// abandoned as diverging (the caller then takes a smaller load increment).
inline constexpr double kStaticDivergence = 1e6;

}  // namespace stroma
