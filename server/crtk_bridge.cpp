#include "server/crtk_bridge.hpp"

#include <time.h>

#include <cmath>
#include <cstring>
#include <stdexcept>

#include <spdlog/spdlog.h>

#include "ros_crtk.h"
#include "dds/dds_participant.hpp"

namespace stroma {

namespace {

using PoseStamped = geometry_msgs_msg_dds__PoseStamped_;
using WrenchStamped = geometry_msgs_msg_dds__WrenchStamped_;
using OperatingState = crtk_msgs_msg_dds__OperatingState_;
using StringStamped = crtk_msgs_msg_dds__StringStamped_;
using JointState = sensor_msgs_msg_dds__JointState_;

char kWorldFrame[] = "world";

/// servo_cp reader history: 64 poses, 64 ms of a 1 kHz device between two takes of the input thread.
constexpr int kServoDepth = 64;

/// ROS time: the system clock (what a ROS 2 node's stamps are).
builtin_interfaces_msg_dds__Time_ ros_now() {
  timespec ts;
  clock_gettime(CLOCK_REALTIME, &ts);
  return {static_cast<int32_t>(ts.tv_sec), static_cast<uint32_t>(ts.tv_nsec)};
}

int64_t stamp_ns(const builtin_interfaces_msg_dds__Time_& t) {
  return static_cast<int64_t>(t.sec) * 1000000000LL + static_cast<int64_t>(t.nanosec);
}

dds_qos_t* qos(bool reliable, bool transient_local, int depth) {
  dds_qos_t* q = dds_create_qos();
  dds_qset_reliability(q, reliable ? DDS_RELIABILITY_RELIABLE : DDS_RELIABILITY_BEST_EFFORT, DDS_MSECS(100));
  dds_qset_history(q, DDS_HISTORY_KEEP_LAST, depth);
  if (transient_local) dds_qset_durability(q, DDS_DURABILITY_TRANSIENT_LOCAL);
  return q;
}

}  // namespace

const char* crtk_state_name(CrtkState s) {
  switch (s) {
    case CrtkState::Disabled: return "DISABLED";
    case CrtkState::Enabled: return "ENABLED";
    case CrtkState::Paused: return "PAUSED";
    case CrtkState::Fault: return "FAULT";
  }
  return "DISABLED";
}

struct CrtkBridge::Tool {
  std::string name;
  dds_entity_t servo_reader = 0, command_reader = 0;
  dds_entity_t cp_writer = 0, cf_writer = 0, state_writer = 0;
  dds_entity_t jaw_reader = 0, js_writer = 0;  ///< a grasper's jaw (0: not a grasper)
  std::atomic<CrtkState> state{CrtkState::Disabled};
  uint64_t seq = 0;  ///< commands submitted (the gate's seq for this source)
  // Input thread only: the jaw the device last set (its poses carry it), and the last pose sent
  // (a jaw set alone goes in with it).
  double jaw = 0;
  bool have_pose = false;
  ToolPose last_pose;
};

CrtkBridge::CrtkBridge(dds_entity_t pp, const Model& model, dds_entity_t waitset) : model_(model) {
  // Pre-emptive (only the newest pose is applied), but deep enough that the input thread takes
  // every pose that arrived since it last looked, so each is counted (applied, superseded or
  // refused) — a keep-last-1 reader overwrites unseen poses uncounted.
  dds_qos_t* q_servo = qos(false, false, kServoDepth);
  dds_qos_t* q_command = qos(true, false, 16);     // state commands are few and must not be lost
  dds_qos_t* q_measured = qos(true, false, 1);     // reliable keep-last 1: matches ROS 2's default
                                                   // (reliable) and sensor-data (best effort) readers
  dds_qos_t* q_state = qos(true, true, 1);         // the current state, for late joiners too
  for (const ToolSpec& spec : model.tools) {
    auto t = std::make_unique<Tool>();
    t->name = spec.name;
    const std::string ns = "rt/" + spec.name + "/";
    auto topic = [&](const dds_topic_descriptor_t* d, const char* leaf) {
      const std::string name = ns + leaf;
      const dds_entity_t e = dds_create_topic(pp, d, name.c_str(), nullptr, nullptr);
      if (e == DDS_RETCODE_NOT_ALLOWED_BY_SECURITY)
        throw std::runtime_error("CRTK topic " + name + ": not allowed by the security directory's permissions for "
                                 "'server' (a directory made by `stroma security init` before it covered --crtk): run "
                                 "`stroma security init NEW_DIR` with the same clients and serve with --security NEW_DIR");
      return dds_check(e, "CRTK topic");
    };
    const dds_entity_t servo = topic(&geometry_msgs_msg_dds__PoseStamped__desc, "servo_cp");
    const dds_entity_t command = topic(&crtk_msgs_msg_dds__StringStamped__desc, "state_command");
    const dds_entity_t cp = topic(&geometry_msgs_msg_dds__PoseStamped__desc, "measured_cp");
    const dds_entity_t cf = topic(&geometry_msgs_msg_dds__WrenchStamped__desc, "measured_cf");
    const dds_entity_t st = topic(&crtk_msgs_msg_dds__OperatingState__desc, "operating_state");
    t->servo_reader = dds_check(dds_create_reader(pp, servo, q_servo, nullptr), "CRTK reader servo_cp");
    t->command_reader = dds_check(dds_create_reader(pp, command, q_command, nullptr), "CRTK reader state_command");
    t->cp_writer = dds_check(dds_create_writer(pp, cp, q_measured, nullptr), "CRTK writer measured_cp");
    t->cf_writer = dds_check(dds_create_writer(pp, cf, q_measured, nullptr), "CRTK writer measured_cf");
    t->state_writer = dds_check(dds_create_writer(pp, st, q_state, nullptr), "CRTK writer operating_state");
    if (spec.can_grasp) {  // the dVRK's jaw: rt/T/jaw/servo_jp in, rt/T/jaw/measured_js out
      const dds_entity_t jaw = topic(&sensor_msgs_msg_dds__JointState__desc, "jaw/servo_jp");
      const dds_entity_t js = topic(&sensor_msgs_msg_dds__JointState__desc, "jaw/measured_js");
      t->jaw_reader = dds_check(dds_create_reader(pp, jaw, q_servo, nullptr), "CRTK reader jaw/servo_jp");
      t->js_writer = dds_check(dds_create_writer(pp, js, q_measured, nullptr), "CRTK writer jaw/measured_js");
    }
    for (const dds_entity_t r : {t->servo_reader, t->command_reader, t->jaw_reader}) {
      if (r == 0) continue;
      const dds_entity_t rc = dds_check(dds_create_readcondition(r, DDS_ANY_STATE), "CRTK read condition");
      dds_check(dds_waitset_attach(waitset, rc, r), "CRTK waitset attach");
    }
    publish_state(*t);
    tools_.push_back(std::move(t));
  }
  dds_delete_qos(q_servo);
  dds_delete_qos(q_command);
  dds_delete_qos(q_measured);
  dds_delete_qos(q_state);
  spdlog::info("CRTK: {} tool(s) as ROS 2 devices: rt/<tool>/{{servo_cp, state_command}} in, "
               "rt/<tool>/{{measured_cp, measured_cf, operating_state}} out; a grasper's jaw/servo_jp in, "
               "jaw/measured_js out (docs/CRTK.md)",
               tools_.size());
}

CrtkBridge::~CrtkBridge() = default;

CrtkState CrtkBridge::state(int tool) const { return tools_[tool]->state.load(); }  // the participant's deletion takes its entities along

void CrtkBridge::publish_state(Tool& t) {
  OperatingState msg{};
  msg.header.stamp = ros_now();
  msg.header.frame_id = kWorldFrame;
  msg.state = const_cast<char*>(crtk_state_name(t.state.load()));
  msg.is_homed = true;
  msg.is_busy = false;
  dds_write(t.state_writer, &msg);
}

namespace {

/// Takes every sample waiting in `reader`, 16 at a time, and calls each(sample) for the valid
/// ones (a loan returned before the next batch).
template <class Sample, class F>
void take_every(dds_entity_t reader, F&& each) {
  void* samples[16] = {nullptr};
  dds_sample_info_t infos[16];
  for (;;) {
    const dds_return_t n = dds_take(reader, samples, infos, 16, 16);
    for (dds_return_t i = 0; i < n; ++i)
      if (infos[i].valid_data) each(*static_cast<const Sample*>(samples[i]));
    if (n > 0) dds_return_loan(reader, samples, n);
    if (n < 16) break;
  }
}

}  // namespace

void CrtkBridge::set_state(Tool& t, CrtkState s) {
  if (t.state.load() == s) return;
  spdlog::info("CRTK: tool '{}' {} -> {}", t.name, crtk_state_name(t.state.load()), crtk_state_name(s));
  t.state.store(s);
  publish_state(t);
}

void CrtkBridge::take_commands(Tool& t) {
  take_every<StringStamped>(t.command_reader, [&](const StringStamped& sample) {
    const auto* c = &sample;
    const std::string cmd = c->string ? c->string : "";
    const CrtkState s = t.state.load();
    CrtkState next = s;
    bool ok = stamp_ns(c->header.stamp) != 0;
    if (ok) {
      if (cmd == "enable") next = CrtkState::Enabled;
      else if (cmd == "disable") next = CrtkState::Disabled;
      else if (cmd == "pause" && s == CrtkState::Enabled) next = CrtkState::Paused;
      else if (cmd == "resume" && s == CrtkState::Paused) next = CrtkState::Enabled;
      else if (cmd == "home" || cmd == "unhome") next = s;  // always homed: nothing to do
      else ok = false;
    }
    if (ok) {
      cnt_.commands_accepted.fetch_add(1);
    } else {
      cnt_.commands_refused.fetch_add(1);
      refusals_.refused("CRTK: tool '{}' state command '{}' refused in state {} ({})", t.name, cmd,
                        crtk_state_name(s),
                        stamp_ns(c->header.stamp) == 0 ? "header stamp 0: invalid data"
                        : (cmd == "pause" || cmd == "resume")
                            ? "allowed from ENABLED (pause) or PAUSED (resume) only"
                            : "known: enable, disable, pause, resume, home, unhome");
    }
    // The state after every command, accepted or refused: a client waits on it (CRTK devices
    // answer each command with their operating state).
    if (next != s) set_state(t, next);
    else publish_state(t);
  });
}

void CrtkBridge::refuse_servo(Tool& t, std::atomic<uint64_t>& counter, ToolCommandPort& port, const char* why) {
  counter.fetch_add(1);
  port.count_rejected();  // as any refused tool command (SimStatus, --stats tool_commands)
  refusals_.refused("CRTK: tool '{}' servo_cp refused: {}", t.name, why);
}

void CrtkBridge::take_servo(Tool& t, int index, ToolCommandPort& port) {
  bool have = false;  // the newest valid pose of this take, to apply
  ToolPose newest;
  int64_t newest_stamp = 0;
  uint64_t valid = 0;
  // Every pose waiting: the reader holds up to kServoDepth.
  take_every<PoseStamped>(t.servo_reader, [&](const PoseStamped& sample) {
    cnt_.servo_received.fetch_add(1);
    const auto* c = &sample;
    const int64_t stamp = stamp_ns(c->header.stamp);
    const auto& p = c->pose.position;
    const auto& q = c->pose.orientation;
    if (stamp == 0) {
      refuse_servo(t, cnt_.servo_invalid, port, "header stamp 0 (invalid data)");
      return;
    }
    bool finite = true;
    for (double v : {p.x, p.y, p.z, q.x, q.y, q.z, q.w}) finite = finite && std::isfinite(v);
    if (!finite) {
      refuse_servo(t, cnt_.servo_non_finite, port, "a non-finite position or orientation");
      return;
    }
    const double qn = std::sqrt(q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w);
    if (!(std::fabs(qn - 1.0) <= 1e-3)) {
      refuse_servo(t, cnt_.servo_not_unit, port, "the orientation is not a unit quaternion");
      return;
    }
    if (t.state.load() != CrtkState::Enabled) {
      refuse_servo(t, cnt_.servo_not_enabled, port, t.state.load() == CrtkState::Fault
                                                        ? "the tool is in FAULT (send enable)"
                                                        : "the tool is not ENABLED");
      return;
    }
    ++valid;
    have = true;
    newest.position = {p.x, p.y, p.z};
    newest.orientation = {q.w, q.x, q.y, q.z};  // ROS (x, y, z, w) -> Stroma (w, x, y, z)
    newest_stamp = stamp;
  });
  if (!have) return;
  if (valid > 1) {  // pre-emptive: the newest wins, the older are superseded unchecked
    cnt_.servo_superseded.fetch_add(valid - 1);
    port.count_superseded(valid - 1);
  }
  newest.jaw = t.jaw;
  if (submit(t, index, port, newest, newest_stamp, "servo_cp")) cnt_.servo_accepted.fetch_add(1);
  else cnt_.servo_limits.fetch_add(1);
}

bool CrtkBridge::submit(Tool& t, int index, ToolCommandPort& port, const ToolPose& pose, int64_t stamp,
                        const char* what) {
  t.last_pose = pose;
  t.have_pose = true;
  const ToolCheck chk = port.submit(index, pose, ++t.seq, stamp, steady_now_ns());
  if (chk.result != ToolCheck::Rejected) return true;
  spdlog::warn("CRTK: tool '{}' {} rejected ({}): FAULT until enabled again", t.name, what, chk.reason);
  set_state(t, CrtkState::Fault);
  return false;
}

bool CrtkBridge::take_jaw(Tool& t, int64_t* stamp_out) {
  if (t.jaw_reader == 0) return false;
  bool set = false;
  uint64_t valid = 0;
  take_every<JointState>(t.jaw_reader, [&](const JointState& sample) {
    cnt_.jaw_received.fetch_add(1);
    const auto* js = &sample;
    const int64_t stamp = stamp_ns(js->header.stamp);
    const char* why = nullptr;
    if (stamp == 0) why = "header stamp 0 (invalid data)";
    else if (js->position._length < 1) why = "no position (the jaw's angle is position[0])";
    else if (!std::isfinite(js->position._buffer[0])) why = "a non-finite jaw angle";
    else if (t.state.load() != CrtkState::Enabled) why = "the tool is not ENABLED";
    if (why) {
      cnt_.jaw_refused.fetch_add(1);
      refusals_.refused("CRTK: tool '{}' jaw/servo_jp refused: {}", t.name, why);
      return;
    }
    ++valid;
    t.jaw = js->position._buffer[0];
    *stamp_out = stamp;
    set = true;
  });
  if (valid > 1) cnt_.jaw_superseded.fetch_add(valid - 1);
  if (valid > 0) cnt_.jaw_accepted.fetch_add(1);
  return set;
}

void CrtkBridge::take_inputs(ToolCommandPort& port) {
  for (size_t k = 0; k < tools_.size(); ++k) {
    Tool& t = *tools_[k];
    take_commands(t);
    int64_t jaw_stamp = 0;
    const bool jaw_set = take_jaw(t, &jaw_stamp);
    const uint64_t before = t.seq;
    take_servo(t, static_cast<int>(k), port);
    if (jaw_set && t.seq == before && t.have_pose) {  // a jaw set alone: with the last pose
      ToolPose p = t.last_pose;
      p.jaw = t.jaw;
      submit(t, static_cast<int>(k), port, p, jaw_stamp, "jaw/servo_jp");
    }
  }
}

void CrtkBridge::publish_feedback(const FeedbackBatch& b) {
  PoseStamped cp{};
  WrenchStamped cf{};
  JointState js{};
  char jaw_joint[] = "jaw";
  char* jaw_name[] = {jaw_joint};
  const auto now = ros_now();
  for (int i = 0; i < b.count; ++i) {
    const ToolFeedbackFrame& f = b.frames[i];
    if (f.tool < 0 || static_cast<size_t>(f.tool) >= tools_.size()) continue;
    Tool& t = *tools_[f.tool];
    cp.header.stamp = now;
    cp.header.frame_id = kWorldFrame;
    cp.pose.position = {f.pose.position[0], f.pose.position[1], f.pose.position[2]};
    cp.pose.orientation = {f.pose.orientation[1], f.pose.orientation[2], f.pose.orientation[3], f.pose.orientation[0]};
    dds_write(t.cp_writer, &cp);
    cf.header = cp.header;
    cf.wrench.force = {f.force[0], f.force[1], f.force[2]};
    cf.wrench.torque = {f.torque[0], f.torque[1], f.torque[2]};
    dds_write(t.cf_writer, &cf);
    if (t.js_writer != 0) {  // the jaw's angle as the tick applied it
      double angle = f.pose.jaw;
      js.header = cp.header;
      js.name._length = js.name._maximum = 1;
      js.name._buffer = jaw_name;
      js.position._length = js.position._maximum = 1;
      js.position._buffer = &angle;
      dds_write(t.js_writer, &js);
    }
  }
}

nlohmann::ordered_json CrtkBridge::stats_json() const {
  nlohmann::ordered_json j;
  uint64_t lost = 0;  // samples the DDS layer saw missing in transit (never received: not in received)
  for (const auto& t : tools_) {
    dds_sample_lost_status_t st{};
    if (dds_get_sample_lost_status(t->servo_reader, &st) == DDS_RETCODE_OK) lost += st.total_count;
  }
  j["servo_cp"] = {{"received", cnt_.servo_received.load()},
                   {"accepted", cnt_.servo_accepted.load()},
                   {"superseded", cnt_.servo_superseded.load()},
                   {"refused_invalid_stamp", cnt_.servo_invalid.load()},
                   {"refused_non_finite", cnt_.servo_non_finite.load()},
                   {"refused_not_unit_quaternion", cnt_.servo_not_unit.load()},
                   {"refused_not_enabled", cnt_.servo_not_enabled.load()},
                   {"refused_limits", cnt_.servo_limits.load()},
                   {"lost_in_transit", lost}};
  j["jaw_servo_jp"] = {{"received", cnt_.jaw_received.load()},
                       {"applied", cnt_.jaw_accepted.load()},
                       {"superseded", cnt_.jaw_superseded.load()},
                       {"refused", cnt_.jaw_refused.load()}};
  j["state_command"] = {{"accepted", cnt_.commands_accepted.load()}, {"refused", cnt_.commands_refused.load()}};
  nlohmann::ordered_json states;
  for (const auto& t : tools_) states[t->name] = crtk_state_name(t->state.load());
  j["operating_state"] = states;
  return j;
}

}  // namespace stroma
