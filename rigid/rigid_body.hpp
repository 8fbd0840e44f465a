#pragma once
/// \file rigid_body.hpp
/// A compiled rigid body (issue 42; docs/RIGID.md): the constants its rows of the step read. Its
/// body frame has its origin at the centre of mass and the shape's axes, so `mass.centre` is
/// zero and `shape_origin` is where the shape's own frame origin (the one the scenario poses)
/// sits in it.
///
/// Invariants: `mass` satisfies MassProperties' invariants with centre (0, 0, 0); `initial.q` is
/// a unit quaternion; a fixed body's initial velocities are zero; `surface_triangles` index
/// `surface_vertices` (body frame), and are empty for the analytic shapes.

#include <string>
#include <vector>

#include "rigid/mass_properties.hpp"
#include "rigid/needle_shape.hpp"
#include "rigid/rigid_motion.hpp"

namespace stroma {

enum class RigidShape : uint8_t { Sphere, Box, Capsule, Mesh, Needle };

struct RigidBodyModel {
  std::string name;
  RigidShape shape = RigidShape::Sphere;
  double radius = 0, length = 0;  ///< sphere, capsule (m)
  Vec3 size{0, 0, 0};             ///< box (m)
  NeedleGeometry needle;          ///< a needle's wire and curve (shape frame; rigid/needle_shape.hpp)
  MassProperties mass;            ///< about the centre of mass, body frame
  Vec3 shape_origin{0, 0, 0};     ///< the shape frame's origin in the body frame (m)
  std::vector<Vec3> surface_vertices;  ///< a mesh shape's surface, body frame
  std::vector<Tri> surface_triangles;
  bool fixed = false;
  RigidState initial;             ///< centre of mass, orientation and velocities at the start
  /// Contact (rigid/rigid_contact.hpp): pressure per metre of penetration (Pa/m), per metre per
  /// second (Pa·s/m), and the Coulomb friction coefficient against tissue and other bodies.
  double contact_stiffness = 0, contact_damping = 0, friction = 0;
  double bounding_radius = 0;     ///< m: the shape lies within this distance of the centre of mass
  /// The smallest feature's size (m): a sphere's or capsule's radius, half a box's shortest side,
  /// a mesh's mean edge; contact samples are spaced by a fraction of it.
  double feature = 0;
  /// Surface samples in the body frame (point, outward normal, area): how this body presses on
  /// another rigid body's shape (rigid/rigid_contact.hpp). Invariant: the areas sum to the surface's.
  std::vector<Vec3> sample_points, sample_normals;
  std::vector<double> sample_areas;
  /// A needle's wire, as it presses on the tissue's surface (rigid/wire_contact.hpp): points of
  /// its curve (body frame) from the tail to one wire radius short of its end, each with its arc
  /// length and its share of the arc length (m). Invariant: empty unless a needle; at most
  /// kMaxWireSamples, the same count in each; arcs increasing; the shares sum to the last arc.
  std::vector<Vec3> wire_axis;
  std::vector<double> wire_arc, wire_share;
  /// A needle's track points at most (rigid/needle_track.hpp; NeedleState::track's size).
  int32_t track_capacity = 0;
};

}  // namespace stroma
