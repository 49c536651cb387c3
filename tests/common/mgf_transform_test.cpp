// MGF transforms (common/scene/mgf_transform.h, mgfdoc.tr §2.2.2, §2.2.3): rotations follow the
// right-hand rule and are exact for quarter turns, composition order is "first b, then a",
// powers equal repeated application, mirrors are detected at any scale, and array counters
// enumerate every instance once, in odometer order.

#include "common/scene/mgf_transform.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <numbers>
#include <vector>

namespace pf::mgf {
namespace {

TEST(MgfTransform, QuarterTurnsAreExactAndRightHanded) {
  // Counter-clockwise about each axis: x -> y about z, y -> z about x, z -> x about y.
  EXPECT_EQ(Rotation(2, 90).Point({1, 0, 0}), (Vec3d{0, 1, 0}));
  EXPECT_EQ(Rotation(0, 90).Point({0, 1, 0}), (Vec3d{0, 0, 1}));
  EXPECT_EQ(Rotation(1, 90).Point({0, 0, 1}), (Vec3d{1, 0, 0}));
  // Equivalent angles give bit-identical maps.
  EXPECT_EQ(Rotation(2, -270).Point({1, 2, 3}), Rotation(2, 90).Point({1, 2, 3}));
  EXPECT_EQ(Rotation(2, 450).Point({1, 2, 3}), Rotation(2, 90).Point({1, 2, 3}));
  EXPECT_EQ(Rotation(0, 180).Point({1, 2, 3}), (Vec3d{1, -2, -3}));
  // Other angles: cos/sin, length preserved.
  const Vec3d p = Rotation(2, 30).Point({2, 0, 0});
  EXPECT_NEAR(p.x, 2 * std::cos(std::numbers::pi / 6), 1e-15);
  EXPECT_NEAR(p.y, 1.0, 1e-15);
}

TEST(MgfTransform, ComposeAppliesTheRightOperandFirstAndPowerRepeats) {
  Affine move;
  move.t = {1, 0, 0};
  const Affine turn = Rotation(2, 90);
  // First move, then turn: (1,0,0) -> (2,0,0) -> (0,2,0).
  EXPECT_EQ(Compose(turn, move).Point({1, 0, 0}), (Vec3d{0, 2, 0}));
  // First turn, then move: (1,0,0) -> (0,1,0) -> (1,1,0).
  EXPECT_EQ(Compose(move, turn).Point({1, 0, 0}), (Vec3d{1, 1, 0}));

  const Affine step = Compose(move, Rotation(0, 37));  // a screw motion
  Vec3d q{0.5, -1, 2};
  const Vec3d by_power = Power(step, 7).Point(q);
  for (int i = 0; i < 7; ++i) q = step.Point(q);
  EXPECT_NEAR(Length(by_power - q), 0.0, 1e-12);
  EXPECT_EQ(Power(step, 0).Point({4, 5, 6}), (Vec3d{4, 5, 6}));
}

TEST(MgfTransform, MirrorsAreDetectedAtAnyScale) {
  Affine mx;
  mx.m[0][0] = -1;
  EXPECT_TRUE(mx.Mirrors());
  Affine my;
  my.m[1][1] = -1;
  EXPECT_FALSE(Compose(mx, my).Mirrors());  // two mirrors are a rotation
  // A negative uniform scale mirrors; a huge one must not overflow the determinant.
  Affine huge;
  for (int k = 0; k < 3; ++k) huge.m[k][k] = -1e200;
  EXPECT_TRUE(std::isinf(huge.Det()));
  EXPECT_TRUE(huge.Mirrors());
  EXPECT_DOUBLE_EQ(huge.Scale(), 1e200);
  EXPECT_TRUE(huge.IsFinite());
  huge.t = {std::numeric_limits<double>::infinity(), 0, 0};
  EXPECT_FALSE(huge.IsFinite());
}

TEST(MgfTransform, ArrayCountersEnumerateEveryInstanceOnce) {
  // "xf -t 1 0 0 -a 3 -t 0 1 0 -a 2 -i 2 -t 0 0 5": a 3 × 2 array, then a fixed segment.
  XformSpec spec;
  Affine tx, ty, tz;
  tx.t = {1, 0, 0};
  ty.t = {0, 1, 0};
  tz.t = {0, 0, 5};
  spec.segments = {XformSegment{false, 1, Affine{}}, XformSegment{true, 3, tx}, XformSegment{true, 2, ty},
                   XformSegment{false, 2, tz}};
  ASSERT_EQ(spec.NumArrays(), 2u);
  std::vector<long> counters(spec.NumArrays(), 0);
  std::vector<Vec3d> origins;
  do {
    origins.push_back(spec.Instance(counters).Point({0, 0, 0}));
  } while (AdvanceCounters(spec, counters));
  const std::vector<Vec3d> expected = {{0, 0, 10}, {1, 0, 10}, {2, 0, 10},
                                       {0, 1, 10}, {1, 1, 10}, {2, 1, 10}};
  EXPECT_EQ(origins, expected);
  EXPECT_EQ(counters, (std::vector<long>{0, 0}));  // reset after the last instance
}

}  // namespace
}  // namespace pf::mgf
