// `stroma serve` as a separate process on loopback, driven and observed over DDS like a real
// client: late-joining mesh subscriber, status, pause / step / resume / reset / shutdown,
// SIGTERM. Each test uses its own DDS domain so ctest -j can run them side by side.

#include <gtest/gtest.h>

#include <set>

#include <sched.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <sstream>
#include <array>
#include <cmath>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "tests/test_labels.hpp"
#include "dds/dds_participant.hpp"
#include "runtime/realtime.hpp"
#include "tests/server/process.hpp"

using stroma::test::Process;
#include "stroma.h"

extern char** environ;

using namespace stroma;
namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

namespace {

const std::string kLiver = std::string(STROMA_SOURCE_DIR) + "/scenarios/liver.yaml";
const std::string kPress = std::string(STROMA_SOURCE_DIR) + "/scenarios/trajectories/liver_press.yaml";

/// `stroma serve` on the liver scenario in domain `domain`.
class Server : public Process {
 public:
  Server(int domain, std::vector<std::string> extra) : Process(args(domain, std::move(extra))) {}

 private:
  static std::vector<std::string> args(int domain, std::vector<std::string> extra) {
    std::vector<std::string> a = {STROMA_BINARY, "serve", kLiver, "--domain", std::to_string(domain),
                                  "--realtime", "off"};
    a.insert(a.end(), extra.begin(), extra.end());
    return a;
  }
};

/// A test-side DDS client (loopback config, like the server's default).
class Client {
 public:
  explicit Client(int domain) : pp_(create_participant(domain, "").participant) {
    status_topic_ = dds_create_topic(pp_, &stroma_SimStatus_desc, "stroma_SimStatus", nullptr, nullptr);
    control_topic_ = dds_create_topic(pp_, &stroma_Control_desc, "stroma_Control", nullptr, nullptr);
    dds_qos_t* q = dds_create_qos();
    dds_qset_reliability(q, DDS_RELIABILITY_RELIABLE, DDS_SECS(1));
    dds_qset_history(q, DDS_HISTORY_KEEP_LAST, 1);
    status_reader_ = dds_create_reader(pp_, status_topic_, q, nullptr);
    command_topic_ = dds_create_topic(pp_, &stroma_ToolCommand_desc, "stroma_ToolCommand", nullptr, nullptr);
    dds_qset_history(q, DDS_HISTORY_KEEP_ALL, 0);
    control_writer_ = dds_create_writer(pp_, control_topic_, q, nullptr);
    dds_delete_qos(q);
  }
  ~Client() { dds_delete(pp_); }
  /// A best-effort ToolCommand writer, matched with the server before it returns.
  dds_entity_t command_writer() {
    dds_qos_t* q = dds_create_qos();
    dds_qset_reliability(q, DDS_RELIABILITY_BEST_EFFORT, 0);
    dds_qset_history(q, DDS_HISTORY_KEEP_LAST, 1);
    const dds_entity_t w = dds_create_writer(pp_, command_topic_, q, nullptr);
    dds_delete_qos(q);
    const auto end = Clock::now() + std::chrono::seconds(10);
    dds_publication_matched_status_t m{};
    while (Clock::now() < end && (dds_get_publication_matched_status(w, &m), m.current_count == 0))
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    return w;
  }
  dds_entity_t participant() const { return pp_; }

