#include "tissue/rigid_rows.hpp"

#include <cmath>

#include "tissue/constraints.hpp"
#include "tissue/demand.hpp"

namespace stroma {

namespace {

/// K' = ks·K + cs·C of a spring.
inline void spring_kprime(const ContactSpring& sp, double ks, double cs, double* Kp) {
  for (int k = 0; k < 9; ++k) Kp[k] = ks * sp.K[k] + cs * sp.C[k];
}

/// J u = v + ω × a: the velocity of the point at arm a of a body moving with u = (v, ω).
inline void point_velocity(const double* u, const double* a, double* p) {
  p[0] = u[0] + u[4] * a[2] - u[5] * a[1];
  p[1] = u[1] + u[5] * a[0] - u[3] * a[2];
  p[2] = u[2] + u[3] * a[1] - u[4] * a[0];
}

/// g += s·Jᵀ f = s·(f, a × f): a point force f at arm a as a generalised force.
inline void add_generalised(const double* f, const double* a, double s, double* g) {
  g[0] += s * f[0];
  g[1] += s * f[1];
  g[2] += s * f[2];
  g[3] += s * (a[1] * f[2] - a[2] * f[1]);
  g[4] += s * (a[2] * f[0] - a[0] * f[2]);
  g[5] += s * (a[0] * f[1] - a[1] * f[0]);
}

inline void mul3(const double* A, const double* x, double* y) {
  for (int i = 0; i < 3; ++i) y[i] = A[3 * i] * x[0] + A[3 * i + 1] * x[1] + A[3 * i + 2] * x[2];
}

/// One side of a spring acting on a row: its row, sign in the relative velocity, arm.
struct Side {
  int32_t row;
  double sign;
  const double* arm;
};

}  // namespace

void RigidRows::reserve(int32_t rows) {
  cap_ = rows;
  A_.assign(36 * static_cast<size_t>(rows) * static_cast<size_t>(rows), 0.0);
  b_.assign(6 * static_cast<size_t>(rows), 0.0);
  z_.assign(6 * static_cast<size_t>(rows), 0.0);
}

bool RigidRows::assemble(const RigidRowsInput& in, const ContactSpring* springs, int count, double h,
                         const double* v_t0, double* rhs_t, const FemModel& m, const double* spring_force) {
  STROMA_DEMAND(in.rows <= cap_, "rigid rows: more rows than reserved");
  rows_ = in.rows;
  in_ = &in;
  springs_ = springs;
  count_ = count;
  m_ = &m;
  kscale_ = h * h;
  cscale_ = h;
  if (rows_ == 0) return true;
  const int N = 6 * rows_;
  std::fill(A_.begin(), A_.begin() + static_cast<size_t>(N) * N, 0.0);
  for (int r = 0; r < rows_; ++r) {
    double* Ar = &A_[static_cast<size_t>(6 * r) * N + 6 * r];
    for (int k = 0; k < 3; ++k) Ar[k * N + k] = in.mass[r];
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) Ar[(3 + i) * N + 3 + j] = in.inertia[9 * r + 3 * i + j];
    for (int k = 0; k < 6; ++k) b_[6 * r + k] = h * in.force[6 * r + k];
  }
  for (int c = 0; c < count; ++c) {
    const ContactSpring& sp = springs[c];
    if (!spring_has_rows(sp)) continue;
    STROMA_DEMAND(sp.row_p < rows_ && sp.row_n < rows_ && (sp.n == 0) == (sp.row_p >= 0),
                  "rigid rows: a spring names a row that is not in the step, or has both DOFs and row_p");
    double Kp[9];
    spring_kprime(sp, kscale_, cscale_, Kp);
    const Side sides[2] = {{sp.row_p, 1.0, sp.arm_p}, {sp.row_n, -1.0, sp.arm_n}};
    // The relative velocity at the step's start, g0 = W v_t0 + J_p u_p − J_n u_n, and the
    // generalised impulse h f − K' g0 the rows get (with their side's sign).
    double g0[3] = {0, 0, 0};
    for (int a = 0; a < sp.n; ++a)
      for (int k = 0; k < 3; ++k) g0[k] += sp.w[a] * v_t0[3 * sp.node[a] + k];
    for (const Side& s : sides) {
      if (s.row < 0) continue;
      double pv[3];
      point_velocity(in.u0 + 6 * s.row, s.arm, pv);
      for (int k = 0; k < 3; ++k) g0[k] += s.sign * pv[k];
    }
    double Kg[3], imp[3];
    mul3(Kp, g0, Kg);
    const double* f = spring_force ? spring_force + 3 * c : sp.force;
    for (int k = 0; k < 3; ++k) imp[k] = h * f[k] - Kg[k];
    for (const Side& s : sides)
      if (s.row >= 0) add_generalised(imp, s.arm, s.sign, &b_[6 * s.row]);
    // The tissue's share: its rhs already holds Wᵀ(h f − K' W v_t0) (the stepper's SpMV); the
    // anchor's start velocity adds −Wᵀ K' (−J_n u_n) = Wᵀ K' J_n u_n.
    if (sp.n > 0 && sp.row_n >= 0) {
      double pv[3], t[3];
      point_velocity(in.u0 + 6 * sp.row_n, sp.arm_n, pv);
      mul3(Kp, pv, t);
      for (int a = 0; a < sp.n; ++a)
        for (int k = 0; k < 3; ++k)
          if (!dof_constrained(m, sp.node[a], k)) rhs_t[3 * sp.node[a] + k] += sp.w[a] * t[k];
    }
    // A_rr's blocks s_α s_β J_αᵀ K' J_β. With P = K' J_β = [K', −K'[b]×]: J_αᵀ P = [P; [a]× P].
    for (const Side& sa : sides) {
      if (sa.row < 0) continue;
      for (const Side& sb : sides) {
        if (sb.row < 0) continue;
        const double* b = sb.arm;
        double P[18];  // 3 × 6
        for (int i = 0; i < 3; ++i) {
          const double* k = Kp + 3 * i;
          P[6 * i + 0] = k[0];
          P[6 * i + 1] = k[1];
          P[6 * i + 2] = k[2];
          // −(K'[b]×) row i: −(k × ... ) : [b]× = [[0,−b2,b1],[b2,0,−b0],[−b1,b0,0]]
          P[6 * i + 3] = -(k[1] * b[2] - k[2] * b[1]);
          P[6 * i + 4] = -(k[2] * b[0] - k[0] * b[2]);
          P[6 * i + 5] = -(k[0] * b[1] - k[1] * b[0]);
        }
        const double* a = sa.arm;
        const double sgn = sa.sign * sb.sign;
        double* Ab = &A_[static_cast<size_t>(6 * sa.row) * N + 6 * sb.row];
        for (int j = 0; j < 6; ++j) {
          const double p0 = P[j], p1 = P[6 + j], p2 = P[12 + j];
          Ab[0 * N + j] += sgn * p0;
          Ab[1 * N + j] += sgn * p1;
          Ab[2 * N + j] += sgn * p2;
          Ab[3 * N + j] += sgn * (a[1] * p2 - a[2] * p1);
          Ab[4 * N + j] += sgn * (a[2] * p0 - a[0] * p2);
          Ab[5 * N + j] += sgn * (a[0] * p1 - a[1] * p0);
        }
      }
    }
  }
  // Cholesky in place (lower), N ≤ 6·capacity.
  for (int j = 0; j < N; ++j) {
    double d = A_[static_cast<size_t>(j) * N + j];
    for (int k = 0; k < j; ++k) d -= A_[static_cast<size_t>(j) * N + k] * A_[static_cast<size_t>(j) * N + k];
    if (!(d > 0)) {
      rows_ = 0;
      return false;
    }
    d = std::sqrt(d);
    A_[static_cast<size_t>(j) * N + j] = d;
    for (int i = j + 1; i < N; ++i) {
      double s = A_[static_cast<size_t>(i) * N + j];
      for (int k = 0; k < j; ++k) s -= A_[static_cast<size_t>(i) * N + k] * A_[static_cast<size_t>(j) * N + k];
      A_[static_cast<size_t>(i) * N + j] = s / d;
    }
  }
  return true;
}

