// An animation (docs/farm.md "Animation"), real processes: frames 20-23 of the shipped cornell-box's
// camera path as one job on two workers. Checked: every frame complete in the job's status; `pf get
// -o frame.%04d.exr` writes one EXR per frame with its camera and number; the job's two maps traced
// once, in pieces (counted: every piece uploaded once, every map built once); each frame bit-identical
// to a single-frame job of that frame's camera with the same seed — and those four jobs trace nothing,
// because their maps have the same keys (the key holds no camera).
#include <gtest/gtest.h>
#include <httplib.h>

#include <filesystem>
#include <string>
#include <vector>

#include "client/farm_client.h"
#include "common/image/exr_io.h"
#include "tests/e2e/harness.h"

namespace pf::e2e {
namespace {
namespace fs = std::filesystem;
namespace v1 = photonfarm::v1;

// Two maps of 40000 photons, each in three pieces of 16384 (--map-chunk-photons), over tiles.
std::vector<std::string> AnimationFlags() {
  return {"--integrator", "photonmap",     "--photons", "40000", "--k",    "20",
          "--plan",       "multiple-maps", "--maps",    "2",     "--tile", "32",
          "--res",        "48x32",         "--spp",     "1",     "--seed", "5"};
}

size_t CountInLogs(const std::vector<fs::path>& logs, const std::string& re) {
  size_t n = 0;
  for (const fs::path& log : logs) n += Grep(log, re).size();
  return n;
}

TEST(Animation, FramesShareOneSetOfMapsAndAreBitIdenticalToSingleFrameJobs) {
  TestDir dir;
  CoordinatorProcess coordinator(dir / "data", dir.path(),
                                 {"--map-chunk-photons", "16384", "--http", "127.0.0.1:0"});
  const std::string address = coordinator.address();
  const std::string animation = SubmitJob(dir, address, Concat(AnimationFlags(), {"--frames", "20-23"}));
  ASSERT_FALSE(animation.empty());
  std::vector<std::unique_ptr<Process>> workers;
  std::vector<fs::path> logs;
  for (const char* id : {"w1", "w2"}) {
    workers.push_back(StartWorker(address, dir.path(), id));
    logs.push_back(dir / (std::string(id) + ".log"));
  }
  FarmClient client(address, "");
  const v1::JobStatus st = WaitForJob(client, animation, 120);
  ASSERT_EQ(st.state(), v1::JOB_STATE_SUCCEEDED) << st.failure_reason();
  ASSERT_EQ(st.frames_size(), 4);
  for (int f = 0; f < 4; ++f) {
    EXPECT_EQ(st.frames(f).frame(), uint32_t(20 + f));
    EXPECT_GT(st.frames(f).tasks_total(), 0u);
    EXPECT_EQ(st.frames(f).tasks_done(), st.frames(f).tasks_total());
  }
  // pf watch counts the complete frames.
  const RunResult watch =
      RunCommand({Binaries::Pf(), "watch", animation, "--coordinator", address}, dir.path());
  EXPECT_EQ(watch.exit_code, 0) << watch.err;
  EXPECT_NE(watch.err.find("tasks  frames 4/4"), std::string::npos) << watch.err;
  // The web page's job page lists the frames, its JSON too.
  httplib::Client http("127.0.0.1", coordinator.http_port());
  const auto page = http.Get("/jobs/" + animation);
  ASSERT_TRUE(page);
  EXPECT_NE(page->body.find("<table id=\"frames\">"), std::string::npos) << page->body;
  EXPECT_NE(page->body.find("<tr><td>23</td><td>"), std::string::npos) << page->body;
  const auto api = http.Get("/api/status");
  ASSERT_TRUE(api);
  EXPECT_NE(api->body.find("\"frames\":[{\"done\""), std::string::npos) << api->body;
  const fs::path clog = coordinator.process().log();
  EXPECT_EQ(Grep(clog, "built once from 3 pieces").size(), 2u) << "two maps, each built once";
  EXPECT_EQ(CountInLogs(logs, "uploaded-piece .* accepted=true"), 6u) << "each piece traced once";

  const RunResult get = RunCommand(
      {Binaries::Pf(), "get", animation, "--coordinator", address, "-o", (dir / "frame.%04d.exr").string()},
      dir.path());
  ASSERT_EQ(get.exit_code, 0) << get.err;
  EXPECT_NE(get.out.find("frame.0020.exr .. "), std::string::npos) << get.out;
  std::vector<Image> frames;
  for (int f = 20; f <= 23; ++f) {
    ImageMetadata meta;
    const fs::path file = dir / ("frame.00" + std::to_string(f) + ".exr");
    frames.push_back(ReadExr(file, &meta));
    ASSERT_EQ(frames.back().width(), 48);
    ASSERT_EQ(frames.back().height(), 32);
    EXPECT_GT(PixelSum(frames.back()), 0.0);
    EXPECT_EQ(meta["frame"], std::to_string(f));
    EXPECT_EQ(meta["animation.frames"], "20-23");
    // The frame's own camera, as a single-frame job of it is asked for.
    const std::string single = SubmitJob(
        dir, address,
        Concat(AnimationFlags(), {"--eye=" + meta["camera.eye"], "--look-at=" + meta["camera.look_at"]}));
    ASSERT_FALSE(single.empty());
    const v1::JobStatus sst = WaitForJob(client, single, 120);
    ASSERT_EQ(sst.state(), v1::JOB_STATE_SUCCEEDED) << sst.failure_reason();
    EXPECT_EQ(sst.frames_size(), 0);
    EXPECT_TRUE(BitIdentical(DecodeImage(client.GetImage(single)), frames.back())) << "frame " << f;
  }
  EXPECT_FALSE(BitIdentical(frames.front(), frames.back())) << "the camera moves";
  // The single-frame jobs fetched the animation's maps: nothing more was traced or built.
  EXPECT_EQ(Grep(clog, "built once from").size(), 2u) << ReadFile(clog);
  EXPECT_EQ(CountInLogs(logs, "uploaded-piece .* accepted=true"), 6u);
  for (auto& w : workers) w->Signal(SIGTERM);
  for (auto& w : workers) EXPECT_TRUE(w->Wait(20).has_value());
}

// An animation is refused, before anything is uploaded, where it cannot be one.
TEST(Animation, FramesThatCannotBeRenderedAreRefusedWithTheReason) {
  TestDir dir;
  struct Case {
    std::vector<std::string> flags;
    std::string message;
  };
  for (const Case& c : std::vector<Case>{
           {{"--frames", "1-60", "--workers", "1"},
            "--frames: 1-60 is not within the camera path's frames 1-48"},
           {{"--frames", "1-4", "--local-only", "--plan", "multiple-maps"},
            "--frames: an animation renders on a farm"},
           {{"--frames", "1-4", "--workers", "1", "--plan", "skipping"}, "not with --frames"},
           {{"--frames", "x", "--workers", "1"}, "expected FIRST-LAST"},
           {{"--frames", "+3", "--workers", "1"}, "expected FIRST-LAST"},
           {{"--frames", "1-4", "--workers", "1", "--eye", "0,1,3"}, "--eye: not with --frames"},
       }) {
    const RunResult r = RunCommand(
        Concat({Binaries::Pf(), "render", Binaries::Scene(), "-o", (dir / "x.exr").string(), "-q"}, c.flags),
        dir.path());
    EXPECT_EQ(r.exit_code, 3) << r.err;
    EXPECT_NE(r.err.find(c.message), std::string::npos) << r.err;
  }
  // An empty range is a usage error (exit 2), not a still image.
  const RunResult empty = RunCommand({Binaries::Pf(), "render", Binaries::Scene(), "--frames", "",
                                      "--workers", "1", "-o", (dir / "x.exr").string()},
                                     dir.path());
  EXPECT_EQ(empty.exit_code, 2) << empty.err;
  EXPECT_NE(empty.err.find("expected FIRST-LAST"), std::string::npos) << empty.err;
}

}  // namespace
}  // namespace pf::e2e
