#pragma once
/// \file rigid_motion.hpp
/// A free rigid body's motion over one step: its pose (centre of mass and orientation) and
/// velocities under gravity, with no contact or coupling — the part of the rigid rows that
/// needs no other body (docs/ARCHITECTURE.md, "Bodies of more than one kind").
///
/// Translation: implicit Euler as the tissue's nodes (v += h·g, then x += h·v). Rotation: the
/// gyroscopic term ω × Iω does no work, so it must neither add nor remove energy; Euler's
/// equations in the body frame, I ω̇ = −ω × I ω, are stepped by the implicit midpoint rule (a
/// Newton solve of I (ω' − ω) + h ω̄ × I ω̄ = 0 with ω̄ = (ω + ω') / 2), which keeps both of
/// their quadratic invariants — the kinetic energy ½ ωᵀIω and |Iω|, the angular momentum's
/// magnitude — to the solve's tolerance; the orientation turns by exp(h ω̄) in the body frame.
/// What it does not keep exactly is the angular momentum's direction in space (a second-order
/// error per step; measured in tests/rigid/test_rigid_motion.cpp).
///
/// Invariants: `q` is a unit quaternion (w, x, y, z), renormalised every step; the inertia is
/// the body frame's, symmetric positive definite (MassProperties' invariants).

#include <array>

#include "rigid/mass_properties.hpp"

namespace stroma {

/// A rigid body's state: everything its next step depends on.
struct RigidState {
  Vec3 x{0, 0, 0};                    ///< centre of mass, world (m)
  std::array<double, 4> q{1, 0, 0, 0};  ///< orientation body → world, unit (w, x, y, z)
  Vec3 v{0, 0, 0};                    ///< centre-of-mass velocity, world (m/s)
  Vec3 w{0, 0, 0};                    ///< angular velocity, world (rad/s)
};

/// What the rotation's solve did (the Newton iterations and the last residual, N·m·s).
struct RigidStepReport {
  int newton_iterations = 0;
  double residual = 0;
};

/// Rotation matrix (row-major) of a unit quaternion.
std::array<double, 9> rotation_of(const std::array<double, 4>& q);

/// One step of length h of a free body of body-frame inertia `inertia` under gravity g.
RigidStepReport step_free_rigid(const std::array<double, 9>& inertia, const Vec3& g, double h, RigidState& s);

/// The body touching something (its rows in the step's system, tissue/rigid_rows.hpp) is
/// stepped in two parts. First the gyroscopic part alone: ω after Euler's torque-free equations
/// over h by the same implicit midpoint rule, the orientation held (the kinetic energy and |L|
/// kept exactly); returns that ω (world). The rows then add the step's Δu (contact, gravity).
Vec3 gyroscopic_step(const std::array<double, 9>& inertia, double h, const RigidState& s);
/// Then the pose over h from the step's end velocities: x += h·v, q ← exp(h·ω)·q (a turn
/// about ω itself, which keeps ½ωᵀI_world ω).
void advance_pose(double h, RigidState& s);
/// The inertia tensor in world axes, R I Rᵀ (row-major).
std::array<double, 9> world_inertia(const std::array<double, 9>& inertia, const std::array<double, 4>& q);

/// Kinetic energy ½ m |v|² + ½ ωᵀ I_world ω (J).
double rigid_kinetic_energy(double mass, const std::array<double, 9>& inertia, const RigidState& s);
/// Angular momentum about the centre of mass, world (kg·m²/s).
Vec3 rigid_angular_momentum(const std::array<double, 9>& inertia, const RigidState& s);

}  // namespace stroma
