#pragma once
// Small helpers the C++ benchmarks share: wall time of a callable and the median of repeats
// (benchmarks quote medians: the machines are shared and noisy).

#include <algorithm>
#include <chrono>
#include <vector>

namespace pf::bench {

// The median (mean of the two middle values for an even count); 0 for no values.
inline double Median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0.0 : (v.size() % 2 ? v[v.size() / 2] : 0.5 * (v[v.size() / 2 - 1] + v[v.size() / 2]));
}

// Seconds `f()` took (steady clock).
template <typename F>
double TimeIt(F&& f) {
  const auto t0 = std::chrono::steady_clock::now();
  f();
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace pf::bench
