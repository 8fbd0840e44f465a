/// \file bench_cut_methods.cpp
/// The cutting method, measured against the alternatives (docs/CUTTING.md, "Why this method"):
/// random planes cut a scenario's mesh, and each method's result is measured on the same cut —
///
///  - virtual nodes (Stroma's: tissue/cut_topology): the topology built from the plane's edge
///    crossings, kept f_e of an edge from a node as the engine keeps them (CutBase::min_fraction;
///    --fixed-clamp: 5 % of every edge, as before 2026-12-03);
///  - element splitting without snapping: every crossed tetrahedron split along the plane into
///    sub-tetrahedra (1|3 nodes: a tetrahedron and a prism of 3; 2|2: two prisms of 3);
///  - element splitting with node snapping: crossings within 20 % of an edge from a node moved
///    to the node before splitting (fewer slivers, the cut moved);
///  - element deletion: every crossed tetrahedron removed.
///
/// Per method: the cut surface's largest distance from the plane in units of h_min (the
/// shortest edge the plane crosses; the bound is h_min/4), the volume (mass) lost, the
/// worst radius ratio (3·r_in/r_circ, 1 for the regular tetrahedron) among the elements the cut
/// made or kept, the slivers (radius ratio < 0.1) it made, and the elements added.
///
/// Usage: stroma_bench_cut_methods SCENARIO [--planes N] [--seed S] [--fixed-clamp] [--markdown]

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include "engine/model.hpp"
#include "scene/compiled_scenario.hpp"
#include "scene/scenario_spec.hpp"
#include "tissue/cut_model.hpp"
#include "tissue/cut_topology.hpp"

using namespace stroma;

