// Knots (issue 43; docs/THREAD.md "Knots"): a USP 3-0 suture tied in an overhand knot, and in a
// square knot around a rod, pulled at both ends by two graspers, tightens and holds its load —
// no two of its segments ever pass through each other (the independent continuous check of
// every pair over every tick); the same two bights laid without interlocking come apart.

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "engine/state.hpp"
#include "engine/tick.hpp"
#include "scene/compiled_scenario.hpp"
#include "scene/scenario_spec.hpp"
#include "tests/test_labels.hpp"
#include "tests/test_scenarios.hpp"
#include "tests/knot_determinant.hpp"
#include "tests/thread_crossing.hpp"

using namespace stroma;
using stroma::test_support::count_passes;
using stroma::test_support::knot_determinant;

namespace {

const std::string kSrc = STROMA_SOURCE_DIR;
constexpr double kPi = 3.14159265358979323846;
constexpr double kD = 2.0e-4;  // the suture's diameter (USP 3-0)
using P3 = std::array<double, 3>;

P3 trefoil(double t) {
  return {std::sin(t) + 2 * std::sin(2 * t), std::cos(t) - 2 * std::cos(2 * t), -std::sin(3 * t)};
}
P3 trefoil_tangent(double t) {
  const P3 d{std::cos(t) + 4 * std::cos(2 * t), -std::sin(t) + 4 * std::sin(2 * t), -3 * std::cos(3 * t)};
  const double n = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
  return {d[0] / n, d[1] / n, d[2] / n};
}
P3 bezier(const P3& a, const P3& b, const P3& c, const P3& d, double u) {
  P3 p;
  for (int k = 0; k < 3; ++k)
    p[size_t(k)] = (1 - u) * (1 - u) * (1 - u) * a[size_t(k)] + 3 * (1 - u) * (1 - u) * u * b[size_t(k)] +
                   3 * (1 - u) * u * u * c[size_t(k)] + u * u * u * d[size_t(k)];
  return p;
}
double dist(const P3& a, const P3& b) {
  return std::sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) + (a[2] - b[2]) * (a[2] - b[2]));
}

/// An overhand knot, loosely laid: the trefoil (sin t + 2 sin 2t, cos t − 2 cos 2t, −sin 3t)
/// scaled by `scale`, cut open at its bottom lobe (t = π ± 0.5), each cut end carried on by a
/// cubic Bézier from its tangent there into a straight tail, 1.5 scales below the cut, `tail`
/// out along −x (the first end) and +x (the last) — a fine polyline.
std::vector<P3> overhand_lay(double scale, double tail) {
  const double delta = 0.5;
  std::vector<P3> knot;
  for (int i = 0; i <= 2000; ++i) {
    const P3 p = trefoil(kPi + delta + (2 * kPi - 2 * delta) * i / 2000.0);
    knot.push_back({scale * p[0], scale * p[1], scale * p[2]});
  }
  const P3 A = knot.front(), B = knot.back();
  const P3 ta = trefoil_tangent(kPi + delta), tb = trefoil_tangent(3 * kPi - delta);
  const double y = A[1] - 1.5 * scale, arm = 1.5 * scale;
  const P3 Fs{-tail, y, A[2]}, Fe{tail, y, B[2]};
  std::vector<P3> path;
  for (int i = 3000; i >= 1; --i)  // the first tail, from its end in to the knot
    path.push_back(bezier(A, {A[0] - arm * ta[0], A[1] - arm * ta[1], A[2] - arm * ta[2]},
                          {Fs[0] + tail / 3, Fs[1], Fs[2]}, Fs, i / 3000.0));
  path.insert(path.end(), knot.begin(), knot.end());
  for (int i = 1; i <= 3000; ++i)
    path.push_back(bezier(B, {B[0] + arm * tb[0], B[1] + arm * tb[1], B[2] + arm * tb[2]},
                          {Fe[0] - tail / 3, Fe[1], Fe[2]}, Fe, i / 3000.0));
  return path;
}

