#include "tissue/tet_walk.hpp"

#include <algorithm>
#include <map>

namespace stroma {

std::vector<int32_t> tet_face_neighbours(const std::vector<ElementParams>& elements) {
  std::vector<int32_t> out(4 * elements.size(), -1);
  std::map<std::array<int32_t, 3>, int32_t> open;  // sorted face → 4e + i of its first element
  for (size_t e = 0; e < elements.size(); ++e)
    for (int i = 0; i < 4; ++i) {
      std::array<int32_t, 3> f;
      for (int k = 0, j = 0; k < 4; ++k)
        if (k != i) f[size_t(j++)] = elements[e].node[size_t(k)];
      std::sort(f.begin(), f.end());
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

TetWalkResult walk_to_point(const std::vector<ElementParams>& elements, const int32_t* neighbours, const double* x,
                            int32_t start, const double* p, int32_t max_steps) {
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
