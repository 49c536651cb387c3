// (e) WatchJob on a multi-round skipping job delivers several image snapshots whose estimated
// noise decreases, and the last one equals GetImage; `pf watch -o` keeps the EXR up to date
// (atomically rewritten) and ends with the final image. `pf watch` outlives coordinator restarts
// within its window: 10 graceful (SIGTERM) and 10 kill -9 restarts while two watches follow a job,
// and both end with the job (exit 0, the final image).
#include <signal.h>

#include <algorithm>
#include <condition_variable>
#include <mutex>
#include <nlohmann/json.hpp>
#include <thread>

#include "client/farm_client.h"
#include "tests/e2e/harness.h"

namespace pf::e2e {
namespace {
namespace v1 = photonfarm::v1;

// client.Watch with a watchdog: a watch has no end of its own if the job never finishes, so it
// is cancelled after 90 s.
v1::JobStatus WatchAtMost90s(FarmClient& client, const std::string& job_id, bool include_images,
                             const std::function<void(const v1::JobUpdate&)>& on_update) {
  std::mutex m;
  std::condition_variable cv;
  bool done = false;
  std::thread watchdog([&] {
    std::unique_lock lock(m);
    if (!cv.wait_for(lock, std::chrono::seconds(90), [&] { return done; })) client.Cancel();
  });
  const v1::JobStatus status = client.Watch(job_id, include_images, 0.05, on_update);
  {
    std::lock_guard lock(m);
    done = true;
  }
  cv.notify_all();
  watchdog.join();
  return status;
}

TEST(FarmWatch, SnapshotsGetLessNoisyAndTheLastIsTheImage) {
  TestDir dir;
  JobArgs job;
  job.photons = 100000;  // ~0.15 s per task: the coordinator refreshes its noise estimate every 0.5 s
  job.k = 40;
  job.rounds = 6;  // 24 tasks; the noise estimate needs >= 2 maps per pixel (round 2 on)
  CoordinatorProcess coordinator(dir / "data", dir.path());
  const RunResult sub =
      RunCommand(Concat(Concat({Binaries::Pf(), "submit", Binaries::Scene()}, job.ToFlags()),
                        {"--coordinator", coordinator.address()}),
                 dir.path());
  ASSERT_EQ(sub.exit_code, 0) << sub.err;
  const std::string job_id = sub.out.substr(0, sub.out.find('\n'));

  // pf watch as a second observer, rewriting its EXR.
  const std::string watched = (dir / "watched.exr").string();
  Process pf_watch("pf-watch",
                   {Binaries::Pf(), "watch", job_id, "-o", watched, "--json", "--interval", "0.05",
                    "--coordinator", coordinator.address()},
                   dir / "watch.err", dir / "watch.out");

  struct Snapshot {
    double noise;
    uint32_t rounds_done;
    uint64_t tasks_done;
    std::string exr;
  };
  std::vector<Snapshot> snapshots;
  FarmClient client(coordinator.address(), "");
  std::unique_ptr<Process> worker;
  const v1::JobStatus final_status = WatchAtMost90s(client, job_id, true, [&](const v1::JobUpdate& u) {
    // One worker, started once the watch is subscribed (from this thread: see harness.h).
    if (!worker) worker = StartWorker(coordinator.address(), dir.path(), "w1");
    if (u.has_image() && !u.image().exr_bytes().empty())
      snapshots.push_back({u.status().estimated_noise_rms(), u.status().rounds_done(),
                           u.status().tasks_done(), u.image().exr_bytes()});
  });
  ASSERT_EQ(final_status.state(), v1::JOB_STATE_SUCCEEDED);

  // Several snapshots with a noise estimate, and the estimate comes down as maps accumulate.
  // It is the RMS over pixels with >= 2 maps of their standard error: within a round, pixels
  // that just got their second map join with a large error, so it may tick up briefly; over
  // rounds it falls like 1/sqrt(maps) (2 -> 6 maps: x0.58). So: the last estimate is the lowest,
  // well below the first, and the estimate falls more often than it rises.
  std::vector<double> noise;
  std::string trace;
  for (const Snapshot& s : snapshots) {
    trace += "\n  tasks " + std::to_string(s.tasks_done) + " rounds " + std::to_string(s.rounds_done) +
             " noise " + std::to_string(s.noise);
    if (s.noise >= 0 && (noise.empty() || s.noise != noise.back())) noise.push_back(s.noise);
  }
  std::printf("%zu snapshots, %zu distinct noise estimates:", snapshots.size(), noise.size());
  for (double n : noise) std::printf(" %.4f", n);
  std::printf("\n");
  ASSERT_GE(snapshots.size(), 4u) << trace;
  ASSERT_GE(noise.size(), 3u) << trace;
  int falls = 0, rises = 0;
  for (size_t i = 1; i < noise.size(); ++i) (noise[i] < noise[i - 1] ? falls : rises) += 1;
  EXPECT_EQ(noise.back(), *std::min_element(noise.begin(), noise.end())) << trace;
  EXPECT_LT(noise.back(), 0.85 * noise.front()) << trace;
  EXPECT_GT(falls, rises) << trace;

  // The last snapshot is the final image, bit for bit.
  const std::string final_bytes = client.GetImage(job_id);
  EXPECT_TRUE(BitIdentical(DecodeImage(snapshots.back().exr), DecodeImage(final_bytes)));
  EXPECT_EQ(snapshots.back().tasks_done, final_status.tasks_total());

  // pf watch: exit 0, several snapshot updates, and its EXR is the final image.
  EXPECT_EQ(pf_watch.Wait(30).value_or(-1), 0) << ReadFile(dir / "watch.err");
  int pf_snapshots = 0;
  for (const std::string& line : ReadLines(dir / "watch.out"))
    if (!line.empty() && line[0] == '{') pf_snapshots += nlohmann::json::parse(line)["snapshot"].get<bool>();
  EXPECT_GE(pf_snapshots, 2) << ReadFile(dir / "watch.out");
  EXPECT_TRUE(BitIdentical(ReadImage(watched), DecodeImage(final_bytes)));
  worker->Signal(SIGTERM);
  EXPECT_EQ(worker->Wait(20).value_or(-1), 0);
}

TEST(FarmWatch, SnapshotsLargerThanOneMessageArriveWhole) {
  TestDir dir;
  CoordinatorProcess coordinator(dir / "data", dir.path());
  const RunResult sub =
      RunCommand({Binaries::Pf(), "submit", Binaries::Scene(), "--res", "512x512", "--spp", "1", "--plan",
                  "multiple-maps", "--tile", "128", "--coordinator", coordinator.address()},
                 dir.path());
  ASSERT_EQ(sub.exit_code, 0) << sub.err;
  const std::string job_id = sub.out.substr(0, sub.out.find('\n'));
  FarmClient client(coordinator.address(), "");
  std::unique_ptr<Process> worker;
  size_t largest = 0, snapshots = 0;
  std::string last;
  const v1::JobStatus st = client.Watch(job_id, true, 0.05, [&](const v1::JobUpdate& u) {
    if (!worker) worker = StartWorker(coordinator.address(), dir.path(), "w1");
    if (!u.has_image()) return;
    EXPECT_EQ(u.image().count(), 1u);
    const Image img = DecodeImage(u.image().exr_bytes());  // whole: decodes
    EXPECT_EQ(img.width(), 512);
    largest = std::max(largest, u.image().exr_bytes().size());
    last = u.image().exr_bytes();
    ++snapshots;
  });
  ASSERT_EQ(st.state(), v1::JOB_STATE_SUCCEEDED);
  EXPECT_GT(largest, size_t(1) << 20) << "no snapshot needed more than one chunk";
  EXPECT_GE(snapshots, 2u);
  EXPECT_EQ(last, client.GetImage(job_id));
  worker->Signal(SIGTERM);
  EXPECT_EQ(worker->Wait(20).value_or(-1), 0);
}

}  // namespace
}  // namespace pf::e2e