/// n + 1 points equally spaced along the polyline p (its length in *length).
std::vector<P3> resample(const std::vector<P3>& p, int n, double* length) {
  std::vector<double> s(p.size(), 0.0);
  for (size_t i = 1; i < p.size(); ++i) s[i] = s[i - 1] + dist(p[i], p[i - 1]);
  std::vector<P3> q;
  size_t j = 1;
  for (int k = 0; k <= n; ++k) {
    const double at = s.back() * k / n;
    while (j + 1 < p.size() && s[j] < at) ++j;
    const double u = std::clamp((at - s[j - 1]) / (s[j] - s[j - 1]), 0.0, 1.0);
    q.push_back({p[j - 1][0] + u * (p[j][0] - p[j - 1][0]), p[j - 1][1] + u * (p[j][1] - p[j - 1][1]),
                 p[j - 1][2] + u * (p[j][2] - p[j - 1][2])});
  }
  *length = 0;
  for (size_t i = 1; i < q.size(); ++i) *length += dist(q[i], q[i - 1]);
  return q;
}

std::string num(double v) {
  char b[40];
  std::snprintf(b, sizeof b, "%.12g", v);
  return b;
}

/// A grasper of the knot tests: a 0.3 mm sphere whose jaws close on the thread at its tip and
/// hold it by a spring of 10 kN/m (0.2 mm at 2 N).
std::string grasper(const std::string& name, const P3& at) {
  return "  - name: " + name + R"(
    shape: {type: sphere, radius: 0.0003}
    grasp: {close: 0.05, open: 0.1, stiffness: 1.0e4}
    max_speed: 1.0
    pose: {position: [)" + num(at[0]) + ", " + num(at[1]) + ", " + num(at[2]) + "]}\n";
}


/// The square (reef) knot as tied around a rod along z, laid loose: the flat reef — two
/// interlocked bights — in the plane z–x on top of the rod, `u` the radius of each bight's
/// U-turn. Blue (the first end's half) comes in from −x along z = +βu, rises across to z = +u,
/// turns down round (c·u, 0) and goes back to z = −βu, then round the rod (below it, in the plane
/// z = −βu) up into red's bottom leg, which goes left, turns up round (−c·u, 0) and leaves along
/// +x at z = +βu — the second end. They cross six times: each U-turn over the other's two legs
/// and, where the legs cross each other (x = 0), red over blue — so that each bight lassoes the
/// other's legs (a granny would alternate; `interlocked` false lays blue wholly over red, the
/// control: nothing holds the bights). Heights ±e (≥ a diameter apart at every crossing).
std::vector<P3> square_knot_lay(double u, double tail, double rod_y, double rod_r, bool interlocked) {
  const double beta = 0.4, c = 0.8, e = 0.2e-3, w = 0.5, A = 2.5;
  const int n = 400;
  auto bump = [&](double x) { return interlocked ? std::exp(-(x / u / w) * (x / u / w)) : 0.0; };
  auto ramp = [&](double x) {  // 0 at x ≤ −c·u, 1 at x ≥ c·u, smooth
    const double t = std::clamp((x / u + c) / (2 * c), 0.0, 1.0);
    return t * t * (3 - 2 * t);
  };
  auto blue_y = [&](double x) { return e * (1 - 2 * bump(x)); };  // dips under red at x = 0
  auto red_y = [&](double x) { return -e * (1 - 2 * bump(x)); };
  std::vector<P3> p;
  auto line = [&](double x0, double x1, auto&& at, bool first) {
    for (int i = first ? 0 : 1; i <= n; ++i) p.push_back(at(x0 + (x1 - x0) * i / n));
  };
  line(-tail, -c * u, [&](double x) { return P3{x, blue_y(x), u * beta}; }, true);  // blue's top leg
  line(-c * u, c * u, [&](double x) { return P3{x, blue_y(x), u * (beta + (1 - beta) * ramp(x))}; }, false);
  for (int i = 1; i <= n; ++i) {  // blue's U-turn, over red's legs
    const double th = kPi * i / n;
    p.push_back({u * (c + std::sin(th)), e, u * std::cos(th)});
  }
  line(c * u, -c * u, [&](double x) { return P3{x, blue_y(x), -u * (beta + (1 - beta) * ramp(x))}; }, false);
  line(-c * u, -A * u, [&](double x) { return P3{x, e, -u * beta}; }, false);
  // Round the rod: two cubic Béziers through its bottom, a diameter below it.
  const P3 q{0.0, rod_y - rod_r - 2 * kD, -u * beta}, p1{-A * u, e, -u * beta}, p2{A * u, -e, -u * beta};
  const double k = A * u;
  for (int i = 1; i <= n; ++i)
    p.push_back(bezier(p1, {p1[0] - k, p1[1], p1[2]}, {q[0] - k, q[1], q[2]}, q, double(i) / n));
  for (int i = 1; i <= n; ++i)
    p.push_back(bezier(q, {q[0] + k, q[1], q[2]}, {p2[0] + k, p2[1], p2[2]}, p2, double(i) / n));
  line(A * u, c * u, [&](double x) { return P3{x, -e, -u * beta}; }, false);  // red's bottom leg
  line(c * u, -c * u, [&](double x) { return P3{x, red_y(x), -u * (beta + (1 - beta) * (1 - ramp(x)))}; }, false);
  for (int i = 1; i <= n; ++i) {  // red's U-turn, under blue's legs
    const double th = kPi * i / n;
    p.push_back({-u * (c + std::sin(th)), -e, -u * std::cos(th)});
  }
  line(-c * u, c * u, [&](double x) { return P3{x, red_y(x), u * (beta + (1 - beta) * (1 - ramp(x)))}; }, false);
  line(c * u, tail, [&](double x) { return P3{x, red_y(x), u * beta}; }, false);  // red's top leg
  return p;
}

