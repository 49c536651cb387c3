// (d) Bad requests through the real client library (FarmClient, the code `pf` runs) and the
// real `pf` binary against a real coordinator: each gets the right status code and a message
// that names the field; a worker that returns a wrong-size or NaN result (the fake worker, which
// speaks WorkerService directly) is rejected and the task is re-run.
#include <signal.h>

#include <fstream>
#include <nlohmann/json.hpp>
#include <optional>

#include "client/farm_client.h"
#include "tests/e2e/harness.h"
#include "tests/util/job_specs.h"

namespace pf::e2e {
namespace {
namespace fs = std::filesystem;
namespace v1 = photonfarm::v1;

v1::JobSpec ValidSpec(const std::string& hash) {
  v1::JobSpec s = test_util::CornellPhotonMapSpec(hash, 32, 32, /*rounds=*/1, /*seed=*/1);
  s.set_name("validation");
  return s;
}

// The status of a call that must fail.
grpc::Status Failure(const std::function<void()>& call) {
  try {
    call();
  } catch (const RpcError& e) {
    return e.status();
  }
  return grpc::Status::OK;
}

#define EXPECT_REJECTED(call, code, field)                                                       \
  do {                                                                                           \
    const grpc::Status st_ = Failure([&] { call; });                                             \
    EXPECT_EQ(st_.error_code(), grpc::StatusCode::code) << #call << ": " << StatusToString(st_); \
    EXPECT_NE(st_.error_message().find(field), std::string::npos)                                \
        << #call << ": message does not name '" << field << "': " << st_.error_message();        \
  } while (0)

TEST(FarmValidation, BadJobsAreRejectedNamingTheField) {
  TestDir dir;
  CoordinatorProcess coordinator(dir / "data", dir.path());
  FarmClient client(coordinator.address(), "");
  const std::string hash = client.UploadScene(CollectBundle(Binaries::Scene())).scene_hash();
  ASSERT_EQ(hash.size(), 64u);
  EXPECT_FALSE(client.SubmitJob(ValidSpec(hash)).empty());  // the baseline is valid

  v1::JobSpec s = ValidSpec(hash);
  s.mutable_settings()->mutable_photon_map()->set_photons(0);
  EXPECT_REJECTED(client.SubmitJob(s), INVALID_ARGUMENT, "photons");
  s.mutable_settings()->mutable_photon_map()->set_photons(uint64_t(-1));  // "negative", as uint64
  EXPECT_REJECTED(client.SubmitJob(s), RESOURCE_EXHAUSTED, "photons");

  s = ValidSpec(hash);
  s.mutable_settings()->mutable_photon_map()->set_k(0);
  EXPECT_REJECTED(client.SubmitJob(s), INVALID_ARGUMENT, "k");
  s = ValidSpec(hash);
  s.mutable_settings()->set_integrator(v1::INTEGRATOR_UNSPECIFIED);
  EXPECT_REJECTED(client.SubmitJob(s), INVALID_ARGUMENT, "integrator");

  s = ValidSpec(hash);
  s.mutable_camera()->set_width(0);
  s.mutable_camera()->set_height(0);
  EXPECT_REJECTED(client.SubmitJob(s), INVALID_ARGUMENT, "camera.width");
  s.mutable_camera()->set_width(100000);
  s.mutable_camera()->set_height(100000);
  EXPECT_REJECTED(client.SubmitJob(s), RESOURCE_EXHAUSTED, "camera.width");
  s = ValidSpec(hash);
  s.mutable_camera()->set_vfov_degrees(0);
  EXPECT_REJECTED(client.SubmitJob(s), INVALID_ARGUMENT, "vfov_degrees");

  s = ValidSpec(std::string(64, 'a'));
  EXPECT_REJECTED(client.SubmitJob(s), NOT_FOUND, "scene_hash");
  s = ValidSpec("not-a-hash");
  EXPECT_REJECTED(client.SubmitJob(s), INVALID_ARGUMENT, "scene_hash");

  s = ValidSpec(hash);
  s.mutable_plan()->mutable_skipping()->set_stride(0);
  EXPECT_REJECTED(client.SubmitJob(s), INVALID_ARGUMENT, "plan.skipping.stride");
  s.mutable_plan()->mutable_skipping()->set_stride(100);  // S² = 10000 > 32·32 pixels
  EXPECT_REJECTED(client.SubmitJob(s), INVALID_ARGUMENT, "plan.skipping.stride");
  s = ValidSpec(hash);
  s.mutable_plan()->mutable_skipping()->set_rounds(0);
  EXPECT_REJECTED(client.SubmitJob(s), INVALID_ARGUMENT, "plan.skipping.rounds");
  s = ValidSpec(hash);
  s.mutable_plan()->Clear();
  EXPECT_REJECTED(client.SubmitJob(s), INVALID_ARGUMENT, "plan");
  s = ValidSpec(hash);
  s.mutable_stop()->set_time_budget_seconds(-1);
  EXPECT_REJECTED(client.SubmitJob(s), INVALID_ARGUMENT, "time_budget_seconds");

  EXPECT_REJECTED(client.GetJob("job-999999"), NOT_FOUND, "job_id");
  EXPECT_REJECTED(client.GetImage("job-999999"), NOT_FOUND, "job_id");

  // A malformed scene: file:line.
  SceneBundle bad;
  bad.entry = "bad.mgf";
  bad.files = {{"bad.mgf", "# a broken MGF file\nv p1 =\n\tp 0 0\n"}};
  EXPECT_REJECTED(client.UploadScene(bad), INVALID_ARGUMENT, "bad.mgf:3");
  // A scene without any light would render black: refused on upload, saying why.
  SceneBundle dark;
  dark.entry = "dark.obj";
  dark.files = {{"dark.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"}};
  EXPECT_REJECTED(client.UploadScene(dark), INVALID_ARGUMENT, "dark.obj: the scene has no light");

  // The same through the pf binary: exit 3 and the field on stderr; usage errors exit 2.
  const std::vector<std::string> base = {
      Binaries::Pf(),        "submit",       Binaries::Scene(), "--coordinator",
      coordinator.address(), "--integrator", "photonmap"};
  RunResult r =
      RunCommand(Concat(base, {"--res", "32x32", "--plan", "skipping", "--stride", "100"}), dir.path());
  EXPECT_EQ(r.exit_code, 3) << r.err;
  EXPECT_NE(r.err.find("plan.skipping.stride"), std::string::npos) << r.err;
  r = RunCommand(Concat(base, {"--photons", "-5"}), dir.path());
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("--photons"), std::string::npos) << r.err;
  r = RunCommand(Concat(base, {"--res", "0x0"}), dir.path());
  EXPECT_EQ(r.exit_code, 3) << r.err;
  EXPECT_NE(r.err.find("--res"), std::string::npos) << r.err;
  r = RunCommand({Binaries::Pf(), "get", "job-424242", "-o", (dir / "x.exr").string(), "--coordinator",
                  coordinator.address()},
                 dir.path());
  EXPECT_EQ(r.exit_code, 3) << r.err;
  EXPECT_NE(r.err.find("NOT_FOUND"), std::string::npos) << r.err;
}

TEST(FarmValidation, WrongTokenIsUnauthenticated) {
  TestDir dir;
  { std::ofstream(dir / "token") << "s3cret-token\n"; }
  { std::ofstream(dir / "worker-token") << "w0rker-token\n"; }
  CoordinatorProcess coordinator(dir / "data", dir.path(),
                                 {"--worker-token-file", (dir / "worker-token").string()}, 0,
                                 (dir / "token").string());
  FarmClient right(coordinator.address(), "s3cret-token");
  EXPECT_TRUE(right.ListJobs(true).empty());
  FarmClient wrong(coordinator.address(), "guess");
  EXPECT_REJECTED(wrong.ListJobs(true), UNAUTHENTICATED, "");
  FarmClient none(coordinator.address(), "");
  EXPECT_REJECTED(none.UploadScene(CollectBundle(Binaries::Scene())), UNAUTHENTICATED, "");

  // pf: exit 1 with the code on stderr; the right token through PF_TOKEN works.
  RunResult r = RunCommand({Binaries::Pf(), "list", "--coordinator", coordinator.address()}, dir.path(), 30,
                           {{"PF_TOKEN", "guess"}});
  EXPECT_EQ(r.exit_code, 1) << r.err;
  EXPECT_NE(r.err.find("UNAUTHENTICATED"), std::string::npos) << r.err;
  r = RunCommand({Binaries::Pf(), "list", "--coordinator", coordinator.address()}, dir.path(), 30,
                 {{"PF_TOKEN", "s3cret-token"}});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  // PF_TOKEN_FILE (the deployment recipes' worker.env and client.env) wins over PF_TOKEN; a file it
  // names that cannot be read is an error naming the variable.
  r = RunCommand({Binaries::Pf(), "list", "--coordinator", coordinator.address()}, dir.path(), 30,
                 {{"PF_TOKEN", "guess"}, {"PF_TOKEN_FILE", (dir / "token").string()}});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  r = RunCommand({Binaries::Pf(), "list", "--coordinator", coordinator.address()}, dir.path(), 30,
                 {{"PF_TOKEN_FILE", (dir / "no-such-token").string()}});
  EXPECT_EQ(r.exit_code, 3) << r.err;
  EXPECT_NE(r.err.find("$PF_TOKEN_FILE"), std::string::npos) << r.err;

  // A worker with the wrong token gets nothing, says why, and keeps trying (the operator may fix
  // the token file and restart it; it does not crash-loop); an empty token file is a usage error.
  { std::ofstream(dir / "wrong-token") << "guess\n"; }
  auto worker = StartWorker(coordinator.address(), dir.path(), "w-wrong",
                            {"--token-file", (dir / "wrong-token").string()});
  EXPECT_TRUE(WaitUntil([&] { return !Grep(worker->log(), "UNAUTHENTICATED").empty(); }, 10))
      << ReadFile(worker->log());
  EXPECT_TRUE(worker->Running());
  // ... and the coordinator lists it as refused, with the reason and a count, under its address
  // and the id it announced.
  const auto refused = [&]() -> std::optional<v1::WorkerInfo> {
    for (const v1::WorkerInfo& w : right.ListWorkers())
      if (w.worker_id() == "w-wrong" && w.refused()) return w;
    return std::nullopt;
  };
  EXPECT_TRUE(WaitUntil([&] { return refused().has_value(); }, 10));
  if (const std::optional<v1::WorkerInfo> w = refused()) {
    EXPECT_EQ(w->refused_reason(), "UNAUTHENTICATED: authorization: invalid bearer token");
    EXPECT_GE(w->refused_calls(), 1u);
    EXPECT_EQ(w->peer(), "127.0.0.1");
  }
  r = RunCommand({Binaries::Pf(), "workers", "--coordinator", coordinator.address()}, dir.path(), 30,
                 {{"PF_TOKEN", "s3cret-token"}});
  EXPECT_NE(r.out.find("refused: UNAUTHENTICATED: authorization: invalid bearer token"), std::string::npos)
      << r.out;
  worker->Signal(SIGTERM);
  EXPECT_EQ(worker->Wait(10).value_or(-1), 0);
  auto empty_token = StartWorker(coordinator.address(), dir.path(), "w-empty", {"--token-file", "/dev/null"});
  EXPECT_EQ(empty_token->Wait(10).value_or(-1), 2) << ReadFile(empty_token->log());
  r = RunCommand(
      {Binaries::FakeWorker(), "--coordinator", coordinator.address(), "--mode", "nan", "--wait", "0.2"},
      dir.path(), 30, {{"PF_TOKEN", "guess"}});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.out.find("UNAUTHENTICATED"), std::string::npos) << r.out << r.err;
}

