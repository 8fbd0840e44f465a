#pragma once
/// \file mesh_3_pipeline.hpp
/// The part of CGAL Mesh_3 meshing that surfaces and images share: criteria from a target edge
/// length, refinement, the three optimisers in CGAL's recommended order (ODT, perturbation,
/// exudation), progress while they run, and the export of the complex to a TetMesh. Templates
/// over CGAL's complex and domain types; included by surface_mesher.cpp and image_mesher.cpp only.

#include <CGAL/Mesh_criteria_3.h>
#include <CGAL/make_mesh_3.h>
#include <CGAL/optimize_mesh_3.h>
#include <CGAL/perturb_mesh_3.h>
#include <CGAL/exude_mesh_3.h>
#include <CGAL/Random.h>

#include <chrono>
#include <condition_variable>
#include <mutex>
#include <thread>
#include <algorithm>
#include <cmath>
#include <unordered_map>

#include <fmt/format.h>

#include "tissue/meshing/mesher.hpp"

namespace stroma::meshing::detail {

/// Throws InputError (naming `source` and the option) for an option out of range.
void check_options(const std::string& source, const MeshingOptions& o);
/// The edge length H that gives about `target` tetrahedra in `volume`.
double size_for_tets(double volume, int64_t target);

/// Reports a stage's start and, every 5 s while it runs, its elapsed time; records its duration.
class StageTicker {
 public:
  StageTicker(const MeshingOptions& o, MeshingResult& r, std::string name)
      : o_(o), r_(r), name_(std::move(name)), t0_(std::chrono::steady_clock::now()) {
    if (o_.progress) {
      o_.progress(fmt::format("{} ...", name_));
      thread_ = std::thread([this] {
        std::unique_lock<std::mutex> lock(m_);
        while (!cv_.wait_for(lock, std::chrono::seconds(5), [this] { return done_; }))
          o_.progress(fmt::format("{} ... {:.0f} s", name_, seconds()));
      });
    }
  }
  ~StageTicker() {
    {
      std::lock_guard<std::mutex> lock(m_);
      done_ = true;
    }
    cv_.notify_all();
    if (thread_.joinable()) thread_.join();
    const double s = seconds();
    r_.stage_seconds.emplace_back(name_, s);
    if (o_.progress) o_.progress(fmt::format("{} done in {:.2f} s", name_, s));
  }
  double seconds() const {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0_).count();
  }

 private:
  const MeshingOptions& o_;
  MeshingResult& r_;
  std::string name_;
  std::chrono::steady_clock::time_point t0_;
  std::mutex m_;
  std::condition_variable cv_;
  bool done_ = false;
  std::thread thread_;
};

/// CGAL's optimisers in their recommended order: ODT smoothing, sliver perturbation, sliver
/// exudation, each bounded by `max_seconds_per_optimiser`, the last two aiming 5 degrees above
/// `min_dihedral_deg` (what they reach falls short of their aim; the bound is then checked).
template <class C3t3, class Domain>
void optimise(C3t3& c3t3, const Domain& domain, const MeshingOptions& o, MeshingResult& r) {
  namespace P = CGAL::parameters;
  const double T = o.max_seconds_per_optimiser;
  {
    StageTicker t(o, r, "optimise (ODT smoothing)");
    CGAL::odt_optimize_mesh_3(c3t3, domain, P::time_limit = T, P::max_iteration_number = 20, P::freeze_bound = 0.01);
  }
  {
    StageTicker t(o, r, "perturb slivers");
    CGAL::perturb_mesh_3(c3t3, domain, P::time_limit = T, P::sliver_bound = o.min_dihedral_deg + 5.0);
  }
  {
    StageTicker t(o, r, "exude slivers");
    CGAL::exude_mesh_3(c3t3, P::time_limit = T, P::sliver_bound = o.min_dihedral_deg + 5.0);
  }
}

/// The complex's cells as a TetMesh (nodes: the complex's vertices in first-use order; tags:
/// subdomain indices mapped through `tag_of`).
template <class C3t3, class TagOf>
TetMesh export_tets(const C3t3& c3t3, TagOf tag_of) {
  TetMesh m;
  std::unordered_map<const void*, int32_t> index;
  for (auto c = c3t3.cells_in_complex_begin(); c != c3t3.cells_in_complex_end(); ++c) {
    Tet t;
    for (int i = 0; i < 4; ++i) {
      const auto v = c->vertex(i);
      auto [it, inserted] = index.emplace(&*v, int32_t(m.nodes.size()));
      if (inserted) {
        const auto& p = v->point();
        m.nodes.push_back({CGAL::to_double(p.x()), CGAL::to_double(p.y()), CGAL::to_double(p.z())});
      }
      t[size_t(i)] = it->second;
    }
    m.tets.push_back(t);
    m.tet_tags.push_back(tag_of(c3t3.subdomain_index(c)));
  }
  return m;
}

/// Delaunay refinement only (no optimiser). `edge_size` > 0 adds CGAL's criterion for
/// protected feature edges.
template <class C3t3, class Domain>
C3t3 refine_only(const Domain& domain, double H, double facet_distance, double edge_size) {
  namespace P = CGAL::parameters;
  using Tr = typename C3t3::Triangulation;
  using Criteria = CGAL::Mesh_criteria_3<Tr>;
  const double cell_size = H * 0.6123724356957945;   // sqrt(6)/4: circumradius of a regular tet of edge H
  const double facet_size = H * 0.5773502691896258;  // 1/sqrt(3): circumradius of an equilateral triangle
  Criteria criteria = edge_size > 0
      ? Criteria(P::edge_size = edge_size, P::facet_angle = 25, P::facet_size = facet_size,
                 P::facet_distance = facet_distance, P::cell_radius_edge_ratio = 3, P::cell_size = cell_size)
      : Criteria(P::facet_angle = 25, P::facet_size = facet_size, P::facet_distance = facet_distance,
                 P::cell_radius_edge_ratio = 3, P::cell_size = cell_size);
  return CGAL::make_mesh_3<C3t3>(domain, criteria, P::no_perturb(), P::no_exude(), P::no_odt(), P::no_lloyd());
}

