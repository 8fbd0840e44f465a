/// \file mesh_quality.cpp
/// Element quality measures (see mesh_quality.hpp).

#include "tissue/mesh_quality.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <utility>
#include <vector>

#include <fmt/format.h>

namespace stroma {
namespace {

Vec3 sub(const Vec3& a, const Vec3& b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
Vec3 cross(const Vec3& a, const Vec3& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
double dot(const Vec3& a, const Vec3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
double norm(const Vec3& a) { return std::sqrt(dot(a, a)); }

void add(Histogram& h, double v) {
  const int n = int(h.counts.size());
  int b = int(std::floor((v - h.lo) / (h.hi - h.lo) * n));
  b = std::clamp(b, 0, n - 1);
  ++h.counts[size_t(b)];
}

}  // namespace

double tet_radius_ratio(const Vec3& p0, const Vec3& p1, const Vec3& p2, const Vec3& p3) {
  const Vec3 a = sub(p1, p0), b = sub(p2, p0), c = sub(p3, p0);
  const double six_v = dot(a, cross(b, c));
  if (!(std::abs(six_v) > 0)) return 0.0;
  // Circumradius: |a|^2 (b x c) + |b|^2 (c x a) + |c|^2 (a x b) = 2 * 6V * (circumcentre - p0).
  const Vec3 bc = cross(b, c), ca = cross(c, a), ab = cross(a, b);
  const double la = dot(a, a), lb = dot(b, b), lc = dot(c, c);
  const Vec3 num = {la * bc[0] + lb * ca[0] + lc * ab[0], la * bc[1] + lb * ca[1] + lc * ab[1],
                    la * bc[2] + lb * ca[2] + lc * ab[2]};
  const double R = norm(num) / (2.0 * std::abs(six_v));
  // Inradius: 3V / total face area.
  const double area = 0.5 * (norm(cross(a, b)) + norm(cross(b, c)) + norm(cross(c, a)) +
                             norm(cross(sub(p2, p1), sub(p3, p1))));
  const double r = 0.5 * std::abs(six_v) / area;  // 3 * (|6V|/6) / area
  return std::clamp(3.0 * r / R, 0.0, 1.0);
}

std::array<double, 6> tet_dihedral_angles_deg(const Vec3& p0, const Vec3& p1, const Vec3& p2, const Vec3& p3) {
  const Vec3 p[4] = {p0, p1, p2, p3};
  // Outward-or-inward consistent face normals: face i is opposite vertex i; orient each towards
  // its opposite vertex (inward), then the dihedral at an edge is pi - angle(n_i, n_j).
  Vec3 n[4];
  for (int i = 0; i < 4; ++i) {
    const Vec3& a = p[(i + 1) % 4];
    const Vec3& b = p[(i + 2) % 4];
    const Vec3& c = p[(i + 3) % 4];
    Vec3 v = cross(sub(b, a), sub(c, a));
    if (dot(v, sub(p[i], a)) < 0) v = {-v[0], -v[1], -v[2]};
    const double l = norm(v);
    n[i] = l > 0 ? Vec3{v[0] / l, v[1] / l, v[2] / l} : Vec3{0, 0, 0};
  }
  // Edge (i, j) is shared by the faces opposite the other two vertices k, l.
  static constexpr int kEdges[6][2] = {{0, 1}, {0, 2}, {0, 3}, {1, 2}, {1, 3}, {2, 3}};
  std::array<double, 6> out{};
  for (int e = 0; e < 6; ++e) {
    int kl[2], m = 0;
    for (int v = 0; v < 4; ++v)
      if (v != kEdges[e][0] && v != kEdges[e][1]) kl[m++] = v;
    const double c = std::clamp(dot(n[kl[0]], n[kl[1]]), -1.0, 1.0);
    out[size_t(e)] = 180.0 - std::acos(c) * 180.0 / M_PI;
  }
  return out;
}

namespace {
/// Calls f(length) once per distinct edge.
template <class F>
void for_each_edge_length(const TetMesh& mesh, F f) {
  std::vector<std::pair<int32_t, int32_t>> edges;
  edges.reserve(mesh.tets.size() * 6);
  static constexpr int kPairs[6][2] = {{0, 1}, {0, 2}, {0, 3}, {1, 2}, {1, 3}, {2, 3}};
  for (const Tet& t : mesh.tets)
    for (const auto& p : kPairs) edges.emplace_back(std::minmax(t[size_t(p[0])], t[size_t(p[1])]));
  std::sort(edges.begin(), edges.end());
  edges.erase(std::unique(edges.begin(), edges.end()), edges.end());
  for (const auto& [a, b] : edges) {
    const Vec3 d = sub(mesh.nodes[size_t(a)], mesh.nodes[size_t(b)]);
    f(std::sqrt(dot(d, d)));
  }
}
}  // namespace

double mean_edge_length(const TetMesh& mesh) {
  double sum = 0;
  int64_t n = 0;
  for_each_edge_length(mesh, [&](double l) { sum += l, ++n; });
  return n ? sum / double(n) : 0.0;
}

MeshQuality measure_mesh_quality(const TetMesh& mesh, double sliver_angle_deg) {
  MeshQuality q;
  {
    double sum = 0;
    int64_t n = 0;
    q.edge_min = mesh.tets.empty() ? 0.0 : std::numeric_limits<double>::infinity();
    for_each_edge_length(mesh, [&](double l) {
      sum += l, ++n;
      q.edge_min = std::min(q.edge_min, l);
      q.edge_max = std::max(q.edge_max, l);
    });
    q.edge_mean = n ? sum / double(n) : 0.0;
  }
  q.nodes = int64_t(mesh.nodes.size());
  q.tets = int64_t(mesh.tets.size());
  q.sliver_angle_deg = sliver_angle_deg;
  q.radius_ratio = Histogram{0, 1, std::vector<int64_t>(20, 0)};
  q.dihedral = Histogram{0, 180, std::vector<int64_t>(18, 0)};
  q.radius_ratio_min = q.tets ? 1.0 : 0.0;
  q.dihedral_min_deg = q.tets ? 180.0 : 0.0;
  std::map<int32_t, RegionVolume> regions;
  double rr_sum = 0;
  for (size_t t = 0; t < mesh.tets.size(); ++t) {
    const Tet& e = mesh.tets[t];
    const Vec3 &a = mesh.nodes[size_t(e[0])], &b = mesh.nodes[size_t(e[1])], &c = mesh.nodes[size_t(e[2])],
               &d = mesh.nodes[size_t(e[3])];
    const double vol = dot(sub(b, a), cross(sub(c, a), sub(d, a))) / 6.0;
    if (!(vol > 0)) ++q.inverted;
    const double rr = tet_radius_ratio(a, b, c, d);
    rr_sum += rr;
    q.radius_ratio_min = std::min(q.radius_ratio_min, rr);
    q.radius_ratio_max = std::max(q.radius_ratio_max, rr);
    add(q.radius_ratio, rr);
    const auto ang = tet_dihedral_angles_deg(a, b, c, d);
    double lo = 180;
    for (double x : ang) {
      add(q.dihedral, x);
      lo = std::min(lo, x);
      q.dihedral_max_deg = std::max(q.dihedral_max_deg, x);
    }
    q.dihedral_min_deg = std::min(q.dihedral_min_deg, lo);
    if (lo < sliver_angle_deg) ++q.slivers;
    const int32_t tag = mesh.tet_tags.empty() ? 0 : mesh.tet_tags[t];
    RegionVolume& r = regions[tag];
    r.tag = tag;
    ++r.tets;
    r.volume += std::abs(vol);
    q.total_volume += std::abs(vol);
  }
  q.radius_ratio_mean = q.tets ? rr_sum / double(q.tets) : 0.0;
  for (auto& [tag, r] : regions) {
    for (const auto& [t, name] : mesh.tag_names)
      if (t == tag) r.name = name;
    q.regions.push_back(r);
  }
  return q;
}

std::string format_mesh_quality(const MeshQuality& q) {
  std::string s = fmt::format("  {} tetrahedra, {} nodes\n", q.tets, q.nodes);
  s += fmt::format("  radius ratio   min {:.3f}  mean {:.3f}  max {:.3f}\n", q.radius_ratio_min, q.radius_ratio_mean,
                   q.radius_ratio_max);
  s += fmt::format("  dihedral angle min {:.2f} deg  max {:.2f} deg\n", q.dihedral_min_deg, q.dihedral_max_deg);
  s += fmt::format("  edge length    min {:.4g}  mean {:.4g}  max {:.4g}\n", q.edge_min, q.edge_mean, q.edge_max);
  s += fmt::format("  slivers (a dihedral angle < {:g} deg): {}   inverted: {}\n", q.sliver_angle_deg, q.slivers, q.inverted);
  auto bar = [](const Histogram& h, const char* unit, int prec) {
    std::string out;
    int64_t mx = 1;
    for (int64_t c : h.counts) mx = std::max(mx, c);
    const double w = (h.hi - h.lo) / double(h.counts.size());
    for (size_t i = 0; i < h.counts.size(); ++i) {
      if (h.counts[i] == 0) continue;
      out += fmt::format("    [{:>6.{}f}, {:>6.{}f}){} {:>8}  {}\n", h.lo + w * double(i), prec, h.lo + w * double(i + 1), prec,
                         unit, h.counts[i], std::string(size_t(std::ceil(40.0 * double(h.counts[i]) / double(mx))), '#'));
    }
    return out;
  };
  s += "  radius ratio histogram:\n" + bar(q.radius_ratio, "", 2);
  s += "  dihedral angle histogram (6 per element):\n" + bar(q.dihedral, " deg", 0);
  s += "  regions:\n";
  for (const RegionVolume& r : q.regions) {
    s += fmt::format("    {:>4} {:<12} {:>7} tets  {:.6g} m^3", r.tag, r.name.empty() ? "-" : r.name, r.tets, r.volume);
    if (std::isfinite(r.input_volume))
      s += fmt::format("  (input {:.6g} m^3, {:+.2f} %)", r.input_volume, 100.0 * r.relative_error());
    s += "\n";
  }
  if (std::isfinite(q.hausdorff))
    s += fmt::format("  surface deviation (Hausdorff) {:.4g} m  [{}]\n", q.hausdorff, q.hausdorff_reference);
  return s;
}

}  // namespace stroma
