// The coordinator's web status page (pf-coordinator --http) with real processes: the
// gRPC side's token guards it (Bearer, or Basic with the token as password), headless Chromium
// (Debian's chromium) shows the jobs, the workers and a live preview that appears and changes as
// the job runs, and hostile clients without a token (huge bodies and heads, slow heads) neither
// grow the coordinator nor keep the page away (docs/security.md, "The web status page").
#include <httplib.h>
#include <signal.h>

#include <fstream>
#include <nlohmann/json.hpp>
#include <regex>
#include <thread>

#include "client/farm_client.h"
#include "common/image/png_io.h"
#include "tests/e2e/harness.h"
#include "tests/util/raw_connection.h"

namespace pf::e2e {
using pf::test_util::RawConnection;
namespace {
namespace fs = std::filesystem;

std::string Submit(const TestDir& dir, const std::string& address, const JobArgs& job,
                   const std::map<std::string, std::string>& env = {}) {
  const RunResult r = RunCommand(Concat(Concat({Binaries::Pf(), "submit", Binaries::Scene()}, job.ToFlags()),
                                        {"--coordinator", address}),
                                 dir.path(), 60, env);
  EXPECT_EQ(r.exit_code, 0) << r.err;
  return r.out.substr(0, r.out.find('\n'));
}

// A coordinator whose token is "s3cret-token", with its status page on 127.0.0.1 (any port).
CoordinatorProcess WithTokenAndStatusPage(const TestDir& dir) {
  std::ofstream(dir / "token") << "s3cret-token\n";
  return CoordinatorProcess(dir / "data", dir.path(), {"--http", "127.0.0.1:0"}, 0, (dir / "token").string());
}

TEST(WebStatus, SameTokenAsGrpc) {
  TestDir dir;
  CoordinatorProcess coordinator = WithTokenAndStatusPage(dir);
  const int port = coordinator.http_port();
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

// The page's actions (POST /jobs/<id>/<action>; docs/farm.md "The web status page"): the client
// credential only, the page's own header and origin only (cross-site requests are 403), and each
// does what pf does: pause, resume, cancel, requeue, delete, with the gRPC refusals as HTTP codes.
TEST(WebStatus, ActionsNeedTheClientTokenAndThePagesHeaderAndDoWhatPfDoes) {
  TestDir dir;
  std::ofstream(dir / "token") << "s3cret-token\n";
  std::ofstream(dir / "worker-token") << "w0rker-token\n";
  CoordinatorProcess coordinator(
      dir / "data", dir.path(),
      {"--http", "127.0.0.1:0", "--worker-token-file", (dir / "worker-token").string()}, 0,
      (dir / "token").string());
  const int port = coordinator.http_port();
  ASSERT_GT(port, 0);
  const std::string id = Submit(dir, coordinator.address(), JobArgs(), {{"PF_TOKEN", "s3cret-token"}});
  FarmClient client(coordinator.address(), "s3cret-token");
  httplib::Client http("127.0.0.1", port);
  const std::string own = "http://127.0.0.1:" + std::to_string(port);
  const auto post = [&](const std::string& job, const std::string& action, httplib::Headers headers) {
    auto r = http.Post("/jobs/" + job + "/" + action, headers, "", "text/plain");
    EXPECT_TRUE(r) << action;
    return r ? std::make_pair(r->status, r->body) : std::make_pair(0, std::string());
  };
  const httplib::Headers page = {
      {"Authorization", "Bearer s3cret-token"}, {"X-Photonfarm-Action", "pause"}, {"Origin", own}};
  // Refused: no credential, the worker's, no header, another action's header, another site.
  EXPECT_EQ(post(id, "pause", {{"X-Photonfarm-Action", "pause"}}).first, 401);
  EXPECT_EQ(
      post(id, "pause", {{"Authorization", "Bearer w0rker-token"}, {"X-Photonfarm-Action", "pause"}}).first,
      401);
  EXPECT_EQ(post(id, "pause", {{"Authorization", "Bearer s3cret-token"}}).first, 403);
  EXPECT_EQ(
      post(id, "pause", {{"Authorization", "Bearer s3cret-token"}, {"X-Photonfarm-Action", "cancel"}}).first,
      403);
  EXPECT_EQ(post(id, "pause",
                 {{"Authorization", "Bearer s3cret-token"},
                  {"X-Photonfarm-Action", "pause"},
                  {"Origin", "http://evil.example"}})
                .first,
            403);
  EXPECT_FALSE(client.GetJob(id).paused()) << "a refused request changed the job";
  EXPECT_EQ(http.Get("/jobs/" + id + "/pause", {{"Authorization", "Bearer s3cret-token"}})->status, 404);

  // Done, as pf does it (no worker: the job stays queued).
  const auto act = [&](const std::string& job, const std::string& action) {
    httplib::Headers h = {{"Authorization", "Bearer s3cret-token"}, {"X-Photonfarm-Action", action}};
    if (action != "cancel") h.insert({"Origin", own});  // optional: a request without one is the page's too
    return post(job, action, h);
  };
  auto [code, body] = act(id, "pause");
  EXPECT_EQ(code, 200) << body;
  EXPECT_TRUE(client.GetJob(id).paused());
  EXPECT_EQ(act(id, "resume").first, 200);
  EXPECT_FALSE(client.GetJob(id).paused());
  std::tie(code, body) = act(id, "delete");
  EXPECT_EQ(code, 409) << "a live job is not deleted: " << body;
  EXPECT_EQ(act(id, "cancel").first, 200);
  EXPECT_EQ(client.GetJob(id).state(), photonfarm::v1::JOB_STATE_CANCELLED);
  std::tie(code, body) = act(id, "requeue");
  ASSERT_EQ(code, 200) << body;
  const std::string requeued = nlohmann::json::parse(body).at("job_id");
  EXPECT_EQ(client.GetJob(requeued).spec().requeued_from(), id);
  EXPECT_EQ(act(id, "delete").first, 200);
  EXPECT_THROW(client.GetJob(id), RpcError);
  EXPECT_EQ(act("job-0123456789abcdef0123456789abcdef", "cancel").first, 404);
  // The page offers the requeued job's live buttons.
  http.set_basic_auth("anyone", "s3cret-token");
  const auto r = http.Get("/");
  ASSERT_TRUE(r);
  EXPECT_NE(r->body.find("act('" + requeued + "', 'pause')"), std::string::npos) << r->body;
  EXPECT_EQ(r->body.find("act('" + id + "'"), std::string::npos) << "the deleted job is still offered";
}

// A job's page (GET /jobs/<id>): its events newest first, naming the worker, and the image as an
// EXR download equal to what GetImage sends; an unknown job is 404, no token 401.
TEST(WebStatus, AJobsPageShowsItsEventsAndTheImageDownloadsAsTheFarmHasIt) {
  TestDir dir;
  CoordinatorProcess coordinator = WithTokenAndStatusPage(dir);
  JobArgs job;
  job.rounds = 1;
  const std::string id = Submit(dir, coordinator.address(), job, {{"PF_TOKEN", "s3cret-token"}});
  auto worker =
      StartWorker(coordinator.address(), dir.path(), "w-page", {"--token-file", (dir / "token").string()});
  FarmClient client(coordinator.address(), "s3cret-token");
  ASSERT_EQ(WaitForJob(client, id, 120).state(), photonfarm::v1::JOB_STATE_SUCCEEDED);
  httplib::Client http("127.0.0.1", coordinator.http_port());
  EXPECT_EQ(http.Get("/jobs/" + id)->status, 401);
  http.set_bearer_token_auth("s3cret-token");
  auto r = http.Get("/jobs/" + id);
  ASSERT_TRUE(r);
  ASSERT_EQ(r->status, 200);
  EXPECT_NE(r->body.find("succeeded"), std::string::npos) << r->body;
  EXPECT_TRUE(
      std::regex_search(r->body, std::regex("<td>merged</td><td>[0-9]+</td><td>1</td><td>w-page</td>")))
      << r->body;
  EXPECT_LT(r->body.find("<td>merged</td>"), r->body.find("<td>leased</td>")) << "newest first";
  EXPECT_NE(r->body.find("/jobs/" + id + "/image.exr"), std::string::npos);
  r = http.Get("/jobs/" + id + "/image.exr");
  ASSERT_TRUE(r);
  ASSERT_EQ(r->status, 200);
  EXPECT_EQ(r->get_header_value("Content-Disposition"), "attachment; filename=\"" + id + ".exr\"");
  EXPECT_TRUE(BitIdentical(DecodeImage(r->body), DecodeImage(client.GetImage(id))));
  EXPECT_EQ(DecodeImage(r->body).width(), job.res);
  EXPECT_EQ(http.Get("/jobs/job-0123456789abcdef0123456789abcdef")->status, 404);
  EXPECT_EQ(http.Get("/jobs/job-0123456789abcdef0123456789abcdef/image.exr")->status, 404);
  // The jobs table links the job's page.
  r = http.Get("/");
  EXPECT_NE(r->body.find("<a href=\"/jobs/" + id + "\">"), std::string::npos) << r->body;
  worker->Signal(SIGTERM);
  EXPECT_EQ(worker->Wait(20).value_or(-1), 0);
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

// The page updates itself in place (no reload): loaded as it was with one job, its update()
// swaps in the tables and previews of the page as it is after a second job was submitted. The
// newer page is handed to it through a stubbed fetch, so the test does not depend on when
// Chromium's timer fires relative to the submission.
TEST(WebStatus, ThePageUpdatesItselfInPlace) {
  ASSERT_TRUE(fs::exists("/usr/bin/chromium")) << "Debian's chromium (tools/install-deps.sh) is needed";
  TestDir dir;
  CoordinatorProcess coordinator(dir / "data", dir.path(), {"--http", "127.0.0.1:0"});
  httplib::Client http("127.0.0.1", coordinator.http_port());
  const std::string first = Submit(dir, coordinator.address(), JobArgs());
  const auto before = http.Get("/");
  ASSERT_TRUE(before);
  const std::string second = Submit(dir, coordinator.address(), JobArgs());
  const auto after = http.Get("/");
  ASSERT_TRUE(after);
  ASSERT_EQ(before->body.find(second), std::string::npos);
  ASSERT_NE(after->body.find(second), std::string::npos);
  std::string page = before->body;
  // The newer page as a JS string literal inside a <script>: "</" would end the element.
  std::string literal = nlohmann::json(after->body).dump();
  for (size_t at = literal.find("</"); at != std::string::npos; at = literal.find("</", at + 3))
    literal.replace(at, 2, "<\\/");
  const std::string stub =
      "<script>window.fetch = async () => new Response(" + literal + ", {status: 200});</script>";
  page.insert(page.find("<head>") + 6, stub);
  std::ofstream(dir / "page.html") << page;
  const RunResult r =
      Chromium(dir, {"--dump-dom", "--virtual-time-budget=10000", "file://" + (dir / "page.html").string()},
               "profile-update");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("act('" + second + "', 'pause')"), std::string::npos) << "the jobs table\n" << r.out;
  EXPECT_NE(r.out.find("id=\"preview-" + second + "\""), std::string::npos) << "the previews\n" << r.out;
  EXPECT_NE(r.out.find("id=\"preview-" + first + "\""), std::string::npos) << r.out;
}

TEST(WebStatus, ChromiumShowsJobsWorkersAndALivePreview) {
  ASSERT_TRUE(fs::exists("/usr/bin/chromium")) << "Debian's chromium (tools/install-deps.sh) is needed";
  TestDir dir;
  CoordinatorProcess coordinator(dir / "data", dir.path(), {"--http", "127.0.0.1:0"});
  const int port = coordinator.http_port();
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

// Bodies are refused from the head alone, before authentication: nothing of a 400 MiB body is
// read, so the coordinator's memory does not move (before the gate, two such POSTs took its peak
// from 25 to 601 MiB: the body after the 401 was read as one next request line).
TEST(WebStatus, HugeBodiesAndHeadsWithoutATokenAreRefusedUnread) {
  TestDir dir;
  CoordinatorProcess coordinator = WithTokenAndStatusPage(dir);
  const int port = coordinator.http_port();
  ASSERT_GT(port, 0);
  const ProcessMemory before = MemoryOf(coordinator.process().pid());
  ASSERT_GT(before.peak_kib, 0);
  constexpr size_t k400MiB = size_t(400) << 20, k64MiB = size_t(64) << 20;
  for (const std::string head : {"POST /api/status HTTP/1.1\r\nHost: x\r\nContent-Length: 419430400\r\n\r\n",
                                 "POST / HTTP/1.1\r\nHost: x\r\nTransfer-Encoding: chunked\r\n\r\n",
                                 "GET / HTTP/1.1\r\nHost: x\r\nContent-Length: 419430400\r\n\r\n"}) {
    const auto start = std::chrono::steady_clock::now();
    RawConnection c(port);
    ASSERT_TRUE(c.connected());
    ASSERT_TRUE(c.Send(head));
    const std::string answer = c.Receive();
    EXPECT_EQ(answer.substr(0, 12), "HTTP/1.1 413") << head << answer;
    EXPECT_LT(c.SendMany('a', k400MiB), k64MiB) << head << ": the body was read";
    EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(5)) << head;
  }
  {  // A head that never ends: 400 MiB without a line end.
    const auto start = std::chrono::steady_clock::now();
    RawConnection c(port);
    ASSERT_TRUE(c.Send("GET /"));
    EXPECT_LT(c.SendMany('a', k400MiB), k64MiB) << "the head was read on and on";
    EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(5));
  }
  const ProcessMemory after = MemoryOf(coordinator.process().pid());
  EXPECT_LT(after.peak_kib - before.peak_kib, 8 * 1024)
      << "peak RSS " << before.peak_kib << " -> " << after.peak_kib << " KiB";
  EXPECT_LT(after.rss_kib - before.rss_kib, 8 * 1024)
      << "RSS " << before.rss_kib << " -> " << after.rss_kib << " KiB";
  // The page still answers.
  httplib::Client http("127.0.0.1", port);
  const auto r = http.Get("/api/status", {{"Authorization", "Bearer s3cret-token"}});
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 200);
}

// Clients that open a connection and send their head a little at a time (slowloris) hold no
// thread: with 50 of them, and then 200 (more than the 128 the gate keeps waiting), an
// authenticated GET is answered at once (before the gate, 3 of them made the page unreachable).
TEST(WebStatus, SlowHeadsDoNotKeepThePageAway) {
  TestDir dir;
  CoordinatorProcess coordinator = WithTokenAndStatusPage(dir);
  const int port = coordinator.http_port();
  ASSERT_GT(port, 0);
  std::vector<std::unique_ptr<RawConnection>> slow;
  const auto open_slow = [&](int n) {
    for (int i = 0; i < n; ++i) {
      slow.push_back(std::make_unique<RawConnection>(port));
      ASSERT_TRUE(slow.back()->connected());
      ASSERT_TRUE(slow.back()->Send("GET / HTTP/1.1\r\nHost: x\r\n"));
    }
  };
  const auto page_answers = [&] {
    httplib::Client http("127.0.0.1", port);
    http.set_connection_timeout(2);
    http.set_read_timeout(2);
    const auto start = std::chrono::steady_clock::now();
    const auto r = http.Get("/api/status", {{"Authorization", "Bearer s3cret-token"}});
    EXPECT_TRUE(r) << "no answer within 2 s with " << slow.size() << " slow clients connected";
    if (r) {
      EXPECT_EQ(r->status, 200);
    }
    EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(2));
  };
  open_slow(50);
  for (int round = 0; round < 3; ++round) {
    for (auto& c : slow) c->Send("X-Slow: " + std::to_string(round) + "\r\n");  // one more header line
    page_answers();
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
  }
  open_slow(150);
  page_answers();
  // The longest waiting made room: the first 50 are closed, the newest still wait.
  for (size_t i = 0; i < 50; ++i) EXPECT_TRUE(slow[i]->ClosedByPeer(2)) << "slow client " << i;
  EXPECT_FALSE(slow.back()->ClosedByPeer(0.2));
}

}  // namespace
}  // namespace pf::e2e
