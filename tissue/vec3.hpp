#pragma once
/// \file vec3.hpp
/// Value arithmetic on Vec3 (std::array<double, 3>) for geometry outside the hot loops (cutting's
/// topology and blade tests). The element kernels use mat3.hpp's pointer forms instead.

#include "tissue/tet_mesh.hpp"

namespace stroma::v3 {

inline Vec3 sub(const Vec3& a, const Vec3& b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
inline Vec3 cross(const Vec3& a, const Vec3& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
inline double dot(const Vec3& a, const Vec3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

}  // namespace stroma::v3
