#include "tissue/time_stepper.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

#include "tissue/clock.hpp"
#include "tissue/constraints.hpp"
#include "tissue/fem_forces.hpp"
#include "tissue/mat3.hpp"

namespace stroma {

TimeStepper::TimeStepper(const FemModel& model, const StepperSettings& settings)
    : m_(model), cfg_(settings), cg_(model.num_nodes) {
  if (!m_.rods.empty()) cg_.set_rods(m_.pattern, m_.rods);
  const size_t n3 = 3 * static_cast<size_t>(m_.num_nodes);
  force_.assign(n3, 0.0);
  kv_.assign(n3, 0.0);
  rhs_.assign(n3, 0.0);
  tmp_.assign(n3, 0.0);
  rot_.assign(9 * m_.elements.size(), 0.0);
  bool polar = false;
  for (const ElementRange& r : m_.ranges) {
    if (r.fixed) continue;
    if (r.kernel == ElementKernel::CorotationalQR) guard_applies_ = false;
    if (r.kernel == ElementKernel::CorotationalPolar) polar = true;
  }
  // Rotations to hand on exist only where a guard runs after implicit steps of polar elements.
  if (polar && guard_applies_ && cfg_.integrator == Integrator::ImplicitEuler) {
    end_rot_.assign(9 * m_.elements.size(), 0.0);
    end_rot_x_.assign(n3, 0.0);
  }
  if (cfg_.newton_iterations > 1 && cfg_.integrator == Integrator::ImplicitEuler)
    for (auto* v : {&newton_x_, &newton_v_, &newton_r_, &newton_trial_r_, &newton_delta_, &newton_dv_}) v->assign(n3, 0.0);
  A_.assign(9 * static_cast<size_t>(m_.pattern.nnzb()), 0.0);
  visco_q_start_.assign(static_cast<size_t>(m_.visco_q_size), 0.0);
  visco_s0_start_.assign(static_cast<size_t>(m_.visco_s0_size), 0.0);
  const bool needs_direct = cfg_.linear_solver == LinearSolverKind::Cholmod &&
                            cfg_.integrator != Integrator::SymplecticEuler;
  if (needs_direct) cholmod_ = std::make_unique<CholmodSolver>(m_.pattern);
  if (cfg_.preconditioner == Preconditioner::WarpedCholesky && cfg_.linear_solver == LinearSolverKind::CG)
    warped_ = std::make_unique<WarpedPreconditioner>(m_);
  if (m_.smoothing.matrix_free && !m_.smoothing.empty()) nodal_ = std::make_unique<NodalSystem>(m_);
  extra_op_.apply = &TimeStepper::extra_apply;
  extra_op_.context = this;
  extra_op_.diag = nodal_ ? nodal_->op()->diag : nullptr;
}

void TimeStepper::extra_apply(void* self, const double* x, double* y) {
  const TimeStepper& t = *static_cast<const TimeStepper*>(self);
  if (t.nodal_) t.nodal_->op()->apply(t.nodal_->op()->context, x, y);
  t.rows_.apply(x, y);
  t.apply_cross(x, y);
}

void TimeStepper::apply_cross(const double* x, double* y) const {
  const double ks = h_ * h_, cs = h_;
  for (int c = cross_begin_; c < cross_end_; ++c) {
    const ContactSpring& sp = in_.springs[c];
    if (!sp.matrix_free) continue;
    double Kp[9];
    for (int k = 0; k < 9; ++k) Kp[k] = ks * sp.K[k] + cs * sp.C[k];
    for (int a = 0; a < sp.n; ++a) {
      const int32_t na = sp.node[a];
      double acc[3] = {0, 0, 0};
      for (int b = 0; b < sp.n; ++b) {
        if (sp.slot[spring_slot(a, b)] != kSlotMatrixFree) continue;
        const int32_t nb = sp.node[b];
        double xb[3];
        for (int k = 0; k < 3; ++k) xb[k] = dof_constrained(m_, nb, k) ? 0.0 : x[3 * nb + k];
        const double ww = sp.w[a] * sp.w[b];
        for (int r = 0; r < 3; ++r) acc[r] += ww * (Kp[3 * r] * xb[0] + Kp[3 * r + 1] * xb[1] + Kp[3 * r + 2] * xb[2]);
      }
      for (int r = 0; r < 3; ++r)
        if (!dof_constrained(m_, na, r)) y[3 * na + r] += acc[r];
    }
  }
}

void TimeStepper::set_realtime(bool realtime) {
  realtime_ = realtime;
  if (warped_ && warped_->refreshing()) warped_->enable_refresh(!realtime);
}

void TimeStepper::prepare(double h) {
  lag_h_ = h;
  if (!warped_) return;
  if (cfg_.integrator == Integrator::Static) warped_->factor(-1.0, 0.0, 1.0);
  if (cfg_.integrator != Integrator::ImplicitEuler) return;
  warped_->factor(h, h, h * h);
  int& period = cfg_.preconditioner_refresh;
  // A refreshed factor is of the assembled system, which lacks the matrix-free node domains.
  if (nodal_) period = 0;
  // `auto` unresolved (a model not made by compile_scenario): the period of a worker that
  // keeps up with real time (scene/compile.cpp resolves it with the run's own pace).
  if (period < 0) {
    cfg_.refresh_follows_pace = true;
    period = auto_refresh_period(m_, warped_->factor_entries(), kTypicalWarpedIterations);
  }
  refresh_entries_ = warped_->factor_entries();
  if (period > 0) warped_->enable_refresh(!realtime_);
}

TimeStepper::~TimeStepper() = default;

void TimeStepper::project_constraints(double* A, double diag_scale) {
  stroma::project_constraints(m_, A, diag_scale, true);
}

void TimeStepper::add_mass_diagonal(double* A, double h) const {
  stroma::add_mass_diagonal(m_, A, h, in_.node_mass ? in_.node_mass : m_.mass.data());
}

void TimeStepper::scatter_springs(double* force, double* A, double k_scale, double c_scale, const double* v) const {
  for (int c = 0; c < in_.spring_count; ++c) {
    const ContactSpring& sp = in_.springs[c];
    const double* f0 = spring_force(c);
    double f[3] = {f0[0], f0[1], f0[2]};
    if (v) {  // explicit damping at the contact point's velocity
      double vc[3] = {0, 0, 0};
      for (int a = 0; a < sp.n; ++a)
        for (int k = 0; k < 3; ++k) vc[k] += sp.w[a] * v[3 * sp.node[a] + k];
      for (int k = 0; k < 3; ++k) f[k] -= sp.C[3 * k] * vc[0] + sp.C[3 * k + 1] * vc[1] + sp.C[3 * k + 2] * vc[2];
    }
    for (int a = 0; a < sp.n; ++a)
      for (int k = 0; k < 3; ++k) force[3 * sp.node[a] + k] += sp.w[a] * f[k];
    if (!A) continue;
    for (int a = 0; a < sp.n; ++a)
      for (int b = 0; b < sp.n; ++b) {
        const int32_t slot = sp.slot[spring_slot(a, b)];
        if (slot < 0) continue;  // lower triangle: the symmetric (b, a) adds it; or matrix-free
        const double ww = sp.w[a] * sp.w[b];
        double* B = A + 9 * slot;
        for (int k = 0; k < 9; ++k) B[k] += ww * (k_scale * sp.K[k] + c_scale * sp.C[k]);
      }
  }
}

double TimeStepper::assemble(TissueState& s, double h, const StepInputs& inputs) {
  const bool implicit = cfg_.integrator == Integrator::ImplicitEuler;
  // The last step's system, before it is overwritten: a refresh may take it (buffer swap).
  // `auto` re-evaluates the period from the warped iterations so far: stale factors make slow
  // ticks, which leave the worker time to refresh more often (tissue/solver_costs.hpp).
  if (warped_ && implicit && warped_->refreshing()) {
    SolverHistory& hist = s.solver;
    hist.period = cfg_.refresh_follows_pace
                      ? auto_refresh_period(m_, refresh_entries_, hist.pace_iterations, realtime_ ? h : 0.0)
                      : cfg_.preconditioner_refresh;
    warped_->begin_step(A_, h_, h, hist);
  }
  in_ = inputs;
  h_ = h;
  cross_begin_ = cross_end_ = 0;
  for (int c = 0; c < in_.spring_count; ++c)
    if (in_.springs[c].matrix_free) {
      if (cross_end_ == 0) cross_begin_ = c;
      cross_end_ = c + 1;
    }
  rows_.clear();  // until this step's are assembled
  std::fill(force_.begin(), force_.end(), 0.0);
  ElasticPass p;
  p.x = s.x.data();
  p.force = force_.data();
  p.rotations = rot_.data();
  // The energy guard ended the last step here: its rotations are these positions' (end_rot_).
  if (reuse_rotations_ && end_rot_valid_ && std::memcmp(s.x.data(), end_rot_x_.data(), s.x.size() * sizeof(double)) == 0) {
    p.rotations_in = end_rot_.data();
    ++rotations_reused_;
  }
  end_rot_valid_ = false;
  p.damage = in_.damage;
  // Visco-elastic bodies: the implicit step's stress c(h)·σ₀ + H; an explicit step's force is
  // the present stress (h = 0).
  p.visco_q = s.visco_q.data();
  p.visco_s0 = s.visco_s0.data();
  p.visco_h = implicit ? h : 0.0;
  std::copy(s.visco_q.begin(), s.visco_q.end(), visco_q_start_.begin());
  std::copy(s.visco_s0.begin(), s.visco_s0.end(), visco_s0_start_.begin());
  const bool any_beta = m_.any_stiffness_damping;
  if (implicit) {
    // A = (1 + hα) M + h(β + h) K. The damping and h·K·v terms of the right-hand side come
    // from one SpMV with A below, cheaper than a second element pass over the velocities.
    p.kvals = A_.data();
    p.k_beta = h;
    p.k_const = h * h;
    if (nodal_) {
      nodal_->begin();
      p.nodal_system = nodal_.get();
    }
  } else if (any_beta) {
    std::fill(kv_.begin(), kv_.end(), 0.0);
    p.v = s.v.data();
    p.kv = kv_.data();
    p.kv_beta = 1.0;  // symplectic: damping force −βK·v
    p.kv_const = 0.0;
  }
  double energy = 0;
  if (implicit && cfg_.stiffness_every > 1) {
    energy = lagged_elastic_pass(s, p, h);
  } else {
    if (implicit) std::fill(A_.begin(), A_.end(), 0.0);
    energy = elastic_pass(m_, p);
    if (implicit) ++stiffness_refreshes_;
  }
  u_start_ = energy;
  // Contact: forces join the elastic ones; stiffness and damping join the system matrix, so
  // the SpMV below also forms their −h(hK + C)v terms of the right-hand side.
  if (implicit) scatter_springs(force_.data(), A_.data(), h * h, h);
  else scatter_springs(force_.data(), nullptr, 0.0, 0.0, s.v.data());

  const int32_t n = m_.num_nodes;
  const double* fe = m_.f_ext.data();
  if (implicit) {
    add_mass_diagonal(A_.data(), h);
    // h(f_ext + f − αMv − (β + h)Kv) = h(f_ext + f) + Mv − Av   (constrained v are 0).
    bsr_spmv(m_.pattern, A_.data(), s.v.data(), tmp_.data());
    if (nodal_) nodal_->apply(s.v.data(), tmp_.data());
    apply_cross(s.v.data(), tmp_.data());  // springs across parts: their unassembled pairs
    for (int32_t i = 0; i < n; ++i) {
      const double mi = mass(i), dm = mi - m_.mass[i];  // gravity follows the current mass
      for (int k = 0; k < 3; ++k) {
        const int32_t d = 3 * i + k;
        rhs_[d] = dof_constrained(m_, i, k) ? 0.0
                                            : h * (fe[d] + dm * m_.gravity[k] + force_[d]) + mi * s.v[d] - tmp_[d];
      }
    }
    // Rigid rows (tissue/rigid_rows.hpp): their A_rr and b_r, the tissue's share of the
    // anchors' velocity, then eliminated: the solve is of the Schur complement.
    if (in_.rigid && in_.rigid->rows > 0 &&
        rows_.assemble(*in_.rigid, in_.springs, in_.spring_count, h, s.v.data(), rhs_.data(), m_, in_.spring_force))
      rows_.reduce_rhs(rhs_.data());
    project_constraints(A_.data(), 1.0);
    if (nodal_) nodal_->finish();
    if (warped_) {
      // Rest-pose factor with this step's coefficients, built once (prepare). Sub-steps keep
      // the factor made for the tick's h: a nearby matrix preconditions them well, where
      // refactoring the rest pose for h/2 and back would cost two factorisations (20–40 ms
      // at 4k nodes) on the physics thread.
      if (!warped_->factored()) warped_->factor(h, h, h * h);
      warped_->update_rotations(rot_.data());
      warped_->end_assembly(A_, h, s.solver);  // deterministic: this step's system to the worker, when due
    }
  } else {
    for (int32_t i = 0; i < n; ++i) {
      const double mi = mass(i), am = m_.alpha[i] * mi, dm = mi - m_.mass[i];
      const double inv = mi > 0 ? 1.0 / mi : 0.0;
      for (int k = 0; k < 3; ++k) {
        const int32_t d = 3 * i + k;
        const double f = fe[d] + dm * m_.gravity[k] + force_[d] - am * s.v[d] - (any_beta ? kv_[d] : 0.0);
        rhs_[d] = dof_constrained(m_, i, k) ? 0.0 : h * f * inv;
      }
    }
  }
  return energy;
}

double TimeStepper::lagged_elastic_pass(TissueState& s, ElasticPass p, double h) {
  SolverHistory& hist = s.solver;
  std::vector<double>&blocks = hist.element_blocks, &next = hist.element_blocks_next;
  if (lag_h_ == 0) lag_h_ = h;  // (prepare() not called: the first step's length)
  double energy = 0;
  p.parts = PassParts::Elements;
  if (h != lag_h_) {
    // A step of another length (a sub-step): its own blocks, the kept ones left as they are.
    std::fill(A_.begin(), A_.end(), 0.0);
    energy = elastic_pass(m_, p);
    ++stiffness_refreshes_;
  } else if (hist.element_blocks_phase < 0 || blocks.size() != A_.size() || next.size() != A_.size() ||
             hist.element_blocks_key != h) {
    // None yet (the first step, a cut's new model, a state from elsewhere): all made now.
    std::fill(A_.begin(), A_.end(), 0.0);
    energy = elastic_pass(m_, p);
    blocks.assign(A_.begin(), A_.end());  // into the room State::initial made (no allocation)
    next.assign(A_.size(), 0.0);
    hist.element_blocks_key = h;
    hist.element_blocks_phase = 0;
    ++stiffness_refreshes_;
  } else {
    // The kept blocks into the system; this phase's share of the batches made into the next.
    std::copy(blocks.begin(), blocks.end(), A_.begin());
    p.kvals = next.data();
    p.k_every = cfg_.stiffness_every;
    p.k_phase = hist.element_blocks_phase;
    energy = elastic_pass(m_, p);
    if (++hist.element_blocks_phase == cfg_.stiffness_every) {  // complete: the next steps use it
      blocks.swap(next);
      std::fill(next.begin(), next.end(), 0.0);
      hist.element_blocks_phase = 0;
    }
    p.k_every = 1;
    ++stiffness_reuses_;
  }
  p.kvals = A_.data();
  p.parts = PassParts::Rest;
  return energy + elastic_pass(m_, p);
}

void TimeStepper::error_bounds(const double* r, double h, SolveStats& st) const {
  double rmr = 0, total_mass = 0;
  for (int32_t i = 0; i < m_.num_nodes; ++i) {
    const double mi = mass(i);
    if (mi <= 0) continue;
    total_mass += mi;
    const double meff = (1.0 + h * m_.alpha[i]) * mi;
    for (int k = 0; k < 3; ++k)
      if (!dof_constrained(m_, i, k)) rmr += r[3 * i + k] * r[3 * i + k] / meff;
  }
  st.error_energy = 0.5 * rmr;
  st.error_position = total_mass > 0 ? h * std::sqrt(rmr / total_mass) : 0.0;
}

SolveStats TimeStepper::solve(TissueState& s, Deadline* deadline) {
  SolveStats st;
  double* dv = s.dv.data();
  const size_t n3 = rhs_.size();
  if (cfg_.integrator == Integrator::SymplecticEuler) {
    std::copy(rhs_.begin(), rhs_.end(), dv);  // assemble already formed h·M⁻¹·f
    return st;
  }
  // Initial guess. Δv changes smoothly from tick to tick, so a linear extrapolation of the last
  // two cuts CG iterations 2–3× against the previous value alone (liver: 22 → 9).
  double* prev = s.dv_prev.data();
  // After a capped or truncated solve its increment is no trend to extrapolate: start from it
  // (CG then drops it if it is worse than zero).
  SolverHistory& hist = s.solver;
  const WarmStart warm = hist.converged_in_a_row >= 2 || cfg_.warm_start != WarmStart::Extrapolate ? cfg_.warm_start
                                                                                           : WarmStart::Previous;
  switch (warm) {
    case WarmStart::Off:
      std::fill(dv, dv + n3, 0.0);
      break;
    case WarmStart::Previous:
      std::copy(dv, dv + n3, prev);  // the history extrapolation will use
      break;
    case WarmStart::Extrapolate:
      for (size_t i = 0; i < n3; ++i) {
        const double d = dv[i];
        dv[i] = 2.0 * d - prev[i];
        prev[i] = d;
      }
      break;
  }
  for (int32_t i : m_.constrained_nodes)
    for (int k = 0; k < 3; ++k)
      if (dof_constrained(m_, i, k)) dv[3 * i + k] = 0.0;
  if (cfg_.linear_solver == LinearSolverKind::Cholmod) {
    st.converged = cholmod_->factor(A_.data());
    if (st.converged && (rows_.rows() > 0 || has_cross())) {
      // The Schur complement is A minus a term of rank ≤ 6·rows (and springs across parts add
      // their unassembled pairs, of rank ≤ 3 each): CG preconditioned by A's factor converges in
      // at most that many + 1 iterations.
      const ExternalPreconditioner factor_solve{
          [](void* c, const double* r, double* z) { static_cast<CholmodSolver*>(c)->solve(r, z); }, cholmod_.get()};
      st = cg_.solve(m_.pattern, A_.data(), rhs_.data(), dv, Preconditioner::WarpedCholesky,
                     std::max(cfg_.max_iterations, 6 * rows_.rows() + 3 * (cross_end_ - cross_begin_) + 2),
                     cfg_.tolerance, &factor_solve, deadline,
                     true, extra());
      rows_.back_substitute(dv);
      return st;
    }
    if (st.converged) cholmod_->solve(rhs_.data(), dv);
    st.iterations = 0;
    return st;
  }
  if (warped_) {
    // The warped factor may not know this tangent: it lags it (rest pose, or a refresh a few
    // ticks old) and penalty contact stiffness joins it only at a refresh. Where it fits badly
    // each of its iterations costs a triangular solve, relative_cost() Jacobi iterations, so it
    // gets the share of the cap that costs as much as the cap of Jacobi iterations (at least
    // 3) — and beyond it, up to twice the share (at least 10 more), only while its progress says
    // it converges within that (CgSolver's `progress_from`/`progress_limit`). Otherwise
    // Jacobi-PCG, whose diagonal holds this tick's contacts and tangent, continues from its
    // iterate with the full cap. Why the share (docs/PERFORMANCE.md): a stiff sphere on a
    // 7,457-node block, where the rest factor fits so badly that CG stalled on it, and one warped
    // iteration cost ~40 Jacobi iterations before the blocked float solves (relative_cost()
    // estimates that ratio from the factor's size; ~4–5 on the 0.2 m Armadillo today). Why the
    // progress (issue 39): with SOFA's cap of 25 and tolerance 1e-9 the share is 3–5 warped
    // iterations where 4–8 reach 1e-9, and Jacobi never does in 25 — a hard share cut half the
    // SOFA liver's solves short. Why not the whole cap: a factor that fits an inverted mesh
    // badly but converges slowly ran 200 iterations to a step that gained energy where Jacobi's
    // finish did not (stability suite, `dt 1 ms, E 1kPa, nu 0.499, inverted, fibres`).
    const int share = std::max(3, static_cast<int>(cfg_.max_iterations / warped_->relative_cost()));
    const int limit = std::min(cfg_.max_iterations, std::max(2 * share, share + 10));
    // Under a budget its coarse iterations look ahead: one that would end past the deadline is
    // not started (a served tick would otherwise overrun by up to a triangular solve pair).
    st = cg_.solve(m_.pattern, A_.data(), rhs_.data(), dv, cfg_.preconditioner, limit, cfg_.tolerance, external(),
                   deadline, hist.converged_in_a_row == 0, extra(), share < limit ? share : 0, limit, true);
    if (!st.converged && !st.budget_stopped && limit < cfg_.max_iterations) st.stalled = true;  // at the limit
    // A solve far above the usual iterations (contact stiffness entered, damage, a large
    // strain: the factor no longer fits) asks for a refresh now rather than at the next period.
    // The usual: a running mean (1/16) of the converged solves' iterations.
    if (st.stalled ||
        (st.converged && hist.warped_solves >= 4 && st.iterations > 2.0 * hist.typical_iterations + 2.0))
      hist.demand = true;
    if (st.converged) {
      hist.typical_iterations += (st.iterations - hist.typical_iterations) /
                                 static_cast<double>(hist.warped_solves < 16 ? hist.warped_solves + 1 : 16);
      ++hist.warped_solves;
    }
    hist.pace_iterations += (st.iterations - hist.pace_iterations) / 16.0;
    if (st.stalled) {
      const int warped_iterations = st.iterations;
      st = cg_.solve(m_.pattern, A_.data(), rhs_.data(), dv, Preconditioner::Jacobi, cfg_.max_iterations,
                     cfg_.tolerance, nullptr, deadline, false, extra());
      st.iterations += warped_iterations;
      st.preconditioner_fallback = true;
    }
  } else {
    st = cg_.solve(m_.pattern, A_.data(), rhs_.data(), dv, cfg_.preconditioner, cfg_.max_iterations, cfg_.tolerance,
                   nullptr, deadline, hist.converged_in_a_row == 0, extra());
  }
  hist.converged_in_a_row = st.converged ? hist.converged_in_a_row + 1 : 0;
  error_bounds(cg_.residual(), h_, st);
  rows_.back_substitute(dv);
  return st;
}

double TimeStepper::implicit_residual(const TissueState& s, double h, const double* dv, bool matrix, double* R,
                                      double* merit) {
  const int32_t n = m_.num_nodes;
  double* xk = newton_x_.data();
  double* vk = newton_v_.data();
  for (int32_t i = 0; i < n; ++i)
    for (int k = 0; k < 3; ++k) {
      const int32_t d = 3 * i + k;
      const bool fixed = (m_.constrained[i] >> k) & 1;
      vk[d] = fixed ? 0.0 : s.v[d] + dv[d];
      xk[d] = fixed ? s.x[d] : s.x[d] + h * vk[d];
    }
  std::fill(force_.begin(), force_.end(), 0.0);
  ElasticPass p;
  p.x = xk;
  p.force = force_.data();
  p.damage = in_.damage;
  p.visco_q = s.visco_q.data();  // the step's history, its stress at the iterate
  p.visco_s0 = s.visco_s0.data();
  p.visco_h = h;
  if (matrix) {
    std::fill(A_.begin(), A_.end(), 0.0);
    p.kvals = A_.data();
    p.k_beta = h;
    p.k_const = h * h;
    p.rotations = rot_.data();
    if (nodal_) {
      nodal_->begin();
      p.nodal_system = nodal_.get();
    }
  }
  const bool any_beta = m_.any_stiffness_damping;
  if (any_beta) {  // hβK(x)v: the stiffness damping at the iterate
    std::fill(kv_.begin(), kv_.end(), 0.0);
    p.v = vk;
    p.kv = kv_.data();
    p.kv_beta = h;
    p.kv_const = 0.0;
  }
  const double elastic_energy = elastic_pass(m_, p);
  double contact_merit = 0;  // the contact terms of the merit (see below)
  // Contacts, linearised at the step's start as in assemble(): force f_c − (hK_c + C_c)v at the
  // iterate, so h·that = h f_c − (h²K_c + hC_c)v; tmp_ collects the (h²K_c + hC_c)v part.
  std::fill(tmp_.begin(), tmp_.end(), 0.0);
  for (int c = 0; c < in_.spring_count; ++c) {
    const ContactSpring& sp = in_.springs[c];
    double vc[3] = {0, 0, 0};
    for (int a = 0; a < sp.n; ++a)
      for (int k = 0; k < 3; ++k) vc[k] += sp.w[a] * vk[3 * sp.node[a] + k];
    double lin[3];
    for (int k = 0; k < 3; ++k)
      lin[k] = (h * h * sp.K[3 * k] + h * sp.C[3 * k]) * vc[0] + (h * h * sp.K[3 * k + 1] + h * sp.C[3 * k + 1]) * vc[1] +
               (h * h * sp.K[3 * k + 2] + h * sp.C[3 * k + 2]) * vc[2];
    for (int a = 0; a < sp.n; ++a)
      for (int k = 0; k < 3; ++k) tmp_[3 * sp.node[a] + k] += sp.w[a] * lin[k];
    const double* f0 = spring_force(c);
    for (int k = 0; k < 3; ++k) contact_merit += -h * f0[k] * vc[k] + 0.5 * vc[k] * lin[k];
  }
  scatter_springs(force_.data(), matrix ? A_.data() : nullptr, h * h, h);
  const double* fe = m_.f_ext.data();
  double r2 = 0, phi = elastic_energy + contact_merit;
  if (matrix) add_mass_diagonal(A_.data(), h);
  for (int32_t i = 0; i < n; ++i) {
    const double mi = mass(i), dm = mi - m_.mass[i];
    for (int k = 0; k < 3; ++k) {
      const int32_t d = 3 * i + k;
      if (dof_constrained(m_, i, k)) {
        R[d] = 0.0;
        continue;
      }
      const double kv = any_beta ? kv_[d] : 0.0;
      R[d] = h * (fe[d] + dm * m_.gravity[k] + force_[d]) - (1.0 + h * m_.alpha[i]) * mi * vk[d] + mi * s.v[d] - kv -
             tmp_[d];
      r2 += R[d] * R[d];
      const double dvd = vk[d] - s.v[d];
      phi += 0.5 * mi * dvd * dvd - h * (fe[d] + dm * m_.gravity[k]) * vk[d] + 0.5 * h * m_.alpha[i] * mi * vk[d] * vk[d] +
             0.5 * kv * vk[d];
    }
  }
  if (matrix) {
    project_constraints(A_.data(), 1.0);
    if (nodal_) nodal_->finish();
    if (warped_) warped_->update_rotations(rot_.data());
  }
  if (merit) *merit = phi;
  return std::sqrt(r2);
}

double TimeStepper::timed_residual(NewtonStats& st, const TissueState& s, double h, const double* dv, bool matrix,
                                   double* R, double* merit) {
  const int64_t t0 = steady_now_ns();
  const double r = implicit_residual(s, h, dv, matrix, R, merit);
  st.element_pass_ns += steady_now_ns() - t0;
  return r;
}

NewtonStats TimeStepper::newton(TissueState& s, double h, Deadline* deadline) {
  NewtonStats st;
  if (cfg_.newton_iterations <= 1 || cfg_.integrator != Integrator::ImplicitEuler) return st;
  // With rigid rows the linearised step is the step (docs/RIGID.md): the iterations' residual
  // is the tissue's alone.
  if (rows_.rows() > 0) return st;
  const size_t n3 = rhs_.size();
  double* dv = s.dv.data();
  // Scale: the largest of the linearised system's right-hand side, the step's momentum change
  // M·Δv and the impulses h·f of the elastic and external forces at the start (at rest under a
  // balanced load the first two are ~0; the residual is then measured against the load).
  // force_ still holds assemble()'s elastic + contact forces.
  double b2 = 0, m2 = 0, f2 = 0, e2 = 0;
  for (size_t d = 0; d < n3; ++d) {
    b2 += rhs_[d] * rhs_[d];
    const double md = mass(static_cast<int32_t>(d / 3)) * dv[d];
    m2 += md * md;
    f2 += force_[d] * force_[d];
    e2 += m_.f_ext[d] * m_.f_ext[d];
  }
  const double scale = std::max({std::sqrt(b2), std::sqrt(m2), h * std::sqrt(f2), h * std::sqrt(e2), 1e-300});
  // The first check is a forces-only pass: most ticks end here (the linearised step is good).
  double phi = 0;
  double rn = timed_residual(st, s, h, dv, false, newton_r_.data(), &phi);
  if (rn > cfg_.newton_tolerance * scale && std::isfinite(rn)) {
    // The linearised step may have gone uphill in the incremental potential (large steps on
    // soft, inverted or near-incompressible elements): then shorten it towards Δv = 0 first.
    double phi0 = 0;
    std::fill(newton_dv_.begin(), newton_dv_.end(), 0.0);
    timed_residual(st, s, h, newton_dv_.data(), false, newton_trial_r_.data(), &phi0);
    for (int ls = 0; ls < 5 && !(phi <= phi0) && std::isfinite(phi0); ++ls) {
      ++st.line_search_halvings;
      for (size_t d = 0; d < n3; ++d) dv[d] *= 0.5;
      rn = timed_residual(st, s, h, dv, false, newton_r_.data(), &phi);
    }
  }
  bool a_current = false;  // A_ assembled at the current iterate?
  while (st.iterations < cfg_.newton_iterations && rn > cfg_.newton_tolerance * scale && std::isfinite(rn)) {
    if (deadline && deadline->past()) {  // keep the last accepted iterate: each one lowered Φ
      st.budget_stopped = true;
      break;
    }
    if (!a_current) rn = timed_residual(st, s, h, dv, true, newton_r_.data(), &phi);
    a_current = true;  // (line-search trials assemble at the point they try)
    std::fill(newton_delta_.begin(), newton_delta_.end(), 0.0);
    if (cfg_.linear_solver == LinearSolverKind::Cholmod) {
      if (!cholmod_->factor(A_.data())) break;
      cholmod_->solve(newton_r_.data(), newton_delta_.data());
    } else {
      const SolveStats cs = cg_.solve(m_.pattern, A_.data(), newton_r_.data(), newton_delta_.data(), cfg_.preconditioner,
                                      cfg_.max_iterations, cfg_.tolerance, external(), deadline, false, extra());
      st.linear_iterations += cs.iterations;
    }
    ++st.iterations;
    // Backtracking on the incremental potential Φ (Armijo): keep the longest of Δ, Δ/2, … Δ/16
    // that lowers Φ enough — Δ solves with a PSD-projected tangent, a descent direction of Φ,
    // so descending Φ rather than ‖R‖ never trades a smaller residual for an energy gain.
    // Where Φ's decrease is lost in round-off (near the solution), a smaller ‖R‖ decides.
    double slope = 0;  // −∇Φ·Δ = R·Δ
    for (size_t d = 0; d < n3; ++d) slope += newton_r_[d] * newton_delta_[d];
    const bool descent = slope > 0;
    const double phi_noise = 1e-12 * (std::abs(phi) + scale * scale);
    bool accepted = false;
    double t = 1.0;
    for (int ls = 0; ls < 5 && !accepted; ++ls, t *= 0.5) {
      for (size_t d = 0; d < n3; ++d) newton_dv_[d] = dv[d] + t * newton_delta_[d];
      double phi_try = 0;
      const double r_try = timed_residual(st, s, h, newton_dv_.data(), true, newton_trial_r_.data(), &phi_try);
      const bool finite = std::isfinite(r_try) && std::isfinite(phi_try);
      const bool armijo = descent && phi_try <= phi - 1e-4 * t * slope;
      const bool round_off = std::abs(phi_try - phi) <= phi_noise && r_try < rn;
      if (finite && (armijo || round_off || (!descent && r_try < rn))) {
        accepted = true;
        rn = r_try;
        phi = phi_try;
        std::copy(newton_dv_.begin(), newton_dv_.end(), dv);
        newton_r_.swap(newton_trial_r_);
      } else {
        ++st.line_search_halvings;
      }
    }
    if (!accepted) break;
  }
  st.relative_residual = rn / scale;
  return st;
}

double TimeStepper::potential_terms(const double* x, bool skip_rows) const {
  double e = 0;
  for (int32_t i = 0; i < m_.num_nodes; ++i) {
    const double dm = mass(i) - m_.mass[i];
    for (int k = 0; k < 3; ++k) {
      const int32_t d = 3 * i + k;
      e -= (m_.f_ext[d] + dm * m_.gravity[k]) * (x[d] - m_.rest[d]);
    }
  }
  if (!in_.contact_origin) return e;
  for (int c = 0; c < in_.spring_count; ++c) {
    const ContactSpring& sp = in_.springs[c];
    if (skip_rows && spring_has_rows(sp)) continue;
    double p0[3], p1[3];
    spring_point(sp, in_.contact_origin, p0);
    spring_point(sp, x, p1);
    const double dp[3] = {p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2]};
    for (int k = 0; k < 3; ++k)
      e += -sp.force[k] * dp[k] + 0.5 * dp[k] * (sp.K[3 * k] * dp[0] + sp.K[3 * k + 1] * dp[1] + sp.K[3 * k + 2] * dp[2]);
  }
  return e;
}

