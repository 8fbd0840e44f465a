/// \file visual_mapping.cpp
/// Building and applying the visual-surface mapping (see visual_mapping.hpp).
///
/// locate_point (barycentric.hpp) tries every tetrahedron for every point, which is fine for a
/// few probes but O(vertices × tets) for a surface: 50k vertices into 20k tets would take
/// minutes. Here the tets are binned by bounding box into a uniform grid once; a vertex then
/// tests only the tets of its own cell, and a vertex outside the mesh searches rings of cells
/// outwards until no unvisited cell can hold anything nearer.
#include "tissue/visual_mapping.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "tissue/barycentric.hpp"
#include "tissue/input_error.hpp"
#include "tissue/triangle_closest_point.hpp"

namespace stroma {
namespace {

/// A vertex is inside a tet when its smallest barycentric weight is at least −kInsideTol (the
/// tolerance locate_point uses), so vertices on shared faces are never "outside".
constexpr double kInsideTol = 1e-9;

double dot3(const Vec3& a, const Vec3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
Vec3 sub3(const Vec3& a, const Vec3& b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }

/// Where a point landed: weights on the tet's 4 nodes, the tet, its distance (0 if inside).
struct Location {
  std::array<double, 4> w{};
  int32_t tet = -1;
  double distance = 0;
  bool inside = false;
};

/// Uniform grid over the mesh's bounding box; each cell lists the tets whose (slightly padded)
/// bounding boxes overlap it, so the cell containing a point lists every tet that may contain it.
class TetLocator {
 public:
  explicit TetLocator(const TetMesh& mesh) : mesh_(mesh), box_(mesh.tets.size()) {
    constexpr double kBig = std::numeric_limits<double>::max();
    Vec3 lo{kBig, kBig, kBig}, hi{-kBig, -kBig, -kBig};
    for (size_t e = 0; e < mesh.tets.size(); ++e) {
      auto& b = box_[e];
      b = {kBig, kBig, kBig, -kBig, -kBig, -kBig};
      for (int32_t n : mesh.tets[e])
        for (int a = 0; a < 3; ++a) {
          b[a] = std::min(b[a], mesh.nodes[n][a]);
          b[a + 3] = std::max(b[a + 3], mesh.nodes[n][a]);
        }
      // Padding keeps points that pass the −1e-9 weight tolerance inside the box.
      const double pad = 1e-8 * std::max({b[3] - b[0], b[4] - b[1], b[5] - b[2]});
      for (int a = 0; a < 3; ++a) {
        b[a] -= pad;
        b[a + 3] += pad;
        lo[a] = std::min(lo[a], b[a]);
        hi[a] = std::max(hi[a], b[a + 3]);
      }
    }
    // About one cell per tet, cubic cells; a flat extent still gets a cell of finite size.
    const double diag = std::sqrt(dot3(sub3(hi, lo), sub3(hi, lo)));
    double len[3], vol = 1;
    for (int a = 0; a < 3; ++a) {
      len[a] = std::max(hi[a] - lo[a], 1e-3 * diag + std::numeric_limits<double>::min());
      vol *= len[a];
    }
    const double h = std::cbrt(vol / static_cast<double>(mesh.tets.size()));
    h_min_ = std::numeric_limits<double>::max();
    for (int a = 0; a < 3; ++a) {
      lo_[a] = lo[a];
      n_[a] = static_cast<int>(std::clamp(std::ceil(len[a] / h), 1.0, 256.0));
      h_[a] = len[a] / n_[a];
      h_min_ = std::min(h_min_, h_[a]);
    }
    // Tets per cell in compressed rows: count, prefix-sum, fill.
    start_.assign(static_cast<size_t>(n_[0]) * n_[1] * n_[2] + 1, 0);
    for (int pass = 0; pass < 2; ++pass) {
      if (pass == 1) {
        for (size_t c = 1; c < start_.size(); ++c) start_[c] += start_[c - 1];
        items_.resize(start_.back());
      }
      for (size_t e = 0; e < mesh.tets.size(); ++e) {
        const auto& b = box_[e];
        int c0[3], c1[3];
        for (int a = 0; a < 3; ++a) {
          c0[a] = cell(b[a], a);
          c1[a] = cell(b[a + 3], a);
        }
        for (int k = c0[2]; k <= c1[2]; ++k)
          for (int j = c0[1]; j <= c1[1]; ++j)
            for (int i = c0[0]; i <= c1[0]; ++i) {
              const size_t c = index(i, j, k);
              if (pass == 0)
                ++start_[c + 1];
              else
                items_[start_[c]++] = static_cast<int32_t>(e);
            }
      }
      // The fill advanced each row start to the next row's: shift back.
      if (pass == 1) {
        for (size_t c = start_.size() - 1; c > 0; --c) start_[c] = start_[c - 1];
        start_[0] = 0;
      }
    }
    stamp_.assign(mesh.tets.size(), 0);
  }

  Location locate(const Vec3& p) {
    Location best;
    int c[3];
    for (int a = 0; a < 3; ++a) c[a] = cell(p[a], a);
    // Inside: of the tets whose box holds p, the one with the largest smallest weight (on a
    // shared face both neighbours qualify; either gives the same point).
    double best_min = -std::numeric_limits<double>::max();
    const size_t c_p = index(c[0], c[1], c[2]);
    for (size_t s = start_[c_p]; s < start_[c_p + 1]; ++s) {
      const int32_t e = items_[s];
      if (box_distance2(box_[e].data(), p) > 0) continue;
      const auto w = barycentric_coordinates(mesh_, mesh_.tets[e], p);
      const double mn = std::min({w[0], w[1], w[2], w[3]});
      if (mn > best_min) {
        best_min = mn;
        best.tet = e;
        best.w = w;
      }
    }
    if (best_min >= -kInsideTol) {
      best.inside = true;
      return best;
    }
    // Outside: nearest tet, searching rings of cells (Chebyshev distance r from c) outwards.
    // Any tet not met by ring r − 1 lies in cells at least (r − 1)·h_min further along some
    // axis, and every cell is at least as far as the grid box is from p: together a lower
    // bound that ends the search.
    if (++query_ == 0) {  // wrapped: old stamps could collide
      std::fill(stamp_.begin(), stamp_.end(), 0u);
      query_ = 1;
    }
    double out2 = 0;
    for (int a = 0; a < 3; ++a) {
      const double below = lo_[a] - p[a], above = p[a] - (lo_[a] + n_[a] * h_[a]);
      const double d = std::max({below, above, 0.0});
      out2 += d * d;
    }
    int r_max = 0;
    for (int a = 0; a < 3; ++a) r_max = std::max({r_max, c[a], n_[a] - 1 - c[a]});
    double best_d2 = std::numeric_limits<double>::max();
    for (int r = 0; r <= r_max; ++r) {
      const double gap = std::max(r - 1, 0) * h_min_;
      if (out2 + gap * gap >= best_d2) break;
      const int i0 = std::max(c[0] - r, 0), i1 = std::min(c[0] + r, n_[0] - 1);
      const int j0 = std::max(c[1] - r, 0), j1 = std::min(c[1] + r, n_[1] - 1);
      const int k0 = std::max(c[2] - r, 0), k1 = std::min(c[2] + r, n_[2] - 1);
      // Only the shell of the ring: rows on its j/k faces whole, other rows at their two ends.
      for (int k = k0; k <= k1; ++k)
        for (int j = j0; j <= j1; ++j) {
          if (std::abs(k - c[2]) == r || std::abs(j - c[1]) == r) {
            for (int i = i0; i <= i1; ++i) visit_cell(i, j, k, p, best, best_d2);
          } else {
            if (c[0] - r >= 0) visit_cell(c[0] - r, j, k, p, best, best_d2);
            if (r > 0 && c[0] + r < n_[0]) visit_cell(c[0] + r, j, k, p, best, best_d2);
          }
        }
    }
    best.distance = std::sqrt(best_d2);
    return best;
  }

 private:
  /// Measures p against the tets of cell (i, j, k) not yet measured for this point, unless the
  /// cell (or a tet's box) is already farther than the best so far.
  void visit_cell(int i, int j, int k, const Vec3& p, Location& best, double& best_d2) {
    const double cb[6] = {lo_[0] + i * h_[0],       lo_[1] + j * h_[1],
                          lo_[2] + k * h_[2],       lo_[0] + (i + 1) * h_[0],
                          lo_[1] + (j + 1) * h_[1], lo_[2] + (k + 1) * h_[2]};
    if (box_distance2(cb, p) >= best_d2) return;
    const size_t c = index(i, j, k);
    for (size_t s = start_[c]; s < start_[c + 1]; ++s) {
      const int32_t e = items_[s];
      if (stamp_[e] == query_) continue;
      stamp_[e] = query_;
      if (box_distance2(box_[e].data(), p) >= best_d2) continue;
      std::array<double, 4> w;
      const double d2 = nearest_in_tet(e, p, w);
      if (d2 < best_d2) {
        best_d2 = d2;
        best.tet = e;
        best.w = w;
      }
    }
  }

  int cell(double x, int a) const {
    const double t = std::floor((x - lo_[a]) / h_[a]);
    // Compare in double first: a point far away must not overflow the int conversion.
    if (!(t >= 0)) return 0;
    if (t >= n_[a] - 1) return n_[a] - 1;
    return static_cast<int>(t);
  }
  size_t index(int i, int j, int k) const {
    return static_cast<size_t>(i) +
           static_cast<size_t>(n_[0]) * (j + static_cast<size_t>(n_[1]) * k);
  }
  /// Squared distance from p to box b = {min x, y, z, max x, y, z} (0 inside).
  static double box_distance2(const double* b, const Vec3& p) {
    double d2 = 0;
    for (int a = 0; a < 3; ++a) {
      const double d = std::max({b[a] - p[a], p[a] - b[a + 3], 0.0});
      d2 += d * d;
    }
    return d2;
  }
  /// Squared distance from p (outside tet e) to tet e; w gets the projection's weights. The
  /// nearest point of a tet to an outside point lies on its boundary: the best of the 4 faces.
  double nearest_in_tet(int32_t e, const Vec3& p, std::array<double, 4>& w) const {
    static constexpr int kFaces[4][3] = {{0, 1, 2}, {0, 1, 3}, {0, 2, 3}, {1, 2, 3}};
    const Tet& t = mesh_.tets[e];
    double best = std::numeric_limits<double>::max();
    for (const auto& f : kFaces) {
      const Vec3 &a = mesh_.nodes[t[f[0]]], &b = mesh_.nodes[t[f[1]]], &c = mesh_.nodes[t[f[2]]];
      const auto u = closest_on_triangle(p, a, b, c);
      Vec3 q;
      for (int k = 0; k < 3; ++k) q[k] = u[0] * a[k] + u[1] * b[k] + u[2] * c[k];
      const Vec3 d = sub3(q, p);
      const double d2 = dot3(d, d);
      if (d2 < best) {
        best = d2;
        w = {0, 0, 0, 0};
        for (int k = 0; k < 3; ++k) w[f[k]] = u[k];
      }
    }
    return best;
  }

  const TetMesh& mesh_;
  std::vector<std::array<double, 6>> box_;  // padded bounding box of each tet
  double lo_[3] = {0, 0, 0};
  double h_[3] = {1, 1, 1};
  double h_min_ = 1;
  int n_[3] = {1, 1, 1};
  std::vector<size_t> start_;    // cell c's tets are items_[start_[c] .. start_[c + 1])
  std::vector<int32_t> items_;
  std::vector<uint32_t> stamp_;  // stamp_[e] == query_: tet e already measured for this point
  uint32_t query_ = 0;
};

template <class Out>
void apply_impl(const VisualMapping& m, const double* x, Out* out) {
  const size_t n = m.size();
  for (size_t v = 0; v < n; ++v) {
    const auto& nd = m.node[v];
    const auto& w = m.w[v];
    for (int k = 0; k < 3; ++k)
      out[3 * v + k] = static_cast<Out>(w[0] * x[3 * static_cast<size_t>(nd[0]) + k] +
                                        w[1] * x[3 * static_cast<size_t>(nd[1]) + k] +
                                        w[2] * x[3 * static_cast<size_t>(nd[2]) + k] +
                                        w[3] * x[3 * static_cast<size_t>(nd[3]) + k]);
  }
}

}  // namespace

void VisualMapping::apply(const double* x, double* out) const { apply_impl(*this, x, out); }
void VisualMapping::apply(const double* x, float* out) const { apply_impl(*this, x, out); }

void VisualMapping::apply_transpose(const double* f_visual, double* f_nodes) const {
  const size_t n = size();
  for (size_t v = 0; v < n; ++v)
    for (int i = 0; i < 4; ++i) {
      double* f = f_nodes + 3 * static_cast<size_t>(node[v][i]);
      for (int k = 0; k < 3; ++k) f[k] += w[v][i] * f_visual[3 * v + k];
    }
}

VisualMapping build_visual_mapping(const TetMesh& mesh, const std::vector<Vec3>& vertices,
                                   double max_distance, int32_t node_offset, int32_t tet_offset,
                                   const std::string& source) {
  if (mesh.tets.empty())
    throw InputError(source, 0, "",
                     fmt::format("cannot map the surface onto '{}': it has no tetrahedra",
                                 mesh.source));
  TetLocator locator(mesh);
  VisualMapping m;
  m.node.resize(vertices.size());
  m.w.resize(vertices.size());
  m.tet.resize(vertices.size());
  size_t too_far = 0, first_far = 0;
  double first_far_distance = 0;
  int32_t first_far_tet = 0;
  for (size_t v = 0; v < vertices.size(); ++v) {
    const Location loc = locator.locate(vertices[v]);
    const Tet& t = mesh.tets[loc.tet];
    for (int i = 0; i < 4; ++i) m.node[v][i] = t[i] + node_offset;
    m.w[v] = loc.w;
    m.tet[v] = loc.tet + tet_offset;
    if (!loc.inside) {
      ++m.outside;
      m.max_distance = std::max(m.max_distance, loc.distance);
    }
    if (!(loc.distance <= max_distance) && too_far++ == 0) {
      first_far = v;
      first_far_distance = loc.distance;
      first_far_tet = loc.tet;
    }
  }
  // Reported after the pass so the message can say how many vertices are affected: one stray
  // vertex and a surface in the wrong units need different fixes.
  if (too_far > 0) {
    const Vec3& p = vertices[first_far];
    throw InputError(
        source, 0, "",
        fmt::format("visual vertex {} (0-based) at ({:.6g}, {:.6g}, {:.6g}) is "
                    "{:.4g} from the nearest tetrahedron ({} of '{}'), more than max_distance "
                    "{:.4g}; {} of {} vertices are that far",
                    first_far, p[0], p[1], p[2], first_far_distance,
                    first_far_tet, mesh.source, max_distance, too_far, vertices.size()));
  }
  return m;
}

}  // namespace stroma
