#include "tissue/tet_walk.hpp"

#include <algorithm>
#include <limits>
#include <map>

namespace stroma {

std::array<int32_t, 3> sorted_tet_face(const ElementParams& e, int i) {
  std::array<int32_t, 3> f;
  for (int k = 0, j = 0; k < 4; ++k)
    if (k != i) f[size_t(j++)] = e.node[size_t(k)];
  std::sort(f.begin(), f.end());
  return f;
}

std::vector<int32_t> tet_face_neighbours(const std::vector<ElementParams>& elements) {
  std::vector<int32_t> out(4 * elements.size(), -1);
  std::map<std::array<int32_t, 3>, int32_t> open;  // sorted face → 4e + i of its first element
  for (size_t e = 0; e < elements.size(); ++e)
    for (int i = 0; i < 4; ++i) {
      const std::array<int32_t, 3> f = sorted_tet_face(elements[e], i);
      const int32_t me = static_cast<int32_t>(4 * e + size_t(i));
      auto [it, fresh] = open.emplace(f, me);
      if (!fresh) {
        out[size_t(me)] = it->second / 4;
        out[size_t(it->second)] = static_cast<int32_t>(e);
        open.erase(it);
      }
    }
  return out;
}

void tet_weights(const ElementParams& e, const double* x, const double* p, double* w) {
  const double* a = x + 3 * e.node[0];
  double m[9], r[3];
  for (int k = 0; k < 3; ++k) {
    for (int j = 0; j < 3; ++j) m[3 * k + j] = x[3 * e.node[size_t(j + 1)] + k] - a[k];
    r[k] = p[k] - a[k];
  }
  // Cramer's rule on [b−a, c−a, d−a] (w1, w2, w3) = p − a.
  const double det = m[0] * (m[4] * m[8] - m[5] * m[7]) - m[1] * (m[3] * m[8] - m[5] * m[6]) +
                     m[2] * (m[3] * m[7] - m[4] * m[6]);
  if (det == 0) {
    w[0] = w[1] = w[2] = w[3] = -1;  // degenerate: never "inside"
    return;
  }
  const double inv = 1.0 / det;
  w[1] = inv * (r[0] * (m[4] * m[8] - m[5] * m[7]) - m[1] * (r[1] * m[8] - m[5] * r[2]) + m[2] * (r[1] * m[7] - m[4] * r[2]));
  w[2] = inv * (m[0] * (r[1] * m[8] - m[5] * r[2]) - r[0] * (m[3] * m[8] - m[5] * m[6]) + m[2] * (m[3] * r[2] - r[1] * m[6]));
  w[3] = inv * (m[0] * (m[4] * r[2] - r[1] * m[7]) - m[1] * (m[3] * r[2] - r[1] * m[6]) + r[0] * (m[3] * m[7] - m[4] * m[6]));
  w[0] = 1.0 - w[1] - w[2] - w[3];
}

double WalkMesh::material_depth(int32_t e, const double* w) const {
  if (plane_begin == nullptr) return std::numeric_limits<double>::infinity();
  double depth = std::numeric_limits<double>::infinity();
  for (int32_t j = plane_begin[e]; j < plane_begin[e + 1]; ++j) {
    const std::array<double, 4>& c = planes[j];
    depth = std::min(depth, c[0] * w[0] + c[1] * w[1] + c[2] * w[2] + c[3] * w[3]);
  }
  return depth;
}

void WalkMesh::into_material(int32_t e, double* w) const {
  if (plane_begin == nullptr) return;
  // The material nodes: the corners every plane accepts (c_k ≥ 0); their centroid is inside.
  double m[4] = {0, 0, 0, 0};
  int n = 0;
  for (int k = 0; k < 4; ++k) {
    bool in = true;
    for (int32_t j = plane_begin[e]; j < plane_begin[e + 1]; ++j) in = in && planes[j][size_t(k)] >= 0;
    if (in) m[k] = 1, ++n;
  }
  for (double& v : m) v = n > 0 ? v / n : 0.25;
  double lam = 0;
  for (int32_t j = plane_begin[e]; j < plane_begin[e + 1]; ++j) {
    const std::array<double, 4>& c = planes[j];
    const double cw = c[0] * w[0] + c[1] * w[1] + c[2] * w[2] + c[3] * w[3];
    const double cm = c[0] * m[0] + c[1] * m[1] + c[2] * m[2] + c[3] * m[3];
    if (cw < 0 && cm > cw) lam = std::max(lam, -cw / (cm - cw));
  }
  lam = std::min(lam, 1.0);
  for (int k = 0; k < 4; ++k) w[k] += lam * (m[k] - w[k]);
}

namespace {

/// Whether twin o holds the same DOFs as e on the face e shares with `from` (the face a walk
/// entered e through): the face borders both, so the point may be in either's material. A twin
/// not glued there is across the cut from where the walk came (a front in one lip of an incision
/// must exit at the cut, not pass into the other lip's copy of the same tetrahedron).
bool glued_alike(const ElementParams& e, const ElementParams& o, const ElementParams& from) {
  for (int k = 0; k < 4; ++k) {
    const int32_t n = e.node[size_t(k)];
    if ((n == from.node[0] || n == from.node[1] || n == from.node[2] || n == from.node[3]) && o.node[size_t(k)] != n)
      return false;
  }
  return true;
}

}  // namespace

TetWalkResult walk_to_point(const WalkMesh& mesh, const double* x, int32_t start, const double* p,
                            int32_t max_steps) {
  const std::vector<ElementParams>& elements = *mesh.elements;
  const int32_t* neighbours = mesh.neighbours;
  TetWalkResult r;
  int32_t e = start, prev = -1;
  for (r.steps = 0; r.steps < max_steps; ++r.steps) {
    double w[4];
    tet_weights(elements[size_t(e)], x, p, w);
    int i = 0;
    for (int k = 1; k < 4; ++k)
      if (w[k] < w[i]) i = k;
    r.tet = e;
    if (w[i] >= -1e-9) {
      std::copy(w, w + 4, r.w);
      if (mesh.material_depth(e, w) < -1e-12) {  // in e's shape, beyond its cut: in a twin's material?
        if (mesh.next_twin != nullptr && prev >= 0)
          for (int32_t o = mesh.next_twin[e]; o != e; o = mesh.next_twin[o]) {
            if (!glued_alike(elements[size_t(e)], elements[size_t(o)], elements[size_t(prev)])) continue;
            double wo[4];
            tet_weights(elements[size_t(o)], x, p, wo);
            if (*std::min_element(wo, wo + 4) >= -1e-9 && mesh.material_depth(o, wo) >= -1e-12) {
              r.tet = o;
              std::copy(wo, wo + 4, r.w);
              r.inside = true;
              return r;
            }
          }
        mesh.into_material(e, r.w);  // outside the tissue
        r.past_cut = true;
        return r;
      }
      r.inside = true;
      return r;
    }
    int32_t next = neighbours[4 * e + i];
    if (next == prev && prev >= 0) {  // would step straight back: leave by the next most negative face instead
      int j = -1;
      for (int k = 0; k < 4; ++k)
        if (k != i && w[k] < -1e-9 && (j < 0 || w[k] < w[j])) j = k;
      if (j >= 0) next = neighbours[4 * e + j], i = j;
    }
    if (next < 0) {  // a boundary face: p is outside the tissue beyond it
      double s = 0;
      for (int k = 0; k < 4; ++k) s += (r.w[k] = std::max(w[k], 0.0));
      for (double& v : r.w) v = s > 0 ? v / s : 0.25;
      if (mesh.material_depth(e, r.w) < -1e-12) mesh.into_material(e, r.w);  // a copy's face beyond its cut
      return r;
    }
    prev = e;
    e = next;
  }
  r.w[0] = r.w[1] = r.w[2] = r.w[3] = 0.25;
  r.lost = true;
  return r;
}

}  // namespace stroma
