// The progressive plan (Knaus & Zwicker 2011; common/plan/task_plan.h (e)) on a real farm: the
// passes travel as tasks whose estimates read each pass's radius, and the image is bit-identical to
// the single-process render of the same plan and seed (`pf render --local-only`) for 1 and 2
// workers, and it is not the multiple-maps image of the same maps (the radius query is used).
#include "tests/e2e/harness.h"

namespace pf::e2e {
namespace {

// The same job under `plan`, whose number of maps is given by `count_flag` (--passes for the
// progressive plan, --maps for multiple maps).
std::vector<std::string> Flags(const std::string& plan, const std::string& count_flag) {
  return {"--integrator", "photonmap", "--photons", "2000", "--k",   "20",    "--plan", plan, count_flag, "3",
          "--tile",       "16",        "--spp",     "1",    "--res", "33x33", "--seed", "5"};
}

TEST(ProgressiveFarm, BitIdenticalForOneAndTwoWorkersAndLocal) {
  TestDir dir;
  const std::vector<std::string> flags = Flags("progressive", "--passes");
  const Image reference = RenderLocallyToImage(dir, flags);
  ASSERT_GT(PixelSum(reference), 0.0) << "the reference image is black";
  ExpectLocalFarmsBitIdentical(dir, flags, reference, {1, 2}, "farm-");
  EXPECT_FALSE(BitIdentical(RenderLocallyToImage(dir, Flags("multiple-maps", "--maps")), reference))
      << "the progressive passes rendered like multiple maps";
}

}  // namespace
}  // namespace pf::e2e