/// A suture of the knot tests: USP 3-0 polyglactin-like by default (0.2 mm, E 5 GPa, friction
/// 0.2 on itself) in segments of about 0.5 mm (2.5 diameters).
struct Suture {
  double diameter = kD, modulus = 5.0e9, friction = 0.2, segment = 5e-4;
};

/// What a knot did when its two ends were pulled (pull_knot).
struct KnotPull {
  int segments = 0, bad_ticks = 0, passes = 0;
  int loaded_at = -1;             ///< the tick the hold began (−1: the load was never held)
  double loose = 0, least = 0;    ///< m: the thread in the knot as laid, and the least over the run
  double held = 0, force = 0;     ///< m, N: at the hold's start
  double drift = 0, force_drift = 0;  ///< m, N: the most either moved from there over the hold
  int det_laid = 0, det_held = 0;     ///< the knot's determinant as laid and after the hold (−1: projections disagree)
};

/// The knot determinant of the thread's nodes (tests/knot_determinant.hpp) in the first three
/// projections that are not degenerate: their common value, or −1 if they disagree (they cannot,
/// for a knot: a check of the check).
int thread_knot(const Model& m, const State& s) {
  const RodRange& r = m.fem.rods[0];
  std::vector<std::array<double, 3>> x;
  for (int32_t i = r.node_begin; i < r.node_end; ++i)
    x.push_back({s.tissue.x[3 * i], s.tissue.x[3 * i + 1], s.tissue.x[3 * i + 2]});
  std::vector<int> d;
  for (uint64_t seed = 1; seed <= 20 && d.size() < 3; ++seed)
    if (const int k = knot_determinant(x, seed); k >= 0) d.push_back(k);
  return d.size() == 3 && d[0] == d[1] && d[1] == d[2] ? d[0] : -1;
}

/// The thread in a knot (and round whatever it is tied on): its length along the nodes less
/// the distance between its ends — zero for a straight thread, and what a knot stores.
double stored_length(const Model& m, const State& s) {
  const RodRange& r = m.fem.rods[0];
  const double* x = s.tissue.x.data();
  double arc = 0;
  for (int32_t i = r.node_begin; i + 1 < r.node_end; ++i)
    arc += std::hypot(x[3 * i + 3] - x[3 * i], x[3 * i + 4] - x[3 * i + 1], x[3 * i + 5] - x[3 * i + 2]);
  const int32_t a = r.node_begin, b = r.node_end - 1;
  return arc - std::hypot(x[3 * b] - x[3 * a], x[3 * b + 1] - x[3 * a + 1], x[3 * b + 2] - x[3 * a + 2]);
}

