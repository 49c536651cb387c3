#include "worker/backoff.h"

#include <algorithm>

namespace pf::worker {

double Backoff::NextSeconds() {
  const double base = std::min(cap_, 0.1 * double(1u << std::min(failures_, 16)));
  std::uniform_real_distribution<double> u(0.5, 1.0);
  const double seconds = base * u(rng_);
  ++failures_;
  return seconds;
}

void Backoff::AtLeast(int failures) {
  failures_ = std::max(failures_, failures);
}

}  // namespace pf::worker
