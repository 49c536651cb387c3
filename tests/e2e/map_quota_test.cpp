// The map store's quota (pf-coordinator --maps-quota; docs/farm.md "The map store's quota"), real
// processes: a paused job whose map is stored, then 30 jobs of one map each, one after the other,
// through a store with room for four maps and a half. The least recently used maps are evicted as the jobs
// run, the store stays at the quota (over it by at most the map just built, until its eviction a moment
// later), the paused job's map is never evicted, and once resumed the job renders from it — nothing traced
// again — an image bit-identical to a local render.
#include <signal.h>

#include <filesystem>
#include <regex>

#include "client/farm_client.h"
#include "tests/e2e/harness.h"

namespace pf::e2e {
namespace {
namespace fs = std::filesystem;
namespace v1 = photonfarm::v1;

// One map of 4096 photons (one piece), one 8x8 render task.
std::vector<std::string> SmallJob(int seed) {
  return {"--integrator", "photonmap",     "--photons", "4096", "--k",    "20",
          "--plan",       "multiple-maps", "--maps",    "1",    "--tile", "8",
          "--res",        "8x8",           "--spp",     "1",    "--seed", std::to_string(seed)};
}

// The bytes of the store's files; `built_only`: of built maps and their records (not the pieces of
// maps still tracing, which no quota may evict).
uint64_t StoreBytes(const fs::path& dir, bool built_only = false) {
  uint64_t total = 0;
  std::error_code ec;
  for (fs::recursive_directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (built_only && !name.ends_with(".pfmaps") && !name.ends_with(".pfmaps.by")) continue;
    if (std::error_code fec; it->is_regular_file(fec)) total += it->file_size(fec);
  }
  return total;
}

// The short key (12 hex digits) the coordinator logged for the job's map 0.
std::string ShortKeyOf(const fs::path& log, const std::string& job_id) {
  const std::vector<std::string> lines = Grep(log, "job " + job_id + " map 0: traced once.*key [0-9a-f]{12}");
  if (lines.empty()) return "";
  std::smatch m;
  std::regex_search(lines[0], m, std::regex("key ([0-9a-f]{12})"));
  return m[1].str();
}

bool MapStored(const fs::path& maps, const std::string& short_key) {
  std::error_code ec;
  for (const fs::directory_entry& e : fs::directory_iterator(maps, ec)) {
    const std::string name = e.path().filename().string();
    if (name.starts_with(short_key) && name.ends_with(".pfmaps")) return true;
  }
  return false;
}

TEST(MapQuota, LeastRecentlyUsedMapsGoAPausedJobsMapStaysAndItsJobRendersFromIt) {
  TestDir dir;
  const std::vector<std::string> held_flags = SmallJob(7);
  ASSERT_EQ(RenderLocally(dir, held_flags).exit_code, 0);
  const Image reference = ReadImage(dir / "local.exr");
  ASSERT_GT(PixelSum(reference), 0.0);
  const fs::path data = dir / "data", maps = data / "maps";
  const std::vector<std::string> distributed = {"--map-tracing", "distributed"};

  // A first coordinator without a quota: the held job, paused before any worker runs, and a job of
  // the same scene, settings and seed that stores their map.
  std::string held, first_key;
  uint64_t map_bytes = 0;
  {
    CoordinatorProcess coordinator(data, dir.path());
    FarmClient client(coordinator.address(), "");
    held = SubmitJob(dir, coordinator.address(), Concat(held_flags, distributed));
    ASSERT_FALSE(held.empty());
    client.SetJobPaused(held, true);
    const std::string twin = SubmitJob(dir, coordinator.address(), Concat(held_flags, distributed));
    auto worker = StartWorker(coordinator.address(), dir.path(), "w0");
    ASSERT_EQ(WaitForJob(client, twin, 60).state(), v1::JOB_STATE_SUCCEEDED);
    first_key = ShortKeyOf(coordinator.process().log(), twin);
    ASSERT_EQ(first_key.size(), 12u);
    ASSERT_TRUE(MapStored(maps, first_key));
    map_bytes = StoreBytes(maps);
    ASSERT_GT(map_bytes, 1000u);
    coordinator.process().Signal(SIGTERM);
    ASSERT_EQ(coordinator.process().Wait(30), std::optional<int>(0));
  }

  // Room for four maps and a half. The held job stays paused across the restart.
  const uint64_t quota = 4 * map_bytes + map_bytes / 2;
  CoordinatorProcess coordinator(data, dir.path(), {"--maps-quota", std::to_string(quota)});
  FarmClient client(coordinator.address(), "");
  ASSERT_TRUE(client.GetJob(held).paused());
  auto w1 = StartWorker(coordinator.address(), dir.path(), "w1");
  auto w2 = StartWorker(coordinator.address(), dir.path(), "w2");
  // One job after the other: a queued or running job's map is live, so jobs submitted together
  // would hold the store over the quota until they end.
  uint64_t most = 0;
  for (int seed = 100; seed < 130; ++seed) {
    const std::string id = SubmitJob(dir, coordinator.address(), Concat(SmallJob(seed), distributed));
    ASSERT_FALSE(id.empty());
    v1::JobStatus st;
    WaitUntil(
        [&] {
          most = std::max(most, StoreBytes(maps, /*built_only=*/true));
          st = client.GetJob(id);
          return IsFinalState(st.state());
        },
        120);
    ASSERT_EQ(st.state(), v1::JOB_STATE_SUCCEEDED) << id << ": " << st.failure_reason();
  }
  // The last eviction follows the last build on the coordinator's builder thread.
  EXPECT_TRUE(WaitUntil([&] { return StoreBytes(maps) <= quota; }, 10)) << StoreBytes(maps) << " > " << quota;
  // (A map's size varies by a few percent with its seed: the bound allows one of 1.5 times the first.)
  EXPECT_LE(most, quota + map_bytes * 3 / 2) << "built maps over the quota by more than the one just built";
  const fs::path log = coordinator.process().log();
  EXPECT_GE(Grep(log, "maps: evicted map [0-9a-f]{12} \\([0-9]+ bytes").size(), 30u - 4u) << ReadFile(log);
  EXPECT_TRUE(Grep(log, "maps: evicted map " + first_key).empty()) << "the paused job's map was evicted";
  EXPECT_TRUE(Grep(log, "over --maps-quota .* every map left").empty()) << "the quota could be met";
  EXPECT_TRUE(MapStored(maps, first_key));

  client.SetJobPaused(held, false);
  const v1::JobStatus st = WaitForJob(client, held, 60);
  ASSERT_EQ(st.state(), v1::JOB_STATE_SUCCEEDED) << st.failure_reason();
  EXPECT_TRUE(BitIdentical(DecodeImage(client.GetImage(held)), reference));
  EXPECT_TRUE(Grep(log, "leased to .*map " + first_key + "\\)").empty())
      << "the held job's map was traced again";
  EXPECT_FALSE(Grep(log, "job " + held + " map 0: built map " + first_key + " found on disk").empty())
      << ReadFile(log);
}

}  // namespace
}  // namespace pf::e2e
