#include "haptics/tool_shape.hpp"

#include <algorithm>
#include <cmath>

namespace stroma {

int tool_capsules(const ToolSpec& spec, const ToolPose& pose, const double* c, Capsule* out) {
  double Rm[9];
  quaternion_to_matrix(pose.orientation, Rm);
  const double ex[3] = {Rm[0], Rm[3], Rm[6]}, ez[3] = {Rm[2], Rm[5], Rm[8]};
  auto set = [&](Capsule& k, const double* dir, double from, double to, double r) {
    for (int i = 0; i < 3; ++i) {
      k.a[i] = c[i] + from * dir[i];
      k.b[i] = c[i] + to * dir[i];
    }
    k.r = r;
  };
  switch (spec.shape) {
    case ToolShape::Sphere:
      set(out[0], ez, 0, 0, spec.radius);
      return 1;
    case ToolShape::Probe:
      set(out[0], ez, 0, 0, spec.radius);
      set(out[1], ez, 0, spec.shaft_length, spec.shaft_radius);
      return 2;
    case ToolShape::Blade:
      set(out[0], ex, -0.5 * spec.shaft_length, 0.5 * spec.shaft_length, spec.radius);
      return 1;
    case ToolShape::Grasper: {
      const double h = 0.5 * std::max(0.0, pose.jaw);
      const double up[3] = {std::cos(h) * ez[0] + std::sin(h) * ex[0], std::cos(h) * ez[1] + std::sin(h) * ex[1],
                            std::cos(h) * ez[2] + std::sin(h) * ex[2]};
      const double dn[3] = {std::cos(h) * ez[0] - std::sin(h) * ex[0], std::cos(h) * ez[1] - std::sin(h) * ex[1],
                            std::cos(h) * ez[2] - std::sin(h) * ex[2]};
      set(out[0], up, 0, spec.shaft_length, spec.radius);
      set(out[1], dn, 0, spec.shaft_length, spec.radius);
      return 2;
    }
    case ToolShape::None:
      break;
  }
  return 0;
}

}  // namespace stroma
