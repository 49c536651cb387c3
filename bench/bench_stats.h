#pragma once
// Small helpers the C++ benchmarks share: wall time of a callable and the median of repeats
// (benchmarks quote medians: the machines are shared and noisy).

#include <time.h>

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

// CPU seconds the whole process spent while `f()` ran (all threads). On a shared, oversubscribed
// machine this leaves out the time the process waited for a core, which wall time counts; for
// single-threaded work it is the better clock to compare variants by.
template <typename F>
double CpuTimeIt(F&& f) {
  auto now = [] {
    timespec t{};
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
    return double(t.tv_sec) + 1e-9 * double(t.tv_nsec);
  };
  const double t0 = now();
  f();
  return now() - t0;
}

}  // namespace pf::bench
