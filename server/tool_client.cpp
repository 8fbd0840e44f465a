#include "server/tool_client.hpp"

#include <time.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <sstream>
#include <stdexcept>
#include <thread>
#include <vector>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "dds/dds_participant.hpp"
#include "engine/trajectory.hpp"
#include "runtime/realtime.hpp"
#include "ros_crtk.h"
#include "stroma.h"

namespace stroma {

namespace {

int64_t mono_ns() {
  timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<int64_t>(ts.tv_sec) * 1000000000LL + ts.tv_nsec;
}

/// Per command: when it was sent and when its seq first came back in a feedback.
struct Sent {
  int64_t sent_ns = 0;
  std::atomic<int64_t> received_ns{0};
  std::atomic<double> force[3] = {0, 0, 0};
  // CRTK: measured_cp carries no seq; a pose comes back as itself (bit for bit). Only a pose
  // that differs from the one sent before it can be told apart, so only those are timed.
  double position[3] = {0, 0, 0};
  bool distinct = true;
};

/// Parses a stdin command line: "x y z [qw qx qy qz] [jaw]". False if malformed.
bool parse_line(const std::string& line, ToolPose& p) {
  std::istringstream ss(line);
  std::vector<double> v;
  double d;
  while (ss >> d) v.push_back(d);
  if (!ss.eof() || (v.size() != 3 && v.size() != 4 && v.size() != 7 && v.size() != 8)) return false;
  p.position = {v[0], v[1], v[2]};
  if (v.size() >= 7) p.orientation = {v[3], v[4], v[5], v[6]};
  if (v.size() == 4) p.jaw = v[3];
  if (v.size() == 8) p.jaw = v[7];
  return true;
}

/// The client's two endpoints: commands out (best effort, keep last 1), feedback in (keep 64).
struct ToolEndpoints {
  dds_entity_t writer = 0, reader = 0;
};

/// `partition` (protected domain): the command writer publishes in it — the tool's name, which
/// the client's permissions must grant (DDS Security refuses the writer otherwise).
ToolEndpoints open_endpoints(dds_entity_t participant, const std::string& partition) {
  const dds_entity_t t_cmd = dds_check(dds_create_topic(participant, &stroma_ToolCommand_desc, "stroma_ToolCommand", nullptr, nullptr), "topic");
  const dds_entity_t t_fb = dds_check(dds_create_topic(participant, &stroma_ToolFeedback_desc, "stroma_ToolFeedback", nullptr, nullptr), "topic");
  dds_qos_t* q = dds_create_qos();
  dds_qset_reliability(q, DDS_RELIABILITY_BEST_EFFORT, 0);
  dds_qset_history(q, DDS_HISTORY_KEEP_LAST, 1);
  ToolEndpoints ep;
  dds_entity_t publisher = participant;
  if (!partition.empty()) {
    dds_qos_t* qp = dds_create_qos();
    dds_qset_partition1(qp, partition.c_str());
    publisher = dds_check(dds_create_publisher(participant, qp, nullptr), "publisher (tool partition)");
    dds_delete_qos(qp);
  }
  const dds_entity_t w = dds_create_writer(publisher, t_cmd, q, nullptr);
  if (w < 0 && !partition.empty())
    throw std::runtime_error(fmt::format("commanding tool '{}' is not permitted to this identity ({})", partition,
                                         dds_strretcode(w)));
  ep.writer = dds_check(w, "writer stroma_ToolCommand");
  dds_qset_history(q, DDS_HISTORY_KEEP_LAST, 64);
  ep.reader = dds_check(dds_create_reader(participant, t_fb, q, nullptr), "reader");
  dds_delete_qos(q);
  return ep;
}

/// Writes stroma_Control RESUME (reliable) once a server reads it; false (logged) if none does
/// within `seconds` or this identity may not write Control.
bool resume_server(dds_entity_t participant, double seconds) {
  const dds_entity_t topic = dds_create_topic(participant, &stroma_Control_desc, "stroma_Control", nullptr, nullptr);
  dds_qos_t* q = dds_create_qos();
  dds_qset_reliability(q, DDS_RELIABILITY_RELIABLE, DDS_SECS(1));
  dds_qset_history(q, DDS_HISTORY_KEEP_ALL, 0);
  const dds_entity_t w = topic < 0 ? topic : dds_create_writer(participant, topic, q, nullptr);
  dds_delete_qos(q);
  if (w < 0) {
    spdlog::error("--resume: cannot write stroma_Control ({}): on a protected domain only an operator identity may",
                  dds_strretcode(w));
    return false;
  }
  const int64_t end = mono_ns() + static_cast<int64_t>(seconds * 1e9);
  dds_publication_matched_status_t ms{};
  while ((dds_get_publication_matched_status(w, &ms), ms.current_count == 0) && mono_ns() < end)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  if (ms.current_count == 0) {
    spdlog::error("--resume: no server reads stroma_Control after {:.0f} s", seconds);
    return false;
  }
  stroma_Control c{};
  c.command = stroma_RESUME;
  c.seq = 1;
  if (dds_write(w, &c) < 0) {
    spdlog::error("--resume: writing RESUME failed");
    return false;
  }
  spdlog::info("resumed the server");
  return true;
}

/// Waits until a server reads the command topic (commands sent before matching are lost).
bool wait_for_server(dds_entity_t writer, double seconds) {
  const int64_t wait_end = mono_ns() + static_cast<int64_t>(seconds * 1e9);
  dds_publication_matched_status_t ms{};
  while ((dds_get_publication_matched_status(writer, &ms), ms.current_count == 0) && mono_ns() < wait_end)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  return ms.current_count > 0;
}

/// A receiver thread's loop: waits on `reader`, takes what arrived and calls
/// on_sample(sample, arrival_ns) for each valid sample, until `done`.
template <class OnSample>
void receive_until(dds_entity_t participant, dds_entity_t reader, const std::atomic<bool>& done, OnSample&& on_sample) {
  const dds_entity_t ws = dds_create_waitset(participant);
  const dds_entity_t rc = dds_create_readcondition(reader, DDS_ANY_STATE);
  dds_waitset_attach(ws, rc, reader);
  void* samples[64] = {nullptr};
  dds_sample_info_t infos[64];
  while (!done.load()) {
    dds_waitset_wait(ws, nullptr, 0, DDS_MSECS(50));
    const dds_return_t n = dds_take(reader, samples, infos, 64, 64);
    const int64_t now = mono_ns();
    for (dds_return_t i = 0; i < n; ++i)
      if (infos[i].valid_data) on_sample(samples[i], now);
    if (n > 0) dds_return_loan(reader, samples, n);
  }
}

/// Receiver thread: every feedback of tool `name` marks the commands up to the seq it echoes
/// as arrived (the echoed one with its force) until `done`.
void receive_feedback(dds_entity_t participant, dds_entity_t reader, const std::string& name, std::vector<Sent>& sent,
                      const std::atomic<bool>& done, std::atomic<uint64_t>& feedback_msgs) {
  const uint64_t capacity = sent.size() - 1;
  uint64_t acked = 0;
  receive_until(participant, reader, done, [&](const void* sample, int64_t now) {
    const auto* f = static_cast<const stroma_ToolFeedback*>(sample);
    if (name != f->tool) return;
    feedback_msgs.fetch_add(1);
    const uint64_t s = std::min<uint64_t>(f->seq, capacity);
    if (s > acked && sent[s].sent_ns != 0) {
      sent[s].received_ns.store(now);
      for (int c = 0; c < 3; ++c) sent[s].force[c].store(f->force[c]);
    }
    acked = std::max(acked, s);
  });
}

/// CRTK endpoints of one device (docs/CRTK.md): servo_cp and state_command out, measured_cp and
/// operating_state in — ROS 2's topic names and types (dds/ros_crtk.idl).
struct CrtkEndpoints {
  dds_entity_t servo = 0, command = 0, measured = 0, state = 0;
  dds_entity_t jaw = 0;  ///< rt/<tool>/jaw/servo_jp (0: not permitted to this identity)
};

CrtkEndpoints open_crtk_endpoints(dds_entity_t pp, const std::string& tool) {
  const std::string ns = "rt/" + tool + "/";
  auto topic = [&](const dds_topic_descriptor_t* d, const char* leaf) {
    return dds_check(dds_create_topic(pp, d, (ns + leaf).c_str(), nullptr, nullptr), "CRTK topic");
  };
  dds_qos_t* fast = dds_create_qos();  // as Stroma's own commands: the newest pose only
  dds_qset_reliability(fast, DDS_RELIABILITY_BEST_EFFORT, 0);
  dds_qset_history(fast, DDS_HISTORY_KEEP_LAST, 1);
  dds_qos_t* reliable = dds_create_qos();
  dds_qset_reliability(reliable, DDS_RELIABILITY_RELIABLE, DDS_SECS(1));
  dds_qset_history(reliable, DDS_HISTORY_KEEP_LAST, 16);
  dds_qos_t* latched = dds_create_qos();
  dds_qset_reliability(latched, DDS_RELIABILITY_RELIABLE, DDS_SECS(1));
  dds_qset_durability(latched, DDS_DURABILITY_TRANSIENT_LOCAL);
  dds_qset_history(latched, DDS_HISTORY_KEEP_LAST, 16);
  dds_qos_t* feedback = dds_create_qos();
  dds_qset_reliability(feedback, DDS_RELIABILITY_BEST_EFFORT, 0);
  dds_qset_history(feedback, DDS_HISTORY_KEEP_LAST, 64);
  CrtkEndpoints ep;
  const dds_entity_t w = dds_create_writer(pp, topic(&geometry_msgs_msg_dds__PoseStamped__desc, "servo_cp"), fast, nullptr);
  if (w < 0)
    throw std::runtime_error(fmt::format("writing rt/{}/servo_cp is not permitted to this identity ({})", tool,
                                         dds_strretcode(w)));
  ep.servo = w;
  ep.command = dds_check(dds_create_writer(pp, topic(&crtk_msgs_msg_dds__StringStamped__desc, "state_command"), reliable, nullptr),
                         "writer state_command");
  // The jaw (a grasper's; dVRK's convention): reliable, as it changes seldom and must arrive.
  const dds_entity_t jt = dds_create_topic(pp, &sensor_msgs_msg_dds__JointState__desc, (ns + "jaw/servo_jp").c_str(), nullptr, nullptr);
  const dds_entity_t jw = jt < 0 ? jt : dds_create_writer(pp, jt, reliable, nullptr);
  if (jw < 0)
    spdlog::warn("CRTK: writing rt/{}/jaw/servo_jp is not permitted to this identity ({}): the jaw stays as the server has it",
                 tool, dds_strretcode(jw));
  else
    ep.jaw = jw;
  ep.measured = dds_check(dds_create_reader(pp, topic(&geometry_msgs_msg_dds__PoseStamped__desc, "measured_cp"), feedback, nullptr),
                          "reader measured_cp");
  ep.state = dds_check(dds_create_reader(pp, topic(&crtk_msgs_msg_dds__OperatingState__desc, "operating_state"), latched, nullptr),
                       "reader operating_state");
  for (dds_qos_t* q : {fast, reliable, latched, feedback}) dds_delete_qos(q);
  return ep;
}

builtin_interfaces_msg_dds__Time_ ros_time_now() {
  timespec ts;
  clock_gettime(CLOCK_REALTIME, &ts);
  return {static_cast<int32_t>(ts.tv_sec), static_cast<uint32_t>(ts.tv_nsec)};
}

/// The device's operating state once it is `want` (or "" after `seconds`).
std::string wait_crtk_state(const CrtkEndpoints& ep, const char* want, double seconds) {
  const int64_t end = mono_ns() + static_cast<int64_t>(seconds * 1e9);
  std::string last;
  while (mono_ns() < end) {
    void* samples[16] = {nullptr};
    dds_sample_info_t infos[16];
    const dds_return_t n = dds_take(ep.state, samples, infos, 16, 16);
    for (dds_return_t i = 0; i < n; ++i)
      if (infos[i].valid_data) last = static_cast<const crtk_msgs_msg_dds__OperatingState_*>(samples[i])->state;
    if (n > 0) dds_return_loan(ep.state, samples, n);
    if (last == want) return last;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return "";
}

/// Receiver thread (CRTK): each measured_cp marks the newest distinct pose it carries as arrived.
void receive_measured(dds_entity_t participant, dds_entity_t reader, std::vector<Sent>& sent,
                      const std::atomic<uint64_t>& sent_count, const std::atomic<bool>& done,
                      std::atomic<uint64_t>& feedback_msgs) {
  uint64_t acked = 0;
  receive_until(participant, reader, done, [&](const void* sample, int64_t now) {
    feedback_msgs.fetch_add(1);
    const uint64_t newest = sent_count.load(std::memory_order_acquire);
    const auto& p = static_cast<const geometry_msgs_msg_dds__PoseStamped_*>(sample)->pose.position;
    // The pose applied in that tick: one of the last poses sent (the server applies the newest).
    for (uint64_t k = newest; k > acked && k + 64 > newest; --k) {
      if (sent[k].position[0] == p.x && sent[k].position[1] == p.y && sent[k].position[2] == p.z) {
        if (sent[k].distinct && sent[k].received_ns.load() == 0) sent[k].received_ns.store(now);
        acked = k;
        break;
      }
    }
  });
}

/// Writes the CSV log and prints the summary line; returns the number of commands echoed.
uint64_t report(const ToolClientOptions& o, const std::vector<Sent>& sent, uint64_t seq, int64_t t0,
                uint64_t feedback_msgs) {
  std::vector<double> rtt;
  uint64_t echoed = 0;
  std::FILE* csv = o.out_csv.empty() ? nullptr : std::fopen(o.out_csv.c_str(), "w");
  if (!o.out_csv.empty() && !csv) spdlog::error("cannot write '{}'", o.out_csv);
  if (csv) std::fputs("seq,sent_s,received_s,round_trip_ms,fx,fy,fz\n", csv);
  uint64_t timed = 0;  // commands that can come back told apart (all, but for CRTK's repeated poses)
  for (uint64_t k = 1; k <= seq; ++k) {
    timed += sent[k].distinct;
    const int64_t r = sent[k].received_ns.load();
    if (r) {
      ++echoed;
      rtt.push_back(static_cast<double>(r - sent[k].sent_ns) * 1e-6);
    }
    if (csv)
      std::fprintf(csv, "%llu,%.9f,%s,%s,%.9g,%.9g,%.9g\n", static_cast<unsigned long long>(k),
                   static_cast<double>(sent[k].sent_ns - t0) * 1e-9,
                   r ? fmt::format("{:.9f}", static_cast<double>(r - t0) * 1e-9).c_str() : "",
                   r ? fmt::format("{:.4f}", static_cast<double>(r - sent[k].sent_ns) * 1e-6).c_str() : "",
                   sent[k].force[0].load(), sent[k].force[1].load(), sent[k].force[2].load());
  }
  if (csv) std::fclose(csv);
  auto pct = [&](double q) {
    if (rtt.empty()) return 0.0;
    std::vector<double> v = rtt;
    const size_t k = std::min(v.size() - 1, static_cast<size_t>(q * v.size()));
    std::nth_element(v.begin(), v.begin() + k, v.end());
    return v[k];
  };
  fmt::print("tool '{}'{}: {} commands sent, {} feedback messages, {} commands echoed ({} superseded or lost, {:.2f} %); "
             "round trip ms p50 {:.3f} p99 {:.3f} max {:.3f}\n",
             o.name, o.crtk ? " (CRTK)" : "", seq, feedback_msgs, echoed, timed - echoed,
             timed ? 100.0 * static_cast<double>(timed - echoed) / static_cast<double>(timed) : 0.0, pct(0.5), pct(0.99),
             pct(1.0));
  return echoed;
}

}  // namespace

int run_tool_client(const ToolClientOptions& o) {
  Trajectory traj;
  if (!o.script.empty()) traj = load_trajectory(o.script);  // InputError → exit 2 in the CLI
  // The feedback arrives through Cyclone's receive threads: real-time like the client's own
  // threads (55), unless --no-realtime.
  const DdsParticipant pp =
      create_participant(o.domain, o.dds_config, o.realtime ? 55 : 0, o.security_dir, o.identity);
  spdlog::info("DDS domain {}: {}", o.domain, pp.config_source);
  ToolEndpoints ep;
  CrtkEndpoints cep;
  try {
    if (o.crtk) cep = open_crtk_endpoints(pp.participant, o.name);
    else ep = open_endpoints(pp.participant, o.security_dir.empty() ? "" : o.name);
  } catch (...) {
    close_dds(pp);
    throw;
  }
  if (!wait_for_server(o.crtk ? cep.command : ep.writer, o.wait_server)) {
    spdlog::error("no server is reading {} on domain {} after {:.0f} s",
                  o.crtk ? "rt/" + o.name + "/state_command (serve --crtk)" : std::string("stroma_ToolCommand"), o.domain,
                  o.wait_server);
    close_dds(pp);
    return 1;
  }
  if (o.crtk) {  // enable the device (docs/CRTK.md) and wait until it says ENABLED
    crtk_msgs_msg_dds__StringStamped_ c{};
    c.header.stamp = ros_time_now();
    c.header.frame_id = const_cast<char*>("");
    c.string = const_cast<char*>("enable");
    dds_write(cep.command, &c);
    if (wait_crtk_state(cep, "ENABLED", o.wait_server).empty()) {
      spdlog::error("CRTK device '{}' did not become ENABLED after 'enable' within {:.0f} s", o.name, o.wait_server);
      close_dds(pp);
      return 1;
    }
    spdlog::info("CRTK device '{}' ENABLED", o.name);
  }

  const double duration = o.duration > 0 ? o.duration : traj.keys.empty() ? 0.0 : traj.end_time();
  const size_t capacity = traj.keys.empty() ? 1000000 : static_cast<size_t>(duration * o.rate) + 2;
  std::vector<Sent> sent(capacity + 1);
  std::atomic<bool> done{false};
  std::atomic<uint64_t> feedback_msgs{0};
  std::atomic<uint64_t> sent_count{0};  // CRTK: published after each pose is recorded

  // A haptic bridge is a real-time client: ask for SCHED_FIFO (silently best effort if denied)
  // so the round trips measure the server, not the client's scheduling. Memory stays unlocked:
  // mlockall would fault in the whole send log at priority 55 and stall a renderer sharing the
  // core for ~0.1 s (seen in the demo).
  const RealtimeMode rt = o.realtime ? RealtimeMode::Auto : RealtimeMode::Off;
  std::thread receiver([&] {
    setup_realtime_thread(rt, -1, 55, 64 * 1024, false);
    if (o.crtk) receive_measured(pp.participant, cep.measured, sent, sent_count, done, feedback_msgs);
    else receive_feedback(pp.participant, ep.reader, o.name, sent, done, feedback_msgs);
  });

  setup_realtime_thread(rt, -1, 55, 64 * 1024, false);
  stroma_ToolCommand msg{};
  std::snprintf(msg.tool, sizeof(msg.tool), "%s", o.name.c_str());
  uint64_t seq = 0;
  int64_t t0 = mono_ns();
  geometry_msgs_msg_dds__PoseStamped_ pose_msg{};
  pose_msg.header.frame_id = const_cast<char*>("world");
  double last_jaw = 0;
  auto send = [&](const ToolPose& p) {
    if (seq >= capacity) return;
    if (o.crtk) {
      ++seq;
      Sent& e = sent[seq];
      for (int k = 0; k < 3; ++k) e.position[k] = p.position[k];
      e.distinct = seq == 1 || sent[seq - 1].position[0] != p.position[0] || sent[seq - 1].position[1] != p.position[1] ||
                   sent[seq - 1].position[2] != p.position[2];
      pose_msg.header.stamp = ros_time_now();
      pose_msg.pose.position = {p.position[0], p.position[1], p.position[2]};
      pose_msg.pose.orientation = {p.orientation[1], p.orientation[2], p.orientation[3], p.orientation[0]};
      if (cep.jaw != 0 && (seq == 1 || p.jaw != last_jaw)) {  // the jaw when it changes, before the pose
        sensor_msgs_msg_dds__JointState_ js{};
        char joint[] = "jaw";
        char* names[] = {joint};
        double angle = p.jaw;
        js.header = pose_msg.header;
        js.header.stamp = ros_time_now();
        js.name._length = js.name._maximum = 1;
        js.name._buffer = names;
        js.position._length = js.position._maximum = 1;
        js.position._buffer = &angle;
        dds_write(cep.jaw, &js);
        last_jaw = p.jaw;
      }
      e.sent_ns = mono_ns();
      sent_count.store(seq, std::memory_order_release);
      dds_write(cep.servo, &pose_msg);
      return;
    }
    msg.seq = ++seq;
    msg.client_time_ns = mono_ns();
    for (int k = 0; k < 3; ++k) msg.position[k] = p.position[k];
    for (int k = 0; k < 4; ++k) msg.orientation[k] = p.orientation[k];
    msg.jaw = p.jaw;
    msg.buttons = p.buttons;
    sent[seq].sent_ns = msg.client_time_ns;
    dds_write(ep.writer, &msg);
  };
  if (o.resume) {  // the first pose in, then RESUME a paused server; the script's clock starts then
    if (!traj.keys.empty()) send(traj.sample(0.0));
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    if (!resume_server(pp.participant, o.wait_server)) {
      done = true;
      receiver.join();
      close_dds(pp);
      return 1;
    }
    t0 = mono_ns();
  }
  if (!traj.keys.empty()) {  // the script at --rate, on absolute deadlines
    const int64_t period = static_cast<int64_t>(1e9 / o.rate);
    int64_t next = t0;
    int64_t last_report = t0;
    while (next - t0 <= static_cast<int64_t>(duration * 1e9)) {
      timespec ts{static_cast<time_t>(next / 1000000000LL), static_cast<long>(next % 1000000000LL)};
      clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr);
      const double t = static_cast<double>(next - t0) * 1e-9;
      send(o.loop ? traj.sample_looping(t) : traj.sample(t));
      next += period;
      if (next - last_report > 2000000000LL) {
        last_report = next;
        spdlog::info("sent {} commands, {:.1f} s of {:.1f} s", seq, (next - t0) * 1e-9, duration);
      }
    }
  } else {  // stdin lines as they come
    std::string line;
    int ln = 0;
    while (std::getline(std::cin, line)) {
      ++ln;
      if (line.empty() || line[0] == '#') continue;
      ToolPose p;
      if (!parse_line(line, p)) {
        spdlog::error("stdin:{}: expected 'x y z [qw qx qy qz] [jaw]', got '{}'", ln, line);
        continue;
      }
      send(p);
      if (o.duration > 0 && mono_ns() - t0 > static_cast<int64_t>(o.duration * 1e9)) break;
    }
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(200));  // last feedback in flight
  done = true;
  receiver.join();
  report(o, sent, seq, t0, feedback_msgs.load());
  close_dds(pp);
  return feedback_msgs.load() > 0 ? 0 : 1;
}

}  // namespace stroma
