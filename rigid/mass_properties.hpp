#pragma once
/// \file mass_properties.hpp
/// Mass, centre of mass and inertia tensor of a rigid body's shape at a uniform density: the
/// constants a rigid body's rows of the implicit system need (docs/ARCHITECTURE.md, "Bodies of
/// more than one kind"). Closed forms for the sphere, the box and the capsule; for a closed
/// triangulated surface, the divergence theorem over the tetrahedra each triangle makes with the
/// origin (signed volumes, so any closed, consistently oriented surface works, convex or not).
///
/// Invariants of a MassProperties made here: mass > 0; `inertia` (about the centre of mass, in
/// the shape's frame, kg·m²) is symmetric positive definite and satisfies the triangle
/// inequalities of its principal moments (I1 + I2 ≥ I3 for every ordering).

#include <array>
#include <string>
#include <vector>

#include "tissue/tet_mesh.hpp"

namespace stroma {

struct MassProperties {
  double mass = 0;                  ///< kg
  double volume = 0;                ///< m³
  Vec3 centre{0, 0, 0};             ///< centre of mass in the shape's frame (m)
  std::array<double, 9> inertia{};  ///< about the centre of mass, shape frame, row-major (kg·m²)
};

/// A solid sphere of radius r. Throws std::invalid_argument for r ≤ 0 or density ≤ 0.
MassProperties sphere_mass_properties(double radius, double density);
/// A solid box of full side lengths (sx, sy, sz) centred on the origin.
MassProperties box_mass_properties(const Vec3& size, double density);
/// A solid capsule: a cylinder of radius r and length L along z, centred on the origin, closed by
/// two hemispheres (total length L + 2r).
MassProperties capsule_mass_properties(double radius, double length, double density);
/// The solid a closed triangle surface bounds (vertices in the shape's frame, triangles oriented
/// either way consistently: the sign of the enclosed volume decides). Throws std::invalid_argument
/// when the enclosed volume is not positive (an open or degenerate surface; the scenario loader
/// checks closedness first and says where).
MassProperties mesh_mass_properties(const std::vector<Vec3>& vertices, const std::vector<std::array<int32_t, 3>>& triangles,
                                    double density);

/// The principal moments of an inertia tensor, ascending.
std::array<double, 3> principal_moments(const std::array<double, 9>& inertia);

/// Whether `p` satisfies the invariants above (mass > 0, inertia symmetric positive definite,
/// principal moments satisfying the triangle inequality within `rel` of the largest); `why` says
/// what failed.
bool is_physical(const MassProperties& p, std::string* why = nullptr, double rel = 1e-9);

}  // namespace stroma
