/// \file surface_mesher.cpp
/// A closed triangle surface to a tetrahedral mesh (CGAL Mesh_3 on a polyhedral domain with its
/// sharp edges protected). See mesher.hpp.

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Mesh_complex_3_in_triangulation_3.h>
#include <CGAL/Mesh_triangulation_3.h>
#include <CGAL/Polygon_mesh_processing/measure.h>
#include <CGAL/Polygon_mesh_processing/orientation.h>
#include <CGAL/Polygon_mesh_processing/repair_self_intersections.h>
#include <CGAL/Polygon_mesh_processing/self_intersections.h>
#include <CGAL/Polyhedral_mesh_domain_with_features_3.h>
#include <CGAL/Surface_mesh.h>

#include <cmath>

#include "tissue/input_error.hpp"
#include "tissue/mesh_prepare.hpp"
#include "tissue/meshing/hausdorff.hpp"
#include "tissue/meshing/mesh_3_pipeline.hpp"
#include "io/surface_check.hpp"

namespace stroma::meshing {
namespace {

using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using SM = CGAL::Surface_mesh<K::Point_3>;
using Domain = CGAL::Polyhedral_mesh_domain_with_features_3<K, SM>;
using Tr = CGAL::Mesh_triangulation_3<Domain, CGAL::Default, CGAL::Sequential_tag>::type;
using C3t3 = CGAL::Mesh_complex_3_in_triangulation_3<Tr, Domain::Corner_index, Domain::Curve_index>;
namespace PMP = CGAL::Polygon_mesh_processing;

}  // namespace

MeshingResult mesh_surface(const SurfaceMesh& input, double scale, const MeshingOptions& options) {
  const std::string& src = input.source;
  detail::check_options(src, options);
  if (!(scale > 0) || !std::isfinite(scale)) throw InputError(src, 0, "--scale", fmt::format("{} is not > 0", scale));
  if (input.triangles.size() < 4) throw InputError(src, 0, "", fmt::format("{} triangles: a closed surface has at least 4", input.triangles.size()));
  SurfaceMesh s = input;
  for (Vec3& v : s.vertices)
    for (double& x : v) x *= scale;
  const SurfaceDefects defects = find_surface_defects(s);
  if (!defects.empty())
    throw InputError(src, 0, "", "not the closed, manifold boundary of a volume; nothing written:" + describe_surface_defects(s, defects));

  SM sm;
  std::vector<SM::Vertex_index> vi;
  vi.reserve(s.vertices.size());
  for (const Vec3& v : s.vertices) vi.push_back(sm.add_vertex(K::Point_3(v[0], v[1], v[2])));
  for (const Tri& t : s.triangles) {
    if (sm.add_face(vi[size_t(t[0])], vi[size_t(t[1])], vi[size_t(t[2])]) == SM::null_face()) {
      // Manifold edges traversed the same way by both neighbours: flip-inconsistent orientation.
      throw InputError(src, 0, "", fmt::format("triangles are not consistently oriented (triangle {} runs an edge the same "
                                               "way as its neighbour); nothing written. Re-orient the surface (MeshLab: "
                                               "'Re-Orient all faces coherently')", &t - s.triangles.data()));
    }
  }
  MeshingResult r;
  auto intersecting = [&] {
    std::vector<std::pair<SM::Face_index, SM::Face_index>> pairs;
    PMP::self_intersections(sm, std::back_inserter(pairs));
    return pairs;
  };
  std::vector<std::pair<SM::Face_index, SM::Face_index>> pairs;
  {
    detail::StageTicker t(options, r, "check self-intersections");
    pairs = intersecting();
  }
  if (!pairs.empty() && options.repair_self_intersections) {
    detail::StageTicker t(options, r, fmt::format("repair {} self-intersecting triangle pairs (CGAL)", pairs.size()));
    const size_t before = pairs.size();
    PMP::experimental::remove_self_intersections(sm, PMP::parameters::preserve_genus(true));
    sm.collect_garbage();
    pairs = intersecting();
    if (pairs.empty()) {
      r.notes.push_back(fmt::format("repaired {} self-intersecting triangle pairs (CGAL's remove_self_intersections: the "
                                    "triangles around them were removed and the holes refilled)", before));
      s.vertices.clear();
      s.triangles.clear();
      for (auto v : sm.vertices()) s.vertices.push_back({sm.point(v).x(), sm.point(v).y(), sm.point(v).z()});
      for (auto f : sm.faces()) {
        Tri t;
        int k = 0;
        for (auto v : CGAL::vertices_around_face(sm.halfedge(f), sm)) t[size_t(k++)] = int32_t(v);
        s.triangles.push_back(t);
      }
      const SurfaceDefects after = find_surface_defects(s);
      if (!after.empty())
        throw InputError(src, 0, "--repair", "repairing the self-intersections left the surface open or non-manifold; "
                                             "nothing written:" + describe_surface_defects(s, after));
    }
  }
  if (!pairs.empty()) {
    std::string m = fmt::format("the surface intersects itself ({} pairs of triangles{}); nothing written:", pairs.size(),
                                options.repair_self_intersections ? ", after CGAL's repair" : "");
    for (size_t i = 0; i < std::min<size_t>(pairs.size(), 8); ++i) {
      const auto [f, g] = pairs[i];
      double c[3] = {0, 0, 0};
      for (auto v : CGAL::vertices_around_face(sm.halfedge(f), sm)) {
        c[0] += sm.point(v).x() / 3;
        c[1] += sm.point(v).y() / 3;
        c[2] += sm.point(v).z() / 3;
      }
      m += fmt::format("\n    triangles {} and {} near ({:.6g}, {:.6g}, {:.6g})", size_t(f), size_t(g), c[0], c[1], c[2]);
    }
    if (pairs.size() > 8) m += fmt::format("\n    ... and {} more", pairs.size() - 8);
    if (!options.repair_self_intersections)
      m += "\n  --repair lets CGAL remove and refill the triangles around them (small local folds), or fix the surface "
           "in MeshLab or Blender";
    throw InputError(src, 0, "", m);
  }
  PMP::orient_to_bound_a_volume(sm);
  const double volume = CGAL::to_double(PMP::volume(sm));
  Domain domain(sm);
  if (options.feature_angle_deg > 0) domain.detect_features(options.feature_angle_deg);
  auto refine = [&](double H) {
    const double d = options.facet_distance > 0 ? options.facet_distance : H / 40.0;
    return detail::refine_only<C3t3>(domain, H, d, options.feature_angle_deg > 0 ? H : 0.0);
  };
  C3t3 c3t3 = detail::optimise_to_bound(detail::refine_to_size<C3t3>(refine, volume, options, r), domain, refine, options, r);
  const double H = r.size;
  r.mesh = detail::export_tets(c3t3, [](auto) { return int32_t(1); });
  if (options.fit_boundary && options.feature_angle_deg <= 0) {  // protected edges stay where CGAL put them
    detail::StageTicker t(options, r, "fit boundary");
    const auto inside = domain.is_in_domain_object();
    const double d = options.facet_distance > 0 ? options.facet_distance : r.size / 40.0;
    r.fit = fit_boundary_to_surface(
        r.mesh, [&](const Vec3& p) { return inside(K::Point_3(p[0], p[1], p[2])) ? int32_t(1) : int32_t(0); },
        4.0 * d, options.min_dihedral_deg + 1.0);
  }
  r.mesh.source = src;
  r.mesh.tag_names = {{1, "volume"}};
  if (r.mesh.tets.empty())
    throw InputError(src, 0, "--size", fmt::format("{:g} produced no tetrahedra: the size is larger than the shape", H));
  {
    detail::StageTicker t(options, r, "measure quality");
    r.quality = measure_mesh_quality(r.mesh, options.sliver_angle_deg);
    r.quality.regions.at(0).input_volume = volume;
    const std::vector<Tri> boundary = extract_boundary(r.mesh.tets);
    r.quality.hausdorff = symmetric_hausdorff(r.mesh.nodes, boundary, s.vertices, s.triangles, H / 4);
    r.quality.hausdorff_reference = "the input surface";
  }
  return r;
}

}  // namespace stroma::meshing
