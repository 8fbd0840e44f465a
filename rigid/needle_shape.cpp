#include "rigid/needle_shape.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include <fmt/format.h>

namespace stroma {

namespace {
constexpr double kTwoPi = 6.28318530717958647692;
}  // namespace

void needle_curve(const NeedleGeometry& g, double s, double* c, double* t) {
  s = std::clamp(s, 0.0, g.length);
  if (!g.curved) {
    c[0] = c[1] = 0, c[2] = s;
    t[0] = t[1] = 0, t[2] = 1;
    return;
  }
  const double phi = s / g.arc_radius, cs = std::cos(phi), sn = std::sin(phi);
  c[0] = g.arc_radius * cs, c[1] = g.arc_radius * sn, c[2] = 0;
  t[0] = -sn, t[1] = cs, t[2] = 0;
}

double needle_nearest_s(const NeedleGeometry& g, const double* q) {
  if (!g.curved) return std::clamp(q[2], 0.0, g.length);
  // The angle of q's projection on the arc's plane, measured from the tail; outside the arc,
  // the nearer end (by the angle from each: the arc's ends are the nearest points there).
  double phi = std::atan2(q[1], q[0]);
  if (phi < 0) phi += kTwoPi;
  if (phi <= g.angle) return phi * g.arc_radius;
  const double past_tip = phi - g.angle, before_tail = kTwoPi - phi;
  return past_tip < before_tail ? g.length : 0.0;
}

double needle_distance(const NeedleGeometry& g, const double* q, double* normal) {
  double c[3], t[3];
  needle_curve(g, needle_nearest_s(g, q), c, t);
  const double d[3] = {q[0] - c[0], q[1] - c[1], q[2] - c[2]};
  const double r = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
  if (r > 1e-300) {
    for (int k = 0; k < 3; ++k) normal[k] = d[k] / r;
  } else {  // on the axis: any direction across it
    normal[0] = t[1], normal[1] = -t[0], normal[2] = t[2];
    if (!g.curved) normal[0] = 1, normal[1] = 0, normal[2] = 0;
  }
  return r - g.wire_radius;
}

MassProperties needle_mass_properties(const NeedleGeometry& g, double density) {
  auto bad = [](const std::string& why) { throw std::invalid_argument(why); };
  if (!(g.wire_radius > 0)) bad(fmt::format("a needle's wire_radius must be > 0 (got {})", g.wire_radius));
  if (!(g.length > 0)) bad("a needle without a tip: give its length (straight) or its radius and angle (curved)");
  if (!(density > 0)) bad(fmt::format("density must be > 0 (got {})", density));
  if (g.curved) {
    if (!(g.arc_radius > g.wire_radius))
      bad(fmt::format("a curved needle's radius ({} m) must exceed its wire_radius ({} m)", g.arc_radius, g.wire_radius));
    if (!(g.angle > 0 && g.angle <= kTwoPi + 1e-12)) bad("a curved needle's angle must be within (0, 360] degrees");
  }
  // Slices of the wire (midpoint rule): a disc of mass dm each, its own inertia
  // dm r² (¼ I + ¼ t tᵀ), shifted to the centre of mass (parallel axis).
  const int n = 4096;
  const double ds = g.length / n, r2 = g.wire_radius * g.wire_radius, dm = density * M_PI * r2 * ds;
  MassProperties p;
  p.mass = dm * n;
  p.volume = M_PI * r2 * g.length;
  double sum[3] = {0, 0, 0}, second[9] = {}, own[9] = {};
  for (int i = 0; i < n; ++i) {
    double c[3], t[3];
    needle_curve(g, (i + 0.5) * ds, c, t);
    for (int a = 0; a < 3; ++a) {
      sum[a] += dm * c[a];
      for (int b = 0; b < 3; ++b) {
        second[3 * a + b] += dm * c[a] * c[b];
        own[3 * a + b] += dm * r2 * 0.25 * ((a == b ? 1.0 : 0.0) + t[a] * t[b]);
      }
    }
  }
  for (int a = 0; a < 3; ++a) p.centre[size_t(a)] = sum[a] / p.mass;
  // I = Σ dm (|d|² I − d dᵀ) + own, d = c − centre: from the second moments about the origin.
  double S[9];
  for (int a = 0; a < 3; ++a)
    for (int b = 0; b < 3; ++b) S[3 * a + b] = second[3 * a + b] - p.mass * p.centre[size_t(a)] * p.centre[size_t(b)];
  const double tr = S[0] + S[4] + S[8];
  for (int a = 0; a < 3; ++a)
    for (int b = 0; b < 3; ++b) p.inertia[size_t(3 * a + b)] = (a == b ? tr : 0.0) - S[3 * a + b] + own[3 * a + b];
  return p;
}

}  // namespace stroma
