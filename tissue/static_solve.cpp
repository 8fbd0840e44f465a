/// \file static_solve.cpp
/// TimeStepper::solve_static: Newton iterations to static equilibrium at one load factor. The
/// continuation over load factors and tool poses (load stepping) is the engine's
/// (engine/static_run.cpp): this file solves one increment.

#include <algorithm>
#include <cmath>
#include <limits>

#include "tissue/constraints.hpp"
#include "tissue/fem_forces.hpp"
#include "tissue/time_stepper.hpp"

namespace stroma {

StaticResult TimeStepper::solve_static(TissueState& s, double load_factor,
                                       const std::function<StepInputs(const TissueState&)>& inputs_at) {
  StaticResult res;
  const int32_t n = m_.num_nodes;
  std::fill(s.v.begin(), s.v.end(), 0.0);
  // The residual is measured against the full external load (1 when there is none).
  double fref = 0;
  for (int32_t i = 0; i < n; ++i)
    for (int k = 0; k < 3; ++k)
      if (!dof_constrained(m_, i, k)) fref += m_.f_ext[3 * i + k] * m_.f_ext[3 * i + k];
  fref = std::sqrt(fref);
  if (fref == 0) fref = 1.0;
  CholmodSolver* direct = cholmod_.get();
  std::unique_ptr<CholmodSolver> own;
  if (cfg_.linear_solver == LinearSolverKind::Cholmod && !direct) {
    own = std::make_unique<CholmodSolver>(m_.pattern);
    direct = own.get();
  }
  double first_residual = -1;
  res.best_residual = std::numeric_limits<double>::infinity();
  int since_gain = 0;  // iterations since the best residual last halved
  double gain_mark = std::numeric_limits<double>::infinity();
  for (int it = 0; it <= cfg_.static_max_newton; ++it) {
    std::fill(force_.begin(), force_.end(), 0.0);
    std::fill(A_.begin(), A_.end(), 0.0);
    if (inputs_at) in_ = inputs_at(s);  // contacts at this iterate
    ElasticPass p;
    p.x = s.x.data();
    p.force = force_.data();
    p.kvals = A_.data();
    p.k_const = 1.0;
    p.rotations = rot_.data();
    p.damage = in_.damage;
    if (nodal_) {
      nodal_->begin();
      p.nodal_system = nodal_.get();
    }
    elastic_pass(m_, p);
    scatter_springs(force_.data(), A_.data(), 1.0, 0.0);  // contact: force and stiffness at this iterate
    double rn = 0, dsum = 0;
    int dcount = 0;
    for (int32_t i = 0; i < n; ++i) {
      for (int k = 0; k < 3; ++k) {
        const int32_t d = 3 * i + k;
        rhs_[d] = dof_constrained(m_, i, k) ? 0.0 : load_factor * m_.f_ext[d] + force_[d];
        rn += rhs_[d] * rhs_[d];
      }
      const double* D = A_.data() + 9 * m_.pattern.diag[i];
      for (int k = 0; k < 3; ++k)
        if (!dof_constrained(m_, i, k)) {
          dsum += D[4 * k];
          ++dcount;
        }
    }
    res.relative_residual = std::sqrt(rn) / fref;
    if (!std::isfinite(res.relative_residual)) return res;
    if (res.relative_residual <= cfg_.static_tolerance) {
      res.converged = true;
      return res;
    }
    if (first_residual < 0) first_residual = res.relative_residual;
    if (res.relative_residual > kStaticDivergence * first_residual) return res;  // diverging
    res.best_residual = std::min(res.best_residual, res.relative_residual);
    if (res.relative_residual <= 0.5 * gain_mark) {
      gain_mark = res.relative_residual;
      since_gain = 0;
    } else if (res.best_residual < kStaticRoundoffLevel && ++since_gain >= kStaticStallIterations) {
      // No progress this close to equilibrium: the round-off floor (above it, Newton runs its
      // iterations and the continuation halves the increment, as before).
      res.stalled = true;
      return res;
    }
    if (it == cfg_.static_max_newton) break;
    // Constrained rows get the mean free diagonal: keeps CG's conditioning; rhs there is 0.
    const double scale = dcount ? dsum / dcount : 1.0;
    stroma::project_constraints(m_, A_.data(), scale, false);
    if (nodal_) nodal_->finish();
    std::fill(tmp_.begin(), tmp_.end(), 0.0);
    if (direct) {
      if (!direct->factor(A_.data())) return res;
      direct->solve(rhs_.data(), tmp_.data());
    } else {
      if (warped_) {
        warped_->factor(-1.0, 0.0, 1.0);
        warped_->update_rotations(rot_.data());
      }
      // Inner solves need not be tighter than the Newton target relative to this residual.
      const double tol = std::clamp(0.1 * cfg_.static_tolerance / std::max(res.relative_residual, 1e-300), 1e-14, 0.1);
      const SolveStats cs = cg_.solve(m_.pattern, A_.data(), rhs_.data(), tmp_.data(), cfg_.preconditioner,
                                      20 * cfg_.max_iterations, tol, external(), nullptr, false, extra());
      res.linear_iterations += cs.iterations;
    }
    for (size_t d = 0; d < s.x.size(); ++d) s.x[d] += tmp_[d];
    ++res.newton_iterations;
  }
  return res;
}

}  // namespace stroma
