// The EXR header of a render (docs/farm.md, "Image headers"): a farm job's image — as the
// coordinator serves it to pf get, and as pf render --workers writes it — and a local pf render
// of the same scene, camera, settings and plan carry the same keys with the same values, so pf
// merge merges them without a warning; images of other settings are still warned about.

#include <gtest/gtest.h>

#include <map>
#include <string>
#include <vector>

#include "common/image/exr_io.h"
#include "common/plan/render_header.h"
#include "tests/e2e/harness.h"

namespace pf::e2e {
namespace {

namespace fs = std::filesystem;

ImageMetadata HeaderOf(const fs::path& exr) {
  ImageMetadata meta;
  ReadExr(exr.string(), &meta);
  return meta;
}

// What the image is of (common/plan/render_header.h): the scene, camera, settings and plan.
std::map<std::string, std::string> WhatItIsOf(const ImageMetadata& meta) {
  std::map<std::string, std::string> out;
  for (const auto& [key, value] : meta)
    if (SameRenderKey(key) || key == "plan") out[key] = value;
  return out;
}

// A photon-map job with every kind of setting value (a real, a choice, a whole number) set.
std::vector<std::string> Flags(uint64_t seed, int photons = 2000) {
  JobArgs job;
  job.seed = seed;
  job.photons = photons;
  return Concat(job.ToFlags(), {"--set", "photon-direct-cache=0.3", "--direct", "photon-direct"});
}

RunResult Merge(const TestDir& dir, const std::vector<fs::path>& inputs, const std::string& out) {
  std::vector<std::string> argv = {Binaries::Pf(), "merge"};
  for (const fs::path& p : inputs) argv.push_back(p.string());
  return RunCommand(Concat(argv, {"-o", (dir / out).string()}), dir.path(), 60);
}

TEST(ImageHeader, FarmAndLocalImagesOfOneRenderCarryTheSameHeader) {
  TestDir dir;
  CoordinatorProcess coordinator(dir / "data", dir.path());
  const auto worker = StartWorker(coordinator.address(), dir.path(), "w1");
  // Two farm jobs of other seeds, fetched with pf get.
  std::vector<fs::path> farm;
  for (uint64_t seed : {7u, 8u}) {
    const std::string id = SubmitJob(dir, coordinator.address(), Flags(seed));
    ASSERT_FALSE(id.empty());
    const fs::path out = dir / ("farm" + std::to_string(seed) + ".exr");
    const RunResult r = RunCommand(
        {Binaries::Pf(), "watch", id, "-q", "-o", out.string(), "--coordinator", coordinator.address()},
        dir.path(), 120);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const RunResult g = RunCommand(
        {Binaries::Pf(), "get", id, "-o", (dir / "got.exr").string(), "--coordinator", coordinator.address()},
        dir.path(), 60);
    ASSERT_EQ(g.exit_code, 0) << g.err;
    EXPECT_EQ(HeaderOf(dir / "got.exr"), HeaderOf(out)) << "pf get and pf watch -o: the coordinator's header";
    farm.push_back(out);
  }
  // The same render in process, and on a local farm (pf render --workers).
  ASSERT_EQ(RenderLocally(dir, Flags(9)).exit_code, 0);
  const RunResult lf = RunCommand(
      Concat(Concat({Binaries::Pf(), "render", Binaries::Scene()}, Flags(10)),
             {"--workers", "2", "--threads", "1", "-o", (dir / "local_farm.exr").string(), "--no-png", "-q"}),
      dir.path(), 180);
  ASSERT_EQ(lf.exit_code, 0) << lf.err;

  const ImageMetadata farm_header = HeaderOf(farm[0]);
  const std::map<std::string, std::string> of = WhatItIsOf(farm_header);
  EXPECT_EQ(WhatItIsOf(HeaderOf(dir / "local.exr")), of);
  EXPECT_EQ(WhatItIsOf(HeaderOf(dir / "local_farm.exr")), of);
  EXPECT_EQ(WhatItIsOf(HeaderOf(farm[1])), of);
  // Readable values: the scene by name and hash, the plan as pf render's flags, every setting.
  EXPECT_EQ(of.at("scene"), "cornell-box.json");
  EXPECT_EQ(of.at("scene.hash").size(), 64u);
  EXPECT_EQ(of.at("plan"), "skipping stride=2 rounds=2 spp=1");
  EXPECT_EQ(of.at("settings.photon-direct-cache"), "0.3");
  EXPECT_EQ(of.at("settings.direct"), "photon-direct");
  EXPECT_EQ(of.at("settings.photons"), "2000");
  EXPECT_EQ(of.count("settings.caustic-split-method"), 1u);  // every row, not only those given
  EXPECT_EQ(farm_header.at("seed"), "7");
  EXPECT_EQ(HeaderOf(dir / "local.exr").at("seed"), "9");
  for (const auto& [key, value] : of)
    EXPECT_EQ(value.find("000000"), std::string::npos) << key << " " << value;

  // pf info shows them.
  const RunResult info = RunCommand({Binaries::Pf(), "info", farm[0].string()}, dir.path(), 30);
  ASSERT_EQ(info.exit_code, 0) << info.err;
  for (const char* line :
       {"plan        skipping stride=2 rounds=2 spp=1", "scene.hash ", "settings.photons 2000"})
    EXPECT_NE(info.out.find(line), std::string::npos) << line << "\n" << info.out;

  // Merged: two farm outputs, a farm output with the local renders — no warning; the merged image
  // keeps what its inputs are of, so it merges again without one.
  RunResult r = Merge(dir, {farm[0], farm[1]}, "ff.exr");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.err.find("warn"), std::string::npos) << r.err;
  r = Merge(dir, {dir / "ff.exr", dir / "local.exr", dir / "local_farm.exr"}, "all.exr");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.err.find("warn"), std::string::npos) << r.err;
  EXPECT_EQ(WhatItIsOf(HeaderOf(dir / "all.exr")), of);
  // A merged image's seeds count: merging farm7 into it again is the same noise twice.
  r = Merge(dir, {dir / "ff.exr", farm[0]}, "again.exr");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.err.find("seed 7: the same noise twice"), std::string::npos) << r.err;

  // Other settings: warned, naming the setting.
  ASSERT_EQ(RunCommand(Concat(Concat({Binaries::Pf(), "render", Binaries::Scene()}, Flags(11, 3000)),
                              {"--local-only", "-o", (dir / "other.exr").string(), "--no-png", "-q"}),
                       dir.path())
                .exit_code,
            0);
  r = Merge(dir, {farm[0], dir / "other.exr"}, "mixed.exr");
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.err.find("settings.photons 3000 differs from the first input's 2000"), std::string::npos)
      << r.err;
  EXPECT_EQ(r.err.find("settings.k "), std::string::npos) << "only what differs\n" << r.err;
  // The mixed image no longer claims a photon count.
  EXPECT_EQ(HeaderOf(dir / "mixed.exr").count("settings.photons"), 0u);
}

