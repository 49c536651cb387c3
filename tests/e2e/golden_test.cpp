// Golden images: ten representative jobs — both integrators, every plan, the single-process
// render, the in-process plan render (--local-only) and a farm of real processes — rendered
// bit-for-bit as the committed EXRs under tests/data/golden/ (recorded at ed93769, before the
// settings table, the scheduler's layering and the one task queue; pixels only, the header may
// gain fields; the four photon-map jobs of the Cornell box re-recorded when the emission seen
// directly became a split estimate, docs/renderer.md "Emitters seen directly"). A refactor that
// changes one bit of one pixel fails here.
//
// Recording is deliberate: PF_GOLDEN_RECORD=1 rewrites the files from this build (and fails the
// test, so that such a run is never mistaken for a check), for a change that is meant to change
// images (say why in its commit).

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <ostream>
#include <string>
#include <vector>

#include "tests/e2e/harness.h"

namespace pf::e2e {
namespace {

namespace fs = std::filesystem;

struct GoldenJob {
  std::string name;
  std::string scene;  // below scenes/
  std::vector<std::string> flags;
};

// Photon-map settings every photon-map job shares: few photons, small images, so the ten jobs
// take seconds.
std::vector<std::string> PhotonMapFlags(const std::string& photons) {
  return {"--integrator", "photonmap", "--photons", photons, "--k", "20"};
}

std::vector<GoldenJob> Jobs() {
  const std::string box = "cornell-box/cornell-box.json";
  const std::string sphere = "cornell-sphere/cornell-sphere.json";
  auto with = [](std::vector<std::string> a, const std::vector<std::string>& b) { return Concat(a, b); };
  const std::vector<std::string> farm = {"--workers", "2", "--threads", "1"};
  return {
      // The single-process render (no plan), both integrators.
      {"path_single", box, {"--integrator", "path", "--spp", "4", "--seed", "11"}},
      {"photonmap_single", sphere, with(PhotonMapFlags("4000"), {"--spp", "2", "--seed", "12"})},
      // Every plan in process (--local-only), through the same JobSpec as the farm.
      {"multiple_maps_local", box,
       with(PhotonMapFlags("3000"), {"--plan", "multiple-maps", "--maps", "2", "--tile", "16", "--spp", "1",
                                     "--seed", "13", "--local-only"})},
      {"maps_in_turn_local", sphere,
       with(PhotonMapFlags("2000"), {"--plan", "maps-in-turn", "--spp", "2", "--tile", "16", "--seed", "14",
                                     "--direct", "photon-direct", "--local-only"})},
      {"skipping_local", box,
       with(PhotonMapFlags("2000"), {"--plan", "skipping", "--stride", "2", "--rounds", "2", "--spp", "1",
                                     "--seed", "15", "--local-only"})},
      {"hierarchical_local", box,
       with(PhotonMapFlags("1500"), {"--plan", "hierarchical", "--levels", "2", "--base-samples", "4",
                                     "--seed", "16", "--local-only"})},
      // A farm: coordinator + two pf-worker processes.
      {"path_multiple_maps_farm", box,
       with(farm, {"--integrator", "path", "--plan", "multiple-maps", "--spp", "2", "--tile", "16", "--seed",
                   "17"})},
      {"skipping_distributed_maps_farm", sphere,
       with(with(PhotonMapFlags("3000"), farm),
            {"--plan", "skipping", "--stride", "2", "--rounds", "1", "--spp", "1", "--seed", "18",
             "--map-tracing", "distributed"})},
      {"hierarchical_farm", sphere,
       with(with(PhotonMapFlags("1500"), farm),
            {"--plan", "hierarchical", "--levels", "2", "--base-samples", "4", "--seed", "19"})},
      {"auto_plan_farm", box,
       with(with(PhotonMapFlags("6000"), farm),
            {"--plan", "auto", "--spp", "2", "--seed", "20", "--direct", "mc", "--local-pass", "2"})},
  };
}

// gtest prints a parameter by its name, not its bytes.
void PrintTo(const GoldenJob& job, std::ostream* os) {
  *os << job.name;
}

fs::path GoldenDir() {
  return fs::path(PF_SOURCE_DIR) / "tests" / "data" / "golden";
}

class GoldenImage : public ::testing::TestWithParam<GoldenJob> {};

TEST_P(GoldenImage, IsBitIdenticalToTheRecordedImage) {
  const GoldenJob& job = GetParam();
  TestDir dir;
  const fs::path out = dir / (job.name + ".exr");
  const std::vector<std::string> argv =
      Concat({Binaries::Pf(), "render", (fs::path(PF_SOURCE_DIR) / "scenes" / job.scene).string(), "--res",
              "24x16", "--no-png", "-q", "-o", out.string()},
             job.flags);
  const RunResult r = RunCommand(argv, dir.path(), 240);
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  const fs::path golden = GoldenDir() / (job.name + ".exr");
  if (const char* record = std::getenv("PF_GOLDEN_RECORD"); record && std::strcmp(record, "1") == 0) {
    fs::create_directories(GoldenDir());
    fs::copy_file(out, golden, fs::copy_options::overwrite_existing);
    // Recording never passes: a run with PF_GOLDEN_RECORD set checks nothing, so it must not
    // look like a check (CI never sets it).
    FAIL() << "recorded " << golden << "; run again without PF_GOLDEN_RECORD to compare";
  }
  ASSERT_TRUE(fs::exists(golden)) << golden << " missing: record it with PF_GOLDEN_RECORD=1";
  const Image want = ReadImage(golden);
  const Image got = ReadImage(out);
  ASSERT_EQ(got.width(), want.width());
  ASSERT_EQ(got.height(), want.height());
  ASSERT_GT(PixelSum(want), 0.0) << "a black golden image proves nothing";
  size_t differing = 0;
  std::string first;
  for (int y = 0; y < want.height(); ++y)
    for (int x = 0; x < want.width(); ++x) {
      const Rgb a = got.at(x, y), b = want.at(x, y);
      if (std::memcmp(&a, &b, sizeof(Rgb)) != 0) {
        if (differing++ == 0)
          first = fmt::format("({}, {}): got {} {} {}, golden {} {} {}", x, y, a.r, a.g, a.b, b.r, b.g, b.b);
      }
    }
  EXPECT_EQ(differing, 0u) << differing << " pixels differ; first at " << first << "\n" << r.err;
}

INSTANTIATE_TEST_SUITE_P(TenJobs, GoldenImage, ::testing::ValuesIn(Jobs()),
                         [](const ::testing::TestParamInfo<GoldenJob>& info) { return info.param.name; });

}  // namespace
}  // namespace pf::e2e
