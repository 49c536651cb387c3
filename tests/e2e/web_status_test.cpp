// The coordinator's web status page (pf-coordinator --http; issue #16) with real processes: the
// gRPC side's token guards it (Bearer, or Basic with the token as password), and headless
// Chromium (Debian's chromium) shows the jobs, the workers and a live preview that appears and
// changes as the job runs.
#include <httplib.h>
#include <signal.h>

#include <fstream>
#include <regex>

#include "common/image/png_io.h"
#include "tests/e2e/harness.h"

namespace pf::e2e {
namespace {
namespace fs = std::filesystem;

// The "http on HOST:PORT" line of a coordinator started with --http.
int HttpPort(const fs::path& log_dir) {
  int port = 0;
  WaitUntil(
      [&] {
        for (const auto& entry : fs::directory_iterator(log_dir)) {
          if (entry.path().extension() != ".out") continue;
          std::smatch m;
          const std::string text = ReadFile(entry.path());
          static const std::regex re(R"(http on 127\.0\.0\.1:([0-9]+))");
          if (std::regex_search(text, m, re)) port = std::stoi(m[1].str());
        }
        return port > 0;
      },
      30);
  return port;
}

std::string Submit(const TestDir& dir, const std::string& address, const JobArgs& job,
                   const std::map<std::string, std::string>& env = {}) {
  const RunResult r = RunCommand(Concat(Concat({Binaries::Pf(), "submit", Binaries::Scene()}, job.ToFlags()),
                                        {"--coordinator", address}),
                                 dir.path(), 60, env);
  EXPECT_EQ(r.exit_code, 0) << r.err;
  return r.out.substr(0, r.out.find('\n'));
}

TEST(WebStatus, SameTokenAsGrpc) {
  TestDir dir;
  std::ofstream(dir / "token") << "s3cret-token\n";
  CoordinatorProcess coordinator(dir / "data", dir.path(), {"--http", "127.0.0.1:0"}, 0,
                                 (dir / "token").string());
  const int port = HttpPort(dir.path());
  ASSERT_GT(port, 0);
  const std::string id = Submit(dir, coordinator.address(), JobArgs(), {{"PF_TOKEN", "s3cret-token"}});
  httplib::Client http("127.0.0.1", port);
  auto r = http.Get("/");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 401);
  EXPECT_EQ(r->get_header_value("WWW-Authenticate"), "Basic realm=\"photonfarm\"");
  r = http.Get("/api/status", {{"Authorization", "Bearer wrong"}});
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 401);
  r = http.Get("/jobs/" + id + "/preview.png");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 401);
  r = http.Get("/api/status", {{"Authorization", "Bearer s3cret-token"}});
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 200);
  EXPECT_NE(r->body.find("\"job_id\":\"" + id + "\""), std::string::npos) << r->body;
  http.set_basic_auth("anyone", "s3cret-token");
  r = http.Get("/");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 200);
  EXPECT_NE(r->body.find(id), std::string::npos) << r->body;
  r = http.Get("/jobs/" + id + "/preview.png");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 200);
  EXPECT_EQ(r->body.substr(1, 3), "PNG");
  r = http.Get("/jobs/job-999/preview.png");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 404);
}

// Mean absolute difference of two screenshots' RGB over the square [x0, x0+n) x [y0, y0+n), and
// the standard deviation of the first one's values there.
struct Region {
  double diff = 0, stddev = 0;
};
Region Compare(const Png8Image& a, const Png8Image& b, int x0, int y0, int n) {
  double sum = 0, sum2 = 0, diff = 0;
  int count = 0;
  for (int y = y0; y < y0 + n; ++y)
    for (int x = x0; x < x0 + n; ++x)
      for (int c = 0; c < 3; ++c) {
        const size_t i = (size_t(y) * a.width + x) * 3 + c;
        sum += a.rgb[i];
        sum2 += double(a.rgb[i]) * a.rgb[i];
        diff += std::abs(int(a.rgb[i]) - int(b.rgb[i]));
        ++count;
      }
  const double mean = sum / count;
  return {diff / count, std::sqrt(std::max(0.0, sum2 / count - mean * mean))};
}

RunResult Chromium(const TestDir& dir, const std::vector<std::string>& args, const std::string& profile) {
  std::vector<std::string> argv = {"/usr/bin/chromium",
                                   "--headless",
                                   "--no-sandbox",
                                   "--disable-gpu",
                                   "--disable-quic",
                                   "--no-first-run",
                                   "--disable-background-networking",
                                   "--disable-component-update",
                                   "--disable-sync",
                                   "--hide-scrollbars",
                                   "--user-data-dir=" + (dir / profile).string(),
                                   "--window-size=800,600"};
  return RunCommand(Concat(argv, args), dir.path(), 90, {{"HOME", dir.path().string()}});
}

TEST(WebStatus, ChromiumShowsJobsWorkersAndALivePreview) {
  ASSERT_TRUE(fs::exists("/usr/bin/chromium")) << "Debian's chromium (tools/install-deps.sh) is needed";
  TestDir dir;
  CoordinatorProcess coordinator(dir / "data", dir.path(), {"--http", "127.0.0.1:0"});
  const int port = HttpPort(dir.path());
  ASSERT_GT(port, 0);
  const std::string url = "http://127.0.0.1:" + std::to_string(port) + "/";
  JobArgs job;
  job.rounds = 4;  // 16 tasks
  job.res = 64;
  const std::string id = Submit(dir, coordinator.address(), job);
  auto worker = StartWorker(coordinator.address(), dir.path(), "w1");
  // Hold the worker still after a few merges: the first screenshot sees a partial image.
  ASSERT_TRUE(WaitUntil([&] { return Grep(dir / "w1.log", "merged=true").size() >= 3; }, 60))
      << ReadFile(dir / "w1.log");
  worker->Signal(SIGSTOP);
  RunResult r = Chromium(dir, {"--screenshot=" + (dir / "early.png").string(), url}, "profile-1");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  r = Chromium(dir, {"--dump-dom", url}, "profile-2");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("preview-" + id), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("<td>w1</td>"), std::string::npos) << "the workers table names the worker\n" << r.out;
  EXPECT_NE(r.out.find("running"), std::string::npos) << r.out;
  worker->Signal(SIGCONT);
  const RunResult watch = RunCommand(
      {Binaries::Pf(), "watch", id, "-q", "--coordinator", coordinator.address()}, dir.path(), 120);
  ASSERT_EQ(watch.exit_code, 0) << watch.err;
  r = Chromium(dir, {"--screenshot=" + (dir / "late.png").string(), url}, "profile-3");
  ASSERT_EQ(r.exit_code, 0) << r.err;

  // The preview is the first image of the page: 192x192 at the body's 8 px margin.
  const Png8Image early = ReadPng8(dir / "early.png"), late = ReadPng8(dir / "late.png");
  ASSERT_EQ(early.width, 800);
  ASSERT_EQ(late.width, 800);
  const Region appeared = Compare(early, late, 8, 8, 192);
  EXPECT_GT(appeared.stddev, 10) << "the early preview shows an image, not a flat box";
  EXPECT_GT(Compare(late, early, 8, 8, 192).stddev, 10) << "the final preview shows an image";
  EXPECT_GT(appeared.diff, 2) << "the preview changed as the job ran";
  // Outside the preview (the page's background to its right) nothing is drawn.
  EXPECT_LT(Compare(early, late, 600, 8, 100).stddev, 1);
}

}  // namespace
}  // namespace pf::e2e
