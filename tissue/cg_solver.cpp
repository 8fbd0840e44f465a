#include "tissue/cg_solver.hpp"

#include <algorithm>
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

extern "C" {
// LAPACK's banded Cholesky factorisation (Debian's liblapack-dev: the reference LAPACK or
// OpenBLAS's). Its solve, dpbtrs, is not called: see band_solve.
void dpbtrf_(const char* uplo, const int* n, const int* kd, double* ab, const int* ldab, int* info);
}

namespace {
/// L·Lᵀ·x = b in place for a factor in LAPACK's lower band storage (ab[(i − j) + j·ld] = L(i, j),
/// j ≤ i ≤ j + kd): what dpbtrs("L") computes, by the same two triangular sweeps. Written out
/// because dpbtrs's triangular solves (OpenBLAS's dtbsv) take a work buffer from OpenBLAS's pool
/// and the first call on a thread maps it: under `serve`'s mlockall the mapping is populated at
/// once, and the physics thread's first tick with a thread took 41–66 ms (perf: dtbsv →
/// blas_memory_alloc → mmap → __mm_populate; docs/PERFORMANCE.md, "Stiffness every N steps").
/// A tick allocates nothing and takes no lock; this is 2·n·kd multiply-adds and nothing else.
void band_solve(int n, int kd, const double* ab, int ld, double* x) {
  for (int j = 0; j < n; ++j) {  // L·y = b
    const double* col = ab + static_cast<size_t>(j) * ld;
    const double yj = x[j] / col[0];
    x[j] = yj;
    const int last = std::min(n - 1, j + kd);
    for (int i = j + 1; i <= last; ++i) x[i] -= col[i - j] * yj;
  }
  for (int j = n - 1; j >= 0; --j) {  // Lᵀ·x = y
    const double* col = ab + static_cast<size_t>(j) * ld;
    double s = x[j];
    const int last = std::min(n - 1, j + kd);
    for (int i = j + 1; i <= last; ++i) s -= col[i - j] * x[i];
    x[j] = s / col[0];
  }
}
}  // namespace

namespace {
constexpr int kRodBand = 8;  ///< scalar bandwidth of a rod's rows: blocks (i, i+2), 3 rows each, less one
}  // namespace

void CgSolver::set_rods(const BsrPattern& p, const std::vector<RodRange>& rods) {
  rods_.clear();
  rod_slot_.clear();
  size_t band = 0;
  for (const RodRange& r : rods) {
    rods_.push_back({r.node_begin, r.nodes(), static_cast<int32_t>(band)});
    band += static_cast<size_t>(kRodBand + 1) * 3 * static_cast<size_t>(r.nodes());
    for (int32_t i = r.node_begin; i < r.node_end; ++i)
      rod_slot_.push_back({p.diag[i], i + 1 < r.node_end ? p.find(i, i + 1) : -1, i + 2 < r.node_end ? p.find(i, i + 2) : -1});
  }
  rod_band_.assign(band, 0.0);
  rod_ok_.assign(rods_.size(), 0);
}

// Each rod's sub-matrix in LAPACK's lower band storage, ab[(i − j) + j·ldab] = A(i, j) for
// j ≤ i ≤ j + kd, factored by dpbtrf. Why LAPACK's scalar Cholesky and not a 3×3-block L·D·Lᵀ:
// a tilted stiff segment makes a node's block nearly singular across its axis (axial h²·EA/ℓ
// ~0.06 against ~1e-7 of mass and bending), and inverting such blocks by their adjugate lost
// accuracy that grew along the chain — 0.49 relative error after 75 nodes, where the scalar
// factor stays at round-off (tests/tissue/test_rod.cpp). A rod whose matrix is not positive
// definite (it always is: mass, and positive semi-definite stretching and bending) keeps its
// rows' Jacobi blocks.
void CgSolver::factor_rod_bands(const double* A, const double* extra_diag) {
  constexpr int ld = kRodBand + 1;
  size_t k = 0;  // rod node index (rod_slot_)
  for (size_t ri = 0; ri < rods_.size(); ++ri) {
    const auto [begin, count, offset] = rods_[ri];
    double* ab = rod_band_.data() + offset;
    const int n = 3 * count;
    std::fill(ab, ab + static_cast<size_t>(ld) * n, 0.0);
    for (int32_t a = 0; a < count; ++a, ++k) {
      for (int off = 0; off < 3; ++off) {
        const int32_t slot = rod_slot_[k][off];
        if (slot < 0) continue;
        const double* B = A + 9 * slot;  // block (a, a + off), upper: A(3a + r, 3(a + off) + c) = B[r][c]
        for (int r = 0; r < 3; ++r)
          for (int c = 0; c < 3; ++c) {
            const int row = 3 * (a + off) + c, col = 3 * a + r;  // the lower entry A(row, col) = B[r][c]
            if (row < col) continue;
            double v = B[3 * r + c];
            if (off == 0 && extra_diag) v += extra_diag[9 * (begin + a) + 3 * r + c];
            ab[(row - col) + col * ld] = v;
          }
      }
    }
    int info = 0;
    const int kd = kRodBand;
    dpbtrf_("L", &n, &kd, ab, &ld, &info);
    rod_ok_[ri] = info == 0;
  }
}

void CgSolver::solve_rod_bands(const double* r, double* z) const {
  constexpr int ld = kRodBand + 1;
  for (size_t ri = 0; ri < rods_.size(); ++ri) {
    if (!rod_ok_[ri]) continue;  // its Jacobi blocks stand
    const auto [begin, count, offset] = rods_[ri];
    const int n = 3 * count, kd = kRodBand;
    double* zr = z + 3 * static_cast<size_t>(begin);
    std::copy(r + 3 * static_cast<size_t>(begin), r + 3 * static_cast<size_t>(begin + count), zr);
    band_solve(n, kd, rod_band_.data() + offset, ld, zr);
  }
}

void CgSolver::build_preconditioner(const BsrPattern& p, const double* A, Preconditioner prec, const double* extra_diag) {
  if (!rods_.empty() && prec != Preconditioner::WarpedCholesky) factor_rod_bands(A, extra_diag);
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
  if (!rods_.empty() && prec != Preconditioner::WarpedCholesky) solve_rod_bands(r, z);
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
