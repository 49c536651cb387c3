// worker/backoff.h: the reconnect wait doubles from 100 ms per failure in a row, never exceeds its
// cap, keeps at least half of it fixed (equal jitter), and starts again after a success.
#include "worker/backoff.h"

#include <gtest/gtest.h>

#include <algorithm>

namespace pf::worker {
namespace {

TEST(BackoffTest, DoublesWithEqualJitterUpToTheCap) {
  Backoff b(5.0, 42);
  for (int n = 0; n < 12; ++n) {
    const double base = std::min(5.0, 0.1 * double(1u << n));
    EXPECT_EQ(b.failures(), n);
    const double s = b.NextSeconds();
    EXPECT_GE(s, 0.5 * base) << "failure " << n;
    EXPECT_LT(s, base) << "failure " << n;
  }
}

TEST(BackoffTest, JitterSpreadsWorkersApart) {
  Backoff a(5.0, 1), b(5.0, 2);
  EXPECT_NE(a.NextSeconds(), b.NextSeconds());
}

TEST(BackoffTest, ResetAtLeastAndSlowest) {
  Backoff b(100.0, 7);
  b.Slowest();
  EXPECT_EQ(b.failures(), 16);
  EXPECT_GE(b.NextSeconds(), 50.0);  // min(100, 0.1 · 2^16) · [0.5, 1)
  b.Reset();
  EXPECT_EQ(b.failures(), 0);
  EXPECT_LT(b.NextSeconds(), 0.1);
  b.AtLeast(3);
  EXPECT_EQ(b.failures(), 3);
  b.AtLeast(1);
  EXPECT_EQ(b.failures(), 3) << "AtLeast never lowers the exponent";
  b.Reset();
  for (int i = 0; i < 40; ++i) EXPECT_LT(b.NextSeconds(), 100.0);  // the shift stops at 2^16
}

}  // namespace
}  // namespace pf::worker
