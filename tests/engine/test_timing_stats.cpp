// engine/timing_stats: the latency histogram behind the server's percentiles; and
// engine/log_histogram, the renderer's fixed-size render and publish-to-disk statistics.

#include <gtest/gtest.h>
#include <array>
#include <atomic>
#include <thread>
#include <algorithm>
#include <random>
#include <vector>
#include "engine/timing_stats.hpp"
#include "engine/triple_buffer.hpp"
#include "runtime/log_histogram.hpp"

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

// Against exact order statistics of samples over six decades: each percentile within the
// bucket's 0.5 % of the exact sample of the same rank, never below it, never above the max.
TEST(LogHistogram, PercentilesWithinHalfAPercentOfTheExactOnes) {
  std::mt19937 rng(7);
  std::lognormal_distribution<double> dist(std::log(20.0), 2.0);  // ms: ~0.01 .. 10,000
  LogHistogram h;
  std::vector<double> v;
  for (int i = 0; i < 20000; ++i) {
    const double x = dist(rng);
    v.push_back(x);
    h.record(x);
  }
  std::sort(v.begin(), v.end());
  ASSERT_EQ(h.count(), 20000);
  for (double q : {0.0, 0.01, 0.25, 0.5, 0.9, 0.99, 0.999, 1.0}) {
    const double exact = v[static_cast<size_t>(q * static_cast<double>(v.size() - 1))];
    const double got = h.percentile_ms(q);
    EXPECT_GE(got, exact * (1 - 1e-12)) << "q " << q;
    EXPECT_LE(got, exact * LogHistogram::kRatio * (1 + 1e-12)) << "q " << q;
  }
  EXPECT_DOUBLE_EQ(h.max_ms(), v.back());
  EXPECT_DOUBLE_EQ(h.percentile_ms(1.0), v.back());
  double sum = 0;
  for (double x : v) sum += x;
  EXPECT_NEAR(h.mean_ms(), sum / 20000, 1e-9 * sum / 20000);
}

TEST(LogHistogram, EdgesEmptyAndOutOfRange) {
  LogHistogram h;
  EXPECT_EQ(h.percentile_ms(0.5), 0.0);
  h.record(-1.0);                 // a clock step backwards counts as zero
  h.record(std::nan(""));         // and so does a NaN
  EXPECT_EQ(h.count(), 2);
  EXPECT_EQ(h.percentile_ms(1.0), 0.0);
  h.record(1e9);                  // 11.6 days: the last bucket, exact max
  EXPECT_DOUBLE_EQ(h.max_ms(), 1e9);
  EXPECT_DOUBLE_EQ(h.percentile_ms(1.0), 1e9);
  EXPECT_LT(sizeof(LogHistogram), 40000u);  // constant memory, the point of it
}
