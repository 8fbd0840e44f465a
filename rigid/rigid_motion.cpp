#include "rigid/rigid_motion.hpp"

#include <cmath>

#include "tissue/mat3.hpp"

namespace stroma {
namespace {

Vec3 cross(const Vec3& a, const Vec3& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
Vec3 mul(const std::array<double, 9>& A, const Vec3& x) {
  Vec3 y;
  m3::mulv(A.data(), x.data(), y.data());
  return y;
}
Vec3 mul_t(const std::array<double, 9>& A, const Vec3& x) {
  Vec3 y;
  m3::mulv_t(A.data(), x.data(), y.data());
  return y;
}

/// q ⊗ exp(θ) for a rotation vector θ (body frame): the orientation turned by θ about the body.
std::array<double, 4> turned(const std::array<double, 4>& q, const Vec3& th) {
  const double a = std::sqrt(th[0] * th[0] + th[1] * th[1] + th[2] * th[2]);
  // exp(θ) = (cos(a/2), sin(a/2) θ/a); sin(a/2)/a → 1/2 as a → 0.
  const double c = std::cos(0.5 * a), k = a > 1e-8 ? std::sin(0.5 * a) / a : 0.5 - a * a / 48;
  const double r[4] = {c, k * th[0], k * th[1], k * th[2]};
  std::array<double, 4> o = {q[0] * r[0] - q[1] * r[1] - q[2] * r[2] - q[3] * r[3],
                             q[0] * r[1] + q[1] * r[0] + q[2] * r[3] - q[3] * r[2],
                             q[0] * r[2] - q[1] * r[3] + q[2] * r[0] + q[3] * r[1],
                             q[0] * r[3] + q[1] * r[2] - q[2] * r[1] + q[3] * r[0]};
  const double n = std::sqrt(o[0] * o[0] + o[1] * o[1] + o[2] * o[2] + o[3] * o[3]);
  for (double& v : o) v /= n;
  return o;
}

}  // namespace

std::array<double, 9> rotation_of(const std::array<double, 4>& q) {
  const double w = q[0], x = q[1], y = q[2], z = q[3];
  return {1 - 2 * (y * y + z * z), 2 * (x * y - w * z),     2 * (x * z + w * y),
          2 * (x * y + w * z),     1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
          2 * (x * z - w * y),     2 * (y * z + w * x),     1 - 2 * (x * x + y * y)};
}

namespace {

/// ω' of the implicit midpoint rule for I (ω' − ω) + h ω̄ × I ω̄ = 0 (body frame), by Newton.
Vec3 midpoint_omega(const std::array<double, 9>& I, double h, const Vec3& w0, RigidStepReport& r) {
  const Vec3 L0 = mul(I, w0);
  // Newton on f(ω') = I (ω' − ω) + h ω̄ × I ω̄, ω̄ = (ω + ω') / 2. J = I + h/2 ([ω̄]× I − [Iω̄]×).
  Vec3 w1 = w0;
  const double scale = std::sqrt(L0[0] * L0[0] + L0[1] * L0[1] + L0[2] * L0[2]) + 1e-300;
  for (int it = 0; it < 20; ++it) {
    const Vec3 wb = {0.5 * (w0[0] + w1[0]), 0.5 * (w0[1] + w1[1]), 0.5 * (w0[2] + w1[2])};
    const Vec3 Iwb = mul(I, wb), gyro = cross(wb, Iwb), Iw1 = mul(I, w1);
    const Vec3 f = {Iw1[0] - L0[0] + h * gyro[0], Iw1[1] - L0[1] + h * gyro[1], Iw1[2] - L0[2] + h * gyro[2]};
    r.residual = std::sqrt(f[0] * f[0] + f[1] * f[1] + f[2] * f[2]);
    r.newton_iterations = it;
    if (r.residual <= 1e-15 * scale) break;
    // [a]× b = a × b; [ω̄]× I − [Iω̄]×, as a matrix.
    const double wx[9] = {0, -wb[2], wb[1], wb[2], 0, -wb[0], -wb[1], wb[0], 0};
    const double lx[9] = {0, -Iwb[2], Iwb[1], Iwb[2], 0, -Iwb[0], -Iwb[1], Iwb[0], 0};
    double wxI[9], J[9], Ji[9];
    m3::mul(wx, I.data(), wxI);
    for (int k = 0; k < 9; ++k) J[k] = I[size_t(k)] + 0.5 * h * (wxI[k] - lx[k]);
    m3::inverse(J, Ji);
    double dw[3];
    m3::mulv(Ji, f.data(), dw);
    for (int k = 0; k < 3; ++k) w1[size_t(k)] -= dw[k];
  }
  return w1;
}

}  // namespace

Vec3 gyroscopic_step(const std::array<double, 9>& I, double h, const RigidState& s) {
  const std::array<double, 9> R = rotation_of(s.q);
  RigidStepReport r;
  return mul(R, midpoint_omega(I, h, mul_t(R, s.w), r));
}

void advance_pose(double h, RigidState& s) {
  for (int i = 0; i < 3; ++i) s.x[size_t(i)] += h * s.v[size_t(i)];
  // exp(h ω_world)·q = q·exp(h Rᵀω): the turn in the body frame.
  const Vec3 wb = mul_t(rotation_of(s.q), s.w);
  s.q = turned(s.q, {h * wb[0], h * wb[1], h * wb[2]});
}

std::array<double, 9> world_inertia(const std::array<double, 9>& I, const std::array<double, 4>& q) {
  const std::array<double, 9> R = rotation_of(q);
  double RI[9], Rt[9], out[9];
  m3::mul(R.data(), I.data(), RI);
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) Rt[3 * i + j] = R[size_t(3 * j + i)];
  m3::mul(RI, Rt, out);
  std::array<double, 9> o;
  for (int k = 0; k < 9; ++k) o[size_t(k)] = 0.5 * (out[k] + out[3 * (k % 3) + k / 3]);  // symmetric to round-off
  return o;
}

RigidStepReport step_free_rigid(const std::array<double, 9>& I, const Vec3& g, double h, RigidState& s) {
  for (int i = 0; i < 3; ++i) {
    s.v[size_t(i)] += h * g[size_t(i)];
    s.x[size_t(i)] += h * s.v[size_t(i)];
  }
  const std::array<double, 9> R = rotation_of(s.q);
  const Vec3 w0 = mul_t(R, s.w);  // body frame
  RigidStepReport r;
  const Vec3 w1 = midpoint_omega(I, h, w0, r);
  const Vec3 wbar = {0.5 * (w0[0] + w1[0]), 0.5 * (w0[1] + w1[1]), 0.5 * (w0[2] + w1[2])};
  s.q = turned(s.q, {h * wbar[0], h * wbar[1], h * wbar[2]});
  s.w = mul(rotation_of(s.q), w1);
  return r;
}

double rigid_kinetic_energy(double mass, const std::array<double, 9>& I, const RigidState& s) {
  const Vec3 wb = mul_t(rotation_of(s.q), s.w), Iw = mul(I, wb);
  return 0.5 * mass * (s.v[0] * s.v[0] + s.v[1] * s.v[1] + s.v[2] * s.v[2]) +
         0.5 * (wb[0] * Iw[0] + wb[1] * Iw[1] + wb[2] * Iw[2]);
}

Vec3 rigid_angular_momentum(const std::array<double, 9>& I, const RigidState& s) {
  const std::array<double, 9> R = rotation_of(s.q);
  return mul(R, mul(I, mul_t(R, s.w)));
}

}  // namespace stroma
