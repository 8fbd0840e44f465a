#include "tissue/cut_topology.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <stdexcept>
#include <string>
#include <unordered_map>
#include <unordered_set>

#include "tissue/vec3.hpp"

namespace stroma {

namespace {

/// Nodes of the face opposite local node k.
constexpr int kFace[4][3] = {{1, 2, 3}, {0, 2, 3}, {0, 1, 3}, {0, 1, 2}};

int local_edge(int i, int j) {
  if (i > j) std::swap(i, j);
  for (int k = 0; k < 6; ++k)
    if (kTetEdge[k][0] == i && kTetEdge[k][1] == j) return k;
  return -1;
}

struct UnionFind {
  std::vector<int32_t> parent;
  explicit UnionFind(size_t n) : parent(n) { std::iota(parent.begin(), parent.end(), 0); }
  int32_t find(int32_t x) {
    while (parent[x] != x) {
      parent[x] = parent[parent[x]];
      x = parent[x];
    }
    return x;
  }
  void unite(int32_t a, int32_t b) {
    a = find(a);
    b = find(b);
    if (a != b) parent[std::max(a, b)] = std::min(a, b);
  }
};

using P3 = Vec3;
using v3::cross;
using v3::dot;
using v3::sub;

/// A reference to a point of one tetrahedron: 0..3 its nodes, 4..9 the cut point of local
/// edge (ref − 4).
using LocalRef = uint8_t;
constexpr LocalRef edge_ref(int local_edge_index) { return static_cast<LocalRef>(4 + local_edge_index); }

/// Why a triangle of a copy's boundary is there.
enum class Part : uint8_t { Polygon, Face };

struct LocalTri {
  std::array<LocalRef, 3> r;
  Part part;
  int8_t face;  ///< local face (opposite node) for Part::Face
};

/// One tetrahedron's geometry and cut state, for building its copies' boundaries.
struct TetView {
  std::array<int32_t, 4> node{};     ///< global nodes
  std::array<P3, 4> x{};             ///< rest positions
  std::array<int32_t, 6> edge{};     ///< global edge of each local edge
  std::array<double, 6> t{};         ///< cut parameter from the edge's lower *global* node, or < 0
  uint8_t cut_mask = 0;              ///< bit k: local edge k is cut