/// A suture `su` (1100 kg/m³, mass damping 20/s) along `lay`, its ends held by two graspers (`rest`: more of the scene, YAML),
/// which stand still for 50 ms, then pull the ends apart along x at 20 mm/s each whenever the
/// right one feels less than `load` — until it has felt at least that for 200 ticks running —
/// then hold still for 1 s. Every tick: its status, and the independent crossing check.
KnotPull pull_knot(const std::vector<P3>& lay, const std::string& rest, double load, const Suture& su = {}) {
  KnotPull out;
  double fine = 0, L = 0;
  for (size_t i = 1; i < lay.size(); ++i) fine += dist(lay[i], lay[i - 1]);
  out.segments = static_cast<int>(std::lround(fine / su.segment));
  const std::vector<P3> q = resample(lay, out.segments, &L);
  std::string path = "[";
  for (size_t i = 0; i < q.size(); ++i)
    path += (i ? ", [" : "[") + num(q[i][0]) + ", " + num(q[i][1]) + ", " + num(q[i][2]) + "]";
  path += "]";
  const std::string yaml = test_scenarios::rigid_scene_head("knot") + rest + "tools:\n" + grasper("left", q.front()) +
                           grasper("right", q.back()) + "threads:\n  - name: suture\n    length: " + num(L) +
                           "\n    segments: " + std::to_string(out.segments) +
                           "\n    diameter: " + num(su.diameter) + "\n    young_modulus: " + num(su.modulus) +
                           "\n    density: 1100\n    damping: {rayleigh_mass: 20}\n    friction: " + num(su.friction) +
                           "\n    path: " + path + "\n";
  const auto m = compile_model(parse_scenario(yaml, "knot.yaml", kSrc));
  State s = State::initial(*m);
  TickWorkspace w(*m);
  out.loose = out.least = stored_length(*m, s);
  out.det_laid = thread_knot(*m, s);
  P3 left = q.front(), right = q.back();
  std::vector<double> x0(s.tissue.x.size());
  int still = 0;  // ticks running at the load, the graspers still
  for (int i = 0; i < 12000; ++i) {
    ToolInput in[2];
    for (int t = 0; t < 2; ++t) {
      in[t].tool = t;
      in[t].seq = uint64_t(i + 1);
      const P3& p = t == 0 ? left : right;
      in[t].pose.position = {p[0], p[1], p[2]};
      in[t].pose.jaw = 0.0;
    }
    std::copy(s.tissue.x.begin(), s.tissue.x.end(), x0.begin());
    const TickReport& rep = tick(*m, s, w, in, 2);
    out.bad_ticks += rep.status != TickStatus::Ok && rep.status != TickStatus::SolverNotConverged;
    out.passes += count_passes(*m, x0, s.tissue.x.data());
    const double now = stored_length(*m, s), f = std::abs(rep.tools[1].force[0]);
    out.least = std::min(out.least, now);
    if (out.loaded_at < 0) {
      if (i < 50) continue;
      if (f < load) {
        left[0] -= 2e-5, right[0] += 2e-5;
        still = 0;
      } else if (++still == 200) {
        out.loaded_at = i;
        out.held = now;
        out.force = f;
      }
    } else {
      out.drift = std::max(out.drift, std::abs(now - out.held));
      out.force_drift = std::max(out.force_drift, std::abs(f - out.force));
      if (i - out.loaded_at >= 1000) break;
    }
  }
  out.det_held = thread_knot(*m, s);
  std::printf("  %d segments; the knot stores %.2f mm laid, %.2f mm at %.3f N (tick %d), then over 1 s within "
              "%.4f mm and %.4f N; least %.2f mm (%.1f diameters); %d pass-throughs; knot determinant %d laid, %d held\n",
              out.segments, 1e3 * out.loose, 1e3 * out.held, out.force, out.loaded_at, 1e3 * out.drift,
              out.force_drift, 1e3 * out.least, out.least / su.diameter, out.passes, out.det_laid, out.det_held);
  return out;
}

/// A fixed rigid rod along z, 2 mm thick, 0.1 m long, its axis at y = −1.5 mm: what the square
/// knot is tied around.
constexpr double kRodY = -0.0015, kRodR = 0.001;
const std::string kRod = R"(rigid_bodies:
  - name: rod
    shape: {type: capsule, radius: 0.001, length: 0.1}
    density: 1000
    fixed: true
    pose: {position: [0, -0.0015, 0]}
)";

}  // namespace

