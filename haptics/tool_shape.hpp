#pragma once
/// \file tool_shape.hpp
/// A tool's geometry as capsules (segments swept by spheres) in world coordinates: what contact
/// tests against and what the server publishes for renderers, so both see the same tool.

#include "haptics/tool.hpp"

namespace stroma {

/// A segment [a, b] swept by a sphere of radius r (a = b: a sphere).
struct Capsule {
  double a[3], b[3], r;
};

/// Where the simulated tool is: the proxy when the tool is coupled (once it has one), else the
/// commanded device position. Contact, grasping and what renderers draw all use this centre.
inline const Vec3& tool_center(const ToolSpec& spec, const ToolState& ts) {
  return spec.coupling_stiffness > 0 && ts.has_proxy ? ts.proxy : ts.pose.position;
}

/// Most capsules a tool shape has.
inline constexpr int kMaxCapsules = 3;

/// The tool's shape as capsules in world coordinates, the tool frame at centre c (x, z axes of
/// the pose's rotation). Sphere: one degenerate capsule. Probe: tip sphere + shaft along +z.
/// Blade: an edge along x, centred on c. Grasper: two jaws from c, opened ±jaw/2 about y.
/// Returns the number written to `out` (≤ kMaxCapsules; 0 for ToolShape::None).
int tool_capsules(const ToolSpec& spec, const ToolPose& pose, const double* c, Capsule* out);

}  // namespace stroma
