#include "haptics/tool.hpp"

#include <algorithm>
#include <cmath>

namespace stroma {

ToolCheck validate_tool_command(const ToolSpec& spec, const ToolPose& last, double dt,
                                const ToolPose& cmd) {
  ToolCheck c;
  c.pose = cmd;
  bool finite = std::isfinite(cmd.jaw);
  for (double v : cmd.position) finite = finite && std::isfinite(v);
  for (double v : cmd.orientation) finite = finite && std::isfinite(v);
  if (!finite) {
    c.result = ToolCheck::Rejected;
    c.cause = ToolCheck::Malformed;
    c.reason = "non-finite value";
    return c;
  }
  const auto& q = cmd.orientation;
  const double qn = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
  if (!(std::fabs(qn - 1.0) <= 1e-3)) {
    c.result = ToolCheck::Rejected;  // not a rotation: nothing sensible to clamp to
    c.cause = ToolCheck::Malformed;
    c.reason = "orientation is not a unit quaternion";
    return c;
  }
  for (double& v : c.pose.orientation) v /= qn;
  const bool clamp = spec.on_invalid == InvalidCommandPolicy::Clamp;
  bool outside = false;
  for (int k = 0; k < 3; ++k)
    outside = outside || cmd.position[k] < spec.workspace_min[k] || cmd.position[k] > spec.workspace_max[k];
  if (outside) {
    c.cause = ToolCheck::Limit;
    if (!clamp) {
      c.result = ToolCheck::Rejected;
      c.reason = "position outside the tool workspace";
      return c;
    }
    for (int k = 0; k < 3; ++k)
      c.pose.position[k] = std::clamp(cmd.position[k], spec.workspace_min[k], spec.workspace_max[k]);
    c.result = ToolCheck::Clamped;
    c.reason = "position outside the tool workspace";
  }
  if (dt > 0) {
    const double d[3] = {c.pose.position[0] - last.position[0], c.pose.position[1] - last.position[1],
                         c.pose.position[2] - last.position[2]};
    const double dist = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    const double limit = spec.max_speed * dt;
    if (dist > limit) {
      c.cause = ToolCheck::Limit;
      if (!clamp) {
        c.result = ToolCheck::Rejected;
        c.reason = "jump faster than the tool's max_speed";
        return c;
      }
      for (int k = 0; k < 3; ++k) c.pose.position[k] = last.position[k] + d[k] * (limit / dist);
      c.result = ToolCheck::Clamped;
      c.reason = "jump faster than the tool's max_speed";
    }
  }
  return c;
}

void quaternion_to_matrix(const std::array<double, 4>& q, double* R) {
  const double w = q[0], x = q[1], y = q[2], z = q[3];
  R[0] = 1 - 2 * (y * y + z * z); R[1] = 2 * (x * y - w * z);     R[2] = 2 * (x * z + w * y);
  R[3] = 2 * (x * y + w * z);     R[4] = 1 - 2 * (x * x + z * z); R[5] = 2 * (y * z - w * x);
  R[6] = 2 * (x * z - w * y);     R[7] = 2 * (y * z + w * x);     R[8] = 1 - 2 * (x * x + y * y);
}

}  // namespace stroma
