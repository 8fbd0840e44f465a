/// \file hausdorff.cpp
/// Sampled symmetric Hausdorff distance through CGAL's AABB tree (see hausdorff.hpp).

#include "tissue/meshing/hausdorff.hpp"

#include <CGAL/AABB_traits.h>
#include <CGAL/AABB_tree.h>
#include <CGAL/AABB_triangle_primitive.h>
#include <CGAL/Simple_cartesian.h>

#include <algorithm>
#include <cmath>

namespace stroma::meshing {
namespace {

using K = CGAL::Simple_cartesian<double>;
using Triangle = K::Triangle_3;
using Iterator = std::vector<Triangle>::const_iterator;
using Primitive = CGAL::AABB_triangle_primitive<K, Iterator>;
using Tree = CGAL::AABB_tree<CGAL::AABB_traits<K, Primitive>>;

K::Point_3 P(const Vec3& v) { return {v[0], v[1], v[2]}; }

/// Largest distance from samples of surface A to the tree of surface B.
double one_sided(const std::vector<Vec3>& va, const std::vector<Tri>& ta, const Tree& tree, double spacing) {
  double worst2 = 0;
  auto probe = [&](const Vec3& p) { worst2 = std::max(worst2, CGAL::to_double(tree.squared_distance(P(p)))); };
  // Only points of the surface: `va` may hold more (a tet mesh's interior nodes).
  for (const Tri& t : ta) {
    const Vec3 &a = va[size_t(t[0])], &b = va[size_t(t[1])], &c = va[size_t(t[2])];
    double longest = 0;
    for (const auto& [p, q] : {std::pair{&a, &b}, std::pair{&b, &c}, std::pair{&c, &a}})
      longest = std::max(longest, std::hypot((*p)[0] - (*q)[0], (*p)[1] - (*q)[1], (*p)[2] - (*q)[2]));
    const int n = spacing > 0 ? std::clamp(int(std::ceil(longest / spacing)), 2, 64) : 2;
    for (int i = 0; i <= n; ++i)
      for (int j = 0; i + j <= n; ++j) {
        const double u = double(i) / n, w = double(j) / n, s = 1 - u - w;
        probe({s * a[0] + u * b[0] + w * c[0], s * a[1] + u * b[1] + w * c[1], s * a[2] + u * b[2] + w * c[2]});
      }
    probe({(a[0] + b[0] + c[0]) / 3, (a[1] + b[1] + c[1]) / 3, (a[2] + b[2] + c[2]) / 3});
  }
  return std::sqrt(worst2);
}

std::vector<Triangle> triangles(const std::vector<Vec3>& v, const std::vector<Tri>& t) {
  std::vector<Triangle> out;
  out.reserve(t.size());
  for (const Tri& x : t) out.emplace_back(P(v[size_t(x[0])]), P(v[size_t(x[1])]), P(v[size_t(x[2])]));
  return out;
}

}  // namespace

double symmetric_hausdorff(const std::vector<Vec3>& va, const std::vector<Tri>& ta, const std::vector<Vec3>& vb,
                           const std::vector<Tri>& tb, double spacing) {
  if (ta.empty() || tb.empty()) return 0.0 / 0.0;
  const std::vector<Triangle> A = triangles(va, ta), B = triangles(vb, tb);
  Tree tree_a(A.begin(), A.end()), tree_b(B.begin(), B.end());
  tree_a.accelerate_distance_queries();
  tree_b.accelerate_distance_queries();
  return std::max(one_sided(va, ta, tree_b, spacing), one_sided(vb, tb, tree_a, spacing));
}

}  // namespace stroma::meshing