EnergyLimit TimeStepper::energy_guard(TissueState& s, double h, double* removed, GuardRows* rows) {
  *removed = 0;
  // With rigid rows energy moves between the tissue and the bodies within the step: the
  // account closes only with the bodies' share (the engine's), else the guard stays out.
  if (rows_.rows() > 0 && !rows) return EnergyLimit::None;
  const bool with_rows = rows != nullptr;
  GuardRows none;
  GuardRows& g = with_rows ? *rows : none;
  g.theta = g.velocity_scale = 1;
  const size_t n3 = s.x.size();
  // The start of the step: v₀ = v − Δv, x₀ = x − h·v (constrained DOFs did not move).
  std::vector<double>& x0 = tmp_;
  double ke0 = g.kinetic0, ke1 = g.kinetic1;
  for (int32_t i = 0; i < m_.num_nodes; ++i) {
    const double mi = mass(i);
    for (int k = 0; k < 3; ++k) {
      const int32_t d = 3 * i + k;
      const bool fixed = dof_constrained(m_, i, k);
      const double v0 = fixed ? 0.0 : s.v[d] - s.dv[d];
      x0[d] = fixed ? s.x[d] : s.x[d] - h * s.v[d];
      ke0 += 0.5 * mi * v0 * v0;
      ke1 += 0.5 * mi * s.v[d] * s.v[d];
    }
  }
  // The potential θ of the way along the step (θ = 1: its end), less the elastic part.
  auto rows_potential = [&](double theta) {
    return g.gravity0 + theta * (g.gravity1 - g.gravity0) + theta * g.spring_linear + theta * theta * g.spring_quadratic;
  };
  const double e0 = ke0 + u_start_ + potential_terms(x0.data(), with_rows) + g.gravity0;
  const double v1 = step_potential(s.x.data()) + potential_terms(s.x.data(), with_rows) + rows_potential(1.0);
  const double tol = 1e-12 * (std::abs(e0) + ke1 + std::abs(v1)) + 1e-300;
  if (ke1 + v1 <= e0 + tol) return EnergyLimit::None;
  auto velocity_factor = [&](double available, double ke) {
    const double f = ke > 0 ? std::sqrt(std::max(0.0, available) / ke) : 0.0;
    return std::min(f, 1.0);
  };
  if (v1 <= e0) {  // the kinetic energy is what grew: damp this tick's velocities
    const double f = velocity_factor(e0 - v1, ke1);
    if (f < 1.0)
      for (double& v : s.v) v *= f;
    g.velocity_scale = f;
    *removed = ke1 + v1 - e0;
    return EnergyLimit::VelocityScaled;
  }
  // The positions alone hold more than the start energy: pull them back along the step.
  std::vector<double>& x1 = kv_;  // free scratch after integrate()
  std::copy(s.x.begin(), s.x.end(), x1.begin());
  for (double theta = 0.5; theta >= 1.0 / 64; theta *= 0.5) {
    for (size_t d = 0; d < n3; ++d) s.x[d] = x0[d] + theta * (x1[d] - x0[d]);
    const double vt = step_potential(s.x.data()) + potential_terms(s.x.data(), with_rows) + rows_potential(theta);
    if (vt <= e0) {
      for (double& v : s.v) v *= theta;
      const double f = velocity_factor(e0 - vt, theta * theta * ke1);
      if (f < 1.0)
        for (double& v : s.v) v *= f;
      g.theta = theta;
      g.velocity_scale = theta * f;
      *removed = ke1 + v1 - e0;
      redo_viscous_update(s);
      return EnergyLimit::PositionsPulled;
    }
  }
  std::copy(x0.begin(), x0.end(), s.x.begin());
  std::fill(s.v.begin(), s.v.end(), 0.0);
  g.theta = 0;
  g.velocity_scale = 0;
  *removed = ke1 + v1 - e0;
  redo_viscous_update(s);
  return EnergyLimit::Held;
}