  /// Newest status that satisfies `pred`, waiting up to `seconds`.
  bool wait_status(double seconds, const std::function<bool(const stroma_SimStatus&)>& pred,
                   stroma_SimStatus* out = nullptr) {
    const auto end = Clock::now() + std::chrono::duration<double>(seconds);
    while (Clock::now() < end) {
      void* samples[1] = {nullptr};
      dds_sample_info_t info;
      if (dds_take(status_reader_, samples, &info, 1, 1) > 0) {
        const stroma_SimStatus s = *static_cast<stroma_SimStatus*>(samples[0]);
        dds_return_loan(status_reader_, samples, 1);
        if (info.valid_data) {
          if (out) *out = s;  // the last status seen, also for failure messages
          if (pred(s)) return true;
        }
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    return false;
  }
  void control(stroma_ControlCommand c, uint32_t steps = 0) {
    // Wait until the server's reader is matched so the command is not lost.
    const auto end = Clock::now() + std::chrono::seconds(10);
    dds_publication_matched_status_t m{};
    while (Clock::now() < end && (dds_get_publication_matched_status(control_writer_, &m), m.current_count == 0))
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    stroma_Control msg{};
    msg.command = c;
    msg.steps = steps;
    msg.seq = ++seq_;
    ASSERT_GE(dds_write(control_writer_, &msg), 0);
  }

 private:
  dds_entity_t pp_, status_topic_, control_topic_, status_reader_, control_writer_, command_topic_;
  uint64_t seq_ = 0;
};

}  // namespace

TEST(Serve, StatusPublishedAndControlPauseStepResumeShutdown) {
  const std::string stats = (fs::temp_directory_path() / "stroma_serve_ctl.json").string();
  fs::remove(stats);
  Server server(111, {"--duration", "60", "--stats", stats});
  Client client(111);
  stroma_SimStatus s{};
  ASSERT_TRUE(client.wait_status(15, [](const stroma_SimStatus& st) { return st.state == stroma_RUNNING && st.ticks > 100; }, &s))
      << "no running status from the server";
  EXPECT_GT(s.sim_time, 0.0);
  EXPECT_GT(s.cg_iterations_mean, 0.0);
  EXPECT_GT(s.stage_ms[2], 0.0) << "assemble stage time published live";
  EXPECT_GT(s.stage_ms[3], 0.0) << "solve stage time published live";
  EXPECT_GE(s.tick_ms_p999, s.tick_ms_p99);
  EXPECT_GE(s.tick_ms_max, s.tick_ms_p999);
  EXPECT_DOUBLE_EQ(s.budget_ms, 1.0 - 0.15) << "the period minus the default margin";
  EXPECT_GT(s.residual_max, 0.0) << "the solve's accuracy is published live";
  EXPECT_GT(s.error_energy_max, 0.0);
  EXPECT_GE(s.ticks_over_budget, s.ticks_over_budget_window);
  EXPECT_STREQ(s.solver, "jacobi (scenario)") << "SimStatus names the solver and who chose it";

  client.control(stroma_PAUSE);
  ASSERT_TRUE(client.wait_status(5, [](const stroma_SimStatus& st) { return st.state == stroma_PAUSED; }, &s));
  stroma_SimStatus later{};
  ASSERT_TRUE(client.wait_status(5, [&](const stroma_SimStatus& st) { return st.wall_time > s.wall_time + 0.25; }, &later));
  EXPECT_EQ(later.state, stroma_PAUSED);
  EXPECT_EQ(later.ticks, s.ticks) << "paused server must not tick";
  EXPECT_DOUBLE_EQ(later.sim_time, s.sim_time);

  client.control(stroma_STEP, 7);
  ASSERT_TRUE(client.wait_status(5, [&](const stroma_SimStatus& st) { return st.ticks == later.ticks + 7; }, &s))
      << "STEP 7 must advance exactly 7 ticks";
  EXPECT_NEAR(s.sim_time, later.sim_time + 0.007, 1e-9);

  client.control(stroma_RESUME);
  ASSERT_TRUE(client.wait_status(5, [&](const stroma_SimStatus& st) { return st.state == stroma_RUNNING && st.ticks > s.ticks + 50; }));

  // Paused + RESET: back to the initial state, exactly sim time 0, and it stays there.
  client.control(stroma_PAUSE);
  client.control(stroma_RESET);
  ASSERT_TRUE(client.wait_status(5, [&](const stroma_SimStatus& st) { return st.state == stroma_PAUSED && st.sim_time == 0.0; }))
      << "RESET returns to the initial state (sim time 0)";

  client.control(stroma_SHUTDOWN);
  EXPECT_EQ(server.wait_exit(15), 0);
  std::ifstream f(stats);
  ASSERT_TRUE(f.good()) << "stats written at exit";
  const auto j = nlohmann::json::parse(f);
  EXPECT_GT(j["ticks"].get<int64_t>(), 100);
  EXPECT_EQ(j["controls"]["received"].get<int>(), 6);
  EXPECT_GT(j["wake_latency"]["count"].get<int64_t>(), 0);
  EXPECT_GE(j["tick_time"]["p99_us"].get<double>(), j["tick_time"]["p50_us"].get<double>());
  EXPECT_DOUBLE_EQ(j["budget_ms"].get<double>(), 0.85);
  EXPECT_TRUE(j.contains("ticks_over_budget") && j.contains("ticks_degraded"));
  // The solver in --stats: the scenario's preconditioner, the cap policy resolved from auto.
  EXPECT_EQ(j["solver"]["preconditioner"], "jacobi");
  EXPECT_EQ(j["solver"]["preconditioner_chosen_by"], "scenario");
  EXPECT_EQ(j["solver"]["on_cg_cap"], "continue");
  EXPECT_EQ(j["solver"]["on_cg_cap_chosen_by"], "auto");
}

TEST(Serve, LateJoiningSubscriberReceivesTheMesh) {
  Server server(112, {"--duration", "60"});
  Client client(112);
  ASSERT_TRUE(client.wait_status(15, [](const stroma_SimStatus& st) { return st.ticks > 500; }))
      << "server not running";
  // Joins after the mesh was written: transient-local durability must deliver it.
  const dds_entity_t topic = dds_create_topic(client.participant(), &stroma_TissueMesh_desc, "stroma_TissueMesh", nullptr, nullptr);
  dds_qos_t* q = dds_create_qos();
  dds_qset_reliability(q, DDS_RELIABILITY_RELIABLE, DDS_SECS(1));
  dds_qset_durability(q, DDS_DURABILITY_TRANSIENT_LOCAL);
  dds_qset_history(q, DDS_HISTORY_KEEP_LAST, 1);
  const dds_entity_t reader = dds_create_reader(client.participant(), topic, q, nullptr);
  dds_delete_qos(q);
  bool got = false;
  const auto end = Clock::now() + std::chrono::seconds(10);
  while (!got && Clock::now() < end) {
    void* samples[1] = {nullptr};
    dds_sample_info_t info;
    if (dds_take(reader, samples, &info, 1, 1) > 0) {
      const auto* m = static_cast<const stroma_TissueMesh*>(samples[0]);
      if (info.valid_data) {
        got = true;
        EXPECT_STREQ(m->body, "liver");
        EXPECT_GT(m->triangles._length, 0u);
        EXPECT_EQ(m->triangles._length % 3, 0u);
        EXPECT_EQ(m->rest_positions._length % 3, 0u);
        uint32_t max_index = 0;
        for (uint32_t i = 0; i < m->triangles._length; ++i) max_index = std::max(max_index, m->triangles._buffer[i]);
        EXPECT_LT(max_index, m->rest_positions._length / 3);
      }
      dds_return_loan(reader, samples, 1);
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  EXPECT_TRUE(got) << "late joiner did not receive stroma_TissueMesh";
  server.signal(SIGTERM);
  EXPECT_EQ(server.wait_exit(15), 0) << "SIGTERM: clean shutdown";
}

TEST(Serve, StateIsPublishedOnlyToSubscribersAndMoves) {
  Server server(113, {"--duration", "60"});
  Client client(113);
  const dds_entity_t topic = dds_create_topic(client.participant(), &stroma_TissueState_desc, "stroma_TissueState", nullptr, nullptr);
  dds_qos_t* q = dds_create_qos();
  dds_qset_reliability(q, DDS_RELIABILITY_BEST_EFFORT, 0);
  dds_qset_history(q, DDS_HISTORY_KEEP_LAST, 1);
  const dds_entity_t reader = dds_create_reader(client.participant(), topic, q, nullptr);
  dds_delete_qos(q);
  std::vector<std::pair<uint64_t, double>> frames;
  float first_y = 0, last_y = 0;
  const auto end = Clock::now() + std::chrono::seconds(15);
  while (frames.size() < 20 && Clock::now() < end) {
    void* samples[1] = {nullptr};
    dds_sample_info_t info;
    if (dds_take(reader, samples, &info, 1, 1) > 0) {
      const auto* st = static_cast<const stroma_TissueState*>(samples[0]);
      if (info.valid_data && st->positions._length > 3) {
        if (frames.empty()) first_y = st->positions._buffer[1];
        last_y = st->positions._buffer[1];
        frames.emplace_back(st->frame, st->sim_time);
        EXPECT_EQ(st->scalar._length * 3, st->positions._length);
      }
      dds_return_loan(reader, samples, 1);
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  ASSERT_GE(frames.size(), 20u) << "TissueState not received";
  for (size_t i = 1; i < frames.size(); ++i) {
    EXPECT_GT(frames[i].first, frames[i - 1].first);
    EXPECT_GT(frames[i].second, frames[i - 1].second);
  }
  EXPECT_NE(first_y, last_y) << "the liver sags under gravity";
  server.signal(SIGINT);
  EXPECT_EQ(server.wait_exit(15), 0) << "SIGINT: clean shutdown";
}

namespace {
std::string read_file(const std::string& p) {
  std::ifstream f(p, std::ios::binary);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}
}  // namespace

// The whole loop over DDS: `stroma tool` drives the probe and gets feedback every tick; the
// session (commands + pause/step/resume) is recorded; `stroma run --replay` reproduces the
// server's final state bit for bit.
TEST(Serve, ToolClientFeedbackAndBitExactReplay) {
  const fs::path dir = fs::temp_directory_path() / "stroma_replay_test";
  fs::remove_all(dir);
  fs::create_directories(dir);
  const std::string rec = (dir / "session.log").string(), fin = (dir / "server_final.csv").string();
  const std::string stats = (dir / "stats.json").string(), csv = (dir / "tool.csv").string();
  Server server(114, {"--duration", "60", "--record", rec, "--final-state", fin, "--stats", stats});
  Client client(114);
  ASSERT_TRUE(client.wait_status(15, [](const stroma_SimStatus& st) { return st.ticks > 100; }));
  Process tool({STROMA_BINARY, "tool", "--name", "probe", "--script", kPress, "--rate", "500",
                "--duration", "1.5", "--domain", "114", "--out", csv});
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  client.control(stroma_PAUSE);
  client.control(stroma_STEP, 25);
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  client.control(stroma_RESUME);
  EXPECT_EQ(tool.wait_exit(30), 0) << "tool client: feedback must arrive";
  client.control(stroma_SHUTDOWN);
  ASSERT_EQ(server.wait_exit(15), 0);

  // Tool log: most commands echoed, round trips positive and below 100 ms on loopback.
  std::ifstream f(csv);
  std::string line;
  std::getline(f, line);
  int rows = 0, echoed = 0;
  while (std::getline(f, line)) {
    ++rows;
    std::stringstream ss(line);
    std::string seq, sent, recv, rtt;
    std::getline(ss, seq, ',');
    std::getline(ss, sent, ',');
    std::getline(ss, recv, ',');
    std::getline(ss, rtt, ',');
    if (!rtt.empty()) {
      ++echoed;
      EXPECT_GT(std::stod(rtt), 0.0);
      EXPECT_LT(std::stod(rtt), 100.0);
    }
  }
  EXPECT_GT(rows, 500);
  EXPECT_GT(echoed, rows / 2);
  const auto j = nlohmann::json::parse(read_file(stats));
  EXPECT_GT(j["tool_commands"]["accepted"].get<int>(), 500);

  // Replay headless: bit-identical final state.
  Process replay({STROMA_BINARY, "run", kLiver, "--replay", rec, "--out", (dir / "replay").string(),
                  "--quiet", "--no-metrics"});
  ASSERT_EQ(replay.wait_exit(60), 0);
  const std::string a = read_file(fin), b = read_file((dir / "replay" / "final_state.csv").string());
  EXPECT_FALSE(a.empty());
  EXPECT_TRUE(a == b) << "replayed final state differs from the server's";
  fs::remove_all(dir);
}

// A live session with cuts replays headless bit for bit: the server builds each cut model on its
// worker and swaps it in whenever it is ready (wall-clock dependent); the session log records
// the tick each build's edge cuts were taken at and the tick its model was swapped in, and the
// replay builds the same models from the same cuts and swaps them at the same ticks.
TEST(Serve, CuttingSessionReplaysBitForBit) {
  const std::string incision = std::string(STROMA_SOURCE_DIR) + "/scenarios/regression/liver_incision.yaml";
  const std::string script = std::string(STROMA_SOURCE_DIR) + "/scenarios/trajectories/liver_incision.yaml";
  const fs::path dir = fs::temp_directory_path() / "stroma_cut_replay_test";
  fs::remove_all(dir);
  fs::create_directories(dir);
  const std::string rec = (dir / "session.log").string(), fin = (dir / "server_final.csv").string();
  const std::string stats = (dir / "stats.json").string();
  Process server({STROMA_BINARY, "serve", incision, "--domain", "136", "--realtime", "off", "--duration", "60",
                  "--record", rec, "--final-state", fin, "--stats", stats});
  Client client(136);
  // The topology events, as a client would read them (reliable, keep all).
  const dds_entity_t t_topo = dds_create_topic(client.participant(), &stroma_TopologyEvent_desc, "stroma_TopologyEvent",
                                               nullptr, nullptr);
  dds_qos_t* q = dds_create_qos();
  dds_qset_reliability(q, DDS_RELIABILITY_RELIABLE, DDS_SECS(1));
  dds_qset_history(q, DDS_HISTORY_KEEP_ALL, 0);
  const dds_entity_t topo_reader = dds_create_reader(client.participant(), t_topo, q, nullptr);
  dds_delete_qos(q);
  ASSERT_GT(topo_reader, 0);
  ASSERT_TRUE(client.wait_status(15, [](const stroma_SimStatus& st) { return st.ticks > 100; }));
  Process tool({STROMA_BINARY, "tool", "--name", "scalpel", "--script", script, "--rate", "1000", "--duration", "2.2",
                "--domain", "136"});
  // SimStatus says live what was cut.
  EXPECT_TRUE(client.wait_status(15, [](const stroma_SimStatus& st) {
    return st.topology_version > 0 && st.elements_split > 0 && st.cut_area > 0;
  })) << "SimStatus never reported a cut";
  EXPECT_EQ(tool.wait_exit(30), 0);
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  client.control(stroma_SHUTDOWN);
  ASSERT_EQ(server.wait_exit(15), 0);
  const auto j = nlohmann::json::parse(read_file(stats));
  ASSERT_TRUE(j.contains("cutting")) << j.dump();
  const int swaps = j["cutting"]["topology_swaps"].get<int>();
  EXPECT_GT(swaps, 0) << "the scalpel cut the served liver";
  EXPECT_GT(j["cutting"]["elements_split"].get<int>(), 0);
  EXPECT_EQ(j["ticks_non_finite"].get<int>(), 0);
  int logged = 0;
  {
    std::ifstream f(rec);
    std::string line;
    while (std::getline(f, line)) logged += line.find(",topology,") != std::string::npos;
  }
  EXPECT_EQ(logged, swaps) << "every swap is in the session log";
  // One topology event per swap, versions 1, 2, …, the last with the run's cut figures.
  std::vector<stroma_TopologyEvent> events;
  for (;;) {
    void* samples[16] = {nullptr};
    dds_sample_info_t infos[16];
    const dds_return_t n = dds_take(topo_reader, samples, infos, 16, 16);
    if (n <= 0) break;
    for (dds_return_t i = 0; i < n; ++i)
      if (infos[i].valid_data) events.push_back(*static_cast<stroma_TopologyEvent*>(samples[i]));
    dds_return_loan(topo_reader, samples, n);
  }
  ASSERT_EQ(static_cast<int>(events.size()), swaps) << "a topology event per swap";
  for (size_t i = 0; i < events.size(); ++i) EXPECT_EQ(events[i].topology_version, i + 1);
  EXPECT_EQ(events.back().elements_split, j["cutting"]["elements_split"].get<uint32_t>());
  EXPECT_NEAR(events.back().cut_area, j["cutting"]["cut_area"].get<double>(), 1e-12);
  EXPECT_GT(events.back().sim_time, 0.0);

  Process replay({STROMA_BINARY, "run", incision, "--replay", rec, "--out", (dir / "replay").string(), "--quiet",
                  "--no-metrics"});
  ASSERT_EQ(replay.wait_exit(60), 0);
  const std::string a = read_file(fin), b = read_file((dir / "replay" / "final_state.csv").string());
  EXPECT_FALSE(a.empty());
  EXPECT_TRUE(a == b) << "replayed final state differs from the server's";
  const auto r = nlohmann::json::parse(read_file((dir / "replay" / "summary.json").string()));
  EXPECT_EQ(r["cutting"]["topology_swaps"].get<int>(), swaps);
  fs::remove_all(dir);
}

// A server killed outright while recording (SIGKILL: no 'end' line): its log, flushed every
// 10 ms with a checkpoint every 10 ticks, replays headless to its last checkpoint — close to
// where the server was — and does so deterministically.
TEST(Serve, RecordingOfAKilledServerReplaysToItsLastCheckpoint) {
  const fs::path dir = fs::temp_directory_path() / "stroma_killed_record_test";
  fs::remove_all(dir);
  fs::create_directories(dir);
  const std::string rec = (dir / "session.log").string();
  Server server(121, {"--duration", "60", "--record", rec});
  Client client(121);
  ASSERT_TRUE(client.wait_status(15, [](const stroma_SimStatus& st) { return st.ticks > 100; }));
  Process tool({STROMA_BINARY, "tool", "--name", "probe", "--script", kPress, "--duration", "30", "--domain", "121"});
  stroma_SimStatus s{};
  ASSERT_TRUE(client.wait_status(15, [](const stroma_SimStatus& st) { return st.commands_accepted > 1000; }, &s));
  server.signal(SIGKILL);
  EXPECT_EQ(server.wait_exit(5), 128 + SIGKILL);
  tool.signal(SIGTERM);
  tool.wait_exit(5);
  const std::string log = read_file(rec);
  EXPECT_EQ(log.find(",end,"), std::string::npos) << "a killed server wrote its 'end' line?";
  std::string replayed[2];
  for (int k = 0; k < 2; ++k) {
    const std::string out = (dir / ("replay" + std::to_string(k))).string();
    Process replay({STROMA_BINARY, "run", kLiver, "--replay", rec, "--out", out, "--quiet", "--no-metrics"});
    ASSERT_EQ(replay.wait_exit(120), 0) << "the killed server's log does not replay";
    const auto j = nlohmann::json::parse(read_file(out + "/summary.json"));
    EXPECT_EQ(j["status"], "ok");
    // The last status seen was at most ~0.1 s old and the log is at most ~20 ms behind the kill.
    EXPECT_GE(j["steps"].get<int64_t>(), static_cast<int64_t>(s.ticks) - 50) << "replayed only to tick " << j["steps"];
    EXPECT_EQ(j["steps"].get<int64_t>() % 10, 0) << "not a checkpoint";
    replayed[k] = read_file(out + "/final_state.csv");
  }
  EXPECT_FALSE(replayed[0].empty());
  EXPECT_TRUE(replayed[0] == replayed[1]) << "the replay is not deterministic";
  fs::remove_all(dir);
}

// Recording onto a full disk (/dev/full: every write fails with ENOSPC): a clear error, the
// recording stops, physics and DDS go on, and the statistics say so.
TEST(Serve, RecordingOntoAFullDiskStopsTheRecordingNotTheServer) {
  const fs::path stats = fs::temp_directory_path() / "stroma_full_disk_stats.json";
  Server server(123, {"--duration", "3", "--record", "/dev/full", "--stats", stats.string()});
  Client client(123);
  stroma_SimStatus s{};
  ASSERT_TRUE(client.wait_status(15, [](const stroma_SimStatus& st) { return st.ticks > 1500; }, &s))
      << "the server stopped ticking when its recording failed";
  EXPECT_EQ(s.state, stroma_RUNNING);
  EXPECT_EQ(server.wait_exit(20), 1);  // the recording is incomplete: said by the exit status too
  const auto j = nlohmann::json::parse(read_file(stats.string()));
  EXPECT_GT(j["ticks"].get<int>(), 2000);
  EXPECT_FALSE(j["record"]["ok"].get<bool>());
  EXPECT_NE(j["record"]["error"].get<std::string>().find("No space left"), std::string::npos) << j["record"];
  fs::remove(stats);
}

// Malformed commands are rejected and counted; they never reach physics.
TEST(Serve, MalformedCommandsAreCountedAndPhysicsStaysFinite) {
  Server server(115, {"--duration", "60"});
  Client client(115);
  ASSERT_TRUE(client.wait_status(15, [](const stroma_SimStatus& st) { return st.ticks > 100; }));
  const dds_entity_t w = client.command_writer();
  auto send = [&](const char* tool, double x, double y, double z, std::array<double, 4> q, int64_t t_ns, uint64_t seq) {
    stroma_ToolCommand c{};
    std::snprintf(c.tool, sizeof(c.tool), "%s", tool);
    c.seq = seq;
    c.client_time_ns = t_ns;
    c.position[0] = x; c.position[1] = y; c.position[2] = z;
    for (int k = 0; k < 4; ++k) c.orientation[k] = q[k];
    dds_write(w, &c);
    std::this_thread::sleep_for(std::chrono::milliseconds(30));  // keep-last-1: one at a time
  };
  const double nan = std::nan("");
  // Discovery is asymmetric: repeat a valid command until the server has accepted one.
  stroma_SimStatus s{};
  for (int i = 0; i < 100 && !(client.wait_status(0.05, [](const stroma_SimStatus& st) { return st.commands_accepted > 0; }, &s)); ++i)
    send("probe", 0, 7, 0, {1, 0, 0, 0}, 1000000, 1);          // valid: becomes the last pose
  ASSERT_GT(s.commands_accepted, 0u);
  // A repeat sent before that status was published may still be landing: count from a status
  // taken after the last repeat has had time to arrive (seen once in CI: accepted0 one short).
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  client.wait_status(0.3, [](const stroma_SimStatus&) { return false; }, &s);  // the newest status seen
  const uint64_t accepted0 = s.commands_accepted;
  send("probe", nan, 7, 0, {1, 0, 0, 0}, 2000000, 2);          // NaN
  send("probe", 0, 7, 0, {0.5, 0.5, 0, 0}, 3000000, 3);        // not a unit quaternion
  send("probe", 0, 70, 0, {1, 0, 0, 0}, 4000000, 4);           // outside the workspace
  send("probe", 4, 7, 0, {1, 0, 0, 0}, 5000000, 5);            // 4 units in 1 ms: too fast
  send("scalpel", 0, 7, 0, {1, 0, 0, 0}, 6000000, 6);          // unknown tool
  send("probe", 0.01, 7, 0, {1, 0, 0, 0}, 16000000, 7);        // valid again
  ASSERT_TRUE(client.wait_status(5, [&](const stroma_SimStatus& st) { return st.commands_rejected >= 5 && st.commands_accepted > accepted0; }, &s))
      << "rejected " << s.commands_rejected << ", accepted " << s.commands_accepted;
  EXPECT_EQ(s.commands_rejected, 5u);
  EXPECT_EQ(s.commands_accepted, accepted0 + 1);
  EXPECT_EQ(s.commands_superseded, 0u);  // one at a time: none replaced before it was taken
  EXPECT_EQ(s.state, stroma_RUNNING);
  EXPECT_TRUE(std::isfinite(s.kinetic_energy));
  EXPECT_TRUE(std::isfinite(s.elastic_energy));
  server.signal(SIGTERM);
  EXPECT_EQ(server.wait_exit(15), 0);
}

// The server's command reader keeps only the newest sample per tool: a burst overwrites most
// of them before the input thread takes them. Those are counted (superseded), from the gaps in
// the writer's seq, so that accepted + rejected + superseded = received.
TEST(Serve, CommandsSupersededInABurstAreCounted) {
  Server server(120, {"--duration", "60"});
  Client client(120);
  ASSERT_TRUE(client.wait_status(15, [](const stroma_SimStatus& st) { return st.ticks > 100; }));
  const dds_entity_t w = client.command_writer();
  auto send = [&](uint64_t seq) {
    stroma_ToolCommand c{};
    std::snprintf(c.tool, sizeof(c.tool), "%s", "probe");
    c.seq = seq;
    c.client_time_ns = static_cast<int64_t>(seq) * 1000000;  // 1 ms apart: within max_speed
    c.position[1] = 7;
    c.orientation[0] = 1;
    c.jaw = 1;
    dds_write(w, &c);
  };
  stroma_SimStatus s{};
  for (int i = 0; i < 100 && !(client.wait_status(0.05, [](const stroma_SimStatus& st) { return st.commands_accepted > 0; }, &s)); ++i)
    send(1);  // until discovery is complete (repeats of one seq are no gap)
  ASSERT_GT(s.commands_accepted, 0u);
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  ASSERT_TRUE(client.wait_status(1, [](const stroma_SimStatus&) { return true; }, &s));
  const uint64_t before = s.commands_accepted + s.commands_rejected + s.commands_superseded;
  constexpr uint64_t kBurst = 3000;
  for (uint64_t q = 2; q <= kBurst + 1; ++q) send(q);  // back to back
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  send(kBurst + 2);  // after a pause: taken on its own, closing the count
  const bool complete = client.wait_status(5, [&](const stroma_SimStatus& st) {
    return st.commands_accepted + st.commands_rejected + st.commands_superseded - before >= kBurst + 1;
  }, &s);
  ASSERT_TRUE(complete) << "accepted " << s.commands_accepted << " rejected " << s.commands_rejected << " superseded "
                        << s.commands_superseded << " (before " << before << ")";
  EXPECT_EQ(s.commands_accepted + s.commands_rejected + s.commands_superseded - before, kBurst + 1);
  EXPECT_GT(s.commands_superseded, 0u) << "a burst of " << kBurst << " commands was taken one by one?";
  EXPECT_EQ(s.commands_rejected, 0u);
  server.signal(SIGTERM);
  EXPECT_EQ(server.wait_exit(15), 0);
}

namespace {

/// The local addresses (hex, as /proc/net/udp{,6} print them) of process `pid`'s UDP sockets.
std::vector<std::string> udp_local_addresses(pid_t pid) {
  std::set<std::string> inodes;  // socket:[INODE] links in /proc/PID/fd
  for (const auto& e : fs::directory_iterator(fs::path("/proc") / std::to_string(pid) / "fd")) {
    std::error_code ec;
    const std::string target = fs::read_symlink(e.path(), ec).string();
    if (!ec && target.rfind("socket:[", 0) == 0) inodes.insert(target.substr(8, target.size() - 9));
  }
  std::vector<std::string> out;
  for (const char* table : {"udp", "udp6"}) {
    std::ifstream f(fs::path("/proc") / std::to_string(pid) / "net" / table);
    std::string line;
    std::getline(f, line);  // header
    while (std::getline(f, line)) {
      std::istringstream ss(line);
      std::string sl, local, remote, st, queues, tr, retr, uid, timeout, inode;
      ss >> sl >> local >> remote >> st >> queues >> tr >> retr >> uid >> timeout >> inode;
      if (inodes.count(inode)) out.push_back(local);
    }
  }
  return out;
}

}  // namespace

// Cyclone 0.10 binds its receive sockets to 0.0.0.0 whatever interface it is told to use; with
// the built-in loopback configuration every socket of the server must be bound to 127.0.0.1
// (or ::1), so another host cannot reach it (dds/loopback_bind.hpp).
TEST(Serve, SocketsAreBoundToLoopbackOnly) {
  Server server(122, {"--duration", "60"});
  Client client(122);
  ASSERT_TRUE(client.wait_status(15, [](const stroma_SimStatus& st) { return st.ticks > 100; }));
  const std::vector<std::string> local = udp_local_addresses(server.pid());
  EXPECT_GE(local.size(), 2u) << "found no DDS sockets of the server";  // discovery + data, at least
  for (const std::string& a : local) {
    const std::string host = a.substr(0, a.find(':'));
    EXPECT_TRUE(host == "0100007F" || host == "00000000000000000000000001000000")
        << "a server socket is bound to " << a << " (not loopback)";
  }
  // The test's own participant (same built-in configuration) too.
  for (const std::string& a : udp_local_addresses(getpid())) EXPECT_EQ(a.substr(0, 8), "0100007F") << a;
  server.signal(SIGTERM);
  EXPECT_EQ(server.wait_exit(15), 0);
}

// The same with the user's own loopback-only configuration (issue 41 §6): the shipped template
// passed with --dds-config. Cyclone would bind its receive sockets to 0.0.0.0; the server binds
// them to loopback as with its built-in configuration.
TEST(Serve, AUserLoopbackConfigurationIsBoundToLoopback) {
  const std::string config = std::string(STROMA_SOURCE_DIR) + "/dds/cyclonedds-loopback.xml";
  Server server(124, {"--duration", "60", "--dds-config", config});
  Client client(124);
  ASSERT_TRUE(client.wait_status(15, [](const stroma_SimStatus& st) { return st.ticks > 100; }));
  const std::vector<std::string> local = udp_local_addresses(server.pid());
  EXPECT_GE(local.size(), 2u) << "found no DDS sockets of the server";
  for (const std::string& a : local) {
    const std::string host = a.substr(0, a.find(':'));
    EXPECT_TRUE(host == "0100007F" || host == "00000000000000000000000001000000")
        << "a server socket is bound to " << a << " (not loopback) with a loopback-only --dds-config";
  }
  server.signal(SIGTERM);
  EXPECT_EQ(server.wait_exit(15), 0);
}

// A client that dies mid-run does not disturb the server.
TEST(Serve, KillingTheToolClientLeavesTheServerHealthy) {
  Server server(116, {"--duration", "60"});
  Client client(116);
  ASSERT_TRUE(client.wait_status(15, [](const stroma_SimStatus& st) { return st.ticks > 100; }));
  Process tool({STROMA_BINARY, "tool", "--name", "probe", "--script", kPress, "--duration", "30", "--domain", "116"});
  stroma_SimStatus s{};
  ASSERT_TRUE(client.wait_status(10, [](const stroma_SimStatus& st) { return st.commands_accepted > 200; }, &s));
  tool.signal(SIGKILL);
  EXPECT_EQ(tool.wait_exit(5), 128 + SIGKILL);
  stroma_SimStatus later{};
  ASSERT_TRUE(client.wait_status(5, [&](const stroma_SimStatus& st) { return st.ticks > s.ticks + 1000; }, &later))
      << "server stopped ticking after the client died";
  EXPECT_EQ(later.state, stroma_RUNNING);
  EXPECT_TRUE(std::isfinite(later.kinetic_energy));
  server.signal(SIGTERM);
  EXPECT_EQ(server.wait_exit(15), 0);
}

// Two clients commanding the same tool: the documented policy is "latest writer wins" — every
// valid command is applied in arrival order, whoever sent it.
TEST(Serve, SecondClientOnTheSameToolLatestWriterWins) {
  Server server(117, {"--duration", "60"});
  Client a(117), b(117);
  ASSERT_TRUE(a.wait_status(15, [](const stroma_SimStatus& st) { return st.ticks > 100; }));
  const dds_entity_t wa = a.command_writer(), wb = b.command_writer();
  const dds_entity_t t_fb = dds_create_topic(a.participant(), &stroma_ToolFeedback_desc, "stroma_ToolFeedback", nullptr, nullptr);
  dds_qos_t* q = dds_create_qos();
  dds_qset_reliability(q, DDS_RELIABILITY_BEST_EFFORT, 0);
  dds_qset_history(q, DDS_HISTORY_KEEP_LAST, 1);
  const dds_entity_t fb = dds_create_reader(a.participant(), t_fb, q, nullptr);
  dds_delete_qos(q);
  int64_t t_ns = 1000000;
  auto drive_until_echoed = [&](dds_entity_t w, uint64_t seq, double z) {
    const auto end = Clock::now() + std::chrono::seconds(10);
    while (Clock::now() < end) {
      stroma_ToolCommand c{};
      std::snprintf(c.tool, sizeof(c.tool), "probe");
      c.seq = seq;
      c.client_time_ns = (t_ns += 10000000);  // 10 ms apart: well under max_speed
      c.position[1] = 7;
      c.position[2] = z;
      c.orientation[0] = 1;
      dds_write(w, &c);
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
      void* samples[1] = {nullptr};
      dds_sample_info_t info;
      while (dds_take(fb, samples, &info, 1, 1) > 0) {
        const uint64_t got = static_cast<const stroma_ToolFeedback*>(samples[0])->seq;
        const bool valid = info.valid_data;
        dds_return_loan(fb, samples, 1);
        if (valid && got == seq) return true;
      }
    }
    return false;
  };
  EXPECT_TRUE(drive_until_echoed(wa, 10, 0.0)) << "client A's command applied";
  EXPECT_TRUE(drive_until_echoed(wb, 2000, 0.001)) << "client B takes over (latest writer wins)";
  EXPECT_TRUE(drive_until_echoed(wa, 11, 0.0)) << "and A again";
  server.signal(SIGTERM);
  EXPECT_EQ(server.wait_exit(15), 0);
}

// `stroma tool` reading commands from stdin lines ("x y z [qw qx qy qz] [jaw]").
TEST(Serve, ToolClientFromStdinLines) {
  Server server(118, {"--duration", "60"});
  Client client(118);
  ASSERT_TRUE(client.wait_status(15, [](const stroma_SimStatus& st) { return st.ticks > 100; }));
  std::string cmd = "i=0; while [ $i -lt 200 ]; do echo \"-1.5 7 0.5 1 0 0 0 0.1\"; echo 'not a command'; "
                    "sleep 0.002; i=$((i+1)); done | " + std::string(STROMA_BINARY) +
                    " tool --name probe --domain 118 2>&1";
  FILE* p = popen(cmd.c_str(), "r");
  ASSERT_NE(p, nullptr);
  std::string out;
  char buf[512];
  while (fgets(buf, sizeof buf, p)) out += buf;
  const int rc = pclose(p);
  EXPECT_EQ(WEXITSTATUS(rc), 0) << out;
  EXPECT_NE(out.find("200 commands sent"), std::string::npos) << out;
  EXPECT_NE(out.find("stdin:2: expected 'x y z"), std::string::npos) << "bad lines are reported: " << out;
  stroma_SimStatus s{};
  EXPECT_TRUE(client.wait_status(5, [](const stroma_SimStatus& st) { return st.commands_accepted > 50; }, &s))
      << s.commands_accepted;
  server.signal(SIGTERM);
  EXPECT_EQ(server.wait_exit(15), 0);
}

// Damage over DDS: reliable stroma_DamageEvent samples (warning → onset → rupture, in order per
// element) and the per-vertex damage field of stroma_TissueState.
TEST(Serve, DamageEventsAndDamageFieldArePublished) {
  Process server({STROMA_BINARY, "serve", std::string(STROMA_SOURCE_DIR) + "/tests/data/server/liver_fragile.yaml",
                  "--domain", "119", "--realtime", "off", "--duration", "60", "--paused"});
  Client client(119);
  const dds_entity_t t_ev = dds_create_topic(client.participant(), &stroma_DamageEvent_desc, "stroma_DamageEvent", nullptr, nullptr);
  const dds_entity_t t_st = dds_create_topic(client.participant(), &stroma_TissueState_desc, "stroma_TissueState", nullptr, nullptr);
  dds_qos_t* q = dds_create_qos();
  dds_qset_reliability(q, DDS_RELIABILITY_RELIABLE, DDS_SECS(1));
  dds_qset_history(q, DDS_HISTORY_KEEP_ALL, 0);
  const dds_entity_t ev_reader = dds_create_reader(client.participant(), t_ev, q, nullptr);
  dds_qset_reliability(q, DDS_RELIABILITY_BEST_EFFORT, 0);
  dds_qset_history(q, DDS_HISTORY_KEEP_LAST, 1);
  const dds_entity_t st_reader = dds_create_reader(client.participant(), t_st, q, nullptr);
  dds_delete_qos(q);
  // Start ticking only once our event reader is there (reliable events are not kept for
  // late joiners): the server was started paused.
  ASSERT_TRUE(client.wait_status(15, [](const stroma_SimStatus& st) { return st.state == stroma_PAUSED; }));
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  client.control(stroma_RESUME);
  std::map<uint32_t, int> last_level;
  int warnings = 0, onsets = 0, ruptures = 0;
  float max_vertex_damage = 0;
  const auto end = Clock::now() + std::chrono::seconds(20);
  while (Clock::now() < end && !(ruptures > 0 && max_vertex_damage >= 1.0f)) {
    void* samples[16] = {nullptr};
    dds_sample_info_t infos[16];
    const dds_return_t n = dds_take(ev_reader, samples, infos, 16, 16);
    for (dds_return_t i = 0; i < n; ++i) {
      if (!infos[i].valid_data) continue;
      const auto* e = static_cast<const stroma_DamageEvent*>(samples[i]);
      EXPECT_STREQ(e->body, "liver");
      EXPECT_LT(e->element, 596u);
      const int lvl = static_cast<int>(e->level);
      EXPECT_GT(lvl, last_level.count(e->element) ? last_level[e->element] : -1) << "levels only increase";
      last_level[e->element] = lvl;
      warnings += e->level == stroma_DAMAGE_WARNING;
      onsets += e->level == stroma_DAMAGE_ONSET;
      ruptures += e->level == stroma_DAMAGE_RUPTURE;
      EXPECT_GT(e->value, 0.0);
    }
    if (n > 0) dds_return_loan(ev_reader, samples, n);
    void* st[1] = {nullptr};
    dds_sample_info_t si;
    if (dds_take(st_reader, st, &si, 1, 1) > 0) {
      const auto* s = static_cast<const stroma_TissueState*>(st[0]);
      if (si.valid_data) {
        EXPECT_EQ(s->damage._length * 3, s->positions._length);
        for (uint32_t i = 0; i < s->damage._length; ++i) max_vertex_damage = std::max(max_vertex_damage, s->damage._buffer[i]);
      }
      dds_return_loan(st_reader, st, 1);
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  EXPECT_GT(warnings, 0);
  EXPECT_GT(onsets, 0);
  EXPECT_GT(ruptures, 0);
  EXPECT_GE(max_vertex_damage, 1.0f) << "a ruptured element shows d = 1 on its surface vertices";
  server.signal(SIGTERM);
  EXPECT_EQ(server.wait_exit(15), 0);
}

// Rigid bodies and needles over DDS (docs/DDS.md): the shape once (stroma_RigidBody,
// transient-local), per frame the pose, the tool holding it and a needle's insertion with its
// track (stroma_RigidBodyState), and reliable stroma_NeedleEvent samples — as a client written
// from the IDL reads them, with and without the CRTK bridge. The scripted grasper drives an 80 mm
// needle sideways through the 50 mm block (x = 0 → x = 0.05) and back out.
static /// The process is alive (not exited: a zombie is not).
bool still_running(pid_t pid) {
  std::ifstream f("/proc/" + std::to_string(pid) + "/stat");
  std::string stat;
  std::getline(f, stat);
  const size_t close = stat.rfind(')');
  return !stat.empty() && close != std::string::npos && close + 2 < stat.size() && stat[close + 2] != 'Z';
}

/// Appends the NeedleEvent samples waiting in `reader` to `events`.
void take_needle_events(dds_entity_t reader, std::vector<stroma_NeedleEvent>& events) {
  void* sm[16] = {nullptr};
  dds_sample_info_t si[16];
  const dds_return_t n = dds_take(reader, sm, si, 16, 16);
  for (dds_return_t i = 0; i < n; ++i)
    if (si[i].valid_data) events.push_back(*static_cast<stroma_NeedleEvent*>(sm[i]));
  if (n > 0) dds_return_loan(reader, sm, n);
}

/// A reliable, keep-all reader of stroma_NeedleEvent: every event, in order.
dds_entity_t needle_event_reader(dds_entity_t pp) {
  const dds_entity_t t = dds_create_topic(pp, &stroma_NeedleEvent_desc, "stroma_NeedleEvent", nullptr, nullptr);
  dds_qos_t* q = dds_create_qos();
  dds_qset_reliability(q, DDS_RELIABILITY_RELIABLE, DDS_SECS(1));
  dds_qset_history(q, DDS_HISTORY_KEEP_ALL, 0);
  const dds_entity_t r = dds_create_reader(pp, t, q, nullptr);
  dds_delete_qos(q);
  return r;
}

/// `stroma serve` of the source tree's `scenario` (a path from its root), paused, on `domain`,
/// with `--crtk` if asked.
std::vector<std::string> paused_serve_args(const std::string& scenario, int domain, bool crtk) {
  std::vector<std::string> args = {STROMA_BINARY, "serve", std::string(STROMA_SOURCE_DIR) + scenario,
                                   "--domain", std::to_string(domain), "--realtime", "off", "--duration", "60", "--paused"};
  if (crtk) args.push_back("--crtk");
  return args;
}

/// A best-effort reader of stroma_RigidBodyState keeping each body's newest sample.
dds_entity_t rigid_state_reader(dds_entity_t pp) {
  const dds_entity_t t = dds_create_topic(pp, &stroma_RigidBodyState_desc, "stroma_RigidBodyState", nullptr, nullptr);
  dds_qos_t* q = dds_create_qos();
  dds_qset_reliability(q, DDS_RELIABILITY_BEST_EFFORT, 0);
  dds_qset_history(q, DDS_HISTORY_KEEP_LAST, 1);
  const dds_entity_t r = dds_create_reader(pp, t, q, nullptr);
  dds_delete_qos(q);
  return r;
}

void needle_over_dds(int domain, bool crtk) {
  Process server(paused_serve_args("/tests/data/server/needle_through.yaml", domain, crtk));
  Client client(domain);
  const dds_entity_t pp = client.participant();
  const dds_entity_t t_body = dds_create_topic(pp, &stroma_RigidBody_desc, "stroma_RigidBody", nullptr, nullptr);
  const dds_entity_t ev_reader = needle_event_reader(pp);
  dds_qos_t* q = dds_create_qos();
  dds_qset_reliability(q, DDS_RELIABILITY_RELIABLE, DDS_SECS(1));
  dds_qset_history(q, DDS_HISTORY_KEEP_ALL, 0);
  dds_qset_durability(q, DDS_DURABILITY_TRANSIENT_LOCAL);
  const dds_entity_t body_reader = dds_create_reader(pp, t_body, q, nullptr);
  dds_delete_qos(q);
  const dds_entity_t st_reader = rigid_state_reader(pp);
  ASSERT_TRUE(client.wait_status(15, [](const stroma_SimStatus& st) { return st.state == stroma_PAUSED; }));

  // The shape, published before we joined (transient-local).
  stroma_RigidBody body{};
  bool have_body = false;
  for (const auto end = Clock::now() + std::chrono::seconds(10); Clock::now() < end && !have_body;) {
    void* sm[1] = {nullptr};
    dds_sample_info_t si;
    if (dds_take(body_reader, sm, &si, 1, 1) > 0) {
      if (si.valid_data) {
        body = *static_cast<stroma_RigidBody*>(sm[0]);
        have_body = true;
        EXPECT_EQ(static_cast<stroma_RigidBody*>(sm[0])->vertices._length, 0u) << "a needle is analytic";
      }
      dds_return_loan(body_reader, sm, 1);
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  ASSERT_TRUE(have_body) << "no stroma_RigidBody sample";
  EXPECT_STREQ(body.body, "needle");
  EXPECT_EQ(body.shape, stroma_SHAPE_NEEDLE);
  EXPECT_FALSE(body.curved);
  EXPECT_DOUBLE_EQ(body.wire_radius, 0.0004);
  EXPECT_DOUBLE_EQ(body.length, 0.08);
  const double cylinder = 7800 * M_PI * 0.0004 * 0.0004 * 0.08;  // a steel wire; the rounded tip adds < 1 %
  EXPECT_NEAR(body.mass, cylinder, 0.01 * cylinder);

  std::this_thread::sleep_for(std::chrono::milliseconds(500));  // the event reader matched
  client.control(stroma_RESUME);
  // The grasper, driven as a user drives it: `stroma tool` playing the script (a CRTK client
  // sending servo_cp with --crtk).
  std::vector<std::string> tool = {STROMA_BINARY, "tool", "--name", "grasper", "--script",
                                   std::string(STROMA_SOURCE_DIR) + "/tests/data/server/needle_through_script.yaml",
                                   "--domain", std::to_string(domain), "--no-realtime"};
  if (crtk) tool.push_back("--crtk");
  Process driver(tool);
  std::vector<stroma_NeedleEvent> events;
  std::set<int> phases;
  double max_inserted = 0, worst_off_axis = 0;
  size_t max_track = 0, states = 0, held = 0;
  bool released = false;  // held, then held by nothing: the script's jaws opened
  const auto end = Clock::now() + std::chrono::seconds(40);
  while (Clock::now() < end && (events.empty() || events.back().kind != stroma_NEEDLE_LEFT || !released)) {
    take_needle_events(ev_reader, events);
    void* sm[1] = {nullptr};
    dds_sample_info_t si[1];
    if (dds_take(st_reader, sm, si, 1, 1) > 0) {
      const auto* s = static_cast<const stroma_RigidBodyState*>(sm[0]);
      if (si[0].valid_data) {
        ++states;
        EXPECT_STREQ(s->body, "needle");
        held += std::string(s->held_by) == "grasper";
        // Let go while the client still commands (its jaw opened), not after it stopped (the
        // tool's timeout would let go too).
        released = released || (held > 0 && std::string(s->held_by).empty() && still_running(driver.pid()));
        if (s->needle_phase != stroma_NEEDLE_OUTSIDE) EXPECT_STREQ(s->held_by, "grasper") << "held while in the tissue";
        phases.insert(static_cast<int>(s->needle_phase));
        max_inserted = std::max(max_inserted, s->inserted_length);
        max_track = std::max<size_t>(max_track, s->track._length / 3);
        ASSERT_EQ(s->track._length % 3, 0u);
        if (s->needle_phase != stroma_NEEDLE_OUTSIDE) EXPECT_STREQ(s->tissue, "block");
        // Every track point is tissue on the needle's path: on its axis, the shape frame's z from
        // the published position along the published orientation, to the wire's size.
        const double* qv = s->orientation;
        const double axis[3] = {2 * (qv[1] * qv[3] + qv[0] * qv[2]), 2 * (qv[2] * qv[3] - qv[0] * qv[1]),
                                1 - 2 * (qv[1] * qv[1] + qv[2] * qv[2])};
        for (uint32_t i = 0; i + 2 < s->track._length; i += 3) {
          double d[3], along = 0, off = 0;
          for (int c = 0; c < 3; ++c) along += (d[c] = s->track._buffer[i + c] - s->position[c]) * axis[c];
          for (int c = 0; c < 3; ++c) off += (d[c] - along * axis[c]) * (d[c] - along * axis[c]);
          worst_off_axis = std::max(worst_off_axis, std::sqrt(off));
          EXPECT_GE(along, -1e-3);
          EXPECT_LE(along, 0.08 + 1e-3);
        }
      }
      dds_return_loan(st_reader, sm, 1);
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  ASSERT_EQ(events.size(), 3u) << "a puncture, an exit and the needle leaving";
  EXPECT_EQ(events[0].kind, stroma_NEEDLE_PUNCTURE);
  EXPECT_EQ(events[1].kind, stroma_NEEDLE_EXIT);
  EXPECT_EQ(events[2].kind, stroma_NEEDLE_LEFT);
  for (const stroma_NeedleEvent& e : events) {
    EXPECT_STREQ(e.needle, "needle");
    EXPECT_STREQ(e.tissue, "block");
    EXPECT_NEAR(e.position[1], 0.03, 1e-3) << "the needle moves along x at y = 0.03";
  }
  EXPECT_EQ(events[0].punctures, 1u);
  EXPECT_EQ(events[1].punctures, 2u);
  EXPECT_GE(events[0].tip_force, 0.3) << "it punctures above the puncture force";
  EXPECT_NEAR(events[0].position[0], 0.0, 2e-3) << "the tip enters at the x = 0 face (dimpling it)";
  EXPECT_NEAR(events[1].position[0], 0.05, 3e-3) << "and leaves through x = 0.05";
  EXPECT_LT(events[0].sim_time, events[1].sim_time);
  EXPECT_LT(events[1].sim_time, events[2].sim_time);
  EXPECT_GT(states, 20u);
  EXPECT_GT(held, 10u) << "the grasper holds it";
  EXPECT_TRUE(released) << "opening the jaws lets it go (with --crtk: rt/grasper/jaw/servo_jp)";
  EXPECT_EQ(phases, (std::set<int>{stroma_NEEDLE_OUTSIDE, stroma_NEEDLE_INSERTED, stroma_NEEDLE_EXITED}));
  EXPECT_NEAR(max_inserted, 0.05, 3e-3) << "through the whole block";
  EXPECT_GE(max_track, 5u);
  EXPECT_LT(worst_off_axis, 1e-3) << "the track stays on the needle's path";
  EXPECT_EQ(driver.wait_exit(15), 0);
  server.signal(SIGTERM);
  EXPECT_EQ(server.wait_exit(15), 0);
}

// `stroma tool --resume` starts a paused server once its first pose is in (the first tick has
// the tool where its script starts).
TEST(Serve, AToolClientResumesAPausedServer) {
  Server server(185, {"--duration", "60", "--paused"});
  Client client(185);
  ASSERT_TRUE(client.wait_status(15, [](const stroma_SimStatus& st) { return st.state == stroma_PAUSED; }));
  stroma_SimStatus s{};
  EXPECT_FALSE(client.wait_status(1, [](const stroma_SimStatus& st) { return st.ticks > 0; }, &s)) << "paused: no ticks";
  Process tool({STROMA_BINARY, "tool", "--name", "probe", "--script", kPress, "--duration", "1", "--domain", "185",
                "--no-realtime", "--resume"});
  ASSERT_TRUE(client.wait_status(15, [](const stroma_SimStatus& st) { return st.state == stroma_RUNNING && st.ticks > 100; }, &s))
      << "the client's RESUME did not start it";
  EXPECT_GT(s.commands_accepted, 0u);
  EXPECT_EQ(tool.wait_exit(15), 0);
  server.signal(SIGTERM);
  EXPECT_EQ(server.wait_exit(15), 0);
}

// A needle through an incision under `stroma serve`, as users drive it: one client's scalpel
// cuts the block's upper part across the needle's path (the cut model built on the server's
// worker and swapped in at a tick), then another client's grasper drives the needle through
// both lips and back. The events a DDS client reads are two bites': puncture, exit at the cut,
// puncture of the far lip, exit from the far face, and the needle leaving (docs/NEEDLE.md).
void needle_through_incision_over_dds(int domain, bool crtk) {
  STROMA_LONG_TEST();  // 7.5 s each in the release build; the sanitizers run the needle's serve test above
  const std::string data = std::string(STROMA_SOURCE_DIR) + "/tests/data/server/";
  std::vector<std::string> args = {STROMA_BINARY, "serve", data + "needle_incision.yaml", "--domain",
                                   std::to_string(domain), "--realtime", "off", "--duration", "60"};
  if (crtk) args.push_back("--crtk");
  Process server(args);
  Client client(domain);
  const dds_entity_t ev_reader = needle_event_reader(client.participant());
  ASSERT_TRUE(client.wait_status(15, [](const stroma_SimStatus& st) { return st.ticks > 100; }));
  auto tool = [&](const char* name, const std::string& script) {
    std::vector<std::string> a = {STROMA_BINARY, "tool", "--name", name, "--script", data + script,
                                  "--domain", std::to_string(domain), "--no-realtime"};
    if (crtk) a.push_back("--crtk");
    return a;
  };
  {
    Process scalpel(tool("scalpel", "scalpel_incision_script.yaml"));
    EXPECT_EQ(scalpel.wait_exit(30), 0);
  }
  ASSERT_TRUE(client.wait_status(10, [](const stroma_SimStatus& st) {
    return st.topology_version > 0 && st.elements_split > 0 && st.cut_area > 0;
  })) << "the scalpel never cut the block";
  std::this_thread::sleep_for(std::chrono::milliseconds(300));  // the last cut swapped in
  Process driver(tool("grasper", "needle_incision_script.yaml"));
  std::vector<stroma_NeedleEvent> events;
  for (const auto end = Clock::now() + std::chrono::seconds(40);
       Clock::now() < end && (events.empty() || events.back().kind != stroma_NEEDLE_LEFT);) {
    take_needle_events(ev_reader, events);
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  std::string seen;
  for (const stroma_NeedleEvent& e : events) seen += std::to_string(e.kind) + "@" + std::to_string(e.position[0]) + " ";
  // Puncture, then exits and punctures alternating, then the needle leaving; the first puncture on
  // x = 0, an exit from the near lip and a puncture of the far lip at the cut, and an exit from
  // the far face. Served, the scene is not the same run to run, and the test accepts what the
  // runs showed around that: a sliver 0.1–0.3 mm thick left at the plane by some cuts (one more
  // exit and puncture there: a served cut is made in increments swapped in at ticks set by its
  // worker's timing); under a loaded machine's degraded ticks (CI: 11 % missed, solves cut by
  // the budget) a re-bite at the far face, punctured and exited in one tick.
  ASSERT_GE(events.size(), 5u) << seen;
  const size_t n = events.size();
  bool cut_exit = false, cut_entry = false, far_exit = false;
  for (size_t i = 0; i < n; ++i) {
    const uint32_t want = i + 1 == n ? stroma_NEEDLE_LEFT : i % 2 == 0 ? stroma_NEEDLE_PUNCTURE : stroma_NEEDLE_EXIT;
    EXPECT_EQ(static_cast<uint32_t>(events[i].kind), want) << i << ": " << seen;
    EXPECT_STREQ(events[i].tissue, "block");
    if (i > 0) EXPECT_LE(events[i - 1].sim_time, events[i].sim_time);
    if (i + 1 == n) break;
    // Each puncture and exit counted (an event carries the count at the end of its tick).
    EXPECT_GE(events[i].punctures, i + 1) << seen;
    EXPECT_LE(events[i].punctures, n - 1) << seen;
    const double x = events[i].position[0];
    const bool at_cut = std::abs(x - 0.025) < 3e-3, beyond = x > 0.047;
    if (i > 0) EXPECT_TRUE(at_cut || beyond) << i << ": at the cut or the far face; " << seen;
    cut_exit = cut_exit || (want == stroma_NEEDLE_EXIT && at_cut);
    cut_entry = cut_entry || (want == stroma_NEEDLE_PUNCTURE && at_cut && cut_exit);
    far_exit = far_exit || (want == stroma_NEEDLE_EXIT && beyond);
  }
  EXPECT_NEAR(events[0].position[0], 0.0, 2e-3) << "in through the x = 0 face";
  EXPECT_TRUE(cut_exit && cut_entry) << "out of the near lip and into the far lip at the cut: " << seen;
  EXPECT_TRUE(far_exit) << "out through the far face: " << seen;
  EXPECT_EQ(driver.wait_exit(15), 0);
  server.signal(SIGTERM);
  EXPECT_EQ(server.wait_exit(15), 0);
}

// More than one needle served (docs/NEEDLE.md): two needles in one block, each driven by a
// client of its own at the same time (`stroma tool` twice). Each needle's events and state are
// its own, keyed by its name: a puncture on x = 0 at its z, an exit through x = 0.05, then
// leaving as it is withdrawn; each held by its own grasper while in the tissue.
TEST(Serve, TwoNeedlesDrivenByTwoClientsEachPunctureExitAndLeave) {
  const int domain = 191;
  const std::string data = std::string(STROMA_SOURCE_DIR) + "/tests/data/server/";
  Process server({STROMA_BINARY, "serve", data + "two_needles.yaml", "--domain", std::to_string(domain), "--realtime",
                  "off", "--duration", "60", "--paused"});
  Client client(domain);
  const dds_entity_t ev_reader = needle_event_reader(client.participant());
  const dds_entity_t st_reader = rigid_state_reader(client.participant());
  ASSERT_TRUE(client.wait_status(15, [](const stroma_SimStatus& st) { return st.state == stroma_PAUSED; }));
  std::this_thread::sleep_for(std::chrono::milliseconds(500));  // the readers matched
  client.control(stroma_RESUME);
  auto tool = [&](const char* name, const char* script) {
    return std::vector<std::string>{STROMA_BINARY, "tool", "--name", name, "--script", data + script,
                                    "--domain", std::to_string(domain), "--no-realtime"};
  };
  Process driver_a(tool("grasper_a", "two_needles_a_script.yaml"));
  Process driver_b(tool("grasper_b", "two_needles_b_script.yaml"));
  std::map<std::string, std::vector<stroma_NeedleEvent>> events;
  std::map<std::string, double> max_inserted;
  std::map<std::string, size_t> held;
  std::vector<stroma_NeedleEvent> taken;
  auto left = [&](const char* n) { return !events[n].empty() && events[n].back().kind == stroma_NEEDLE_LEFT; };
  for (const auto end = Clock::now() + std::chrono::seconds(40); Clock::now() < end && !(left("needle_a") && left("needle_b"));) {
    taken.clear();
    take_needle_events(ev_reader, taken);
    for (const stroma_NeedleEvent& e : taken) events[e.needle].push_back(e);
    void* sm[4] = {nullptr};
    dds_sample_info_t si[4];
    const dds_return_t n = dds_take(st_reader, sm, si, 4, 4);
    for (dds_return_t i = 0; i < n; ++i) {
      if (!si[i].valid_data) continue;
      const auto* st = static_cast<const stroma_RigidBodyState*>(sm[i]);
      const std::string body = st->body;
      max_inserted[body] = std::max(max_inserted[body], st->inserted_length);
      if (st->needle_phase == stroma_NEEDLE_OUTSIDE) continue;
      const std::string grasper = body == "needle_a" ? "grasper_a" : "grasper_b";
      EXPECT_EQ(std::string(st->held_by), grasper) << body << " in the tissue, held by its own grasper";
      ++held[body];
    }
    if (n > 0) dds_return_loan(st_reader, sm, n);
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  EXPECT_EQ(events.size(), 2u) << "events from both needles, and no other";
  for (const auto& [name, z] : {std::pair{"needle_a", 0.015}, std::pair{"needle_b", 0.035}}) {
    const std::vector<stroma_NeedleEvent>& ev = events[name];
    ASSERT_EQ(ev.size(), 3u) << name << ": a puncture, an exit and leaving";
    EXPECT_EQ(ev[0].kind, stroma_NEEDLE_PUNCTURE);
    EXPECT_EQ(ev[1].kind, stroma_NEEDLE_EXIT);
    EXPECT_EQ(ev[2].kind, stroma_NEEDLE_LEFT);
    EXPECT_EQ(ev[0].punctures, 1u);
    EXPECT_EQ(ev[1].punctures, 2u);
    EXPECT_NEAR(ev[0].position[0], 0.0, 2e-3) << name << " enters at x = 0";
    EXPECT_NEAR(ev[1].position[0], 0.05, 3e-3) << name << " leaves through x = 0.05";
    for (const stroma_NeedleEvent& e : ev) {
      EXPECT_STREQ(e.tissue, "block");
      EXPECT_NEAR(e.position[2], z, 1e-3) << name << " along its own line";
    }
    EXPECT_NEAR(max_inserted[name], 0.05, 3e-3) << name << " through the whole block";
    EXPECT_GT(held[name], 10u) << name;
  }
  EXPECT_EQ(driver_a.wait_exit(15), 0);
  EXPECT_EQ(driver_b.wait_exit(15), 0);
  server.signal(SIGTERM);
  EXPECT_EQ(server.wait_exit(15), 0);
}

namespace {
/// Bounding box of 3-float points (of those with x in [x0, x1]): min x, y, z then max x, y, z.
std::array<double, 6> bounds(const float* p, uint32_t n, double x0 = -1e30, double x1 = 1e30) {
  std::array<double, 6> b{1e30, 1e30, 1e30, -1e30, -1e30, -1e30};
  for (uint32_t i = 0; i + 2 < n; i += 3)
    for (int k = 0; k < 3; ++k) {
      if (p[i] < x0 || p[i] > x1) break;
      b[size_t(k)] = std::min(b[size_t(k)], double(p[i + size_t(k)]));
      b[size_t(k) + 3] = std::max(b[size_t(k) + 3], double(p[i + size_t(k)]));
    }
  return b;
}

/// A prestretched body served (docs/TISSUE.md, "Prestretch"): scenarios/prestretched_bar.yaml, a
/// 50 mm cube whose mesh is stretched 5 % along x over its rest shape, held at both ends. The
/// TissueMesh's rest positions are the rest shape (50/1.05 mm along x); the state — the first
/// frame of a paused server, the frames while it runs, the frame after a Reset — is the mesh
/// (50 mm along x, held there).
void prestretch_over_dds(int domain, bool crtk) {
  Process server(paused_serve_args("/scenarios/prestretched_bar.yaml", domain, crtk));
  Client client(domain);
  ASSERT_TRUE(client.wait_status(15, [](const stroma_SimStatus& st) { return st.state == stroma_PAUSED; }));
  const dds_entity_t pp = client.participant();
  dds_qos_t* q = dds_create_qos();
  dds_qset_reliability(q, DDS_RELIABILITY_RELIABLE, DDS_SECS(1));
  dds_qset_durability(q, DDS_DURABILITY_TRANSIENT_LOCAL);
  dds_qset_history(q, DDS_HISTORY_KEEP_LAST, 1);
  const dds_entity_t mesh_reader =
      dds_create_reader(pp, dds_create_topic(pp, &stroma_TissueMesh_desc, "stroma_TissueMesh", nullptr, nullptr), q, nullptr);
  dds_qset_reliability(q, DDS_RELIABILITY_BEST_EFFORT, 0);
  dds_qset_durability(q, DDS_DURABILITY_VOLATILE);
  const dds_entity_t state_reader =
      dds_create_reader(pp, dds_create_topic(pp, &stroma_TissueState_desc, "stroma_TissueState", nullptr, nullptr), q, nullptr);
  dds_delete_qos(q);

  const double L = 0.05, s = 1.05;
  std::array<double, 6> rest{};
  bool have_mesh = false;
  for (auto end = Clock::now() + std::chrono::seconds(10); !have_mesh && Clock::now() < end;) {
    void* samples[1] = {nullptr};
    dds_sample_info_t info;
    if (dds_take(mesh_reader, samples, &info, 1, 1) > 0) {
      const auto* m = static_cast<const stroma_TissueMesh*>(samples[0]);
      if (info.valid_data) {
        rest = bounds(m->rest_positions._buffer, m->rest_positions._length);
        have_mesh = true;
      }
      dds_return_loan(mesh_reader, samples, 1);
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  ASSERT_TRUE(have_mesh);
  EXPECT_NEAR(rest[3] - rest[0], L / s, 1e-6) << "rest positions: the rest shape, shrunk along x";
  EXPECT_NEAR(rest[4] - rest[1], L, 1e-6);
  EXPECT_NEAR(rest[5] - rest[2], L, 1e-6);

  // The newest state frame satisfying `pred` within `seconds`; its bounds and sim time.
  // (mid: of the vertices within 5 mm of mid-length, where the bar necks; its ends are held.)
  auto state = [&](double seconds, const std::function<bool(double)>& pred, std::array<double, 6>* b, double* t,
                   std::array<double, 6>* mid) {
    for (auto end = Clock::now() + std::chrono::duration<double>(seconds); Clock::now() < end;) {
      void* samples[1] = {nullptr};
      dds_sample_info_t info;
      bool ok = false;
      if (dds_take(state_reader, samples, &info, 1, 1) > 0) {
        const auto* st = static_cast<const stroma_TissueState*>(samples[0]);
        if (info.valid_data && st->positions._length > 0 && pred(st->sim_time)) {
          *b = bounds(st->positions._buffer, st->positions._length);
          *mid = bounds(st->positions._buffer, st->positions._length, L / 2 - 0.005, L / 2 + 0.005);
          *t = st->sim_time;
          ok = true;
        }
        dds_return_loan(state_reader, samples, 1);
      }
      if (ok) return true;
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    return false;
  };
  auto is_mesh = [&](const std::array<double, 6>& b, const char* when) {
    EXPECT_NEAR(b[0], 0.0, 1e-6) << when << ": held at x = 0";
    EXPECT_NEAR(b[3], L, 1e-6) << when << ": held at x = 50 mm, the mesh's length";
  };
  std::array<double, 6> b{}, mid{};
  double t = -1;
  ASSERT_TRUE(state(10, [](double) { return true; }, &b, &t, &mid)) << "a paused server publishes its state once";
  EXPECT_EQ(t, 0.0);
  is_mesh(b, "first frame (paused)");
  EXPECT_NEAR(mid[4] - mid[1], L, 1e-6) << "the first frame is the mesh: no necking yet";
  EXPECT_NEAR(mid[5] - mid[2], L, 1e-6);

  client.control(stroma_RESUME);
  ASSERT_TRUE(state(15, [](double time) { return time > 0.2; }, &b, &t, &mid)) << "frames while running";
  is_mesh(b, "running");
  EXPECT_LT(mid[4] - mid[1], L - 1e-4) << "the free faces neck in under the tension";
  EXPECT_LT(mid[5] - mid[2], L - 1e-4);

  client.control(stroma_PAUSE);
  ASSERT_TRUE(client.wait_status(5, [](const stroma_SimStatus& st) { return st.state == stroma_PAUSED; }));
  client.control(stroma_RESET);
  ASSERT_TRUE(state(10, [](double time) { return time == 0.0; }, &b, &t, &mid))
      << "a Reset while paused publishes the initial state";
  is_mesh(b, "after a Reset");
  EXPECT_NEAR(mid[4] - mid[1], L, 1e-6) << "after a Reset: the mesh again";
  server.signal(SIGTERM);
  EXPECT_EQ(server.wait_exit(15), 0);
}
}  // namespace

namespace {
/// A thread scene served (tests/data/server/thread.yaml): its stroma_ThreadState samples, as a
/// client written from the IDL reads them — the paused first frame is the thread as the
/// scenario lays it out (straight along −x from its start, its rest length), and while running
/// its free end swings down while its held end stays and it stretches < 1 %.
/// A best-effort, keep-last reader of stroma_ThreadState (as a client written from the IDL makes).
dds_entity_t thread_state_reader(dds_entity_t pp) {
  dds_qos_t* q = dds_create_qos();
  dds_qset_reliability(q, DDS_RELIABILITY_BEST_EFFORT, 0);
  dds_qset_history(q, DDS_HISTORY_KEEP_LAST, 1);
  const dds_entity_t reader =
      dds_create_reader(pp, dds_create_topic(pp, &stroma_ThreadState_desc, "stroma_ThreadState", nullptr, nullptr), q, nullptr);
  dds_delete_qos(q);
  return reader;
}

void thread_over_dds(int domain, bool crtk) {
  const std::string stats = (fs::temp_directory_path() / ("stroma_serve_thread_" + std::to_string(domain) + ".json")).string();
  fs::remove(stats);
  std::vector<std::string> args = paused_serve_args("/tests/data/server/thread.yaml", domain, crtk);
  args.insert(args.end(), {"--stats", stats});
  Process server(args);
  Client client(domain);
  const dds_entity_t pp = client.participant();
  const dds_entity_t reader = thread_state_reader(pp);
  ASSERT_GT(reader, 0);
  struct Sample {
    double t = -1, length = 0, rest = 0, diameter = 0, tension = 0;
    size_t punctures = 0;
    std::vector<float> x;
    std::string name;
  };
  auto take = [&](double seconds, const std::function<bool(double)>& pred, Sample* out) {
    for (auto end = Clock::now() + std::chrono::duration<double>(seconds); Clock::now() < end;) {
      void* sm[1] = {nullptr};
      dds_sample_info_t info;
      bool ok = false;
      if (dds_take(reader, sm, &info, 1, 1) > 0) {
        const auto* st = static_cast<const stroma_ThreadState*>(sm[0]);
        if (info.valid_data && pred(st->sim_time)) {
          out->t = st->sim_time;
          out->length = st->length;
          out->rest = st->rest_length;
          out->diameter = st->diameter;
          out->tension = st->max_tension;
          out->x.assign(st->positions._buffer, st->positions._buffer + st->positions._length);
          out->punctures = st->punctures._length;
          out->name = st->thread;
          ok = true;
        }
        dds_return_loan(reader, sm, 1);
      }
      if (ok) return true;
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    return false;
  };
  Sample s;
  ASSERT_TRUE(take(15, [](double) { return true; }, &s)) << "a paused server publishes the thread once";
  EXPECT_EQ(s.t, 0.0);
  EXPECT_EQ(s.name, "suture");
  ASSERT_EQ(s.x.size(), 3u * 41u);
  EXPECT_DOUBLE_EQ(s.rest, 0.1);
  EXPECT_DOUBLE_EQ(s.diameter, 2e-4);
  EXPECT_NEAR(s.length, 0.1, 1e-6);
  EXPECT_LT(s.tension, 1e-9) << "straight at its rest length: no tension but round-off";
  EXPECT_EQ(s.punctures, 0u) << "it goes through no tissue";
  for (int i = 0; i <= 40; ++i) {
    EXPECT_NEAR(s.x[3 * i], -0.01 - 0.0025 * i, 1e-6) << i;
    EXPECT_NEAR(s.x[3 * i + 1], 0.1, 1e-6) << i;
  }
  client.control(stroma_RESUME);
  ASSERT_TRUE(take(15, [](double t) { return t > 0.2; }, &s)) << "frames while running";
  EXPECT_NEAR(s.x[0], -0.01, 1e-6) << "the held end stays";
  EXPECT_NEAR(s.x[1], 0.1, 1e-6);
  EXPECT_LT(s.x[3 * 40 + 1], 0.1 - 0.05) << "the free end swung down";
  EXPECT_NEAR(s.length, 0.1, 0.001) << "stretched < 1 %";
  EXPECT_GT(s.tension, 0.0) << "its weight and swing pull on it";
  server.signal(SIGTERM);
  EXPECT_EQ(server.wait_exit(15), 0);
  // --stats counts what the continuous contact check after the step did (docs/THREAD.md, "Contact").
  std::ifstream in(stats);
  ASSERT_TRUE(in.good()) << stats;
  const auto j = nlohmann::json::parse(in);
  ASSERT_TRUE(j.contains("thread_contact")) << j.dump();
  EXPECT_GE(j["thread_contact"]["missed_springs_added"].get<int64_t>(), 0);
  EXPECT_GE(j["thread_contact"]["checks_skipped"].get<int64_t>(), 0);
  EXPECT_LE(j["thread_contact"]["checks_skipped"].get<int64_t>(), j["ticks"].get<int64_t>());
}

// Served end to end: tests/data/thread_draw_through.yaml under `stroma serve`, its graspers driven
// by two `stroma tool` clients one after the other — the driver takes the needle 65 mm into the
// block and lets go, the puller takes its tip beyond the far face and draws it 80 mm on. A client
// written from the IDL reads stroma_ThreadState: the thread goes through the block at the entry
// (x = 0) and the exit (x = 50 mm), each puncture its tissue point and σ (segments from the
// tied end), the thread's point at σ on it, and σ's arc length what the needle travelled past it.
void thread_draw_through_over_dds(int domain, bool crtk) {
  STROMA_LONG_TEST();  // ~6 s served
  const std::string data = std::string(STROMA_SOURCE_DIR) + "/tests/data/";
  std::vector<std::string> args = {STROMA_BINARY, "serve", data + "thread_draw_through.yaml", "--domain",
                                   std::to_string(domain), "--realtime", "off", "--duration", "60"};
  if (crtk) args.push_back("--crtk");
  Process server(args);
  Client client(domain);
  const dds_entity_t pp = client.participant();
  const dds_entity_t reader = thread_state_reader(pp);
  ASSERT_GT(reader, 0);
  ASSERT_TRUE(client.wait_status(15, [](const stroma_SimStatus& st) { return st.ticks > 100; }));
  auto tool = [&](const char* name, const std::string& script) {
    std::vector<std::string> a = {STROMA_BINARY, "tool", "--name", name, "--script", data + "server/" + script,
                                  "--domain", std::to_string(domain), "--no-realtime"};
    if (crtk) a.push_back("--crtk");
    return a;
  };
  {
    Process driver(tool("driver", "thread_draw_driver.yaml"));
    EXPECT_EQ(driver.wait_exit(30), 0);
  }
  {
    Process puller(tool("puller", "thread_draw_puller.yaml"));
    EXPECT_EQ(puller.wait_exit(30), 0);
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  std::vector<float> x, punctures;
  for (const auto end = Clock::now() + std::chrono::seconds(10); Clock::now() < end && punctures.empty();) {
    void* sm[1] = {nullptr};
    dds_sample_info_t info;
    if (dds_take(reader, sm, &info, 1, 1) > 0) {
      const auto* st = static_cast<const stroma_ThreadState*>(sm[0]);
      if (info.valid_data) {
        x.assign(st->positions._buffer, st->positions._buffer + st->positions._length);
        punctures.assign(st->punctures._buffer, st->punctures._buffer + st->punctures._length);
      }
      dds_return_loan(reader, sm, 1);
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  server.signal(SIGTERM);
  EXPECT_EQ(server.wait_exit(15), 0);
  ASSERT_EQ(punctures.size(), 8u) << "two punctures, 4 floats each (point, sigma)";
  ASSERT_EQ(x.size(), 3u * 51u);
  const double seg = 0.1 / 50, tail_x = x[0];
  EXPECT_GT(tail_x, 0.05) << "the needle's tail, and the thread's end with it, is out of the far face";
  const double expect_x[2] = {0.0, 0.05};
  for (int k = 0; k < 2; ++k) {
    const float* p = punctures.data() + 4 * k;
    EXPECT_NEAR(p[0], expect_x[k], 0.003) << "puncture " << k << (k ? ": the exit" : ": the entry");
    const double sigma = p[3];
    const int j = std::min(49, static_cast<int>(sigma));
    const double u = sigma - j;
    double d2 = 0;
    for (int c = 0; c < 3; ++c) d2 += std::pow((1 - u) * x[3 * j + c] + u * x[3 * j + 3 + c] - p[c], 2);
    EXPECT_LT(std::sqrt(d2), 5e-4) << "puncture " << k << ": the thread passes through its point";
    EXPECT_NEAR(sigma * seg, tail_x - p[0], 0.005) << "puncture " << k << ": slid through by the travel";
  }
}
}  // namespace

TEST(Serve, AThreadDrawnThroughTheTissueIsPublishedWithItsPunctures) { thread_draw_through_over_dds(198, false); }
TEST(Serve, AThreadDrawnThroughTheTissueIsPublishedWithItsPuncturesWithCrtk) { thread_draw_through_over_dds(199, true); }
TEST(Serve, AThreadsNodesArePublished) { thread_over_dds(194, false); }
TEST(Serve, AThreadsNodesArePublishedWithCrtk) { thread_over_dds(195, true); }
TEST(Serve, APrestretchedBodyIsPublishedAsItsMeshFromTheFirstFrame) { prestretch_over_dds(192, false); }
TEST(Serve, APrestretchedBodyIsPublishedAsItsMeshFromTheFirstFrameWithCrtk) { prestretch_over_dds(193, true); }
TEST(Serve, RigidBodiesAndNeedleEventsArePublished) { needle_over_dds(183, false); }
TEST(Serve, ANeedleThroughAnIncisionBitesBothLips) { needle_through_incision_over_dds(188, false); }
TEST(Serve, ANeedleThroughAnIncisionBitesBothLipsWithCrtk) { needle_through_incision_over_dds(189, true); }
TEST(Serve, RigidBodiesAndNeedleEventsArePublishedWithCrtk) { needle_over_dds(184, true); }

// With a receive priority, the built-in configuration runs Cyclone's single receive thread
// ("recv"; no "recvUC", whose priority 0.10 cannot configure) under SCHED_FIFO when the process
// may, and says which it got; the participant works either way.
TEST(Dds, ReceiveThreadRunsAtTheRequestedRealTimePriority) {
  const std::string xml = loopback_config_with_receive_priority(42);
  EXPECT_NE(xml.find("<Thread Name=\"recv\"><Scheduling><Class>realtime</Class><Priority>42</Priority>"), std::string::npos);
  EXPECT_NE(xml.find("<MultipleReceiveThreads>false</MultipleReceiveThreads>"), std::string::npos);
  EXPECT_NE(xml.find("<NetworkInterface name=\"lo\"/>"), std::string::npos) << "still loopback only";
  const DdsParticipant p = create_participant(171, "", 42);
  ASSERT_GT(p.participant, 0);
  const bool fifo = fifo_permitted(42);
  EXPECT_NE(p.config_source.find(fifo ? "receive thread SCHED_FIFO 42" : "SCHED_FIFO denied"), std::string::npos)
      << p.config_source;
  int recv = 0, recv_uc = 0;
  for (const auto& t : std::filesystem::directory_iterator("/proc/self/task")) {
    std::ifstream comm(t.path() / "comm");
    std::string name;
    std::getline(comm, name);
    if (name == "recvUC") ++recv_uc;
    if (name != "recv") continue;
    ++recv;
    const pid_t tid = static_cast<pid_t>(std::stol(t.path().filename().string()));
    sched_param sp{};
    const int policy = sched_getscheduler(tid);
    sched_getparam(tid, &sp);
    if (fifo) {
      EXPECT_EQ(policy, SCHED_FIFO);
      EXPECT_EQ(sp.sched_priority, 42);
    }
  }
  EXPECT_EQ(recv, 1);
  EXPECT_EQ(recv_uc, 0);
  dds_delete(p.participant);
}