namespace {

using P = std::array<double, 3>;

P sub(const P& a, const P& b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
P cross(const P& a, const P& b) { return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]}; }
double dot(const P& a, const P& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
double norm(const P& a) { return std::sqrt(dot(a, a)); }

/// Radius ratio 3·r_in / r_circ of a tetrahedron (0 when degenerate).
double radius_ratio(const P& a, const P& b, const P& c, const P& d) {
  const P u = sub(b, a), v = sub(c, a), w = sub(d, a);
  const double six_v = std::abs(dot(u, cross(v, w)));
  if (six_v <= 0) return 0;
  const double area = 0.5 * (norm(cross(u, v)) + norm(cross(v, w)) + norm(cross(w, u)) + norm(cross(sub(c, b), sub(d, b))));
  const double r_in = 0.5 * six_v / area;  // 3V / S
  const P num = {dot(u, u) * cross(v, w)[0] + dot(v, v) * cross(w, u)[0] + dot(w, w) * cross(u, v)[0],
                 dot(u, u) * cross(v, w)[1] + dot(v, v) * cross(w, u)[1] + dot(w, w) * cross(u, v)[1],
                 dot(u, u) * cross(v, w)[2] + dot(v, v) * cross(w, u)[2] + dot(w, w) * cross(u, v)[2]};
  const double r_circ = norm(num) / (2.0 * six_v);
  return r_circ > 0 ? 3.0 * r_in / r_circ : 0;
}

double volume(const P& a, const P& b, const P& c, const P& d) {
  return std::abs(dot(sub(b, a), cross(sub(c, a), sub(d, a)))) / 6.0;
}

struct Figures {
  double deviation = 0;  ///< max distance of the cut surface from the plane / h_min
  double volume_lost = 0;  ///< fraction of the body's volume
  double worst_ratio = 1;  ///< among the elements made (or kept, for copies)
  long slivers = 0, added = 0;
};

/// One plane: n·x = c.
struct Plane {
  P n;
  double c;
  double dist(const P& x) const { return dot(n, x) - c; }
};

/// The prism (bottom a0 a1 a2, top b0 b1 b2, ai joined to bi) as three tetrahedra.
void prism(const P& a0, const P& a1, const P& a2, const P& b0, const P& b1, const P& b2, std::vector<std::array<P, 4>>& out) {
  out.push_back({a0, a1, a2, b0});
  out.push_back({a1, a2, b0, b1});
  out.push_back({a2, b0, b1, b2});
}

/// The sub-tetrahedra of tetrahedron x split by the plane, cut points at parameter t (from the
/// lower local node) on the crossed edges — snapped to a node when within `snap` of it.
void split(const std::array<P, 4>& x, const Plane& pl, double snap, std::vector<std::array<P, 4>>& out, double& dev,
           double h_min) {
  double d[4];
  for (int i = 0; i < 4; ++i) d[i] = pl.dist(x[i]);
  auto point = [&](int i, int j) {
    double t = d[i] / (d[i] - d[j]);
    if (t < snap) t = 0;
    else if (t > 1 - snap) t = 1;
    P p;
    for (int k = 0; k < 3; ++k) p[k] = (1 - t) * x[i][k] + t * x[j][k];
    dev = std::max(dev, std::abs(pl.dist(p)) / h_min);
    return p;
  };
  std::vector<int> A, B;
  for (int i = 0; i < 4; ++i) (d[i] < 0 ? A : B).push_back(i);
  if (A.size() == 2) {
    const int a = A[0], b = A[1], c = B[0], e = B[1];
    const P pac = point(a, c), pae = point(a, e), pbc = point(b, c), pbe = point(b, e);
    prism(x[a], pac, pae, x[b], pbc, pbe, out);
    prism(x[c], pac, pbc, x[e], pae, pbe, out);
  } else {
    const std::vector<int>& one = A.size() == 1 ? A : B;
    const std::vector<int>& three = A.size() == 1 ? B : A;
    const int a = one[0];
    const P p0 = point(a, three[0]), p1 = point(a, three[1]), p2 = point(a, three[2]);
    out.push_back({x[a], p0, p1, p2});
    prism(x[three[0]], x[three[1]], x[three[2]], p0, p1, p2, out);
  }
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Cutting methods compared on one mesh: virtual nodes, splitting (with and without snapping), deletion"};
  std::string scenario;
  int planes = 100;
  unsigned seed = 1;
  bool markdown = false, fixed_clamp = false;
  app.add_flag("--fixed-clamp", fixed_clamp, "virtual nodes with the old clamp (5 % of every edge) instead of the per-edge one");
  app.add_option("scenario", scenario, "scenario YAML (its first body is cut)")->required();
  app.add_option("--planes", planes, "random planes through the body's middle half")->check(CLI::Range(1, 100000));
  app.add_option("--seed", seed, "random seed");
  app.add_flag("--markdown", markdown, "print Markdown table rows");
  CLI11_PARSE(app, argc, argv);

  const std::shared_ptr<const Model> model = compile_model(load_scenario(scenario));
  const FemModel& fem = model->fem;
  const BodyRange& body = fem.bodies[0];
  const CutBase base = make_cut_base(fem);
  const bool clamp = !fixed_clamp;
  auto X = [&](int32_t n) { return P{fem.rest[3 * n], fem.rest[3 * n + 1], fem.rest[3 * n + 2]}; };
  P lo{1e300, 1e300, 1e300}, hi{-1e300, -1e300, -1e300};
  for (int32_t n = body.node_begin; n < body.node_end; ++n)
    for (int k = 0; k < 3; ++k) {
      lo[k] = std::min(lo[k], X(n)[k]);
      hi[k] = std::max(hi[k], X(n)[k]);
    }
  double total_volume = 0, uncut_worst = 1;
  for (int32_t e = body.element_begin; e < body.element_end; ++e) {
    const Tet& t = base.tets[e];
    total_volume += volume(X(t[0]), X(t[1]), X(t[2]), X(t[3]));
    uncut_worst = std::min(uncut_worst, radius_ratio(X(t[0]), X(t[1]), X(t[2]), X(t[3])));
  }
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u01(0, 1);
  std::normal_distribution<double> g;
  enum { kVna, kSplit, kSnap, kDelete, kMethods };
  std::vector<Figures> worst(kMethods), sum(kMethods);
  std::vector<std::vector<double>> dev(kMethods), lost(kMethods);
  int used = 0;
  double min_share = 1;  // the smallest volume share of a copy (virtual nodes)
  for (int p = 0; p < planes; ++p) {
    Plane pl;
    pl.n = {g(rng), g(rng), g(rng)};
    const double len = norm(pl.n);
    for (double& v : pl.n) v /= len;
    P at;
    for (int k = 0; k < 3; ++k) at[k] = lo[k] + (0.25 + 0.5 * u01(rng)) * (hi[k] - lo[k]);
    pl.c = dot(pl.n, at);
    // Crossed edges and h_min.
    std::vector<double> edge_cut(base.adj.edges.size(), kEdgeUncut);
    double h_min = 1e300;
    for (size_t e = 0; e < base.adj.edges.size(); ++e) {
      const auto [a, b] = base.adj.edges[e];
      if (a < body.node_begin || a >= body.node_end) continue;
      const double da = pl.dist(X(a)), db = pl.dist(X(b));
      if ((da < 0) == (db < 0)) continue;
      edge_cut[e] = std::clamp(da / (da - db), clamp ? base.min_fraction[e] : kCutMinFraction,
                               1 - (clamp ? base.min_fraction[e] : kCutMinFraction));
      h_min = std::min(h_min, norm(sub(X(b), X(a))));
    }
    if (h_min == 1e300) continue;
    ++used;
    std::vector<Figures> f(kMethods);
    // Virtual nodes.
    const CutTopology topo = build_cut_topology(base.tets, fem.rest, base.adj, edge_cut, base.node_ranges);
    for (const CutVertex& v : topo.vertices) {
      if (v.a == v.b || v.t == 0) continue;
      const P a = X(topo.dof_node[v.a]), b = X(topo.dof_node[v.b]);
      P q;
      for (int k = 0; k < 3; ++k) q[k] = (1 - v.t) * a[k] + v.t * b[k];
      f[kVna].deviation = std::max(f[kVna].deviation, std::abs(pl.dist(q)) / h_min);
    }
    f[kVna].added = static_cast<long>(topo.copies.size() - base.tets.size());
    for (const ElementCopy& c : topo.copies) min_share = std::min(min_share, c.fraction);
    // Splitting, deletion: per crossed tetrahedron.
    for (int32_t e = body.element_begin; e < body.element_end; ++e) {
      const Tet& t = base.tets[e];
      const std::array<P, 4> x{X(t[0]), X(t[1]), X(t[2]), X(t[3])};
      int neg = 0;
      for (const P& q : x) neg += pl.dist(q) < 0;
      if (neg == 0 || neg == 4) continue;
      f[kVna].worst_ratio = std::min(f[kVna].worst_ratio, radius_ratio(x[0], x[1], x[2], x[3]));  // copies keep it
      for (int m : {kSplit, kSnap}) {
        std::vector<std::array<P, 4>> sub_tets;
        split(x, pl, m == kSnap ? 0.2 : 0.0, sub_tets, f[m].deviation, h_min);
        long made = 0;
        for (const auto& s : sub_tets) {
          if (volume(s[0], s[1], s[2], s[3]) <= 1e-18 * total_volume) continue;  // collapsed by a snap
          ++made;
          const double r = radius_ratio(s[0], s[1], s[2], s[3]);
          f[m].worst_ratio = std::min(f[m].worst_ratio, r);
          f[m].slivers += r < 0.1;
        }
        f[m].added += made - 1;
      }
      f[kDelete].volume_lost += volume(x[0], x[1], x[2], x[3]) / total_volume;
      f[kDelete].added -= 1;
      for (const P& q : x) f[kDelete].deviation = std::max(f[kDelete].deviation, std::abs(pl.dist(q)) / h_min);
    }
    f[kDelete].worst_ratio = uncut_worst;
    for (int m = 0; m < kMethods; ++m) {
      dev[m].push_back(f[m].deviation);
      lost[m].push_back(f[m].volume_lost);
      worst[m].deviation = std::max(worst[m].deviation, f[m].deviation);
      worst[m].volume_lost = std::max(worst[m].volume_lost, f[m].volume_lost);
      worst[m].worst_ratio = std::min(worst[m].worst_ratio, f[m].worst_ratio);
      sum[m].slivers += f[m].slivers;
      sum[m].added += f[m].added;
    }
  }
  const char* names[kMethods] = {"virtual nodes (Stroma)", "splitting, no snapping", "splitting, snap 20 %",
                                 "deleting crossed elements"};
  auto med = [](std::vector<double> v) {
    std::sort(v.begin(), v.end());
    return v.empty() ? 0.0 : v[v.size() / 2];
  };
  if (!markdown)
    fmt::print("{}: {} tets, {} random planes (uncut worst radius ratio {:.3f}; smallest copy: {:.2e} of its tetrahedron)\n",
               scenario, body.element_end - body.element_begin, used, uncut_worst, min_share);
  for (int m = 0; m < kMethods; ++m) {
    const double per = used ? 1.0 / used : 0;
    if (markdown)
      fmt::print("| {} | {:.3f} / {:.3f} | {:.2f} / {:.2f} % | {:.3f} | {:.1f} | {:+.1f} |\n", names[m], med(dev[m]),
                 worst[m].deviation, 100 * med(lost[m]), 100 * worst[m].volume_lost, worst[m].worst_ratio,
                 sum[m].slivers * per, sum[m].added * per);
    else
      fmt::print("  {:28s} deviation/h_min median {:.3f} max {:.3f}; volume lost median {:.2f} % max {:.2f} %; "
                 "worst radius ratio {:.3f}; slivers per cut {:.1f}; elements added per cut {:+.1f}\n",
                 names[m], med(dev[m]), worst[m].deviation, 100 * med(lost[m]), 100 * worst[m].volume_lost,
                 worst[m].worst_ratio, sum[m].slivers * per, sum[m].added * per);
  }
  return 0;
}
