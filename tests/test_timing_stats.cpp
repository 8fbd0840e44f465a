// engine/timing_stats: the latency histogram behind the server's percentiles.

#include <gtest/gtest.h>
#include <array>
#include <atomic>
#include <thread>
#include "engine/timing_stats.hpp"
#include "engine/triple_buffer.hpp"

using namespace stroma;

TEST(LatencyHistogram, PercentilesFromKnownSamples) {
  LatencyHistogram h;
  for (int i = 1; i <= 1000; ++i) h.record(static_cast<int64_t>(i) * 1000);  // 1..1000 µs
  EXPECT_EQ(h.count(), 1000);
  EXPECT_NEAR(h.percentile_us(0.5), 500, 1.0);
  EXPECT_NEAR(h.percentile_us(0.99), 990, 1.0);
  EXPECT_NEAR(h.percentile_us(0.999), 999, 1.0);
  EXPECT_DOUBLE_EQ(h.max_us(), 1000);
  EXPECT_NEAR(h.mean_us(), 500.5, 1e-9);
  h.record(int64_t{1} << 40);  // beyond the range: overflow bucket, exact max
  EXPECT_DOUBLE_EQ(h.max_us(), static_cast<double>(int64_t{1} << 40) * 1e-3);
}
