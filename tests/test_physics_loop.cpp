// The fixed-rate physics loop with its lock-free ports, exercised from other threads as the
// server does (also under ThreadSanitizer: cmake --preset tsan).

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <thread>

#include "engine/physics_loop.hpp"
#include "engine/spsc_queue.hpp"

using namespace stroma;

TEST(SpscQueue, FifoOrderCapacityAndConcurrentTransfer) {
  SpscQueue<int, 4> q;
  for (int i = 0; i < 4; ++i) EXPECT_TRUE(q.push(i));
  EXPECT_FALSE(q.push(99));  // full: refused, never blocks
  int v = -1;
  for (int i = 0; i < 4; ++i) {
    ASSERT_TRUE(q.pop(v));
    EXPECT_EQ(v, i);
  }
  EXPECT_FALSE(q.pop(v));

  SpscQueue<int64_t, 64> big;
  constexpr int64_t kN = 100000;
  std::thread producer([&] {
    for (int64_t i = 1; i <= kN; ++i)
      while (!big.push(i)) std::this_thread::yield();
  });
  int64_t expect = 1, x;
  while (expect <= kN)
    if (big.pop(x)) EXPECT_EQ(x, expect++);
  producer.join();
}

TEST(PhysicsLoop, TicksAtTheStepRateAndObeysControlsFromAnotherThread) {
  ScenarioSpec spec = load_scenario(std::string(STROMA_SOURCE_DIR) + "/scenarios/liver.yaml");
  auto m = compile_model(spec);
  PhysicsLoopOptions opt;
  opt.status_every = 20;
  opt.publish_every = 5;
  PhysicsLoop loop(m, opt);
  loop.state_wanted = true;
  std::atomic<bool> stop{false};
  std::thread physics([&] { loop.run(stop); });

  // Consumer: reads frames and statuses while physics runs; frames must be whole and ordered.
  uint64_t last_frame = 0, frames = 0, statuses = 0;
  double last_time = -1;
  auto consume_for = [&](double seconds) {
    const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
    while (std::chrono::steady_clock::now() < end) {
      if (loop.state_out.update()) {
        const StateFrame& f = loop.state_out.read_slot();
        EXPECT_GT(f.frame, last_frame);
        EXPECT_EQ(f.x.size(), m->fem.rest.size());
        EXPECT_TRUE(std::isfinite(f.x[0]));
        last_frame = f.frame;
        ++frames;
      }
      if (loop.status_out.update()) {
        const StatusFrame& s = loop.status_out.read_slot();
        EXPECT_GE(s.sim_time, last_time - 1e-12);
        last_time = s.sim_time;
        ++statuses;
      }
      std::this_thread::sleep_for(std::chrono::microseconds(200));
    }
  };
  // Let it run for at least 50 ticks (a sanitizer build or a loaded machine runs slower).
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30);
  while (loop.status_out.read_slot().ticks < 50 && std::chrono::steady_clock::now() < deadline)
    consume_for(0.05);
  ASSERT_GE(loop.status_out.read_slot().ticks, 50u);
  ASSERT_TRUE(loop.controls.push({ControlEvent::Pause, 0}));
  consume_for(0.3);
  const uint64_t paused_at = loop.status_out.read_slot().ticks;
  consume_for(0.3);
  EXPECT_EQ(loop.status_out.read_slot().ticks, paused_at) << "paused: no ticks";
  ASSERT_TRUE(loop.controls.push({ControlEvent::Step, 3}));
  consume_for(0.3);
  EXPECT_EQ(loop.status_out.read_slot().ticks, paused_at + 3);
  ASSERT_TRUE(loop.controls.push({ControlEvent::Shutdown, 0}));
  physics.join();
  EXPECT_TRUE(loop.finished.load());
  const PhysicsLoopStats& st = loop.stats();
  EXPECT_GE(frames, 5u);  // every 5th tick of ≥ 50
  EXPECT_GE(statuses, 3u);
  EXPECT_EQ(st.ticks, paused_at + 3);
  EXPECT_GT(st.loops, st.ticks);  // the paused loops kept their schedule without ticking
  EXPECT_EQ(st.wake.count(), static_cast<int64_t>(st.loops));
  EXPECT_DOUBLE_EQ(st.sim_time, static_cast<double>(loop.state().step) * m->time_step);
}
