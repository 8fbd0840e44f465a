#include "tissue/meshing/boundary_fit.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <unordered_map>
#include <vector>

#include "tissue/mesh_quality.hpp"

namespace stroma::meshing {
namespace {

Vec3 sub(const Vec3& a, const Vec3& b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
Vec3 cross(const Vec3& a, const Vec3& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
double dot(const Vec3& a, const Vec3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
Vec3 along(const Vec3& c, const Vec3& n, double t) { return {c[0] + t * n[0], c[1] + t * n[1], c[2] + t * n[2]}; }

double signed_volume(const std::vector<Vec3>& x, const Tet& t) {
  return dot(sub(x[size_t(t[1])], x[size_t(t[0])]),
             cross(sub(x[size_t(t[2])], x[size_t(t[0])]), sub(x[size_t(t[3])], x[size_t(t[0])]))) / 6.0;
}

double smallest_dihedral(const std::vector<Vec3>& x, const Tet& t) {
  const auto a = tet_dihedral_angles_deg(x[size_t(t[0])], x[size_t(t[1])], x[size_t(t[2])], x[size_t(t[3])]);
  return *std::min_element(a.begin(), a.end());
}

struct FaceKey {
  std::array<int32_t, 3> v;
  bool operator==(const FaceKey& o) const { return v == o.v; }
};
struct FaceHash {
  size_t operator()(const FaceKey& k) const {
    return (size_t(uint32_t(k.v[0])) * 73856093u) ^ (size_t(uint32_t(k.v[1])) * 19349663u) ^
           (size_t(uint32_t(k.v[2])) * 83492791u);
  }
};
struct FaceSide {
  int32_t tet = -1, other = -1;
  int corner = 0;  ///< the tet's vertex opposite the face
};

/// Where along c + t n (t in [-search, search]) the region changes from `a` (inside, t < 0
/// side) to `b`; false when it is not found there.
bool surface_offset(const std::function<int32_t(const Vec3&)>& tag_at, const Vec3& c, const Vec3& n, int32_t a,
                    int32_t b, double search, double& t_out) {
  constexpr int kSteps = 16, kBisections = 24;
  const int32_t at_c = tag_at(c);
  if (at_c != a && at_c != b) return false;
  // Walk away from the side the centroid is on (outward from a, inward from b) to the change.
  const double dir = at_c == a ? 1.0 : -1.0;
  const int32_t other = at_c == a ? b : a;
  double prev = 0, hit = 0;
  bool found = false;
  for (int i = 1; i <= kSteps && !found; ++i) {
    const double t = dir * search * i / kSteps;
    const int32_t g = tag_at(along(c, n, t));
    if (g == at_c) {
      prev = t;
      continue;
    }
    if (g != other) return false;
    hit = t, found = true;
  }
  if (!found) return false;
  double lo = at_c == a ? prev : hit, hi = at_c == a ? hit : prev;  // tag a at lo, not a at hi
  for (int i = 0; i < kBisections; ++i) {
    const double m = 0.5 * (lo + hi);
    (tag_at(along(c, n, m)) == a ? lo : hi) = m;
  }
  t_out = 0.5 * (lo + hi);
  return true;
}

}  // namespace

BoundaryFitReport fit_boundary_to_surface(TetMesh& mesh, const std::function<int32_t(const Vec3&)>& tag_at,
                                          double search, double min_dihedral_deg) {
  BoundaryFitReport r;
  const auto tag_of = [&](int32_t t) { return t < 0 ? 0 : (mesh.tet_tags.empty() ? 1 : mesh.tet_tags[size_t(t)]); };
  std::unordered_map<FaceKey, FaceSide, FaceHash> faces;
  faces.reserve(mesh.tets.size() * 3);
  for (int32_t t = 0; t < int32_t(mesh.tets.size()); ++t)
    for (int k = 0; k < 4; ++k) {
      std::array<int32_t, 3> f;
      for (int j = 0, m = 0; j < 4; ++j)
        if (j != k) f[size_t(m++)] = mesh.tets[size_t(t)][size_t(j)];
      std::sort(f.begin(), f.end());
      auto [it, fresh] = faces.try_emplace(FaceKey{f}, FaceSide{t, -1, k});
      if (!fresh) it->second.other = t;
    }

  const size_t n_nodes = mesh.nodes.size();
  std::vector<Vec3> shift_sum(n_nodes, Vec3{0, 0, 0});
  std::vector<double> weight(n_nodes, 0.0);
  std::vector<int64_t> first_pair(n_nodes, -1);  // the (a, b) region pair a vertex's facets separate
  std::vector<char> junction(n_nodes, 0);
  const std::vector<Vec3>& x = mesh.nodes;
  for (const auto& [key, side] : faces) {
    int32_t a = tag_of(side.tet), b = tag_of(side.other);
    if (a == b) continue;
    ++r.facets;
    // Oriented from region a (the tet `side.tet`) to b: away from the opposite vertex.
    const Tet& tet = mesh.tets[size_t(side.tet)];
    const Vec3& p0 = x[size_t(key.v[0])];
    Vec3 n = cross(sub(x[size_t(key.v[1])], p0), sub(x[size_t(key.v[2])], p0));
    const double twice_area = std::sqrt(dot(n, n));
    if (!(twice_area > 0)) continue;
    for (double& c : n) c /= twice_area;
    if (dot(n, sub(x[size_t(tet[size_t(side.corner)])], p0)) > 0)
      for (double& c : n) c = -c;
    const int64_t pair = int64_t(std::min(a, b)) * 65536 + std::max(a, b);
    for (int32_t v : key.v) {
      if (first_pair[size_t(v)] < 0) first_pair[size_t(v)] = pair;
      else if (first_pair[size_t(v)] != pair) junction[size_t(v)] = 1;
    }
    Vec3 c{0, 0, 0};
    for (int32_t v : key.v)
      for (int i = 0; i < 3; ++i) c[size_t(i)] += x[size_t(v)][size_t(i)] / 3.0;
    double s = 0;
    if (!surface_offset(tag_at, c, n, a, b, search, s)) continue;
    ++r.facets_measured;
    const double w = 0.5 * twice_area, move = 0.75 * s;
    for (int32_t v : key.v) {
      for (int i = 0; i < 3; ++i) shift_sum[size_t(v)][size_t(i)] += w * move * n[size_t(i)];
      weight[size_t(v)] += w;
    }
  }

  // Elements around each vertex, to refuse a move that would crush one.
  std::vector<int32_t> start(n_nodes + 1, 0), around;
  for (const Tet& t : mesh.tets)
    for (int32_t v : t) ++start[size_t(v) + 1];
  for (size_t i = 0; i < n_nodes; ++i) start[i + 1] += start[i];
  around.resize(size_t(start[n_nodes]));
  {
    std::vector<int32_t> fill(start.begin(), start.end() - 1);
    for (int32_t t = 0; t < int32_t(mesh.tets.size()); ++t)
      for (int32_t v : mesh.tets[size_t(t)]) around[size_t(fill[size_t(v)]++)] = t;
  }
  for (size_t v = 0; v < n_nodes; ++v) {
    if (!(weight[v] > 0)) continue;
    if (junction[v]) {
      ++r.vertices_kept;
      continue;
    }
    const Vec3 old = mesh.nodes[v];
    std::vector<std::pair<double, double>> before;  // volume, smallest dihedral angle
    for (int32_t i = start[v]; i < start[v + 1]; ++i)
      before.emplace_back(signed_volume(mesh.nodes, mesh.tets[size_t(around[size_t(i)])]),
                          smallest_dihedral(mesh.nodes, mesh.tets[size_t(around[size_t(i)])]));
    const Vec3 d{shift_sum[v][0] / weight[v], shift_sum[v][1] / weight[v], shift_sum[v][2] / weight[v]};
    mesh.nodes[v] = {old[0] + d[0], old[1] + d[1], old[2] + d[2]};
    bool ok = true;
    for (int32_t i = start[v]; i < start[v + 1] && ok; ++i) {
      const Tet& t = mesh.tets[size_t(around[size_t(i)])];
      const double after = signed_volume(mesh.nodes, t);
      const auto [b, angle] = before[size_t(i - start[v])];
      ok = (b > 0 ? after > 0.2 * b : after < 0.2 * b) &&
           smallest_dihedral(mesh.nodes, t) >= std::min(angle, min_dihedral_deg);
    }
    if (!ok) {
      mesh.nodes[v] = old;
      ++r.vertices_kept;
      continue;
    }
    ++r.vertices_moved;
    r.max_shift = std::max(r.max_shift, std::sqrt(dot(d, d)));
  }
  return r;
}

}  // namespace stroma::meshing