// Every `auto` a job resolved, with its reason: pf's integrator choice (made where the scene is
// loaded) and the coordinator's (caustic map, direct light), stored with the job and written as
// auto.* keys, the same for a farm job and a render in this process.
TEST(ImageHeader, AutoChoicesAndTheirReasonsAreRecordedAlikeOnTheFarmAndLocally) {
  TestDir dir;
  CoordinatorProcess coordinator(dir / "data", dir.path());
  const auto worker = StartWorker(coordinator.address(), dir.path(), "w1");
  // No --integrator: auto, which a photon-map setting makes the photon map.
  const std::vector<std::string> flags = {"--res", "16x16",        "--spp", "1",
                                          "--set", "photons=2000", "--set", "k=20"};
  const std::string id = SubmitJob(dir, coordinator.address(), flags);
  ASSERT_FALSE(id.empty());
  const fs::path farm = dir / "farm.exr";
  const RunResult r = RunCommand(
      {Binaries::Pf(), "watch", id, "-q", "-o", farm.string(), "--coordinator", coordinator.address()},
      dir.path(), 120);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  ASSERT_EQ(RenderLocally(dir, flags).exit_code, 0);
  std::map<std::string, std::string> farm_auto, local_auto;
  for (const auto& [key, value] : HeaderOf(farm))
    if (key.starts_with("auto.")) farm_auto[key] = value;
  for (const auto& [key, value] : HeaderOf(dir / "local.exr"))
    if (key.starts_with("auto.")) local_auto[key] = value;
  ASSERT_EQ(farm_auto.count("auto.integrator"), 1u);
  EXPECT_EQ(farm_auto.at("auto.integrator").rfind("photonmap: settings only the photon map reads", 0), 0u);
  EXPECT_EQ(farm_auto.count("auto.caustic-map"), 1u) << "the coordinator's choice";
  EXPECT_EQ(farm_auto.count("auto.direct"), 1u);
  EXPECT_EQ(farm_auto, local_auto);
}

}  // namespace
}  // namespace pf::e2e
