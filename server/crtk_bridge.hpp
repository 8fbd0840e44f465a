#pragma once
/// \file crtk_bridge.hpp
/// `stroma serve --crtk`: each tool as a CRTK device on ROS 2's DDS conventions (docs/CRTK.md),
/// so a ROS 2 node drives it and feels its force with no bridge and no ROS on the server.
///
/// Per tool T (topic names as ROS 2 puts them on DDS, types from dds/ros_crtk.idl):
///   rt/T/servo_cp         geometry_msgs/PoseStamped    in   the device pose, pre-emptive (newest wins)
///   rt/T/state_command    crtk_msgs/StringStamped      in   enable | disable | pause | resume
///   rt/T/measured_cp      geometry_msgs/PoseStamped    out  the tool's pose, every tick
///   rt/T/measured_cf      geometry_msgs/WrenchStamped  out  the tissue's force and torque on it, every tick
///   rt/T/operating_state  crtk_msgs/OperatingState     out  on every change (transient-local: late joiners get it)
///
/// Operating states: DISABLED (the start), ENABLED, PAUSED, FAULT; is_homed is always true (a
/// simulated tool needs no homing), is_busy always false (no trajectories run on the server).
/// servo_cp is applied only while ENABLED. It is refused and counted when its header stamp is 0
/// (CRTK: invalid data), when a value is not finite, or when the tool is not ENABLED; a pose the
/// tool's limits reject (workspace, speed; on_invalid: reject) puts the tool in FAULT, which only
/// `enable` (or `disable`) leaves. Accepted poses go through the same commands port (engine/tool_commands.hpp) as Stroma's own
/// ToolCommand, so both count in SimStatus alike.
///
/// Threads: take_inputs() runs on the server's input thread (its readers are attached to that
/// thread's waitset), publish_feedback() on the feedback thread; they share only atomics.

#include <atomic>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <dds/dds.h>
#include <nlohmann/json.hpp>

#include "engine/model.hpp"
#include "engine/tool_commands.hpp"
#include "runtime/physics_loop.hpp"
#include "tissue/clock.hpp"

namespace stroma {

/// The CRTK operating states (crtk_msgs/OperatingState.state strings).
enum class CrtkState : uint8_t { Disabled, Enabled, Paused, Fault };
const char* crtk_state_name(CrtkState s);

/// What became of the CRTK inputs (atomics: read by the stats at exit and by tests).
struct CrtkCounters {
  std::atomic<uint64_t> servo_accepted{0};     ///< applied (the gate accepted or clamped them)
  std::atomic<uint64_t> servo_invalid{0};      ///< header stamp 0: invalid data
  std::atomic<uint64_t> servo_non_finite{0};   ///< a NaN or infinite position or orientation
  std::atomic<uint64_t> servo_not_enabled{0};  ///< the tool was DISABLED, PAUSED or in FAULT
  std::atomic<uint64_t> servo_limits{0};       ///< rejected by the tool's limits: FAULT
  std::atomic<uint64_t> commands_accepted{0};  ///< state commands that changed or kept a state
  std::atomic<uint64_t> commands_refused{0};   ///< unknown command, stamp 0, or not allowed in the state
};

class CrtkBridge {
 public:
  /// Creates the topics, readers and writers of every tool on `participant`, attaches the
  /// readers to `waitset` (the input thread's) and publishes each tool's initial DISABLED state.
  CrtkBridge(dds_entity_t participant, const Model& model, dds_entity_t waitset);
  ~CrtkBridge();
  CrtkBridge(const CrtkBridge&) = delete;
  CrtkBridge& operator=(const CrtkBridge&) = delete;

  /// Input thread: takes state commands, then servo_cp samples (the newest per tool first
  /// wins), through `port`.
  void take_inputs(ToolCommandPort& port);
  /// Feedback thread: measured_cp and measured_cf of every tool for this tick.
  void publish_feedback(const FeedbackBatch& batch);

  CrtkState state(int tool) const;
  const CrtkCounters& counters() const { return cnt_; }
  nlohmann::ordered_json stats_json() const;

 private:
  struct Tool;
  void set_state(Tool& t, CrtkState s);
  void publish_state(Tool& t);
  void take_commands(Tool& t);
  void take_servo(Tool& t, int index, ToolCommandPort& port);

  const Model& model_;
  std::vector<std::unique_ptr<Tool>> tools_;
  CrtkCounters cnt_;
};

}  // namespace stroma
