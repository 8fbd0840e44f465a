#include "render/capsule_mesh.hpp"

#include <cmath>

#include <Eigen/Dense>

namespace stroma::render {

void append_capsule(const Vec3f& a3, const Vec3f& b3, float r, std::vector<float>& vertices,
                    std::vector<uint32_t>& indices, int stride) {
  constexpr int kSegments = 32;  // around the axis
  constexpr int kRings = 8;      // per hemisphere, pole to equator
  using V = Eigen::Vector3f;
  const V a(a3[0], a3[1], a3[2]), b(b3[0], b3[1], b3[2]);
  V axis = b - a;
  const float len = axis.norm();
  axis = len > 1e-9f ? V(axis / len) : V(0, 0, 1);
  // An orthonormal frame around the axis.
  const V helper = std::abs(axis.x()) < 0.9f ? V(1, 0, 0) : V(0, 1, 0);
  const V u = axis.cross(helper).normalized(), w = axis.cross(u);
  const uint32_t base = static_cast<uint32_t>(vertices.size() / stride);
  // Rings from the pole at a (angle −π/2) through a's equator, b's equator, to the pole at b.
  // Each ring is a loop of kSegments + 1 vertices (the seam is duplicated).
  int rings = 0;
  auto ring = [&](const V& centre, float phi) {
    for (int s = 0; s <= kSegments; ++s) {
      const float th = 2.0f * static_cast<float>(M_PI) * static_cast<float>(s) / kSegments;
      const V n = std::cos(phi) * (std::cos(th) * u + std::sin(th) * w) + std::sin(phi) * axis;
      const V p = centre + r * n;
      const size_t o = vertices.size();
      vertices.resize(o + stride, 0.0f);
      vertices[o] = p.x();
      vertices[o + 1] = p.y();
      vertices[o + 2] = p.z();
      vertices[o + 3] = n.x();
      vertices[o + 4] = n.y();
      vertices[o + 5] = n.z();
    }
    ++rings;
  };
  const float half_pi = 0.5f * static_cast<float>(M_PI);
  for (int i = 0; i <= kRings; ++i) ring(a, -half_pi + half_pi * static_cast<float>(i) / kRings);
  for (int i = 0; i <= kRings; ++i) ring(b, half_pi * static_cast<float>(i) / kRings);
  const uint32_t per = kSegments + 1;
  for (int k = 0; k + 1 < rings; ++k)
    for (uint32_t s = 0; s < kSegments; ++s) {
      const uint32_t i0 = base + k * per + s, i1 = i0 + 1, j0 = i0 + per, j1 = j0 + 1;
      indices.insert(indices.end(), {i0, i1, j1, i0, j1, j0});
    }
}

}  // namespace stroma::render
