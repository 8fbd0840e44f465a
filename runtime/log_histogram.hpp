#pragma once
/// \file log_histogram.hpp
/// Fixed-size statistics of durations that may span many decades (a frame's render time, a
/// frame's publish-to-disk latency): log-spaced buckets of 0.5 % relative width from 1 µs to
/// about 1,000 s, plus exact count, mean and max. Memory is constant (~33 KB) however long a
/// recording runs — the reason it exists: keeping every sample grew a one-hour renderer by 6 %.
/// Percentiles are the upper edge of the bucket holding them, so they read at most 0.5 % high
/// (and never above the exact max). record() is O(1) with no allocation; one writer at a time.

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>

namespace stroma {

/// Histogram of non-negative durations in milliseconds with 0.5 % relative resolution.
/// Invariants: count() == sum of the buckets; percentile_ms(q) <= max_ms(); values below 1 µs
/// share the first bucket, values above ~1,000 s the last (max_ms() stays exact for them).
class LogHistogram {
 public:
  static constexpr double kMinMs = 1e-3;     ///< lower edge of bucket 1 (bucket 0: below it)
  static constexpr double kRatio = 1.005;    ///< upper / lower edge of a bucket
  static constexpr int kBuckets = 4200;      ///< 1 µs · 1.005^4199 ≈ 1.2e6 ms

  void record(double ms) {
    if (!(ms >= 0)) ms = 0;  // NaN and negatives count as zero
    ++counts_[static_cast<size_t>(bucket(ms))];
    ++n_;
    sum_ms_ += ms;
    max_ms_ = std::max(max_ms_, ms);
  }

  int64_t count() const { return n_; }
  double mean_ms() const { return n_ ? sum_ms_ / static_cast<double>(n_) : 0.0; }
  double max_ms() const { return max_ms_; }
  /// The q-quantile (q in [0, 1]) as the upper edge of its bucket, capped at max_ms(); 0 when
  /// empty. Same rank convention as LatencyHistogram: the (floor(q·(n−1))+1)-th smallest sample.
  double percentile_ms(double q) const {
    if (n_ == 0) return 0.0;
    const int64_t target = static_cast<int64_t>(q * static_cast<double>(n_ - 1)) + 1;
    int64_t acc = 0;
    for (int i = 0; i < kBuckets; ++i) {
      acc += counts_[static_cast<size_t>(i)];
      // The last bucket is open-ended: its only known bound is the max.
      if (acc >= target) return i == kBuckets - 1 ? max_ms_ : std::min(upper_edge(i), max_ms_);
    }
    return max_ms_;
  }

 private:
  static int bucket(double ms) {
    if (ms < kMinMs) return 0;
    const int b = 1 + static_cast<int>(std::log(ms / kMinMs) / std::log(kRatio));
    return std::min(b, kBuckets - 1);
  }
  static double upper_edge(int i) { return kMinMs * std::pow(kRatio, i); }

  std::array<int64_t, kBuckets> counts_{};
  int64_t n_ = 0;
  double sum_ms_ = 0;
  double max_ms_ = 0;
};

}  // namespace stroma