void RigidRows::solve_rr(double* z) const {
  const int N = 6 * rows_;
  for (int i = 0; i < N; ++i) {
    double s = z[i];
    for (int k = 0; k < i; ++k) s -= A_[static_cast<size_t>(i) * N + k] * z[k];
    z[i] = s / A_[static_cast<size_t>(i) * N + i];
  }
  for (int i = N - 1; i >= 0; --i) {
    double s = z[i];
    for (int k = i + 1; k < N; ++k) s -= A_[static_cast<size_t>(k) * N + i] * z[k];
    z[i] = s / A_[static_cast<size_t>(i) * N + i];
  }
}

void RigidRows::mul_bt(const double* x, double* z) const {
  // B = Σ Wᵀ K' (−J_n) over springs with DOFs and an anchor row: Bᵀx = −Σ J_nᵀ K' W x.
  std::fill(z, z + 6 * rows_, 0.0);
  for (int c = 0; c < count_; ++c) {
    const ContactSpring& sp = springs_[c];
    if (sp.n == 0 || sp.row_n < 0) continue;
    double wx[3] = {0, 0, 0};
    for (int a = 0; a < sp.n; ++a)
      for (int k = 0; k < 3; ++k)
        if (!dof_constrained(*m_, sp.node[a], k)) wx[k] += sp.w[a] * x[3 * sp.node[a] + k];
    double Kp[9], t[3];
    spring_kprime(sp, kscale_, cscale_, Kp);
    mul3(Kp, wx, t);
    add_generalised(t, sp.arm_n, -1.0, z + 6 * sp.row_n);
  }
}

void RigidRows::sub_b(const double* z, double* y) const {
  for (int c = 0; c < count_; ++c) {
    const ContactSpring& sp = springs_[c];
    if (sp.n == 0 || sp.row_n < 0) continue;
    double pv[3], t[3], Kp[9];
    point_velocity(z + 6 * sp.row_n, sp.arm_n, pv);
    spring_kprime(sp, kscale_, cscale_, Kp);
    mul3(Kp, pv, t);  // (B z) at the spring's nodes = −w_a K' J_n z: y −= that
    for (int a = 0; a < sp.n; ++a)
      for (int k = 0; k < 3; ++k)
        if (!dof_constrained(*m_, sp.node[a], k)) y[3 * sp.node[a] + k] += sp.w[a] * t[k];
  }
}

void RigidRows::reduce_rhs(double* rhs_t) const {
  if (rows_ == 0) return;
  std::copy(b_.begin(), b_.begin() + 6 * rows_, z_.begin());
  solve_rr(z_.data());
  sub_b(z_.data(), rhs_t);
}

void RigidRows::apply(const double* x, double* y) const {
  if (rows_ == 0) return;
  mul_bt(x, z_.data());
  solve_rr(z_.data());
  sub_b(z_.data(), y);  // y −= B A⁻¹ Bᵀ x
}

void RigidRows::back_substitute(const double* dv) const {
  if (rows_ == 0) return;
  mul_bt(dv, z_.data());
  for (int i = 0; i < 6 * rows_; ++i) in_->du[i] = b_[static_cast<size_t>(i)] - z_[static_cast<size_t>(i)];
  solve_rr(in_->du);
}

}  // namespace stroma