// An overhand knot in a USP 3-0 suture, laid loose (the trefoil at 1 mm, tails of 30 mm), each
// end held by a grasper, pulled apart until the knot holds 2 N with the graspers still for
// 200 ms, then held for 1 s (pull_knot). The knot tightens: the thread it stores falls from
// 27 mm to a few millimetres; over the hold that length and the force stay put (it neither
// slips nor comes undone); it is never less than the tightest an open trefoil can be, 10.1
// diameters of rope (Pierański, Przybył, Stasiak, "Tight open knots", Eur. Phys. J. E 6, 2001):
// a thread that went into itself could be tighter. No two segments pass through each other.
TEST(ThreadKnot, AnOverhandKnotPulledAtBothEndsTightensAndHoldsItsLoad) {
  STROMA_LONG_TEST();
  // The 3-0 suture; and a thinner, softer, slipperier one (USP 4-0-like: 0.15 mm, E 3 GPa,
  // friction 0.1, segments of 0.4 mm) laid at 0.8 mm.
  const Suture sutures[2] = {Suture{}, Suture{1.5e-4, 3.0e9, 0.1, 4e-4}};
  const double scales[2] = {1e-3, 0.8e-3};
  for (int c = 0; c < 2; ++c) {
    const Suture& su = sutures[c];
    const KnotPull k = pull_knot(overhand_lay(scales[c], 0.03), "", 2.0, su);
    EXPECT_EQ(k.bad_ticks, 0) << c;
    EXPECT_EQ(k.passes, 0) << c << ": no segment went through another";
    ASSERT_GE(k.loaded_at, 0) << c << ": the knot came to hold the load";
    EXPECT_GT(k.loose, 0.02) << c;
    EXPECT_EQ(k.det_laid, 3) << c << ": laid, an overhand knot (a trefoil once its ends are joined)";
    EXPECT_EQ(k.det_held, 3) << c << ": and still one, tight";
    EXPECT_LT(k.held, 0.3 * k.loose) << c << ": the knot tightened";
    EXPECT_GT(k.least, 10.1 * su.diameter) << c << ": a knot, and never tighter than a tight open trefoil";
    EXPECT_LT(k.drift, 0.01 * k.held) << c << ": held: the knot does not slip under the load";
    EXPECT_LT(k.force_drift, 0.02 * k.force) << c << ": and the graspers keep feeling it";
  }
}

// A square knot tied around a fixed 2 mm rod (square_knot_lay: laid loose, bights of 1 mm, tails
// of 30 mm), pulled at both ends by the graspers until it holds 2 N for 200 ms with them still,
// then held for 1 s: it tightens onto the rod and holds — the thread it stores (the loop round
// the rod and the knot on top) more than the rod's circumference at the thread's axis, and
// steady over the hold with the force; no pass-through. The control: the same two bights laid
// without interlocking (blue wholly over red) come apart under the same pull — the thread ends
// draped under the rod, storing less than a tenth of that.
TEST(ThreadKnot, ASquareKnotAroundARodPulledAtBothEndsHoldsItsLoad) {
  STROMA_LONG_TEST();
  const double around = 2 * kPi * (kRodR + 0.5 * kD);
  const KnotPull k = pull_knot(square_knot_lay(1e-3, 0.03, kRodY, kRodR, true), kRod, 2.0);
  EXPECT_EQ(k.bad_ticks, 0);
  EXPECT_EQ(k.passes, 0) << "no segment went through another";
  ASSERT_GE(k.loaded_at, 0) << "the knot came to hold the load";
  EXPECT_GT(k.held, around) << "round the rod and knotted";
  EXPECT_EQ(k.det_laid, 9) << "laid, a square knot (trefoil and mirror trefoil: 3 x 3)";
  EXPECT_EQ(k.det_held, 9) << "and still one, tight";
  EXPECT_LT(k.held, 0.6 * k.loose) << "it tightened";
  EXPECT_LT(k.drift, 0.01 * k.held) << "held: the knot does not slip under the load";
  EXPECT_LT(k.force_drift, 0.02 * k.force) << "and the graspers keep feeling it";
  const KnotPull none = pull_knot(square_knot_lay(1e-3, 0.03, kRodY, kRodR, false), kRod, 2.0);
  EXPECT_EQ(none.passes, 0);
  EXPECT_EQ(none.det_laid, 1) << "the control is no knot";
  EXPECT_LT(none.held, 0.1 * around) << "laid without interlocking, the bights slide apart";
}

