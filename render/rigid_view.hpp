#pragma once
/// \file rigid_view.hpp
/// A rigid body as the renderer draws it (issue 42): its shape (stroma_RigidBody's fields, in
/// its shape frame) posed in the world (stroma_RigidBodyState) as capsules — a sphere, a capsule,
/// a needle's wire as a chain of them along its curve: a tube — and flat triangles (a box's or a
/// mesh's faces), with a needle's track points as marks; a suture thread as a tube along its
/// nodes (issue 43). Plain arrays: no GL, no DDS.

#include <array>
#include <cstdint>
#include <vector>

#include "render/renderer.hpp"

namespace stroma::render {

/// A rigid body's shape in its shape frame (the fields of stroma_RigidBody; docs/DDS.md).
struct RigidShapeDesc {
  enum Kind : uint8_t { Sphere, Box, Capsule, Mesh, Needle } kind = Sphere;
  double radius = 0, length = 0;       ///< sphere, capsule (axis along z, centred); needle: arc length
  std::array<double, 3> size{0, 0, 0};  ///< box: full edges
  double wire_radius = 0;              ///< needle
  bool curved = false;
  double arc_radius = 0, angle = 0;    ///< a curved needle: an arc about the origin in the xy-plane, tail on +x
  std::vector<float> vertices;         ///< mesh: 3 per vertex, shape frame
  std::vector<uint32_t> triangles;     ///< mesh: 3 per triangle
};

/// Segments a curved needle's tube is drawn with (a straight one: one).
inline constexpr int kNeedleSegments = 24;

/// The view of `shape` with its shape frame at `position`, rotated by the unit quaternion
/// `orientation` (w, x, y, z), and `track_points` track marks (3 floats each, world). Mesh
/// triangles with an index out of range are skipped.
RigidView make_rigid_view(const RigidShapeDesc& shape, const double position[3], const double orientation[4],
                          const float* track, size_t track_points);

/// Radius (m) a thread's tube is drawn with at least: a suture (0.1 mm) is below a pixel at the
/// distances organs are framed from (~0.3 mm per pixel at 0.3 m and 720 lines), and would vanish.
inline constexpr double kThreadMinDrawRadius = 4e-4;

/// A suture thread (stroma_ThreadState) as a tube: a capsule along each segment between its
/// `nodes` positions (3 floats each, world), of radius max(diameter / 2, kThreadMinDrawRadius).
RigidView make_thread_view(const float* positions, size_t nodes, double diameter);

}  // namespace stroma::render