/// The size control (mesher.hpp): calls `refine(H)` (a refined complex at CGAL size H, seeded
/// from CGAL's random generator reset to `o.seed`) until its mean edge is within 8 % of
/// `o.size`, or its element count within 15 % of `o.target_tets` when `o.size` is 0, at most
/// four times, and returns the closest complex. The first H: `o.size` x 1.4 (CGAL's edges
/// come out ~0.7 H on smooth shapes), or the H for the count in `volume`; then secant steps on
/// log H against the log of the ratio, the slope bounded to what the relation can be (edge ~
/// H, count ~ H^-3).
template <class C3t3, class Refine>
C3t3 refine_to_size(Refine refine, double volume, const MeshingOptions& o, MeshingResult& r) {
  const bool by_edge = o.size > 0;
  const double target = by_edge ? o.size : double(o.target_tets);
  const double tolerance = by_edge ? 0.08 : 0.15;
  constexpr int kMaxPasses = 4;
  r.size_asked = by_edge ? fmt::format("mean edge {:g}", o.size) : fmt::format("{} elements", o.target_tets);
  double H = by_edge ? 1.4 * o.size : size_for_tets(volume, o.target_tets);
  double last_x = 0, last_e = 0, best_e = 0;
  C3t3 best;
  StageTicker ticker(o, r, "refine (Delaunay) to size");
  for (int pass = 1; pass <= kMaxPasses; ++pass) {
    CGAL::get_default_random() = CGAL::Random(o.seed);
    C3t3 c = refine(H);
    const TetMesh m = export_tets(c, [](auto) { return int32_t(0); });
    const double edge = mean_edge_length(m);
    const double got = by_edge ? edge : double(m.tets.size());
    if (!(got > 0)) {  // nothing meshed at this size: the next pass halves it
      if (o.progress) o.progress(fmt::format("size pass {}: CGAL size {:.4g} gave no element", pass, H));
      H *= 0.5;
      continue;
    }
    const double x = std::log(H), e = std::log(got / target);
    if (o.progress)
      o.progress(fmt::format("size pass {}: CGAL size {:.4g} -> {} elements, mean edge {:.4g}", pass, H, m.tets.size(), edge));
    if (r.size_passes == 0 || std::abs(e) < std::abs(best_e)) {
      best = std::move(c);
      best_e = e;
      r.size = H;
    }
    r.size_passes = pass;
    if (std::abs(e) <= std::log1p(tolerance)) break;
    double slope = by_edge ? 1.0 : -3.0;
    if (pass > 1 && std::abs(x - last_x) > 1e-9) {
      const double s = (e - last_e) / (x - last_x);
      slope = by_edge ? std::clamp(s, 0.5, 1.5) : std::clamp(s, -4.5, -1.5);
    }
    last_x = x, last_e = e;
    if (pass < kMaxPasses) H = std::exp(x - e / slope);
  }
  if (r.size_passes == 0) r.size = H;
  if (r.size_passes > 0 && std::abs(best_e) > std::log1p(tolerance))
    r.notes.push_back(fmt::format("the size control came within {:+.0f} % of the {} asked in {} refinements", 100 * std::expm1(best_e),
                                  by_edge ? "mean edge" : "element count", r.size_passes));
  return best;
}

/// The smallest dihedral angle of the complex's cells (degrees).
template <class C3t3>
double smallest_dihedral_deg(const C3t3& c3t3) {
  const TetMesh m = export_tets(c3t3, [](auto) { return int32_t(0); });
  double lo = 180;
  for (const Tet& t : m.tets) {
    const auto a = tet_dihedral_angles_deg(m.nodes[size_t(t[0])], m.nodes[size_t(t[1])], m.nodes[size_t(t[2])], m.nodes[size_t(t[3])]);
    lo = std::min(lo, *std::min_element(a.begin(), a.end()));
  }
  return lo;
}

/// Optimises `c3t3` (refined at `r.size`). CGAL's optimisers guarantee no angle, and on coarse
/// meshes of thin layers (a few elements across) they leave a sliver for about one seed in
/// three; then the same size is refined again from the next seed (o.seed + 7919 k, so still
/// deterministic) and optimised, at most twice more, and the complex with the largest smallest
/// angle is kept.
template <class C3t3, class Domain, class Refine>
C3t3 optimise_to_bound(C3t3 c3t3, const Domain& domain, Refine refine, const MeshingOptions& o, MeshingResult& r) {
  const double bound = std::max(o.min_dihedral_deg, o.sliver_angle_deg);
  optimise(c3t3, domain, o, r);
  double best = smallest_dihedral_deg(c3t3);
  for (int k = 1; k <= 2 && best < bound; ++k) {
    if (o.progress)
      o.progress(fmt::format("smallest dihedral angle {:.2f} deg < {:g}: refining again from seed {}", best, bound,
                             o.seed + 7919u * unsigned(k)));
    CGAL::get_default_random() = CGAL::Random(o.seed + 7919u * unsigned(k));
    C3t3 again = refine(r.size);
    optimise(again, domain, o, r);
    const double angle = smallest_dihedral_deg(again);
    if (angle > best) {
      best = angle;
      c3t3 = std::move(again);
    }
  }
  return c3t3;
}

}  // namespace stroma::meshing::detail