// The knot check itself (tests/knot_determinant.hpp) on known curves, opened at an outermost
// point (the last 2 % cut off, then joined far away): the (2,3) torus knot (the trefoil) 3, the
// (2,5) torus knot 5, the (2,4) torus link's one component and a circle 1 — in ten projections.
TEST(ThreadKnot, TheKnotDeterminantTellsKnotsApart) {
  auto torus = [](int p, int q) {  // ((2 + cos qt) cos pt, (2 + cos qt) sin pt, sin qt): outermost at t = 0
    std::vector<std::array<double, 3>> x;
    for (int i = 0; i < 490; ++i) {
      const double t = 2 * kPi * i / 500.0;
      x.push_back({(2 + std::cos(q * t)) * std::cos(p * t), (2 + std::cos(q * t)) * std::sin(p * t), std::sin(q * t)});
    }
    return x;
  };
  for (uint64_t seed = 0; seed < 10; ++seed) {
    EXPECT_EQ(knot_determinant(torus(2, 3), seed, 100), 3) << seed;
    EXPECT_EQ(knot_determinant(torus(2, 5), seed, 100), 5) << seed;
    EXPECT_EQ(knot_determinant(torus(1, 0), seed, 100), 1) << seed;  // a circle of radius 3
  }
}

// The first throw of an instrument tie, scripted (docs/THREAD.md, "Knots"; its Python twin is
// the pytest `-k instrument_tie`): a 3-0 suture passes under the fixed 2 mm rod, grasper A (a
// 0.3 mm sphere) holds its long end, B — a needle holder: a probe with a 1 mm tip and a 30 mm
// shaft along +z, its grasp at the tip — holds the short end. B's tip goes 8 mm over the rod, its
// shaft beside the rod; A wraps its strand 1¼ turns round the shaft (4 mm out, 4 mm behind the
// tip) and takes up the slack to 0.05 N; B draws back 9 mm along its shaft, so the wrap slides
// off its tip onto the tail; both pull apart to 1 N. Unknotted before (knot determinant 1), the
// thread is then a half knot round the rod (3: a trefoil once closed far away), its loop still
// under the rod — and no two segments went through each other on the way (the crossing check,
// every tick): the knot came from the motions, not from a thread passing itself.
TEST(ThreadKnot, TheFirstThrowOfAnInstrumentTieIsAHalfKnotRoundTheRod) {
  STROMA_LONG_TEST();
  const double rr = 0.001 + 1e-4 + 5e-5;  // the thread's axis round the rod's bottom
  std::vector<P3> lay;
  for (int i = 0; i < 200; ++i) {
    const double u = i / 199.0;
    lay.push_back({-0.004 + (-rr + 0.004) * u, 0.018 * (1 - u), 0.0});
  }
  for (int i = 1; i < 200; ++i) {
    const double a = kPi + kPi * i / 199.0;
    lay.push_back({rr * std::cos(a), rr * std::sin(a), 0.0});
  }
  for (int i = 1; i < 200; ++i) {
    const double u = i / 199.0;
    lay.push_back({rr + (0.004 - rr) * u, 0.009 * u, 0.0});
  }
  double fine = 0, L = 0;
  for (size_t i = 1; i < lay.size(); ++i) fine += dist(lay[i], lay[i - 1]);
  const int segments = static_cast<int>(std::lround(fine / 5e-4));
  const std::vector<P3> q = resample(lay, segments, &L);
  std::string path = "[";
  for (size_t i = 0; i < q.size(); ++i)
    path += (i ? ", [" : "[") + num(q[i][0]) + ", " + num(q[i][1]) + ", " + num(q[i][2]) + "]";
  const std::string yaml = test_scenarios::rigid_scene_head("tie") + R"(rigid_bodies:
  - name: rod
    shape: {type: capsule, radius: 0.001, length: 0.1}
    density: 1000
    fixed: true
    pose: {position: [0, 0, 0]}
tools:
)" + grasper("A", q.front()) + R"(  - name: B
    shape: {type: probe, radius: 0.001, length: 0.03}
    grasp: {close: 0.05, open: 0.1, stiffness: 1.0e4}
    max_speed: 1.0
    pose: {position: [)" + num(q.back()[0]) + ", " + num(q.back()[1]) + ", " + num(q.back()[2]) +
                           "]}\nthreads:\n  - name: suture\n    length: " + num(L) + "\n    segments: " +
                           std::to_string(segments) + "\n    diameter: " + num(kD) +
                           "\n    young_modulus: 5.0e9\n    density: 1100\n    damping: {rayleigh_mass: 20}"
                           "\n    friction: 0.2\n    path: " + path + "]\n";
  const auto m = compile_model(parse_scenario(yaml, "tie.yaml", kSrc));
  State s = State::initial(*m);
  TickWorkspace w(*m);
  std::vector<double> x0(s.tissue.x.size());
  P3 pose[2] = {q.front(), q.back()};
  int bad = 0, passes = 0, ticks = 0;
  const TickReport* rep = nullptr;
  auto step = [&] {
    ToolInput in[2];
    for (int t = 0; t < 2; ++t) {
      in[t].tool = t;
      in[t].seq = uint64_t(++ticks);
      in[t].pose.position = {pose[t][0], pose[t][1], pose[t][2]};
      in[t].pose.jaw = 0.0;
    }
    std::copy(s.tissue.x.begin(), s.tissue.x.end(), x0.begin());
    rep = &tick(*m, s, w, in, 2);
    bad += rep->status != TickStatus::Ok && rep->status != TickStatus::SolverNotConverged;
    passes += count_passes(*m, x0, s.tissue.x.data());
  };
  auto line = [&](int who, const P3& to, double speed) {  // straight, at `speed` (m/s)
    const P3 from = pose[who];
    const int n = std::max(1, static_cast<int>(std::lround(dist(from, to) / speed * 1000)));
    for (int i = 1; i <= n; ++i) {
      for (int k = 0; k < 3; ++k) pose[who][size_t(k)] = from[size_t(k)] + (to[size_t(k)] - from[size_t(k)]) * i / n;
      step();
    }
  };
  auto force = [&](int t) { return std::hypot(rep->tools[t].force[0], rep->tools[t].force[1], rep->tools[t].force[2]); };
  for (int i = 0; i < 50; ++i) step();
  EXPECT_EQ(thread_knot(*m, s), 1) << "laid round the rod: no knot";
  const double H = 0.008, RW = 0.004, ZW = 0.004;
  auto ring = [&](double a) { return P3{RW * std::cos(a), H + RW * std::sin(a), ZW}; };
  line(1, {0, H, 0}, 0.03);  // B's tip over the rod, its shaft along +z beside it
  const P3 r0 = ring(kPi);
  line(0, {r0[0] - 0.002, r0[1] + 0.003, r0[2]}, 0.03);
  line(0, r0, 0.03);
  const int wrap = static_cast<int>(std::lround(2.25 * kPi * RW / 0.03 * 1000));
  for (int i = 1; i <= wrap; ++i) {  // over the shaft, down behind it, under, up: 1¼ turns
    pose[0] = ring(kPi - 2.25 * kPi * i / wrap);
    step();
  }
  for (int i = 0; i < 3000 && force(0) < 0.05; ++i) {  // A takes up the slack
    pose[0][0] -= 1e-5, pose[0][1] += 2e-6;
    step();
  }
  line(1, {pose[1][0], pose[1][1], pose[1][2] + 0.009}, 0.02);  // B draws back along its shaft
  int i = 0;
  for (; i < 3000 && std::max(force(0), force(1)) < 1.0; ++i) {  // both pull apart to 1 N
    pose[0][0] -= 2e-5, pose[0][1] -= 4e-6;
    pose[1][0] += 2e-5, pose[1][1] -= 4e-6;
    step();
  }
  std::printf("  %d segments, %d ticks; pulled apart %d ms to %.2f / %.2f N; %d pass-throughs\n", segments, ticks, i,
              force(0), force(1), passes);
  EXPECT_LT(i, 3000) << "the graspers came to feel 1 N";
  EXPECT_EQ(bad, 0);
  EXPECT_EQ(passes, 0) << "no segment went through another";
  EXPECT_EQ(thread_knot(*m, s), 3) << "a half knot: a trefoil once its ends are joined far away";
  const RodRange& r = m->fem.rods[0];
  double lowest = 1;  // its loop still under the rod, both ends above it
  for (int32_t k = r.node_begin; k < r.node_end; ++k)
    if (std::abs(s.tissue.x[3 * k]) < 0.0015) lowest = std::min(lowest, s.tissue.x[3 * k + 1]);
  EXPECT_LT(lowest, -0.001);
  EXPECT_GT(s.tissue.x[3 * r.node_begin + 1], 0.0);
  EXPECT_GT(s.tissue.x[3 * (r.node_end - 1) + 1], 0.0);
}
