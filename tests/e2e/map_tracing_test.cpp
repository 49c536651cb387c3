// Photon maps traced once (docs/farm.md "Photon maps traced once"), real processes:
//  - images bit-identical for 1, 2, 3 workers and `pf render --local-only`, with the maps traced in
//    pieces and fetched (the default for a tiled map) and with every worker tracing its own;
//  - a worker SIGKILLed while tracing a piece, while uploading it and while fetching the built
//    map: the work is redone elsewhere and the image is bit-identical;
//  - a map part whose checksum fails is refused and the map fetched again;
//  - a coordinator SIGKILLed with some pieces stored resumes with only the missing ones traced,
//    and one SIGKILLed after the map was built serves it from disk without tracing anything.
// The kill points are made deterministic by the faulty worker's PF_TEST_PAUSE_AT (it sleeps
// there, logging "test-pause at ..."; tests/e2e/faulty_worker.cpp); PF_TEST_CORRUPT_MAP_PART
// corrupts one received part.
#include <signal.h>

#include <algorithm>
#include <thread>

#include "client/farm_client.h"
#include "photonfarm/v1/farm.grpc.pb.h"
#include "photonfarm_version.h"
#include "rpc/grpc_channel.h"
#include "tests/e2e/harness.h"

namespace pf::e2e {
namespace {
namespace fs = std::filesystem;
namespace v1 = photonfarm::v1;

// One map of 40000 photons (three pieces of 16384 with --map-chunk-photons 16384) over 6 tiles.
std::vector<std::string> TiledJobFlags() {
  return {"--integrator", "photonmap",     "--photons", "40000", "--k",    "20",
          "--plan",       "multiple-maps", "--maps",    "1",     "--tile", "16",
          "--res",        "48x32",         "--spp",     "1",     "--seed", "9"};
}

Image LocalReference(const TestDir& dir) {
  const RunResult r = RenderLocally(dir, TiledJobFlags());
  EXPECT_EQ(r.exit_code, 0) << r.err;
  return ReadImage(dir / "local.exr");
}

std::string Submit(const TestDir& dir, const std::string& address,
                   const std::vector<std::string>& more = {}) {
  return SubmitJob(dir, address, Concat(TiledJobFlags(), more));
}

// Waits for the job to succeed (its status in *st) and checks its image against the local render.
void ExpectSucceedsBitIdentical(const std::string& address, const std::string& job_id, const Image& reference,
                                v1::JobStatus* st) {
  FarmClient client(address, "");
  *st = WaitForJob(client, job_id, 120);
  ASSERT_EQ(st->state(), v1::JOB_STATE_SUCCEEDED) << st->failure_reason();
  EXPECT_TRUE(BitIdentical(DecodeImage(client.GetImage(job_id)), reference));
}

size_t Count(const fs::path& log, const std::string& re) {
  return Grep(log, re).size();
}

TEST(MapTracingFarm, BitIdenticalForOneTwoThreeWorkersLocalTracedOnceOrByEachWorker) {
  TestDir dir;
  const Image reference = LocalReference(dir);
  ASSERT_GT(PixelSum(reference), 0.0);
  struct Run {
    int workers;
    std::string tracing;
  };
  for (const Run& run : {Run{1, "auto"}, Run{2, "auto"}, Run{3, "distributed"}, Run{2, "local"}}) {
    SCOPED_TRACE(std::to_string(run.workers) + " workers, --map-tracing " + run.tracing);
    const fs::path data = dir / ("data-" + std::to_string(run.workers) + run.tracing);
    CoordinatorProcess coordinator(data, dir.path(), {"--map-chunk-photons", "16384"});
    const std::string job_id = Submit(dir, coordinator.address(), {"--map-tracing", run.tracing});
    ASSERT_FALSE(job_id.empty());
    std::vector<std::unique_ptr<Process>> workers;
    std::vector<fs::path> logs;
    for (int w = 0; w < run.workers; ++w) {
      const std::string id = run.tracing + std::to_string(run.workers) + "-w" + std::to_string(w);
      workers.push_back(StartWorker(coordinator.address(), dir.path(), id));
      logs.push_back(dir / (id + ".log"));
    }
    v1::JobStatus st;
    ASSERT_NO_FATAL_FAILURE(ExpectSucceedsBitIdentical(coordinator.address(), job_id, reference, &st));
    size_t pieces = 0, fetched = 0, decisions = 0;
    for (const fs::path& log : logs) {
      pieces += Count(log, "uploaded-piece .* accepted=true");
      fetched += Count(log, "map [0-9a-f]+ for .* fetched: ");
      decisions += Count(log, "map [0-9a-f]+ for job=.*: (fetch|trace): fetch [0-9]+ bytes");
    }
    const fs::path clog = coordinator.process().log();
    if (run.tracing == "local") {
      EXPECT_EQ(pieces, 0u);
      EXPECT_EQ(fetched, 0u);
      EXPECT_EQ(Count(clog, "built once"), 0u);
    } else {
      EXPECT_EQ(pieces, 3u) << "40000 photons in pieces of 16384, each traced once";
      EXPECT_EQ(Count(clog, "built once from 3 pieces"), 1u) << ReadFile(clog);
      // A worker that renders decides once per map (and logs the numbers), then fetches it once.
      EXPECT_EQ(decisions, fetched);
      EXPECT_GE(fetched, 1u);
      EXPECT_LE(fetched, size_t(run.workers));
      // The maps are on the coordinator's disk (with the record of who traced them, .by), the pieces gone.
      std::vector<std::string> files;
      for (const fs::directory_entry& e : fs::directory_iterator(data / "maps"))
        files.push_back(e.path().extension().string());
      std::sort(files.begin(), files.end());
      EXPECT_EQ(files, (std::vector<std::string>{".by", ".pfmaps"}));
    }
    for (auto& w : workers) w->Signal(SIGTERM);
    for (auto& w : workers) EXPECT_TRUE(w->Wait(20).has_value());
  }
}

// The tiled job submitted to a coordinator with 1.5 s leases and five attempts, its map traced in
// pieces of 16384 photons, beside the job's local render: the farm of the kill and pause tests.
struct ShortLeaseFarm {
  TestDir dir;
  Image reference = LocalReference(dir);
  CoordinatorProcess coordinator{
      dir / "data",
      dir.path(),
      {"--lease-seconds", "1.5", "--max-attempts", "5", "--map-chunk-photons", "16384"}};
  std::string job_id = Submit(dir, coordinator.address());
};

// A worker paused at `where` (PF_TEST_PAUSE_AT) is SIGKILLed there; a second worker finishes.
void KillWhile(const std::string& where) {
  ShortLeaseFarm farm;
  auto victim =
      StartFaultyWorker(farm.coordinator.address(), farm.dir.path(), "victim", {{"PF_TEST_PAUSE_AT", where}});
  ASSERT_TRUE(WaitUntil([&] { return Count(victim->log(), "test-pause at " + where) > 0; }, 60))
      << ReadFile(victim->log());
  victim->Signal(SIGKILL);
  victim->Wait(5);
  auto survivor = StartWorker(farm.coordinator.address(), farm.dir.path(), "survivor");
  v1::JobStatus st;
  ASSERT_NO_FATAL_FAILURE(
      ExpectSucceedsBitIdentical(farm.coordinator.address(), farm.job_id, farm.reference, &st));
  EXPECT_EQ(st.tasks_done(), st.tasks_total());
  EXPECT_EQ(st.samples_merged(), uint64_t(48 * 32));
  const fs::path clog = farm.coordinator.process().log();
  EXPECT_EQ(Count(clog, "built once from 3 pieces"), 1u) << ReadFile(clog);
  if (where == "fetch") {
    // The victim held a render lease: it ran out and the task ran again, merged once.
    EXPECT_GE(Count(clog, "task [0-9]+: leased to .?survivor.? \\(attempt 2"), 1u) << ReadFile(clog);
    EXPECT_EQ(Count(survivor->log(), "fetched: "), 1u);
  } else {
    // The victim's piece ran out and was traced again by the survivor.
    EXPECT_GE(Count(clog, "piece [0-9]+: attempt 1 ended: lease expired \\(worker victim\\)"), 1u)
        << ReadFile(clog);
    EXPECT_GE(Count(clog, "piece [0-9]+/3: leased to .?survivor.? .*attempt 2"), 1u) << ReadFile(clog);
    EXPECT_EQ(Count(survivor->log(), "uploaded-piece .* accepted=true"), 3u);
  }
  for (uint64_t t = 0; t < st.tasks_total(); ++t)
    EXPECT_EQ(Count(clog, "job " + farm.job_id + " task " + std::to_string(t) + ": merged "), 1u)
        << "task " << t;
  survivor->Signal(SIGTERM);
  EXPECT_TRUE(survivor->Wait(20).has_value());
}

TEST(MapTracingFarm, WorkerKilledWhileTracingAPieceIsRedone) {
  KillWhile("trace");
}
TEST(MapTracingFarm, WorkerKilledWhileUploadingAPieceIsRedone) {
  KillWhile("upload");
}
TEST(MapTracingFarm, WorkerKilledWhileFetchingTheMapIsRedone) {
  KillWhile("fetch");
}

// A slow step that is not the render (here: a 4 s pause in a piece's trace, or before the map's
// fetch, with leases of 1.5 s) keeps its lease: the worker heartbeats from lease to report, so
// nothing expires, nothing runs twice, and the one worker finishes the job at attempt 1 (before,
// only the render was covered and these leases ran out mid-fetch).
void SlowStepKeepsItsLease(const std::string& where) {
  ShortLeaseFarm farm;
  auto worker = StartFaultyWorker(farm.coordinator.address(), farm.dir.path(), "slow",
                                  {{"PF_TEST_PAUSE_AT", where}, {"PF_TEST_PAUSE_SECONDS", "4"}});
  v1::JobStatus st;
  ASSERT_NO_FATAL_FAILURE(
      ExpectSucceedsBitIdentical(farm.coordinator.address(), farm.job_id, farm.reference, &st));
  const fs::path clog = farm.coordinator.process().log();
  ASSERT_GE(Count(worker->log(), "test-pause over at " + where), 1u) << ReadFile(worker->log());
  EXPECT_EQ(Count(clog, "expired"), 0u) << ReadFile(clog);
  EXPECT_EQ(Count(clog, "attempt 2"), 0u) << ReadFile(clog);
  EXPECT_EQ(Count(worker->log(), "abandoned"), 0u) << ReadFile(worker->log());
  EXPECT_EQ(st.samples_merged(), uint64_t(48 * 32));
  worker->Signal(SIGTERM);
  EXPECT_TRUE(worker->Wait(20).has_value());
}

TEST(MapTracingFarm, SlowPieceTraceKeepsItsLease) {
  SlowStepKeepsItsLease("trace");
}
TEST(MapTracingFarm, SlowMapFetchKeepsItsLease) {
  SlowStepKeepsItsLease("fetch");
}

// UploadPhotonChunk admits a stream on its first part, before buffering anything: a lease that is
// not a live piece lease answers at once (accepted = false) whatever size it declares, and a live
// lease takes one stream at a time (a second is ALREADY_EXISTS until the first is over). So the
// coordinator buffers at most one piece per live piece lease.
TEST(MapTracingFarm, UploadsAreAdmittedOnlyForALivePieceLeaseOneAtATime) {
  TestDir dir;
  CoordinatorProcess coordinator(dir / "data", dir.path(), {"--map-chunk-photons", "16384"});
  Submit(dir, coordinator.address());
  const std::shared_ptr<grpc::Channel> channel = MakeCoordinatorChannel(coordinator.address(), {});
  const std::unique_ptr<v1::WorkerService::Stub> stub = v1::WorkerService::NewStub(channel);
  v1::LeaseTaskRequest lease_req;
  lease_req.set_worker_id("raw");
  lease_req.set_worker_version(PF_VERSION);
  lease_req.set_threads(1);
  lease_req.set_wait_seconds(5);
  v1::LeaseTaskResponse lease_resp;
  {
    grpc::ClientContext ctx;
    PrepareContext(&ctx, "", Seconds(20));
    ASSERT_TRUE(stub->LeaseTask(&ctx, lease_req, &lease_resp).ok());
  }
  ASSERT_TRUE(lease_resp.has_task() && lease_resp.task().has_trace_chunk()) << "pieces are leased first";
  const std::string lease = lease_resp.task().lease_id();

  struct Upload {
    grpc::ClientContext ctx;
    v1::UploadPhotonChunkResponse response;
    std::unique_ptr<grpc::ClientWriter<v1::PhotonChunkPart>> writer;
  };
  auto open = [&](const std::string& lease_id, uint64_t total) {
    auto u = std::make_unique<Upload>();
    PrepareContext(&u->ctx, "", Seconds(20));
    u->writer = stub->UploadPhotonChunk(&u->ctx, &u->response);
    v1::PhotonChunkPart part;
    part.set_lease_id(lease_id);
    part.set_worker_id("raw");
    part.set_total_bytes(total);
    part.set_digest(std::string(64, '0'));
    part.set_offset(0);
    part.set_data("x");
    part.set_sha256(std::string(64, '0'));
    u->writer->Write(part);  // may fail if the server already finished: Finish says why
    return u;
  };
  auto finish = [](Upload& u) {
    u.writer->WritesDone();
    return u.writer->Finish();
  };

  // A well-formed id of no live lease, declaring 512 MiB: answered at once, nothing stored.
  auto forged = open("map-0123456789abcdef", uint64_t(512) << 20);
  const grpc::Status forged_status = finish(*forged);
  EXPECT_TRUE(forged_status.ok()) << forged_status.error_message();
  EXPECT_FALSE(forged->response.accepted());

  // The live lease: one stream admitted, a second refused while the first is open.
  auto first = open(lease, 1000);
  std::this_thread::sleep_for(std::chrono::milliseconds(300));  // its first part is read and admitted
  ASSERT_TRUE(WaitUntil(
      [&] {
        auto second = open(lease, 1000);
        const grpc::Status st = finish(*second);
        return st.error_code() == grpc::StatusCode::ALREADY_EXISTS;
      },
      10))
      << "a second upload for the same lease while the first is open";
  const grpc::Status first_status = finish(*first);  // 1 byte of 1000: refused, and the stream is over
  EXPECT_EQ(first_status.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << first_status.error_message();
  // Over: the lease takes a stream again (these bytes are no piece: INVALID_ARGUMENT, not ALREADY_EXISTS).
  auto third = open(lease, 1);
  const grpc::Status third_status = finish(*third);
  EXPECT_EQ(third_status.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << third_status.error_message();
}

TEST(MapTracingFarm, CorruptMapPartIsRefusedAndFetchedAgain) {
  TestDir dir;
  const Image reference = LocalReference(dir);
  CoordinatorProcess coordinator(dir / "data", dir.path(), {"--map-chunk-photons", "16384"});
  const std::string job_id = Submit(dir, coordinator.address());
  auto worker =
      StartFaultyWorker(coordinator.address(), dir.path(), "w", {{"PF_TEST_CORRUPT_MAP_PART", "1"}});
  v1::JobStatus st;
  ASSERT_NO_FATAL_FAILURE(ExpectSucceedsBitIdentical(coordinator.address(), job_id, reference, &st));
  const fs::path log = worker->log();
  EXPECT_EQ(Count(log, "corrupted on arrival"), 1u) << ReadFile(log);
  EXPECT_EQ(Count(log, "part 0: checksum mismatch: refused \\(attempt 1 of 3\\): fetching again"), 1u)
      << ReadFile(log);
  EXPECT_EQ(Count(log, "fetched: .*\\(attempt 2\\)"), 1u) << ReadFile(log);
  EXPECT_EQ(Count(log, "traced here instead"), 0u);
  // The map went to the worker's disk cache, whole.
  EXPECT_EQ(std::distance(fs::directory_iterator(dir / "cache-w" / "maps"), fs::directory_iterator{}), 1);
  worker->Signal(SIGTERM);
  EXPECT_TRUE(worker->Wait(20).has_value());
}

// --map-tracing is a farm setting (usage error elsewhere); distributed needs the kd-tree (the only
// map with a byte form): INVALID_ARGUMENT naming the field, pf exit 3.
TEST(MapTracingFarm, MapTracingFlagIsCheckedWhereItMeansSomething) {
  TestDir dir;
  const RunResult plain =
      RunCommand(Concat(Concat({Binaries::Pf(), "render", Binaries::Scene()}, TiledJobFlags()),
                        {"--map-tracing", "local", "-o", (dir / "x.exr").string()}),
                 dir.path());
  EXPECT_EQ(plain.exit_code, 2) << plain.err;
  EXPECT_NE(plain.err.find("--map-tracing"), std::string::npos) << plain.err;
  CoordinatorProcess coordinator(dir / "data", dir.path());
  const RunResult grid = RunCommand(
      Concat(Concat({Binaries::Pf(), "submit", Binaries::Scene()}, TiledJobFlags()),
             {"--map-tracing", "distributed", "--map", "grid", "--coordinator", coordinator.address()}),
      dir.path());
  EXPECT_EQ(grid.exit_code, 3) << grid.err;
  EXPECT_NE(grid.err.find("photon_map.map_tracing: distributed tracing needs the kd-tree"), std::string::npos)
      << grid.err;
  // A grid job with auto tracing runs, each worker tracing its maps.
  const std::string id = Submit(dir, coordinator.address(), {"--map", "grid"});
  auto worker = StartWorker(coordinator.address(), dir.path(), "w");
  FarmClient client(coordinator.address(), "");
  EXPECT_EQ(WaitForJob(client, id, 120).state(), v1::JOB_STATE_SUCCEEDED);
  EXPECT_EQ(Count(worker->log(), "leased-piece"), 0u);
  worker->Signal(SIGTERM);
  EXPECT_TRUE(worker->Wait(20).has_value());
}

// A crash of a coordinator's life and its worker: both SIGKILLed (the coordinator first) and reaped.
void KillCoordinatorAndWorker(std::unique_ptr<CoordinatorProcess>& life, std::unique_ptr<Process>& worker) {
  life->process().Signal(SIGKILL);
  life->process().Wait(5);
  life.reset();
  worker->Signal(SIGKILL);
  worker->Wait(5);
}

TEST(MapTracingFarm, RestartedCoordinatorResumesPiecesAndBuiltMaps) {
  TestDir dir;
  const Image reference = LocalReference(dir);
  const std::vector<std::string> args = {"--lease-seconds", "1.5", "--map-chunk-photons", "16384"};
  auto [life1, port, address, job_id] = StartCoordinatorWithJob(dir, args, TiledJobFlags());
  // Life 1: pieces 0 and 1 stored, then the coordinator dies (its worker too, paused before piece 2).
  auto w1 = StartFaultyWorker(address, dir.path(), "w1", {{"PF_TEST_PAUSE_AT", "upload:piece=2/"}});
  ASSERT_TRUE(WaitUntil([&] { return Count(w1->log(), "test-pause at upload") > 0; }, 60))
      << ReadFile(w1->log());
  const fs::path log1 = life1->process().log();
  ASSERT_EQ(Count(log1, "piece [0-9]+: stored \\("), 2u) << ReadFile(log1);
  KillCoordinatorAndWorker(life1, w1);

  // Life 2: finds the two pieces, queues only piece 2; the map is built; its worker dies fetching.
  auto life2 = std::make_unique<CoordinatorProcess>(dir / "data", dir.path(), args, port);
  const fs::path log2 = life2->process().log();
  EXPECT_EQ(Count(log2, "in 3 pieces of 16384 \\(2 already traced on disk\\)"), 1u) << ReadFile(log2);
  auto w2 = StartFaultyWorker(address, dir.path(), "w2", {{"PF_TEST_PAUSE_AT", "fetch"}});
  ASSERT_TRUE(WaitUntil([&] { return Count(w2->log(), "test-pause at fetch") > 0; }, 60))
      << ReadFile(w2->log());
  EXPECT_EQ(Count(w2->log(), "uploaded-piece .*piece=2/3 .*accepted=true"), 1u) << ReadFile(w2->log());
  EXPECT_EQ(Count(w2->log(), "uploaded-piece"), 1u);
  EXPECT_EQ(Count(log2, "built once from 3 pieces"), 1u) << ReadFile(log2);
  KillCoordinatorAndWorker(life2, w2);

  // Life 3: serves the built map from disk; nothing is traced again.
  CoordinatorProcess life3(dir / "data", dir.path(), args, port);
  const fs::path log3 = life3.process().log();
  EXPECT_EQ(Count(log3, "built map [0-9a-f]+ found on disk"), 1u) << ReadFile(log3);
  auto w3 = StartWorker(address, dir.path(), "w3");
  v1::JobStatus st;
  ASSERT_NO_FATAL_FAILURE(ExpectSucceedsBitIdentical(address, job_id, reference, &st));
  EXPECT_EQ(st.samples_merged(), uint64_t(48 * 32));
  EXPECT_EQ(Count(w3->log(), "uploaded-piece"), 0u);
  EXPECT_EQ(Count(w3->log(), "fetched: "), 1u);
  EXPECT_EQ(Count(log3, "built once"), 0u);
  w3->Signal(SIGTERM);
  EXPECT_TRUE(w3->Wait(20).has_value());
}

// Pieces on disk are named by photon range: a coordinator restarted with another piece size
// (--map-chunk-photons 16384 -> 8192) reuses none of them (the same index is another range now)
// and traces the map anew; the image is the same. Named by index, life 2 counted 2 of its 5 pieces
// as traced, and the map's assembly found photons missing.
TEST(MapTracingFarm, RestartWithAnotherPieceSizeTracesThePiecesAnew) {
  TestDir dir;
  const Image reference = LocalReference(dir);
  auto [life1, port, address, job_id] = StartCoordinatorWithJob(
      dir, {"--lease-seconds", "1.5", "--map-chunk-photons", "16384"}, TiledJobFlags());
  auto w1 = StartFaultyWorker(address, dir.path(), "w1", {{"PF_TEST_PAUSE_AT", "upload:piece=2/"}});
  ASSERT_TRUE(WaitUntil([&] { return Count(w1->log(), "test-pause at upload") > 0; }, 60))
      << ReadFile(w1->log());
  ASSERT_EQ(Count(life1->process().log(), "piece [0-9]+: stored \\("), 2u)
      << ReadFile(life1->process().log());
  KillCoordinatorAndWorker(life1, w1);

  CoordinatorProcess life2(dir / "data", dir.path(),
                           {"--lease-seconds", "1.5", "--map-chunk-photons", "8192"}, port);
  const fs::path log2 = life2.process().log();
  EXPECT_EQ(Count(log2, "in 5 pieces of 8192 \\(0 already traced on disk\\)"), 1u) << ReadFile(log2);
  auto w2 = StartWorker(address, dir.path(), "w2");
  v1::JobStatus st;
  ASSERT_NO_FATAL_FAILURE(ExpectSucceedsBitIdentical(address, job_id, reference, &st));
  EXPECT_EQ(Count(w2->log(), "uploaded-piece .* accepted=true"), 5u) << ReadFile(w2->log());
  w2->Signal(SIGTERM);
  EXPECT_TRUE(w2->Wait(20).has_value());
}

}  // namespace
}  // namespace pf::e2e
