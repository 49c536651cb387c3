// `pf submit --after JOB` against a real coordinator and workers (docs/farm.md "Job
// dependencies"): a job starts only once every job it waits for has succeeded — no task of it is
// leased before — fails, naming the job, when one is cancelled (and its own dependents fail in
// turn), keeps its dependencies across a coordinator kill -9, and a job a live job waits for
// cannot be deleted; an unknown dependency is refused naming the field.
#include <signal.h>

#include <chrono>
#include <thread>

#include "client/farm_client.h"
#include "tests/e2e/harness.h"

namespace pf::e2e {
namespace {
namespace fs = std::filesystem;
namespace v1 = photonfarm::v1;

RunResult Pf(const TestDir& dir, const std::string& address, std::vector<std::string> args) {
  return RunCommand(Concat(Concat({Binaries::Pf()}, args), {"--coordinator", address}), dir.path(), 60);
}

// `pf submit` of the small job with `extra` flags: its id ("" and a failure if pf failed).
std::string SubmitAfter(const TestDir& dir, const std::string& address,
                        const std::vector<std::string>& extra) {
  JobArgs job;
  const RunResult r = Pf(dir, address, Concat(Concat({"submit", Binaries::Scene()}, job.ToFlags()), extra));
  EXPECT_EQ(r.exit_code, 0) << r.err;
  return r.exit_code == 0 ? r.out.substr(0, r.out.find('\n')) : "";
}

TEST(JobDependencies, AJobStartsOnceItsDependenciesSucceededAndFailsWhenOneIsCancelled) {
  TestDir dir;
  auto coordinator = std::make_unique<CoordinatorProcess>(dir / "data", dir.path());
  const int port = coordinator->port();
  const std::string address = coordinator->address();
  FarmClient client(address, "");
  const std::string a = SubmitAfter(dir, address, {});
  const std::string b = SubmitAfter(dir, address, {"--after", a.substr(0, 10)});
  const std::string c = SubmitAfter(dir, address, {"--after", b, "--after", a});
  ASSERT_FALSE(a.empty() || b.empty() || c.empty());
  v1::JobStatus st = client.GetJob(b);
  ASSERT_EQ(st.spec().after_size(), 1);
  EXPECT_EQ(st.spec().after(0), a) << "stored as the whole id";
  ASSERT_EQ(st.waiting_for_size(), 1);
  EXPECT_EQ(st.waiting_for(0), a);
  const RunResult paused = Pf(dir, address, {"pause", b});  // its summary says what it waits for
  EXPECT_NE(paused.out.find("waiting for " + a), std::string::npos) << paused.out;
  ASSERT_EQ(Pf(dir, address, {"resume", b}).exit_code, 0);
  const RunResult listed = Pf(dir, address, {"list"});
  EXPECT_NE(listed.out.find("waiting"), std::string::npos) << listed.out;

  // A cancelled dependency fails its dependents, and theirs.
  const std::string x = SubmitAfter(dir, address, {});
  const std::string e = SubmitAfter(dir, address, {"--after", x});
  const std::string f = SubmitAfter(dir, address, {"--after", e});
  ASSERT_EQ(Pf(dir, address, {"cancel", x}).exit_code, 0);
  st = client.GetJob(e);
  EXPECT_EQ(st.state(), v1::JOB_STATE_FAILED);
  EXPECT_EQ(st.failure_reason(), "job " + x + " it waits for (--after) ended CANCELLED");
  st = client.GetJob(f);
  EXPECT_EQ(st.state(), v1::JOB_STATE_FAILED);
  EXPECT_EQ(st.failure_reason(), "job " + e + " it waits for (--after) ended FAILED");
  st = client.GetJob(SubmitAfter(dir, address, {"--after", e}));
  EXPECT_EQ(st.state(), v1::JOB_STATE_FAILED) << "submitted after its dependency failed";

  // Workers paced at 0.1 s a task: no task of b or c runs before its dependencies succeeded.
  std::vector<fs::path> logs;
  auto workers = StartTwoPatientWorkers(address, dir.path(), &logs, 0.1);
  int early = 0;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  for (bool done = false; !done && std::chrono::steady_clock::now() < deadline;) {
    // Read in reverse order: states only move forward, so a dependency read later is never
    // behind the job that waits for it.
    const v1::JobStatus sc = client.GetJob(c), sb = client.GetJob(b), sa = client.GetJob(a);
    if (sa.state() != v1::JOB_STATE_SUCCEEDED && (sb.tasks_running() + sb.tasks_done() > 0)) ++early;
    if (sb.state() != v1::JOB_STATE_SUCCEEDED && (sc.tasks_running() + sc.tasks_done() > 0)) ++early;
    done = sc.state() != v1::JOB_STATE_QUEUED && sc.state() != v1::JOB_STATE_RUNNING;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  EXPECT_EQ(early, 0) << "a job ran before a job it waits for succeeded";
  for (const std::string& id : {a, b, c})
    EXPECT_EQ(WaitForJob(client, id, 60).state(), v1::JOB_STATE_SUCCEEDED);

  // A dependency of a live job stays: a restart must find it.
  for (auto& w : workers) w->Signal(SIGTERM);
  for (auto& w : workers) ASSERT_TRUE(w->Wait(20).has_value());
  const std::string h = SubmitAfter(dir, address, {"--after", a});
  EXPECT_EQ(client.GetJob(h).waiting_for_size(), 0) << "its dependency had succeeded";
  RunResult r = Pf(dir, address, {"delete", a});
  EXPECT_EQ(r.exit_code, 1) << r.err;
  EXPECT_NE(r.err.find("is a dependency (--after) of job '" + h + "'"), std::string::npos) << r.err;
  coordinator->process().Signal(SIGKILL);
  coordinator->process().Wait(5);
  coordinator =
      std::make_unique<CoordinatorProcess>(dir / "data", dir.path(), std::vector<std::string>{}, port);
  FarmClient again(address, "");  // the old channel saw the coordinator die
  st = again.GetJob(h);
  EXPECT_EQ(st.state(), v1::JOB_STATE_QUEUED) << st.failure_reason();
  EXPECT_EQ(again.GetJob(e).state(), v1::JOB_STATE_FAILED);
  auto worker = StartWorker(address, dir.path(), "w3");
  EXPECT_EQ(WaitForJob(again, h, 60).state(), v1::JOB_STATE_SUCCEEDED);
  EXPECT_EQ(Pf(dir, address, {"delete", a}).exit_code, 0) << "once no live job waits for it";

  r = Pf(dir, address,
         Concat(Concat({"submit", Binaries::Scene()}, JobArgs().ToFlags()), {"--after", "0000"}));
  EXPECT_EQ(r.exit_code, 3) << r.err;
  EXPECT_NE(r.err.find("spec.after[0]: unknown job"), std::string::npos) << r.err;
  worker->Signal(SIGTERM);
  EXPECT_TRUE(worker->Wait(20).has_value());
}

}  // namespace
}  // namespace pf::e2e