namespace pf::e2e {
namespace {

// The ETA a watcher sees against the time that really remained. One worker traces and balances a
// 1M-photon map (seconds) before its first tile, then renders 16 tiles from it (a fraction of a
// second each): the old average-rate ETA, elapsed × remaining / done, carried that start-up in
// every tile and ran 1.5–3× high until late in the job; the throughput ETA must be close.
TEST(FarmWatch, EtaTracksTheTimeThatRemains) {
  TestDir dir;
  CoordinatorProcess coordinator(dir / "data", dir.path());
  const RunResult sub = RunCommand({Binaries::Pf(),
                                    "submit",
                                    Binaries::Scene(),
                                    "--integrator",
                                    "photonmap",
                                    "--photons",
                                    "1000000",
                                    "--k",
                                    "50",
                                    "--res",
                                    "128x128",
                                    "--spp",
                                    "8",
                                    "--plan",
                                    "multiple-maps",
                                    "--tile",
                                    "32",
                                    "--tail-tile",
                                    "0",
                                    "--coordinator",
                                    coordinator.address()},
                                   dir.path());
  ASSERT_EQ(sub.exit_code, 0) << sub.err;
  const std::string job_id = sub.out.substr(0, sub.out.find('\n'));
  FarmClient client(coordinator.address(), "");
  std::unique_ptr<Process> worker;
  struct Sample {
    double elapsed, eta;
    uint64_t done;
  };
  std::vector<Sample> samples;
  const v1::JobStatus st = WatchAtMost90s(client, job_id, false, [&](const v1::JobUpdate& u) {
    if (!worker) worker = StartWorker(coordinator.address(), dir.path(), "w1");  // one thread
    samples.push_back({u.status().elapsed_seconds(), u.status().eta_seconds(), u.status().tasks_done()});
  });
  ASSERT_EQ(st.state(), v1::JOB_STATE_SUCCEEDED);
  ASSERT_EQ(st.tasks_total(), 16u);
  const double end = st.elapsed_seconds();

  // Ratio ETA / truth over the middle of the job (4..12 of 16 tiles merged), where the old
  // formula was 1 + start-up / (done × tile): a median of 3.4 measured on an idle machine. The
  // tolerance is wide, the median within [0.5, 2]: tile times vary with the load of a shared
  // machine (ctest -j2 runs other tests beside this one; 1.43 seen there), and an ETA is a
  // forecast of that, not a measurement.
  std::vector<double> ratios;
  std::string trace;
  for (const Sample& s : samples) {
    trace += "\n  elapsed " + std::to_string(s.elapsed) + " done " + std::to_string(s.done) + " eta " +
             std::to_string(s.eta) + " truth " + std::to_string(end - s.elapsed);
    if (s.done >= 4 && s.done <= 12 && s.eta >= 0 && end - s.elapsed > 0.05)
      ratios.push_back(s.eta / (end - s.elapsed));
  }
  ASSERT_GE(ratios.size(), 3u) << trace;
  std::nth_element(ratios.begin(), ratios.begin() + ratios.size() / 2, ratios.end());
  const double median = ratios[ratios.size() / 2];
  EXPECT_GE(median, 0.5) << trace;
  EXPECT_LE(median, 2.0) << trace;
  worker->Signal(SIGTERM);
  EXPECT_EQ(worker->Wait(20).value_or(-1), 0);
}

TEST(FarmWatch, EveryWatchOutlivesTwentyCoordinatorRestarts) {
  TestDir dir;
  JobArgs job;
  auto coordinator = std::make_unique<CoordinatorProcess>(dir / "data", dir.path());
  const int port = coordinator->port();
  const std::string address = coordinator->address();
  // No worker yet: the job stays queued through every restart.
  const std::string id = SubmitJob(dir, address, job.ToFlags());
  ASSERT_FALSE(id.empty());
  Process image_watch(
      "watch-image",
      {Binaries::Pf(), "watch", id, "-o", (dir / "watched.exr").string(), "-q", "--coordinator", address},
      dir / "watch-image.log");
  Process json_watch("watch-json", {Binaries::Pf(), "watch", id, "--json", "--coordinator", address},
                     dir / "watch-json.err", dir / "watch-json.out");
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  for (int restart = 0; restart < 20; ++restart) {
    // Alternately graceful and kill -9, each followed by a pause in which the watches re-subscribe.
    const size_t updates_before = ReadLines(dir / "watch-json.out").size();
    coordinator->process().Signal(restart % 2 == 0 ? SIGTERM : SIGKILL);
    ASSERT_TRUE(coordinator->process().Wait(20).has_value()) << "restart " << restart;
    coordinator =
        std::make_unique<CoordinatorProcess>(dir / "data", dir.path(), std::vector<std::string>{}, port);
    // The JSON watch has subscribed again once it prints the status the new stream starts with.
    ASSERT_TRUE(WaitUntil([&] { return ReadLines(dir / "watch-json.out").size() > updates_before; }, 20))
        << "restart " << restart << ": " << ReadFile(dir / "watch-json.err");
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    ASSERT_TRUE(image_watch.Running()) << "restart " << restart << ": " << ReadFile(dir / "watch-image.log");
    ASSERT_TRUE(json_watch.Running()) << "restart " << restart << ": " << ReadFile(dir / "watch-json.err");
  }
  auto worker = StartWorker(address, dir.path(), "w1");
  EXPECT_EQ(image_watch.Wait(60).value_or(-1), 0) << ReadFile(dir / "watch-image.log");
  EXPECT_EQ(json_watch.Wait(60).value_or(-1), 0) << ReadFile(dir / "watch-json.err");
  const std::vector<std::string> updates = ReadLines(dir / "watch-json.out");
  ASSERT_FALSE(updates.empty());
  EXPECT_EQ(nlohmann::json::parse(updates.back()).at("state"), "succeeded") << updates.back();
  FarmClient client(address, "");
  EXPECT_TRUE(BitIdentical(ReadImage(dir / "watched.exr"), DecodeImage(client.GetImage(id))));
  worker->Signal(SIGTERM);
  EXPECT_TRUE(worker->Wait(20).has_value());
}

}  // namespace
}  // namespace pf::e2e