void TimeStepper::redo_viscous_update(TissueState& s) const {
  if (m_.visco_q_size == 0) return;
  std::copy(visco_q_start_.begin(), visco_q_start_.end(), s.visco_q.begin());
  std::copy(visco_s0_start_.begin(), visco_s0_start_.end(), s.visco_s0.begin());
  viscous_update(m_, s.x.data(), in_.damage, h_, s.visco_q.data(), s.visco_s0.data());
}

void TimeStepper::integrate(TissueState& s, double h) {
  const int32_t n = m_.num_nodes;
  for (int32_t i = 0; i < n; ++i) {
    const uint8_t mask = m_.constrained[i];
    for (int k = 0; k < 3; ++k) {
      const int32_t d = 3 * i + k;
      if ((mask >> k) & 1) {
        s.v[d] = 0.0;  // fixed DOF: stays at its rest value
        continue;
      }
      s.v[d] += s.dv[d];
      s.x[d] += h * s.v[d];
    }
  }
  // The visco-elastic internal variables follow the step to its end positions.
  if (m_.visco_q_size > 0) viscous_update(m_, s.x.data(), in_.damage, h, s.visco_q.data(), s.visco_s0.data());
}

double TimeStepper::kinetic_energy(const TissueState& s) const {
  double e = 0;
  for (int32_t i = 0; i < m_.num_nodes; ++i) {
    const double* v = &s.v[3 * i];
    e += 0.5 * mass(i) * (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
  }
  return e;
}

double TimeStepper::external_potential(const TissueState& s) const {
  double e = 0;
  for (size_t d = 0; d < s.x.size(); ++d) e -= m_.f_ext[d] * (s.x[d] - m_.rest[d]);
  return e;
}

double TimeStepper::step_potential(const double* x) {
  ElasticPass p;
  p.x = x;
  if (!end_rot_.empty()) {
    p.rotations = end_rot_.data();
    std::copy(x, x + end_rot_x_.size(), end_rot_x_.begin());
    end_rot_valid_ = true;
  }
  p.damage = in_.damage;
  p.visco_q = visco_q_start_.data();  // the step's history, as in assemble()
  p.visco_s0 = visco_s0_start_.data();
  p.visco_h = h_;
  return elastic_pass(m_, p);
}

int64_t TimeStepper::time_energy_guard_pass(const double* x) {
  int64_t t[3];
  for (int64_t& ti : t) {
    const int64_t a = steady_now_ns();
    step_potential(x);
    ti = steady_now_ns() - a;
  }
  end_rot_valid_ = false;  // the first assemble computes its own rotations
  std::sort(t, t + 3);
  return t[1];
}

double TimeStepper::elastic_energy(const TissueState& s) const {
  ElasticPass p;
  p.x = s.x.data();
  p.damage = in_.damage;  // damaged elements store (1 − d) of the energy
  p.visco_q = s.visco_q.data();  // present stress (h = 0); the branches' own energy is
  p.visco_s0 = s.visco_s0.data();  // viscous_stored_energy's
  return elastic_pass(m_, p);
}

double TimeStepper::free_energy(const TissueState& s) const {
  if (m_.visco_q_size == 0) return elastic_energy(s);
  ElasticPass p;
  p.x = s.x.data();
  p.damage = in_.damage;
  // A step of infinite length (viscoelastic.hpp): c = 1 − Σgᵢ, every decay and gᵢγᵢ 0, so no
  // history: the long-term energy alone.
  p.visco_q = s.visco_q.data();
  p.visco_s0 = s.visco_s0.data();
  p.visco_h = std::numeric_limits<double>::infinity();
  return elastic_pass(m_, p) + viscous_stored_energy(m_, s.visco_q.data());
}

void TimeStepper::elastic_force(const TissueState& s, double* f) const {
  std::fill(f, f + s.x.size(), 0.0);
  ElasticPass p;
  p.x = s.x.data();
  p.force = f;
  p.visco_q = s.visco_q.data();  // the present stress of visco-elastic bodies (h = 0)
  p.visco_s0 = s.visco_s0.data();
  elastic_pass(m_, p);
}

void TimeStepper::stiffness(const TissueState& s, std::vector<double>& kvals) const {
  kvals.assign(9 * static_cast<size_t>(m_.pattern.nnzb()), 0.0);
  ElasticPass p;
  p.x = s.x.data();
  p.kvals = kvals.data();
  p.k_const = 1.0;
  elastic_pass(m_, p);
}

}  // namespace stroma