TEST(FarmValidation, WrongSizeAndNanResultsAreRejectedAndRerun) {
  TestDir dir;
  JobArgs job;
  job.rounds = 1;  // 4 tasks
  const RunResult local = RenderLocally(dir, job.ToFlags());
  ASSERT_EQ(local.exit_code, 0) << local.err;
  CoordinatorProcess coordinator(dir / "data", dir.path(), {"--max-attempts", "6"});
  RunResult r = RunCommand(Concat(Concat({Binaries::Pf(), "submit", Binaries::Scene()}, job.ToFlags()),
                                  {"--coordinator", coordinator.address()}),
                           dir.path());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::string job_id = r.out.substr(0, r.out.find('\n'));

  std::vector<uint64_t> rejected_tasks;
  // -1e9 and 1e9 are finite and within the accumulator's range, so they used to be
  // merged (the job succeeded with a mean of -125); now negative values are invalid and 1e9 is
  // above the job's bound (1024 x the brightest emitter per sample).
  for (const char* mode : {"bad-size", "nan", "negative", "huge"}) {
    r = RunCommand({Binaries::FakeWorker(), "--coordinator", coordinator.address(), "--mode", mode},
                   dir.path());
    ASSERT_EQ(r.exit_code, 0) << mode << ": " << r.out << r.err;
    const nlohmann::json j = nlohmann::json::parse(r.out);
    EXPECT_EQ(j["code"], "INVALID_ARGUMENT") << mode;
    EXPECT_NE(j["message"].get<std::string>().find("rgb_sums"), std::string::npos) << j.dump();
    if (std::string(mode) == "negative") {
      EXPECT_NE(j["message"].get<std::string>().find("is negative"), std::string::npos) << j.dump();
    }
    if (std::string(mode) == "huge") {
      EXPECT_NE(j["message"].get<std::string>().find("exceeds the job's bound"), std::string::npos)
          << j.dump();
    }
    EXPECT_FALSE(j["merged"].get<bool>());
    rejected_tasks.push_back(j["task_id"].get<uint64_t>());
  }
  FarmClient client(coordinator.address(), "");
  EXPECT_EQ(client.GetJob(job_id).tasks_done(), 0u);
  // Each rejection is visible to people: `pf events` lists it with its reason.
  r = RunCommand({Binaries::Pf(), "events", job_id, "--coordinator", coordinator.address()}, dir.path());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  size_t rejections = 0;
  for (size_t at = r.out.find(" rejected "); at != std::string::npos; at = r.out.find(" rejected ", at + 1))
    ++rejections;
  EXPECT_EQ(rejections, 4u) << r.out;
  EXPECT_NE(r.out.find("is negative"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("exceeds the job's bound"), std::string::npos) << r.out;

  auto worker = StartWorker(coordinator.address(), dir.path(), "w1");
  v1::JobStatus st;
  ASSERT_TRUE(WaitUntil([&] { return IsFinalState((st = client.GetJob(job_id)).state()); }, 60));
  ASSERT_EQ(st.state(), v1::JOB_STATE_SUCCEEDED) << st.failure_reason();
  // The rejected tasks were re-run by the real worker (attempt > 1) and merged once.
  for (uint64_t t : rejected_tasks)
    EXPECT_FALSE(Grep(worker->log(),
                      "completed job=" + job_id + " task=" + std::to_string(t) + " attempt=[2-9] merged=true")
                     .empty())
        << "task " << t << "\n"
        << ReadFile(worker->log());
  EXPECT_EQ(st.samples_merged(), uint64_t(job.res) * job.res * job.spp * job.rounds);
  EXPECT_TRUE(BitIdentical(DecodeImage(client.GetImage(job_id)), ReadImage(dir / "local.exr")));
  worker->Signal(SIGTERM);
  EXPECT_EQ(worker->Wait(20).value_or(-1), 0);
}

}  // namespace
}  // namespace pf::e2e
