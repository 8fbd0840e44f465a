#include "tissue/mesh_prepare.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <unordered_map>

#include <fmt/format.h>

#include "tissue/input_error.hpp"

namespace stroma {

double signed_volume(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d) {
  const double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
  const double v[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
  const double w[3] = {d[0] - a[0], d[1] - a[1], d[2] - a[2]};
  return (u[0] * (v[1] * w[2] - v[2] * w[1]) - u[1] * (v[0] * w[2] - v[2] * w[0]) +
          u[2] * (v[0] * w[1] - v[1] * w[0])) / 6.0;
}

namespace {

double longest_edge(const TetMesh& m, const Tet& t) {
  double l2 = 0;
  for (int i = 0; i < 4; ++i)
    for (int j = i + 1; j < 4; ++j) {
      const Vec3& a = m.nodes[t[i]];
      const Vec3& b = m.nodes[t[j]];
      const double d = (a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) +
                       (a[2] - b[2]) * (a[2] - b[2]);
      l2 = std::max(l2, d);
    }
  return std::sqrt(l2);
}

}  // namespace

std::vector<Tri> extract_boundary(const std::vector<Tet>& tets) {
  // Outward faces of a positively oriented tet (a, b, c, d).
  static constexpr int kFaces[4][3] = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
  struct Entry {
    Tri face;
    int count;
  };
  auto key = [](Tri f) {
    std::sort(f.begin(), f.end());
    return (static_cast<uint64_t>(f[0]) << 42) ^ (static_cast<uint64_t>(f[1]) << 21) ^
           static_cast<uint64_t>(f[2]);
  };
  std::unordered_map<uint64_t, Entry> faces;
  faces.reserve(tets.size() * 4);
  std::vector<uint64_t> order;  // first-seen order, so the output is deterministic
  order.reserve(tets.size() * 4);
  for (const Tet& t : tets)
    for (const auto& f : kFaces) {
      const Tri tri{t[f[0]], t[f[1]], t[f[2]]};
      const uint64_t k = key(tri);
      auto [it, inserted] = faces.try_emplace(k, Entry{tri, 0});
      if (inserted) order.push_back(k);
      ++it->second.count;
    }
  std::vector<Tri> out;
  for (uint64_t k : order) {
    const Entry& e = faces.at(k);
    if (e.count == 1) out.push_back(e.face);
  }
  return out;
}

PreparedMesh prepare_mesh(TetMesh mesh, double degenerate_ratio) {
  if (mesh.tets.empty())
    throw InputError(mesh.source, 0, "", "mesh has no tetrahedra");
  const int32_t n = static_cast<int32_t>(mesh.nodes.size());
  PreparedMesh out;
  std::vector<char> used(mesh.nodes.size(), 0);
  for (size_t e = 0; e < mesh.tets.size(); ++e) {
    Tet& t = mesh.tets[e];
    for (int k = 0; k < 4; ++k) {
      if (t[k] < 0 || t[k] >= n)
        throw InputError(mesh.source, 0, "",
                         fmt::format("tetrahedron {} (element {} in the file) references node {} "
                                     "but the mesh has {} nodes",
                                     e, e + 1, t[k], n));
      used[t[k]] = 1;
    }
    if (t[0] == t[1] || t[0] == t[2] || t[0] == t[3] || t[1] == t[2] || t[1] == t[3] ||
        t[2] == t[3])
      throw InputError(mesh.source, 0, "",
                       fmt::format("degenerate tetrahedron {} (element {} in the file): repeated "
                                   "node in [{}, {}, {}, {}]",
                                   e, e + 1, t[0], t[1], t[2], t[3]));
    const double v = signed_volume(mesh.nodes[t[0]], mesh.nodes[t[1]], mesh.nodes[t[2]],
                                   mesh.nodes[t[3]]);
    const double l = longest_edge(mesh, t);
    // A zero longest edge (every node at one point) must not pass as 0 >= 0, nor an l³ that
    // underflows: the element's inverse rest shape would be infinite.
    const double l3 = l * l * l;
    if (!(l3 >= std::numeric_limits<double>::min()) || !(std::fabs(v) >= degenerate_ratio * l3) || !std::isfinite(v))
      throw InputError(mesh.source, 0, "",
                       fmt::format("degenerate tetrahedron {} (element {} in the file): volume "
                                   "{:.3g} is below {:.1g} x (longest edge {:.3g})^3",
                                   e, e + 1, v, degenerate_ratio, l));
    if (v < 0) {
      std::swap(t[2], t[3]);
      out.reoriented.push_back(static_cast<int32_t>(e));
    }
  }
  for (int32_t i = 0; i < n; ++i)
    if (!used[i]) out.unused_nodes.push_back(i);
  out.boundary = extract_boundary(mesh.tets);
  out.mesh = std::move(mesh);
  return out;
}

}  // namespace stroma
