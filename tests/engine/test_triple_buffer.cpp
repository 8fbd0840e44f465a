// engine/triple_buffer: the lock-free hand-off. The concurrent test also runs under
// ThreadSanitizer (cmake -DSTROMA_TSAN=ON, see README).

#include <gtest/gtest.h>

#include <array>
#include <atomic>
#include <thread>

#include "engine/timing_stats.hpp"
#include "engine/triple_buffer.hpp"

using namespace stroma;

TEST(TripleBuffer, ConsumerSeesOnlyPublishedValuesNewestFirst) {
  TripleBuffer<int> tb(0);
  EXPECT_FALSE(tb.update());
  tb.write_slot() = 1;
  tb.publish();
  tb.write_slot() = 2;
  tb.publish();
  EXPECT_TRUE(tb.update());
  EXPECT_EQ(tb.read_slot(), 2);  // 1 was overwritten: latest wins
  EXPECT_FALSE(tb.update());
  EXPECT_EQ(tb.read_slot(), 2);
  tb.write_slot() = 3;  // written but not published: invisible
  EXPECT_FALSE(tb.update());
  tb.publish();
  EXPECT_TRUE(tb.update());
  EXPECT_EQ(tb.read_slot(), 3);
}

// A producer publishes frames whose every field equals the frame number; the consumer must
// never see a torn frame and must see frame numbers only increase.
TEST(TripleBuffer, ConcurrentFramesAreNeverTornAndMonotonic) {
  struct Frame {
    std::array<int64_t, 64> v{};
  };
  TripleBuffer<Frame> tb(Frame{});
  constexpr int64_t kFrames = 200000;
  std::atomic<bool> done{false};
  std::thread producer([&] {
    for (int64_t f = 1; f <= kFrames; ++f) {
      Frame& w = tb.write_slot();
      for (auto& x : w.v) x = f;
      tb.publish();
    }
    done = true;
  });
  int64_t last = 0, seen = 0, torn = 0, backwards = 0;
  for (;;) {
    const bool finished = done.load();  // read before update(): no frame can be missed
    if (tb.update()) {
      const Frame& r = tb.read_slot();
      for (auto x : r.v) torn += (x != r.v[0]);
      backwards += (r.v[0] < last);
      last = r.v[0];
      ++seen;
    } else if (finished) {
      break;
    }
  }
  producer.join();
  EXPECT_EQ(torn, 0);
  EXPECT_EQ(backwards, 0);
  EXPECT_GT(seen, 0);
  EXPECT_EQ(tb.read_slot().v[0], kFrames);  // the last frame is never lost
}