  bool cut(int k) const { return (cut_mask >> k) & 1; }
  /// Rest position of a reference.
  P3 at(LocalRef r) const {
    if (r < 4) return x[r];
    const int k = r - 4;
    int i = kTetEdge[k][0], j = kTetEdge[k][1];
    if (node[i] > node[j]) std::swap(i, j);  // t runs from the lower global node
    const double s = t[k];
    return {(1 - s) * x[i][0] + s * x[j][0], (1 - s) * x[i][1] + s * x[j][1], (1 - s) * x[i][2] + s * x[j][2]};
  }
};

TetView make_view(const std::vector<Tet>& tets, const std::vector<double>& rest, const TetAdjacency& adj,
                  const std::vector<double>& edge_cut, int32_t t) {
  TetView v;
  for (int k = 0; k < 4; ++k) {
    v.node[k] = tets[t][k];
    for (int d = 0; d < 3; ++d) v.x[k][d] = rest[3 * static_cast<size_t>(v.node[k]) + d];
  }
  for (int k = 0; k < 6; ++k) {
    v.edge[k] = adj.tet_edges[t][k];
    v.t[k] = edge_cut[v.edge[k]];
    if (v.t[k] >= 0) v.cut_mask |= static_cast<uint8_t>(1u << k);
  }
  return v;
}

/// Components of the tetrahedron's nodes joined by its uncut edges, as material masks ordered
/// by their lowest local node.
int components(const TetView& v, std::array<uint8_t, 4>& masks) {
  UnionFind uf(4);
  for (int k = 0; k < 6; ++k)
    if (!v.cut(k)) uf.unite(kTetEdge[k][0], kTetEdge[k][1]);
  int n = 0;
  std::array<int, 4> slot{-1, -1, -1, -1};
  for (int i = 0; i < 4; ++i) {
    const int r = uf.find(i);
    if (slot[r] < 0) {
      slot[r] = n;
      masks[n++] = 0;
    }
    masks[slot[r]] |= static_cast<uint8_t>(1u << i);
  }
  return n;
}

bool has(uint8_t mask, int i) { return (mask >> i) & 1; }

/// The cut polygon of material `m` (the marching-tetrahedra surface between m and the rest),
/// as 1 or 2 triangles. A quad is split on the diagonal from its cut point on the lowest-
/// numbered global edge, so the two copies on either side split it the same way.
void polygon(const TetView& v, uint8_t m, std::vector<LocalTri>& out) {
  std::array<int, 4> in{}, outn{};
  int ni = 0, no = 0;
  for (int i = 0; i < 4; ++i) (has(m, i) ? in[ni++] : outn[no++]) = i;
  if (ni == 0 || no == 0) return;
  if (ni == 1 || no == 1) {
    const int c = ni == 1 ? in[0] : outn[0];
    const auto& o = ni == 1 ? outn : in;
    out.push_back({{edge_ref(local_edge(c, o[0])), edge_ref(local_edge(c, o[1])), edge_ref(local_edge(c, o[2]))},
                   Part::Polygon, -1});
    return;
  }
  // 2 | 2: the cycle (in0,out0) (in1,out0) (in1,out1) (in0,out1).
  const std::array<int, 4> cyc{local_edge(in[0], outn[0]), local_edge(in[1], outn[0]), local_edge(in[1], outn[1]),
                               local_edge(in[0], outn[1])};
  int s = 0;
  for (int i = 1; i < 4; ++i)
    if (v.edge[cyc[i]] < v.edge[cyc[s]]) s = i;
  const LocalRef a = edge_ref(cyc[s]), b = edge_ref(cyc[(s + 1) % 4]), c = edge_ref(cyc[(s + 2) % 4]),
                 d = edge_ref(cyc[(s + 3) % 4]);
  out.push_back({{a, b, c}, Part::Polygon, -1});
  out.push_back({{a, c, d}, Part::Polygon, -1});
}

/// The cells of local face f (a subdivision by its cut points that both tetrahedra sharing it
/// make alike, and that splits every cut edge at its point) that material `m` covers.
void face_cells(const TetView& v, int f, uint8_t m, std::vector<LocalTri>& out) {
  const int* fn = kFace[f];
  const uint8_t on_face = static_cast<uint8_t>(m & ((1u << fn[0]) | (1u << fn[1]) | (1u << fn[2])));
  if (!on_face) return;
  const int e01 = local_edge(fn[0], fn[1]), e02 = local_edge(fn[0], fn[2]), e12 = local_edge(fn[1], fn[2]);
  const int ncut = v.cut(e01) + v.cut(e02) + v.cut(e12);
  const auto push = [&](LocalRef a, LocalRef b, LocalRef c) { out.push_back({{a, b, c}, Part::Face, static_cast<int8_t>(f)}); };
  if (ncut == 0) {
    push(static_cast<LocalRef>(fn[0]), static_cast<LocalRef>(fn[1]), static_cast<LocalRef>(fn[2]));
    return;
  }
  if (ncut == 1) {
    // A single cut point cannot separate the face's nodes, but the face is still split at it:
    // the other faces around that edge are, and the surface must not have a T-junction there.
    const int k = v.cut(e01) ? e01 : v.cut(e02) ? e02 : e12;
    const int a = kTetEdge[k][0], b = kTetEdge[k][1];
    const int o = fn[0] + fn[1] + fn[2] - a - b;
    push(static_cast<LocalRef>(a), edge_ref(k), static_cast<LocalRef>(o));
    push(edge_ref(k), static_cast<LocalRef>(b), static_cast<LocalRef>(o));
    return;
  }
  if (ncut == 3) {
    for (int i = 0; i < 3; ++i) {
      const int n = fn[i], o1 = fn[(i + 1) % 3], o2 = fn[(i + 2) % 3];
      if (has(m, n)) push(static_cast<LocalRef>(n), edge_ref(local_edge(n, o1)), edge_ref(local_edge(n, o2)));
    }
    if (__builtin_popcount(on_face) >= 2) push(edge_ref(e01), edge_ref(e12), edge_ref(e02));
    return;
  }
  // Two cut edges meeting at corner c; p, q joined by the uncut edge.
  int c = 0, p = 0, q = 0;
  if (!v.cut(e12)) c = fn[0], p = fn[1], q = fn[2];
  else if (!v.cut(e02)) c = fn[1], p = fn[0], q = fn[2];
  else c = fn[2], p = fn[0], q = fn[1];
  const LocalRef ecp = edge_ref(local_edge(c, p)), ecq = edge_ref(local_edge(c, q));
  if (has(m, c)) push(static_cast<LocalRef>(c), ecp, ecq);
  if (has(m, p)) {  // the quad p, q, E(c,q), E(c,p), split from its lower global node
    const LocalRef P = static_cast<LocalRef>(p), Q = static_cast<LocalRef>(q);
    if (v.node[p] < v.node[q]) {
      push(P, Q, ecq);
      push(P, ecq, ecp);
    } else {
      push(Q, ecq, ecp);
      push(Q, ecp, P);
    }
  }
}

/// Orients each triangle outward of material m: a face cell away from the tetrahedron's
/// centroid, a polygon from m's nodes towards the others.
void orient(const TetView& v, uint8_t m, std::vector<LocalTri>& tris) {
  P3 centroid{0, 0, 0}, cin{0, 0, 0}, cout{0, 0, 0};
  int ni = 0;
  for (int i = 0; i < 4; ++i) {
    for (int d = 0; d < 3; ++d) {
      centroid[d] += 0.25 * v.x[i][d];
      (has(m, i) ? cin : cout)[d] += v.x[i][d];
    }
    ni += has(m, i);
  }
  const int no = 4 - ni;
  for (int d = 0; d < 3; ++d) {
    if (ni) cin[d] /= ni;
    if (no) cout[d] /= no;
  }
  const P3 away = sub(cout, cin);
  for (LocalTri& t : tris) {
    const P3 a = v.at(t.r[0]), b = v.at(t.r[1]), c = v.at(t.r[2]);
    const P3 n = cross(sub(b, a), sub(c, a));
    double s = 0;
    if (t.part == Part::Polygon) {
      s = dot(n, away);
    } else {
      const P3 mid{(a[0] + b[0] + c[0]) / 3, (a[1] + b[1] + c[1]) / 3, (a[2] + b[2] + c[2]) / 3};
      s = dot(n, sub(mid, centroid));
    }
    if (s < 0) std::swap(t.r[1], t.r[2]);
  }
}

/// The closed boundary of material m in the tetrahedron (its polygon and its part of each face),
/// oriented outward.
void copy_boundary(const TetView& v, uint8_t m, std::vector<LocalTri>& out) {
  out.clear();
  polygon(v, m, out);
  for (int f = 0; f < 4; ++f) face_cells(v, f, m, out);
  orient(v, m, out);
}

double enclosed_volume(const TetView& v, const std::vector<LocalTri>& tris) {
  // Relative to a node of the tetrahedron: absolute coordinates far from the origin would cost
  // the volume shares their precision.
  double vol = 0;
  for (const LocalTri& t : tris)
    vol += dot(sub(v.at(t.r[0]), v.x[0]), cross(sub(v.at(t.r[1]), v.x[0]), sub(v.at(t.r[2]), v.x[0])));
  return vol / 6.0;
}

/// A surface vertex's identity: a node's DOF (edge −1), or an edge with its two DOFs.
struct VertexKey {
  int32_t edge, a, b;
  bool operator==(const VertexKey& o) const { return edge == o.edge && a == o.a && b == o.b; }
};
struct VertexKeyHash {
  size_t operator()(const VertexKey& k) const {
    uint64_t h = static_cast<uint32_t>(k.edge) * 0x9E3779B97F4A7C15ull;
    h ^= (static_cast<uint64_t>(static_cast<uint32_t>(k.a)) << 32 | static_cast<uint32_t>(k.b)) + 0x7F4A7C15ull +
         (h << 6) + (h >> 2);
    return static_cast<size_t>(h ^ (h >> 29));
  }
};

struct TriKey {
  std::array<int32_t, 3> v;
  bool operator==(const TriKey& o) const { return v == o.v; }
};
struct TriKeyHash {
  size_t operator()(const TriKey& k) const {
    uint64_t h = 1469598103934665603ull;
    for (int32_t x : k.v) h = (h ^ static_cast<uint32_t>(x)) * 1099511628211ull;
    return static_cast<size_t>(h);
  }
};

/// Accumulates oriented triangles; a triangle and its reverse cancel.
struct SurfaceBuilder {
  struct Entry {
    std::array<int32_t, 3> sorted;
    int net = 0;                    // +1 per triangle in the sorted cycle's orientation, −1 reversed
    int32_t copy_pos = -1, copy_neg = -1;
    bool cut_pos = false, cut_neg = false;
  };
  std::unordered_map<VertexKey, int32_t, VertexKeyHash> vertex_index;
  std::vector<CutVertex> vertices;
  std::unordered_map<TriKey, int32_t, TriKeyHash> tri_index;
  std::vector<Entry> entries;

