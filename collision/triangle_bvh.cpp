#include "collision/triangle_bvh.hpp"

#include <algorithm>
#include <limits>

namespace stroma {

void TriangleBvh::tri_box(int32_t t, const double* x, double* lo, double* hi) const {
  for (int k = 0; k < 3; ++k) {
    const double a = x[3 * tris_[t][0] + k], b = x[3 * tris_[t][1] + k], c = x[3 * tris_[t][2] + k];
    lo[k] = std::min(a, std::min(b, c));
    hi[k] = std::max(a, std::max(b, c));
  }
}

void TriangleBvh::build(const std::vector<Triangle>& tris, const double* x) {
  tris_ = tris;
  order_.resize(tris_.size());
  for (size_t i = 0; i < order_.size(); ++i) order_[i] = static_cast<int32_t>(i);
  nodes_.clear();
  if (tris_.empty()) return;
  nodes_.reserve(2 * (tris_.size() / kLeafSize + 1) + 1);
  nodes_.emplace_back();
  build_range(0, static_cast<int32_t>(order_.size()), x, 0);
  refit(x);
}

void TriangleBvh::build_range(int32_t begin, int32_t end, const double* x, int32_t node) {
  if (end - begin <= kLeafSize) {
    nodes_[node].first = begin;
    nodes_[node].count = end - begin;
    return;
  }
  // Split at the median centroid along the longest axis of the centroids' box.
  double lo[3], hi[3];
  for (int k = 0; k < 3; ++k) {
    lo[k] = std::numeric_limits<double>::max();
    hi[k] = -lo[k];
  }
  auto centroid = [&](int32_t t, int k) {
    return x[3 * tris_[t][0] + k] + x[3 * tris_[t][1] + k] + x[3 * tris_[t][2] + k];
  };
  for (int32_t i = begin; i < end; ++i)
    for (int k = 0; k < 3; ++k) {
      lo[k] = std::min(lo[k], centroid(order_[i], k));
      hi[k] = std::max(hi[k], centroid(order_[i], k));
    }
  int axis = 0;
  for (int k = 1; k < 3; ++k)
    if (hi[k] - lo[k] > hi[axis] - lo[axis]) axis = k;
  const int32_t mid = begin + (end - begin) / 2;
  std::nth_element(order_.begin() + begin, order_.begin() + mid, order_.begin() + end,
                   [&](int32_t a, int32_t b) { return centroid(a, axis) < centroid(b, axis); });
  const int32_t left = static_cast<int32_t>(nodes_.size());
  nodes_.emplace_back();
  nodes_.emplace_back();
  nodes_[node].first = left;
  nodes_[node].count = 0;
  build_range(begin, mid, x, left);
  build_range(mid, end, x, left + 1);
}

void TriangleBvh::refit(const double* x) {
  // Children always have larger indices than their parent: a reverse sweep is bottom-up.
  for (int32_t n = static_cast<int32_t>(nodes_.size()) - 1; n >= 0; --n) {
    Node& nd = nodes_[n];
    if (nd.count > 0) {
      tri_box(order_[nd.first], x, nd.lo, nd.hi);
      for (int32_t i = nd.first + 1; i < nd.first + nd.count; ++i) {
        double lo[3], hi[3];
        tri_box(order_[i], x, lo, hi);
        for (int k = 0; k < 3; ++k) {
          nd.lo[k] = std::min(nd.lo[k], lo[k]);
          nd.hi[k] = std::max(nd.hi[k], hi[k]);
        }
      }
    } else {
      const Node& a = nodes_[nd.first];
      const Node& b = nodes_[nd.first + 1];
      for (int k = 0; k < 3; ++k) {
        nd.lo[k] = std::min(a.lo[k], b.lo[k]);
        nd.hi[k] = std::max(a.hi[k], b.hi[k]);
      }
    }
  }
}

}  // namespace stroma
