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

/// Refines and optimises. `edge_size` > 0 adds CGAL's criterion for protected feature edges.
template <class C3t3, class Domain>
C3t3 refine_and_optimise(const Domain& domain, double H, double facet_distance, double edge_size,
                         const MeshingOptions& o, MeshingResult& r) {
  namespace P = CGAL::parameters;
  using Tr = typename C3t3::Triangulation;
  using Criteria = CGAL::Mesh_criteria_3<Tr>;
  CGAL::get_default_random() = CGAL::Random(o.seed);
  const double cell_size = H * 0.6123724356957945;   // sqrt(6)/4: circumradius of a regular tet of edge H
  const double facet_size = H * 0.5773502691896258;  // 1/sqrt(3): circumradius of an equilateral triangle
  Criteria criteria = edge_size > 0
      ? Criteria(P::edge_size = edge_size, P::facet_angle = 25, P::facet_size = facet_size,
                 P::facet_distance = facet_distance, P::cell_radius_edge_ratio = 3, P::cell_size = cell_size)
      : Criteria(P::facet_angle = 25, P::facet_size = facet_size, P::facet_distance = facet_distance,
                 P::cell_radius_edge_ratio = 3, P::cell_size = cell_size);
  C3t3 c3t3;
  {
    StageTicker t(o, r, "refine (Delaunay)");
    c3t3 = CGAL::make_mesh_3<C3t3>(domain, criteria, P::no_perturb(), P::no_exude(), P::no_odt(), P::no_lloyd());
  }
  optimise(c3t3, domain, o, r);
  return c3t3;
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

}  // namespace stroma::meshing::detail
