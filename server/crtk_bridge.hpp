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
///   rt/T/operating_state  crtk_msgs/OperatingState     out  on every change and state command (transient-local)
///   rt/T/jaw/servo_jp     sensor_msgs/JointState       in   a grasper's jaw angle (rad, position[0]; dVRK's convention)
///   rt/T/jaw/measured_js  sensor_msgs/JointState       out  the jaw angle the tick applied ("jaw"), every tick
///
/// The jaw (graspers only): the newest valid angle is kept and goes in with every servo_cp pose
/// after it; set alone (no pose in the same take) it goes in with the last pose sent. Before any,
/// the jaw is 0 (closed), as for a client that never sets it. Refused (counted, logged): stamp 0,
/// no position, a non-finite angle, a tool not ENABLED. jaw received = applied takes + superseded +
/// refused, where an applied take is the newest valid angle of one take and superseded the older
/// ones; the commands port checks the pose it rides with as any other.
/// Operating states: DISABLED (the start), ENABLED, PAUSED, FAULT; is_homed is always true (a
/// simulated tool needs no homing), is_busy always false (no trajectories run on the server).
/// State commands: enable (any state) and disable (any state); pause from ENABLED; resume from
/// PAUSED; home and unhome in any state, changing nothing (the device is always homed). Anything
/// else is refused and counted. operating_state is published after every state command, accepted
/// or refused, so a client that sends one and waits for the state always gets an answer.
///
/// servo_cp: every sample received is counted exactly once (received = accepted + superseded +
/// refused_*). Refused: a header stamp of 0 (CRTK: invalid data), a non-finite value, a quaternion
/// that is not a unit one (malformed data: refused, the state unchanged), a tool that is not
/// ENABLED. Of the valid poses taken together, the newest goes through the commands port
/// (engine/tool_commands.hpp) and the older are superseded (never checked, as Stroma's own
/// ToolCommand). A pose the tool's limits reject (workspace, speed; on_invalid: reject) puts the
/// tool in FAULT, which only `enable` (or `disable`) leaves. Every refusal and supersession also
/// counts in the port (SimStatus, --stats tool_commands) as any tool command does. Refusals that
/// do not FAULT are logged at most once a second (server/refusal_log.hpp).
///
/// measured_cp and measured_cf are published every tick in every state: the tool's pose in the
/// state (its `pose:` or script start before the first command) and the force on it.
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
#include "server/refusal_log.hpp"
#include "tissue/clock.hpp"

namespace stroma {

/// The CRTK operating states (crtk_msgs/OperatingState.state strings).
enum class CrtkState : uint8_t { Disabled, Enabled, Paused, Fault };
const char* crtk_state_name(CrtkState s);

/// What became of the CRTK inputs (atomics: read by the stats at exit and by tests).
/// Invariant: servo_received = servo_accepted + servo_superseded + servo_invalid +
/// servo_non_finite + servo_not_unit + servo_not_enabled + servo_limits.
struct CrtkCounters {
  std::atomic<uint64_t> servo_received{0};     ///< servo_cp samples taken from DDS
  std::atomic<uint64_t> servo_accepted{0};     ///< applied (the gate accepted or clamped them)
  std::atomic<uint64_t> servo_superseded{0};   ///< valid, but a newer pose of the tool came with them
  std::atomic<uint64_t> servo_invalid{0};      ///< header stamp 0: invalid data
  std::atomic<uint64_t> servo_non_finite{0};   ///< a NaN or infinite position or orientation
  std::atomic<uint64_t> servo_not_unit{0};     ///< orientation not a unit quaternion (|q| off by > 1e-3)
  std::atomic<uint64_t> servo_not_enabled{0};  ///< the tool was DISABLED, PAUSED or in FAULT
  std::atomic<uint64_t> servo_limits{0};       ///< rejected by the tool's limits: FAULT
  std::atomic<uint64_t> jaw_received{0};       ///< jaw/servo_jp samples taken from DDS
  std::atomic<uint64_t> jaw_accepted{0};       ///< takes whose newest valid angle was applied
  std::atomic<uint64_t> jaw_superseded{0};     ///< valid angles a newer one in the same take replaced
  std::atomic<uint64_t> jaw_refused{0};        ///< stamp 0, no position, non-finite, not ENABLED
  std::atomic<uint64_t> commands_accepted{0};  ///< state commands that changed or kept a state
  std::atomic<uint64_t> commands_refused{0};   ///< unknown command, stamp 0, or not allowed in the state
  uint64_t servo_refused() const {
    return servo_invalid.load() + servo_non_finite.load() + servo_not_unit.load() + servo_not_enabled.load() +
           servo_limits.load();
  }
};

class CrtkBridge {
 public:
  /// Creates the topics, readers and writers of every tool on `participant`, attaches the
  /// readers to `waitset` (the input thread's) and publishes each tool's initial DISABLED state.
  CrtkBridge(dds_entity_t participant, const Model& model, dds_entity_t waitset);
  ~CrtkBridge();
  CrtkBridge(const CrtkBridge&) = delete;
  CrtkBridge& operator=(const CrtkBridge&) = delete;

  /// Input thread: takes state commands, then every servo_cp sample waiting (the newest valid
  /// one per tool goes through `port`).
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
  /// The newest valid jaw angle waiting into t.jaw (its stamp into *stamp); false if none.
  bool take_jaw(Tool& t, int64_t* stamp);
  /// A pose (with its jaw) through the commands port; false (and FAULT) if the tool's limits
  /// reject it. `what` names the input in the log.
  bool submit(Tool& t, int index, ToolCommandPort& port, const ToolPose& pose, int64_t stamp, const char* what);
  void refuse_servo(Tool& t, std::atomic<uint64_t>& counter, ToolCommandPort& port, const char* why);

  const Model& model_;
  std::vector<std::unique_ptr<Tool>> tools_;
  CrtkCounters cnt_;
  RefusalLog refusals_;  ///< input thread only
};

}  // namespace stroma
