#pragma once
/// \file bench_stats.hpp
/// Order statistics for the benchmark programs (offline: they copy and partially sort).

#include <algorithm>
#include <cstddef>
#include <vector>

namespace stroma::bench {

/// The q-quantile (q in [0, 1]) of v: the element of rank floor(q·n), capped at the last; 0 for
/// an empty v.
inline double percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0;
  const size_t k = std::min(v.size() - 1, static_cast<size_t>(q * static_cast<double>(v.size())));
  std::nth_element(v.begin(), v.begin() + static_cast<long>(k), v.end());
  return v[k];
}

inline double median(std::vector<double> v) { return percentile(std::move(v), 0.5); }

}  // namespace stroma::bench
