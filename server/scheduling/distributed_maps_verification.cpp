// DistributedMaps, result verification (distributed_maps.h, "Pieces checked" and "Verification";
// docs/farm.md "Result verification"): an uploaded piece traced again here, a piece that is not the
// coordinator's trace refused and its uploader convicted, and a convicted worker's pieces and
// built maps deleted and traced again without it.
#include "server/scheduling/distributed_maps.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cstring>

#include "common/scene/scene_bundle.h"
#include "proto/limits.h"
#include "server/scheduling/map_store_files.h"

namespace pf::server {
namespace fs = std::filesystem;

std::string DistributedMaps::MismatchOf(const JobConfig& config, uint64_t map_seed, const PhotonChunk& chunk,
                                        const std::string& bytes, bool in_full) {
  std::lock_guard check(check_mu_);
  if (check_scene_hash_ != config.scene_hash || !check_scene_) {
    check_scene_.reset();
    check_scene_hash_.clear();
    try {
      check_scene_ = std::make_shared<const SceneRuntime>(
          LoadBundle(scene_directory_(config.scene_hash), config.scene_entry));
      check_scene_hash_ = config.scene_hash;
    } catch (const std::exception& e) {
      // The coordinator's own trouble is not the worker's: the piece is taken unchecked, as before.
      spdlog::error("maps: scene {} cannot be loaded to check an uploaded piece ({}); piece not checked",
                    ShortKey(config.scene_hash), e.what());
      return "";
    }
  }
  const SceneRuntime& scene = *check_scene_;
  // As the worker traces it (Worker::RunMapPiece, worker/worker.cpp): the first photons of the piece, or all
  // of them.
  PhotonMapsOptions mo = config.settings.Resolved(scene.description).MapsOptions();
  mo.tracing.map_seed = map_seed;
  mo.tracing.threads = 1;
  const uint64_t end = in_full ? chunk.end : std::min(chunk.end, chunk.begin + kPhotonTracingChunk);
  const PhotonChunk expected = TracePhotonChunk(scene.accel, scene.lights, mo, chunk.begin, end);
  const auto refused = [&](const std::string& what) {
    return "photons [" + std::to_string(chunk.begin) + ", " + std::to_string(end) +
           ") of the piece are not the coordinator's trace of them: " + what +
           "; the piece is refused (docs/farm.md, Photon maps traced once)";
  };
  if (in_full) {
    // Byte for byte: the photons, their order, light ids, origins, powers and ray count.
    if (SerializePhotonChunk(expected) != bytes)
      return refused("the piece differs from the trace of all of them");
    return "";
  }
  static const char* const kList[] = {"direct", "indirect", "caustic"};
  if (chunk.rays < expected.rays)
    return refused(std::to_string(chunk.rays) + " rays, fewer than those photons' " +
                   std::to_string(expected.rays));
  for (int k = 0; k < 3; ++k) {
    const PhotonChunk::List& got = chunk.lists[k];
    const PhotonChunk::List& want = expected.lists[k];
    const size_t n = want.photons.size();
    if (got.photons.size() < n)
      return refused(std::string(kList[k]) + " list of " + std::to_string(got.photons.size()) + " photons, " +
                     std::to_string(n) + " traced in its first part alone");
    if ((expected.light_ids && got.light.size() < n) || (expected.origins && got.origin.size() < n))
      return refused(std::string(kList[k]) + " photons lack their light ids or origins");
    const bool same =
        std::memcmp(got.photons.data(), want.photons.data(), n * sizeof(Photon)) == 0 &&
        (!expected.light_ids || std::equal(want.light.begin(), want.light.end(), got.light.begin())) &&
        (!expected.origins || std::memcmp(got.origin.data(), want.origin.data(), n * sizeof(Vec3)) == 0);
    if (!same) return refused(std::string(kList[k]) + " photons differ");
  }
  return "";
}

void DistributedMaps::RefuseAndConvict(const std::string& key, uint32_t index, const std::string& lease_id,
                                       const std::string& worker_id, const std::string& why) {
  std::vector<std::string> job_ids;
  MapUpdate update;
  {
    std::lock_guard lock(mu_);
    ++counters_.chunks_refused;
    if (!options_.convict) return;  // refused only: the worker's FailTask or the lease's expiry counts
    Map& m = maps_.at(key);
    job_ids = JobsOfLocked(m);
    const Chunk& c = m.chunks[index];
    // Queued again for another worker, as a failed attempt: a piece that keeps being refused is
    // left to the workers like one that keeps failing. (Its lease in the Scheduler's table is then
    // no longer current: PieceLeaseCurrent.)
    if (m.state == Map::State::kTracing && c.state == Chunk::State::kLeased && c.lease_id == lease_id)
      RequeueLocked(m, index, "piece-refused", "refused: " + why, update);
  }
  spdlog::error("job {} piece {}: worker {} uploaded a piece that is not the coordinator's trace: convicted",
                job_ids.front(), index, limits::Quote(worker_id, limits::kMaxWorkerIdBytes));
  if (scheduler_) {
    // In every job waiting for the map (the first one may have ended), before the failed attempt
    // is reported (the update): a convicted worker's blocklisting never makes a job fail for "no
    // worker left".
    for (const std::string& job_id : job_ids)
      scheduler_->ConvictWorker(job_id, worker_id, index, "map piece " + std::to_string(index) + ": " + why);
    scheduler_->ApplyMapUpdate(update);
  }
}

std::vector<std::string> DistributedMaps::JobsOfLocked(const Map& m) const {
  std::vector<std::string> jobs{m.job_id};
  for (const auto& [job_id, map_index] : m.waiting)
    if (std::find(jobs.begin(), jobs.end(), job_id) == jobs.end()) jobs.push_back(job_id);
  return jobs;
}

std::vector<std::string> DistributedMaps::WorkerConvicted(const std::string& worker_id) {
  std::set<std::string> purged;  // keys of built maps deleted: the jobs that used them restart
  size_t pieces = 0;
  MapUpdate update;  // maps traced again, or with pieces queued again
  {
    std::lock_guard lock(mu_);
    for (auto& [key, m] : maps_) {
      if ((m.state == Map::State::kBuilt || m.state == Map::State::kBuilding) &&
          m.contributors.count(worker_id)) {
        // Built (or being assembled) from its pieces: deleted, and traced again from nothing
        // (the pieces of a built map are gone; an assembly under way is dropped: generation).
        RemoveWithTracers(MapFileOf(options_.dir, key));
        std::error_code ec;
        fs::remove_all(options_.dir / (key + ".chunks"), ec);
        ++m.generation;
        // (A map found built on disk never had its pieces counted.)
        m.chunks.assign((m.photons + m.chunk_photons - 1) / m.chunk_photons, Chunk{});
        m.done = 0;
        m.contributors.clear();
        m.built = BuiltMap{};
        SetStateLocked(m, Map::State::kTracing);
        purged.insert(key);
        update.maps.insert(key);
        continue;
      }
      if (m.state != Map::State::kTracing) continue;
      for (uint32_t i = 0; i < m.chunks.size(); ++i) {
        Chunk& c = m.chunks[i];
        if (c.state == Chunk::State::kDone && c.uploader == worker_id) {
          const uint64_t begin = uint64_t(i) * m.chunk_photons;
          RemoveWithTracers(ChunkFile(key, begin, std::min(m.photons, begin + m.chunk_photons)));
          PieceTransitions().Check(c.state, Chunk::State::kQueued);
          c = Chunk{};
          --m.done;
          ++pieces;
          update.maps.insert(key);
        } else if (c.state == Chunk::State::kLeased && c.worker_id == worker_id) {
          // Its lease is no longer current (PieceLeaseCurrent); its upload would be refused anyway.
          PieceTransitions().Move(c.state, Chunk::State::kQueued);
          c.lease_id.clear();
          update.maps.insert(key);
        }
      }
    }
    for (auto it = on_disk_.begin(); it != on_disk_.end();) {
      if (!maps_.count(it->first) && it->second.contributors.count(worker_id)) {
        RemoveWithTracers(MapFileOf(options_.dir, it->first));
        purged.insert(it->first);
        it = on_disk_.erase(it);
      } else {
        ++it;
      }
    }
    for (auto& [key, ranges] : chunks_on_disk_)
      for (auto it = ranges.begin(); it != ranges.end();) {
        if (it->second == worker_id && !maps_.count(key)) {
          RemoveWithTracers(ChunkFile(key, it->first.first, it->first.second));
          it = ranges.erase(it);
          ++pieces;
        } else {
          ++it;
        }
      }
    for (const std::string& key : purged) {
      on_disk_.erase(key);
      ++counters_.maps_purged;
    }
  }
  std::vector<std::string> jobs;
  {
    std::lock_guard lock(mu_);
    for (const auto& [id, key] : keys_)
      if (purged.count(key) && std::find(jobs.begin(), jobs.end(), id.first) == jobs.end())
        jobs.push_back(id.first);
  }
  if (!purged.empty() || pieces > 0)
    spdlog::warn(
        "maps: worker {} convicted: {} stored maps and {} pieces it traced deleted, traced again without it; "
        "{} jobs used those maps",
        limits::Quote(worker_id, limits::kMaxWorkerIdBytes), purged.size(), pieces, jobs.size());
  if (scheduler_) scheduler_->ApplyMapUpdate(update);
  return jobs;
}

void DistributedMaps::ReleaseCheckSceneIfUnused() {
  std::lock_guard check(check_mu_);
  if (!check_scene_) return;
  {
    std::lock_guard lock(mu_);
    for (const auto& [key, m] : maps_)
      if (m.state == Map::State::kTracing && m.config->scene_hash == check_scene_hash_ &&
          m.done < m.chunks.size())
        return;
  }
  check_scene_.reset();
  check_scene_hash_.clear();
}

}  // namespace pf::server
