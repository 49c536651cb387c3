// The progressive plan (Knaus & Zwicker 2011; common/plan/task_plan.h (e)) on a real farm: the
// passes travel as tasks whose estimates read each pass's radius, and the image is bit-identical to
// the single-process render of the same plan and seed (`pf render --local-only`) for 1 and 2
// workers, and it is not the multiple-maps image of the same maps (the radius query is used).
#include "tests/e2e/harness.h"

namespace pf::e2e {
namespace {

std::vector<std::string> ProgressiveFlags(const std::string& plan) {
  return {"--integrator", "photonmap", "--photons", "2000",   "--k",    "20",     "--plan",
          plan,           "--passes",  "3",         "--maps", "3",      "--tile", "16",
          "--spp",        "1",         "--res",     "33x33",  "--seed", "5"};
}

TEST(ProgressiveFarm, BitIdenticalForOneAndTwoWorkersAndLocal) {
  TestDir dir;
  std::vector<std::string> flags = ProgressiveFlags("progressive");
  // --maps is a multiple-maps flag: the progressive plan reads --passes.
  flags.erase(flags.begin() + 10, flags.begin() + 12);
  const Image reference = RenderLocallyToImage(dir, flags);
  ASSERT_GT(PixelSum(reference), 0.0) << "the reference image is black";
  ExpectLocalFarmsBitIdentical(dir, flags, reference, {1, 2}, "farm-");

  std::vector<std::string> multiple = ProgressiveFlags("multiple-maps");
  multiple.erase(multiple.begin() + 8, multiple.begin() + 10);
  EXPECT_FALSE(BitIdentical(RenderLocallyToImage(dir, multiple), reference))
      << "the progressive passes rendered like multiple maps";
}

}  // namespace
}  // namespace pf::e2e
