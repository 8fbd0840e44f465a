#pragma once
/// \file contact.hpp
/// What a tool does to the tissue and what it feels, for one tick:
///  - virtual coupling: the proxy (the simulated tool) follows the device through a spring and
///    is stopped by the tissue (one implicit quasi-static step per tick);
///  - contact: the tool's shape (sphere tip, or probe = tip + capsule shaft) against the surface
///    triangles the BVH returns, sampled at the centroids of s² sub-triangles (composite midpoint
///    rule); a sample inside the shape gets a penalty pressure k·depth over its share of the area,
///    along the shape's distance gradient (conservative), or along the inward surface normal when
///    the shape's axis is already below that point (deep penetration). Stiffness and damping go
///    into the implicit system as ContactSprings;
///  - grasping: closing the jaws attaches the closest surface points by springs in the tool frame;
///  - outputs: where the contacts were found, the force, torque and dF/dx of the tissue on the
///    tool and the range of its springs; the tick re-evaluates the force at the end of the step
///    and computes what the device renders (haptics/feedback.hpp).
/// No allocation: springs are appended to a vector whose capacity is fixed at load.

#include <array>
#include <cstdint>
#include <vector>

#include "collision/contact_surface.hpp"
#include "collision/triangle_bvh.hpp"
#include "haptics/tool.hpp"
#include "tissue/contact_spring.hpp"

namespace stroma {

/// A cutting blade's bevel: its half-thickness reaches `radius` this many radii behind the edge
/// (a wedge of half-angle atan(1/8) ≈ 7°, as a scalpel's grind).
inline constexpr double kBladeBevel = 8.0;

/// Coupling, grasp and contact of one tool at surface point positions x (collision/
/// contact_surface.hpp; the BVH already refitted to them): moves the proxy (coupling), fills
/// `out` (contacts, energy, and force, torque and stiffness as found at x) and appends the
/// tool's springs (on the DOFs) — recording their range in out — dropping, and counting, beyond
/// capacity. `v` (DOF velocities) and `dt` are for friction (relative sliding velocity); v may
/// be null when the tool has no friction. A tool never commanded, or idle
/// (ToolState::active false: silent past its `timeout`), touches nothing and releases its grasp.
void tool_contact(const ToolSpec& spec, ToolState& ts, ToolOutput& out, const ContactSurface& surf,
                  const TriangleBvh& bvh, const double* x, const double* v, double dt,
                  std::vector<ContactSpring>& springs);

}  // namespace stroma
