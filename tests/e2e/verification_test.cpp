// Result verification with real processes (docs/farm.md "Result verification"): a farm of two
// honest pf-workers and one malicious worker — pf_fake_worker running pf-worker's own loop, which
// renders (or traces) honestly and then multiplies its results by 1.5, 1000 or 0, or moves the
// photons of its map pieces past the first 4096 the coordinator always checks and sends them with
// fresh checksums. The hostile test this answers: such results SUCCEEDED with no event, and the
// poisoned map was stored and reused. Now, with verification on (every result, or every piece, so
// that the outcome is certain), the malicious worker is convicted ("convicted" event, blocklisted
// for the job), the job starts again without it and SUCCEEDS with an image bit-identical to the
// local render. A lease hijack (a leaked lease id presented by another worker) is refused and
// blocklists the presenter for the job, without a restart.
#include <gtest/gtest.h>
#include <signal.h>

#include <nlohmann/json.hpp>
#include <regex>

#include "client/farm_client.h"
#include "tests/e2e/harness.h"

namespace pf::e2e {
namespace {
namespace fs = std::filesystem;
namespace v1 = photonfarm::v1;

struct Attack {
  std::string name;
  std::vector<std::string> fake_worker;  // its mode
  std::vector<std::string> coordinator;  // what is verified
  std::vector<std::string> job;          // pf render / submit flags
  std::vector<std::string> farm_only;    // pf submit only
  std::string leased;                    // the malicious worker's log line once it has work
  bool restarts = true;                  // its conviction restarts the job (its work was merged)
};

// The skipping job the e2e tests share (8 tasks); every merged result verified by another worker.
Attack ScaledResults(const std::string& factor) {
  return {"x" + factor,
          {"--mode", "scale", "--factor", factor},
          {"--verify-fraction", "1"},
          JobArgs{}.ToFlags(),
          {},
          "leased job="};
}

// One map of 20000 photons traced in pieces of 8192 (the first two longer than the 4096 photons
// checked for every piece); every piece traced again in full.
Attack ShiftedPhotons() {
  return {"shifted-photons",
          {"--mode", "shift-photons"},
          {"--verify-fraction", "0", "--verify-piece-fraction", "1", "--map-chunk-photons", "8192"},
          {"--integrator", "photonmap", "--photons", "20000", "--k", "20", "--plan", "multiple-maps",
           "--maps", "2", "--tile", "16", "--res", "32x32", "--spp", "1", "--seed", "9"},
          {"--map-tracing", "distributed"},
          "leased-piece job=",
          // Its first piece is refused and convicts it before it has anything else: no map or
          // image holds its work.
          false};
}

// A lease hijack: the malicious worker presents a lease held by another worker (its accomplice:
// the id leaked) — heartbeat, result or piece upload, FailTask(retryable = false). Every call is
// refused and blocklists it for the job, which goes on without a restart.
Attack LeaseHijack() {
  return {"hijack-task", {"--mode", "hijack"}, {}, JobArgs{}.ToFlags(), {}, "leased-task job=", false};
}
Attack PieceLeaseHijack() {
  return {"hijack-piece",
          {"--mode", "hijack"},
          {"--map-chunk-photons", "8192"},
          {"--integrator", "photonmap", "--photons", "20000", "--k", "20", "--plan", "multiple-maps",
           "--maps", "2", "--tile", "16", "--res", "32x32", "--spp", "1", "--seed", "9"},
          {"--map-tracing", "distributed"},
          "leased-piece job=",
          false};
}

// Its name, not its bytes, in test listings (ctest reads them).
void PrintTo(const Attack& attack, std::ostream* os) {
  *os << attack.name;
}

class MaliciousWorker : public ::testing::TestWithParam<Attack> {};

TEST_P(MaliciousWorker, IsConvictedAndTheJobEndsInTheHonestImage) {
  const Attack& attack = GetParam();
  TestDir dir;
  const RunResult local = RenderLocally(dir, attack.job);
  ASSERT_EQ(local.exit_code, 0) << local.err;
  const Image reference = ReadImage(dir / "local.exr");
  CoordinatorProcess coordinator(dir / "data", dir.path(), attack.coordinator);
  const std::string job_id = SubmitJob(dir, coordinator.address(), Concat(attack.job, attack.farm_only));
  ASSERT_FALSE(job_id.empty());

  // The malicious worker first, so that it has work before the honest ones take it all.
  Process mallory("mallory",
                  Concat({Binaries::FakeWorker(), "--coordinator", coordinator.address(), "--worker-id",
                          "mallory", "--cache-dir", (dir / "cache-mallory").string(), "--seconds", "60"},
                         attack.fake_worker),
                  dir / "mallory.log", dir / "mallory.json");
  ASSERT_TRUE(WaitUntil([&] { return !Grep(dir / "mallory.log", attack.leased).empty(); }, 20))
      << ReadFile(dir / "mallory.log");
  auto w1 = StartWorker(coordinator.address(), dir.path(), "w1");
  auto w2 = StartWorker(coordinator.address(), dir.path(), "w2");

  FarmClient client(coordinator.address(), "");
  const v1::JobStatus st = WaitForJob(client, job_id, 60);
  ASSERT_EQ(st.state(), v1::JOB_STATE_SUCCEEDED) << st.failure_reason() << "\n"
                                                 << ReadFile(coordinator.process().log());
  EXPECT_TRUE(BitIdentical(DecodeImage(client.GetImage(job_id)), reference));
  ASSERT_EQ(st.blocklisted_workers_size(), 1);
  EXPECT_EQ(st.blocklisted_workers(0).worker_id(), "mallory");
  EXPECT_EQ(st.verifications_pending(), 0u);
  const RunResult events =
      RunCommand({Binaries::Pf(), "events", job_id, "--coordinator", coordinator.address()}, dir.path());
  ASSERT_EQ(events.exit_code, 0) << events.err;
  EXPECT_TRUE(std::regex_search(events.out, std::regex("convicted +[0-9]+ +[0-9]+ +mallory"))) << events.out;
  EXPECT_EQ(std::regex_search(events.out, std::regex("restarted .*mallory")), attack.restarts) << events.out;
  EXPECT_FALSE(std::regex_search(events.out, std::regex("convicted +[0-9]+ +[0-9]+ +w[12]"))) << events.out;
  if (attack.fake_worker[1] == "scale") {
    // Its lie was seen by a verification: a mismatch (it verified, or was verified by, an honest
    // worker) or the coordinator's own render; the honest results were verified.
    EXPECT_TRUE(std::regex_search(events.out, std::regex("(mismatch|refereed) ")));
    EXPECT_GT(st.results_verified(), 0u);
  }
  if (attack.fake_worker[1] == "hijack") {
    // Every call it made with the other worker's lease was refused.
    const std::optional<int> code = mallory.Wait(20);
    EXPECT_EQ(code, 0) << ReadFile(dir / "mallory.json");
  }
  for (auto* w : {w1.get(), w2.get()}) w->Signal(SIGTERM);
  for (auto* w : {w1.get(), w2.get()}) EXPECT_TRUE(w->Wait(20).has_value());
  mallory.Signal(SIGKILL);
  mallory.Wait(5);
}

INSTANTIATE_TEST_SUITE_P(Attacks, MaliciousWorker,
                         ::testing::Values(ScaledResults("1.5"), ScaledResults("1000"), ScaledResults("0"),
                                           ShiftedPhotons(), LeaseHijack(), PieceLeaseHijack()),
                         [](const ::testing::TestParamInfo<Attack>& info) {
                           std::string name = info.param.name;
                           for (char& c : name)
                             if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
                           return name;
                         });

}  // namespace
}  // namespace pf::e2e
