#include "rigid/mass_properties.hpp"

#include <Eigen/Eigenvalues>

#include <cmath>
#include <stdexcept>

#include <fmt/format.h>

namespace stroma {
namespace {

void require_positive(double v, const char* what) {
  if (!(v > 0) || !std::isfinite(v)) throw std::invalid_argument(fmt::format("{} must be > 0 (got {})", what, v));
}

MassProperties diagonal(double mass, double volume, double ixx, double iyy, double izz) {
  MassProperties p;
  p.mass = mass;
  p.volume = volume;
  p.inertia = {ixx, 0, 0, 0, iyy, 0, 0, 0, izz};
  return p;
}

}  // namespace

MassProperties sphere_mass_properties(double r, double density) {
  require_positive(r, "radius");
  require_positive(density, "density");
  const double v = 4.0 / 3.0 * M_PI * r * r * r, m = density * v, i = 0.4 * m * r * r;
  return diagonal(m, v, i, i, i);
}

MassProperties box_mass_properties(const Vec3& s, double density) {
  for (double x : s) require_positive(x, "box size");
  require_positive(density, "density");
  const double v = s[0] * s[1] * s[2], m = density * v;
  return diagonal(m, v, m / 12 * (s[1] * s[1] + s[2] * s[2]), m / 12 * (s[0] * s[0] + s[2] * s[2]),
                  m / 12 * (s[0] * s[0] + s[1] * s[1]));
}

MassProperties capsule_mass_properties(double r, double L, double density) {
  require_positive(r, "radius");
  if (!(L >= 0) || !std::isfinite(L)) throw std::invalid_argument(fmt::format("length must be >= 0 (got {})", L));
  require_positive(density, "density");
  // Cylinder (radius r, length L) plus a sphere split into two hemispheres whose centres of mass
  // sit 3r/8 beyond the cylinder's ends (parallel axes about the capsule's centre).
  const double vc = M_PI * r * r * L, vs = 4.0 / 3.0 * M_PI * r * r * r;
  const double mc = density * vc, ms = density * vs;
  const double izz = 0.5 * mc * r * r + 0.4 * ms * r * r;
  // Each hemisphere (mass ms/2): about its own centre of mass, transverse 83/320 (ms/2) r²; its
  // centre at L/2 + 3r/8 from the capsule's centre.
  const double d = 0.5 * L + 3.0 * r / 8.0;
  const double ixx = mc * (r * r / 4 + L * L / 12) + 2 * (83.0 / 320.0 * (ms / 2) * r * r + (ms / 2) * d * d);
  return diagonal(mc + ms, vc + vs, ixx, ixx, izz);
}

MassProperties mesh_mass_properties(const std::vector<Vec3>& x, const std::vector<std::array<int32_t, 3>>& tris,
                                    double density) {
  require_positive(density, "density");
  // Per triangle (a, b, c): the tetrahedron (0, a, b, c) of signed volume det[a b c] / 6, whose
  // first moment is its volume times (a + b + c) / 4 and whose second moment ∫ x xᵀ is
  // det/120 · (Σ_i v_i v_iᵀ + (Σ_i v_i)(Σ_i v_i)ᵀ) over its three non-zero vertices.
  // Moments about the vertices' mean, not the frame's origin: a body far from its origin would
  // lose digits in the parallel-axis subtraction (a 5 cm box 0.3 m away: 1e-12 relative).
  Vec3 o{0, 0, 0};
  for (const Vec3& p : x)
    for (int i = 0; i < 3; ++i) o[size_t(i)] += p[size_t(i)] / double(x.size());
  auto local = [&](int32_t k) {
    const Vec3& p = x.at(size_t(k));
    return Vec3{p[0] - o[0], p[1] - o[1], p[2] - o[2]};
  };
  double vol = 0, first[3] = {0, 0, 0}, second[9] = {0};
  for (const auto& t : tris) {
    const Vec3 a = local(t[0]), b = local(t[1]), c = local(t[2]);
    const double det = a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) +
                       a[2] * (b[0] * c[1] - b[1] * c[0]);
    vol += det / 6;
    const double s[3] = {a[0] + b[0] + c[0], a[1] + b[1] + c[1], a[2] + b[2] + c[2]};
    for (int i = 0; i < 3; ++i) first[i] += det / 24 * s[i];
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j)
        second[3 * i + j] += det / 120 * (a[i] * a[j] + b[i] * b[j] + c[i] * c[j] + s[i] * s[j]);
  }
  if (vol < 0) {  // inward-oriented: the same solid with every sign flipped
    vol = -vol;
    for (double& f : first) f = -f;
    for (double& s : second) s = -s;
  }
  if (!(vol > 0) || !std::isfinite(vol))
    throw std::invalid_argument(fmt::format("the surface encloses no volume ({:g}): not closed, or degenerate", vol));
  MassProperties p;
  p.volume = vol;
  p.mass = density * vol;
  double g[3];  // centre of mass relative to o
  for (int i = 0; i < 3; ++i) g[i] = first[i] / vol;
  for (int i = 0; i < 3; ++i) p.centre[size_t(i)] = o[size_t(i)] + g[i];
  // Second moment about the centre of mass, then inertia = tr(C) I − C (times the density).
  double C[9];
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) C[3 * i + j] = density * (second[3 * i + j] - vol * g[i] * g[j]);
  const double tr = C[0] + C[4] + C[8];
  for (int i = 0; i < 9; ++i) p.inertia[size_t(i)] = -C[i];
  for (int i = 0; i < 3; ++i) p.inertia[size_t(4 * i)] += tr;
  return p;
}

std::array<double, 3> principal_moments(const std::array<double, 9>& I) {
  Eigen::Matrix3d m;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) m(i, j) = 0.5 * (I[size_t(3 * i + j)] + I[size_t(3 * j + i)]);
  const Eigen::Vector3d e = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(m, Eigen::EigenvaluesOnly).eigenvalues();
  return {e[0], e[1], e[2]};
}

bool is_physical(const MassProperties& p, std::string* why, double rel) {
  auto fail = [&](std::string m) {
    if (why) *why = std::move(m);
    return false;
  };
  if (!(p.mass > 0) || !std::isfinite(p.mass)) return fail(fmt::format("mass {} is not > 0", p.mass));
  const auto& I = p.inertia;
  const double scale = std::abs(I[0]) + std::abs(I[4]) + std::abs(I[8]);
  for (int i = 0; i < 3; ++i)
    for (int j = i + 1; j < 3; ++j)
      if (std::abs(I[size_t(3 * i + j)] - I[size_t(3 * j + i)]) > rel * scale) return fail("the inertia tensor is not symmetric");
  const auto e = principal_moments(I);
  if (!(e[0] > 0)) return fail(fmt::format("a principal moment is {} (not > 0): a degenerate shape", e[0]));
  if (e[0] + e[1] < e[2] * (1 - rel)) return fail("the principal moments break the triangle inequality");
  return true;
}

}  // namespace stroma
