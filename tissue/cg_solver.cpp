#include "tissue/cg_solver.hpp"

#include <cmath>

#include "tissue/mat3.hpp"

namespace stroma {

namespace {
inline double dotn(const double* __restrict a, const double* __restrict b, int32_t n) {
  double s0 = 0, s1 = 0, s2 = 0, s3 = 0;
  int32_t i = 0;
  for (; i + 4 <= n; i += 4) {
    s0 += a[i] * b[i];
    s1 += a[i + 1] * b[i + 1];
    s2 += a[i + 2] * b[i + 2];
    s3 += a[i + 3] * b[i + 3];
  }
  for (; i < n; ++i) s0 += a[i] * b[i];
  return (s0 + s1) + (s2 + s3);
}
}  // namespace

void CgSolver::resize(int32_t n) {
  n_ = n;
  r_.assign(3 * n, 0.0);
  z_.assign(3 * n, 0.0);
  p_.assign(3 * n, 0.0);
  q_.assign(3 * n, 0.0);
  inv_diag_.assign(9 * n, 0.0);
}

void CgSolver::build_preconditioner(const BsrPattern& p, const double* A, Preconditioner prec, const double* extra_diag) {
  if (prec == Preconditioner::Jacobi) {
    for (int32_t i = 0; i < n_; ++i) {
      const double* D = A + 9 * p.diag[i];
      const double* X = extra_diag ? extra_diag + 9 * i : nullptr;
      inv_diag_[3 * i] = 1.0 / (D[0] + (X ? X[0] : 0.0));
      inv_diag_[3 * i + 1] = 1.0 / (D[4] + (X ? X[4] : 0.0));
      inv_diag_[3 * i + 2] = 1.0 / (D[8] + (X ? X[8] : 0.0));
    }
  } else if (prec == Preconditioner::BlockJacobi) {
    for (int32_t i = 0; i < n_; ++i) {
      double B[9];
      for (int k = 0; k < 9; ++k) B[k] = A[9 * p.diag[i] + k] + (extra_diag ? extra_diag[9 * i + k] : 0.0);
      m3::inverse(B, inv_diag_.data() + 9 * i);
    }
  }
}

void CgSolver::apply_preconditioner(Preconditioner prec, const double* r, double* z) const {
  const int32_t m = 3 * n_;
  if (prec == Preconditioner::Jacobi) {
    for (int32_t i = 0; i < m; ++i) z[i] = inv_diag_[i] * r[i];
  } else if (prec == Preconditioner::BlockJacobi) {
    for (int32_t i = 0; i < n_; ++i) m3::mulv(inv_diag_.data() + 9 * i, r + 3 * i, z + 3 * i);
  } else if (prec == Preconditioner::WarpedCholesky && external_ && external_->apply) {
    external_->apply(external_->context, r, z);
  } else {
    for (int32_t i = 0; i < m; ++i) z[i] = r[i];
  }
}

SolveStats CgSolver::solve(const BsrPattern& pat, const double* A, const double* b, double* x,
                           Preconditioner prec, int max_iterations, double tolerance,
                           const ExternalPreconditioner* external, Deadline* deadline, bool safe_start,
                           const ExtraOperator* extra, int progress_from, int progress_limit, bool look_ahead) {
  external_ = external;
  const int32_t m = 3 * n_;
  SolveStats st;
  const double bnorm = std::sqrt(dotn(b, b, m));
  if (!std::isfinite(bnorm)) {  // NaN/Inf in the system: report it, leave x alone
    st.converged = false;
    st.relative_residual = bnorm;
    return st;
  }
  if (bnorm == 0.0) {
    for (int32_t i = 0; i < m; ++i) x[i] = 0.0;
    return st;
  }
  build_preconditioner(pat, A, prec, extra ? extra->diag : nullptr);
  double* r = r_.data();
  double* z = z_.data();
  double* p = p_.data();
  double* q = q_.data();
  bsr_spmv(pat, A, x, q);
  if (extra) extra->apply(extra->context, x, q);
  for (int32_t i = 0; i < m; ++i) r[i] = b[i] - q[i];
  if (safe_start) {
    // ½x₀ᵀAx₀ − bᵀx₀ = −½x₀ᵀ(b + r₀): positive means x₀ is worse than x = 0.
    double phi = 0;
    for (int32_t i = 0; i < m; ++i) phi -= 0.5 * x[i] * (b[i] + r[i]);
    if (phi > 0) {
      for (int32_t i = 0; i < m; ++i) {
        x[i] = 0.0;
        r[i] = b[i];
      }
      st.started_from_zero = true;
    }
  }
  apply_preconditioner(prec, r, z);
  for (int32_t i = 0; i < m; ++i) p[i] = z[i];
  double rz = dotn(r, z, m);
  double rnorm = std::sqrt(dotn(r, r, m));
  const double rnorm0 = rnorm;
  const double target = tolerance * bnorm;
  st.converged = false;
  int k = 0;
  // A warm start may already meet the relative test; a zero start never does (‖r‖ = ‖b‖).
  if (rnorm <= target) {
    st.converged = true;
    st.relative_residual = rnorm / bnorm;
    return st;
  }
  // Look-ahead: the duration of the last iteration (the next one will be about as long).
  const bool timed = look_ahead && deadline && deadline->at_ns > 0;
  int64_t iteration_start = timed ? steady_now_ns() : 0, last_iteration_ns = 0;
  while (k < max_iterations) {
    bsr_spmv(pat, A, p, q);
    if (extra) extra->apply(extra->context, p, q);
    const double pq = dotn(p, q, m);
    if (!(pq > 0.0)) break;  // not positive definite along p (or NaN): stop, report
    const double alpha = rz / pq;
    for (int32_t i = 0; i < m; ++i) {
      x[i] += alpha * p[i];
      r[i] -= alpha * q[i];
    }
    ++k;
    rnorm = std::sqrt(dotn(r, r, m));
    if (rnorm <= target) {
      st.converged = true;
      break;
    }
    if (timed) {
      const int64_t now = steady_now_ns();
      last_iteration_ns = now - iteration_start;
      iteration_start = now;
    }
    if (deadline && deadline->past_in(last_iteration_ns)) {
      st.budget_stopped = true;
      break;
    }
    // Progress: at the mean rate ρ = (‖r_k‖/‖r_0‖)^(1/k) the target is log(target/‖r_k‖)/log ρ
    // iterations away; past progress_limit, this preconditioner is not converging here.
    if (progress_from > 0 && k >= progress_from) {
      const double log_rate = std::log(rnorm / rnorm0) / k;
      if (!(log_rate < 0.0) || k + std::log(target / rnorm) / log_rate > progress_limit) {
        st.stalled = true;
        break;
      }
    }
    apply_preconditioner(prec, r, z);
    const double rz_new = dotn(r, z, m);
    const double beta = rz_new / rz;
    rz = rz_new;
    for (int32_t i = 0; i < m; ++i) p[i] = z[i] + beta * p[i];
  }
  st.iterations = k;
  st.relative_residual = rnorm / bnorm;
  return st;
}

}  // namespace stroma
