// `stroma serve` as a separate process on loopback, driven and observed over DDS like a real
// client: late-joining mesh subscriber, status, pause / step / resume / reset / shutdown,
// SIGTERM. Each test uses its own DDS domain so ctest -j can run them side by side.

#include <gtest/gtest.h>

#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "server/dds_participant.hpp"
#include "stroma.h"

extern char** environ;

using namespace stroma;
namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

namespace {

/// A `stroma serve` child process.
class Server {
 public:
  Server(int domain, std::vector<std::string> extra) {
    std::vector<std::string> args = {STROMA_BINARY, "serve",
                                     std::string(STROMA_SOURCE_DIR) + "/scenarios/liver.yaml",
                                     "--domain", std::to_string(domain), "--realtime", "off"};
    args.insert(args.end(), extra.begin(), extra.end());
    std::vector<char*> argv;
    for (auto& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    EXPECT_EQ(posix_spawn(&pid_, argv[0], nullptr, nullptr, argv.data(), environ), 0);
  }
  ~Server() {
    if (pid_ > 0) {
      kill(pid_, SIGKILL);
      waitpid(pid_, nullptr, 0);
    }
  }
  /// Waits for the process to exit; returns its exit status (−1 on timeout).
  int wait_exit(double seconds) {
    const auto end = Clock::now() + std::chrono::duration<double>(seconds);
    while (Clock::now() < end) {
      int st = 0;
      if (waitpid(pid_, &st, WNOHANG) == pid_) {
        pid_ = -1;
        return WIFEXITED(st) ? WEXITSTATUS(st) : 128 + WTERMSIG(st);
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    return -1;
  }
  void signal(int sig) { kill(pid_, sig); }

 private:
  pid_t pid_ = -1;
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
    dds_qset_history(q, DDS_HISTORY_KEEP_ALL, 0);
    control_writer_ = dds_create_writer(pp_, control_topic_, q, nullptr);
    dds_delete_qos(q);
  }
  ~Client() { dds_delete(pp_); }
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
        if (info.valid_data && pred(s)) {
          if (out) *out = s;
          return true;
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
  dds_entity_t pp_, status_topic_, control_topic_, status_reader_, control_writer_;
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