  int32_t vertex(const VertexKey& k, const CutVertex& cv) {
    auto [it, fresh] = vertex_index.try_emplace(k, static_cast<int32_t>(vertices.size()));
    if (fresh) vertices.push_back(cv);
    return it->second;
  }
  void add(std::array<int32_t, 3> v, int32_t copy, bool cut) {
    // Rotate so the smallest comes first; the orientation is then that of (v0, v1, v2) or its reverse.
    while (v[0] > v[1] || v[0] > v[2]) v = {v[1], v[2], v[0]};
    const bool even = v[1] < v[2];
    const TriKey key{{v[0], std::min(v[1], v[2]), std::max(v[1], v[2])}};
    auto [it, fresh] = tri_index.try_emplace(key, static_cast<int32_t>(entries.size()));
    if (fresh) entries.push_back({key.v});
    Entry& e = entries[it->second];
    if (even) {
      ++e.net;
      e.copy_pos = copy;
      e.cut_pos = cut;
    } else {
      --e.net;
      e.copy_neg = copy;
      e.cut_neg = cut;
    }
  }
};

/// Where the two lips of a cut share their DOFs along a line (a crack front lying in a face or
/// in the outer surface: the lips can never part there), four or more triangles meet at an
/// edge of the cancelled surface. The surface is made manifold without moving anything: at each
/// such edge the triangles are paired into sheets, and each vertex is split into one vertex per
/// fan of triangles joined through paired edges (the copies are the same point, on the same
/// DOFs). A pairing whose fans all join up again leaves the edge shared; such edges are
/// re-paired (another of the possible pairings) and the split redone, a few rounds at most.
/// Returns the edges still shared by more than two triangles (0 in every case tested).
int make_manifold(CutTopology& topo, const std::unordered_set<uint64_t>& glued) {
  struct EdgeUse {
    int32_t tri;
    int corner;    // the corner of `tri` where the edge starts (direction corner → corner + 1)
    bool forward;  // runs lower vertex → higher vertex
  };
  const auto key = [](int32_t a, int32_t b) {
    return static_cast<uint64_t>(std::min(a, b)) << 32 | static_cast<uint32_t>(std::max(a, b));
  };
  const int32_t nt = static_cast<int32_t>(topo.triangles.size());
  std::unordered_map<uint64_t, std::vector<EdgeUse>> edges;
  for (int32_t t = 0; t < nt; ++t)
    for (int i = 0; i < 3; ++i) {
      const int32_t a = topo.triangles[t].v[i], b = topo.triangles[t].v[(i + 1) % 3];
      edges[key(a, b)].push_back({t, i, a < b});
    }
  std::vector<std::vector<EdgeUse>> shared;  // the non-manifold edges' uses, deterministic order
  std::vector<uint64_t> shared_keys;
  for (const auto& [k, uses] : edges)
    if (uses.size() > 2) shared_keys.push_back(k);
  if (shared_keys.empty()) return 0;
  std::sort(shared_keys.begin(), shared_keys.end());
  for (uint64_t k : shared_keys) shared.push_back(edges[k]);
  const auto is_glued = [&](int32_t c, int32_t d) {
    return glued.count(static_cast<uint64_t>(std::min(c, d)) << 32 | static_cast<uint32_t>(std::max(c, d))) > 0;
  };
  const std::vector<std::array<int32_t, 3>> original = [&] {
    std::vector<std::array<int32_t, 3>> v;
    for (const CutTriangle& t : topo.triangles) v.push_back(t.v);
    return v;
  }();
  const size_t original_vertices = topo.vertices.size();
  std::vector<int> choice(shared.size(), 0);
  int remaining = 0;
  for (int round = 0; round < 6; ++round) {
    UnionFind corners(static_cast<size_t>(nt) * 3);
    const auto join = [&](const EdgeUse& u, const EdgeUse& w) {  // u: a → b, w: b → a
      corners.unite(3 * u.tri + u.corner, 3 * w.tri + (w.corner + 1) % 3);
      corners.unite(3 * u.tri + (u.corner + 1) % 3, 3 * w.tri + w.corner);
    };
    for (auto& [k, uses] : edges)
      if (uses.size() == 2 && uses[0].forward != uses[1].forward) join(uses[0].forward ? uses[0] : uses[1], uses[0].forward ? uses[1] : uses[0]);
    for (size_t e = 0; e < shared.size(); ++e) {
      std::vector<EdgeUse> fwd, bwd;
      for (const EdgeUse& u : shared[e]) (u.forward ? fwd : bwd).push_back(u);
      const size_t n = std::min(fwd.size(), bwd.size());
      if (choice[e] == 0) {  // material wedges: the same copy, else a glued one, else any
        std::vector<char> taken(bwd.size(), 0);
        for (const EdgeUse& u : fwd) {
          const int32_t cu = topo.triangles[u.tri].copy;
          int best = -1, best_rank = 3;
          for (size_t j = 0; j < bwd.size(); ++j) {
            if (taken[j]) continue;
            const int32_t cw = topo.triangles[bwd[j].tri].copy;
            const int rank = cw == cu ? 0 : is_glued(cu, cw) ? 1 : 2;
            if (rank < best_rank) best = static_cast<int>(j), best_rank = rank;
          }
          if (best < 0) continue;
          taken[best] = 1;
          join(u, bwd[best]);
        }
      } else {  // the other pairings in turn
        for (size_t i = 0; i < n; ++i) join(fwd[i], bwd[(i + static_cast<size_t>(choice[e])) % n]);
      }
    }
    // One vertex per (vertex, fan): the first fan keeps the vertex, the others get copies.
    topo.vertices.resize(original_vertices);
    std::unordered_map<int32_t, int32_t> fan_vertex;  // corner class → vertex
    std::vector<char> used(original_vertices, 0);
    for (int32_t t = 0; t < nt; ++t)
      for (int i = 0; i < 3; ++i) {
        const int32_t v0 = original[t][i];
        auto [it, fresh] = fan_vertex.try_emplace(corners.find(3 * t + i), v0);
        if (fresh) {
          if (used[v0]) {
            it->second = static_cast<int32_t>(topo.vertices.size());
            topo.vertices.push_back(topo.vertices[v0]);
          } else {
            used[v0] = 1;
          }
        }
        topo.triangles[t].v[i] = it->second;
      }
    // Which shared edges are still shared?
    remaining = 0;
    for (size_t e = 0; e < shared.size(); ++e) {
      std::unordered_map<uint64_t, int> count;
      for (const EdgeUse& u : shared[e]) {
        const auto& v = topo.triangles[u.tri].v;
        ++count[key(v[u.corner], v[(u.corner + 1) % 3])];
      }
      bool bad = false;
      for (const auto& [k, c] : count) bad |= c > 2;
      if (bad) {
        ++remaining;
        ++choice[e];
      }
    }
    if (remaining == 0) break;
  }
  return remaining;
}

}  // namespace

TetAdjacency build_tet_adjacency(const std::vector<Tet>& tets, int32_t num_nodes) {
  TetAdjacency adj;
  adj.tet_edges.resize(tets.size());
  adj.face_neighbor.assign(tets.size(), {-1, -1, -1, -1});
  std::unordered_map<int64_t, int32_t> edge_id;
  edge_id.reserve(tets.size() * 2);
  for (size_t t = 0; t < tets.size(); ++t)
    for (int k = 0; k < 6; ++k) {
      int32_t a = tets[t][kTetEdge[k][0]], b = tets[t][kTetEdge[k][1]];
      if (a > b) std::swap(a, b);
      const int64_t key = static_cast<int64_t>(a) * num_nodes + b;
      auto [it, fresh] = edge_id.try_emplace(key, static_cast<int32_t>(adj.edges.size()));
      if (fresh) adj.edges.push_back({a, b});
      adj.tet_edges[t][k] = it->second;
    }
  struct FaceRef {
    std::array<int32_t, 3> nodes;
    int32_t tet;
    int8_t local;
  };
  std::vector<FaceRef> faces;
  faces.reserve(tets.size() * 4);
  for (size_t t = 0; t < tets.size(); ++t)
    for (int f = 0; f < 4; ++f) {
      std::array<int32_t, 3> n{tets[t][kFace[f][0]], tets[t][kFace[f][1]], tets[t][kFace[f][2]]};
      std::sort(n.begin(), n.end());
      faces.push_back({n, static_cast<int32_t>(t), static_cast<int8_t>(f)});
    }
  std::sort(faces.begin(), faces.end(), [](const FaceRef& a, const FaceRef& b) {
    return a.nodes != b.nodes ? a.nodes < b.nodes : a.tet < b.tet;
  });
  for (size_t i = 0; i < faces.size();) {
    size_t j = i + 1;
    while (j < faces.size() && faces[j].nodes == faces[i].nodes) ++j;
    if (j - i > 2)
      throw std::invalid_argument("face (" + std::to_string(faces[i].nodes[0]) + ", " +
                                  std::to_string(faces[i].nodes[1]) + ", " + std::to_string(faces[i].nodes[2]) +
                                  ") is shared by " + std::to_string(j - i) + " tetrahedra (not a manifold mesh)");
    if (j - i == 2) {
      adj.face_neighbor[faces[i].tet][faces[i].local] = faces[i + 1].tet;
      adj.face_neighbor[faces[i + 1].tet][faces[i + 1].local] = faces[i].tet;
    }
    i = j;
  }
  return adj;
}

CutTopology build_cut_topology(const std::vector<Tet>& tets, const std::vector<double>& rest,
                               const TetAdjacency& adj, const std::vector<double>& edge_cut,
                               const std::vector<int32_t>& node_ranges, bool internal_faces) {
  CutTopology topo;
  const int32_t num_nodes = static_cast<int32_t>(rest.size() / 3);
  const int32_t nt = static_cast<int32_t>(tets.size());
  if (adj.tet_edges.size() != tets.size() || adj.face_neighbor.size() != tets.size() ||
      edge_cut.size() != adj.edges.size())
    throw std::invalid_argument("cut topology: the adjacency or the edge cuts do not belong to these tetrahedra");
  if (node_ranges.size() < 2 || node_ranges.front() != 0 || node_ranges.back() != num_nodes ||
      !std::is_sorted(node_ranges.begin(), node_ranges.end()))
    throw std::invalid_argument("cut topology: node ranges must run from 0 to the node count in order");
  for (const Tet& t : tets)
    for (int32_t n : t)
      if (n < 0 || n >= num_nodes) throw std::invalid_argument("cut topology: a tetrahedron's node is out of range");
  for (double t : edge_cut) topo.cut_edges += t >= 0;

  // 1. Copies: one per component of each tetrahedron's nodes; volume shares of split ones.
  topo.tet_copy_begin.resize(static_cast<size_t>(nt) + 1);
  std::vector<LocalTri> tris;
  for (int32_t t = 0; t < nt; ++t) {
    topo.tet_copy_begin[t] = static_cast<int32_t>(topo.copies.size());
    const TetView v = make_view(tets, rest, adj, edge_cut, t);
    std::array<uint8_t, 4> masks{};
    const int nc = v.cut_mask ? components(v, masks) : 1;
    if (nc == 1) {
      topo.copies.push_back({t, 0xF, 1.0, {}});
      continue;
    }
    ++topo.split_tets;
    std::array<double, 4> vol{};
    double total = 0;
    for (int c = 0; c < nc; ++c) {
      copy_boundary(v, masks[c], tris);
      vol[c] = std::max(enclosed_volume(v, tris), 0.0);
      total += vol[c];
    }
    for (int c = 0; c < nc; ++c)
      topo.copies.push_back({t, masks[c], total > 0 ? vol[c] / total : 1.0 / nc, {}});
  }
  topo.tet_copy_begin[nt] = static_cast<int32_t>(topo.copies.size());
  const int32_t ncopies = static_cast<int32_t>(topo.copies.size());

  // 2. Gluing: copies of face neighbours whose material meets on the face share its nodes.
  UnionFind uf(static_cast<size_t>(ncopies) * 4);
  std::unordered_set<uint64_t> glued;  // (lower copy << 32 | higher copy)
  for (int32_t t = 0; t < nt; ++t)
    for (int f = 0; f < 4; ++f) {
      const int32_t u = adj.face_neighbor[t][f];
      if (u < t) continue;  // boundary, or done from u's side
      std::array<int, 3> lt{}, lu{};  // the face's nodes, local in t and in u
      for (int i = 0; i < 3; ++i) {
        lt[i] = kFace[f][i];
        const int32_t g = tets[t][lt[i]];
        lu[i] = static_cast<int>(std::find(tets[u].begin(), tets[u].end(), g) - tets[u].begin());
      }
      for (int32_t c = topo.tet_copy_begin[t]; c < topo.tet_copy_begin[t + 1]; ++c)
        for (int32_t d = topo.tet_copy_begin[u]; d < topo.tet_copy_begin[u + 1]; ++d) {
          bool meet = false;
          for (int i = 0; i < 3; ++i) meet |= has(topo.copies[c].material, lt[i]) && has(topo.copies[d].material, lu[i]);
          if (!meet) continue;
          for (int i = 0; i < 3; ++i) uf.unite(4 * c + lt[i], 4 * d + lu[i]);
          glued.insert(static_cast<uint64_t>(std::min(c, d)) << 32 | static_cast<uint32_t>(std::max(c, d)));
        }
    }

  // 3. DOFs: each class of incidences is a node copy. A node's classes in order of first use;
  // its primary one holds its first material incidence and keeps the node's place.
  std::vector<int32_t> class_of(static_cast<size_t>(ncopies) * 4);
  std::vector<std::vector<int32_t>> node_classes(static_cast<size_t>(num_nodes));
  std::vector<int32_t> primary(static_cast<size_t>(num_nodes), -1);
  std::vector<char> seen(static_cast<size_t>(ncopies) * 4, 0);
  for (int32_t c = 0; c < ncopies; ++c)
    for (int k = 0; k < 4; ++k) {
      const int32_t r = uf.find(4 * c + k);
      class_of[4 * c + k] = r;
      const int32_t g = tets[topo.copies[c].tet][k];
      if (!seen[r]) {
        seen[r] = 1;
        node_classes[g].push_back(r);
      }
      if (primary[g] < 0 && has(topo.copies[c].material, k)) primary[g] = r;
    }
  std::vector<int32_t> dof_of_class(static_cast<size_t>(ncopies) * 4, -1);
  topo.node_dof.assign(static_cast<size_t>(num_nodes), -1);
  topo.range_dof_begin.clear();
  int32_t next = 0;
  for (size_t ri = 0; ri + 1 < node_ranges.size(); ++ri) {
    const int32_t nb = node_ranges[ri], ne = node_ranges[ri + 1];
    topo.range_dof_begin.push_back(next);
    for (int32_t g = nb; g < ne; ++g) {
      topo.node_dof[g] = next + (g - nb);
      if (primary[g] >= 0) dof_of_class[primary[g]] = topo.node_dof[g];
    }
    int32_t extra = next + (ne - nb);
    for (int32_t g = nb; g < ne; ++g)
      for (int32_t r : node_classes[g])
        if (r != primary[g]) dof_of_class[r] = extra++;
    next = extra;
  }
  topo.range_dof_begin.push_back(next);
  topo.num_dofs = next;
  topo.dof_node.assign(static_cast<size_t>(next), -1);
  topo.dof_material.assign(static_cast<size_t>(next), 0);
  for (int32_t g = 0; g < num_nodes; ++g) {
    topo.dof_node[topo.node_dof[g]] = g;
    topo.dof_material[topo.node_dof[g]] = 1;  // a primary DOF holds material (or is an unused node)
    for (int32_t r : node_classes[g]) topo.dof_node[dof_of_class[r]] = g;
  }
  for (int32_t c = 0; c < ncopies; ++c)
    for (int k = 0; k < 4; ++k)
      if (has(topo.copies[c].material, k)) topo.dof_material[dof_of_class[class_of[4 * c + k]]] = 1;
  for (int32_t c = 0; c < ncopies; ++c)
    for (int k = 0; k < 4; ++k) topo.copies[c].dof[k] = dof_of_class[class_of[4 * c + k]];

  // 4. Surface: each copy's boundary, what glued copies share cancelled. Whole tetrahedra
  // between whole neighbours contribute nothing to it (their shared faces cancel), so they are
  // added only when the internal faces are wanted (the cancelled pairs are those).
  SurfaceBuilder sb;
  std::vector<char> split(static_cast<size_t>(nt), 0);
  for (int32_t t = 0; t < nt; ++t) split[t] = topo.tet_copy_begin[t + 1] - topo.tet_copy_begin[t] > 1;
  for (int32_t t = 0; t < nt; ++t) {
    const TetView v = make_view(tets, rest, adj, edge_cut, t);
    for (int32_t c = topo.tet_copy_begin[t]; c < topo.tet_copy_begin[t + 1]; ++c) {
      const ElementCopy& cp = topo.copies[c];
      if (split[t]) {
        copy_boundary(v, cp.material, tris);
      } else {
        tris.clear();
        for (int f = 0; f < 4; ++f) {
          const int32_t u = adj.face_neighbor[t][f];
          if (u < 0 || split[u] || internal_faces) face_cells(v, f, cp.material, tris);
        }
        orient(v, cp.material, tris);
      }
      for (const LocalTri& lt : tris) {
        std::array<int32_t, 3> vi{};
        for (int i = 0; i < 3; ++i) {
          const LocalRef r = lt.r[i];
          if (r < 4) {
            const int32_t d = cp.dof[r];
            vi[i] = sb.vertex({-1, d, d}, {d, d, 0.0});
          } else {
            const int k = r - 4;
            int li = kTetEdge[k][0], lj = kTetEdge[k][1];
            if (v.node[li] > v.node[lj]) std::swap(li, lj);
            const int32_t a = cp.dof[li], b = cp.dof[lj];
            vi[i] = sb.vertex({v.edge[k], a, b}, {a, b, v.t[k]});
          }
        }
        const bool cut = lt.part == Part::Polygon || adj.face_neighbor[t][lt.face] >= 0;
        sb.add(vi, c, cut);
      }
    }
  }
  topo.vertices = std::move(sb.vertices);
  for (const SurfaceBuilder::Entry& e : sb.entries) {
    if (e.net == 0) {
      if (internal_faces && e.copy_pos >= 0 && e.copy_neg >= 0)
        topo.internal.push_back({{e.sorted[0], e.sorted[1], e.sorted[2]}, e.copy_pos, e.copy_neg});
      continue;
    }
    if (e.net > 1 || e.net < -1) ++topo.unpaired_faces;
    if (e.net > 0) topo.triangles.push_back({{e.sorted[0], e.sorted[1], e.sorted[2]}, e.copy_pos, e.cut_pos});
    else topo.triangles.push_back({{e.sorted[0], e.sorted[2], e.sorted[1]}, e.copy_neg, e.cut_neg});
  }
  topo.nonmanifold_edges = make_manifold(topo, glued);
  // Keep only the vertices a triangle uses (those of cancelled faces go), in order of first use.
  std::vector<int32_t> renumber(topo.vertices.size(), -1);
  std::vector<CutVertex> used;
  for (CutTriangle& t : topo.triangles)
    for (int32_t& v : t.v) {
      if (renumber[v] < 0) {
        renumber[v] = static_cast<int32_t>(used.size());
        used.push_back(topo.vertices[v]);
      }
      v = renumber[v];
    }
  for (CutInternalFace& f : topo.internal)  // (after the surface's: its numbering is unchanged)
    for (int32_t& v : f.v) {
      if (renumber[v] < 0) {
        renumber[v] = static_cast<int32_t>(used.size());
        used.push_back(topo.vertices[v]);
      }
      v = renumber[v];
    }
  topo.vertices = std::move(used);
  return topo;
}

void copy_material_planes(const CutTopology& topo, const std::vector<Tet>& tets, const std::vector<double>& rest,
                          const std::vector<double>& edge_cut, const TetAdjacency& adj, int32_t copy,
                          std::vector<std::array<double, 4>>& planes) {
  const ElementCopy& c = topo.copies[static_cast<size_t>(copy)];
  if (topo.tet_copy_begin[c.tet + 1] - topo.tet_copy_begin[c.tet] == 1) return;  // whole: all material
  const TetView v = make_view(tets, rest, adj, edge_cut, c.tet);
  std::vector<LocalTri> tris;
  polygon(v, c.material, tris);
  orient(v, c.material, tris);  // outward of the material: −(p − a)·n/|n| is the depth inside
  for (const LocalTri& t : tris) {
    const P3 a = v.at(t.r[0]);
    const P3 n = cross(sub(v.at(t.r[1]), a), sub(v.at(t.r[2]), a));
    const double len = std::sqrt(dot(n, n));
    if (len <= 0) continue;
    // p = Σ w_k X_k with Σ w_k = 1, so −(p − a)·n/|n| = Σ w_k (−(X_k − a)·n/|n|).
    std::array<double, 4> w{};
    for (int k = 0; k < 4; ++k) w[static_cast<size_t>(k)] = -dot(sub(v.x[k], a), n) / len;
    planes.push_back(w);
  }
}

int32_t copy_containing(const CutTopology& topo, const std::vector<Tet>& tets, const std::vector<double>& rest,
                        const std::vector<double>& edge_cut, const TetAdjacency& adj, int32_t tet,
                        const std::array<double, 4>& bary) {
  const int32_t begin = topo.tet_copy_begin[tet], end = topo.tet_copy_begin[tet + 1];
  if (end - begin == 1) return begin;
  int32_t best = begin;
  double best_score = -1e300;
  std::vector<std::array<double, 4>> planes;
  for (int32_t c = begin; c < end; ++c) {
    planes.clear();
    copy_material_planes(topo, tets, rest, edge_cut, adj, c, planes);
    // How far inside the material's side of its cut polygon the point lies (the worst plane).
    double score = 1e300;
    for (const auto& q : planes) score = std::min(score, q[0] * bary[0] + q[1] * bary[1] + q[2] * bary[2] + q[3] * bary[3]);
    if (score > best_score) {
      best_score = score;
      best = c;
    }
  }
  return best;
}

}  // namespace stroma
