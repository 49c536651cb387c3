// A hostile soak of a real pf-coordinator (docs/security.md "Budgets", the bound of the soak):
// strangers without a token send huge bodies and slow heads to the status page, and a client
// WITH the token uploads scene bombs, submits and cancels jobs of 2^20 tasks one after another
// (and a second one while the first is held), and opens watches it never reads. The
// coordinator's peak RSS (VmHWM) stays under the documented bound, its memory comes back once
// the jobs have ended, every refusal names its budget (RESOURCE_EXHAUSTED; for a small MGF bomb
// the loader's expansion budget, INVALID_ARGUMENT), and it still answers an authenticated status
// call at once.
//
// Before the budgets, the second 2^20-task job was accepted next to the first (~450 MiB each),
// a cancelled job kept its task list (VmRSS stayed at ~600 MiB), and unread watches stayed open.
#include <httplib.h>

#include <fstream>
#include <future>
#include <thread>

#include "photonfarm/v1/farm.grpc.pb.h"
#include "proto/convert.h"
#include "rpc/grpc_channel.h"
#include "tests/e2e/harness.h"
#include "tests/util/job_specs.h"
#include "tests/util/raw_connection.h"
#include "tests/util/raw_http2.h"

namespace pf::e2e {
namespace {
namespace v1 = photonfarm::v1;
using test_util::RawConnection;
using SteadyClock = std::chrono::steady_clock;

// The documented bounds (docs/security.md "Budgets", the soak): one job of 2^20 tasks (~440 MiB,
// the most tasks_total lets in at once here) plus the coordinator itself (~30 MiB) and what the
// rest of the soak adds (a few MiB); and what is left once every job has ended.
constexpr long kPeakBoundMiB = 640;
constexpr long kAfterBoundMiB = 96;
constexpr int kRounds = 3;

const std::string kToken = "soak-token";

// MemoryOf in MiB.
struct Memory {
  long rss_mib = -1, peak_mib = -1;
};
Memory MiBOf(pid_t pid) {
  const ProcessMemory kib = MemoryOf(pid);
  Memory m;
  if (kib.rss_kib >= 0) m.rss_mib = kib.rss_kib / 1024;
  if (kib.peak_kib >= 0) m.peak_mib = kib.peak_kib / 1024;
  return m;
}

std::unique_ptr<grpc::ClientContext> Ctx(double seconds = 30) {
  auto ctx = std::make_unique<grpc::ClientContext>();
  PrepareContext(ctx.get(), kToken, Seconds(seconds));
  return ctx;
}

::testing::AssertionResult Refused(const grpc::Status& st, const std::string& budget) {
  if (st.error_code() == grpc::StatusCode::RESOURCE_EXHAUSTED &&
      st.error_message().find("the budget " + budget + " = ") != std::string::npos)
    return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure()
         << "expected RESOURCE_EXHAUSTED for " << budget << ", got " << StatusToString(st);
}

// An MGF bomb: arrays of arrays of spheres (10^9 of them), padded with a comment to `bytes`.
v1::UploadSceneRequest MgfBomb(size_t bytes) {
  std::string mgf = "xf -a 1000 -t 1 0 0\nxf -a 1000 -t 0 1 0\nxf -a 1000 -t 0 0 1\nsph c .1\nxf\nxf\nxf\n";
  while (mgf.size() < bytes) mgf += "# " + std::string(1000, 'x') + "\n";
  v1::UploadSceneRequest req;
  req.mutable_bundle()->set_entry("bomb.mgf");
  v1::SceneFile* f = req.mutable_bundle()->add_files();
  f->set_path("bomb.mgf");
  f->set_content(mgf);
  return req;
}

// The small bomb of the hostile test: 4 files, ~200 bytes, `i` arrays three levels deep over one
// quad (10^9 quads). Small enough for every upload budget: the loader's expansion budget
// (docs/security.md, "Scene budgets") must refuse it before any work.
v1::UploadSceneRequest TinyMgfBomb() {
  const std::pair<const char*, const char*> files[] = {
      {"x.mgf", "v a =\n p 0 0 0\nv b =\n p 1 0 0\nv c =\n p 1 1 0\nv d =\n p 0 1 0\nf a b c d\n"},
      {"y.mgf", "i x.mgf -a 1000 -t 0 0 1\n"},
      {"z.mgf", "i y.mgf -a 1000 -t 0 1 0\n"},
      {"bomb.mgf", "i z.mgf -a 1000 -t 1 0 0\n"}};
  v1::UploadSceneRequest req;
  req.mutable_bundle()->set_entry("bomb.mgf");
  for (const auto& [path, content] : files) {
    v1::SceneFile* f = req.mutable_bundle()->add_files();
    f->set_path(path);
    f->set_content(content);
  }
  return req;
}

// The largest job a coordinator admits (2^20 tasks) as a request.
v1::SubmitJobRequest LargestJob(const std::string& scene_hash, uint64_t seed) {
  v1::SubmitJobRequest req;
  *req.mutable_spec() = test_util::LargestJobSpec(scene_hash, seed);
  return req;
}

// A WatchJob with images whose client never reads (a zero flow-control window, raw_http2.h).
std::unique_ptr<RawConnection> UnreadWatch(int port, const std::string& job_id) {
  auto c = std::make_unique<RawConnection>(port);
  v1::WatchJobRequest req;
  req.set_job_id(job_id);
  req.set_include_images(true);
  EXPECT_TRUE(c->connected() && c->Send(test_util::GrpcCallBytes("127.0.0.1:" + std::to_string(port),
                                                                 "/photonfarm.v1.RenderService/WatchJob",
                                                                 req.SerializeAsString(),
                                                                 /*stream_window=*/0, "Bearer " + kToken)));
  return c;
}

// The status of a watch that reads: OK once its first update arrived.
grpc::Status WatchOnce(v1::RenderService::Stub& render, const std::string& job_id) {
  v1::WatchJobRequest req;
  req.set_job_id(job_id);
  auto ctx = Ctx(5);
  auto reader = render.WatchJob(ctx.get(), req);
  v1::JobUpdate update;
  if (!reader->Read(&update)) return reader->Finish();
  ctx->TryCancel();
  while (reader->Read(&update)) {
  }
  reader->Finish();
  return grpc::Status::OK;
}

TEST(HostileSoak, TheCoordinatorStaysUnderItsBoundRefusesByBudgetAndAnswers) {
  const auto start = SteadyClock::now();
  TestDir dir;
  std::ofstream(dir / "token") << kToken << "\n";
  CoordinatorProcess coordinator(
      dir / "data", dir.path(),
      {"--http", "127.0.0.1:0", "--log-level", "warn", "--limit", "tasks_total=1048576", "--limit",
       "upload_bytes=1048576", "--limit", "watchers_per_client=8", "--limit", "watch_unread_seconds=2"},
      0, (dir / "token").string());
  const pid_t pid = coordinator.process().pid();
  const Memory before = MiBOf(pid);
  ASSERT_GT(before.peak_mib, 0);
  auto channel = MakeCoordinatorChannel(coordinator.address(), {});
  auto render = v1::RenderService::NewStub(channel);

  const int http_port = coordinator.http_port();
  ASSERT_GT(http_port, 0);
  v1::UploadSceneRequest cornell;
  const SceneBundle bundle = CollectBundle(Binaries::Scene());
  BundleToProto(bundle, cornell.mutable_bundle());
  v1::UploadSceneResponse scene;
  ASSERT_TRUE(render->UploadScene(Ctx().get(), cornell, &scene).ok());

  std::vector<std::unique_ptr<RawConnection>> slow;
  std::vector<long> rss_after_round;
  uint64_t seed = 0;
  for (int round = 0; round < kRounds; ++round) {
    SCOPED_TRACE("round " + std::to_string(round));
    // Strangers at the status page: 50 more slow heads (the gate drops the oldest), 400 MiB bodies.
    for (int i = 0; i < 50; ++i) {
      slow.push_back(std::make_unique<RawConnection>(http_port));
      ASSERT_TRUE(slow.back()->Send("GET / HTTP/1.1\r\nHost: x\r\n"));
    }
    for (const std::string head :
         {"POST /api/status HTTP/1.1\r\nHost: x\r\nContent-Length: 419430400\r\n\r\n",
          "POST / HTTP/1.1\r\nHost: x\r\nTransfer-Encoding: chunked\r\n\r\n"}) {
      RawConnection c(http_port);
      ASSERT_TRUE(c.Send(head));
      EXPECT_EQ(c.Receive().substr(0, 12), "HTTP/1.1 413") << head;
      EXPECT_LT(c.SendMany('a', size_t(400) << 20), size_t(64) << 20) << head << ": the body was read";
    }
    // Scene bombs from the client with the token, four at once: refused by size, unloaded.
    std::vector<std::future<grpc::Status>> bombs;
    for (int i = 0; i < 4; ++i)
      bombs.push_back(std::async(std::launch::async, [&render] {
        v1::UploadSceneResponse resp;
        return render->UploadScene(Ctx().get(), MgfBomb(size_t(3) << 19), &resp);
      }));
    for (auto& b : bombs) EXPECT_TRUE(Refused(b.get(), "upload_bytes"));
    // … and small ones, four at once: refused by the loader's expansion budget, before any work.
    bombs.clear();
    for (int i = 0; i < 4; ++i)
      bombs.push_back(std::async(std::launch::async, [&render] {
        v1::UploadSceneResponse resp;
        return render->UploadScene(Ctx().get(), TinyMgfBomb(), &resp);
      }));
    // (Beyond two at once, uploads_per_client refuses them before they are read.)
    int by_expansion = 0;
    for (auto& b : bombs) {
      const grpc::Status st = b.get();
      if (st.error_code() == grpc::StatusCode::INVALID_ARGUMENT &&
          st.error_message().find("more than the budget") != std::string::npos)
        ++by_expansion;
      else
        EXPECT_TRUE(Refused(st, "uploads_per_client"));
    }
    EXPECT_GE(by_expansion, 1) << "no small bomb reached the loader's expansion budget";

    // Two jobs of 2^20 tasks one after the other; another one while one is held is refused.
    std::vector<std::unique_ptr<RawConnection>> unread;
    std::string watched;
    for (int j = 0; j < 2; ++j) {
      v1::SubmitJobResponse job;
      grpc::Status st;
      // The previous job's tasks count until the persister has released them (within ~1 s).
      ASSERT_TRUE(WaitUntil(
          [&] {
            return (st = render->SubmitJob(Ctx().get(), LargestJob(scene.scene_hash(), ++seed), &job)).ok();
          },
          10))
          << StatusToString(st);
      v1::SubmitJobResponse second;
      EXPECT_TRUE(Refused(render->SubmitJob(Ctx().get(), LargestJob(scene.scene_hash(), ++seed), &second),
                          "tasks_total"));
      if (j == 0) {
        watched = job.job_id();
        // Watches of it that are never read, as many as the budget allows; more are refused.
        for (int i = 0; i < 8; ++i) {
          unread.push_back(UnreadWatch(coordinator.port(), job.job_id()));
          ASSERT_EQ(test_util::ResponseHeadersFlags(*unread.back()), 0x4) << "accepted, its update not sent";
        }
        EXPECT_TRUE(Refused(WatchOnce(*render, job.job_id()), "watchers_per_client"));
        unread.push_back(UnreadWatch(coordinator.port(), job.job_id()));
        EXPECT_EQ(test_util::ResponseHeadersFlags(*unread.back()) & 0x1, 0x1) << "a ninth watch was accepted";
      }
      v1::CancelJobRequest cancel;
      cancel.set_job_id(job.job_id());
      v1::CancelJobResponse cancelled;
      ASSERT_TRUE(render->CancelJob(Ctx().get(), cancel, &cancelled).ok());
    }
    // The unread watches are ended after watch_unread_seconds: a reading watch gets a place again.
    EXPECT_TRUE(WaitUntil([&] { return WatchOnce(*render, watched).ok(); }, 10))
        << "the unread watches stayed";
    Memory after;
    EXPECT_TRUE(WaitUntil([&] { return (after = MiBOf(pid)).rss_mib < kAfterBoundMiB; }, 5))
        << "VmRSS after every job ended: " << after.rss_mib << " MiB";
    rss_after_round.push_back(after.rss_mib);
  }

  // Bounded, no growth from round to round, answering.
  const Memory peak = MiBOf(pid);
  EXPECT_LT(peak.peak_mib, kPeakBoundMiB) << "VmHWM " << before.peak_mib << " -> " << peak.peak_mib << " MiB";
  EXPECT_LE(rss_after_round.back(), rss_after_round.front() + 8) << "VmRSS grew from round to round";
  const auto asked = SteadyClock::now();
  v1::ListJobsRequest list;
  list.set_include_finished(true);
  v1::ListJobsResponse jobs;
  ASSERT_TRUE(render->ListJobs(Ctx(2).get(), list, &jobs).ok());
  EXPECT_EQ(jobs.jobs_size(), 2 * kRounds);
  for (const v1::JobStatus& j : jobs.jobs()) {
    EXPECT_EQ(j.state(), v1::JOB_STATE_CANCELLED);
    EXPECT_EQ(j.tasks_total(), uint64_t(1) << 20);
  }
  EXPECT_LT(SteadyClock::now() - asked, std::chrono::seconds(1));
  httplib::Client http("127.0.0.1", http_port);
  http.set_read_timeout(2);
  const auto page = http.Get("/api/status", {{"Authorization", "Bearer " + kToken}});
  ASSERT_TRUE(page);
  EXPECT_EQ(page->status, 200);
  std::printf("soak: %d rounds in %.1f s; VmHWM %ld -> %ld MiB (bound %ld); VmRSS after each round:", kRounds,
              std::chrono::duration<double>(SteadyClock::now() - start).count(), before.peak_mib,
              peak.peak_mib, kPeakBoundMiB);
  for (long rss : rss_after_round) std::printf(" %ld", rss);
  std::printf(" MiB (bound %ld)\n", kAfterBoundMiB);
  EXPECT_LT(SteadyClock::now() - start, std::chrono::seconds(60));
}

}  // namespace
}  // namespace pf::e2e
