/// \file surface_check.cpp
/// Topological surface checks (see surface_check.hpp).

#include "io/surface_check.hpp"

#include <algorithm>
#include <cmath>
#include <map>

#include <fmt/format.h>

namespace stroma {

SurfaceDefects find_surface_defects(const SurfaceMesh& s) {
  SurfaceDefects d;
  // Edge use counts: sort (lo, hi, triangle) triples, count runs.
  std::vector<std::array<int32_t, 3>> edges;
  edges.reserve(s.triangles.size() * 3);
  for (size_t t = 0; t < s.triangles.size(); ++t) {
    const Tri& tr = s.triangles[t];
    for (int e = 0; e < 3; ++e) {
      const int32_t a = tr[size_t(e)], b = tr[size_t((e + 1) % 3)];
      edges.push_back({std::min(a, b), std::max(a, b), int32_t(t)});
    }
    const Vec3 &p = s.vertices[size_t(tr[0])], &q = s.vertices[size_t(tr[1])], &r = s.vertices[size_t(tr[2])];
    const double u[3] = {q[0] - p[0], q[1] - p[1], q[2] - p[2]}, v[3] = {r[0] - p[0], r[1] - p[1], r[2] - p[2]};
    const double c[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
    if (!(c[0] * c[0] + c[1] * c[1] + c[2] * c[2] > 0)) d.degenerate_triangles.push_back(int32_t(t));
  }
  std::sort(edges.begin(), edges.end());
  for (size_t i = 0; i < edges.size();) {
    size_t j = i;
    while (j < edges.size() && edges[j][0] == edges[i][0] && edges[j][1] == edges[i][1]) ++j;
    if (j - i == 1) d.boundary_edges.push_back({edges[i][0], edges[i][1]});
    else if (j - i > 2) d.nonmanifold_edges.push_back({edges[i][0], edges[i][1]});
    i = j;
  }
  // Vertex fans: around vertex v, triangles are linked through the edges (v, w) they share; on a
  // manifold closed surface they form one cycle, so one connected component.
  std::vector<std::vector<int32_t>> vt(s.vertices.size());
  for (size_t t = 0; t < s.triangles.size(); ++t)
    for (int32_t v : s.triangles[t]) vt[size_t(v)].push_back(int32_t(t));
  for (size_t v = 0; v < vt.size(); ++v) {
    const auto& ts = vt[v];
    if (ts.size() < 2) continue;
    // Union-find over this vertex's triangles, joined when they share another vertex.
    std::vector<int> parent(ts.size());
    for (size_t i = 0; i < ts.size(); ++i) parent[i] = int(i);
    auto find = [&](int x) {
      while (parent[size_t(x)] != x) x = parent[size_t(x)] = parent[size_t(parent[size_t(x)])];
      return x;
    };
    std::map<int32_t, int> first_with;
    for (size_t i = 0; i < ts.size(); ++i)
      for (int32_t w : s.triangles[size_t(ts[i])]) {
        if (w == int32_t(v)) continue;
        auto [it, inserted] = first_with.emplace(w, int(i));
        if (!inserted) parent[size_t(find(int(i)))] = find(it->second);
      }
    int roots = 0;
    for (size_t i = 0; i < ts.size(); ++i) roots += find(int(i)) == int(i);
    if (roots > 1) d.nonmanifold_vertices.push_back(int32_t(v));
  }
  return d;
}

std::string describe_surface_defects(const SurfaceMesh& s, const SurfaceDefects& d, size_t max_listed) {
  auto pt = [&](int32_t v) {
    const Vec3& p = s.vertices[size_t(v)];
    return fmt::format("#{} ({:.6g}, {:.6g}, {:.6g})", v, p[0], p[1], p[2]);
  };
  std::string m;
  auto list_edges = [&](const std::vector<std::array<int32_t, 2>>& es, const char* what) {
    if (es.empty()) return;
    m += fmt::format("\n  {} {}:", es.size(), what);
    for (size_t i = 0; i < std::min(es.size(), max_listed); ++i) m += fmt::format("\n    edge {} - {}", pt(es[i][0]), pt(es[i][1]));
    if (es.size() > max_listed) m += fmt::format("\n    ... and {} more", es.size() - max_listed);
  };
  list_edges(d.boundary_edges, "boundary edges (used by one triangle: the surface is open, a hole to close)");
  list_edges(d.nonmanifold_edges, "non-manifold edges (used by three or more triangles)");
  if (!d.nonmanifold_vertices.empty()) {
    m += fmt::format("\n  {} non-manifold vertices (surfaces touching at a point):", d.nonmanifold_vertices.size());
    for (size_t i = 0; i < std::min(d.nonmanifold_vertices.size(), max_listed); ++i) m += "\n    vertex " + pt(d.nonmanifold_vertices[i]);
    if (d.nonmanifold_vertices.size() > max_listed) m += fmt::format("\n    ... and {} more", d.nonmanifold_vertices.size() - max_listed);
  }
  if (!d.degenerate_triangles.empty()) {
    m += fmt::format("\n  {} triangles of zero area:", d.degenerate_triangles.size());
    for (size_t i = 0; i < std::min(d.degenerate_triangles.size(), max_listed); ++i) {
      const Tri& t = s.triangles[size_t(d.degenerate_triangles[i])];
      m += fmt::format("\n    triangle {}: {}, {}, {}", d.degenerate_triangles[i], pt(t[0]), pt(t[1]), pt(t[2]));
    }
    if (d.degenerate_triangles.size() > max_listed) m += fmt::format("\n    ... and {} more", d.degenerate_triangles.size() - max_listed);
  }
  return m;
}

}  // namespace stroma
