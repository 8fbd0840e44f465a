#pragma once
/// \file contact_spring.hpp
/// A penalty contact acting at one point of a surface triangle for one tick: the point is
/// Σ w_a x_a over the triangle's nodes, its force is spread as w_a·f, and its stiffness and
/// damping enter the implicit system as the blocks w_a w_b K (so contact stays stable at 1 kHz
/// with implicit Euler). The BSR slots of the 3×3 node pairs are precomputed at load time.

#include <cstdint>

namespace stroma {

/// f = force on the tissue at the contact point; ∂f/∂x ≈ −K, ∂f/∂v ≈ −C (symmetric PSD,
/// row-major), both for the contact point.
struct ContactSpring {
  int32_t node[3] = {0, 0, 0};
  double w[3] = {1, 0, 0};
  int32_t slot[9] = {};  ///< BSR slot of block (node[a], node[b]) at 3a+b
  double force[3] = {0, 0, 0};
  double K[9] = {};
  double C[9] = {};
};

}  // namespace stroma
