#pragma once
/// \file trajectory.hpp
/// Timed tool trajectories: keyframes of (time, position, orientation, jaw, buttons), sampled
/// with linear interpolation of position and jaw and slerp of orientation. The same files drive
/// `stroma tool --script` over DDS and `tools: [{script}]` in headless runs.
///
/// YAML:  keyframes: [{t: 0, position: [x, y, z], orientation: [w, x, y, z], jaw: 0, buttons: 0}, ...]
/// CSV:   header naming the columns, any order: t,x,y,z (required), qw,qx,qy,qz, jaw, buttons.

#include <cmath>
#include <string>
#include <vector>

#include "haptics/tool.hpp"

namespace stroma {

/// One keyframe.
struct Keyframe {
  double t = 0;
  ToolPose pose;
};

/// A trajectory: keyframes with strictly increasing times (at least one).
class Trajectory {
 public:
  std::vector<Keyframe> keys;
  /// Pose at time t: held at the first/last keyframe outside their range; buttons are those of
  /// the keyframe at or before t.
  ToolPose sample(double t) const;
  /// Pose at time t of the script repeated from its start every end_time() (t mod end_time; a
  /// single keyframe, or an end at t ≤ 0, is held). A script meant to loop ends where it starts.
  ToolPose sample_looping(double t) const {
    const double end = end_time();
    return end > 0 && t > end ? sample(std::fmod(t, end)) : sample(t);
  }
  double end_time() const { return keys.empty() ? 0.0 : keys.back().t; }
};

/// The pose a fraction u ∈ [0, 1] of the way from a to b: position and jaw linear, orientation
/// by slerp (shortest arc), buttons those of a.
ToolPose interpolate_pose(const ToolPose& a, const ToolPose& b, double u);

/// Reads a .yaml/.yml or .csv trajectory. Throws InputError (file, line, field) on bad input:
/// missing column, non-numeric value, non-increasing time, non-unit quaternion.
Trajectory load_trajectory(const std::string& path);
/// Parses CSV text (`source` names it in errors).
Trajectory parse_trajectory_csv(const std::string& text, const std::string& source);

}  // namespace stroma
