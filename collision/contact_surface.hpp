#pragma once
/// \file contact_surface.hpp
/// The compiled contact surface of all bodies, as tools and other bodies touch it.

#include <array>
#include <cstdint>
#include <vector>

namespace stroma {

/// The contact surface of all bodies, as compiled: outward triangles (global node ids), the
/// BSR slots of each triangle's node pairs, and each triangle's longest rest edge.
struct ContactSurface {
  const std::vector<std::array<int32_t, 3>>& triangles;
  const std::vector<std::array<int32_t, 9>>& slots;
  const std::vector<double>& longest_edge;
  /// Per face 0 inactive / 1 active / 2 active with reversed orientation; null: all active.
  const uint8_t* active = nullptr;
};

}  // namespace stroma
