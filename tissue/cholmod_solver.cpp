#include "tissue/cholmod_solver.hpp"

#include <algorithm>
#include <cstring>
#include <stdexcept>

#include <cholmod.h>
#include <dlfcn.h>

#include "tissue/supernodal_f32.hpp"

namespace stroma {

namespace {
/// CHOLMOD's supernodal factorisation calls BLAS. OpenBLAS (Debian's default libblas) would run
/// those calls on a thread pool of its own, one thread per core, whose threads spin after each
/// call: on this project's 2-core machine they land on the physics thread's core. Measured with
/// the preconditioner refresh (beam k6, 3,000 ticks): tick p50 4.81 ms with OpenBLAS's pool,
/// 2.58 ms with BLAS on the calling thread. CHOLMOD itself opens OpenMP regions of up to four
/// threads (its scatter and clear loops) whose threads spin likewise; with no active levels
/// every region runs on the thread that meets it — an OpenMP setting of the calling thread, so
/// it is made on each thread that factors. The engine's threads are its own, so both run
/// single-threaded; found at run time (dlsym), so another BLAS or no OpenMP works unchanged.
void single_threaded_numerics() {
  static const bool done = [] {
    for (const char* name : {"openblas_set_num_threads", "goto_set_num_threads"})
      if (void* f = dlsym(RTLD_DEFAULT, name)) {
        reinterpret_cast<void (*)(int)>(f)(1);
        break;
      }
    return true;
  }();
  (void)done;
  thread_local const bool omp_done = [] {
    if (void* f = dlsym(RTLD_DEFAULT, "omp_set_max_active_levels")) reinterpret_cast<void (*)(int)>(f)(0);
    return true;
  }();
  (void)omp_done;
}
}  // namespace

struct CholmodSolver::Impl {
  cholmod_common common;
  cholmod_sparse* A = nullptr;
  cholmod_factor* L = nullptr;
  cholmod_dense* B = nullptr;
  cholmod_dense* X = nullptr;
  cholmod_dense* Y = nullptr;  // workspace of cholmod_solve2
  cholmod_dense* E = nullptr;  // workspace of cholmod_solve2
  std::vector<int64_t> map;    // CSC value k ← BSR value map[k]
  SupernodalF32 f32;           // float copy of L (use_float_solves)
  size_t n = 0;
};

CholmodSolver::CholmodSolver(const BsrPattern& p) : impl_(std::make_unique<Impl>()) {
  single_threaded_numerics();
  Impl& s = *impl_;
  cholmod_start(&s.common);
  s.common.print = 0;
  // Always LLᵀ (supernodal): a simplicial LDLᵀ would "succeed" on indefinite matrices, and the
  // engine must know when the system is not positive definite.
  s.common.supernodal = CHOLMOD_SUPERNODAL;
  s.n = 3 * static_cast<size_t>(p.n);
  // Upper triangle (row ≤ col), column-major: collect (col, row, bsr index) and sort.
  struct Entry {
    int32_t col, row;
    int64_t src;
  };
  std::vector<Entry> entries;
  entries.reserve(static_cast<size_t>(p.nnzb()) * 6);
  for (int32_t I = 0; I < p.n; ++I)
    for (int32_t slot = p.row_ptr[I]; slot < p.row_ptr[I + 1]; ++slot) {
      const int32_t J = p.col[slot];
      if (J < I) continue;
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) {
          const int32_t row = 3 * I + r, col = 3 * J + c;
          if (row <= col) entries.push_back({col, row, 9LL * slot + 3 * r + c});
        }
    }
  std::sort(entries.begin(), entries.end(), [](const Entry& a, const Entry& b) {
    return a.col != b.col ? a.col < b.col : a.row < b.row;
  });
  s.A = cholmod_allocate_sparse(s.n, s.n, entries.size(), 1, 1, 1, CHOLMOD_REAL, &s.common);
  if (!s.A) throw std::runtime_error("CHOLMOD: cannot allocate the sparse matrix");
  auto* colp = static_cast<int*>(s.A->p);
  auto* rowi = static_cast<int*>(s.A->i);
  auto* val = static_cast<double*>(s.A->x);
  std::fill(colp, colp + s.n + 1, 0);
  s.map.resize(entries.size());
  for (size_t k = 0; k < entries.size(); ++k) {
    colp[entries[k].col + 1]++;
    rowi[k] = entries[k].row;
    val[k] = (entries[k].row == entries[k].col) ? 1.0 : 0.0;
    s.map[k] = entries[k].src;
  }
  for (size_t j = 0; j < s.n; ++j) colp[j + 1] += colp[j];
  s.L = cholmod_analyze(s.A, &s.common);
  if (!s.L) throw std::runtime_error("CHOLMOD: symbolic analysis failed");
  s.B = cholmod_zeros(s.n, 1, CHOLMOD_REAL, &s.common);
}

CholmodSolver::~CholmodSolver() {
  Impl& s = *impl_;
  cholmod_free_dense(&s.B, &s.common);
  cholmod_free_dense(&s.X, &s.common);
  cholmod_free_dense(&s.Y, &s.common);
  cholmod_free_dense(&s.E, &s.common);
  cholmod_free_factor(&s.L, &s.common);
  cholmod_free_sparse(&s.A, &s.common);
  cholmod_finish(&s.common);
}

bool CholmodSolver::factor(const double* vals) {
  single_threaded_numerics();  // this thread's OpenMP setting (once per thread)
  Impl& s = *impl_;
  auto* val = static_cast<double*>(s.A->x);
  for (size_t k = 0; k < s.map.size(); ++k) val[k] = vals[s.map[k]];
  const int ok = cholmod_factorize(s.A, s.L, &s.common);
  // Not positive definite: CHOLMOD still returns TRUE but stops at column L->minor < n.
  const bool spd = ok && s.common.status == CHOLMOD_OK && s.L->minor >= s.n;
  if (spd && float_solves_ && !s.f32.load(s.L)) float_solves_ = false;  // not supernodal LLᵀ
  return spd;
}

void CholmodSolver::solve(const double* b, double* x) {
  Impl& s = *impl_;
  if (float_solves_ && s.f32.loaded()) {
    s.f32.solve(b, x);
    return;
  }
  std::memcpy(s.B->x, b, s.n * sizeof(double));
  cholmod_solve2(CHOLMOD_A, s.L, s.B, nullptr, &s.X, nullptr, &s.Y, &s.E, &s.common);
  std::memcpy(x, s.X->x, s.n * sizeof(double));
}

double CholmodSolver::factor_entries() const { return impl_->L->is_super ? impl_->L->xsize : impl_->common.lnz; }
double CholmodSolver::factor_flops() const { return impl_->common.fl; }

}  // namespace stroma
