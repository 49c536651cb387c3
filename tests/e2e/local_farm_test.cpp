// `pf render --workers N`: the farm started, used and stopped by pf itself.
//  (a) the final EXR is bit-identical for 1, 2 and 3 workers and equal to the single-process
//      render of the same plan and seed (`pf render --local-only`);
//  and pf leaves no process behind on success, on failure, on Ctrl-C and when SIGKILLed.
#include <signal.h>

#include <regex>

#include "tests/e2e/harness.h"

namespace pf::e2e {
namespace {

class LocalFarmTest : public ::testing::Test {
 protected:
  void SetUp() override { BecomeSubreaper(); }
  void ExpectNoProcessLeft() {
    // Orphans of pf would be re-parented to us (subreaper); give the kernel a moment.
    std::vector<std::string> left;
    WaitUntil([&] { return (left = LiveChildren()).empty(); }, 5);
    EXPECT_TRUE(left.empty()) << "left behind: " << ::testing::PrintToString(left);
  }
};

TEST_F(LocalFarmTest, SkippingIsBitIdenticalForOneTwoThreeWorkersAndLocal) {
  TestDir dir;
  const JobArgs job;  // cornell-box 32x32, photon map, skipping S=2 x 2 rounds
  const std::vector<std::string> base = Concat({Binaries::Pf(), "render", Binaries::Scene()}, job.ToFlags());

  const RunResult local = RunCommand(
      Concat(base, {"--local-only", "-o", (dir / "local.exr").string(), "--no-png", "-q"}), dir.path());
  ASSERT_EQ(local.exit_code, 0) << local.err;
  const Image reference = ReadImage(dir / "local.exr");
  ASSERT_GT(PixelSum(reference), 0.0) << "the reference image is black";

  for (int workers : {1, 2, 3}) {
    const std::string out = (dir / ("farm-" + std::to_string(workers) + ".exr")).string();
    const RunResult r = RunCommand(
        Concat(base, {"--workers", std::to_string(workers), "--threads", "1", "-o", out, "-q"}), dir.path());
    ASSERT_EQ(r.exit_code, 0) << "workers=" << workers << "\n" << r.err;
    EXPECT_TRUE(BitIdentical(ReadImage(out), reference)) << "workers=" << workers;
    EXPECT_TRUE(std::filesystem::exists(dir / ("farm-" + std::to_string(workers) + ".png")));
    ExpectNoProcessLeft();
  }
}

// One render path: a plain `pf render` (no --plan, --local-only or --workers) is the farm's
// multiple-maps plan with its defaults (1 map, 64-pixel tiles) run in this process, so it equals
// that farm job bit for bit — for the photon map (one map, the same map seed) and for the path
// tracer (the same pixel seeds). (The farm's own default is --plan auto, docs/farm.md "Choosing the plan".)
// Before, the plain render had its own loop and map seed and matched neither.
TEST_F(LocalFarmTest, PlainRenderIsTheFarmsDefaultJob) {
  TestDir dir;
  for (const std::string integrator : {"photonmap", "path"}) {
    // Photon-map options only with the photon map: pf refuses them for the path tracer.
    const std::vector<std::string> photon_map = {"--photons", "3000", "--k", "20"};
    const std::vector<std::string> base =
        Concat({Binaries::Pf(), "render", Binaries::Scene(), "--integrator", integrator, "--res", "80x48",
                "--spp", "2", "--seed", "11", "--no-png", "-q"},  // 80x48: partial tiles
               integrator == "photonmap" ? photon_map : std::vector<std::string>{});
    const std::string plain = (dir / (integrator + "-plain.exr")).string();
    const RunResult r = RunCommand(Concat(base, {"-o", plain}), dir.path());
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const std::string farm = (dir / (integrator + "-farm.exr")).string();
    const RunResult f =
        RunCommand(Concat(base, {"--workers", "2", "--threads", "1", "--plan", "multiple-maps", "-o", farm}),
                   dir.path());
    ASSERT_EQ(f.exit_code, 0) << f.err;
    EXPECT_TRUE(BitIdentical(ReadImage(plain), ReadImage(farm))) << integrator;
    ExpectNoProcessLeft();
  }
}

// A shipped scene (scenes/<folder>/<folder>.json) rendered on two workers is bit-identical to the
// single-process render, with both integrators; `what` lit the image.
void ExpectShippedSceneRendersOnTheFarmAsLocally(const std::string& folder, const std::string& what) {
  TestDir dir;
  const std::string scene =
      (std::filesystem::path(Binaries::Scene()).parent_path().parent_path() / folder / (folder + ".json"))
          .string();
  for (const std::string integrator : {"photonmap", "path"}) {
    const std::vector<std::string> photon_map = {"--photons", "4000", "--k", "20"};
    const std::vector<std::string> base =
        Concat({Binaries::Pf(), "render", scene, "--integrator", integrator, "--res", "40x30", "--spp", "2",
                "--seed", "5", "--plan", "multiple-maps", "--no-png", "-q"},
               integrator == "photonmap" ? photon_map : std::vector<std::string>{});
    const std::string local = (dir / (integrator + "-local.exr")).string();
    const RunResult l = RunCommand(Concat(base, {"--local-only", "-o", local}), dir.path());
    ASSERT_EQ(l.exit_code, 0) << l.err;
    const Image reference = ReadImage(local);
    EXPECT_GT(PixelSum(reference), 0.0) << integrator << ": the " << what << " lit nothing";
    const std::string farm = (dir / (integrator + "-farm.exr")).string();
    const RunResult f =
        RunCommand(Concat(base, {"--workers", "2", "--threads", "1", "-o", farm}), dir.path());
    ASSERT_EQ(f.exit_code, 0) << f.err;
    EXPECT_TRUE(BitIdentical(ReadImage(farm), reference)) << integrator;
  }
}

// Point, spot and directional lights on the farm: a scene lit by them alone (scenes/lamp-stage: no
// emitting material, so the coordinator's result bound from the brightest Le does not apply) renders
// on two workers bit-identically to the single-process render, with both integrators.
TEST_F(LocalFarmTest, PunctualLightsRenderOnTheFarmAsLocally) {
  ExpectShippedSceneRendersOnTheFarmAsLocally("lamp-stage", "lamps");
  ExpectNoProcessLeft();
}

// The environment on the farm: scenes/sky-courtyard, lit by its sky image alone (shipped in the
// bundle: an input, scene_bundle.h), the same bits on two workers as locally, both integrators.
TEST_F(LocalFarmTest, EnvironmentLightRendersOnTheFarmAsLocally) {
  ExpectShippedSceneRendersOnTheFarmAsLocally("sky-courtyard", "sky");
  ExpectNoProcessLeft();
}

// Image textures on the farm: scenes/textured-room (a .glb with an embedded PNG and an external
// one the bundle ships), the same bits on two workers as locally, both integrators.
TEST_F(LocalFarmTest, TexturedGlbRendersOnTheFarmAsLocally) {
  ExpectShippedSceneRendersOnTheFarmAsLocally("textured-room", "spot and panel");
  ExpectNoProcessLeft();
}

// A Blender export on the farm: scenes/blender-studio (glTF from Blender's exporter with a PNG
// texture, a spot lamp whose cone Blender writes hard-edged, glass, and the manifest's HDR sky):
// the same bits on two workers as locally, both integrators.
TEST_F(LocalFarmTest, BlenderExportRendersOnTheFarmAsLocally) {
  ExpectShippedSceneRendersOnTheFarmAsLocally("blender-studio", "sky, spot and panel");
  ExpectNoProcessLeft();
}

// `pf render` of the shipped scene with the photon map (`photons`, k = 20) at 24x16, no PNG, quiet.
std::vector<std::string> PhotonMapRender24x16(const std::string& photons,
                                              const std::vector<std::string>& more) {
  return Concat({Binaries::Pf(), "render", Binaries::Scene(), "--integrator", "photonmap", "--photons",
                 photons, "--k", "20", "--res", "24x16", "--no-png", "-q"},
                more);
}

// `args` rendered with --local-only and on a farm of two one-thread workers: the same bits.
void ExpectFarmMatchesLocal(const std::vector<std::string>& args, const TestDir& dir) {
  const RunResult local =
      RunCommand(Concat(args, {"--local-only", "-o", (dir / "local.exr").string()}), dir.path());
  ASSERT_EQ(local.exit_code, 0) << local.err;
  const RunResult farm = RunCommand(
      Concat(args, {"--workers", "2", "--threads", "1", "-o", (dir / "farm.exr").string()}), dir.path());
  ASSERT_EQ(farm.exit_code, 0) << farm.err;
  EXPECT_TRUE(BitIdentical(ReadImage(dir / "farm.exr"), ReadImage(dir / "local.exr")));
}

// The local render of `args` (to dir/`name`) differs from the last ExpectFarmMatchesLocal's image:
// the setting that `args` leaves out really changes the image, so the farm's match shows that it
// reached the workers.
void ExpectLocalDiffers(const std::vector<std::string>& args, const TestDir& dir, const std::string& name) {
  const RunResult r = RunCommand(Concat(args, {"--local-only", "-o", (dir / name).string()}), dir.path());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_FALSE(BitIdentical(ReadImage(dir / name), ReadImage(dir / "local.exr")));
}

TEST_F(LocalFarmTest, MultipleMapsTilesMatchLocal) {
  TestDir dir;
  const std::vector<std::string> base = PhotonMapRender24x16(
      "2000", {"--plan", "multiple-maps", "--maps", "2", "--tile", "8", "--spp", "1", "--seed", "3"});
  ExpectFarmMatchesLocal(base, dir);
  ExpectNoProcessLeft();
}

// The chapter-4 estimators through the farm (job settings → proto → workers): PhotonDirect with
// the neighbour-set cache, local pass, occlusion test and adaptive k give the local image.
TEST_F(LocalFarmTest, ChapterFourEstimatorsMatchLocal) {
  TestDir dir;
  const std::vector<std::string> base =
      PhotonMapRender24x16("3000", {"--plan", "skipping", "--stride", "2", "--rounds", "1", "--spp", "1",
                                    "--seed", "5", "--occlusion-test", "--adaptive-k-min", "6"});
  const std::vector<std::string> chapter4 =
      Concat(base, {"--direct", "photon-direct", "--non-contributing", "each", "--photon-direct-k", "10",
                    "--local-pass", "3"});
  ExpectFarmMatchesLocal(chapter4, dir);
  // A different estimator is a different image (the options really reached the workers).
  ExpectLocalDiffers(Concat(base, {"--direct", "photon-map"}), dir, "pm.exr");
  ExpectNoProcessLeft();
}

// Importance-driven maps (§4.7; the importons come from the camera, per map seed): the farm of
// two one-thread workers gives the local render's bits; the setting reached the workers (the
// image differs from the map without importance).
TEST_F(LocalFarmTest, ImportanceMatchesLocal) {
  TestDir dir;
  const std::vector<std::string> base =
      PhotonMapRender24x16("3000", {"--plan", "multiple-maps", "--maps", "2", "--tile", "12", "--spp", "1",
                                    "--seed", "3", "--direct", "mc"});
  const std::vector<std::string> on =
      Concat(base, {"--importance", "on", "--importance-strength", "0.5", "--importons", "300"});
  ExpectFarmMatchesLocal(on, dir);
  ExpectLocalDiffers(base, dir, "off.exr");
  ExpectNoProcessLeft();
}

// Irradiance caching (one cache per 16x16-pixel block of a task, filled in pixel order): the
// farm of two one-thread workers gives the local render's bits; the cache really reached the
// workers (the image differs from the uncached local pass).
TEST_F(LocalFarmTest, IrradianceCacheMatchesLocal) {
  TestDir dir;
  const std::vector<std::string> base =
      PhotonMapRender24x16("3000", {"--plan", "multiple-maps", "--maps", "2", "--tile", "12", "--spp", "2",
                                    "--seed", "7", "--direct", "mc", "--local-pass", "4"});
  ExpectFarmMatchesLocal(Concat(base, {"--irradiance-cache", "--irradiance-cache-error", "0.3"}), dir);
  ExpectLocalDiffers(base, dir, "uncached.exr");
  ExpectNoProcessLeft();
}

TEST_F(LocalFarmTest, CtrlCStopsEverything) {
  TestDir dir;
  JobArgs job;
  job.photons = 200000;  // long enough to interrupt: many rounds of slow tasks
  job.rounds = 50;
  const std::string out = (dir / "out.exr").string();
  Process pf("pf",
             Concat(Concat({Binaries::Pf(), "render", Binaries::Scene()}, job.ToFlags()),
                    {"--workers", "2", "--threads", "1", "-o", out, "-q", "--keep-farm-dir"}),
             dir / "pf.log");
  // Wait until a worker has finished a task (the farm is really running).
  std::string farm_dir;
  ASSERT_TRUE(WaitUntil(
      [&] {
        std::smatch m;
        const std::string log = ReadFile(dir / "pf.log");
        static const std::regex re(R"(logs in ([^)]+)\))");
        if (farm_dir.empty() && std::regex_search(log, m, re)) farm_dir = m[1];
        return !farm_dir.empty() &&
               !Grep(std::filesystem::path(farm_dir) / "worker-1.log", "completed").empty();
      },
      60))
      << ReadFile(dir / "pf.log");
  pf.Signal(SIGINT);
  const std::optional<int> code = pf.Wait(30);
  ASSERT_TRUE(code.has_value()) << "pf did not exit after SIGINT";
  EXPECT_EQ(*code, 130) << ReadFile(dir / "pf.log");
  ExpectNoProcessLeft();
  // The workers were stopped by SIGTERM (handed back or finished), not killed.
  EXPECT_FALSE(Grep(std::filesystem::path(farm_dir) / "worker-1.log", "received SIGTERM").empty());
  std::filesystem::remove_all(farm_dir);
}

TEST_F(LocalFarmTest, KilledPfLeavesNothingBehind) {
  TestDir dir;
  JobArgs job;
  job.photons = 200000;
  job.rounds = 50;
  Process pf("pf",
             Concat(Concat({Binaries::Pf(), "render", Binaries::Scene()}, job.ToFlags()),
                    {"--workers", "2", "--threads", "1", "-o", (dir / "out.exr").string(), "-q"}),
             dir / "pf.log");
  ASSERT_TRUE(WaitUntil([&] { return ReadFile(dir / "pf.log").find("submitted") != std::string::npos; }, 60))
      << ReadFile(dir / "pf.log");
  pf.Signal(SIGKILL);
  ASSERT_TRUE(pf.Wait(10).has_value());
  ExpectNoProcessLeft();  // PR_SET_PDEATHSIG took the coordinator and the workers with it
}

TEST_F(LocalFarmTest, BrokenWorkersFailCleanly) {
  TestDir dir;
  const RunResult r = RunCommand(
      Concat(Concat({Binaries::Pf(), "render", Binaries::Scene()}, JobArgs().ToFlags()),
             {"--workers", "2", "--worker-bin", "/bin/false", "-o", (dir / "out.exr").string(), "-q"}),
      dir.path(), 60);
  EXPECT_EQ(r.exit_code, 1) << r.err;
  EXPECT_NE(r.err.find("pf-worker #1 exited with status 1"), std::string::npos) << r.err;
  ExpectNoProcessLeft();
  // On failure the farm's folder is kept for its logs, and pf says where.
  std::smatch m;
  ASSERT_TRUE(std::regex_search(r.err, m, std::regex(R"(farm folder kept: (\S+))"))) << r.err;
  EXPECT_TRUE(std::filesystem::exists(std::filesystem::path(m[1].str()) / "coordinator.log"));
  std::filesystem::remove_all(m[1].str());
}

}  // namespace
}  // namespace pf::e2e
