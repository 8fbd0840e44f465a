#pragma once
/// \file bounding_box.hpp
/// Axis-aligned bounding boxes of point sets: the one place the project measures a scene's or
/// a body's size (the divergence limit of a step, automatic visual-mapping and probe distances,
/// body-contact depths).

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <vector>

#include "tissue/tet_mesh.hpp"

namespace stroma {

/// An axis-aligned box. Invariant: lo ≤ hi component-wise once a point has been added; the
/// empty box (no point) has lo = +∞, hi = −∞ and a diagonal of 0.
struct BoundingBox {
  Vec3 lo{1e300, 1e300, 1e300};
  Vec3 hi{-1e300, -1e300, -1e300};

  void add(const double* p) {
    for (int k = 0; k < 3; ++k) {
      lo[k] = std::min(lo[k], p[k]);
      hi[k] = std::max(hi[k], p[k]);
    }
  }
  bool empty() const { return lo[0] > hi[0]; }
  /// Length of the box's diagonal (0 when empty).
  double diagonal() const {
    if (empty()) return 0.0;
    const double a = hi[0] - lo[0], b = hi[1] - lo[1], c = hi[2] - lo[2];
    return std::sqrt(a * a + b * b + c * c);
  }
  /// Smallest extent along an axis (0 when empty).
  double min_extent() const { return empty() ? 0.0 : std::min({hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]}); }
};

/// Box of `count` points stored as consecutive xyz triples.
inline BoundingBox bounding_box(const double* xyz, size_t count) {
  BoundingBox b;
  for (size_t i = 0; i < count; ++i) b.add(xyz + 3 * i);
  return b;
}

/// Box of a list of points.
inline BoundingBox bounding_box(const std::vector<Vec3>& points) {
  BoundingBox b;
  for (const Vec3& p : points) b.add(p.data());
  return b;
}

}  // namespace stroma
