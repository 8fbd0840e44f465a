#pragma once
/// \file timing_stats.hpp
/// Allocation-free latency statistics for the real-time loop: a fixed histogram with 1 µs
/// buckets up to 50 ms (plus overflow), min/max/mean, and percentiles read off the histogram.
/// record() is O(1) and lock-free-safe for one writer; readers take copies.

#include <algorithm>
#include <array>
#include <cstdint>
#include <cmath>
#include <string>
#include <vector>

namespace stroma {

/// Histogram of durations in nanoseconds at 1 µs resolution.
class LatencyHistogram {
 public:
  static constexpr int kBuckets = 50000;  // 0 .. 50 ms in 1 µs steps; the last is overflow

  void record(int64_t ns) {
    const int64_t us = ns < 0 ? 0 : ns / 1000;
    ++counts_[static_cast<size_t>(std::min<int64_t>(us, kBuckets - 1))];
    ++n_;
    sum_ns_ += ns;
    max_ns_ = std::max(max_ns_, ns);
  }
  void clear() { *this = LatencyHistogram(); }

  int64_t count() const { return n_; }
  double mean_us() const { return n_ ? static_cast<double>(sum_ns_) / static_cast<double>(n_) * 1e-3 : 0.0; }
  double max_us() const { return static_cast<double>(max_ns_) * 1e-3; }
  /// Upper edge (µs) of the bucket holding the q-quantile (q in [0, 1]); 0 when empty.
  double percentile_us(double q) const {
    if (n_ == 0) return 0.0;
    const int64_t target = static_cast<int64_t>(q * static_cast<double>(n_ - 1)) + 1;
    int64_t acc = 0;
    for (int i = 0; i < kBuckets; ++i) {
      acc += counts_[i];
      if (acc >= target) return std::min(static_cast<double>(i + 1), max_us());
    }
    return max_us();
  }
  /// Compact histogram: "lo_us:count" pairs of the non-empty buckets merged into the given
  /// bucket edges (for JSON output).
  template <class F>
  void for_each_bin(const int* edges_us, int n_edges, F&& f) const {
    int b = 0;
    int64_t acc = 0;
    for (int i = 0; i < kBuckets; ++i) {
      while (b + 1 < n_edges && i >= edges_us[b + 1]) {
        f(edges_us[b], acc);
        acc = 0;
        ++b;
      }
      acc += counts_[i];
    }
    f(edges_us[b], acc);
  }

 private:
  std::array<int64_t, kBuckets> counts_{};
  int64_t n_ = 0;
  int64_t sum_ns_ = 0;
  int64_t max_ns_ = 0;
};

/// Percentiles of a sample (milliseconds).
struct TimingSummary {
  double p50 = 0, p99 = 0, max = 0, mean = 0;
};

/// p50, p99, max and mean of a sample (ms); the sample is taken by value (reordered).
inline TimingSummary summarize(std::vector<double> v) {
  TimingSummary t;
  if (v.empty()) return t;
  double sum = 0;
  for (double x : v) sum += x;
  t.mean = sum / static_cast<double>(v.size());
  auto pct = [&](double q) {
    const size_t k = std::min(v.size() - 1, static_cast<size_t>(std::ceil(q * v.size())) - (q > 0 ? 1 : 0));
    std::nth_element(v.begin(), v.begin() + k, v.end());
    return v[k];
  };
  t.p50 = pct(0.5);
  t.p99 = pct(0.99);
  t.max = *std::max_element(v.begin(), v.end());
  return t;
}

}  // namespace stroma
